#!/usr/bin/env python3
"""Independent oracle for hidden models round 4 (lif_neuron, rimless_wheel, pendulum_stops).

Written from docs/models.md alone; shares no code with htfid.  Deterministic.
Usage: python3 oracle.py [lif_neuron rimless_wheel pendulum_stops]
"""
import json, math, sys, time
import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import expm, eigvals
from scipy.optimize import brentq

RTOL, ATOL = 1e-12, 1e-14
JS = [3, 11, 15, 21, 45]
NS = [-2, -1, 0, 1, 2]


class Guard:
    def __init__(self, name, frm, to, h, hx, ht, direction, R=None, DR=None, Rt=None, n=2):
        self.name, self.frm, self.to = name, frm, to
        self.h, self.hx, self.ht, self.direction = h, hx, ht, direction
        self.R = R if R is not None else (lambda t, x: np.array(x, float))
        self.DR = DR if DR is not None else (lambda t, x: np.eye(n))
        self.Rt = Rt if Rt is not None else (lambda t, x: np.zeros(n))


class Out:
    def __init__(self, name, y, C, D, jumps=False):
        self.name, self.y, self.C, self.D, self.jumps = name, y, C, D, jumps


class HModel:
    pass


# ----------------------------------------------------------------------------------------
# the three models (equations written from the .toml files by hand, Jacobians by hand)
# ----------------------------------------------------------------------------------------
def lif_neuron():
    P = dict(tau=0.5, I0=1.16, A=0.3, vth=1.0, vr=0.0, taus=0.2, T=1.0)
    tau, I0, A, vth, vr, taus, T = (P[k] for k in ("tau", "I0", "A", "vth", "vr", "taus", "T"))
    wp = 2 * math.pi / T
    I = lambda t: I0 + A * math.cos(wp * t)
    M = HModel()
    M.name, M.P, M.T, M.wp = "lif_neuron", P, T, wp
    M.states, M.modes, M.n = ["v", "s"], ["main"], 2
    M.f = lambda m, t, x, u: np.array([(I(t) + u - x[0]) / tau, (x[0] - x[1]) / taus])
    Am = np.array([[-1 / tau, 0.0], [1 / taus, -1 / taus]])
    M.A = lambda m, t, x: Am
    M.B = lambda m, t, x: np.array([1 / tau, 0.0])
    M.guards = [Guard("spike", "main", "main", lambda t, x: x[0] - vth,
                      lambda t, x: np.array([1.0, 0.0]), lambda t, x: 0.0, +1,
                      R=lambda t, x: np.array([vr, x[1]]),
                      DR=lambda t, x: np.diag([0.0, 1.0]))]
    M.outputs = [Out("v", lambda m, t, x, u: x[0], lambda m, t, x: np.array([1.0, 0.0]), lambda m, t, x: 0.0, jumps=True),
                 Out("s", lambda m, t, x, u: x[1], lambda m, t, x: np.array([0.0, 1.0]), lambda m, t, x: 0.0),
                 Out("current", lambda m, t, x, u: I(t) + u - x[0], lambda m, t, x: np.array([-1.0, 0.0]),
                     lambda m, t, x: 1.0, jumps=True)]
    M.init_mode, M.init_x = "main", np.array([0.5, 0.5])
    M.regions = None
    return M


def rimless_wheel():
    P = dict(m=1.0, l=1.0, g=9.81, b=0.5, alpha=0.3, tau0=1.0, A=1.0, T=0.62)
    m_, l, g, b, al, tau0, A, T = (P[k] for k in ("m", "l", "g", "b", "alpha", "tau0", "A", "T"))
    wp = 2 * math.pi / T
    J = m_ * l * l
    tq = lambda t: tau0 + A * math.cos(wp * t)
    M = HModel()
    M.name, M.P, M.T, M.wp = "rimless_wheel", P, T, wp
    M.states, M.modes, M.n = ["th", "om"], ["main"], 2  # the one mode of a model without [modes] is `main` (docs/models.md)
    M.f = lambda m, t, x, u: np.array([x[1], (m_ * g * l * math.sin(x[0]) - b * x[1] + tq(t) + u) / J])
    M.A = lambda m, t, x: np.array([[0.0, 1.0], [m_ * g * l * math.cos(x[0]) / J, -b / J]])
    M.B = lambda m, t, x: np.array([0.0, 1 / J])
    c2 = math.cos(2 * al)
    M.guards = [Guard("heelstrike", "main", "main", lambda t, x: x[0] - al,
                      lambda t, x: np.array([1.0, 0.0]), lambda t, x: 0.0, +1,
                      R=lambda t, x: np.array([x[0] - 2 * al, c2 * x[1]]),
                      DR=lambda t, x: np.diag([1.0, c2]))]
    M.outputs = [Out("height", lambda m, t, x, u: l * math.cos(x[0]), lambda m, t, x: np.array([-l * math.sin(x[0]), 0.0]),
                     lambda m, t, x: 0.0),
                 Out("th", lambda m, t, x, u: x[0], lambda m, t, x: np.array([1.0, 0.0]), lambda m, t, x: 0.0, jumps=True)]
    M.init_mode, M.init_x = "main", np.array([-0.3, 1.0])
    M.regions = None
    return M


def pendulum_stops():
    P = dict(m=1.0, l=1.0, g=9.81, c=0.3, wf=2 * math.pi / 1.5, A=5.0, A3=1.0, b0=0.3,
             thR=0.5, thL=0.6, kR=80.0, cR=2.0, kL=120.0, cL=1.5)
    m_, l, g, c, wf, A, A3, b0 = (P[k] for k in ("m", "l", "g", "c", "wf", "A", "A3", "b0"))
    thR, thL, kR, cR, kL, cL = (P[k] for k in ("thR", "thL", "kR", "cR", "kL", "cL"))
    T = 2 * math.pi / wf
    wp = wf
    J = m_ * l * l
    tq = lambda t: b0 + A * math.cos(wf * t) + A3 * math.sin(3 * wf * t)

    def f(m, t, x, u):
        th, om = x
        a = -m_ * g * l * math.sin(th) - c * om + tq(t) + u
        if m == "right":
            a += -kR * (th - thR) - cR * om
        elif m == "left":
            a += -kL * (th + thL) - cL * om
        return np.array([om, a / J])

    def Af(m, t, x):
        a11 = -m_ * g * l * math.cos(x[0])
        a12 = -c
        if m == "right":
            a11 -= kR; a12 -= cR
        elif m == "left":
            a11 -= kL; a12 -= cL
        return np.array([[0.0, 1.0], [a11 / J, a12 / J]])

    def stop_torque_C(m, t, x):
        return np.array([-kR if m == "right" else (-kL if m == "left" else 0.0), 0.0])

    def stop_torque_y(m, t, x, u):
        if m == "right":
            return -kR * (x[0] - thR)
        if m == "left":
            return -kL * (x[0] + thL)
        return 0.0

    M = HModel()
    M.name, M.P, M.T, M.wp = "pendulum_stops", P, T, wp
    M.states, M.modes, M.n = ["th", "om"], ["free", "right", "left"], 2
    M.f, M.A = f, Af
    M.B = lambda m, t, x: np.array([0.0, 1 / J])
    e1 = lambda t, x: np.array([1.0, 0.0])
    z = lambda t, x: 0.0
    M.guards = [Guard("hit_right", "free", "right", lambda t, x: x[0] - thR, e1, z, +1),
                Guard("leave_right", "right", "free", lambda t, x: x[0] - thR, e1, z, -1),
                Guard("hit_left", "free", "left", lambda t, x: x[0] + thL, e1, z, -1),
                Guard("leave_left", "left", "free", lambda t, x: x[0] + thL, e1, z, +1)]
    M.outputs = [Out("bob_x", lambda m, t, x, u: l * math.sin(x[0]), lambda m, t, x: np.array([l * math.cos(x[0]), 0.0]),
                     lambda m, t, x: 0.0),
                 Out("stop_torque", stop_torque_y, stop_torque_C, lambda m, t, x: 0.0)]
    # literal model-file expression of stop_torque (checked equal to the per-mode form on the orbit)
    M.literal = {"stop_torque": lambda t, x: -kR * max(x[0] - thR, 0.0) - kL * min(x[0] + thL, 0.0)}
    M.init_mode, M.init_x = "free", np.array([0.0, 0.0])
    # signed distance inside each mode's region
    M.regions = {"free": lambda x: min(thR - x[0], x[0] + thL), "right": lambda x: x[0] - thR,
                 "left": lambda x: -(x[0] + thL)}
    return M


MODELS = {"lif_neuron": lif_neuron, "rimless_wheel": rimless_wheel, "pendulum_stops": pendulum_stops}


# ----------------------------------------------------------------------------------------
# event-located hybrid simulation (DOP853), optional augmented states
# ----------------------------------------------------------------------------------------
def saltation(M, g, t, xm, xp):
    fm = M.f(g.frm, t, xm, 0.0)
    fp = M.f(g.to, t, xp, 0.0)
    hx = g.hx(t, xm)
    DR = g.DR(t, xm)
    den = hx @ fm + g.ht(t, xm)
    return DR + np.outer(fp - DR @ fm - g.Rt(t, xm), hx) / den, den


def integrate(M, mode, t0, t1, x0, a0=None, arhs=None, ajump=None, u=None, rtol=RTOL, atol=ATOL,
              dense=False, aatol=None, max_events=100000):
    n = M.n
    y = np.array(x0, float) if a0 is None else np.concatenate([x0, a0])
    at = atol if a0 is None or aatol is None else np.concatenate([np.full(n, atol), np.full(len(a0), aatol)])
    t = t0
    events, segs = [], []
    while True:
        gs = [g for g in M.guards if g.frm == mode]
        md = mode

        def rhs(tt, yy):
            x = yy[:n]
            uu = u(tt) if u is not None else 0.0
            dx = M.f(md, tt, x, uu)
            if arhs is None:
                return dx
            return np.concatenate([dx, arhs(md, tt, x, yy[n:])])

        evs = []
        for g in gs:
            fn = (lambda gg: (lambda tt, yy: gg.h(tt, yy[:n])))(g)
            fn.terminal = True
            fn.direction = g.direction
            evs.append(fn)
        sol = solve_ivp(rhs, (t, t1), y, method="DOP853", rtol=rtol, atol=at, events=evs or None,
                        dense_output=dense)
        if not sol.success:
            raise RuntimeError(sol.message)
        if sol.status == 1:
            k = min((i for i in range(len(gs)) if len(sol.t_events[i])), key=lambda i: sol.t_events[i][0])
            g = gs[k]
            te = sol.t_events[k][0]
            ye = sol.y_events[k][0]
            if dense:
                segs.append((mode, t, te, sol.sol))
            xm = ye[:n]
            xp = g.R(te, xm)
            S, den = saltation(M, g, te, xm, xp)
            a = ye[n:]
            if ajump is not None:
                a = ajump(g, te, xm, xp, S, a)
            events.append(dict(guard=g, t=te, xm=xm.copy(), xp=xp.copy(), S=S, den=den, am=ye[n:].copy(),
                               frm=g.frm, to=g.to))
            mode = g.to
            y = np.concatenate([xp, a]) if a0 is not None else xp
            t = te
            if len(events) > max_events:
                raise RuntimeError("too many events")
            continue
        if dense:
            segs.append((mode, t, t1, sol.sol))
        return sol.y[:, -1], mode, events, segs


def var_rhs(M):
    n = M.n
    return lambda m, t, x, a: (M.A(m, t, x) @ a.reshape(n, n)).ravel()


def var_jump(M):
    n = M.n
    return lambda g, t, xm, xp, S, a: (S @ a.reshape(n, n)).ravel()


def period_map(M, mode, x0, var=False, rtol=RTOL):
    n = M.n
    if var:
        xe, me, ev, _ = integrate(M, mode, 0.0, M.T, x0, np.eye(n).ravel(), var_rhs(M), var_jump(M), rtol=rtol)
        return xe[:n], me, xe[n:].reshape(n, n), ev
    xe, me, ev, _ = integrate(M, mode, 0.0, M.T, x0, rtol=rtol)
    return xe, me, None, ev


def shoot(M, settle=60):
    T = M.T
    x, mode, _, _ = integrate(M, M.init_mode, 0.0, settle * T, M.init_x, rtol=1e-10, atol=1e-12)
    for it in range(20):
        xT, mT, Mon, ev = period_map(M, mode, x, var=True)
        assert mT == mode, "mode at t=T differs from mode at 0"
        r = xT - x
        dx = np.linalg.solve(Mon - np.eye(M.n), -r)
        x = x + dx
        if np.max(np.abs(dx)) < 1e-14 * max(1, np.max(np.abs(x))):
            break
    xT, mT, Mon, ev = period_map(M, mode, x, var=True)
    return x, mode, Mon, ev, it + 1, np.max(np.abs(xT - x))


def sort_mults(mu):
    mu = list(mu)
    mu.sort(key=lambda z: (-round(abs(z), 12), -z.imag))
    return mu


# ----------------------------------------------------------------------------------------
# HTF: periodic response of the variational equations integrated by DOP853
# ----------------------------------------------------------------------------------------
def htf_variational(M, mode0, x0, W, n_harm, rtol=RTOL):
    n, T, wp = M.n, M.T, M.wp
    outs = M.outputs
    no = len(outs)

    def r1(m, t, x, a):
        Phi = a[:n * n].reshape(n, n)
        A = M.A(m, t, x)
        r = a[n * n:n * n + n] + 1j * a[n * n + n:]
        dr = A @ r + M.B(m, t, x) * np.exp(1j * W * t)
        return np.concatenate([(A @ Phi).ravel(), dr.real, dr.imag])

    def j1(g, t, xm, xp, S, a):
        Phi = a[:n * n].reshape(n, n)
        r = a[n * n:n * n + n] + 1j * a[n * n + n:]
        r = S @ r
        return np.concatenate([(S @ Phi).ravel(), r.real, r.imag])

    a0 = np.concatenate([np.eye(n).ravel(), np.zeros(2 * n)])
    ye, me, ev, _ = integrate(M, mode0, 0.0, T, x0, a0, r1, j1, rtol=rtol, aatol=1e-15)
    a = ye[n:]
    Mon = a[:n * n].reshape(n, n)
    rT = a[n * n:n * n + n] + 1j * a[n * n + n:]
    d0 = np.linalg.solve(np.exp(1j * W * T) * np.eye(n) - Mon, rT)
    om = W + n_harm * wp

    def r2(m, t, x, a):
        dx = a[:n] + 1j * a[n:2 * n]
        A = M.A(m, t, x)
        e = np.exp(1j * W * t)
        ddx = A @ dx + M.B(m, t, x) * e
        q = np.array([(o.C(m, t, x) @ dx + o.D(m, t, x) * e) * np.exp(-1j * om * t) / T for o in outs])
        return np.concatenate([ddx.real, ddx.imag, q.real, q.imag])

    def j2(g, t, xm, xp, S, a):
        dx = S @ (a[:n] + 1j * a[n:2 * n])
        return np.concatenate([dx.real, dx.imag, a[2 * n:]])

    a0 = np.concatenate([d0.real, d0.imag, np.zeros(2 * no)])
    ye, me, ev, _ = integrate(M, mode0, 0.0, T, x0, a0, r2, j2, rtol=rtol, aatol=1e-15)
    a = ye[n:]
    G = a[2 * n:2 * n + no] + 1j * a[2 * n + no:]
    # pulse term of jumping outputs: -(jump of y) * dtau(t_e) * exp(-j om t_e) / T
    pulse = np.zeros(no, complex)
    for e in ev:
        dxm = e["am"][:n] + 1j * e["am"][n:2 * n]
        dtau = -(e["guard"].hx(e["t"], e["xm"]) @ dxm) / e["den"]
        for i, o in enumerate(outs):
            jump = o.y(e["to"], e["t"], e["xp"], 0.0) - o.y(e["frm"], e["t"], e["xm"], 0.0)
            pulse[i] += -jump * dtau * np.exp(-1j * om * e["t"]) / T
    return G, pulse, d0


# ----------------------------------------------------------------------------------------
# Chebyshev collocation of the linearised periodic system along the orbit's segments
# ----------------------------------------------------------------------------------------
def cheb(N):
    x = np.cos(np.pi * np.arange(N + 1) / N)
    c = np.hstack([2, np.ones(N - 1), 2]) * (-1) ** np.arange(N + 1)
    X = np.tile(x, (N + 1, 1)).T
    dX = X - X.T
    D = np.outer(c, 1 / c) / (dX + np.eye(N + 1))
    D = D - np.diag(D.sum(axis=1))
    return D, x


def clencurt(N):
    theta = np.pi * np.arange(N + 1) / N
    w = np.zeros(N + 1)
    ii = np.arange(1, N)
    v = np.ones(N - 1)
    if N % 2 == 0:
        w[0] = 1 / (N ** 2 - 1); w[N] = w[0]
        for k in range(1, N // 2):
            v = v - 2 * np.cos(2 * k * theta[ii]) / (4 * k * k - 1)
        v = v - np.cos(N * theta[ii]) / (N ** 2 - 1)
    else:
        w[0] = 1 / N ** 2; w[N] = w[0]
        for k in range(1, (N - 1) // 2 + 1):
            v = v - 2 * np.cos(2 * k * theta[ii]) / (4 * k * k - 1)
    w[ii] = 2 * v / N
    return w


class Colloc:
    """Orbit sampled on Chebyshev-Lobatto nodes of every segment between events."""

    def __init__(self, M, mode0, x0, N):
        self.M, self.N = M, N
        _, _, ev, segs = integrate(M, mode0, 0.0, M.T, x0, rtol=1e-13, atol=1e-15, dense=True)
        self.ev = ev
        D, xs = cheb(N)
        w = clencurt(N)
        self.segs = []
        for (mode, a, b, sol) in segs:
            L = b - a
            t = (a + b) / 2 + L / 2 * xs  # node 0 is t = b, node N is t = a
            X = np.array([sol(tt) for tt in t])
            self.segs.append(dict(mode=mode, a=a, b=b, L=L, t=t, X=X, D=D * 2 / L, w=w * L / 2,
                                  A=[M.A(mode, tt, xx) for tt, xx in zip(t, X)],
                                  B=[M.B(mode, tt, xx) for tt, xx in zip(t, X)]))

    def solve(self, W, rhs_B=True, p0=None, periodic=True):
        M, N = self.M, self.N
        n = M.n
        ns = len(self.segs)
        sz = n * (N + 1)
        K = np.zeros((ns * sz, ns * sz), complex)
        ncol = 1 if p0 is None else p0.shape[1]
        R = np.zeros((ns * sz, ncol), complex)
        for s, sg in enumerate(self.segs):
            o = s * sz
            for k in range(N):  # ODE rows at every node except t = a
                for i in range(n):
                    row = o + k * n + i
                    for jn in range(N + 1):
                        K[row, o + jn * n + i] += sg["D"][k, jn]
                    K[row, o + k * n:o + k * n + n] -= sg["A"][k][i]
                    K[row, o + k * n + i] += 1j * W
                    if rhs_B:
                        R[row, :] = sg["B"][k][i]
            # start row: p(a) = S p_prev(b)  (or p(0) = p(T) / p0)
            for i in range(n):
                row = o + N * n + i
                K[row, o + N * n + i] = 1.0
            if s == 0:
                if periodic:
                    last = (ns - 1) * sz
                    K[o + N * n:o + N * n + n, last:last + n] -= np.eye(n)
                else:
                    R[o + N * n:o + N * n + n, :] = p0
            else:
                S = self.ev[s - 1]["S"]
                prev = (s - 1) * sz
                K[o + N * n:o + N * n + n, prev:prev + n] -= S
        P = np.linalg.solve(K, R)
        return P

    def monodromy(self):
        n = self.M.n
        P = self.solve(0.0, rhs_B=False, p0=np.eye(n), periodic=False)
        last = (len(self.segs) - 1) * self.M.n * (self.N + 1)
        return P[last:last + n, :].real

    def htf(self, W, n_harm):
        M, N = self.M, self.N
        n = M.n
        P = self.solve(W)[:, 0]
        om = W + n_harm * M.wp
        sz = n * (N + 1)
        G = np.zeros(len(M.outputs), complex)
        for s, sg in enumerate(self.segs):
            p = P[s * sz:(s + 1) * sz].reshape(N + 1, n)
            for io, o in enumerate(M.outputs):
                y = np.array([o.C(sg["mode"], tt, xx) @ p[k] + o.D(sg["mode"], tt, xx)
                              for k, (tt, xx) in enumerate(zip(sg["t"], sg["X"]))])
                G[io] += np.sum(sg["w"] * y * np.exp(-1j * M.wp * n_harm * sg["t"])) / M.T
        # pulse term of outputs that jump: -(jump of y) * dtau * exp(-j om t_e) / T, dtau = -grad h . dx(t_e-) / hdot
        pulse = np.zeros(len(M.outputs), complex)
        for s, e in enumerate(self.ev):
            pm = P[s * sz:s * sz + n]  # node 0 of segment s is its end, t = t_e
            dtau = -(e["guard"].hx(e["t"], e["xm"]) @ (np.exp(1j * W * e["t"]) * pm)) / e["den"]
            for io, o in enumerate(M.outputs):
                jump = o.y(e["to"], e["t"], e["xp"], 0.0) - o.y(e["frm"], e["t"], e["xm"], 0.0)
                pulse[io] += -jump * dtau * np.exp(-1j * om * e["t"]) / M.T
        self.last_pulse = pulse
        return G


# ----------------------------------------------------------------------------------------
# closed form for the LIF neuron (piecewise linear flow with sinusoidal drive)
# ----------------------------------------------------------------------------------------
def lif_closed_form(M):
    P = M.P
    tau, I0, A, vth, vr, taus, T = (P[k] for k in ("tau", "I0", "A", "vth", "vr", "taus", "T"))
    wp = M.wp
    # augmented z = [v, s, cos(wp t), sin(wp t), 1]
    Aa = np.zeros((5, 5))
    Aa[0, 0] = -1 / tau; Aa[0, 2] = A / tau; Aa[0, 4] = I0 / tau
    Aa[1, 0] = 1 / taus; Aa[1, 1] = -1 / taus
    Aa[2, 3] = -wp; Aa[3, 2] = wp
    E = expm(Aa * T)
    Ef = lambda L: expm(Aa * L)

    def vend(te):  # v just before the next spike, T after a spike at te (v does not depend on s)
        z = np.array([vr, 0.0, math.cos(wp * te), math.sin(wp * te), 1.0])
        return (E @ z)[0] - vth

    grid = np.linspace(0, T, 2001)
    vals = [vend(t) for t in grid]
    roots = []
    for i in range(len(grid) - 1):
        if vals[i] == 0 or vals[i] * vals[i + 1] < 0:
            roots.append(brentq(vend, grid[i], grid[i + 1], xtol=1e-16, rtol=1e-15, maxiter=200))
    sols = []
    for te in roots:
        # s after the spike: s_e = E[1,:] z  =>  (1 - E11) s_e = E10 vr + E12 c + E13 s + E14
        c, sn = math.cos(wp * te), math.sin(wp * te)
        se = (E[1, 0] * vr + E[1, 2] * c + E[1, 3] * sn + E[1, 4]) / (1 - E[1, 1])
        Ie = I0 + A * c
        fm = np.array([(Ie - vth) / tau, (vth - se) / taus])
        fp = np.array([(Ie - vr) / tau, (vr - se) / taus])
        DR = np.diag([0.0, 1.0])
        S = DR + np.outer(fp - DR @ fm, [1.0, 0.0]) / fm[0]
        As = Aa[:2, :2]
        Mon = expm(As * (T - te)) @ S @ expm(As * te)
        z0 = Ef(T - te) @ np.array([vr, se, c, sn, 1.0])
        # admissible: v < vth on the whole flight (no other crossing) and crossing upward
        ts = np.linspace(0, 0.97 * T, 4001)[1:]
        vv = np.array([(Ef(L) @ np.array([vr, se, c, sn, 1.0]))[0] for L in ts])
        ok = fm[0] > 0 and np.all(vv < vth) and all((Ef(L) @ np.array([vr, se, c, sn, 1.0]))[0] < vth for L in np.linspace(0.97 * T, T, 400)[:-1])
        mu = eigvals(Mon)
        sols.append(dict(te=te, se=se, S=S, Mon=Mon, x0=z0[:2], ok=ok, mu=mu, fm=fm, fp=fp,
                         vmax_flight=vv.max(), stable=max(abs(mu)) < 1))
    return sols, Aa


def lif_closed_htf(M, sol, W, n_harm):
    P = M.P
    tau, taus, T = P["tau"], P["taus"], P["T"]
    wp = M.wp
    As = np.array([[-1 / tau, 0.0], [1 / taus, -1 / taus]])
    B = np.array([1 / tau, 0.0])
    te, S = sol["te"], sol["S"]

    def affine(L, p0, a):  # p' = a p + B over L
        K = np.zeros((3, 3), complex)
        K[:2, :2] = a; K[:2, 2] = B
        E = expm(K * L)
        return E[:2, :2] @ p0 + E[:2, 2], E[:2, :2]

    a = As - 1j * W * np.eye(2)
    # p(te-) = E1 p0 + c1 ; p(te+) = S p(te-) ; p(T) = E2 p(te+) + c2 = p0
    c1, E1 = affine(te, np.zeros(2), a)
    c2, E2 = affine(T - te, np.zeros(2), a)
    Mp = E2 @ S @ E1
    p0 = np.linalg.solve(np.eye(2) - Mp, E2 @ S @ c1 + c2)
    pm = E1 @ p0 + c1
    pp = S @ pm

    def fint(t0, L, q0):  # int_0^L p(t0+s) exp(-j n wp (t0+s)) ds
        K = np.zeros((5, 5), complex)
        K[:2, :2] = As - 1j * (W + n_harm * wp) * np.eye(2)
        K[:2, 2] = B
        K[2, 2] = -1j * n_harm * wp
        K[3:5, :2] = np.eye(2)
        E = expm(K * L)
        z = E @ np.concatenate([q0, [1.0], [0, 0]])
        return z[3:5] * np.exp(-1j * n_harm * wp * t0)

    Ip = fint(0.0, te, p0) + fint(te, T - te, pp)
    G, pulse = [], []
    om = W + n_harm * wp
    dtau = -(np.exp(1j * W * te) * pm[0]) / sol["fm"][0]
    for o in M.outputs:
        Cv = o.C("main", 0, None)
        D = o.D("main", 0, None)
        G.append(Cv @ Ip / T + (D if n_harm == 0 else 0.0))
        jump = {"v": P["vr"] - P["vth"], "s": 0.0, "current": -(P["vr"] - P["vth"])}[o.name]
        pulse.append(-jump * dtau * np.exp(-1j * om * te) / T)
    return np.array(G), np.array(pulse)


# ----------------------------------------------------------------------------------------
# brute force: the nonlinear model under u = +-eps cos(W t)
# ----------------------------------------------------------------------------------------
def bruteforce(M, mode0, x0, mW, pairs, eps, settle):
    """mW: |j - 16 n|; pairs: list of (j, n) served by this run. Returns dict (j,n) -> G per output."""
    T, wp = M.T, M.wp
    W = mW * wp / 16
    oms = sorted(set(j for j, n in pairs))
    omv = np.array([j * wp / 16 for j in oms])
    no = len(M.outputs)
    res = {}
    Y = []
    for sgn in (+1, -1):
        u = lambda t, s=sgn: s * eps * math.cos(W * t)
        x, mode, _, _ = integrate(M, mode0, 0.0, settle * T, x0, u=u)
        t0 = settle * T
        L = 16 * T

        def ar(m, t, xx, a):
            uu = sgn * eps * math.cos(W * t)
            q = np.array([[o.y(m, t, xx, uu) for o in M.outputs]]).T * np.exp(-1j * omv * t)[None, :] / L
            return np.concatenate([q.real.ravel(), q.imag.ravel()])

        a0 = np.zeros(2 * no * len(omv))
        ye, _, _, _ = integrate(M, mode, t0, t0 + L, x, a0, ar, lambda g, t, xm, xp, S, a: a, u=u, aatol=1e-16)
        a = ye[M.n:]
        k = no * len(omv)
        Y.append((a[:k] + 1j * a[k:]).reshape(no, len(omv)))
    Yd = (Y[0] - Y[1]) / eps
    for (j, n) in pairs:
        res[(j, n)] = Yd[:, oms.index(j)]
    return res


# ----------------------------------------------------------------------------------------
def fdcheck(M):
    """hand-written Jacobians vs central differences at random points"""
    rng = np.random.default_rng(1)
    worst = 0.0
    for _ in range(20):
        x = rng.normal(size=M.n) * 0.5
        t = rng.uniform(0, M.T)
        for m in M.modes:
            A = M.A(m, t, x)
            for i in range(M.n):
                h = 1e-6 * max(1, abs(x[i]))
                e = np.zeros(M.n); e[i] = h
                fd = (M.f(m, t, x + e, 0) - M.f(m, t, x - e, 0)) / (2 * h)
                worst = max(worst, np.max(np.abs(fd - A[:, i])) / max(1, np.max(np.abs(A))))
            h = 1e-6
            fd = (M.f(m, t, x, h) - M.f(m, t, x, -h)) / (2 * h)
            worst = max(worst, np.max(np.abs(fd - M.B(m, t, x))))
            for o in M.outputs:
                C = o.C(m, t, x)
                for i in range(M.n):
                    hh = 1e-6 * max(1, abs(x[i]))
                    e = np.zeros(M.n); e[i] = hh
                    fd = (o.y(m, t, x + e, 0) - o.y(m, t, x - e, 0)) / (2 * hh)
                    worst = max(worst, abs(fd - C[i]) / max(1, np.max(np.abs(C))))
                fd = (o.y(m, t, x, 1e-6) - o.y(m, t, x, -1e-6)) / 2e-6
                worst = max(worst, abs(fd - o.D(m, t, x)))
        for g in M.guards:
            for i in range(M.n):
                h = 1e-6 * max(1, abs(x[i]))
                e = np.zeros(M.n); e[i] = h
                fd = (g.h(t, x + e) - g.h(t, x - e)) / (2 * h)
                worst = max(worst, abs(fd - g.hx(t, x)[i]))
                fd = (g.R(t, x + e) - g.R(t, x - e)) / (2 * h)
                worst = max(worst, np.max(np.abs(fd - g.DR(t, x)[:, i])))
            fd = (g.h(t + 1e-6, x) - g.h(t - 1e-6, x)) / 2e-6
            worst = max(worst, abs(fd - g.ht(t, x)))
    return worst


def cplx(z):
    return [float(z.real), float(z.imag)]


def run(name):
    t_start = time.time()
    M = MODELS[name]()
    T, wp, n = M.T, M.wp, M.n
    checks = []

    def chk(nm, val, tol, ok=None, detail=None):
        ok = (val <= tol) if ok is None else ok
        d = dict(name=nm, value=float(val), tolerance=tol if isinstance(tol, str) else float(tol), passed=bool(ok))
        if detail:
            d["detail"] = detail
        checks.append(d)
        print(f"  [{'ok' if ok else 'FAIL'}] {nm}: {val:.3g} (tol {tol})", flush=True)

    chk("hand-written Jacobians (A, B, C, D, grad h, dh/dt, DR) vs central differences at 20 random points per mode, max error", fdcheck(M), 1e-6)

    # ---- orbit by shooting
    x0s, mode0, Mon_var, ev, nit, resid = shoot(M)
    print(name, "shooting x0", x0s, mode0, "iters", nit, "resid", resid, flush=True)
    # ---- collocation
    C64 = Colloc(M, mode0, x0s, 64)
    C48 = Colloc(M, mode0, x0s, 48)
    Mon_col = C64.monodromy()
    Mon_col48 = C48.monodromy()
    extra = {}
    if name == "lif_neuron":
        sols, _ = lif_closed_form(M)
        adm = [s for s in sols if s["ok"]]
        st = [s for s in adm if s["stable"]]
        chk("closed form: admissible 1:1 locked solutions (one spike per period, v < vth between spikes); stable ones",
            len(st), 1, ok=(len(st) == 1),
            detail=dict(roots=[dict(t_spike=s["te"], admissible=bool(s["ok"]), max_abs_mu=float(max(abs(s["mu"])))) for s in sols]))
        cf = st[0]
        x0 = cf["x0"]
        Mon = cf["Mon"]
        chk("orbit state at t=0: closed form vs numerical shooting (event-located DOP853, rtol 1e-12) from the model file's [initial]",
            np.max(np.abs(x0 - x0s)), 1e-9)
        chk("spike time: closed form vs shooting (s)", abs(cf["te"] - ev[0]["t"]), 1e-9)
        chk("monodromy: closed form vs variational equations with saltation (DOP853), max|diff|/max|M|",
            np.max(np.abs(Mon - Mon_var)) / np.max(np.abs(Mon)), 1e-8)
        chk("monodromy: closed form vs Chebyshev collocation (64 nodes per segment), max|diff|/max|M|",
            np.max(np.abs(Mon - Mon_col)) / np.max(np.abs(Mon)), 1e-10)
        chk("no other threshold crossing: vth - max v over the first 97 % of the inter-spike interval (closed form, 4000 points)", M.P["vth"] - cf["vmax_flight"], "> 0.02",
            ok=M.P["vth"] - cf["vmax_flight"] > 0.02)
        orbit_method = "closed form: piecewise affine flow with sinusoidal drive, augmented matrix exponential; spike time the root of v(t_e + T-) = vth (Brent to 1e-16); checked by event-located DOP853 shooting"
    else:
        x0 = x0s
        Mon = Mon_col
        chk("monodromy: Chebyshev collocation (64 nodes) vs variational equations with saltation (DOP853), max|diff|/max|M|",
            np.max(np.abs(Mon - Mon_var)) / np.max(np.abs(Mon)), 1e-8)
        orbit_method = "Newton shooting (event-located DOP853, rtol 1e-12, atol 1e-14) from the model file's [initial] after 60 periods of settling"
    chk("monodromy: collocation 48 vs 64 nodes per segment, max|diff|/max|M|",
        np.max(np.abs(Mon_col48 - Mon_col)) / np.max(np.abs(Mon_col)), 1e-11)

    xT, mT, _, ev = period_map(M, mode0, x0)
    resid = np.max(np.abs(xT - x0))
    chk("periodicity residual |P(x0) - x0|_inf of the reference orbit state under the numerical period map", resid, 1e-9)
    # FD of the period map
    Mfd = np.zeros((n, n))
    for i in range(n):
        h = 1e-6 * max(1, abs(x0[i]))
        e = np.zeros(n); e[i] = h
        Mfd[:, i] = (period_map(M, mode0, x0 + e)[0] - period_map(M, mode0, x0 - e)[0]) / (2 * h)
    chk("monodromy: central differences of the simulated nonlinear period map (no saltation needed) vs reference, max|diff|/max|M|",
        np.max(np.abs(Mfd - Mon)) / np.max(np.abs(Mon)), 1e-6)
    mu = sort_mults(eigvals(Mon))
    mufd = sort_mults(eigvals(Mfd))
    chk("Floquet multipliers: reference vs eigenvalues of the central-difference period-map Jacobian, max |diff|",
        max(abs(a - b) for a, b in zip(mu, mufd)), 1e-6)
    # Liouville
    liou = 0.0
    _, _, _, segs = integrate(M, mode0, 0.0, T, x0, dense=True)
    from scipy.integrate import quad
    for (m, a, b, sol) in segs:
        liou += quad(lambda tt: np.trace(M.A(m, tt, sol(tt))), a, b, epsabs=1e-14, epsrel=1e-13, limit=200)[0]
    detS = np.prod([np.linalg.det(e["S"]) for e in ev])
    detL = math.exp(liou) * detS
    chk("det(monodromy) vs Liouville formula times the saltation determinants (relative)",
        abs(np.linalg.det(Mon) - detL) / abs(detL), 1e-9)
    mumax = max(abs(z) for z in mu)
    chk("stability: largest Floquet multiplier modulus", mumax, 0.9)
    # events
    events = []
    for e in ev:
        events.append(dict(kind=f"{e['guard'].name}: {e['frm']} -> {e['to']}", time_in_period=float(e["t"]),
                           state_before=[float(v) for v in e["xm"]], state_after=[float(v) for v in e["xp"]],
                           hdot_before=float(e["den"]),
                           saltation=[[float(v) for v in r] for r in e["S"]]))
    # transversality and grazing
    chk("transversal crossings: smallest |dh/dt| (= grad h . f- + h_t) at a crossing", min(abs(e["den"]) for e in ev),
        "> 0.3", ok=min(abs(e["den"]) for e in ev) > 0.3)
    # after a crossing the new mode's flow must also point away from the surface (no sliding)
    post = []
    for e in ev:
        fp = M.f(e["to"], e["t"], e["xp"], 0.0)
        hs = [g for g in M.guards if g.frm == e["to"]]
        for g in hs:
            post.append(abs(g.hx(e["t"], e["xp"]) @ fp + g.ht(e["t"], e["xp"])))
    # grazing: |h| at every interior turning point of a watched guard function on each segment
    tt = np.linspace(0, T, 40001)
    hmin = np.inf
    region_min = np.inf
    nturn = 0
    for (m, a, b, sol) in segs:
        ts = tt[(tt > a) & (tt < b)]
        for g in [g for g in M.guards if g.frm == m]:
            if len(ts) > 2:
                hv = np.array([g.h(t_, sol(t_)) for t_ in ts])
                dh = np.diff(hv)
                idx = np.where(np.sign(dh[1:]) != np.sign(dh[:-1]))[0] + 1
                nturn += len(idx)
                if len(idx):
                    hmin = min(hmin, np.min(np.abs(hv[idx])))
        if M.regions:
            region_min = min(region_min, min(M.regions[m](sol(t_)) for t_ in ts))
    if nturn:
        chk("no grazing: min |h| of the watched guards at their interior turning points (40000-point grid)", hmin, "> 0.05",
            ok=hmin > 0.05, detail=dict(turning_points=nturn))
    else:
        chk("no grazing: number of interior turning points of the watched guard functions (each is monotone between crossings; 40000-point grid)",
            nturn, 0)
    if M.regions:
        chk("orbit inside the region of its mode at every sampled time (min signed distance, rad)", region_min, "> 0", ok=region_min > 0)
    if name == "rimless_wheel":
        ommin = min(np.min([sol(t_)[1] for t_ in tt[(tt > a) & (tt < b)]]) for (m, a, b, sol) in segs)
        chk("stance angular velocity stays positive (the wheel never rolls back), min om (rad/s)", ommin, "> 0", ok=ommin > 0.1)
    if name == "pendulum_stops":
        mx = 0.0
        for (m, a, b, sol) in segs:
            for t_ in np.linspace(a, b, 200):
                x_ = sol(t_)
                mx = max(mx, abs(M.literal["stop_torque"](t_, x_) - M.outputs[1].y(m, t_, x_, 0.0)))
        chk("model file's stop_torque expression (pos/min) equals the per-mode form on the orbit, max|diff| (N m)", mx, 1e-12)
    # several starts
    starts = {"lif_neuron": [[0.0, 0.0], [0.9, 1.0], [0.3, -0.5]],
              "rimless_wheel": [[-0.3, 0.8], [0.0, 1.5], [-0.2, 1.2]],
              "pendulum_stops": [[0.3, 1.0], [-0.4, -2.0], [0.1, 3.0]]}[name]
    dmax = 0.0
    for s0 in starts:
        xs, ms, _, _ = integrate(M, M.init_mode, 0.0, 80 * T, np.array(s0, float), rtol=1e-11, atol=1e-13)
        dmax = max(dmax, np.max(np.abs(xs - x0)) if ms == mode0 else np.inf)
    chk("stability from several starts: max distance from the orbit state after 80 periods", dmax, 1e-6,
        detail=dict(starts=starts))

    # ---- HTFs
    htf = {o.name: [] for o in M.outputs}
    allG = {}
    for j in JS:
        om = wp * j / 16
        for nh in NS:
            W = om - nh * wp
            Gv, pulse, _ = htf_variational(M, mode0, x0, W, nh)
            Gc48 = C48.htf(W, nh)
            Gc = C64.htf(W, nh)
            if name == "lif_neuron":
                Gm, pulse_cf = lif_closed_htf(M, cf, W, nh)
            else:
                Gm, pulse_cf = Gc, C64.last_pulse
            allG[(j, nh)] = dict(main=Gm, var=Gv, col=Gc, col48=Gc48, pulse=pulse_cf, pulse_var=pulse)
    # brute force
    eps = {"lif_neuron": 3e-4, "rimless_wheel": 3e-4, "pendulum_stops": 3e-4}[name]
    settle = int(math.ceil(math.log(1e-11) / math.log(mumax))) + 2
    runs = {}
    for j in JS:
        for nh in NS:
            runs.setdefault(abs(j - 16 * nh), []).append((j, nh))
    bf = {}
    for mW, pairs in sorted(runs.items()):
        bf.update(bruteforce(M, mode0, x0, mW, pairs, eps, settle))
    print("  brute force done", time.time() - t_start, flush=True)
    no = len(M.outputs)
    maxabs = [max(abs(allG[k]["main"][i]) for k in allG) for i in range(no)]
    worst = dict(var=0, col=0, col48=0, bf=0, pulse=0, var_el=0, bf_el=0)
    worst_el = None
    for (j, nh), d in allG.items():
        om = wp * j / 16
        for i, o in enumerate(M.outputs):
            g = d["main"][i]
            ref_bf = g + (d["pulse"][i] if o.jumps else 0)
            e_var = abs(d["var"][i] - g) / maxabs[i]
            e_col = abs(d["col"][i] - g) / maxabs[i]
            e_48 = abs(d["col48"][i] - d["col"][i]) / maxabs[i]
            e_bf = abs(bf[(j, nh)][i] - ref_bf) / maxabs[i]
            e_pl = abs(d["pulse"][i] - d["pulse_var"][i]) / maxabs[i]
            worst["var"] = max(worst["var"], e_var)
            worst["col"] = max(worst["col"], e_col)
            worst["col48"] = max(worst["col48"], e_48)
            worst["pulse"] = max(worst["pulse"], e_pl)
            if e_bf > worst["bf"]:
                worst["bf"] = e_bf
                worst_el = (j, nh, i)
            if abs(g) > 1e-12 * maxabs[i]:
                worst["var_el"] = max(worst["var_el"], abs(d["var"][i] - g) / abs(g))
            if abs(ref_bf) > 1e-3 * maxabs[i]:
                worst["bf_el"] = max(worst["bf_el"], abs(bf[(j, nh)][i] - ref_bf) / abs(ref_bf))
            row = dict(omega=om, n=nh, input_omega=om - nh * wp, re=float(g.real), im=float(g.imag), abs=float(abs(g)),
                       variational_ode=cplx(d["var"][i]), collocation=cplx(d["col"][i]), bruteforce=cplx(bf[(j, nh)][i]))
            if o.jumps:
                row["pulse"] = cplx(d["pulse"][i])
                row["bruteforce_expected"] = cplx(ref_bf)
            row["err_variational_rel_max"] = e_var
            row["err_collocation_rel_max"] = e_col
            row["err_bruteforce_rel_max"] = e_bf
            htf[o.name].append(row)
    main_name = "closed form" if name == "lif_neuron" else "collocation (64 nodes)"
    chk(f"HTF: main ({main_name}) vs periodic response of the variational ODE integrated by DOP853 (max|diff|/max|G| over outputs, n, omega)",
        worst["var"], 1e-8)
    if name == "lif_neuron":
        chk("HTF: closed form vs Chebyshev collocation (64 nodes), max|diff|/max|G|", worst["col"], 1e-10)
    chk("HTF: collocation 48 vs 64 nodes per segment, max|diff|/max|G|", worst["col48"], 1e-11)
    chk("HTF: main vs variational ODE, worst element-wise relative error (elements with |G| > 1e-12 max|G|)", worst["var_el"], 1e-6)
    if any(o.jumps for o in M.outputs):
        chk("pulse term of the jumping outputs: main (closed form / collocation) vs variational ODE, max|diff|/max|G|", worst["pulse"], 1e-8)
    chk(f"HTF: main (+ pulse term for outputs that jump) vs brute-force nonlinear simulation, u = +-eps cos(W t), eps = {eps}, settle {settle} periods, 16-period window (max|diff|/max|G|)",
        worst["bf"], 1e-4)
    chk("HTF: brute force, worst element-wise relative error (elements with |G| > 1e-3 max|G|)", worst["bf_el"], 1e-3)
    # Richardson at the worst brute-force element
    j, nh, i = worst_el
    mW = abs(j - 16 * nh)
    b3 = bruteforce(M, mode0, x0, mW, [(j, nh)], 3 * eps, settle)[(j, nh)][i]
    b1 = bf[(j, nh)][i]
    d = allG[(j, nh)]
    ref = d["main"][i] + (d["pulse"][i] if M.outputs[i].jumps else 0)
    ratio = abs(b3 - ref) / abs(b1 - ref)
    rich = abs((9 * b1 - b3) / 8 - ref) / maxabs[i]
    chk(f"HTF brute force at its worst element (output {M.outputs[i].name}, omega = {wp * j / 16:.4g}, n = {nh}): error growth from eps to 3 eps (eps^2 law: 9)",
        ratio, "6 .. 12", ok=6 < ratio < 12)
    chk("  same element: error of the Richardson extrapolation (9 G(eps) - G(3 eps))/8 / max|G|", rich, 1e-7)

    out = dict(model=name, model_file=f"{name}.toml", parameters=M.P, period=T, omega_p=wp, states=M.states,
               outputs=[o.name for o in M.outputs],
               orbit_state_phase0=[float(v) for v in x0], mode_phase0=mode0,
               floquet_multipliers=[cplx(z) for z in mu], floquet_multipliers_abs=[float(abs(z)) for z in mu],
               floquet_order="largest modulus first (within a conjugate pair, positive imaginary part first)",
               monodromy_from_phase0=[[float(v) for v in r] for r in Mon],
               monodromy_central_differences=[[float(v) for v in r] for r in Mfd],
               htf_convention="Y(jw) = sum_n G_n(jw) U(jw - j n wp): G_n(jw) maps the input component at w - n wp to the output component at w (omega = OUTPUT frequency, rad/s); linearisation with u = 0; time origin t = 0 = phase 0 of the forcing; Fourier sign exp(-j w t). G = C(t) dx + D(t) u with the saltation matrix at every transition (docs/models.md); for an output that jumps at a transition the pulse (jump x event-time shift) is NOT included in re/im and is given separately as 'pulse'.",
               htf_method=("closed form (augmented matrix exponentials per segment, saltation at the spike, exact Fourier integrals)" if name == "lif_neuron"
                           else "Chebyshev collocation (64 Gauss-Lobatto nodes per segment between events) of the periodic response p(t) of the variational equation, saltation at each event, Clenshaw-Curtis quadrature of the Fourier integrals; orbit at the nodes from the DOP853 (rtol 1e-13) dense output"),
               htf_checks="each value also computed by (a1) the periodic response of the variational ODE integrated with DOP853 rtol 1e-12 (saltation at events), (a2) collocation (LIF only; for the others collocation is the main value), (b) brute force of the nonlinear model (for outputs that jump: compared with re/im + pulse)",
               htf_grid="output frequencies omega = wp * j / 16, j = [3, 11, 15, 21, 45]; harmonics n = -2..2",
               htf={o.name: dict(max_abs_over_grid=float(maxabs[i]), jumps_at_events=o.jumps, values=htf[o.name])
                    for i, o in enumerate(M.outputs)},
               self_checks=checks, orbit_periodicity_residual=float(resid), orbit_method=orbit_method,
               mode_sequence=[mode0] + [e["to"] for e in ev], events=events)
    if name == "lif_neuron":
        out["other_roots"] = [dict(t_spike=float(s["te"]), admissible=bool(s["ok"]), floquet_abs=[float(abs(z)) for z in s["mu"]])
                              for s in sols if s is not cf]
    with open(f"{name}.json", "w") as fh:
        json.dump(out, fh, indent=1)
    print(name, "x0", x0, "mu", mu, "events", [(e['guard'].name, e['t']) for e in ev],
          "all passed" if all(c["passed"] for c in checks) else "SOME FAILED", f"{time.time() - t_start:.0f}s", flush=True)
    return out


if __name__ == "__main__":
    names = sys.argv[1:] or list(MODELS)
    for nm in names:
        run(nm)
