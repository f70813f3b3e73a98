"""Generic hybrid-system machinery for the oracle (numpy/scipy only).

A model is a dict with
  n, modes: {name: dict(f, A, B, guards=[Guard...])}, C (outputs matrix), T, params.
f(t, x, u) -> dx/dt ; A(t, x) = df/dx at u = 0 ; B(t, x) = df/du.
Guard: h(t, x), dh/dx, dh/dt, target mode, reset R(t, x), DR = dR/dx, dR/dt.
A guard fires when h crosses from > 0 to <= 0 (direction -1).
"""
import numpy as np
from scipy.integrate import solve_ivp

RTOL, ATOL = 1e-12, 1e-14


class Guard:
    def __init__(self, name, h, dh_dx, dh_dt, target, reset=None, DR=None, dR_dt=None):
        self.name, self.h, self.dh_dx, self.dh_dt, self.target = name, h, dh_dx, dh_dt, target
        self.reset = reset if reset is not None else (lambda t, x: np.array(x, dtype=float))
        self.DR = DR if DR is not None else (lambda t, x: np.eye(len(x)))
        self.dR_dt = dR_dt if dR_dt is not None else (lambda t, x: np.zeros(len(x)))
        self.identity = reset is None


def simulate(model, t0, x0, mode, t1, u=None, fourier=(), method="DOP853", rtol=RTOL,
             atol=ATOL, max_events=100000):
    """Nonlinear hybrid flow with event location.

    u: callable u(t) (scalar) or None.  fourier: output frequencies W; the state is
    augmented with (1 / (t1 - t0)) int C x(t) exp(-j W t) dt (returned as complex
    array [n_out, n_W]).  Returns (x(t1), mode(t1), events, fourier_coeffs).
    events: list of dict(time, guard, from, to, state_before, state_after).
    """
    n = model["n"]
    C = np.atleast_2d(model["C"])
    nout = C.shape[0]
    W = np.asarray(fourier, dtype=float)
    nW = len(W)
    span = t1 - t0
    uf = u if u is not None else (lambda t: 0.0)
    y = np.concatenate([np.array(x0, dtype=float), np.zeros(2 * nout * nW)])
    t = t0
    events = []
    while t < t1:
        md = model["modes"][mode]
        f = md["f"]

        def rhs(tt, yy, f=f):
            dx = f(tt, yy[:n], uf(tt))
            if nW:
                ph = np.outer(C @ yy[:n], np.exp(-1j * W * tt)).ravel() / span
                return np.concatenate([dx, ph.real, ph.imag])
            return dx

        evs = []
        for gd in md["guards"]:
            ev = (lambda tt, yy, gd=gd: gd.h(tt, yy[:n]))
            ev.terminal = True
            ev.direction = -1.0
            evs.append(ev)
        sol = solve_ivp(rhs, (t, t1), y, method=method, rtol=rtol, atol=atol,
                        events=evs if evs else None)
        if sol.status == 1:
            # earliest event among guards
            k = min((i for i in range(len(evs)) if len(sol.t_events[i])),
                    key=lambda i: sol.t_events[i][0])
            gd = md["guards"][k]
            t = float(sol.t_events[k][0])
            y = np.array(sol.y_events[k][0])
            xb = y[:n].copy()
            xa = gd.reset(t, xb)
            y[:n] = xa
            events.append(dict(time=t, guard=gd.name, **{"from": mode}, to=gd.target,
                               state_before=xb, state_after=xa))
            mode = gd.target
            if len(events) > max_events:
                raise RuntimeError("too many events")
        elif sol.status == 0:
            t, y = t1, sol.y[:, -1]
        else:
            raise RuntimeError(sol.message)
    fc = None
    if nW:
        fc = (y[n:n + nout * nW] + 1j * y[n + nout * nW:]).reshape(nout, nW)
    return y[:n], mode, events, fc


def saltation(model, mode_from, guard, t, xb):
    """S = DR + (f+ - DR f- - dR/dt) grad h^T / (grad h . f- + dh/dt), u = 0."""
    gd = guard
    fm = model["modes"][mode_from]["f"](t, xb, 0.0)
    xa = gd.reset(t, xb)
    fp = model["modes"][gd.target]["f"](t, xa, 0.0)
    DR = gd.DR(t, xb)
    gh = gd.dh_dx(t, xb)
    den = gh @ fm + gd.dh_dt(t, xb)
    return DR + np.outer(fp - DR @ fm - gd.dR_dt(t, xb), gh) / den


def saltation_brief(model, mode_from, guard, t, xb):
    """The formula as written in the brief (no dR/dt term), for reporting only."""
    gd = guard
    fm = model["modes"][mode_from]["f"](t, xb, 0.0)
    xa = gd.reset(t, xb)
    fp = model["modes"][gd.target]["f"](t, xa, 0.0)
    DR = gd.DR(t, xb)
    gh = gd.dh_dx(t, xb)
    den = gh @ fm + gd.dh_dt(t, xb)
    return DR + np.outer(fp - DR @ fm, gh) / den


def find_guard(model, mode, name):
    for gd in model["modes"][mode]["guards"]:
        if gd.name == name:
            return gd
    raise KeyError(name)


def period_map(model, x0, mode0, t0=0.0, **kw):
    x, mode, evs, _ = simulate(model, t0, x0, mode0, t0 + model["T"], **kw)
    return x, mode, evs


def shoot_orbit(model, x0, mode0, tol=1e-14, maxit=30, h=None):
    """Newton shooting on the period map from phase 0 (FD Jacobian of the nonlinear map)."""
    n = model["n"]
    x0 = np.array(x0, dtype=float)
    h = np.full(n, 1e-7) if h is None else np.asarray(h)
    for it in range(maxit):
        x1, m1, _ = period_map(model, x0, mode0)
        if m1 != mode0:
            raise RuntimeError("mode at T differs from mode at 0")
        r = x1 - x0
        J = np.empty((n, n))
        for i in range(n):
            e = np.zeros(n)
            e[i] = h[i]
            xp, _, _ = period_map(model, x0 + e, mode0)
            xm, _, _ = period_map(model, x0 - e, mode0)
            J[:, i] = (xp - xm) / (2 * h[i])
        dx = np.linalg.solve(J - np.eye(n), -r)
        x0 = x0 + dx
        if np.max(np.abs(dx)) < tol * (1 + np.max(np.abs(x0))):
            break
    x1, _, evs = period_map(model, x0, mode0)
    return x0, evs, float(np.max(np.abs(x1 - x0)))


def segments_from_events(model, x0, mode0, events):
    """[(t_lo, t_hi, mode, x_at_lo, S_at_hi or None)] over [0, T]."""
    T = model["T"]
    segs = []
    t, x, mode = 0.0, np.array(x0, float), mode0
    for ev in events:
        gd = find_guard(model, ev["from"], ev["guard"])
        S = saltation(model, ev["from"], gd, ev["time"], ev["state_before"])
        segs.append((t, ev["time"], mode, x, S))
        t, x, mode = ev["time"], np.array(ev["state_after"], float), ev["to"]
    segs.append((t, T, mode, x, None))
    return segs


def monodromy_variational(model, segs):
    n = model["n"]
    Phi = np.eye(n)
    for lo, hi, mode, xlo, S in segs:
        md = model["modes"][mode]

        def rhs(t, y, md=md):
            x = y[:n]
            P = y[n:].reshape(n, n)
            return np.concatenate([md["f"](t, x, 0.0), (md["A"](t, x) @ P).ravel()])

        sol = solve_ivp(rhs, (lo, hi), np.concatenate([xlo, Phi.ravel()]), method="DOP853",
                        rtol=RTOL, atol=ATOL)
        Phi = sol.y[n:, -1].reshape(n, n)
        if S is not None:
            Phi = S @ Phi
    return Phi


def monodromy_fd(model, x0, mode0, h):
    n = model["n"]
    J = np.empty((n, n))
    for i in range(n):
        e = np.zeros(n)
        e[i] = h[i]
        xp, mp_, _ = period_map(model, x0 + e, mode0)
        xm, mm_, _ = period_map(model, x0 - e, mode0)
        assert mp_ == mode0 and mm_ == mode0
        J[:, i] = (xp - xm) / (2 * h[i])
    return J


def htf_ltp(model, segs, w_in, ns):
    """Y[out, n] = G_n(j(w_in + n wp)) of the LTP linearisation (with saltations).

    p = exp(-j w_in t) xi; Z = [homogeneous columns | particular column]; Fourier
    integrals (1/T) int C p exp(-j n wp t) dt as extra states.
    """
    n = model["n"]
    T = model["T"]
    wp = 2 * np.pi / T
    C = np.atleast_2d(model["C"])
    nout = C.shape[0]
    ns_arr = np.asarray(ns, float)
    nh = len(ns)
    Z = np.zeros((n, n + 1), complex)
    Z[:, :n] = np.eye(n)
    Q = np.zeros((nout, nh, n + 1), complex)
    for lo, hi, mode, xlo, S in segs:
        md = model["modes"][mode]

        def rhs(t, y, md=md):
            x = y[:n].real
            Zt = y[n:n + n * (n + 1)].reshape(n, n + 1)
            dZ = (md["A"](t, x) - 1j * w_in * np.eye(n)) @ Zt
            dZ[:, n] += md["B"](t, x)
            ph = np.exp(-1j * wp * ns_arr * t) / T
            CZ = C @ Zt  # nout x (n+1)
            dQ = ph[None, :, None] * CZ[:, None, :]
            return np.concatenate([md["f"](t, x, 0.0).astype(complex), dZ.ravel(), dQ.ravel()])

        y0 = np.concatenate([xlo.astype(complex), Z.ravel(), Q.ravel()])
        sol = solve_ivp(rhs, (lo, hi), y0, method="DOP853", rtol=RTOL, atol=ATOL)
        yy = sol.y[:, -1]
        Z = yy[n:n + n * (n + 1)].reshape(n, n + 1)
        Q = yy[n + n * (n + 1):].reshape(nout, nh, n + 1)
        if S is not None:
            Z = S @ Z
    p0 = np.linalg.solve(np.eye(n) - Z[:, :n], Z[:, n])
    return Q[:, :, n] + Q[:, :, :n] @ p0


def htf_small_signal(model, x0, mode0, w_in, ns, q, Mono, eps, t_start=0.0):
    """G_n(j(w_in + n wp)) from the nonlinear hybrid system driven by eps cos(w_in t).

    The response is q T periodic (w_in q T / 2 pi integer).  Periodic steady state found
    by Newton shooting over q T from t_start (Jacobian approximated by Mono^q - I; the
    fixed point itself only depends on the nonlinear simulation).  Odd part in eps,
    Richardson over eps and 2 eps.
    """
    n = model["n"]
    T = model["T"]
    wp = 2 * np.pi / T
    W = [w_in + k * wp for k in ns]
    J = np.linalg.matrix_power(Mono, q) - np.eye(n)

    def coeffs(e):
        u = lambda t: e * np.cos(w_in * t)  # noqa: E731
        x = np.array(x0, float)
        for it in range(12):
            x1, m1, _, _ = simulate(model, t_start, x, mode0, t_start + q * T, u=u)
            assert m1 == mode0
            r = x1 - x
            x = x - np.linalg.solve(J, r)
            if np.max(np.abs(r)) < 1e-15:
                break
        _, m1, _, fc = simulate(model, t_start, x, mode0, t_start + q * T, u=u, fourier=W)
        return fc, float(np.max(np.abs(r)))

    def odd(e):
        cp, rp = coeffs(e)
        cm, rm = coeffs(-e)
        return (cp - cm) / e, max(rp, rm)

    g1, r1 = odd(eps)
    g2, r2 = odd(2 * eps)
    return (4 * g1 - g2) / 3, g1, max(r1, r2)
