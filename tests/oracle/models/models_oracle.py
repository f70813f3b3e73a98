#!/usr/bin/env python3
"""Reference numbers ("oracles") for four rhythmic hybrid models.

Writes bouncing_ball.json, flight_hopper.json, two_dof.json, closed_loop_friction.json
next to this file.  Everything is computed from the model equations (model_defs.py,
written out in README.md) with numpy / scipy / mpmath; nothing from crates/ is used.

Per model:
  orbit   A: Newton shooting on the nonlinear period map from phase 0 (DOP853,
             rtol 1e-12, event location; FD Jacobian);
          B: multiple shooting with the crossing times as unknowns (guard = 0 as
             equations), each mode integrated between exact endpoints with Radau
             (implicit, analytic Jacobian), no event location;
          C: closed form in mpmath at 30 digits (bouncing_ball, flight_hopper only).
  monodromy  variational equations (DOP853) with saltation matrices at the
             crossings; central finite differences of the nonlinear period map;
             closed form (ball, hopper); det against Liouville * prod det(S).
  HTF     1: periodic solution of the LTP linearisation driven by exp(j w_in t)
             (p = exp(-j w_in t) xi integrated over one period with the saltation
             jumps, periodicity from (I - M) p0 = q, Fourier integrals as ODE states);
          2: nonlinear hybrid model driven by +-eps cos(w_in t), periodic steady
             state by Newton shooting over q periods, Fourier projection over q T,
             odd part in eps with Richardson over (eps, 2 eps).
The script exits non-zero if any self-check fails.

Run: python3 tests/oracle/models/models_oracle.py [model ...]   (numpy, scipy, mpmath)
"""
import json
import os
import sys
import time

import mpmath as mp
import numpy as np
from scipy.integrate import solve_ivp

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

from closed_forms import ball_closed_form, hopper_closed_form  # noqa: E402
from hybrid_core import (ATOL, RTOL, find_guard, htf_ltp, htf_small_signal,  # noqa: E402
                         monodromy_fd, monodromy_variational, period_map, saltation,
                         saltation_brief, segments_from_events, shoot_orbit, simulate)
import model_defs  # noqa: E402

# Output frequencies (rad/s) of the HTF grid: (pi/2) * odd integers.  For T in {0.25,
# 0.5, 1} they are w = wp * m / q with m odd (q = 16, 8, 4), never a multiple of wp, and
# every input frequency w - n wp gives a response that is exactly q T periodic.
GRID_M = [1, 3, 5, 7, 9, 13, 19, 25]
OMEGAS = [np.pi / 2 * mm for mm in GRID_M]
NS = list(range(-3, 4))

failures = []


class Checks:
    def __init__(self, model):
        self.model = model
        self.rows = []

    def __call__(self, name, value, tol):
        value = float(value)
        ok = bool(value <= tol)
        print(f"  [{'ok' if ok else 'FAIL'}] {name}: {value:.3e} (tol {tol:.0e})")
        if not ok:
            failures.append(f"{self.model}: {name}")
        self.rows.append(dict(name=name, value=value, tolerance=float(tol), ok=ok))
        return value


def cmod(z):
    return (-abs(z), -z.imag)


def jacobian_fd_check(model, segs):
    """max relative deviation of the analytic A(t, x), B(t, x) from FD of f along the orbit."""
    n = model["n"]
    worst = 0.0
    for lo, hi, mode, xlo, _ in segs:
        md = model["modes"][mode]
        sol = solve_ivp(lambda t, x: md["f"](t, x, 0.0), (lo, hi), xlo, method="DOP853",
                        rtol=RTOL, atol=ATOL, dense_output=True)
        for t in np.linspace(lo, hi, 7)[1:-1]:
            x = sol.sol(t)
            A = md["A"](t, x)
            Afd = np.empty((n, n))
            for i in range(n):
                h = 1e-6 * max(1e-3, abs(x[i]))
                e = np.zeros(n)
                e[i] = h
                Afd[:, i] = (md["f"](t, x + e, 0.0) - md["f"](t, x - e, 0.0)) / (2 * h)
            Bfd = (md["f"](t, x, 1e-4) - md["f"](t, x, -1e-4)) / 2e-4
            scale = max(1.0, np.max(np.abs(A)))
            worst = max(worst, np.max(np.abs(A - Afd)) / scale,
                        np.max(np.abs(md["B"](t, x) - Bfd)) / max(1.0, np.max(np.abs(Bfd))))
    return worst


def orbit_multishoot(model, x0, mode0, events, method="Radau"):
    """Orbit method B: unknowns (x0, crossing times); guard = 0 and periodicity as equations."""
    n = model["n"]
    T = model["T"]
    seq = [(ev["from"], find_guard(model, ev["from"], ev["guard"])) for ev in events]
    K = len(seq)

    def integ(mode, t0, t1, x):
        md = model["modes"][mode]
        if t1 <= t0:
            return np.array(x, float)
        sol = solve_ivp(lambda t, y: md["f"](t, y, 0.0), (t0, t1), x, method=method,
                        rtol=1e-12, atol=1e-14, jac=lambda t, y: md["A"](t, y))
        return sol.y[:, -1]

    def run(z):
        x = z[:n]
        t, mode = 0.0, mode0
        res, cross = [], []
        for k, (frm, gd) in enumerate(seq):
            tk = z[n + k]
            x = integ(mode, t, tk, x)
            res.append(gd.h(tk, x))
            xa = gd.reset(tk, x)
            cross.append((tk, x.copy(), xa.copy()))
            x, t, mode = xa, tk, gd.target
        x = integ(mode, t, T, x)
        res.extend(list(x - z[:n]))
        return np.array(res), cross

    z = np.concatenate([np.array(x0, float), [ev["time"] for ev in events]])
    # perturb the start so that the Newton iteration does real work
    z = z + 1e-6
    h = np.full(n + K, 1e-7)
    J = None
    for it in range(40):
        r, _ = run(z)
        if J is None or it == 2:  # chord Newton: FD Jacobian at the first and third iterate
            J = np.empty((n + K, n + K))
            for i in range(n + K):
                e = np.zeros(n + K)
                e[i] = h[i]
                J[:, i] = (run(z + e)[0] - run(z - e)[0]) / (2 * h[i])
        dz = np.linalg.solve(J, -r)
        z = z + dz
        if np.max(np.abs(dz)) < 1e-15:
            break
    r, cross = run(z)
    return z[:n], cross, float(np.max(np.abs(r)))


def event_rows(model, events, T):
    rates = transversality(model, events)
    return [dict(time=float(ev["time"]) % T, guard=ev["guard"], **{"from": ev["from"]},
                 to=ev["to"], state_before=[float(v) for v in ev["state_before"]],
                 state_after=[float(v) for v in ev["state_after"]],
                 guard_rate=rt) for ev, rt in zip(events, rates)]


def transversality(model, events):
    """min over crossings of |dh/dt along f-| (guard speed), and of the margin after reset."""
    out = []
    for ev in events:
        gd = find_guard(model, ev["from"], ev["guard"])
        fm = model["modes"][ev["from"]]["f"](ev["time"], ev["state_before"], 0.0)
        out.append(float(gd.dh_dx(ev["time"], ev["state_before"]) @ fm
                         + gd.dh_dt(ev["time"], ev["state_before"])))
    return out


def guard_margins(model, segs, npts=2000):
    """min of every active guard over the interior of each segment (away from its ends).

    Returns the minimum of h over points at least 2 % of the segment away from the end
    where the guard fires (h must stay > 0 there, otherwise the orbit is near grazing or
    has an extra crossing).
    """
    worst = np.inf
    for lo, hi, mode, xlo, _ in segs:
        md = model["modes"][mode]
        if not md["guards"]:
            continue
        sol = solve_ivp(lambda t, x: md["f"](t, x, 0.0), (lo, hi), xlo, method="DOP853",
                        rtol=RTOL, atol=ATOL, dense_output=True)
        L = hi - lo
        ts = np.linspace(lo + 0.02 * L, hi - 0.02 * L, npts)
        for gd in md["guards"]:
            worst = min(worst, min(gd.h(t, sol.sol(t)) for t in ts))
    return float(worst)


def orbit_samples(model, segs, nsamp=16):
    """Orbit state at t = k T / nsamp, k = 0..nsamp-1 (mode and state; at a crossing time the
    state after the reset is reported)."""
    T = model["T"]
    out = []
    for kk in range(nsamp):
        t = kk * T / nsamp
        for lo, hi, mode, xlo, _ in segs:
            if lo <= t < hi:
                md = model["modes"][mode]
                if t == lo:
                    x = xlo
                else:
                    x = solve_ivp(lambda tt, y: md["f"](tt, y, 0.0), (lo, t), xlo,
                                  method="DOP853", rtol=RTOL, atol=ATOL).y[:, -1]
                out.append(dict(t=t, mode=mode, state=[float(v) for v in x]))
                break
    return out


def run_model(name, model, mode0, x_guess, settle, fd_h, eps, extra):
    T = model["T"]
    wp = 2 * np.pi / T
    q = int(round(4 / T))  # w * q T / (2 pi) = m / 4 * 4 ... integer for w = (pi/2) m
    chk = Checks(name)
    t_start = time.time()
    print(f"== {name}")

    # ---------------- orbit A: DOP853 event location + Newton shooting
    x, mode, _, _ = simulate(model, 0.0, x_guess, mode0, settle * T)
    assert mode == mode0, (mode, mode0)
    x0, events, res_a = shoot_orbit(model, x, mode0)
    segs = segments_from_events(model, x0, mode0, events)
    chk("A: DOP853 shooting residual |P(x0) - x0|", res_a, 1e-12)

    # ---------------- orbit B: Radau multiple shooting with crossing times as unknowns
    x0b, crossb, res_b = orbit_multishoot(model, x0, mode0, events)
    chk("B: Radau multiple-shooting residual", res_b, 1e-11)
    chk("max|state0 A - state0 B|", np.max(np.abs(x0 - x0b)), 1e-10)
    if events:
        chk("max|crossing time A - B| (s)",
            max(abs(ev["time"] - c[0]) for ev, c in zip(events, crossb)), 1e-10)
        chk("max|state at crossings A - B|",
            max(np.max(np.abs(ev["state_before"] - c[1])) for ev, c in zip(events, crossb)),
            1e-10)

    # ---------------- monodromy
    Phi = monodromy_variational(model, segs)
    Phi_fd = monodromy_fd(model, x0, mode0, fd_h)
    scale = max(1.0, np.max(np.abs(Phi)))
    fd_dev = chk("max|Phi variational+saltation - Phi FD of nonlinear period map| / max(1,|Phi|)",
                 np.max(np.abs(Phi - Phi_fd)) / scale, 2e-6)
    floq = sorted(np.linalg.eigvals(Phi), key=cmod)
    chk("Jacobians A(t,x), B(t,x) vs FD of f along the orbit (relative)",
        jacobian_fd_check(model, segs), 1e-7)
    if events:
        speeds = transversality(model, events)
        chk("transversality: 1 / min|d h/dt along f-| over the crossings (guard units/s)^-1",
            1.0 / min(abs(s) for s in speeds), 1e2)
        chk("guard decreasing at every crossing: max(d h/dt along f-) (must be < 0)",
            max(speeds), 0.0)
    gm = guard_margins(model, segs)
    if np.isfinite(gm):
        chk("no grazing / no missed crossing: -(min of the active guard over each segment interior, 2 % trimmed) (must be < 0)", -gm, 0.0)

    info = dict(crosscheck=dict(state0_radau_multishoot=x0b.tolist(),
                                crossing_times_radau=[float(c[0]) for c in crossb],
                                monodromy_fd_nonlinear=Phi_fd.tolist()))
    extra_out = extra(model, x0, events, segs, Phi, chk, info) if extra else {}

    # ---------------- HTF method 1 (LTP periodic solution) on the grid
    print("  HTF (LTP) ...")
    nout = np.atleast_2d(model["C"]).shape[0]
    htf_rows = []
    G = {}
    cache = {}
    for w in OMEGAS:
        for n in NS:
            w_in = w - n * wp
            key = round(w_in, 9)
            if key not in cache:
                cache[key] = htf_ltp(model, segs, w_in, NS)
            Y = cache[key]
            for o in range(nout):
                z = Y[o, NS.index(n)]
                G[(o, round(w, 9), n)] = z
                htf_rows.append(dict(output=o, omega=float(w), n=n, omega_in=float(w_in),
                                     re=float(z.real), im=float(z.imag), abs=float(abs(z))))
    g0max = [max(abs(G[(o, round(w, 9), 0)]) for w in OMEGAS) for o in range(nout)]

    # symmetry G_{-n}(-jw) = conj G_n(jw)
    sym = 0.0
    for w, n in ((OMEGAS[1], 2), (OMEGAS[4], -1), (OMEGAS[6], 0), (OMEGAS[2], 3)):
        Ym = htf_ltp(model, segs, -w + n * wp, [-n])
        for o in range(nout):
            sym = max(sym, abs(Ym[o, 0] - np.conj(G[(o, round(w, 9), n)])) / g0max[o])
    chk("symmetry max|G_-n(-jw) - conj G_n(jw)| / max|G_0|", sym, 1e-10)

    # ---------------- HTF method 2 (nonlinear small signal), every grid entry
    print("  HTF (nonlinear small signal) ...")
    need = sorted({round(abs(w - n * wp), 9) for w in OMEGAS for n in NS})
    ss_dev = 0.0
    ss_dev_norich = 0.0
    ss_res = 0.0
    ss_rows = []
    covered = set()
    for w_abs in need:
        fam = [w_abs, -w_abs]
        ns_run = list(range(-3 - 4 * q, 4 + 4 * q))
        # project on lines +-w_abs + n wp for the n that hit a grid output frequency
        Wlist, idx = [], []
        for sgn in (1, -1):
            for n in NS:
                wout = sgn * w_abs + n * wp
                for w in OMEGAS:
                    if abs(wout - w) < 1e-7:
                        Wlist.append(n)
                        idx.append((sgn, n, w))
        if not idx:
            continue
        Gr, G1, r = htf_small_signal_two(model, x0, mode0, w_abs, idx, q, Phi, eps, wp)
        ss_res = max(ss_res, r)
        for (sgn, n, w), zr, z1 in zip(idx, Gr, G1):
            for o in range(nout):
                ref = G[(o, round(w, 9), n)]
                ss_dev = max(ss_dev, abs(zr[o] - ref) / g0max[o])
                ss_dev_norich = max(ss_dev_norich, abs(z1[o] - ref) / g0max[o])
                ss_rows.append(dict(output=o, omega=float(w), n=n, omega_in=float(w - n * wp),
                                    re=float(zr[o].real), im=float(zr[o].imag)))
            covered.add((round(w, 9), n))
    chk("small-signal shooting residual (max over runs)", ss_res, 1e-12)
    chk("grid entries not covered by the small-signal check (count)",
        len(OMEGAS) * len(NS) - len(covered), 0)
    chk("small-signal (Richardson) max|G_sim - G_LTP| / max|G_0| (per output)", ss_dev, 5e-7)
    print(f"    (without Richardson: {ss_dev_norich:.2e})")

    elapsed = time.time() - t_start
    rho = max(abs(z) for z in floq)
    out = dict(
        model=model_text(name, model),
        orbit=dict(t0=0.0, mode0=mode0, state0=[float(v) for v in x0],
                   events=event_rows(model, events, T), period=T,
                   samples=orbit_samples(model, segs),
                   segments=[dict(start=float(lo), end=float(hi), mode=md)
                             for lo, hi, md, _, _ in segs]),
        floquet=[dict(re=float(z.real), im=float(z.imag), abs=float(abs(z))) for z in floq],
        spectral_radius=float(rho),
        monodromy=Phi.tolist(),
        saltation=[dict(time=float(ev["time"]), guard=ev["guard"],
                        S=saltation(model, ev["from"], find_guard(model, ev["from"], ev["guard"]),
                                    ev["time"], ev["state_before"]).tolist())
                   for ev in events],
        htf_convention=("Y(jw) = sum_n G_n(jw) U(jw - j n wp), wp = 2 pi / T. Entry (output o, "
                        "omega w, n) is G_n(j w) for output o: the response at output frequency w "
                        "to the input at omega_in = w - n wp. For u = exp(j w_in t), y_o(t) = "
                        "sum_n G_n(j(w_in + n wp)) exp(j(w_in + n wp) t), t absolute."),
        htf=htf_rows,
        htf_small_signal_nonlinear=ss_rows,
        checks=chk.rows,
        accuracy=None,
        runtime_s=None,
        **info, **extra_out)
    out["accuracy"] = (
        "Orbit (state0, crossing times, states at crossings): two independent shooting "
        "formulations agree to %.1e%s; expect ~1e-11 absolute. Monodromy/Floquet: ~1e-10 "
        "(variational DOP853 at rtol 1e-12%s); the FD-of-nonlinear-map check (%.1e) is "
        "limited by its step. HTF: LTP method at rtol 1e-12, expect ~1e-10 relative to "
        "max|G_0|; the nonlinear small-signal check agrees to %.1e of max|G_0| (limited by "
        "eps and the integrator, not by the reference)." % (
            max(r["value"] for r in chk.rows if r["name"].startswith("max|state0 A")),
            "" if "closed_form" not in extra_out else
            " and the mpmath closed form agrees to %.1e" % extra_out["closed_form"]["max_dev"],
            "" if "closed_form" not in extra_out else ", closed form agrees",
            fd_dev, ss_dev))
    out["runtime_s"] = time.time() - t_start
    path = os.path.join(HERE, name + ".json")
    with open(path, "w") as fh:
        json.dump(out, fh, indent=1)
        fh.write("\n")
    print(f"  state0 {x0.tolist()} mode0 {mode0}")
    for ev in events:
        print(f"  event {ev['guard']} at {ev['time']:.15f}")
    print(f"  floquet {[complex(z) for z in floq]} rho {rho:.6f}")
    print(f"  wrote {path} in {elapsed:.1f} s")
    return out


def htf_small_signal_two(model, x0, mode0, w_abs, idx, q, Mono, eps, wp):
    """Small-signal G at the lines sgn * w_abs + n wp listed in idx (one run per eps)."""
    n = model["n"]
    T = model["T"]
    W = [sgn * w_abs + k * wp for sgn, k, _ in idx]
    J = np.linalg.matrix_power(Mono, q) - np.eye(n)

    def coeffs(e):
        u = lambda t: e * np.cos(w_abs * t)  # noqa: E731
        x = np.array(x0, float)
        r = np.inf
        for it in range(15):
            x1, m1, _, _ = simulate(model, 0.0, x, mode0, q * T, u=u)
            assert m1 == mode0
            r = np.max(np.abs(x1 - x))
            x = x - np.linalg.solve(J, x1 - x)
            if r < 1e-14:
                break
        _, m1, _, fc = simulate(model, 0.0, x, mode0, q * T, u=u, fourier=W)
        return fc, float(r)  # fc[out, k]

    def odd(e):
        cp, rp = coeffs(e)
        cm, rm = coeffs(-e)
        # y contains (e/2) G exp(j W t) for each line; the Fourier integral returns e/2 G.
        return ((cp - cm) / e).T, max(rp, rm)

    g1, r1 = odd(eps)
    g2, r2 = odd(2 * eps)
    return (4 * g1 - g2) / 3, g1, max(r1, r2)


# ---------------------------------------------------------------- model texts

TEXTS = {
    "bouncing_ball": dict(
        states=["y (ball height, m)", "v (ball velocity, m/s)"], input="u: acceleration applied to the ball (m/s^2)",
        outputs=["y"], modes=["flight"],
        equations=["flight: y' = v, v' = -g + u",
                   "table height s(t) = A sin(2 pi t / T)",
                   "guard impact (flight -> flight): h = y - s(t), fires when h crosses from > 0 to <= 0",
                   "reset: y+ = y-, v+ = (1 + e) s'(t) - e v-  (s'(t) = A (2 pi / T) cos(2 pi t / T))",
                   "saltation includes dR/dt = (0, (1 + e) s''(t)) (time-dependent reset)"]),
    "flight_hopper": dict(
        states=["y (body height, m)", "v (velocity, m/s)"], input="u: force on the body (N)",
        outputs=["y"], modes=["flight", "stance"],
        equations=["F(t) = a (1 - cos(2 pi t / T)) / 2, GRF(t, y, v) = k (L0 - y) - c v + F(t)",
                   "flight: y' = v, m v' = -m g + u",
                   "stance: y' = v, m v' = -m g + GRF(t, y, v) + u",
                   "guard touchdown (flight -> stance): h = y - L0, fires when h crosses from > 0 to <= 0; identity reset",
                   "guard liftoff (stance -> flight): h = GRF(t, y, v), fires when h crosses from > 0 to <= 0; identity reset"]),
    "two_dof": dict(
        states=["x1", "v1", "x2", "v2"], input="u: force on mass 1 (N)", outputs=["x1", "x2"],
        modes=["up", "down"],
        equations=["x1' = v1, x2' = v2",
                   "m1 v1' = -k1 x1 - k3 x1^3 - k2 (x1 - x2) - c1 s v1 - c2 (v1 - v2) + a cos(2 pi t / T) + u",
                   "m2 v2' = -k2 (x2 - x1) - c2 (v2 - v1)",
                   "s = 1 in mode up, s = 0 in mode down",
                   "guard v1_falling (up -> down): h = v1, fires when h crosses from > 0 to <= 0; identity reset",
                   "guard v1_rising (down -> up): h = -v1, fires when h crosses from > 0 to <= 0 (v1 rising through 0); identity reset"]),
    "closed_loop_friction": dict(
        states=["x (m)", "v (m/s)"], input="u: perturbation of the reference (m)", outputs=["x"],
        modes=["single"],
        equations=["x' = v",
                   "m v' = kp (r0(t) + u - x) - kd v - Fc tanh(v / vs) - b v, r0(t) = R sin(2 pi t / T)",
                   "one mode, no guards"]),
}


def model_text(name, model):
    d = dict(TEXTS[name])
    d["parameters"] = model["params"]
    d["phase_origin"] = "t absolute; t = 0 mod T is phase 0 of the periodic forcing"
    return d


# ---------------------------------------------------------------- per-model extras

def extra_ball(model, x0, events, segs, Phi, chk, info):
    p = model["params"]
    cf = ball_closed_form(p["g"], p["e"], p["T"], p["A"], root=+1)
    cf_u = ball_closed_form(p["g"], p["e"], p["T"], p["A"], root=-1)
    ev = events[0]
    dev = max(abs(ev["time"] - float(cf["t_impact"])),
              abs(x0[0] - float(cf["y0"])), abs(x0[1] - float(cf["v0"])),
              abs(ev["state_after"][1] - float(cf["v_plus"])),
              abs(ev["state_before"][1] - float(cf["v_minus"])))
    chk("one impact per period (count - 1)", abs(len(events) - 1), 0)
    chk("max|orbit A - closed form| (t_i, y0, v0, v-, v+)", dev, 1e-11)
    Mcf = np.array(cf["monodromy"].tolist(), dtype=float)
    chk("max|Phi variational - Phi closed form|", np.max(np.abs(Phi - Mcf)), 1e-10)
    chk("|det Phi - e^2| (det S = e^2, flight det 1)", abs(np.linalg.det(Phi) - p["e"] ** 2), 1e-11)
    chk("stable root: sin(w t_i) > 0 (value -sin)", -float(cf["sin"]), 0.0)
    # The brief's saltation formula without the dR/dt term, for information.
    gd = find_guard(model, "flight", "impact")
    Sb = saltation_brief(model, "flight", gd, ev["time"], ev["state_before"])
    S = saltation(model, "flight", gd, ev["time"], ev["state_before"])
    # monodromy with the brief's S
    segs_b = [(lo, hi, md, xl, (Sb if Sx is not None else None)) for lo, hi, md, xl, Sx in segs]
    Phi_b = monodromy_variational(model, segs_b)
    fl_b = sorted(np.linalg.eigvals(Phi_b), key=cmod)
    # stable A range (closed form): rho <= 0.9
    As = np.linspace(0.0054, 0.0170, 1161)
    stab = []
    for A in As:
        w = 2 * np.pi / p["T"]
        cth = p["g"] * p["T"] * (1 - p["e"]) / (2 * (1 + p["e"]) * A * w)
        if cth > 1:
            continue
        c2 = ball_closed_form(p["g"], p["e"], p["T"], A, root=+1)
        stab.append((A, float(max(abs(z) for z in c2["floquet"]))))
    a_ok = [A for A, r in stab if r < 1]
    a_09 = [A for A, r in stab if r <= 0.9]
    print("  ball: stable A range (grid 1e-5):", a_ok[0], a_ok[-1], "rho<=0.9:", a_09[0], a_09[-1])
    return dict(
        closed_form=dict(
            t_impact=float(cf["t_impact"]), y_impact=float(cf["y_impact"]),
            v_minus=float(cf["v_minus"]), v_plus=float(cf["v_plus"]),
            cos_w_ti=float(cf["cos"]), sin_w_ti=float(cf["sin"]),
            state0=[float(cf["y0"]), float(cf["v0"])],
            monodromy=Mcf.tolist(),
            floquet=[dict(re=float(mp.re(z)), im=float(mp.im(z))) for z in cf["floquet"]],
            max_dev=dev,
            unstable_root=dict(t_impact=float(cf_u["t_impact"]), sin_w_ti=float(cf_u["sin"]),
                               floquet=[dict(re=float(mp.re(z)), im=float(mp.im(z)))
                                        for z in cf_u["floquet"]])),
        stable_A_range=dict(
            note="closed-form scan over A in [0.0054, 0.0170] step 1e-5 (T, g, e fixed)",
            stable=[a_ok[0], a_ok[-1]], spectral_radius_le_0_9=[a_09[0], a_09[-1]]),
        saltation_without_dRdt=dict(
            note=("The saltation formula without the dR/dt term (as written in the brief) is "
                  "WRONG for this model because the reset v+ = (1+e) s'(t) - e v- depends on t. "
                  "Correct: S = DR + (f+ - DR f- - dR/dt) grad h^T / (grad h . f- + dh/dt)."),
            S_correct=S.tolist(), S_without_dRdt=Sb.tolist(),
            monodromy_without_dRdt=Phi_b.tolist(),
            floquet_without_dRdt=[dict(re=float(z.real), im=float(z.imag)) for z in fl_b],
            max_abs_monodromy_difference=float(np.max(np.abs(Phi_b - Phi)))))


def extra_hopper(model, x0, events, segs, Phi, chk, info):
    p = model["params"]
    td = [e for e in events if e["guard"] == "touchdown"]
    lo = [e for e in events if e["guard"] == "liftoff"]
    chk("one touchdown and one liftoff per period (|count-1| sum)",
        abs(len(td) - 1) + abs(len(lo) - 1), 0)
    t_td, t_lo = td[0]["time"], lo[0]["time"]
    cf = hopper_closed_form(p["m"], p["g"], p["k"], p["c"], p["L0"], p["a"], p["T"],
                            (t_td, td[0]["state_before"][1], t_lo))
    chk("closed form residual", float(cf["residual"]), 1e-25)
    chk("closed form sign violations inside phases (count)", cf["sign_violations"], 0)
    dev = max(abs(t_td - float(cf["t_td"])), abs(t_lo - float(cf["t_lo"])),
              abs(x0[0] - float(cf["y0"])), abs(x0[1] - float(cf["v0"])),
              abs(td[0]["state_before"][1] - float(cf["v_td"])),
              np.max(np.abs(lo[0]["state_before"] - np.array([float(cf["X_lo"][0]),
                                                               float(cf["X_lo"][1])]))))
    chk("max|orbit A - closed form| (t_td, t_lo, state0, v_td, state at liftoff)", dev, 1e-11)
    Mcf = np.array(cf["monodromy"].tolist(), dtype=float)
    chk("max|Phi variational - Phi closed form|", np.max(np.abs(Phi - Mcf)), 1e-10)
    liou = float(mp.exp(-mp.mpf(p["c"]) / p["m"] * cf["stance_duration"]))
    chk("|det Phi - exp(-c/m * stance duration)| (det S_td = det S_lo = 1)",
        abs(np.linalg.det(Phi) - liou), 1e-11)
    chk("liftoff saltation minus identity (f+ - f- = (0, -GRF/m) = 0 on the guard)",
        np.max(np.abs(saltation(model, "stance", find_guard(model, "stance", "liftoff"),
                                t_lo, lo[0]["state_before"]) - np.eye(2))), 1e-9)
    return dict(closed_form=dict(
        t_touchdown=float(cf["t_td"]), v_touchdown=float(cf["v_td"]),
        t_liftoff=float(cf["t_lo"]), state_liftoff=[float(cf["X_lo"][0]), float(cf["X_lo"][1])],
        state0=[float(cf["y0"]), float(cf["v0"])], monodromy=Mcf.tolist(),
        floquet=[dict(re=float(mp.re(z)), im=float(mp.im(z))) for z in cf["floquet"]],
        stance_duration=float(cf["stance_duration"]), det_liouville=liou, max_dev=dev))


def extra_two_dof(model, x0, events, segs, Phi, chk, info):
    p = model["params"]
    ups = [(lo, hi) for lo, hi, md, _, _ in segs if md == "up"]
    t_up = sum(hi - lo for lo, hi in ups)
    liou = np.exp(-p["c1"] / p["m1"] * t_up - (p["c2"] / p["m1"] + p["c2"] / p["m2"]) * p["T"])
    chk("|det Phi - exp(-c1/m1 t_up - (c2/m1 + c2/m2) T)|", abs(np.linalg.det(Phi) - liou), 1e-12)
    chk("two switches per period (|count-2|)", abs(len(events) - 2), 0)
    Smax = max(np.max(np.abs(saltation(model, ev["from"], find_guard(model, ev["from"], ev["guard"]),
                                       ev["time"], ev["state_before"]) - np.eye(4)))
               for ev in events)
    chk("saltation minus identity (fields differ by (0, -c1 v1/m1, 0, 0) = 0 on v1 = 0)", Smax, 1e-9)
    return dict(det_liouville=float(liou), time_in_up=float(t_up))


def extra_friction(model, x0, events, segs, Phi, chk, info):
    p = model["params"]
    n = 2
    # Liouville: det Phi = exp(int trace A dt)
    md = model["modes"]["single"]
    sol = solve_ivp(lambda t, y: np.concatenate([md["f"](t, y[:2], 0.0), [np.trace(md["A"](t, y[:2]))]]),
                    (0, model["T"]), np.concatenate([x0, [0.0]]), method="DOP853", rtol=RTOL, atol=ATOL)
    liou = np.exp(sol.y[2, -1])
    chk("|det Phi - exp(int_0^T trace A dt)| / det", abs(np.linalg.det(Phi) - liou) / liou, 1e-9)
    # LTI self-test of the HTF machinery: Fc = 0 -> G_0 = kp / (m s^2 + (kd + b) s + kp), G_n = 0.
    lti = model_defs.closed_loop_friction(**dict(p, Fc=0.0))
    x_l, _, _ = shoot_orbit(lti, x0, "single")
    segs_l = segments_from_events(lti, x_l, "single", [])
    dev = 0.0
    for w in (OMEGAS[0], OMEGAS[4], OMEGAS[7]):
        for nn in (-2, 0, 1):
            Y = htf_ltp(lti, segs_l, w - nn * 2 * np.pi / p["T"], [nn])[0, 0]
            s = 1j * w
            ref = p["kp"] / (p["m"] * s * s + (p["kd"] + p["b"]) * s + p["kp"]) if nn == 0 else 0.0
            dev = max(dev, abs(Y - ref))
    chk("LTI self-test (Fc = 0) max|G - kp/(m s^2 + (kd+b) s + kp)|", dev, 1e-11)
    # the orbit never has v = 0 for long: report time fraction with |v| < vs
    return dict(det_liouville=float(liou))


CONFIG = {
    "bouncing_ball": dict(make=lambda: model_defs.bouncing_ball(A=0.01), mode0="flight",
                          x_guess=[0.06, -0.5], settle=120, fd_h=[1e-6, 1e-5], eps=1e-3,
                          extra=extra_ball),
    "flight_hopper": dict(make=lambda: model_defs.flight_hopper(a=80.0, T=0.5), mode0="flight",
                          x_guess=[0.74, 0.43], settle=80, fd_h=[1e-6, 1e-5], eps=1e-3,
                          extra=extra_hopper),
    "two_dof": dict(make=model_defs.two_dof, mode0="down", x_guess=[0.1, -0.05, 0.14, 0.12],
                    settle=150, fd_h=[1e-6, 1e-5, 1e-6, 1e-5], eps=2e-3, extra=extra_two_dof),
    "closed_loop_friction": dict(make=model_defs.closed_loop_friction, mode0="single",
                                 x_guess=[-0.03, 0.3], settle=30, fd_h=[1e-6, 1e-5], eps=5e-6,
                                 extra=extra_friction),
}


def main():
    names = [a for a in sys.argv[1:] if not a.startswith("-")] or list(CONFIG)
    t0 = time.time()
    for name in names:
        c = CONFIG[name]
        run_model(name, c["make"](), c["mode0"], c["x_guess"], c["settle"], c["fd_h"], c["eps"],
                  c["extra"])
    print("total runtime %.1f s" % (time.time() - t0))
    if failures:
        print("FAILED checks:")
        for f in failures:
            print("  ", f)
        sys.exit(1)


if __name__ == "__main__":
    main()
