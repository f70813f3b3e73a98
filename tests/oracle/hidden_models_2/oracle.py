#!/usr/bin/env python3
"""Independent oracle for three hidden htfid models, second round:
actuator_brake, clearance_stops, ball_on_paddle.

Written from the mathematics and docs/models.md only (numpy/scipy); it shares no code with htfid.
Run:  python3 oracle.py [model ...]   (deterministic; writes <name>.json next to this file)

HTF convention (docs/outputs.md, the same as ../hidden_models):
Y(jw) = sum_n G_n(jw) U(jw - j n wp),  wp = 2 pi / T,  i.e. G_n(jw) maps an input component
exp(j (w - n wp) t) to the output component exp(j w t); w is the OUTPUT frequency.  For
u = exp(j W t) the steady small-signal output is sum_n G_n(j (W + n wp)) exp(j (W + n wp) t).
"""
import json
import os
import sys
import time

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import expm
from scipy.optimize import brentq

HERE = os.path.dirname(os.path.abspath(__file__))
HARMONICS = [-2, -1, 0, 1, 2]
Q_WINDOW = 16          # brute-force analysis window, in forcing periods
RTOL, ATOL = 1e-12, 1e-13


def cplx(z):
    return [float(np.real(z)), float(np.imag(z))]


def floq_sorted(M):
    ev = np.linalg.eigvals(M)
    return sorted(ev, key=lambda z: (-abs(z), -np.imag(z)))


def int_expm(At, L):
    """int_0^L expm(At s) ds, via the augmented exponential."""
    n = At.shape[0]
    big = np.zeros((2 * n, 2 * n), dtype=complex)
    big[:n, :n] = At
    big[:n, n:] = np.eye(n)
    return expm(big * L)[:n, n:]


def int_exp(nw, t0, t1):
    """int_{t0}^{t1} exp(-j nw t) dt"""
    if nw == 0.0:
        return t1 - t0
    return (np.exp(-1j * nw * t1) - np.exp(-1j * nw * t0)) / (-1j * nw)


def affine_expm(A, c, L):
    """(expm(A L), int_0^L expm(A s) ds c): the flow of x' = A x + c over L."""
    n = A.shape[0]
    big = np.zeros((n + 1, n + 1))
    big[:n, :n] = A
    big[:n, n] = c
    E = expm(big * L)
    return E[:n, :n], E[:n, n]


# --------------------------------------------------------------------------------------
# Piecewise-LTI periodic response to u = exp(j W t) with a periodic input gain
# B(t) = sum_k B_k exp(j k wp t) and a periodic feedthrough D(t) = sum_k D_k exp(j k wp t)
# --------------------------------------------------------------------------------------
def pw_response(T, segs, jumps, W, harmonics, outputs):
    """segs: list of (t0, t1, A, Bk) covering [0, T], Bk a dict k -> vector (the Fourier
    coefficients of B(t)); jumps[i] is the saltation matrix between segs[i] and segs[i+1];
    outputs: list of (C_per_seg, Dk) with Dk a dict k -> scalar.
    The periodic response is dx(t) = sum_k g_k exp(j(W + k wp) t) + expm(A (t - t0)) h per
    segment, g_k = (j(W + k wp) I - A)^{-1} B_k.
    Returns dx(0), the monodromy and q[o][n] = G_n(j(W + n wp)) of output o."""
    wp = 2 * np.pi / T
    n = segs[0][2].shape[0]
    I = np.eye(n)
    P = I.astype(complex)
    p = np.zeros(n, dtype=complex)
    seg_data = []
    for i, (t0, t1, A, Bk) in enumerate(segs):
        gk = {k: np.linalg.solve(1j * (W + k * wp) * I - A, np.asarray(b, complex)) for k, b in Bk.items()}
        xp = lambda t, gk=gk: sum(g * np.exp(1j * (W + k * wp) * t) for k, g in gk.items())
        seg_data.append((P.copy(), p.copy(), gk, xp))
        E = expm(A * (t1 - t0))
        P_end = E @ P
        p_end = xp(t1) + E @ (p - xp(t0))
        if i < len(segs) - 1:
            P_end = jumps[i] @ P_end
            p_end = jumps[i] @ p_end
        P, p = P_end, p_end
    M, r = P, p
    dx0 = np.linalg.solve(np.exp(1j * W * T) * I - M, r)
    q = []
    for (Cs, Dk) in outputs:
        qo = {}
        for hn in harmonics:
            Wn = W + hn * wp
            acc = 0.0 + 0.0j
            for i, (t0, t1, A, Bk) in enumerate(segs):
                Pi, pi_, gk, xp = seg_data[i]
                C = np.asarray(Cs[i], float)
                h = Pi @ dx0 + pi_ - xp(t0)
                for k, g in gk.items():
                    acc += (C @ g) * int_exp((hn - k) * wp, t0, t1)
                acc += np.exp(-1j * Wn * t0) * (C @ (int_expm(A - 1j * Wn * I, t1 - t0) @ h))
            qo[hn] = acc / T + Dk.get(hn, 0.0)
        q.append(qo)
    return dx0, M, q


# --------------------------------------------------------------------------------------
# Generic event-located hybrid simulator (the numerical methods)
# --------------------------------------------------------------------------------------
class Hybrid:
    """modes: {name: dict(f=f(t,x,u), J=J(t,x) (df/dx at u=0), B=B(t,x) (df/du at u=0))}
    guards: list of dicts: frm, to, h(t,x), dh(t,x) (grad_x h), ht(t,x) (dh/dt), direction
            (+1 rising / -1 falling), R(t,x), DR(t,x), Rt(t,x) (dR/dt), surface (True for a
            reset-free pair on one expression: a switching surface, where Filippov sliding
            is possible)
    outputs: list of (name, y(t,x,u,mode), C(t,x,mode), D(t,x)).  y takes the mode so that an
    output written with max/min/abs, whose kink lies exactly on a guard, is integrated with the
    expression of the current mode (identical on the trajectory, where the mode matches the
    region): a DOP853 step that overshoots an event then sees no kink, and the dense output
    at the located event keeps its accuracy."""

    def __init__(self, n, modes, guards, outputs, T):
        self.n, self.modes, self.guards, self.outputs, self.T = n, modes, guards, outputs, T

    def f(self, mode, t, x, u=0.0):
        return np.asarray(self.modes[mode]['f'](t, x, u), float)

    def saltation(self, g, t, xm, m_from):
        """S = DR + (f+ - DR f- - dR/dt) grad(h)^T / (grad(h) . f- + dh/dt)"""
        f_m = self.f(m_from, t, xm)
        xp = np.asarray(g['R'](t, xm), float)
        f_p = self.f(g['to'], t, xp)
        DR = np.asarray(g['DR'](t, xm), float)
        Rt = np.asarray(g['Rt'](t, xm), float)
        dh = np.asarray(g['dh'](t, xm), float)
        den = dh @ f_m + g['ht'](t, xm)
        return DR + np.outer(f_p - DR @ f_m - Rt, dh) / den

    def run(self, x0, mode, t0, t1, u=lambda t: 0.0, extra0=None, extra_rhs=None,
            jump_extra=None, events_out=None, allow_sliding=False, dense_out=None, rtol=RTOL,
            atol=ATOL):
        """Integrate [x, extra] from t0 to t1 (DOP853, events located on the dense output).
        extra_rhs(t, x, e, mode) -> de/dt;  jump_extra(S, e) -> e after a transition.
        A crossing of a switching surface whose far-side flow points back into it starts a
        Filippov sliding motion: allowed only with allow_sliding (settling from rough starts),
        an error otherwise (the orbit itself must not slide)."""
        n = self.n
        x = np.array(x0, float)
        e = np.zeros(0) if extra0 is None else np.array(extra0, float)
        t = t0
        count = 0
        while t < t1:
            fm = self.modes[mode]['f']
            my_guards = [g for g in self.guards if g['frm'] == mode]

            def rhs(tt, s, fm=fm, mode=mode):
                xx = s[:n]
                dx = fm(tt, xx, u(tt))
                if extra_rhs is None:
                    return dx
                return np.concatenate([dx, extra_rhs(tt, xx, s[n:], mode)])
            evs = []
            for g in my_guards:
                def ev(tt, s, g=g):
                    return g['h'](tt, s[:n])
                ev.terminal = True
                ev.direction = g['direction']
                evs.append(ev)
            sol = solve_ivp(rhs, (t, t1), np.concatenate([x, e]), method='DOP853', rtol=rtol,
                            atol=atol, events=evs if evs else None, dense_output=dense_out is not None)
            if dense_out is not None:
                dense_out.append((t, sol.t[-1], mode, sol.sol))
            if sol.status == 1:
                k = next(i for i, te in enumerate(sol.t_events) if len(te))
                te = sol.t_events[k][0]
                s = sol.y_events[k][0]
                g = my_guards[k]
                xm = s[:n]
                x = np.asarray(g['R'](te, xm), float)
                e = s[n:]
                t = te
                count += 1
                if count > 200000:
                    raise RuntimeError('too many events (Zeno?)')
                if g.get('surface'):
                    dh = np.asarray(g['dh'](te, x))
                    far = g['direction'] * (dh @ np.asarray(self.modes[g['to']]['f'](te, x, u(te)))
                                            + g['ht'](te, x))
                    if far < 0:
                        if not allow_sliding:
                            raise RuntimeError(f'sliding on {g["frm"]}->{g["to"]} at t = {te}')
                        mode = self._slide(g, x, te, t1, u)
                        x, t = self._slide_state
                        continue
                S = self.saltation(g, te, xm, mode)
                if jump_extra is not None:
                    e = jump_extra(S, e)
                if events_out is not None:
                    events_out.append(dict(t=te, frm=mode, to=g['to'], name=g.get('name'),
                                           x_before=xm.copy(), x_after=x.copy(), S=S))
                mode = g['to']
            elif sol.status == 0:
                x = sol.y[:n, -1]
                e = sol.y[n:, -1]
                t = t1
            else:
                raise RuntimeError(sol.message)
        return x, mode, e

    def _slide(self, g, x, t, t1, u):
        """Filippov sliding along the surface of guard g (no extra states): the convex
        combination of the two flows that keeps h = 0, until one side's flow leaves."""
        ma, mb = g['frm'], g['to']
        fa = self.modes[ma]['f']
        fb = self.modes[mb]['f']

        def rates(tt, s):
            d = np.asarray(g['dh'](tt, s))
            return d @ fa(tt, s, u(tt)) + g['ht'](tt, s), d @ fb(tt, s, u(tt)) + g['ht'](tt, s)

        def fs(tt, s):
            ra, rb = rates(tt, s)
            al = rb / (rb - ra)
            return al * fa(tt, s, u(tt)) + (1 - al) * fb(tt, s, u(tt))
        e1 = lambda tt, s: rates(tt, s)[0]
        e1.terminal = True
        e2 = lambda tt, s: rates(tt, s)[1]
        e2.terminal = True
        sol = solve_ivp(fs, (t, t1), x, method='DOP853', rtol=RTOL, atol=ATOL, events=[e1, e2])
        self._slide_state = (sol.y[:, -1], sol.t[-1])
        if sol.status == 1:
            kk = next(i for i, te in enumerate(sol.t_events) if len(te))
            return ma if kk == 0 else mb     # the side whose flow turned away from the surface
        return ma

    def period_map(self, x0, mode, t0=0.0):
        n = self.n

        def erhs(t, x, e, md):
            Phi = e.reshape(n, n)
            return (np.asarray(self.modes[md]['J'](t, x)) @ Phi).ravel()
        jump = lambda S, e: (S @ e.reshape(n, n)).ravel()
        evs = []
        x1, m1, e1 = self.run(x0, mode, t0, t0 + self.T, extra0=np.eye(n).ravel(),
                              extra_rhs=erhs, jump_extra=jump, events_out=evs)
        return x1, m1, e1.reshape(n, n), evs

    def find_orbit(self, x0, mode, settle=60, tol=1e-13):
        x, m, _ = self.run(x0, mode, 0.0, settle * self.T, allow_sliding=True)
        for it in range(40):
            x1, m1, M, evs = self.period_map(x, m)
            res = x1 - x
            if np.max(np.abs(res)) < tol:
                break
            x = x + np.linalg.solve(np.eye(self.n) - M, res)
        x1, m1, M, evs = self.period_map(x, m)
        return x, m, M, evs, float(np.max(np.abs(x1 - x))), m1

    def fd_monodromy(self, x0, mode, h=1e-6):
        n = self.n
        M = np.zeros((n, n))
        for i in range(n):
            d = np.zeros(n)
            d[i] = h * max(1.0, abs(x0[i]))
            xp, _, _ = self.run(x0 + d, mode, 0.0, self.T)
            xm, _, _ = self.run(x0 - d, mode, 0.0, self.T)
            M[:, i] = (xp - xm) / (2 * d[i])
        return M

    # (a1) periodic response of the variational equations, integrated numerically
    def htf_variational(self, x0, mode, W, harmonics):
        n, T = self.n, self.T
        wp = 2 * np.pi / T
        no = len(self.outputs)
        nh = len(harmonics)
        iPhi = slice(0, n * n)
        idp = slice(n * n, n * n + 2 * n)
        base = n * n + 2 * n
        nZP = no * nh * n
        iZPhi = slice(base, base + 2 * nZP)
        iZp = slice(base + 2 * nZP, base + 2 * nZP + 2 * no * nh)
        size = base + 2 * nZP + 2 * no * nh
        Wn = np.array([W + hn * wp for hn in harmonics])

        def erhs(t, x, e, md):
            J = np.asarray(self.modes[md]['J'](t, x))
            B = np.asarray(self.modes[md]['B'](t, x))
            Phi = e[iPhi].reshape(n, n)
            dp = e[idp][:n] + 1j * e[idp][n:]
            out = np.zeros(size)
            out[iPhi] = (J @ Phi).ravel()
            ddp = J @ dp + B * np.exp(1j * W * t)
            out[idp] = np.concatenate([ddp.real, ddp.imag])
            ph = np.exp(-1j * Wn * t) / T
            zphi = np.zeros((no, nh, n), complex)
            zp = np.zeros((no, nh), complex)
            for o, (_, y, C, D) in enumerate(self.outputs):
                Cv = np.asarray(C(t, x, md), float)
                Dv = D(t, x)
                zphi[o] = np.outer(ph, Cv @ Phi)
                zp[o] = ph * (Cv @ dp + Dv * np.exp(1j * W * t))
            out[iZPhi] = np.concatenate([zphi.ravel().real, zphi.ravel().imag])
            out[iZp] = np.concatenate([zp.ravel().real, zp.ravel().imag])
            return out

        def jump(S, e):
            e = e.copy()
            e[iPhi] = (S @ e[iPhi].reshape(n, n)).ravel()
            dp = S @ (e[idp][:n] + 1j * e[idp][n:])
            e[idp] = np.concatenate([dp.real, dp.imag])
            return e
        e0 = np.zeros(size)
        e0[iPhi] = np.eye(n).ravel()
        x1, m1, e1 = self.run(x0, mode, 0.0, T, extra0=e0, extra_rhs=erhs, jump_extra=jump)
        M = e1[iPhi].reshape(n, n)
        r = e1[idp][:n] + 1j * e1[idp][n:]
        dx0 = np.linalg.solve(np.exp(1j * W * T) * np.eye(n) - M, r)
        zphi = (e1[iZPhi][:nZP] + 1j * e1[iZPhi][nZP:]).reshape(no, nh, n)
        zp = (e1[iZp][:no * nh] + 1j * e1[iZp][no * nh:]).reshape(no, nh)
        q = zp + zphi @ dx0
        return [{hn: q[o, i] for i, hn in enumerate(harmonics)} for o in range(no)]

    # (b) brute force: nonlinear simulation with u = +-eps cos(W t)
    def htf_bruteforce(self, x0, mode, W, harmonics, eps, settle, Q=Q_WINDOW):
        T = self.T
        wp = 2 * np.pi / T
        no = len(self.outputs)
        Wn = np.array([W + hn * wp for hn in harmonics])
        nh = len(harmonics)
        t_a, t_b = settle * T, (settle + Q) * T
        L = t_b - t_a
        res = []
        for sgn in (+1.0, -1.0):
            uf = lambda t, s=sgn: s * eps * np.cos(W * t)
            xs, ms, _ = self.run(x0, mode, 0.0, t_a, u=uf)

            def erhs(t, x, e, md, uf=uf):
                ph = np.exp(-1j * Wn * t) / L
                z = np.array([[y(t, x, uf(t), md) for (_, y, C, D) in self.outputs]]).T * ph[None, :]
                z = z.ravel()
                return np.concatenate([z.real, z.imag])
            x2, m2, e2 = self.run(xs, ms, t_a, t_b, u=uf, extra0=np.zeros(2 * no * nh),
                                  extra_rhs=erhs)
            res.append((e2[:no * nh] + 1j * e2[no * nh:]).reshape(no, nh))
        G = (res[0] - res[1]) / eps
        return [{hn: G[o, i] for i, hn in enumerate(harmonics)} for o in range(no)]

    def multistart(self, starts, x0, mode0, periods):
        """Simulate from each (state, mode) for `periods` periods (sliding allowed) and return
        the distance of the final state from the orbit state at phase 0 and the final mode."""
        out = []
        for (xs, ms) in starts:
            try:
                x, m, _ = self.run(np.array(xs, float), ms, 0.0, periods * self.T, allow_sliding=True)
            except RuntimeError as ex:
                out.append(dict(start=list(map(float, xs)), start_mode=ms, distance=float('inf'),
                                final_mode=None, converged=False, error=str(ex)))
                continue
            out.append(dict(start=list(map(float, xs)), start_mode=ms,
                            distance=float(np.max(np.abs(x - x0))), final_mode=m,
                            converged=bool(np.max(np.abs(x - x0)) < 1e-6 and m == mode0)))
        return out


def out_grid(T, js, Q=Q_WINDOW):
    wp = 2 * np.pi / T
    return [wp * j / Q for j in js]


def fourier_coeffs(fun, T, Nf=512, K=80):
    """c_k = (1/T) int_0^T fun(t) exp(-j k wp t) dt for |k| <= K (trapezoid = exact for
    band-limited, exponentially accurate for analytic periodic functions); returns the dict and
    the tail |c_K| relative to max |c_k| as a resolution check."""
    t = np.arange(Nf) * T / Nf
    c = np.fft.fft(fun(t)) / Nf
    d = {k: complex(c[k % Nf]) for k in range(-K, K + 1)}
    tail = max(abs(d[K]), abs(d[-K]), abs(c[Nf // 2])) / max(abs(v) for v in d.values())
    return d, float(tail)


# --------------------------------------------------------------------------------------
# Model 1: actuator_brake
# --------------------------------------------------------------------------------------
def actuator_brake():
    P = dict(m=1.0, k=25.0, c1=0.3, c2=2.5, Fb=3.0, vs=0.5, tau=0.2, amax=8.0, A=12.0, T=1.2)
    m, k, c1, c2, Fb, vs, tau, amax, Af, T = (P[s] for s in
                                              ('m', 'k', 'c1', 'c2', 'Fb', 'vs', 'tau', 'amax', 'A', 'T'))
    wp = 2 * np.pi / T
    e1, e2, e3 = np.eye(3)
    A_slow = np.array([[0, 1, 0], [-k / m, -c1 / m, 1 / m], [0, 0, -1 / tau]])
    A_fast = np.array([[0, 1, 0], [-k / m, -c2 / m, 1 / m], [0, 0, -1 / tau]])
    c_slow = np.zeros(3)
    c_fast = np.array([0.0, -Fb / m, 0.0])
    drive = lambda t: amax * np.tanh(Af * np.cos(wp * t) / amax)
    gain = lambda t: 1.0 / np.cosh(Af * np.cos(wp * t) / amax) ** 2     # d drive / d u
    dk, tail_d = fourier_coeffs(drive, T)
    sk, tail_s = fourier_coeffs(gain, T)
    checks = [dict(name='Fourier series of the saturated drive amax tanh(f0/amax) and of its gain '
                   'sech^2(f0/amax): tail |c_80| / max |c_k| (truncation)', value=max(tail_d, tail_s),
                   tolerance=1e-15, passed=bool(max(tail_d, tail_s) < 1e-15))]

    # periodic particular solution of s' = A_i s + e3 drive(t)/tau + c_i, as a Fourier series
    def partsol(Ai, ci):
        coef = {}
        for kk, d in dk.items():
            rhs = e3 * d / tau + (ci if kk == 0 else 0.0)
            coef[kk] = np.linalg.solve(1j * kk * wp * np.eye(3) - Ai, rhs)
        ks = np.array(list(coef.keys()))
        cm = np.array(list(coef.values()))          # (K, 3)

        def p(t):
            ph = np.exp(1j * wp * np.multiply.outer(np.atleast_1d(t), ks))
            val = np.real(ph @ cm)
            return val if np.ndim(t) else val[0]
        return p
    p_slow = partsol(A_slow, c_slow)
    p_fast = partsol(A_fast, c_fast)
    seg = {'slow': (A_slow, p_slow, c_slow), 'fast': (A_fast, p_fast, c_fast)}

    def flow(md, s0, t0, t1):
        Ai, p, _ = seg[md]
        return p(t1) + expm(Ai * (t1 - t0)) @ (s0 - p(t0))

    def fmode(md, t, s):
        Ai, _, ci = seg[md]
        return Ai @ s + ci + e3 * drive(t) / tau

    # mode sequence over [0, T): fast on [0, t_dn], slow on [t_dn, t_up], fast on [t_up, T]
    def periodic(tdn, tup):
        Phi = expm(A_fast * (T - tup)) @ expm(A_slow * (tup - tdn)) @ expm(A_fast * tdn)
        z = flow('fast', flow('slow', flow('fast', np.zeros(3), 0.0, tdn), tdn, tup), tup, T)
        s0 = np.linalg.solve(np.eye(3) - Phi, z)
        sdn = flow('fast', s0, 0.0, tdn)
        sup = flow('slow', sdn, tdn, tup)
        return s0, sdn, sup

    def resid(tt):
        _, sdn, sup = periodic(*tt)
        return np.array([sdn[1] - vs, sup[1] - vs])

    # ---- numerical hybrid model (for the start of the closed form and the checks)
    def mkf(c, F):
        return lambda t, x, u: np.array([x[1], (-k * x[0] - c * x[1] - F + x[2]) / m,
                                         (amax * np.tanh((Af * np.cos(wp * t) + u) / amax) - x[2]) / tau])
    Bf = lambda t, x: e3 * gain(t) / tau
    modes = {'slow': dict(f=mkf(c1, 0.0), J=lambda t, x: A_slow, B=Bf),
             'fast': dict(f=mkf(c2, Fb), J=lambda t, x: A_fast, B=Bf)}
    common = dict(h=lambda t, x: x[1] - vs, dh=lambda t, x: e2, ht=lambda t, x: 0.0,
                  R=lambda t, x: np.array(x), DR=lambda t, x: np.eye(3), Rt=lambda t, x: np.zeros(3),
                  surface=True)
    guards = [dict(common, name='brake_on', frm='slow', to='fast', direction=+1),
              dict(common, name='brake_off', frm='fast', to='slow', direction=-1)]
    outputs = [('x', lambda t, x, u, md: x[0], lambda t, x, md: e1, lambda t, x: 0.0),
               ('a', lambda t, x, u, md: x[2], lambda t, x, md: e3, lambda t, x: 0.0),
               ('drive', lambda t, x, u, md: amax * np.tanh((Af * np.cos(wp * t) + u) / amax),
                lambda t, x, md: np.zeros(3), lambda t, x: gain(t))]
    H = Hybrid(3, modes, guards, outputs, T)
    init_guess, init_mode = np.zeros(3), 'slow'
    xn, mn, Mn, evs, resid_n, _ = H.find_orbit(init_guess, init_mode, settle=60)
    assert mn == 'fast' and [e_['frm'] for e_ in evs] == ['fast', 'slow'], (mn, evs)
    tt = np.array([evs[0]['t'], evs[1]['t']])
    # ---- closed form: Newton on the two switching times
    for it in range(20):
        r = resid(tt)
        if np.max(np.abs(r)) < 1e-15:
            break
        Jt = np.zeros((2, 2))
        for i in range(2):
            d = np.zeros(2)
            d[i] = 1e-7
            Jt[:, i] = (resid(tt + d) - resid(tt - d)) / 2e-7
        tt = tt - np.linalg.solve(Jt, r)
    r_final = float(np.max(np.abs(resid(tt))))
    tdn, tup = tt
    x0, sdn, sup = periodic(tdn, tup)
    checks.append(dict(name='closed form: |v(t_switch) - vs| at the two switching times after Newton',
                       value=r_final, tolerance=1e-13, passed=bool(r_final < 1e-13)))
    # admissibility: v > vs on the fast segments, v < vs on the slow one; no extremum of v near vs
    worst_side, near = np.inf, np.inf
    for (md, ta, tb, sa, sign) in (('fast', 0.0, tdn, x0, +1), ('slow', tdn, tup, sdn, -1),
                                   ('fast', tup, T, sup, +1)):
        ts = np.linspace(ta, tb, 2001)
        Ai, p, ci = seg[md]
        Ed = expm(Ai * (ts[1] - ts[0]))
        pts = p(ts)
        hs = [sa - pts[0]]
        for i in range(1, len(ts)):
            hs.append(Ed @ hs[-1])
        st = pts + np.array(hs)                  # the closed-form trajectory on the grid
        st, ts = st[1:-1], ts[1:-1]
        vv = st[:, 1]
        worst_side = min(worst_side, float(np.min(sign * (vv - vs))))
        acc = np.array([fmode(md, t_, s_)[1] for t_, s_ in zip(ts, st)])
        for i in np.nonzero(acc[:-1] * acc[1:] < 0)[0]:
            near = min(near, abs(vv[i] - vs))
    checks.append(dict(name='closed form: orbit on the right side of v = vs in every segment '
                       '(min of (v - vs) sign(mode) on a 2000-point grid per segment)', value=worst_side,
                       tolerance='> 0', passed=bool(worst_side > 0)))
    checks.append(dict(name='no grazing: |v - vs| at the interior extrema of v', value=near,
                       tolerance='> 0.5 m/s', passed=bool(near > 0.5)))
    # transversality, no sliding: v' on both sides of each switch has the direction of the crossing
    trans = []
    for (t_, s_, frm, to, d) in ((tdn, sdn, 'fast', 'slow', -1), (tup, sup, 'slow', 'fast', +1)):
        a_from = fmode(frm, t_, s_)[1]
        a_to = fmode(to, t_, s_)[1]
        trans.append(dict(time=float(t_), mode_from=frm, mode_to=to, vdot_from=float(a_from),
                          vdot_to=float(a_to)))
    margin = min(min(d * tr['vdot_from'], d * tr['vdot_to'])
                 for tr, d in zip(trans, (-1, +1)))
    checks.append(dict(name='transversal crossings, no sliding: smallest |v\'| on either side of a '
                       'switch, in the crossing direction', value=float(margin),
                       tolerance='> 2 m/s^2', passed=bool(margin > 2), detail=trans))
    # monodromy, closed form
    S_dn = np.eye(3) + np.outer(fmode('slow', tdn, sdn) - fmode('fast', tdn, sdn), e2) / fmode('fast', tdn, sdn)[1]
    S_up = np.eye(3) + np.outer(fmode('fast', tup, sup) - fmode('slow', tup, sup), e2) / fmode('slow', tup, sup)[1]
    M = expm(A_fast * (T - tup)) @ S_up @ expm(A_slow * (tup - tdn)) @ S_dn @ expm(A_fast * tdn)
    mu = floq_sorted(M)
    liou = (np.exp(np.trace(A_fast) * (T - (tup - tdn)) + np.trace(A_slow) * (tup - tdn))
            * (fmode('slow', tdn, sdn)[1] / fmode('fast', tdn, sdn)[1])
            * (fmode('fast', tup, sup)[1] / fmode('slow', tup, sup)[1]))

    def main_htf(W, hn):
        Bk = {kk: e3 * s / tau for kk, s in sk.items()}
        segs = [(0.0, tdn, A_fast, Bk), (tdn, tup, A_slow, Bk), (tup, T, A_fast, Bk)]
        _, _, q = pw_response(T, segs, [S_dn, S_up], W, [hn],
                              [([e1] * 3, {}), ([e3] * 3, {}), ([np.zeros(3)] * 3, sk)])
        return [q[o][hn] for o in range(3)]
    events = [dict(kind='brake_off: fast -> slow (v falls through vs)', time_in_period=tdn,
                   state=sdn.tolist(), saltation=S_dn.tolist(), vdot_before=trans[0]['vdot_from'],
                   vdot_after=trans[0]['vdot_to']),
              dict(kind='brake_on: slow -> fast (v rises through vs)', time_in_period=tup,
                   state=sup.tolist(), saltation=S_up.tolist(), vdot_before=trans[1]['vdot_from'],
                   vdot_after=trans[1]['vdot_to'])]
    starts = [([0.0, 0.0, 0.0], 'slow'), ([0.5, 2.0, 3.0], 'fast'), ([-0.5, -3.0, -5.0], 'slow'),
              ([1.0, 0.0, 0.0], 'slow'), ([0.0, 0.6, 8.0], 'fast'), ([-1.0, 0.5, -8.0], 'slow')]
    return finish('actuator_brake', P, H, x0, 'fast', M, mu, checks, main_htf=main_htf,
                  htf_method=('semi-closed form: the actuator drive and the input gain sech^2(f0/amax) as '
                              'Fourier series (|k| <= 80, exact to round-off), piecewise matrix '
                              'exponentials with exact Fourier integrals, saltation matrix at each switch'),
                  orbit_method=('semi-closed form: per mode the periodic particular solution (Fourier series '
                                'of the drive) plus matrix exponentials; the two switching times solved by '
                                'Newton to |v - vs| < 1e-13; checked by event-located DOP853 shooting'),
                  js=[3, 11, 15, 21, 45], eps=1e-3, init_guess=init_guess, init_mode=init_mode,
                  liouville=liou, state_names=['x', 'v', 'a'], output_names=['x', 'a', 'drive'],
                  starts=starts, has_primary_orbit=True,
                  extra=dict(switch_times=dict(brake_off=tdn, brake_on=tup), events=events))


# --------------------------------------------------------------------------------------
# Chebyshev collocation (piecewise, one polynomial per segment between events)
# --------------------------------------------------------------------------------------
def cheb(N):
    """Chebyshev-Gauss-Lobatto nodes on [-1, 1] in ascending order and the differentiation
    matrix (Trefethen, Spectral Methods in MATLAB, cheb.m), and Clenshaw-Curtis weights."""
    x = np.cos(np.pi * np.arange(N + 1) / N)
    c = np.hstack([2.0, np.ones(N - 1), 2.0]) * (-1.0) ** np.arange(N + 1)
    X = np.tile(x, (N + 1, 1)).T
    dX = X - X.T
    D = np.outer(c, 1.0 / c) / (dX + np.eye(N + 1))
    D = D - np.diag(D.sum(axis=1))
    # Clenshaw-Curtis (clencurt.m)
    theta = np.pi * np.arange(N + 1) / N
    w = np.zeros(N + 1)
    ii = np.arange(1, N)
    v = np.ones(N - 1)
    if N % 2 == 0:
        w[0] = w[N] = 1.0 / (N ** 2 - 1)
        for kk in range(1, N // 2):
            v -= 2 * np.cos(2 * kk * theta[ii]) / (4 * kk ** 2 - 1)
        v -= np.cos(N * theta[ii]) / (N ** 2 - 1)
    else:
        w[0] = w[N] = 1.0 / N ** 2
        for kk in range(1, (N - 1) // 2 + 1):
            v -= 2 * np.cos(2 * kk * theta[ii]) / (4 * kk ** 2 - 1)
    w[ii] = 2 * v / N
    return x[::-1].copy(), D[::-1, ::-1].copy(), w[::-1].copy()


class Collocation:
    """Periodic orbit, monodromy and HTFs of a hybrid system with identity resets, by
    Chebyshev collocation on each segment between events (event times are unknowns)."""

    def __init__(self, H, seq, guards, N, fvec):
        """seq: modes of the segments of [0, T] in order; guards: the guard dicts between them;
        fvec[mode](t, X) vectorised field (X: (npts, n))."""
        self.H, self.seq, self.gs, self.N, self.fvec = H, seq, guards, N, fvec
        self.xi, self.D, self.w = cheb(N)
        self.ns = len(seq)
        self.n = H.n

    def unpack(self, z):
        n, N, ns = self.n, self.N, self.ns
        X = z[:ns * (N + 1) * n].reshape(ns, N + 1, n)
        tb = np.concatenate([[0.0], z[ns * (N + 1) * n:], [self.H.T]])
        return X, tb

    def nodes(self, tb, s):
        L = tb[s + 1] - tb[s]
        return tb[s] + (self.xi + 1) * L / 2, L

    def residual(self, z):
        X, tb = self.unpack(z)
        res = []
        for s, md in enumerate(self.seq):
            t, L = self.nodes(tb, s)
            F = (2 / L) * (self.D @ X[s]) - self.fvec[md](t, X[s])
            res.append(F[1:].ravel())
            prev = X[s - 1][-1] if s > 0 else X[-1][-1]
            res.append(X[s][0] - prev)                  # continuity (identity reset) / periodicity
        for s, g in enumerate(self.gs):
            res.append(np.atleast_1d(g['h'](tb[s + 1], X[s][-1])))
        return np.concatenate(res)

    def solve_orbit(self, z0, tol=1e-14):
        """Newton (central-difference Jacobian) until the residual is below tol or stops
        decreasing (by at least 4x) below 1e-9: the round-off floor is reached."""
        z = z0.copy()
        prev = np.inf
        for it in range(30):
            r = self.residual(z)
            nr = np.max(np.abs(r))
            if nr < tol or (nr < 1e-9 and nr > 0.25 * prev):
                break
            prev = nr
            Jm = np.zeros((len(r), len(z)))
            for i in range(len(z)):
                h = 1e-7 * max(1.0, abs(z[i]))
                zp = z.copy()
                zp[i] += h
                zm = z.copy()
                zm[i] -= h
                Jm[:, i] = (self.residual(zp) - self.residual(zm)) / (2 * h)
            z = z - np.linalg.solve(Jm, r)
        self.z = z
        self.X, self.tb = self.unpack(z)
        return z, float(np.max(np.abs(self.residual(z)))), it

    def initial_from(self, dense):
        """z0 from a simulated period (list of (ta, tb, mode, solfun))."""
        n, N = self.n, self.N
        tev = [d[1] for d in dense[:-1]]
        tb = np.concatenate([[0.0], tev, [self.H.T]])
        X = np.zeros((self.ns, N + 1, n))
        for s in range(self.ns):
            t, _ = self.nodes(tb, s)
            X[s] = dense[s][3](t).T[:, :n]
        return np.concatenate([X.ravel(), tev])

    def saltations(self):
        S = []
        for s, g in enumerate(self.gs):
            S.append(self.H.saltation(g, self.tb[s + 1], self.X[s][-1], self.seq[s]))
        return S

    def seg_matrices(self):
        """per segment: node times, L, J at the nodes, B at the nodes"""
        out = []
        for s, md in enumerate(self.seq):
            t, L = self.nodes(self.tb, s)
            Js = np.array([self.H.modes[md]['J'](t[i], self.X[s][i]) for i in range(self.N + 1)])
            Bs = np.array([self.H.modes[md]['B'](t[i], self.X[s][i]) for i in range(self.N + 1)])
            out.append((t, L, Js, Bs))
        return out

    def monodromy(self):
        n, N = self.n, self.N
        S = self.saltations()
        Phi = np.eye(n)
        for s, (t, L, Js, Bs) in enumerate(self.seg_matrices()):
            Mat = (2 / L) * np.kron(self.D, np.eye(n))
            for i in range(N + 1):
                Mat[i * n:(i + 1) * n, i * n:(i + 1) * n] -= Js[i]
            Mat[:n, :] = 0.0
            Mat[:n, :n] = np.eye(n)
            rhs = np.zeros(((N + 1) * n, n))
            rhs[:n] = Phi
            Y = np.linalg.solve(Mat, rhs)
            Phi = Y[N * n:]
            if s < self.ns - 1:
                Phi = S[s] @ Phi
        return Phi

    def prepare_htf(self, outputs):
        self._segm = self.seg_matrices()
        self._S = self.saltations()
        self._C = [[np.array([C(t[i], self.X[s][i], self.seq[s]) for i in range(self.N + 1)])
                    for s, (t, L, Js, Bs) in enumerate(self._segm)] for (_, y, C, D) in outputs]
        self._D = [[np.array([D(t[i], self.X[s][i]) for i in range(self.N + 1)])
                    for s, (t, L, Js, Bs) in enumerate(self._segm)] for (_, y, C, D) in outputs]

    def htf(self, W, harmonics):
        n, N, ns, T = self.n, self.N, self.ns, self.H.T
        wp = 2 * np.pi / T
        nb = (N + 1) * n
        Mat = np.zeros((ns * nb, ns * nb), complex)
        rhs = np.zeros(ns * nb, complex)
        for s, (t, L, Js, Bs) in enumerate(self._segm):
            blk = (2 / L) * np.kron(self.D, np.eye(n)).astype(complex)
            for i in range(N + 1):
                blk[i * n:(i + 1) * n, i * n:(i + 1) * n] -= Js[i]
            r = (Bs * np.exp(1j * W * t)[:, None]).ravel()
            blk[:n, :] = 0.0
            blk[:n, :n] = np.eye(n)
            r[:n] = 0.0
            Mat[s * nb:(s + 1) * nb, s * nb:(s + 1) * nb] = blk
            rhs[s * nb:(s + 1) * nb] = r
            # junction: dx_s(start) = S dx_{s-1}(end); periodic: dx_0(0) = exp(-j W T) dx_last(T)
            if s > 0:
                Mat[s * nb:s * nb + n, (s - 1) * nb + N * n:(s - 1) * nb + nb] = -self._S[s - 1]
            else:
                Mat[:n, (ns - 1) * nb + N * n:ns * nb] = -np.exp(-1j * W * T) * np.eye(n)
        dx = np.linalg.solve(Mat, rhs).reshape(ns, N + 1, n)
        res = []
        for o in range(len(self._C)):
            qo = {}
            for hn in harmonics:
                Wn = W + hn * wp
                acc = 0.0 + 0.0j
                for s, (t, L, Js, Bs) in enumerate(self._segm):
                    integrand = (np.einsum('ij,ij->i', self._C[o][s], dx[s])
                                 + self._D[o][s] * np.exp(1j * W * t)) * np.exp(-1j * Wn * t)
                    acc += (L / 2) * (self.w @ integrand)
                qo[hn] = acc / T
            res.append(qo)
        return res


# --------------------------------------------------------------------------------------
# Model 2: clearance_stops
# --------------------------------------------------------------------------------------
def clearance_stops():
    P = dict(m=1.0, k=10.0, c=0.5, F0=0.5, A=20.0, T=1.2, dR=0.2, dL=0.25, kR=300.0, sR=0.05,
             cR=3.0, kL=150.0, cL=2.0)
    m, k, c, F0, Af, T, dR, dL, kR, sR, cR, kL, cL = (P[s] for s in (
        'm', 'k', 'c', 'F0', 'A', 'T', 'dR', 'dL', 'kR', 'sR', 'cR', 'kL', 'cL'))
    wp = 2 * np.pi / T

    def base(t, x, v, u):
        return -k * x - c * v + F0 + Af * np.cos(wp * t) + u

    def fv(md):
        def f(t, X, u=0.0):
            x, v = X[..., 0], X[..., 1]
            F = base(t, x, v, u)
            if md == 'right':
                F = F - kR * sR * (np.exp((x - dR) / sR) - 1) - cR * v
            elif md == 'left':
                F = F - kL * (x + dL) - cL * v
            return np.stack([v * np.ones_like(F), F / m], axis=-1)
        return f

    def Jm(md):
        def J(t, x):
            if md == 'free':
                return np.array([[0, 1], [-k / m, -c / m]])
            if md == 'right':
                return np.array([[0, 1], [(-k - kR * np.exp((x[0] - dR) / sR)) / m, -(c + cR) / m]])
            return np.array([[0, 1], [(-k - kL) / m, -(c + cL) / m]])
        return J
    Bv = np.array([0.0, 1.0 / m])
    modes = {md: dict(f=fv(md), J=Jm(md), B=lambda t, x: Bv) for md in ('free', 'right', 'left')}
    e1 = np.array([1.0, 0.0])
    gR = dict(h=lambda t, x: x[0] - dR, dh=lambda t, x: e1, ht=lambda t, x: 0.0,
              R=lambda t, x: np.array(x), DR=lambda t, x: np.eye(2), Rt=lambda t, x: np.zeros(2),
              surface=True)
    gL = dict(gR, h=lambda t, x: x[0] + dL)
    guards = [dict(gR, name='hit_right', frm='free', to='right', direction=+1),
              dict(gR, name='leave_right', frm='right', to='free', direction=-1),
              dict(gL, name='hit_left', frm='free', to='left', direction=-1),
              dict(gL, name='leave_left', frm='left', to='free', direction=+1)]

    def contact_literal(x):
        """the model file's expression: pen_R = max(x - dR, 0), pen_L = abs(min(x + dL, 0)),
        contact = -kR*sR*(exp(pen_R/sR) - 1) + kL*pen_L"""
        pen_R = max(x[0] - dR, 0.0)
        pen_L = abs(min(x[0] + dL, 0.0))
        return -kR * sR * (np.exp(pen_R / sR) - 1) + kL * pen_L

    def contact(t, x, u, md):
        """the same expression in each mode's region (where the kinks of max/min/abs are absent)"""
        if md == 'right':
            return -kR * sR * (np.exp((x[0] - dR) / sR) - 1)
        if md == 'left':
            return -kL * (x[0] + dL)
        return 0.0

    def Ccontact(t, x, md):
        if md == 'right':
            return np.array([-kR * np.exp((x[0] - dR) / sR), 0.0])
        if md == 'left':
            return np.array([-kL, 0.0])
        return np.zeros(2)
    outputs = [('x', lambda t, x, u, md: x[0], lambda t, x, md: e1, lambda t, x: 0.0),
               ('contact', contact, Ccontact, lambda t, x: 0.0)]
    H = Hybrid(2, modes, guards, outputs, T)
    init_guess, init_mode = np.zeros(2), 'free'
    # numerical orbit: the mode sequence and a start for the collocation
    xn, mn, Mn, evs, resid_n, _ = H.find_orbit(init_guess, init_mode, settle=80)
    dense = []
    H.run(xn, mn, 0.0, T, dense_out=dense)
    seq = [d[2] for d in dense]
    gseq = []
    for ev in evs:
        gseq.append(next(g for g in guards if g['frm'] == ev['frm'] and g['to'] == ev['to']))
    checks = []
    fvec = {md: (lambda md: (lambda t, X: modes[md]['f'](t, X)))(md) for md in modes}
    results = {}
    NM, NC = 64, 48            # main and convergence-check numbers of nodes per segment
    for N in (NC, NM):
        col = Collocation(H, seq, gseq, N, fvec)
        z, cres, its = col.solve_orbit(col.initial_from(dense))
        col.prepare_htf(outputs)
        results[N] = (col, cres, its, col.monodromy())
    col, cres, its, M = results[NM]
    colC, cresC, itsC, MC = results[NC]
    x0 = col.X[0][0].copy()
    tb = col.tb
    # round-off floor of the collocation residual: the ODE rows are (2/L) D X - f, whose
    # floating-point evaluation errs by about eps_mach (2/L) ||D||_inf max|X| on the shortest segment
    Dinf = float(np.max(np.sum(np.abs(col.D), axis=1)))
    floor = float(np.finfo(float).eps * max((2 / (tb[s + 1] - tb[s])) * Dinf * np.max(np.abs(col.X[s]))
                                            for s in range(len(seq))))
    checks.append(dict(name=f'collocation ({NM} Chebyshev nodes per segment): max residual of the orbit '
                       'equations (ODE at the nodes, continuity, periodicity, guards) when Newton stagnates, '
                       'vs its round-off floor eps (2/L) ||D||_inf max|X|', value=cres, tolerance=floor,
                       passed=bool(cres < floor), detail=dict(newton_iterations=its, roundoff_floor=floor)))
    dN = float(max(np.max(np.abs(colC.X[0][0] - x0)), np.max(np.abs(colC.tb - tb))))
    checks.append(dict(name=f'collocation convergence: orbit state at t=0 and event times, {NC} vs {NM} nodes '
                       'per segment', value=dN, tolerance=1e-12, passed=bool(dN < 1e-12)))
    dMC = float(np.max(np.abs(MC - M)) / np.max(np.abs(M)))
    checks.append(dict(name=f'collocation convergence: monodromy, {NC} vs {NM} nodes per segment, '
                       'max |diff| / max |M|', value=dMC, tolerance=1e-11, passed=bool(dMC < 1e-11)))
    # admissibility / no grazing: sample each segment's polynomial (interpolate via the
    # numerical dense output, which agrees with the collocation) -- use the simulation
    worst, near_free, events = np.inf, np.inf, []
    dense2 = []
    H.run(x0, mn, 0.0, T, dense_out=dense2)
    assert [d[2] for d in dense2] == seq
    for (ta, tb_, md, sf) in dense2:
        ts = np.linspace(ta, tb_, 3001)[1:-1]
        xs = sf(ts)[0]
        vs_ = sf(ts)[1]
        if md == 'free':
            worst = min(worst, float(np.min(np.minimum(dR - xs, xs + dL))))
            for i in np.nonzero(vs_[:-1] * vs_[1:] < 0)[0]:
                near_free = min(near_free, float(min(dR - xs[i], xs[i] + dL)))
        elif md == 'right':
            worst = min(worst, float(np.min(xs - dR)))
        else:
            worst = min(worst, float(np.min(-dL - xs)))
    checks.append(dict(name='orbit inside the region of its mode at every sampled time (min signed '
                       'distance to the stop, m)', value=worst, tolerance='> 0', passed=bool(worst > 0)))
    checks.append(dict(name='no grazing: distance of the turning points in the clearance from the stops',
                       value=near_free, tolerance='> 0.05 m', passed=bool(near_free > 0.05)))
    dlit = max(abs(contact_literal(sf(t_)) - contact(t_, sf(t_), 0.0, md))
               for (ta, tb_, md, sf) in dense2 for t_ in np.linspace(ta, tb_, 201)[1:-1])
    checks.append(dict(name='the model file\'s contact expression (max/min/abs/exp) equals the per-mode form '
                       'used in the integrations: max |diff| (N) on 200 points per segment of the orbit', value=float(dlit),
                       tolerance=1e-12, passed=bool(dlit < 1e-12)))
    Ss = col.saltations()
    vmin = np.inf
    for s, g in enumerate(gseq):
        xm = col.X[s][-1]
        vmin = min(vmin, abs(xm[1]))
        events.append(dict(kind=f"{g['name']}: {g['frm']} -> {g['to']}", time_in_period=float(tb[s + 1]),
                           state=xm.tolist(), saltation=Ss[s].tolist()))
    checks.append(dict(name='transversal crossings: smallest |v| at a stop crossing (x\' = v on both sides, '
                       'so no sliding)', value=float(vmin), tolerance='> 0.5 m/s', passed=bool(vmin > 0.5)))
    mu = floq_sorted(M)
    tr = {'free': -c / m, 'right': -(c + cR) / m, 'left': -(c + cL) / m}
    liou = np.exp(sum(tr[md] * (tb[s + 1] - tb[s]) for s, md in enumerate(seq)))   # det S = 1 (v continuous)

    def main_htf(W, hn):
        q = col.htf(W, [hn])
        return [q[o][hn] for o in range(2)]
    # convergence of the collocation HTF (NC vs NM nodes) on a few points
    dh = 0.0
    gscale = 0.0
    for j in (3, 21, 45):
        for hn in HARMONICS:
            W = wp * j / Q_WINDOW - hn * wp
            a = col.htf(W, [hn])
            b = colC.htf(W, [hn])
            for o in range(2):
                dh = max(dh, abs(a[o][hn] - b[o][hn]))
                gscale = max(gscale, abs(a[o][hn]))
    checks.append(dict(name=f'collocation convergence: HTFs {NC} vs {NM} nodes per segment (max |diff| / '
                       'max |G| over j = 3, 21, 45, all n, both outputs)', value=float(dh / gscale),
                       tolerance=1e-11, passed=bool(dh / gscale < 1e-11)))
    starts = [([0.0, 0.0], 'free'), ([0.1, 2.0], 'free'), ([-0.2, -3.0], 'free'), ([0.3, 0.0], 'right'),
              ([0.0, -5.0], 'free'), ([-0.4, 1.0], 'left')]
    return finish('clearance_stops', P, H, x0, mn, M, mu, checks, main_htf=main_htf,
                  htf_method=('Chebyshev collocation (64 Gauss-Lobatto nodes per segment between events, '
                              '7 segments) of the periodic response dx = exp(jWt) p(t) of the variational '
                              'equation, saltation matrix at each event, Clenshaw-Curtis quadrature of the '
                              'Fourier integrals'),
                  orbit_method=('Chebyshev collocation of the periodic orbit with the six event times as '
                                'unknowns (Newton to round-off), checked by event-located DOP853 shooting'),
                  js=[3, 11, 15, 21, 45], eps=3e-4, init_guess=init_guess, init_mode=init_mode,
                  liouville=liou, state_names=['x', 'v'], output_names=['x', 'contact'], starts=starts,
                  has_primary_orbit=True,
                  extra=dict(mode_sequence=seq, events=events))


# --------------------------------------------------------------------------------------
# Model 3: ball_on_paddle
# --------------------------------------------------------------------------------------
def ball_on_paddle():
    P = dict(mb=0.05, mp=1.0, kp=400.0, cp=8.0, g=9.81, e=0.8, s1=0.03, s2=0.008, phi2=2.14, T=0.5)
    mb, mp, kp, cp, g, e, s1, s2, phi2, T = (P[s] for s in
                                             ('mb', 'mp', 'kp', 'cp', 'g', 'e', 's1', 's2', 'phi2', 'T'))
    wp = 2 * np.pi / T
    S_ = lambda t: -s1 * np.cos(wp * t) + s2 * np.sin(2 * wp * t + phi2)
    Sv = lambda t: s1 * wp * np.sin(wp * t) + 2 * wp * s2 * np.cos(2 * wp * t + phi2)
    Sa = lambda t: s1 * wp ** 2 * np.cos(wp * t) - 4 * wp ** 2 * s2 * np.sin(2 * wp * t + phi2)
    A = np.array([[0, 1, 0, 0], [0, 0, 0, 0], [0, 0, 0, 1], [0, 0, -kp / mp, -cp / mp]], float)
    cc = np.array([0.0, -g, 0.0, -g])
    Bv = np.array([0.0, 0.0, 0.0, 1.0 / mp])
    al = (1 + e) * mp / (mb + mp)
    be = (1 + e) * mb / (mb + mp)
    DR = np.array([[1, 0, 0, 0], [0, 1 - al, 0, al], [0, 0, 1, 0], [0, be, 0, 1 - be]], float)
    rvec = lambda t: np.array([0.0, al * Sv(t), 0.0, -be * Sv(t)])      # R(t, x) = DR x + rvec(t)
    Rt = lambda t: np.array([0.0, al * Sa(t), 0.0, -be * Sa(t)])
    dh = np.array([1.0, 0.0, -1.0, 0.0])
    f = lambda t, x, u=0.0: A @ x + cc + Bv * u
    E, q = affine_expm(A, cc, T)
    K = np.eye(4) - E @ DR
    assert np.all(K[:, 0] == 0.0)      # the ball's height is fixed by the guard, not by the flow

    def state_minus(tau):
        """pre-impact state of a period-1 orbit with the impact at phase tau, and the
        consistency residual (the ball's height row of the periodicity condition)"""
        rhs = E @ rvec(tau) + q
        xr = np.linalg.solve(K[1:, 1:], rhs[1:])
        xm = np.concatenate([[xr[1] + S_(tau)], xr])
        return xm, K[0, 1:] @ xr - rhs[0]

    def saltation(tau, xm):
        xp = DR @ xm + rvec(tau)
        return DR + np.outer(f(tau, xp) - DR @ f(tau, xm) - Rt(tau), dh) / (dh @ f(tau, xm) - Sv(tau))

    def fly(xp, t0, t):
        Et, qt = affine_expm(A, cc, t - t0)
        return Et @ xp + qt
    grid = np.linspace(0.0, T, 4001)
    gv = np.array([state_minus(t_)[1] for t_ in grid])
    cands = []
    for i in range(len(grid) - 1):
        if gv[i] == 0.0 or gv[i] * gv[i + 1] < 0:
            tau = brentq(lambda t_: state_minus(t_)[1], grid[i], grid[i + 1], xtol=1e-15, rtol=1e-15,
                         maxiter=200)
            xm, _ = state_minus(tau)
            rel = xm[1] - xm[3] - Sv(tau)
            xp = DR @ xm + rvec(tau)
            ts = np.linspace(tau, tau + T, 20001)[1:-1]
            gap = np.array([(lambda s: s[0] - s[2] - S_(t_))(fly(xp, tau, t_)) for t_ in ts])
            inner = (ts > tau + 0.05 * T) & (ts < tau + 0.95 * T)
            Mc = E @ saltation(tau, xm)          # monodromy from just before the impact
            cands.append(dict(tau=tau, xm=xm, xp=xp, rel=rel, ok=bool(rel < 0 and gap.min() > 0),
                              gap_inner=float(gap[inner].min()), mu=floq_sorted(Mc)))
    adm = [cd for cd in cands if cd['ok']]
    stable = [cd for cd in adm if abs(cd['mu'][0]) < 1]
    assert len(stable) == 1, cands
    O = stable[0]
    tau, xm, xp = O['tau'], O['xm'], O['xp']
    Sm = saltation(tau, xm)
    x0 = fly(xp, tau, T)                      # state at t = T = 0 (mod T)
    M = expm(A * (T - tau)) @ Sm @ expm(A * tau)
    mu = floq_sorted(M)
    checks = []
    checks.append(dict(name='closed-form orbit: admissible period-1 one-impact solutions (approaching, '
                       'ball above the surface between impacts)', value=len(adm),
                       detail=[dict(tau=cd['tau'], relative_velocity_before=cd['rel'],
                                    admissible=cd['ok'], max_abs_multiplier=float(abs(cd['mu'][0])))
                               for cd in cands], tolerance='exactly one stable admissible',
                       passed=bool(len(stable) == 1)))
    checks.append(dict(name='no grazing: smallest gap y - z - s between impacts, away from the impact '
                       '(from 5 % to 95 % of the flight)', value=O['gap_inner'], tolerance='> 0.02 m',
                       passed=bool(O['gap_inner'] > 0.02)))
    checks.append(dict(name='impact velocity of the ball relative to the surface (before)',
                       value=float(O['rel']), tolerance='< -1 m/s', passed=bool(O['rel'] < -1)))
    liou = e ** 2 * np.exp(-cp * T / mp)      # det(S) = det(DR) * (rel after / rel before) = e^2

    def main_htf(W, hn):
        segs = [(0.0, tau, A, {0: Bv}), (tau, T, A, {0: Bv})]
        _, _, qq = pw_response(T, segs, [Sm], W, [hn],
                               [([np.eye(4)[0]] * 2, {}), ([np.eye(4)[2]] * 2, {})])
        return [qq[o][hn] for o in range(2)]
    modes = {'main': dict(f=lambda t, x, u: f(t, x, u), J=lambda t, x: A, B=lambda t, x: Bv)}
    guards = [dict(name='impact', frm='main', to='main', h=lambda t, x: x[0] - x[2] - S_(t),
                   dh=lambda t, x: dh, ht=lambda t, x: -Sv(t), direction=-1,
                   R=lambda t, x: DR @ x + rvec(t), DR=lambda t, x: DR, Rt=lambda t, x: Rt(t))]
    outputs = [('y', lambda t, x, u, md: x[0], lambda t, x, md: np.eye(4)[0], lambda t, x: 0.0),
               ('z', lambda t, x, u, md: x[2], lambda t, x, md: np.eye(4)[2], lambda t, x: 0.0)]
    H = Hybrid(4, modes, guards, outputs, T)
    init_guess = np.array([0.3, -0.5, -0.0245, 0.0])      # the model file's [initial]
    # starts inside the basin of this orbit (the basin is not global, see other_attractors)
    starts = [(list(init_guess), 'main'), ([0.2, -2.0, -0.0245, 0.0], 'main'),
              ([0.2, 0.0, -0.0245, 0.0], 'main'), ([0.5, -1.0, -0.0245, 0.0], 'main'),
              ([0.4, 2.0, -0.0245, 0.0], 'main'), ([0.3, -0.5, -0.04, 0.3], 'main'),
              ([0.3, -0.5, 0.0, 0.3], 'main')]
    sal_detail = Sm.tolist()
    # a coexisting attractor: from y = 0.1, v = 2.4 (paddle at rest) the ball settles on a stable
    # period-1 orbit with two impacts per period
    xb, mdb, Mb, evb, rb, _ = H.find_orbit(np.array([0.1, 2.4, -0.0245, 0.0]), 'main', settle=60)
    other = [dict(description='stable period-1 orbit with two impacts per period (reached from y = 0.1, '
                  'v = 2.4, z = -0.0245, w = 0 by event-located simulation and Newton shooting)',
                  orbit_state_phase0=xb.tolist(), periodicity_residual=rb,
                  impact_phases=[ev['t'] for ev in evb],
                  relative_velocity_before=[float(ev['x_before'][1] - ev['x_before'][3] - Sv(ev['t']))
                                            for ev in evb],
                  floquet_multipliers_abs=[float(abs(z_)) for z_ in floq_sorted(Mb)]),
             dict(description='from many other starts (e.g. y = 0.05, v = 2, paddle at rest) the bounces '
                  'shrink to a chattering sequence (the ball would come to rest on the paddle, a sticking '
                  'motion the model cannot represent; an event-located simulation then loses the surface)')]
    return finish('ball_on_paddle', P, H, x0, 'main', M, mu, checks, main_htf=main_htf,
                  htf_method=('closed form: matrix exponentials (exact integrals) with the saltation matrix '
                              'of the impact (time-dependent guard and reset, dR/dt included)'),
                  orbit_method=('closed form: flight = affine matrix exponential, reset affine; the impact '
                                'phase is the root of the periodicity condition of the ball height row '
                                '(all roots on [0, T) bracketed on a 4000-point grid, Brent to 1e-15); '
                                'checked by event-located DOP853 shooting'),
                  js=[3, 11, 15, 21, 45], eps=3e-4, init_guess=init_guess, init_mode='main',
                  liouville=liou, state_names=['y', 'v', 'z', 'w'], output_names=['y', 'z'],
                  starts=starts, has_primary_orbit=True,
                  extra=dict(impact_phase=tau, state_before_impact=xm.tolist(),
                             state_after_impact=xp.tolist(),
                             relative_velocity_before=float(O['rel']),
                             relative_velocity_after=float(xp[1] - xp[3] - Sv(tau)),
                             saltation=sal_detail, other_attractors=other,
                             events=[dict(kind='impact: y - z - s(t) falls through 0; v, w reset',
                                          time_in_period=tau, state_before=xm.tolist(),
                                          state_after=xp.tolist(), saltation=sal_detail)]))


# --------------------------------------------------------------------------------------
def finish(name, P, H, x0, mode0, M, mu, checks, main_htf, htf_method, orbit_method, js, eps,
           init_guess, init_mode, liouville, state_names, output_names, starts, has_primary_orbit,
           extra=None):
    T = H.T
    wp = 2 * np.pi / T
    n = H.n
    # ---- numerical orbit from the model file's initial state (settling + Newton shooting)
    xn, mn, Mn, evs, resid_newton, m1 = H.find_orbit(init_guess, init_mode, settle=60)
    d = float(np.max(np.abs(xn - x0)))
    checks.append(dict(name='orbit state at t=0: primary method vs numerical shooting (event-located DOP853, '
                       'rtol 1e-12) from the model file\'s [initial]', value=d, tolerance=1e-9,
                       passed=bool(d < 1e-9 and mn == mode0),
                       detail=dict(numerical=xn.tolist(), mode_numerical=mn)))
    dM = float(np.max(np.abs(Mn - M)) / np.max(np.abs(M)))
    checks.append(dict(name='monodromy: primary vs variational equations with saltation matrices '
                       '(DOP853), max |diff| / max |M|', value=dM, tolerance=1e-8, passed=bool(dM < 1e-8)))
    x1, m1_, _, _ = H.period_map(x0, mode0)
    resid = float(np.max(np.abs(x1 - x0)))
    checks.append(dict(name='periodicity residual |P(x0) - x0|_inf of the primary orbit state under the '
                       'numerical period map', value=resid, tolerance=1e-9,
                       passed=bool(resid < 1e-9 and m1_ == mode0)))
    Mfd = H.fd_monodromy(x0, mode0)
    dfd = float(np.max(np.abs(Mfd - M)) / np.max(np.abs(M)))
    checks.append(dict(name='monodromy: central differences of the simulated nonlinear period map (no '
                       'saltation matrix needed) vs primary, max |diff| / max |M|', value=dfd,
                       tolerance=1e-6, passed=bool(dfd < 1e-6)))
    detM = float(np.real(np.linalg.det(M)))
    dl = abs(detM - liouville) / abs(liouville)
    checks.append(dict(name='det(monodromy) vs Liouville formula times the saltation determinants',
                       value=float(dl), tolerance=1e-9, passed=bool(dl < 1e-9),
                       detail=dict(det=detM, analytic=float(liouville))))
    checks.append(dict(name='stability: largest Floquet multiplier modulus', value=float(abs(mu[0])),
                       tolerance='< 0.9', passed=bool(abs(mu[0]) < 0.9)))
    sep = min(abs(mu[i] - mu[j]) for i in range(n) for j in range(i + 1, n))
    checks.append(dict(name='Floquet multipliers distinct: min |mu_i - mu_j|', value=float(sep),
                       tolerance='> 0.01', passed=bool(sep > 0.01)))
    ms = H.multistart(starts, x0, mode0, 80)
    worst = max(r['distance'] for r in ms)
    checks.append(dict(name='stability from several starts: max distance from the orbit state after 80 '
                       'periods (sliding allowed in transients)', value=worst, tolerance=1e-6,
                       passed=bool(all(r['converged'] for r in ms)), detail=ms))
    # ---- HTFs
    ws = out_grid(T, js)
    harm = HARMONICS
    no = len(output_names)
    main, var, brute = {}, {}, {}
    for w in ws:
        for hn in harm:
            W = w - hn * wp
            main[(w, hn)] = main_htf(W, hn)
            qv = H.htf_variational(x0, mode0, W, [hn])
            var[(w, hn)] = [qv[o][hn] for o in range(no)]
    settle = int(np.ceil(np.log(1e-11) / np.log(abs(mu[0])))) + 2
    for w in ws:
        for hn in harm:
            W = w - hn * wp
            qb = H.htf_bruteforce(x0, mode0, W, [hn], eps, settle)
            brute[(w, hn)] = [qb[o][hn] for o in range(no)]
    htf = {}
    worst_var, worst_brute = 0.0, 0.0
    elem_var, elem_brute = 0.0, 0.0
    for o, on in enumerate(output_names):
        gmax = max(abs(main[(w, hn)][o]) for w in ws for hn in harm)
        rows = []
        for w in ws:
            for hn in harm:
                g_ = main[(w, hn)][o]
                gv_ = var[(w, hn)][o]
                gb = brute[(w, hn)][o]
                ev_ = abs(gv_ - g_) / gmax
                eb = abs(gb - g_) / gmax
                worst_var = max(worst_var, ev_)
                if eb > worst_brute:
                    worst_brute = eb
                    worst_elem = (o, w, hn, gmax)
                if abs(g_) > 1e-12 * gmax:
                    elem_var = max(elem_var, abs(gv_ - g_) / abs(g_))
                    elem_brute = max(elem_brute, abs(gb - g_) / abs(g_))
                rows.append(dict(omega=w, n=hn, input_omega=w - hn * wp, re=float(g_.real),
                                 im=float(g_.imag), abs=float(abs(g_)),
                                 variational_ode=cplx(gv_), bruteforce=cplx(gb),
                                 err_variational_rel_max=float(ev_), err_bruteforce_rel_max=float(eb)))
        htf[on] = dict(max_abs_over_grid=float(gmax), values=rows)
    checks.append(dict(name='HTF: main method vs periodic response of the numerically integrated variational '
                       'equations (max |diff| / max|G| over all outputs, n, omega)',
                       value=float(worst_var), tolerance=1e-8, passed=bool(worst_var < 1e-8)))
    checks.append(dict(name='HTF: main method vs brute-force nonlinear simulation, u = +-eps cos(W t), '
                       f'eps = {eps}, settle {settle} periods, {Q_WINDOW}-period Fourier window '
                       '(max |diff| / max|G|)', value=float(worst_brute), tolerance=1e-5,
                       passed=bool(worst_brute < 1e-5)))
    checks.append(dict(name='HTF: main vs variational ODE, worst element-wise relative error |diff|/|G| '
                       '(elements with |G| > 1e-12 max|G|)',
                       value=float(elem_var), tolerance=1e-6, passed=bool(elem_var < 1e-6)))
    checks.append(dict(name='HTF: main vs brute force, worst element-wise relative error |diff|/|G| '
                       '(elements with |G| > 1e-12 max|G|)',
                       value=float(elem_brute), tolerance=1e-4, passed=bool(elem_brute < 1e-4)))
    # the brute-force error of the worst element (largest |diff| / max|G|) should be the O(eps^2)
    # cubic term of the nonlinear response (not a flaw of the linear theory) plus integrator noise:
    # repeat it at 3 eps and extrapolate (Richardson), which removes the eps^2 term
    o, w, hn, gmax = worst_elem
    W = w - hn * wp
    g_ = main[(w, hn)][o]
    gb1 = brute[(w, hn)][o]
    gb3 = H.htf_bruteforce(x0, mode0, W, [hn], 3 * eps, settle)[o][hn]
    e1_, e3_ = abs(gb1 - g_) / gmax, abs(gb3 - g_) / gmax
    rich = abs((9 * gb1 - gb3) / 8 - g_) / gmax
    checks.append(dict(name=f'HTF brute force at its worst element (output {output_names[o]}, omega = {w:.4g}, '
                       f'n = {hn}): error of the Richardson extrapolation (9 G(eps) - G(3 eps)) / 8, which removes '
                       'the O(eps^2) nonlinear term, / max|G|', value=float(rich), tolerance=1e-7,
                       passed=bool(rich < 1e-7),
                       detail=dict(err_eps=float(e1_), err_3eps=float(e3_), ratio=float(e3_ / e1_),
                                   ratio_if_the_eps2_term_dominates=9.0)))
    out = dict(
        model=name, model_file=f'{name}.toml', parameters=P,
        period=T, omega_p=wp,
        states=state_names, outputs=output_names,
        orbit_state_phase0=[float(v) for v in x0], mode_phase0=mode0,
        floquet_multipliers=[cplx(z) for z in mu],
        floquet_multipliers_abs=[float(abs(z)) for z in mu],
        floquet_order='largest modulus first (within a conjugate pair, positive imaginary part first)',
        monodromy_from_phase0=np.real(M).tolist(),
        htf_convention=('Y(jw) = sum_n G_n(jw) U(jw - j n wp): G_n(jw) maps the input component at '
                        'w - n wp to the output component at w (omega = OUTPUT frequency, rad/s); '
                        'linearisation with u = 0; time origin t = 0 = phase 0 of the forcing; '
                        'Fourier sign exp(-j w t).'),
        htf_method=htf_method,
        htf_checks=('each value also computed by (a1) the periodic response of the variational ODE '
                    'integrated with DOP853 (saltation at events) and (b) brute force'),
        htf_grid=(f'output frequencies omega = wp * j / {Q_WINDOW}, j = {list(js)}, so that every '
                  'frequency W + k wp of the brute-force runs is an exact bin of the '
                  f'{Q_WINDOW}-period analysis window and 2 omega / wp is not an integer'),
        htf=htf,
        self_checks=checks,
        orbit_periodicity_residual=resid,
        orbit_method=orbit_method,
    )
    if extra:
        out.update(extra)
    return out


def to_json(o):
    if isinstance(o, dict):
        return {str(k): to_json(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [to_json(v) for v in o]
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, np.bool_):
        return bool(o)
    if isinstance(o, np.ndarray):
        return to_json(o.tolist())
    if isinstance(o, complex):
        return cplx(o)
    return o


if __name__ == '__main__':
    which = sys.argv[1:] or ['actuator_brake', 'clearance_stops', 'ball_on_paddle']
    for nm in which:
        t0 = time.time()
        res = globals()[nm]()
        with open(os.path.join(HERE, f'{nm}.json'), 'w') as fh:
            json.dump(to_json(res), fh, indent=1)
        print(f'== {nm} ({time.time() - t0:.0f} s)')
        print('  x0 =', res['orbit_state_phase0'], 'mode', res['mode_phase0'])
        print('  mu =', res['floquet_multipliers'], '|mu| =', res['floquet_multipliers_abs'])
        for c in res['self_checks']:
            print(f"  [{'ok' if c['passed'] else 'FAIL'}] {c['name']}: {c['value']} (tol {c['tolerance']})")
