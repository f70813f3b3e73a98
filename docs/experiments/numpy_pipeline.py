#!/usr/bin/env python3
"""NumPy/SciPy equivalent of `htfid run configs/paper.toml --no-plots`, for a speed comparison.

The same work as the Rust pipeline, written the way a NumPy/SciPy user would write it:

1. limit cycle: 30 forcing periods of settling, then Newton shooting on the period map with the
   variational equations (saltation matrices at the damper switches);
2. the experiment: the hybrid hopper on its orbit from t = 0 to 301 s, nine phase-shifted paper
   chirps from t = 30 s, sampled at 100 Hz (solve_ivp, DOP853, rtol 1e-10, atol 1e-12, a
   terminal event at every switch of the damper);
3. the deviation from the orbit (one unexcited period, tiled);
4. linearisation about the orbit (one period, Gauss-Legendre averages per piece) and the exact,
   untruncated HTF of the piecewise-LTI model (modal closed form, vectorised over frequencies);
5. Siddiqi's regularised single-record estimator (banded Hermitian normal equations, LAPACK
   banded solve; diagonal of the inverse by a block-tridiagonal recursion) and the
   multi-experiment estimator (batched SVD per output bin, variance pooled over 11 bins);
6. the parametric fit of k and c to each estimate through the exact HTF (scipy least_squares,
   central differences; every evaluation re-finds the limit cycle by Newton shooting,
   re-linearises and evaluates the exact HTF);
7. errors against the exact theory, aliasing table, theory grid, and the output files
   (timeseries.csv, limit_cycle.csv, theory.csv, estimate_*.csv, summary.json).

Usage:
    python3 docs/experiments/numpy_pipeline.py [CONFIG] [--out DIR] [--check [RUST_SUMMARY]]

`--check` compares the fitted k, c, the error table, the limit cycle and a few HTF values with a
Rust run (`htfid run configs/paper.toml --out /tmp/np-bench-rust --force`).
"""

import argparse
import json
import math
import os
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import solveh_banded
from scipy.optimize import least_squares

HERE = Path(__file__).resolve().parent
DEFAULT_CONFIG = HERE.parent.parent / "configs" / "paper.toml"

# Gauss-Legendre nodes and weights on [-1, 1], 8 points (as htfid-ltp's linearise).
GL_NODES, GL_WEIGHTS = np.polynomial.legendre.leggauss(8)
LINEAR_SAMPLES = 8
FIT_POINTS_PER_HARMONIC = 200


# --------------------------------------------------------------------------------------------
# Configuration
# --------------------------------------------------------------------------------------------

class Params:
    def __init__(self, m, k, c, g, x0, amplitude, period):
        self.m, self.k, self.c, self.g, self.x0 = m, k, c, g, x0
        self.amp, self.period = amplitude, period
        self.wp = 2.0 * math.pi / period

    def replace(self, **kw):
        d = dict(m=self.m, k=self.k, c=self.c, g=self.g, x0=self.x0,
                 amplitude=self.amp, period=self.period)
        d.update(kw)
        return Params(**d)


def load_config(path):
    with open(path, "rb") as f:
        cfg = tomllib.load(f)
    mo, fo, si = cfg["model"], cfg["forcing"], cfg.get("simulation", {})
    ex, es, th = cfg["excitation"], cfg["estimation"], cfg["theory"]
    if mo.get("damper", "switching") != "switching" or ex.get("kind") != "chirp_train" \
            or ex.get("waveform") != "paper" or "noise" in cfg or "effects" in cfg:
        sys.exit("this script reproduces the paper's experiment only (switching damper, "
                 "paper chirp train, no noise, no effects)")
    p = Params(mo["m"], mo["k"], mo["c"], mo["g"], mo["x0"], fo["amplitude"], fo["period"])
    return dict(
        name=cfg.get("name", Path(path).stem), params=p,
        settle_periods=si.get("settle_periods", 30), fs=si.get("sample_rate", 100.0),
        rtol=si.get("rtol", 1e-10), atol=si.get("atol", 1e-12),
        copies=ex.get("copies", 1),
        harmonics=es.get("harmonics", [-3, -2, -1, 0, 1, 2, 3]),
        band=(es.get("omega_min", 1.0), es.get("omega_max", 40.0)),
        estimators=es.get("estimators", ["siddiqi", "multi"]),
        alpha=es.get("alpha", 1e-3), fit=es.get("fit", ["k", "c"]),
        fit_harmonics=es.get("fit_harmonics", [-1, 0, 1]),
        theory_harmonics=th.get("harmonics", [-3, -2, -1, 0, 1, 2, 3]),
        theory_band=(th.get("omega_min", 1.0), th.get("omega_max", 40.0)),
        theory_points=th.get("points", 400),
    )


# --------------------------------------------------------------------------------------------
# Excitation: the paper's chirp 0.004 sin(14 pi t^2 / 30), nine copies shifted by T/9
# --------------------------------------------------------------------------------------------

class ChirpTrain:
    DURATION = 30.0

    def __init__(self, start, period, copies):
        self.start, self.copies = start, copies
        shift = period / copies
        m = max(math.ceil((self.DURATION - shift) / period - 1e-9), 0)
        self.stride = shift + m * period
        self.end = start + (copies - 1) * self.stride + self.DURATION
        self.segments = [start + k * self.stride for k in range(copies)]

    def __call__(self, t):
        tau = t - self.start
        if tau < 0.0:
            return 0.0
        k = math.floor(tau / self.stride)
        if k >= self.copies:
            return 0.0
        loc = tau - k * self.stride
        return 0.004 * math.sin(14.0 * math.pi * loc * loc / 30.0) if loc < self.DURATION else 0.0

    def sample(self, t):
        tau = t - self.start
        k = np.floor(tau / self.stride)
        loc = tau - k * self.stride
        on = (tau >= 0) & (k < self.copies) & (loc < self.DURATION)
        return np.where(on, 0.004 * np.sin(14.0 * np.pi * loc * loc / 30.0), 0.0)


# --------------------------------------------------------------------------------------------
# The hybrid hopper: m x'' = -m g - c s x' - k (x - x0) + A cos(wp t) + u(t), s = [x' > 0]
# --------------------------------------------------------------------------------------------

def hopper_rhs(p, damped, u=None):
    m, k, g, x0, amp, wp = p.m, p.k, p.g, p.x0, p.amp, p.wp
    cs = p.c if damped else 0.0
    cos = math.cos
    if u is None:
        def rhs(t, y):
            x, v = y.tolist()  # Python floats: faster scalar arithmetic
            return [v, (-m * g - cs * v - k * (x - x0) + amp * cos(wp * t)) / m]
    else:
        def rhs(t, y):
            x, v = y.tolist()  # Python floats: faster scalar arithmetic
            return [v, (-m * g - cs * v - k * (x - x0) + amp * cos(wp * t) + u(t)) / m]
    return rhs


def variational_rhs(p, damped):
    """State [x, v, Phi (2x2 row-major)]; Phi' = A Phi with A = [[0, 1], [-k/m, -c s/m]]."""
    m, k, g, x0, amp, wp = p.m, p.k, p.g, p.x0, p.amp, p.wp
    cs = p.c if damped else 0.0
    a21, a22 = -k / m, -cs / m
    cos = math.cos

    def rhs(t, y):
        x, v, p11, p12, p21, p22 = y.tolist()
        return [v, (-m * g - cs * v - k * (x - x0) + amp * cos(wp * t)) / m,
                p21, p22, a21 * p11 + a22 * p21, a21 * p12 + a22 * p22]
    return rhs


def jacobian_A(p, damped):
    return np.array([[0.0, 1.0], [-p.k / p.m, -(p.c if damped else 0.0) / p.m]])


def _guard(direction):
    def ev(t, y):
        return y[1]
    ev.terminal = True
    ev.direction = direction
    return ev


# The damper switches off on a falling zero of x' and on on a rising one.
GUARD = {True: _guard(-1.0), False: _guard(1.0)}


def saltation(p, from_damped, t, x):
    """S = R_x + (f+ - R_x f-) grad^T / (grad . f-), guard x' = 0, identity reset."""
    fm = np.asarray(hopper_rhs(p, from_damped)(t, x))
    fp = np.asarray(hopper_rhs(p, not from_damped)(t, x))
    grad = np.array([0.0, 1.0])
    return np.eye(2) + np.outer(fp - fm, grad) / (grad @ fm)


def simulate_hybrid(rhs_for, damped, t0, y0, t_end, t_eval, rtol, atol):
    """Integrates chart by chart, restarting at every switch. Returns the states at t_eval
    (shape (len(y0), len(t_eval))), the switch events [(t, from_damped, y)], the final mode and
    state, and the number of right-hand-side evaluations."""
    rhs = {True: rhs_for(True), False: rhs_for(False)}
    t, y = t0, np.asarray(y0, float)
    t_eval = np.asarray(t_eval, float)
    out = np.empty((len(y), len(t_eval)))
    done, events, nfev = 0, [], 0
    while True:
        sol = solve_ivp(rhs[damped], (t, t_end), y, method="DOP853", t_eval=t_eval[done:],
                        events=GUARD[damped], rtol=rtol, atol=atol)
        if sol.status < 0:
            raise RuntimeError(sol.message)
        nfev += sol.nfev
        n = sol.t.size
        out[:, done:done + n] = sol.y
        done += n
        if sol.status == 1:  # a switch
            t, y = float(sol.t_events[0][0]), sol.y_events[0][0]
            events.append((t, damped, y.copy()))
            damped = not damped
            continue
        return out, events, damped, nfev


def final_state(rhs_for, damped, t0, y0, t_end, rtol, atol, on_switch=None):
    """Integrates to t_end (no output grid); `on_switch(t, from_damped, y)` may modify the
    state at a switch (saltation of the variational part)."""
    rhs = {True: rhs_for(True), False: rhs_for(False)}
    t, y = t0, np.asarray(y0, float)
    events = []
    while True:
        sol = solve_ivp(rhs[damped], (t, t_end), y, method="DOP853", events=GUARD[damped],
                        rtol=rtol, atol=atol)
        if sol.status < 0:
            raise RuntimeError(sol.message)
        if sol.status == 1:
            t, y = float(sol.t_events[0][0]), sol.y_events[0][0].copy()
            if on_switch is not None:
                on_switch(t, damped, y)
            events.append((t, damped, y[:2].copy()))
            damped = not damped
            continue
        return sol.y[:, -1], damped, events


# --------------------------------------------------------------------------------------------
# Limit cycle: settling + Newton shooting with the variational equations
# --------------------------------------------------------------------------------------------

def initial_guess(p):
    w = p.wp
    re, im = p.k - p.m * w * w, w * 0.5 * p.c
    den = re * re + im * im
    xr, xi = p.amp * re / den, -p.amp * im / den
    return np.array([p.x0 - p.m * p.g / p.k + xr, -w * xi])


def period_map(p, damped, x, rtol, atol):
    def on_switch(t, from_damped, y):
        s = saltation(p, from_damped, t, y[:2])
        y[2:] = (s @ y[2:].reshape(2, 2)).ravel()
    y0 = np.concatenate([x, np.eye(2).ravel()])
    yT, mode, events = final_state(lambda d: variational_rhs(p, d), damped, 0.0, y0, p.period,
                                   rtol, atol, on_switch)
    return yT[:2], yT[2:].reshape(2, 2), mode, events


def limit_cycle(p, x0, settle_periods, rtol, atol, newton_tol=1e-13, max_newton=30):
    x = np.asarray(x0, float)
    damped = bool(x[1] > 0.0)
    if settle_periods > 0:
        y, damped, _ = final_state(lambda d: hopper_rhs(p, d), damped, 0.0, x,
                                   settle_periods * p.period, rtol, atol)
        x = y
    xt, jac, _, events = period_map(p, damped, x, rtol, atol)
    it = 0
    while True:
        r = xt - x
        res = np.max(np.abs(r))
        scale = max(1.0, np.max(np.abs(x)))
        if res <= newton_tol * scale:
            break
        if it >= max_newton:
            raise RuntimeError("Newton shooting did not converge")
        x = x + np.linalg.solve(jac - np.eye(2), -r)
        it += 1
        xt, jac, _, events = period_map(p, damped, x, rtol, atol)
        new = np.max(np.abs(xt - x))
        if new >= res and new <= 1e3 * newton_tol * scale:
            break
    mult = np.linalg.eigvals(jac)
    mult = mult[np.lexsort((-mult.imag, -np.abs(mult)))]
    if np.abs(mult[0]) >= 1.0 - 1e-6:
        raise RuntimeError("orbit not stable")
    ons = [t % p.period for t, d, _ in events if not d]
    offs = [t % p.period for t, d, _ in events if d]
    return dict(state0=x, mode0=damped, jacobian=jac, multipliers=mult, events=events,
                newton_iterations=it, t_on=ons[0], t_off=offs[0],
                duty=((offs[0] - ons[0]) % p.period) / p.period,
                residual=float(np.max(np.abs(xt - x))))


# --------------------------------------------------------------------------------------------
# Linearisation about the orbit and the exact HTF of the piecewise-LTI model
# --------------------------------------------------------------------------------------------

def linearise(p, orbit, rtol, atol):
    """Pieces between switches: A, B, C averaged by 8-point Gauss-Legendre along the orbit
    (one simulated period, as htfid's linearise), jumps = saltation matrices."""
    T = p.period
    sw = [(t, d, y) for t, d, y in orbit["events"]]
    starts = [t for t, _, _ in sw]
    quad = []
    for i, a in enumerate(starts):
        b = starts[i + 1] if i + 1 < len(starts) else starts[0] + T
        quad.append(0.5 * (a + b) + 0.5 * (b - a) * GL_NODES)
    quad = np.concatenate(quad)
    wrapped = np.where(quad >= T, quad - T, quad)
    grid = np.sort(np.concatenate([np.arange(LINEAR_SAMPLES) * T / LINEAR_SAMPLES, wrapped]))
    ys, _, _, _ = simulate_hybrid(lambda d: hopper_rhs(p, d), orbit["mode0"], 0.0,
                                     orbit["state0"], T, grid, rtol, atol)
    pieces = []
    for i, (a, from_damped, y) in enumerate(sw):
        b = starts[i + 1] if i + 1 < len(starts) else starts[0] + T
        damped = not from_damped
        idx = np.searchsorted(grid, wrapped[8 * i:8 * i + 8])
        vel = ys[1, idx]  # the chart at each node (Jacobian of the chart the state is in)
        A = sum(w * jacobian_A(p, v > 0.0) for w, v in zip(GL_WEIGHTS, vel)) / 2.0
        pieces.append(dict(tau=a, h=b - a, A=A, B=np.array([0.0, 1.0 / p.m]),
                           C=np.array([1.0, 0.0]), J=saltation(p, from_damped, a, y[:2]),
                           damped=damped))
    return pieces


def _phi1(x):
    """(e^x - 1) / x, accurate near 0."""
    small = np.abs(x) < 1e-8
    xs = np.where(small, 1.0, x)
    return np.where(small, 1.0 + x / 2.0, np.expm1(xs) / xs)


def _dd2_series(b, c, terms=24):
    """exp[0, b, c] = sum_m h_m(b, c) / (m + 2)!, |b|, |c| < 1."""
    total = np.zeros_like(c)
    hm = np.ones_like(c)  # h_0
    bp = np.ones_like(c)  # b^m
    fact = 2.0
    for m in range(terms):
        total = total + hm / fact
        bp = bp * b
        hm = hm * c + bp  # h_{m+1}(b, c) = c h_m + b^{m+1}
        fact *= m + 3
    return total


class ExactHtf:
    """G_n(jw) in the estimation convention Y(jw) = sum_n G_n(jw) U(jw - j n wp), for a SISO
    piecewise-LTI system with jumps, in closed form on the modal path (vectorised over
    (n, w) pairs)."""

    def __init__(self, pieces, period):
        self.T, self.wp = period, 2.0 * math.pi / period
        self.pieces = []
        for pc in pieces:
            lam, V = np.linalg.eig(pc["A"])
            Vi = np.linalg.inv(V)
            self.pieces.append(dict(tau=pc["tau"], h=pc["h"], lam=lam, V=V, Vi=Vi,
                                    beta=Vi @ pc["B"], gamma=pc["C"] @ V, J=pc["J"]))
        npc = len(self.pieces)
        mono = np.eye(2, dtype=complex)
        for i, q in enumerate(self.pieces):
            nxt = self.pieces[(i + 1) % npc]
            q["transfer"] = nxt["Vi"] @ nxt["J"] @ q["V"]
            mono = q["transfer"] @ (np.exp(q["lam"] * q["h"])[:, None] * mono)
        self.monodromy = mono
        # Floquet multipliers (from the plain-coordinates monodromy).
        self.multipliers = np.linalg.eigvals(self.pieces[0]["V"] @ mono @ self.pieces[0]["Vi"])

    def g(self, n, w):
        n = np.asarray(n, float)
        w = np.asarray(w, float)
        n, w = np.broadcast_arrays(n, w)
        shape = n.shape
        n, w = n.ravel(), w.ravel()
        s = 1j * (w - n * self.wp)
        per = []
        for q in self.pieces:
            h = q["h"]
            X = (q["lam"][None, :] - s[:, None]) * h  # (F, 2)
            Bh = (-1j * n * self.wp * h)[:, None] * np.ones((1, 2))
            Ch = X + Bh  # (lambda - j w) h
            E = np.exp(X)
            phiX, phiB, phiC = _phi1(X), _phi1(Bh), _phi1(Ch)
            # exp[0, B, C], divided by the widest of the three differences.
            aX, aB, aC = np.abs(X), np.abs(Bh), np.abs(Ch)
            eB = np.exp(Bh)
            with np.errstate(divide="ignore", invalid="ignore"):
                d_x = (phiC - phiB) / X
                d_c = (eB * phiX - phiB) / Ch
                d_b = (eB * phiX - phiC) / Bh
            dd2 = np.where((aC >= aX) & (aC >= aB), d_c, np.where(aB >= aX, d_b, d_x))
            tiny = np.maximum(np.maximum(aX, aB), aC) < 1.0
            if tiny.any():
                dd2[tiny] = _dd2_series(Bh[tiny], Ch[tiny])
            per.append((E, phiX, phiC, dd2))
        # One period from the zero state, then (I - exp(-sT) Phi) zeta0 = psi.
        v = np.zeros((n.size, 2), complex)
        for q, (E, phiX, _, _) in zip(self.pieces, per):
            v = (E * v + q["beta"] * q["h"] * phiX) @ q["transfer"].T
        e_st = np.exp(-s * self.T)
        M = np.eye(2) - e_st[:, None, None] * self.monodromy[None]
        z = np.linalg.solve(M, v[..., None])[..., 0]
        y = np.zeros(n.size, complex)
        for q, (E, phiX, phiC, dd2) in zip(self.pieces, per):
            h = q["h"]
            acc = (q["gamma"] * (z * phiC + q["beta"] * dd2 * h)).sum(axis=1)
            y += np.exp(-1j * ((n * self.wp * q["tau"]) % (2 * np.pi))) * acc * h
            z = (E * z + q["beta"] * h * phiX) @ q["transfer"].T
        return (y / self.T).reshape(shape)


# --------------------------------------------------------------------------------------------
# Estimators
# --------------------------------------------------------------------------------------------

def dft(x, dt, t_start):
    """X[k] = dt sum_i x[i] exp(-j w_k (t_start + i dt)), FFT order."""
    N = x.shape[-1]
    k = np.fft.fftfreq(N, 1.0 / N)
    turns = k * (np.asarray(t_start, float)[..., None] / (N * dt))
    return np.fft.fft(x, axis=-1) * dt * np.exp(-2j * np.pi * (turns - np.round(turns)))


def bin_grid(N, dt, period, band):
    p_bins = round(N * dt / period)
    dw = 2.0 * math.pi / (N * dt)
    k_lo = math.ceil(band[0] / dw - 1e-9)
    k_hi = math.floor(band[1] / dw + 1e-9)
    return p_bins, dw, np.arange(k_lo, k_hi + 1)


def siddiqi(u, y, dt, t_start, period, harmonics, band, alpha):
    N = u.size
    P, dw, bins = bin_grid(N, dt, period, band)
    H, M = len(harmonics), bins.size
    U, Y = dft(np.stack([u, y]), dt, t_start)
    shifts = np.asarray(harmonics) * P
    a = U[(bins[:, None] - shifts[None, :]) % N]  # (M, H): U[k - n P]
    yb = Y[bins % N]
    scale = np.sum(np.abs(a) ** 2) / (M * H)
    alpha_eff = alpha * scale
    # Second-difference penalty D2^T D2 (bands 0, 1, 2) for M bins.
    pen = np.zeros((3, M))
    st = np.array([1.0, -2.0, 1.0])
    centres = np.arange(1, M - 1)
    for di in range(3):
        for dj in range(di, 3):
            np.add.at(pen[dj - di], centres - 1 + di, st[di] * st[dj])
    # Banded lower storage of the normal matrix, unknowns bin-major x[kb * H + h].
    n = M * H
    b = 2 * H
    ab = np.zeros((b + 1, n), complex)
    gram = np.conj(a)[:, :, None] * a[:, None, :]  # (M, H, H): conj(a_h1) a_h2
    for d in range(H):
        # N[kb H + h2 + d, kb H + h2] = gram[kb, h2 + d, h2]
        blk = np.zeros((M, H), complex)
        blk[:, :H - d] = gram[:, np.arange(d, H), np.arange(0, H - d)]
        ab[d] += blk.ravel()
    ab[0] += np.repeat(alpha_eff * pen[0], H)
    ab[H] += np.repeat(alpha_eff * pen[1], H)
    ab[2 * H] += np.repeat(alpha_eff * pen[2], H)
    rhs = (np.conj(a) * yb[:, None]).ravel()
    x = solveh_banded(ab, rhs, lower=True, check_finite=False)
    X = x.reshape(M, H)
    rss = np.sum(np.abs(yb - np.sum(a * X, axis=1)) ** 2)
    # Diagonal blocks of the inverse: the matrix is block tridiagonal in super-blocks of two
    # bins (2H x 2H); one forward (Schur complements) and one backward sweep.
    Mp = M + (M % 2)
    Dbin = np.zeros((Mp, H, H), complex)
    Dbin[:M] = gram + alpha_eff * pen[0][:, None, None] * np.eye(H)
    if Mp > M:
        Dbin[M] = np.eye(H)  # decoupled dummy bin
    p1 = np.zeros(Mp)
    p2 = np.zeros(Mp)
    p1[:M] = alpha_eff * pen[1]
    p2[:M] = alpha_eff * pen[2]
    if Mp > M:
        p1[M - 1] = 0.0
    nb = Mp // 2
    I = np.eye(H)
    D = np.zeros((nb, 2 * H, 2 * H), complex)
    D[:, :H, :H] = Dbin[0::2]
    D[:, H:, H:] = Dbin[1::2]
    D[:, H:, :H] = p1[0::2, None, None] * I
    D[:, :H, H:] = p1[0::2, None, None] * I
    L = np.zeros((nb - 1, 2 * H, 2 * H), complex)  # N[J + 1, J]
    L[:, :H, :H] = p2[0:-2:2, None, None] * I
    L[:, :H, H:] = p1[1:-1:2, None, None] * I
    L[:, H:, H:] = p2[1:-1:2, None, None] * I
    Sinv = np.empty_like(D)
    W = np.empty_like(L)
    S = D[0]
    for J in range(nb - 1):
        Sinv[J] = np.linalg.inv(S)
        W[J] = L[J] @ Sinv[J]
        S = D[J + 1] - W[J] @ L[J].conj().T
    Sinv[nb - 1] = np.linalg.inv(S)
    Z = np.empty_like(D)
    Zoff = np.empty_like(L)  # Z[J + 1, J]
    Z[nb - 1] = Sinv[nb - 1]
    for J in range(nb - 2, -1, -1):
        Zoff[J] = -Z[J + 1] @ W[J]
        Z[J] = Sinv[J] - W[J].conj().T @ Zoff[J]
    zdiag = np.concatenate([np.diagonal(Z[:, :H, :H], axis1=1, axis2=2),
                            np.diagonal(Z[:, H:, H:], axis1=1, axis2=2)], axis=1)
    zdiag = zdiag.reshape(nb, 2, H).reshape(Mp, H)[:M].real
    # alpha tr(Z P) from the penalty parts of D and L (tr S = n - alpha tr(Z P)).
    p0 = np.zeros(Mp)
    p0[:M] = alpha_eff * pen[0]
    Dpen = np.zeros_like(D)
    Dpen[:, :H, :H] = p0[0::2, None, None] * I
    Dpen[:, H:, H:] = p0[1::2, None, None] * I
    Dpen[:, H:, :H] = Dpen[:, :H, H:] = p1[0::2, None, None] * I
    pen_tr = np.einsum("jab,jba->", Z, Dpen).real + 2.0 * np.einsum("jab,jab->", Zoff, L).real
    trace = n - pen_tr
    dof = M - trace
    sigma2 = rss / dof if dof >= 1.0 else np.nan
    stderr = np.sqrt(sigma2 * zdiag)
    return dict(omega=bins * dw, values=X.T, stderr=stderr.T, alpha=alpha,
                alpha_effective=alpha_eff, dof=dof)


def multi_experiment(us, ys, dt, t_starts, period, harmonics, band, pool=5, rcond=1e-10):
    K, N = us.shape
    P, dw, bins = bin_grid(N, dt, period, band)
    H, M = len(harmonics), bins.size
    U = dft(us, dt, t_starts)  # (K, N)
    Y = dft(ys, dt, t_starts)
    shifts = np.asarray(harmonics) * P
    A = np.transpose(U[:, (bins[:, None] - shifts[None, :]) % N], (1, 0, 2))  # (M, K, H)
    yb = Y[:, bins % N].T  # (M, K)
    Uu, s, Vh = np.linalg.svd(A, full_matrices=False)
    keep = s > rcond * s[:, :1]
    sinv = np.where(keep, 1.0 / np.where(keep, s, 1.0), 0.0)
    proj = np.einsum("mki,mk->mi", Uu.conj(), yb) * sinv
    x = np.einsum("mih,mi->mh", Vh.conj(), proj)
    var = np.einsum("mih,mi->mh", np.abs(Vh) ** 2, sinv ** 2)
    rss = np.sum(np.abs(yb - np.einsum("mkh,mh->mk", A, x)) ** 2, axis=1)
    rank = keep.sum(axis=1)
    dof = K - rank
    crss = np.concatenate([[0.0], np.cumsum(rss)])
    cdof = np.concatenate([[0], np.cumsum(dof)])
    kb = np.arange(M)
    lo, hi = np.maximum(kb - pool, 0), np.minimum(kb + pool + 1, M)
    d = cdof[hi] - cdof[lo]
    with np.errstate(invalid="ignore", divide="ignore"):
        sigma2 = np.where(d > 0, (crss[hi] - crss[lo]) / d, np.nan)
    stderr = np.where((rank == H)[:, None], np.sqrt(sigma2[:, None] * var), np.inf)
    return dict(omega=bins * dw, values=x.T, stderr=stderr.T, cond=s[:, 0] / s[:, -1],
                dof=float(d.min()))


# --------------------------------------------------------------------------------------------
# Parametric fit through the exact HTF
# --------------------------------------------------------------------------------------------

def fit_rows(est, harmonics, fit_harmonics, band):
    ns, ws, vs, ss = [], [], [], []
    for n in fit_harmonics:
        h = harmonics.index(n)
        w, v, s = est["omega"], est["values"][h], est["stderr"][h]
        ok = (w >= band[0]) & (w <= band[1]) & np.isfinite(v.real) & np.isfinite(v.imag)
        w, v, s = w[ok], v[ok], s[ok]
        stride = max(-(-w.size // FIT_POINTS_PER_HARMONIC), 1)
        w, v, s = w[::stride], v[::stride], s[::stride]
        floor = 1e-6 * np.max(np.abs(v))
        s = np.where(np.isfinite(s), np.maximum(s, floor), floor)
        ns.append(np.full(w.size, n))
        ws.append(w)
        vs.append(v)
        ss.append(s)
    return np.concatenate(ns), np.concatenate(ws), np.concatenate(vs), 1.0 / np.concatenate(ss)


def fit_parameters(cfg, p0, x_start, est):
    n, w, v, weight = fit_rows(est, cfg["harmonics"], cfg["fit_harmonics"], cfg["band"])
    names = cfg["fit"]
    rtol, atol = cfg["rtol"], cfg["atol"]
    start = np.array([getattr(p0, nm) for nm in names])
    counter = [0]

    def residuals(q):
        counter[0] += 1
        p = p0.replace(**dict(zip(names, q)))
        orbit = limit_cycle(p, x_start, 0, rtol, atol)
        exact = ExactHtf(linearise(p, orbit, rtol, atol), p.period)
        d = (v - exact.g(n, w)) * weight
        return np.column_stack([d.real, d.imag]).ravel()

    lower = [0.0 if nm == "c" else 1e-12 for nm in names]
    res = least_squares(residuals, start, jac="3-point", method="trf",
                        bounds=(lower, np.inf), x_scale=np.maximum(np.abs(start), 1e-3),
                        ftol=1e-12, xtol=1e-12, gtol=1e-10)
    cost = float(np.sum(res.fun ** 2))
    m, npar = res.fun.size, len(names)
    out = {}
    try:
        cov = np.linalg.inv(res.jac.T @ res.jac) * cost / (m - npar)
        se = np.sqrt(np.diag(cov))
    except np.linalg.LinAlgError:
        se = np.full(npar, np.nan)
    for i, nm in enumerate(names):
        out[nm] = float(res.x[i])
        out[nm + "_stderr"] = float(se[i])
    out.update(harmonics=cfg["fit_harmonics"], points=int(n.size), evaluations=counter[0],
               nfev=int(res.nfev), njev=int(res.njev or 0), cost=cost, status=int(res.status))
    return out


# --------------------------------------------------------------------------------------------
# The pipeline
# --------------------------------------------------------------------------------------------

def harmonic_errors(cfg, exact, est):
    lo, hi = cfg["band"]
    out = {}
    w = est["omega"]
    ok = (w >= lo) & (w <= hi)
    for h, n in enumerate(cfg["harmonics"]):
        truth = exact.g(n, w[ok])
        scale = np.max(np.abs(truth))
        rel = np.sort(np.abs(est["values"][h][ok] - truth) / scale)
        out[str(n)] = dict(median=float(rel[rel.size // 2]), max=float(rel[-1]),
                           max_abs_g=float(scale), points=int(rel.size))
    return out


def aliasing(cfg, exact):
    K = cfg["copies"]
    omegas = np.exp(np.linspace(math.log(cfg["band"][0]), math.log(cfg["band"][1]), 200))
    allh = list(range(-10, 11))
    peaks = dict(zip(allh, np.abs(exact.g(np.array(allh)[:, None], omegas[None, :])).max(axis=1)))
    by = {}
    for n in cfg["harmonics"]:
        al = [m for m in allh if m != n and (m - n) % K == 0]
        by[str(n)] = dict(max_abs_g=float(peaks[n]), aliases=[
            dict(harmonic=m, max_abs_g=float(peaks[m]),
                 relative_to_estimated=float(peaks[m] / peaks[n])) for m in al])
    return dict(copies=K, n_max=10, by_harmonic=by)


def write_estimate(path, est, harmonics):
    H, M = len(harmonics), est["omega"].size
    rows = np.column_stack([np.tile(est["omega"], H), np.repeat(harmonics, M),
                            est["values"].real.ravel(), est["values"].imag.ravel(),
                            est["stderr"].ravel()])
    np.savetxt(path, rows, fmt="%.17g", delimiter=",", header="omega,n,re,im,stderr",
               comments="")


def run(cfg, out_dir):
    timings = {}
    t_all = time.perf_counter()

    def stage(name, fn):
        t = time.perf_counter()
        r = fn()
        timings[name] = (time.perf_counter() - t) * 1e3
        return r

    p, rtol, atol = cfg["params"], cfg["rtol"], cfg["atol"]
    T, fs = p.period, cfg["fs"]
    dt = 1.0 / fs

    orbit = stage("limit cycle", lambda: limit_cycle(
        p, initial_guess(p), max(cfg["settle_periods"], 30), rtol, atol))

    start = cfg["settle_periods"] * T
    train = ChirpTrain(start, T, cfg["copies"])
    end = start + math.ceil(max(train.end - start, 0.0) / T - 1e-9) * T
    n_samples = math.floor(end / dt + 1e-9) + 1
    grid = np.arange(n_samples) * dt

    def simulate():
        ys, ev, _, nfev = simulate_hybrid(lambda d: hopper_rhs(p, d, train), orbit["mode0"],
                                             0.0, orbit["state0"], end, grid, rtol, atol)
        return ys, len(ev), nfev
    (ys, switches, nfev) = stage("simulate", simulate)
    x, xd = ys
    u = train.sample(grid)
    f = p.amp * np.cos(p.wp * grid) + u

    def deviation():
        m = round(fs * T)
        one, _, _, _ = simulate_hybrid(lambda d: hopper_rhs(p, d), orbit["mode0"], 0.0,
                                          orbit["state0"], T, grid[:m], rtol, atol)
        return x - np.resize(one[0], x.size)
    y = stage("orbit deviation", deviation)

    def theory():
        pieces = linearise(p, orbit, rtol, atol)
        return pieces, ExactHtf(pieces, T)
    pieces, exact = stage("linearise", theory)

    harmonics, band = cfg["harmonics"], cfg["band"]

    def record(t_a, duration):
        i0 = max(math.ceil(t_a / dt - 1e-6), 0)
        n = round(duration / dt)
        return i0, n

    estimates = {}
    for name in cfg["estimators"]:
        if name == "siddiqi":
            def est():
                periods = math.floor((grid[-1] - start) / T + 1e-9)
                i0, n = record(start, periods * T)
                return siddiqi(u[i0:i0 + n], y[i0:i0 + n], dt, i0 * dt, T, harmonics, band,
                               cfg["alpha"])
        else:
            def est():
                periods = math.floor(ChirpTrain.DURATION / T)
                idx = [record(s, periods * T) for s in train.segments]
                n = idx[0][1]
                us = np.stack([u[i0:i0 + n] for i0, _ in idx])
                yy = np.stack([y[i0:i0 + n] for i0, _ in idx])
                return multi_experiment(us, yy, dt, np.array([i0 * dt for i0, _ in idx]), T,
                                        harmonics, band)
        estimates[name] = stage(f"estimate ({name})", est)

    errors, fits = {}, {}
    for name, e in estimates.items():
        errors[name] = stage(f"errors ({name})", lambda: harmonic_errors(cfg, exact, e))
        fits[name] = stage(f"fit ({name})", lambda: fit_parameters(cfg, p, orbit["state0"], e))

    def theory_grid():
        lo, hi = cfg["theory_band"]
        om = np.exp(np.linspace(math.log(lo), math.log(hi), cfg["theory_points"]))
        nh = np.asarray(cfg["theory_harmonics"])
        return om, nh, exact.g(nh[None, :], om[:, None])  # (points, harmonics)
    om, nh, G = stage("exact HTF", theory_grid)
    alias = stage("aliasing", lambda: aliasing(cfg, exact))

    def write():
        out_dir.mkdir(parents=True, exist_ok=True)
        np.savetxt(out_dir / "timeseries.csv", np.column_stack([grid, f, x, xd, u]),
                   fmt="%.17g", delimiter=",", header="t,f,x,xd,u", comments="")
        ph = np.arange(1000) * T / 1000
        lc, _, _, _ = simulate_hybrid(lambda d: hopper_rhs(p, d), orbit["mode0"], 0.0,
                                         orbit["state0"], T, ph, rtol, atol)
        sflag = (lc[1] > 0).astype(float)
        np.savetxt(out_dir / "limit_cycle.csv", np.column_stack([ph, lc[0], lc[1], sflag]),
                   fmt="%.17g", delimiter=",", header="phase,x,xd,s", comments="")
        np.savetxt(out_dir / "theory.csv",
                   np.column_stack([np.repeat(om, nh.size), np.tile(nh, om.size),
                                    G.real.ravel(), G.imag.ravel()]),
                   fmt="%.17g", delimiter=",", header="omega,n,re,im", comments="")
        for name, e in estimates.items():
            write_estimate(out_dir / f"estimate_{name}.csv", e, harmonics)
    stage("write outputs", write)
    timings["total"] = (time.perf_counter() - t_all) * 1e3

    summary = dict(
        name=cfg["name"],
        limit_cycle=dict(period=T, t_on=orbit["t_on"], t_off=orbit["t_off"], duty=orbit["duty"],
                         state_phase0=orbit["state0"].tolist(),
                         floquet_multipliers=[[z.real, z.imag] for z in orbit["multipliers"]],
                         newton_iterations=orbit["newton_iterations"],
                         periodicity_residual=orbit["residual"]),
        simulation=dict(t_end=end, samples=n_samples, sample_rate=fs, switches=switches,
                        rhs_evaluations=nfev),
        ltp=dict(floquet_multipliers=[[z.real, z.imag] for z in exact.multipliers],
                 pieces=[dict(start=q["tau"], duration=q["h"], a=q["A"].tolist())
                         for q in pieces]),
        alpha={k: dict(alpha=e["alpha"], alpha_effective=e["alpha_effective"])
               for k, e in estimates.items() if "alpha" in e},
        fit=fits, errors=errors, aliasing=alias,
        timings_ms=timings,
    )
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2))
    return summary, exact, estimates


# --------------------------------------------------------------------------------------------
# --check: the same work as the Rust run
# --------------------------------------------------------------------------------------------

def check(summary, exact, estimates, rust_summary):
    rs = json.loads(Path(rust_summary).read_text())
    rdir = Path(rust_summary).parent
    ok = True

    def cmp(label, mine, theirs, tol, rel=True):
        nonlocal ok
        err = abs(mine - theirs) / (abs(theirs) if rel and theirs != 0 else 1.0)
        good = err <= tol
        ok &= good
        print(f"  {label:44s} numpy {mine: .10g}   rust {theirs: .10g}   "
              f"{'rel' if rel else 'abs'} diff {err:.1e} {'ok' if good else 'MISMATCH'}")

    print(f"\ncheck against {rust_summary}")
    lc, rlc = summary["limit_cycle"], rs["limit_cycle"]
    cmp("limit cycle x(0)", lc["state_phase0"][0], rlc["state_phase0"][0], 1e-9)
    cmp("limit cycle t_on", lc["t_on"], rlc["t_on"], 1e-9)
    cmp("limit cycle t_off", lc["t_off"], rlc["t_off"], 1e-9)
    cmp("|Floquet multiplier|", math.hypot(*lc["floquet_multipliers"][0]),
        math.hypot(*rlc["floquet_multipliers"][0]), 1e-8)
    cmp("switches in the record", summary["simulation"]["switches"],
        rs["simulation"]["switches"], 0.0)
    for name in summary["fit"]:
        f, rf = summary["fit"][name], rs["fit"][name]
        cmp(f"fit ({name}) points", f["points"], rf["points"], 0.0)
        cmp(f"fit ({name}) k", f["k"], rf["k"], 1e-6)
        cmp(f"fit ({name}) c", f["c"], rf["c"], 1e-5)
        cmp(f"fit ({name}) k_stderr", f["k_stderr"], rf["k_stderr"], 1e-2)
        cmp(f"fit ({name}) c_stderr", f["c_stderr"], rf["c_stderr"], 1e-2)
    for name in summary["errors"]:
        for n in ("-2", "0", "2"):
            e, re_ = summary["errors"][name][n], rs["errors"][name][n]
            cmp(f"errors ({name}) G_{n} max", e["max"], re_["max"], 1e-3)
            cmp(f"errors ({name}) G_{n} median", e["median"], re_["median"], 1e-3)
            cmp(f"errors ({name}) G_{n} points", e["points"], re_["points"], 0.0)
    if "siddiqi" in summary["alpha"]:
        cmp("Siddiqi alpha_effective", summary["alpha"]["siddiqi"]["alpha_effective"],
            rs["alpha"]["siddiqi"]["alpha_effective"], 1e-8)
    for n in ("-2", "2"):
        a, ra = summary["aliasing"]["by_harmonic"][n], rs["aliasing"]["by_harmonic"][n]
        cmp(f"aliasing G_{n} relative", a["aliases"][0]["relative_to_estimated"],
            ra["aliases"][0]["relative_to_estimated"], 1e-8)
    # A few HTF values against the Rust CSVs (when the Rust run wrote them).
    th = rdir / "theory.csv"
    if th.exists():
        r = np.loadtxt(th, delimiter=",", skiprows=1)
        g = exact.g(r[:, 1], r[:, 0])
        rv = r[:, 2] + 1j * r[:, 3]
        worst = max((np.abs(g - rv)[r[:, 1] == n].max() / np.abs(rv[r[:, 1] == n]).max())
                    for n in np.unique(r[:, 1]))
        cmp(f"theory.csv: all {r.shape[0]} exact G_n, max |diff|/max|G_n|", worst, 0.0, 1e-8,
            rel=False)
    for name, e in estimates.items():
        path = rdir / f"estimate_{name}.csv"
        if not path.exists():
            continue
        r = np.loadtxt(path, delimiter=",", skiprows=1)
        H, M = len(e["values"]), e["omega"].size
        if r.shape[0] != H * M:
            print(f"  {name}: {H * M} rows, rust {r.shape[0]}  MISMATCH")
            ok = False
            continue
        rv = (r[:, 2] + 1j * r[:, 3]).reshape(H, M)
        scale = np.abs(rv).max(axis=1)
        cmp(f"{name}: omega grid, max |diff|", np.abs(e["omega"] - r[:M, 0]).max(), 0.0, 1e-12,
            rel=False)
        worst = (np.abs(e["values"] - rv) / scale[:, None]).max()
        cmp(f"{name}: all {H * M} G_n, max |diff|/max|G_n|", worst, 0.0, 1e-4, rel=False)
        sd = r[:, 4].reshape(H, M)
        cmp(f"{name}: all stderr, max rel diff", (np.abs(e["stderr"] - sd) / sd).max(), 0.0, 1e-4,
            rel=False)
        for i in np.linspace(0, H * M - 1, 4).astype(int):
            h, k = divmod(i, M)
            print(f"    G_{int(r[i, 1])}({r[i, 0]:.4f} rad/s): numpy {e['values'][h, k]:.8e}"
                  f"  rust {rv[h, k]:.8e}")
    print("check:", "all within tolerance" if ok else "MISMATCHES above")
    return ok


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("config", nargs="?", default=str(DEFAULT_CONFIG))
    ap.add_argument("--out", default="/tmp/np-bench-python")
    ap.add_argument("--check", nargs="?", const="/tmp/np-bench-rust/summary.json", default=None,
                    metavar="RUST_SUMMARY")
    args = ap.parse_args()
    cfg = load_config(args.config)
    summary, exact, estimates = run(cfg, Path(args.out))
    print(f"{'stage':28s} {'ms':>10s}")
    for k, v in summary["timings_ms"].items():
        print(f"{k:28s} {v:10.1f}")
    sim = summary["simulation"]
    print(f"\nsimulation: {sim['samples']} samples, {sim['switches']} switches, "
          f"{sim['rhs_evaluations']} rhs evaluations")
    for name, f in summary["fit"].items():
        print(f"fit ({name}): k = {f['k']:.6f} +- {f['k_stderr']:.3g}, "
              f"c = {f['c']:.6f} +- {f['c_stderr']:.3g}  "
              f"({f['points']} points, {f['evaluations']} model evaluations)")
    if args.check:
        if not check(summary, exact, estimates, args.check):
            sys.exit(1)


if __name__ == "__main__":
    main()
