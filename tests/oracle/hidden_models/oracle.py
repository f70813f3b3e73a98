#!/usr/bin/env python3
"""Independent oracle for three hidden htfid models (impact_oscillator, forced_duffing,
phase_switched).

Written from the mathematics only (numpy/scipy); it shares no code with htfid.
Run:  python3 oracle.py      (deterministic; writes <name>.json next to this file)

HTF convention (docs/outputs.md):  Y(jw) = sum_n G_n(jw) U(jw - j n wp),  wp = 2 pi / T,
i.e. G_n(jw) maps an input component exp(j (w - n wp) t) to the output component
exp(j w t); w is the OUTPUT frequency.  For u = exp(j W t) the steady small-signal output is
sum_n G_n(j (W + n wp)) exp(j (W + n wp) t).
"""
import json
import os
import sys
import time

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import expm
from scipy.optimize import brentq, root

HERE = os.path.dirname(os.path.abspath(__file__))
HARMONICS = [-2, -1, 0, 1, 2]
Q_WINDOW = 16          # brute-force analysis window, in forcing periods
RTOL, ATOL = 1e-12, 1e-13


def cplx(z):
    return [float(np.real(z)), float(np.imag(z))]


# --------------------------------------------------------------------------------------
# Closed form: periodic response of a piecewise-LTI system to u = exp(j W t)
# --------------------------------------------------------------------------------------
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


def pw_lti_response(T, segs, jumps, W, harmonics, outputs, amp=1.0):
    """segs: list of (t0, t1, A, B) covering [0, T]; jumps[i] applied between segs[i] and
    segs[i+1]; input u = amp * exp(j W t); outputs: list of (C_per_seg, D_per_seg).
    Returns dx0 (the periodic response's state at t = 0) and q[o][n] = the Fourier
    coefficient of output o at frequency W + n wp (= G_n(j(W + n wp)) for amp = 1)."""
    wp = 2 * np.pi / T
    n = segs[0][2].shape[0]
    I = np.eye(n)
    # affine propagation: state = P dx0 + p
    P = I.astype(complex)
    p = np.zeros(n, dtype=complex)
    seg_data = []
    for i, (t0, t1, A, B) in enumerate(segs):
        g = np.linalg.solve(1j * W * I - A, B * amp)
        E = expm(A * (t1 - t0))
        # h = dx(t0+) - g e^{jWt0} = P dx0 + p - g e^{jW t0}
        seg_data.append((P.copy(), p.copy(), g))
        P_end = E @ P
        p_end = g * np.exp(1j * W * t1) + E @ (p - g * np.exp(1j * W * t0))
        if i < len(segs) - 1:
            S = jumps[i]
            P_end = S @ P_end
            p_end = S @ p_end
        P, p = P_end, p_end
    M, r = P, p
    dx0 = np.linalg.solve(np.exp(1j * W * T) * I - M, r)
    q = []
    for (Cs, Ds) in outputs:
        qo = {}
        for hn in harmonics:
            Wn = W + hn * wp
            acc = 0.0 + 0.0j
            for i, (t0, t1, A, B) in enumerate(segs):
                Pi, pi_, g = seg_data[i]
                C, D = Cs[i], Ds[i]
                h = Pi @ dx0 + pi_ - g * np.exp(1j * W * t0)
                In = int_exp(hn * wp, t0, t1)
                acc += (C @ g) * In + D * amp * In
                acc += np.exp(-1j * Wn * t0) * (C @ (int_expm(A - 1j * Wn * I, t1 - t0) @ h))
            qo[hn] = acc / T
        q.append(qo)
    return dx0, M, q


# --------------------------------------------------------------------------------------
# Generic event-located hybrid simulator (numerical methods)
# --------------------------------------------------------------------------------------
class Hybrid:
    """modes: {name: (f(t,x,u), J(t,x) = df/dx at u=0, B(t,x) = df/du)}
    guards: list of dicts: frm, to, h(t,x), dh(t,x) (grad), ht(t,x) (dh/dt), direction (+1/-1),
            R(x), DR(x)
    outputs: list of (name, y(t,x,u), C(t,x), D(t,x))"""

    def __init__(self, n, modes, guards, outputs, T):
        self.n, self.modes, self.guards, self.outputs, self.T = n, modes, guards, outputs, T

    def saltation(self, g, t, xm, m_from, m_to):
        f_m = np.asarray(self.modes[m_from][0](t, xm, 0.0))
        xp = np.asarray(g['R'](xm))
        f_p = np.asarray(self.modes[m_to][0](t, xp, 0.0))
        DR = np.asarray(g['DR'](xm))
        dh = np.asarray(g['dh'](t, xm))
        den = dh @ f_m + g['ht'](t, xm)
        return DR + np.outer(f_p - DR @ f_m, dh) / den

    def run(self, x0, mode, t0, t1, u=lambda t: 0.0, extra0=None, extra_rhs=None,
            jump_extra=None, events_out=None):
        """Integrate [x, extra] from t0 to t1.  extra_rhs(t, x, e, mode) -> de/dt;
        jump_extra(S, e) -> e after a transition."""
        n = self.n
        x = np.array(x0, float)
        e = np.zeros(0) if extra0 is None else np.array(extra0, float)
        t = t0
        count = 0
        while t < t1:
            f = self.modes[mode][0]
            my_guards = [g for g in self.guards if g['frm'] == mode]

            def rhs(tt, s, f=f, mode=mode):
                xx = s[:n]
                dx = f(tt, xx, u(tt))
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
            sol = solve_ivp(rhs, (t, t1), np.concatenate([x, e]), method='DOP853',
                            rtol=RTOL, atol=ATOL, events=evs if evs else None)
            if sol.status == 1:
                k = next(i for i, te in enumerate(sol.t_events) if len(te))
                te = sol.t_events[k][0]
                s = sol.y_events[k][0]
                g = my_guards[k]
                xm = s[:n]
                S = self.saltation(g, te, xm, mode, g['to'])
                x = np.asarray(g['R'](xm), float)
                e = s[n:]
                if jump_extra is not None:
                    e = jump_extra(S, e)
                if events_out is not None:
                    events_out.append(dict(t=te, frm=mode, to=g['to'], x_before=xm.copy(),
                                           x_after=x.copy(), S=S))
                mode = g['to']
                t = te
                count += 1
                if count > 100000:
                    raise RuntimeError('too many events (Zeno?)')
            elif sol.status == 0:
                x = sol.y[:n, -1]
                e = sol.y[n:, -1]
                t = t1
            else:
                raise RuntimeError(sol.message)
        return x, mode, e

    # period map with the monodromy (variational equations, saltation at events)
    def period_map(self, x0, mode, t0=0.0):
        n = self.n

        def erhs(t, x, e, md):
            Phi = e.reshape(n, n)
            return (self.modes[md][1](t, x) @ Phi).ravel()
        jump = lambda S, e: (S @ e.reshape(n, n)).ravel()
        evs = []
        x1, m1, e1 = self.run(x0, mode, t0, t0 + self.T, extra0=np.eye(n).ravel(),
                              extra_rhs=erhs, jump_extra=jump, events_out=evs)
        return x1, m1, e1.reshape(n, n), evs

    def find_orbit(self, x0, mode, settle=60, tol=1e-12):
        x, m, _ = self.run(x0, mode, 0.0, settle * self.T)
        for it in range(30):
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
        # extra layout: Phi (n*n real), dp (n complex -> 2n), ZPhi (no*nh*n complex), Zp (no*nh complex)
        iPhi = slice(0, n * n)
        idp = slice(n * n, n * n + 2 * n)
        base = n * n + 2 * n
        nZP = no * nh * n
        iZPhi = slice(base, base + 2 * nZP)
        iZp = slice(base + 2 * nZP, base + 2 * nZP + 2 * no * nh)
        size = base + 2 * nZP + 2 * no * nh
        Wn = np.array([W + hn * wp for hn in harmonics])

        def erhs(t, x, e, md):
            J = self.modes[md][1](t, x)
            B = np.asarray(self.modes[md][2](t, x))
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
                Cv = np.asarray(C(t, x))
                Dv = D(t, x)
                zphi[o] = np.outer(ph, Cv @ Phi)
                zp[o] = ph * (Cv @ dp + Dv * np.exp(1j * W * t))
            out[iZPhi] = np.concatenate([zphi.ravel().real, zphi.ravel().imag])
            out[iZp] = np.concatenate([zp.ravel().real, zp.ravel().imag])
            return out

        def jump(S, e):
            e = e.copy()
            e[iPhi] = (S @ e[iPhi].reshape(n, n)).ravel()
            dp = e[idp][:n] + 1j * e[idp][n:]
            dp = S @ dp
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
                z = np.array([[y(t, x, uf(t)) for (_, y, C, D) in self.outputs]]).T * ph[None, :]
                z = z.ravel()
                return np.concatenate([z.real, z.imag])
            x2, m2, e2 = self.run(xs, ms, t_a, t_b, u=uf, extra0=np.zeros(2 * no * nh),
                                  extra_rhs=erhs)
            res.append((e2[:no * nh] + 1j * e2[no * nh:]).reshape(no, nh))
        G = (res[0] - res[1]) / eps
        return [{hn: G[o, i] for i, hn in enumerate(harmonics)} for o in range(no)]


def rel_err(a, b):
    return abs(a - b) / max(abs(b), 1e-300)


def floq_sorted(M):
    ev = np.linalg.eigvals(M)
    return sorted(ev, key=lambda z: -abs(z))


def out_grid(T, js, Q=Q_WINDOW):
    wp = 2 * np.pi / T
    return [wp * j / Q for j in js]


def htf_table(ws, harmonics, compute):
    """compute(W) -> list over outputs of dict hn -> coefficient at W + hn wp."""
    table = {}
    for w in ws:
        for hn in harmonics:
            table[(w, hn)] = compute(w, hn)
    return table


# --------------------------------------------------------------------------------------
# Model 1: impact oscillator
# --------------------------------------------------------------------------------------
def impact_oscillator():
    P = dict(m=1.0, k=30.0, c=1.0, A=20.0, T=1.0, xw=-0.3, e=0.7)
    m, k, c, Af, T, xw, e = (P[s] for s in ('m', 'k', 'c', 'A', 'T', 'xw', 'e'))
    wp = 2 * np.pi / T
    Ac = np.array([[0.0, 1.0], [-k / m, -c / m]])
    Bv = np.array([0.0, 1.0 / m])
    R = np.diag([1.0, -e])
    # particular (periodic) solution of the free flight: X e^{j wp t}
    Xc = Af / (k - m * wp ** 2 + 1j * c * wp)

    def p(t):
        z = Xc * np.exp(1j * wp * t)
        return np.array([z.real, (1j * wp * z).real])

    def flow(s0, t0, t):
        return p(t) + expm(Ac * (t - t0)) @ (s0 - p(t0))
    E = expm(Ac * T)
    K = np.linalg.inv(np.eye(2) - E @ R) @ (np.eye(2) - E)

    def sminus(tau):
        return K @ p(tau)      # pre-impact state if the impact is at phase tau
    g = lambda tau: sminus(tau)[0] - xw
    # all roots of g on [0, T)
    grid = np.linspace(0.0, T, 4001)
    gv = np.array([g(t) for t in grid])
    cands = []
    for i in range(len(grid) - 1):
        if gv[i] == 0.0 or gv[i] * gv[i + 1] < 0:
            tau = brentq(g, grid[i], grid[i + 1], xtol=1e-15, rtol=1e-15, maxiter=200)
            sm = sminus(tau)
            # admissible: approaching the wall, no penetration during the flight
            if sm[1] >= 0:
                continue
            sp = R @ sm
            tt = np.linspace(tau, tau + T, 20001)[1:-1]
            st = np.array([flow(sp, tau, t) for t in tt])
            xs = st[:, 0]
            ok = xs.min() > xw
            # interior local minima of x (v from - to +): a grazing orbit would have one near x_w
            imin = [i for i in range(len(tt) - 1) if st[i, 1] < 0 <= st[i + 1, 1]]
            xmin_interior = min([xs[i] for i in imin], default=np.inf)
            Sx = salt_impact(P, tau, sm)
            M = expm(Ac * (T - tau)) @ Sx @ expm(Ac * tau) if True else None
            mu = floq_sorted(M)
            cands.append(dict(tau=tau, sm=sm, ok=ok, mu=mu, M=M, S=Sx, xmin=xmin_interior))
    stable = [cd for cd in cands if cd['ok'] and abs(cd['mu'][0]) < 1]
    assert len(stable) == 1, cands
    O = stable[0]
    tau, sm, S, M = O['tau'], O['sm'], O['S'], O['M']
    sp = R @ sm
    x0 = flow(sp, tau, T)   # state at t = T = 0 (mod T)
    mu = O['mu']
    checks = []
    checks.append(dict(name='closed-form orbit: admissible period-1 one-impact solutions found',
                       value=len([cd for cd in cands if cd['ok']]),
                       detail=[dict(tau=cd['tau'], v_minus=cd['sm'][1], stable=bool(abs(cd['mu'][0]) < 1),
                                    no_penetration=bool(cd['ok'])) for cd in cands],
                       tolerance='exactly one stable admissible', passed=True))
    gap = float(O['xmin'] - xw) if np.isfinite(O['xmin']) else 'no interior minimum of x'
    checks.append(dict(name='closed form: no grazing -- smallest interior local minimum of x(t) - x_w '
                       'during the flight (x > x_w everywhere between impacts)', value=gap,
                       tolerance='> 0.05 m or no interior minimum',
                       passed=bool(not np.isfinite(O['xmin']) or O['xmin'] - xw > 0.05)))
    checks.append(dict(name='impact velocity (pre-impact v-)', value=float(sm[1]),
                       tolerance='< -1 m/s (clear impact)', passed=bool(sm[1] < -1)))
    # ---------- numerical hybrid model
    def f(t, x, u):
        return np.array([x[1], (-k * x[0] - c * x[1] + Af * np.cos(wp * t) + u) / m])
    J = lambda t, x: Ac
    Bf = lambda t, x: Bv
    guards = [dict(frm='main', to='main', h=lambda t, x: x[0] - xw,
                   dh=lambda t, x: np.array([1.0, 0.0]), ht=lambda t, x: 0.0, direction=-1,
                   R=lambda x: np.array([x[0], -e * x[1]]), DR=lambda x: R)]
    outputs = [('x', lambda t, x, u: x[0], lambda t, x: np.array([1.0, 0.0]), lambda t, x: 0.0)]
    H = Hybrid(2, {'main': (f, J, Bf)}, guards, outputs, T)
    return finish('impact_oscillator', P, H, x0, 'main', M, mu, checks,
                  segs=[(0.0, tau, Ac, Bv), (tau, T, Ac, Bv)], jumps=[S],
                  out_cd=[([np.array([1.0, 0.0])] * 2, [0.0, 0.0])],
                  js=[3, 11, 15, 21, 45], eps=1e-3,
                  init_guess=np.array([0.3, 0.0]),
                  liouville=e ** 2 * np.exp(-c * T / m),
                  extra=dict(impact_phase=tau, impact_velocity_before=sm[1],
                             impact_velocity_after=sp[1], saltation=S.tolist(),
                             events=[dict(kind='impact x = x_w, v -> -e v', time_in_period=tau,
                                          state_before=sm.tolist(), state_after=sp.tolist(),
                                          saltation=S.tolist())]),
                  state_names=['x', 'v'], output_names=['x'])


def salt_impact(P, tau, sm):
    m, k, c, Af, T, e = (P[s] for s in ('m', 'k', 'c', 'A', 'T', 'e'))
    wp = 2 * np.pi / T
    F = Af * np.cos(wp * tau)
    a_m = (-k * sm[0] - c * sm[1] + F) / m
    a_p = (-k * sm[0] + c * e * sm[1] + F) / m
    # S = [[-e, 0], [(a+ + e a-)/v-, -e]]  (derived by hand for h = x - x_w, R = diag(1,-e))
    return np.array([[-e, 0.0], [(a_p + e * a_m) / sm[1], -e]])


# --------------------------------------------------------------------------------------
# Model 2: forced Duffing oscillator with a static load (no guards)
# --------------------------------------------------------------------------------------
def forced_duffing():
    P = dict(m=1.0, k=10.0, k3=40.0, c=0.8, F0=4.0, A=15.0, T=1.5)
    m, k, k3, c, F0, Af, T = (P[s] for s in ('m', 'k', 'k3', 'c', 'F0', 'A', 'T'))
    wp = 2 * np.pi / T

    def force(t, x, u):
        return -k * x[0] - k3 * x[0] ** 3 - c * x[1] + F0 + Af * np.cos(wp * t) + u

    def f(t, x, u):
        return np.array([x[1], force(t, x, u) / m])
    J = lambda t, x: np.array([[0.0, 1.0], [(-k - 3 * k3 * x[0] ** 2) / m, -c / m]])
    Bf = lambda t, x: np.array([0.0, 1.0 / m])
    outputs = [('x', lambda t, x, u: x[0], lambda t, x: np.array([1.0, 0.0]), lambda t, x: 0.0),
               ('acc', lambda t, x, u: force(t, x, u) / m,
                lambda t, x: np.array([(-k - 3 * k3 * x[0] ** 2) / m, -c / m]), lambda t, x: 1.0 / m)]
    H = Hybrid(2, {'main': (f, J, Bf)}, [], outputs, T)
    x0, mode, M, evs, resid, _ = H.find_orbit(np.array([0.0, 0.0]), 'main', settle=80)
    checks = []
    # independent orbit: harmonic balance (Fourier collocation), Newton on the samples
    N = 256
    tt = np.arange(N) * T / N
    kk = np.fft.fftfreq(N, d=1.0 / N)
    xs_sim = []
    xx = x0.copy()
    for i in range(N):
        if i == 0:
            xs_sim.append(x0[0])
            continue
        xx_, _, _ = H.run(x0, 'main', 0.0, tt[i])
        xs_sim.append(xx_[0])
    xs_sim = np.array(xs_sim)

    def deriv(xv, order):
        X = np.fft.fft(xv)
        X = X * (1j * kk * wp) ** order
        if order % 2 == 1:
            X[N // 2] = 0.0
        return np.real(np.fft.ifft(X))

    def hb_res(xv):
        return m * deriv(xv, 2) + c * deriv(xv, 1) + k * xv + k3 * xv ** 3 - F0 - Af * np.cos(wp * tt)
    sol = root(hb_res, xs_sim * (1 + 1e-3), method='hybr', tol=1e-14)
    xhb = sol.x
    hb_resid = np.max(np.abs(hb_res(xhb)))
    vhb = deriv(xhb, 1)
    d_orbit = max(abs(xhb[0] - x0[0]), abs(vhb[0] - x0[1]))
    checks.append(dict(name='orbit at t=0: harmonic balance (256-point Fourier collocation) vs shooting',
                       value=float(d_orbit), tolerance=1e-9, passed=bool(d_orbit < 1e-9),
                       detail=dict(hb_residual_max=float(hb_resid), hb_state0=[float(xhb[0]), float(vhb[0])])))
    spec = np.abs(np.fft.fft(xhb)) / N
    checks.append(dict(name='harmonic balance: spectral tail |X_k| at k = N/4 relative to |X_1| (resolution)',
                       value=float(spec[N // 4] / spec[1]), tolerance=1e-13,
                       passed=bool(spec[N // 4] / spec[1] < 1e-13)))
    # Hill (harmonic balance) HTF, from the Fourier series of x(t)^2
    X2 = np.fft.fft(xhb ** 2) / N    # X2[k] = coefficient of e^{j k wp t}
    Kh = 60

    def x2c(kq):
        return X2[kq % N] if abs(kq) < N // 2 else 0.0

    def hill(W, hn):
        nb = 2 * Kh + 1
        Hm = np.zeros((2 * nb, 2 * nb), complex)
        rhs = np.zeros(2 * nb, complex)
        ks = np.arange(-Kh, Kh + 1)
        for a, kq in enumerate(ks):
            Hm[2 * a:2 * a + 2, 2 * a:2 * a + 2] += 1j * (W + kq * wp) * np.eye(2)
            for b, lq in enumerate(ks):
                Ak = np.zeros((2, 2), complex)
                if kq == lq:
                    Ak += np.array([[0, 1], [-k / m, -c / m]])
                Ak[1, 0] += -3 * k3 * x2c(kq - lq) / m
                Hm[2 * a:2 * a + 2, 2 * b:2 * b + 2] -= Ak
        a0 = Kh
        rhs[2 * a0 + 1] = 1.0 / m
        Xs = np.linalg.solve(Hm, rhs).reshape(nb, 2)
        # outputs
        y_x = Xs[a0 + hn, 0]
        acc = sum((-3 * k3 * x2c(hn - lq) / m) * Xs[b, 0] for b, lq in enumerate(ks))
        acc += (-k / m) * Xs[a0 + hn, 0] + (-c / m) * Xs[a0 + hn, 1] + (1.0 / m if hn == 0 else 0.0)
        return [y_x, acc]
    mu = floq_sorted(M)
    return finish('forced_duffing', P, H, x0, 'main', M, mu, checks, hill=hill,
                  js=[3, 7, 13, 21, 37], eps=1e-3, init_guess=np.array([0.0, 0.0]),
                  liouville=np.exp(-c * T / m), orbit_resid=resid,
                  state_names=['x', 'v'], output_names=['x', 'acc'],
                  extra=dict(orbit_method='Newton shooting on the variational equations (DOP853, rtol 1e-12), checked by harmonic balance'))


# --------------------------------------------------------------------------------------
# Model 3: phase-switched stiffness and damping (time-only guard)
# --------------------------------------------------------------------------------------
def phase_switched():
    P = dict(m=1.0, k1=20.0, c1=0.4, k2=45.0, c2=3.0, A=6.0, T=1.2, phi=0.7)
    m, k1, c1, k2, c2, Af, T, phi = (P[s] for s in ('m', 'k1', 'c1', 'k2', 'c2', 'A', 'T', 'phi'))
    wp = 2 * np.pi / T
    A_soft = np.array([[0.0, 1.0], [-k1 / m, -c1 / m]])
    A_stiff = np.array([[0.0, 1.0], [-k2 / m, -c2 / m]])
    Bv = np.array([0.0, 1.0 / m])
    # h(t) = sin(wp t + phi) > 0: stiff; < 0: soft.  Switch times in [0, T):
    t_down = (np.pi - phi) / wp        # h falls through 0: stiff -> soft
    t_up = (2 * np.pi - phi) / wp      # h rises through 0: soft -> stiff
    segs = [(0.0, t_down, A_stiff, Bv), (t_down, t_up, A_soft, Bv), (t_up, T, A_stiff, Bv)]
    jumps = [np.eye(2), np.eye(2)]     # grad_x h = 0 -> saltation = identity
    # orbit: periodic response to the forcing A cos(wp t) = Re(A e^{j wp t})
    dx0, M, _ = pw_lti_response(T, segs, jumps, wp, [0], [], amp=Af)
    x0 = dx0.real
    checks = []
    mu = floq_sorted(M)

    def mk(kk, cc):
        return lambda t, x, u: np.array([x[1], (-kk * x[0] - cc * x[1] + Af * np.cos(wp * t) + u) / m])
    modes = {'stiff': (mk(k2, c2), lambda t, x: A_stiff, lambda t, x: Bv),
             'soft': (mk(k1, c1), lambda t, x: A_soft, lambda t, x: Bv)}
    hfun = lambda t, x: np.sin(wp * t + phi)
    dhdt = lambda t, x: wp * np.cos(wp * t + phi)
    guards = [dict(frm='stiff', to='soft', h=hfun, dh=lambda t, x: np.zeros(2), ht=dhdt, direction=-1,
                   R=lambda x: np.array(x), DR=lambda x: np.eye(2)),
              dict(frm='soft', to='stiff', h=hfun, dh=lambda t, x: np.zeros(2), ht=dhdt, direction=+1,
                   R=lambda x: np.array(x), DR=lambda x: np.eye(2))]
    outputs = [('x', lambda t, x, u: x[0], lambda t, x: np.array([1.0, 0.0]), lambda t, x: 0.0),
               ('v', lambda t, x, u: x[1], lambda t, x: np.array([0.0, 1.0]), lambda t, x: 0.0)]
    H = Hybrid(2, modes, guards, outputs, T)
    Cx = np.array([1.0, 0.0])
    Cv = np.array([0.0, 1.0])
    return finish('phase_switched', P, H, x0, 'stiff', M, mu, checks, segs=segs, jumps=jumps,
                  out_cd=[([Cx] * 3, [0.0] * 3), ([Cv] * 3, [0.0] * 3)],
                  js=[3, 9, 13, 19, 35], eps=1e-2, init_guess=np.array([0.0, 0.0]),
                  liouville=np.exp(-(c2 * (T - (t_up - t_down)) + c1 * (t_up - t_down)) / m),
                  state_names=['x', 'v'], output_names=['x', 'v'],
                  extra=dict(switch_times=dict(stiff_to_soft=t_down, soft_to_stiff=t_up),
                             events=[dict(kind='stiff -> soft (sin falls through 0)', time_in_period=t_down),
                                     dict(kind='soft -> stiff (sin rises through 0)', time_in_period=t_up)]))


# --------------------------------------------------------------------------------------
def finish(name, P, H, x0, mode0, M, mu, checks, js, eps, init_guess, liouville, state_names,
           output_names, segs=None, jumps=None, out_cd=None, hill=None, orbit_resid=None, extra=None):
    T = H.T
    wp = 2 * np.pi / T
    t_start = time.time()
    # ---- numerical orbit from a rough start (settling + Newton shooting) vs closed form
    xn, mn, Mn, evs, resid, m1 = H.find_orbit(init_guess, mode0 if segs is None else mode0, settle=60)
    if segs is not None:
        d = float(np.max(np.abs(xn - x0)))
        checks.append(dict(name='orbit state at t=0: closed form vs numerical shooting (event-located DOP853)',
                           value=d, tolerance=1e-9, passed=bool(d < 1e-9),
                           detail=dict(numerical=xn.tolist(), mode_numerical=mn)))
        dM = float(np.max(np.abs(Mn - M)))
        checks.append(dict(name='monodromy: closed form (expm + saltation) vs variational equations',
                           value=dM, tolerance=1e-8, passed=bool(dM < 1e-8)))
    checks.append(dict(name='periodicity residual |P(x0) - x0|_inf of the numerical period map',
                       value=float(resid), tolerance=1e-10, passed=bool(resid < 1e-10)))
    if mn != mode0 or m1 != mode0:
        checks.append(dict(name='mode at phase 0', value=mn, tolerance=mode0, passed=False))
    Mfd = H.fd_monodromy(x0, mode0)
    dfd = float(np.max(np.abs(Mfd - M)) / np.max(np.abs(M)))
    checks.append(dict(name='monodromy: central differences of the simulated period map vs reported',
                       value=dfd, tolerance=1e-6, passed=bool(dfd < 1e-6)))
    detM = float(np.real(np.linalg.det(M)))
    dl = abs(detM - liouville) / liouville
    checks.append(dict(name='det(monodromy) vs Liouville/saltation product (analytic)',
                       value=float(dl), tolerance=1e-9, passed=bool(dl < 1e-9),
                       detail=dict(det=detM, analytic=float(liouville))))
    checks.append(dict(name='stability: largest Floquet multiplier modulus', value=float(abs(mu[0])),
                       tolerance='< 0.9', passed=bool(abs(mu[0]) < 0.9)))
    # ---- HTFs
    ws = out_grid(T, js)
    harm = HARMONICS
    no = len(output_names)
    main, var, brute = {}, {}, {}
    for w in ws:
        for hn in harm:
            W = w - hn * wp
            if segs is not None:
                _, _, q = pw_lti_response(T, segs, jumps, W, [hn], out_cd)
                main[(w, hn)] = [q[o][hn] for o in range(no)]
            else:
                main[(w, hn)] = hill(W, hn)
            qv = H.htf_variational(x0, mode0, W, [hn])
            var[(w, hn)] = [qv[o][hn] for o in range(no)]
    # brute force: settle long enough for the transient to decay below 1e-11
    settle = int(np.ceil(np.log(1e-11) / np.log(abs(mu[0])))) + 2
    for w in ws:
        for hn in harm:
            W = w - hn * wp
            qb = H.htf_bruteforce(x0, mode0, W, [hn], eps, settle)
            brute[(w, hn)] = [qb[o][hn] for o in range(no)]
    method_main = ('closed form: piecewise matrix exponentials (exact integrals) with the saltation '
                   'matrix at each transition' if segs is not None else
                   "Hill's method (harmonic balance of the variational equation, 121 harmonics) on the "
                   'harmonic-balance orbit')
    htf = {}
    worst_var, worst_brute = 0.0, 0.0
    elem_var, elem_brute = 0.0, 0.0
    for o, on in enumerate(output_names):
        gmax = max(abs(main[(w, hn)][o]) for w in ws for hn in harm)
        rows = []
        for w in ws:
            for hn in harm:
                g = main[(w, hn)][o]
                gv_ = var[(w, hn)][o]
                gb = brute[(w, hn)][o]
                ev_ = abs(gv_ - g) / gmax
                eb = abs(gb - g) / gmax
                worst_var = max(worst_var, ev_)
                worst_brute = max(worst_brute, eb)
                elem_var = max(elem_var, abs(gv_ - g) / abs(g))
                elem_brute = max(elem_brute, abs(gb - g) / abs(g))
                rows.append(dict(omega=w, n=hn, input_omega=w - hn * wp, re=float(g.real), im=float(g.imag),
                                 abs=float(abs(g)),
                                 variational_ode=cplx(gv_), bruteforce=cplx(gb),
                                 err_variational_rel_max=float(ev_), err_bruteforce_rel_max=float(eb)))
        htf[on] = dict(max_abs_over_grid=float(gmax), values=rows)
    checks.append(dict(name='HTF: main method vs periodic response of the numerically integrated variational '
                       'equations (max |diff| / max|G| over all outputs, n, omega)',
                       value=float(worst_var), tolerance=1e-7, passed=bool(worst_var < 1e-7)))
    checks.append(dict(name='HTF: main method vs brute-force nonlinear simulation, u = +-eps cos(W t), '
                       f'eps = {eps}, settle {settle} periods, {Q_WINDOW}-period Fourier window '
                       '(max |diff| / max|G|)', value=float(worst_brute), tolerance=1e-5,
                       passed=bool(worst_brute < 1e-5)))
    checks.append(dict(name='HTF: main vs variational ODE, worst element-wise relative error |diff|/|G|',
                       value=float(elem_var), tolerance=1e-6, passed=bool(elem_var < 1e-6)))
    checks.append(dict(name='HTF: main vs brute force, worst element-wise relative error |diff|/|G|',
                       value=float(elem_brute), tolerance=1e-5, passed=bool(elem_brute < 1e-5)))
    out = dict(
        model=name, model_file=f'{name}.toml', parameters=P,
        period=T, omega_p=wp,
        states=state_names, outputs=output_names,
        orbit_state_phase0=[float(v) for v in x0], mode_phase0=mode0,
        floquet_multipliers=[cplx(z) for z in mu],
        floquet_multipliers_abs=[float(abs(z)) for z in mu],
        floquet_order='largest modulus first',
        monodromy_from_phase0=np.real(M).tolist(),
        htf_convention=('Y(jw) = sum_n G_n(jw) U(jw - j n wp): G_n(jw) maps the input component at '
                        'w - n wp to the output component at w (omega = OUTPUT frequency, rad/s); '
                        'linearisation with u = 0; time origin t = 0 = phase 0 of the forcing; '
                        'Fourier sign exp(-j w t).'),
        htf_method=method_main,
        htf_checks=('each value also computed by (a1) the periodic response of the variational ODE '
                    'integrated with DOP853 (saltation at events) and (b) brute force'),
        htf_grid=(f'output frequencies omega = wp * j / {Q_WINDOW}, j = {list(js)}, so that every '
                  'frequency W + k wp of the brute-force runs is an exact bin of the '
                  f'{Q_WINDOW}-period analysis window and 2 omega / wp is not an integer'),
        htf=htf,
        self_checks=checks,
    )
    if orbit_resid is not None:
        out['orbit_periodicity_residual'] = float(orbit_resid)
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
    which = sys.argv[1:] or ['impact_oscillator', 'forced_duffing', 'phase_switched']
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
