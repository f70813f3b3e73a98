"""Independent hybrid-system machinery (numpy/scipy only) for the round-3 hidden models.

Written from the mathematics of the two models in this folder, not from htfid's code.
A model is described by a small Python class (see models.py) giving, per mode, the vector
field f(t, x, u), its Jacobians A = df/dx and B = df/du, and guards (h, grad h, dh/dt,
direction, target mode).  Everything here uses scipy's DOP853 with event location.
"""
import numpy as np
from scipy.integrate import solve_ivp

RTOL = 1e-12
ATOL = 1e-14


def _event_fn(g, model):
    def ev(t, y):
        return g["h"](t, y[: model.n])
    ev.terminal = True
    ev.direction = {"rising": 1, "falling": -1, "either": 0}[g["direction"]]
    return ev


def simulate(model, mode, t0, x0, t1, u=None, rtol=RTOL, atol=ATOL, dense_t=None,
             max_events=100000):
    """Simulate the nonlinear hybrid model from (t0, x0) in `mode` to t1.

    u: callable u(t) (None = 0).  Returns final (mode, x), the list of events
    (t, from, to, x_before, x_after) and, when dense_t is given, the states at those times.
    """
    uf = u if u is not None else (lambda t: 0.0)
    t = t0
    x = np.array(x0, float)
    events = []
    out = None
    if dense_t is not None:
        dense_t = np.asarray(dense_t)
        out = np.full((len(dense_t), model.n), np.nan)
        modes_out = np.full(len(dense_t), -1)
    nev = 0
    while t < t1:
        guards = model.guards_from(mode)
        evs = [_event_fn(g, model) for g in guards]
        sol = solve_ivp(lambda tt, yy: model.f(mode, tt, yy, uf(tt)), (t, t1), x,
                        method="DOP853", rtol=rtol, atol=atol, events=evs,
                        dense_output=dense_t is not None)
        if not sol.success:
            raise RuntimeError(sol.message)
        t_end = sol.t[-1]
        if dense_t is not None:
            sel = (dense_t >= t) & (dense_t <= t_end)
            if sel.any():
                out[sel] = sol.sol(dense_t[sel]).T
                modes_out[sel] = model.modes.index(mode)
        fired = None
        for i, te in enumerate(sol.t_events):
            if len(te):
                fired = i
        if sol.status == 1 and fired is not None:
            g = guards[fired]
            te = sol.t_events[fired][0]
            xb = sol.y_events[fired][0].copy()
            xa = g["reset"](te, xb) if "reset" in g else xb.copy()
            events.append((te, mode, g["to"], xb, xa))
            mode = g["to"]
            # nudge: step a tiny bit so the same guard does not re-fire at once
            t, x = te, xa
            nev += 1
            if nev > max_events:
                raise RuntimeError("too many events")
        else:
            t, x = t_end, sol.y[:, -1]
            break
    if dense_t is not None:
        return mode, x, events, out, modes_out
    return mode, x, events


def saltation(model, g, t, xb, xa, mode_from, mode_to):
    """S = DR + (f_to(x+) - DR f_from(x-) - dR/dt) grad h^T / (grad h . f_from + dh/dt)."""
    n = model.n
    DR = g.get("DR", lambda t, x: np.eye(n))(t, xb)
    dRdt = g.get("dRdt", lambda t, x: np.zeros(n))(t, xb)
    fb = model.f(mode_from, t, xb, 0.0)
    fa = model.f(mode_to, t, xa, 0.0)
    gh = g["grad"](t, xb)
    ht = g["dhdt"](t, xb)
    return DR + np.outer(fa - DR @ fb - dRdt, gh) / (gh @ fb + ht)


def one_period(model, mode0, x0, T, rtol=RTOL, atol=ATOL):
    """Orbit over one period from t = 0 and its event list."""
    return simulate(model, mode0, 0.0, x0, T, rtol=rtol, atol=atol)


def find_orbit(model, mode0, x_guess, T, settle=60, tol=1e-13):
    """Settle, then Newton shooting on P(x) - x with the variational monodromy."""
    mode, x, _ = simulate(model, mode0, 0.0, x_guess, settle * T, rtol=1e-10, atol=1e-12)
    # time origin: settle*T is phase 0 of the forcing
    for it in range(30):
        m1, xT, evs = one_period(model, mode, x, T)
        r = xT - x
        M = monodromy(model, mode, x, T)
        if m1 != mode:
            raise RuntimeError("mode at T differs from mode at 0")
        dx = np.linalg.solve(M - np.eye(model.n), -r)
        x = x + dx
        if np.max(np.abs(dx)) < tol * max(1.0, np.max(np.abs(x))):
            break
    m1, xT, evs = one_period(model, mode, x, T)
    return mode, x, evs, np.max(np.abs(xT - x))


def pieces(model, mode0, x0, T):
    """The orbit's pieces [(t_start, t_end, mode, x_start)] and saltation matrices at the ends."""
    _, _, evs = one_period(model, mode0, x0, T)
    out = []
    t, mode, x = 0.0, mode0, np.array(x0, float)
    for (te, mf, mt, xb, xa) in evs:
        g = [gg for gg in model.guards_from(mf) if gg["to"] == mt and abs(gg["h"](te, xb)) < 1e-6][0]
        S = saltation(model, g, te, xb, xa, mf, mt)
        out.append((t, te, mode, x, S, (te, mf, mt, xb, xa)))
        t, mode, x = te, mt, xa
    out.append((t, T, mode, x, None, None))
    return out


def monodromy(model, mode0, x0, T):
    n = model.n
    M = np.eye(n)
    for (ta, tb, mode, xa, S, _) in pieces(model, mode0, x0, T):
        def rhs(t, y):
            x = y[:n]
            P = y[n:].reshape(n, n)
            return np.concatenate([model.f(mode, t, x, 0.0), (model.A(mode, t, x) @ P).ravel()])
        y0 = np.concatenate([xa, M.ravel()])
        sol = solve_ivp(rhs, (ta, tb), y0, method="DOP853", rtol=RTOL, atol=ATOL)
        M = sol.y[n:, -1].reshape(n, n)
        if S is not None:
            M = S @ M
    return M


def htf_column(model, mode0, x0, T, w_in, harmonics, M=None, pcs=None):
    """Steady periodic response to u = exp(j w_in t) of the linearised hybrid system.

    Returns {n: Y_n (vector over outputs)}, Y_n = G_n(j (w_in + n wp)) in the convention
    Y(jw) = sum_n G_n(jw) U(jw - j n wp).
    """
    n = model.n
    wp = 2 * np.pi / T
    if pcs is None:
        pcs = pieces(model, mode0, x0, T)
    if M is None:
        M = monodromy(model, mode0, x0, T)
    p = model.p_out

    def run(dx0, accumulate):
        dx = np.array(dx0, complex)
        z = np.zeros((len(harmonics), p), complex)
        for (ta, tb, mode, xa, S, _) in pcs:
            def rhs(t, y):
                x = y[:n].real
                d = y[n:2 * n]
                uu = np.exp(1j * w_in * t)
                fx = model.f(mode, t, x, 0.0)
                dd = model.A(mode, t, x) @ d + model.B(mode, t, x) * uu
                out = [fx.astype(complex), dd]
                if accumulate:
                    yv = model.C(mode, t, x) @ d + model.D(mode, t, x) * uu
                    for k, h in enumerate(harmonics):
                        out.append(yv * np.exp(-1j * (w_in + h * wp) * t) / T)
                return np.concatenate(out)
            y0 = np.concatenate([xa.astype(complex), dx, z.ravel() if accumulate else []])
            sol = solve_ivp(rhs, (ta, tb), y0, method="DOP853", rtol=RTOL, atol=ATOL)
            yend = sol.y[:, -1]
            dx = yend[n:2 * n]
            if accumulate:
                z = yend[2 * n:].reshape(len(harmonics), p)
            if S is not None:
                dx = S @ dx
        return dx, z

    r, _ = run(np.zeros(n), False)
    d0 = np.linalg.solve(np.exp(1j * w_in * T) * np.eye(n) - M, r)
    dT, z = run(d0, True)
    # consistency: dT should equal exp(j w T) d0
    assert np.max(np.abs(dT - np.exp(1j * w_in * T) * d0)) < 1e-7 * (1 + np.max(np.abs(d0)))
    return {h: z[k] for k, h in enumerate(harmonics)}


def htf_grid(model, mode0, x0, T, omegas, harmonics):
    """G_n(j omega) at output frequencies omega: returns array [len(omegas), len(harmonics), p]."""
    wp = 2 * np.pi / T
    pcs = pieces(model, mode0, x0, T)
    M = monodromy(model, mode0, x0, T)
    G = np.zeros((len(omegas), len(harmonics), model.p_out), complex)
    for i, w in enumerate(omegas):
        for k, h in enumerate(harmonics):
            col = htf_column(model, mode0, x0, T, w - h * wp, [h], M=M, pcs=pcs)
            G[i, k] = col[h]
    return G


def brute_force_htf(model, mode0, x0, T, p_num, q_den, eps, harmonics, settle_periods=40,
                    samples_per_period=512):
    """Nonlinear simulation with u = eps cos(w_in t), w_in = (p/q) wp, steady state over q
    periods (the response is q T periodic), central difference in eps.

    Returns {n: G_n(j (w_in + n wp))} estimated from the DFT.
    """
    wp = 2 * np.pi / T
    w_in = p_num / q_den * wp
    N = samples_per_period * q_den
    res = {}
    Ys = []
    for s in (+1, -1):
        u = lambda t, s=s: s * eps * np.cos(w_in * t)
        mode, x, _ = simulate(model, mode0, 0.0, x0, settle_periods * q_den * T, u=u,
                              rtol=1e-12, atol=1e-14)
        t0 = settle_periods * q_den * T
        tt = t0 + np.arange(N) * (q_den * T / N)
        _, _, _, X, modes = simulate(model, mode, t0, x, t0 + q_den * T, u=u, dense_t=tt,
                                     rtol=1e-12, atol=1e-14)
        Y = np.array([model.y(tt[i], X[i], u(tt[i])) for i in range(N)])
        Ys.append((tt, Y))
    (tt, Yp), (_, Ym) = Ys
    dY = (Yp - Ym) / 2.0  # odd part in eps: linear response (+ cubic)
    for h in harmonics:
        wout = w_in + h * wp
        # response to eps cos = eps/2 (e^{jwt} + e^{-jwt}); the e^{+j w_in t} part at wout
        c = np.mean(dY * np.exp(-1j * wout * tt)[:, None], axis=0)
        res[h] = c / (eps / 2)
    return res
