#!/usr/bin/env python3
"""Independent generator of "real-like" system-identification records.

Usage:
    python3 tests/oracle/real_like/generate.py OUTDIR
    python3 tests/oracle/real_like/generate.py --search-duffing-rms   (helper, prints only)

Writes into OUTDIR:
    bouc_wen.csv           t,u,y   hysteretic oscillator (Bouc-Wen benchmark form)
    friction_stage.csv     t,u,x   PD-controlled stage with Coulomb + viscous friction
    duffing_hardening.csv  t,u,y   hardening Duffing oscillator
    truth.json             parameters, equations, self-checks

Everything is deterministic (fixed seeds).  Only numpy and scipy are used; the
code shares nothing with htfid, which it tests.  See README.md next to this
file for the exact definitions.
"""

import json
import os
import sys
import time

import numpy as np
import scipy
from scipy.integrate import solve_ivp

RTOL_MAIN = 1e-9
RTOL_CHECK = 1e-10
# atol_i = ATOL_FRAC * rtol * scale_i  (scale_i = typical magnitude of state i)
ATOL_FRAC = 1e-2

TWO_PI = 2.0 * np.pi
TINY = 1e-300   # restart value of a state component that just crossed zero


# ----------------------------------------------------------------------------
# Multisine (evaluated analytically)
# ----------------------------------------------------------------------------
class Multisine:
    """u(t) = A * sum_k cos(2 pi k f0 t + phi_k),  k = k_min..k_max (all lines),
    f0 = fs / N, phi_k ~ U[0, 2 pi) from numpy default_rng(seed),
    A = rms * sqrt(2 / K) so that the RMS over one period is exactly `rms`."""

    def __init__(self, fs, n_period, f_min, f_max, rms, seed):
        self.fs = float(fs)
        self.n_period = int(n_period)
        self.f0 = self.fs / self.n_period
        self.period = self.n_period / self.fs
        k_min = int(np.ceil(f_min / self.f0 - 1e-9))
        k_max = int(np.floor(f_max / self.f0 + 1e-9))
        self.k = np.arange(k_min, k_max + 1)
        rng = np.random.default_rng(seed)
        self.phi = rng.uniform(0.0, TWO_PI, self.k.size)
        self.rms = float(rms)
        self.amp = self.rms * np.sqrt(2.0 / self.k.size)
        self.omega = TWO_PI * self.f0 * self.k
        self.seed = seed

    def __call__(self, t):
        # reduce time modulo the period (the signal is exactly periodic)
        tm = np.fmod(t, self.period)
        return self.amp * np.cos(self.omega * tm + self.phi).sum()

    def samples(self, n_samples):
        """Values at t = n / fs, n = 0..n_samples-1, using exact integer phase
        reduction (k n mod N)."""
        out = np.empty(n_samples)
        n_all = np.arange(n_samples)
        chunk = 256
        for i in range(0, n_samples, chunk):
            n = n_all[i:i + chunk] % self.n_period
            kn = np.mod(np.outer(n, self.k), self.n_period)
            out[i:i + chunk] = self.amp * np.cos(TWO_PI * kn / self.n_period + self.phi).sum(axis=1)
        return out

    def describe(self):
        return {
            "type": "random-phase multisine, flat amplitude spectrum, all lines in band excited",
            "formula": "u(t) = A * sum_{k=k_min}^{k_max} cos(2*pi*k*f0*t + phi_k)",
            "evaluation": "analytic (sum of cosines evaluated at every ODE right-hand-side call); "
                          "no interpolation of the samples",
            "fs_Hz": self.fs,
            "period_samples": self.n_period,
            "f0_Hz": self.f0,
            "k_min": int(self.k[0]),
            "k_max": int(self.k[-1]),
            "f_min_excited_Hz": float(self.k[0] * self.f0),
            "f_max_excited_Hz": float(self.k[-1] * self.f0),
            "n_lines": int(self.k.size),
            "amplitude_per_line_A": float(self.amp),
            "rms": self.rms,
            "phases": "phi_k = numpy.random.default_rng(%d).uniform(0, 2*pi, n_lines)" % self.seed,
            "phase_seed": self.seed,
        }


def rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


def write_csv(path, header, columns):
    # "+ 0.0" turns a negative zero into 0.0 (no "-0.0" in the files)
    cols = [(np.asarray(c, dtype=float) + 0.0).tolist() for c in columns]
    with open(path, "w") as f:
        f.write(",".join(header) + "\n")
        for row in zip(*cols):
            f.write(",".join(repr(v) for v in row) + "\n")


# ----------------------------------------------------------------------------
# Record 1: Bouc-Wen
# ----------------------------------------------------------------------------
BW = dict(m=2.0, c=10.0, k=5e4, alpha=5e4, beta=1e3, gamma=0.8, delta=-1.1, nu=1.0)
BW_FS = 750.0
BW_NPER = 8192
BW_PERIODS = 5
BW_RMS = 50.0
BW_PHASE_SEED = 11
BW_NOISE_STD = 8e-7
BW_NOISE_SEED = 1
BW_SCALE = np.array([1e-3, 0.3, 60.0])   # typical |y| [m], |y'| [m/s], |z| [N]


def simulate_bouc_wen(u_fun, t_grid, rtol):
    """Piecewise-smooth integration.  nu = 1, so
         z' = y' * (alpha - beta * z * (gamma*sv + delta*sz)),  sv = sign(y'), sz = sign(z).
    Inside a segment the signs (sv, sz) are frozen, which makes the right-hand
    side a polynomial in the state (smooth); terminal events on y' = 0 and z = 0
    (direction = the one that leaves the current sign) end the segment, the
    corresponding sign is flipped and integration restarts from the located event
    state.  The true vector field is Lipschitz-continuous, so no sliding
    (Filippov) mode exists and flipping the sign at a crossing is exact.

    Grazing: a step can jump over a short excursion of y' to the wrong sign (two
    zeros inside one step, no sign change at the step ends).  To catch it, the
    extrema of y' on the side approaching zero (y'' = 0) are recorded as
    (non-terminal) events; if y' has the wrong sign at such an extremum, or at
    the end of the segment, the first zero of y' is located on the dense output
    (y' is unimodal between consecutive recorded extrema) and the integration
    restarts from there with the flipped sign.  Between zeros of y', z is
    monotone (alpha - beta*z*(gamma*sv + delta*sz) > 0 for these parameters),
    so z cannot graze.

    At every restart the component that just crossed zero is set to
    (new sign) * TINY, TINY = 1e-300 (instead of 0), so that a second crossing
    inside the very first step is seen as a proper sign change (the event root
    finder would otherwise return the starting point)."""
    p = BW
    m, c, k, alpha, beta, gamma, delta = (p[n] for n in ("m", "c", "k", "alpha", "beta", "gamma", "delta"))
    atol = ATOL_FRAC * rtol * BW_SCALE
    n = t_grid.size
    out = np.empty((n, 3))
    out[0] = 0.0
    idx = 1
    t = 0.0
    state = np.zeros(3)
    u0 = u_fun(0.0)
    sv = 1.0 if u0 >= 0 else -1.0  # y''(0) = u(0)/m, z follows y'
    sz = sv
    t_end = float(t_grid[-1])
    n_seg = 0
    n_ev_v = 0
    n_ev_z = 0
    n_graze = 0
    nfev = 0
    t_prev = -1.0
    n_stall = 0
    while idx < n:
        if n_seg > 10 * n + 1000:
            raise RuntimeError("Bouc-Wen: too many segments")
        n_stall = n_stall + 1 if t <= t_prev else 0
        if n_stall > 4:
            raise RuntimeError("Bouc-Wen: no progress at t=%r" % t)
        t_prev = t
        g = gamma * sv + delta * sz

        def rhs(tt, s, g=g):
            y, v, z = s
            return np.array([v, (u_fun(tt) - c * v - k * y - z) / m, v * (alpha - beta * z * g)])

        def ev_v(tt, s):
            return s[1]
        ev_v.terminal = True
        ev_v.direction = -sv

        def ev_z(tt, s):
            return s[2]
        ev_z.terminal = True
        ev_z.direction = -sz

        def ev_ext(tt, s):          # m*y'' ; extremum of y' approaching zero
            return u_fun(tt) - c * s[1] - k * s[0] - s[2]
        ev_ext.terminal = False
        ev_ext.direction = sv

        t_seg = t
        sol = solve_ivp(rhs, (t, t_end), state, method="DOP853", rtol=rtol, atol=atol,
                        t_eval=t_grid[idx:], events=[ev_v, ev_z, ev_ext], dense_output=True)
        n_seg += 1
        nfev += sol.nfev
        if sol.status < 0:
            raise RuntimeError("Bouc-Wen integration failed: " + sol.message)
        t_stop = float(sol.t_events[0][0]) if sol.t_events[0].size else (
            float(sol.t_events[1][0]) if sol.t_events[1].size else t_end)
        # --- grazing check: wrong sign of y' at a recorded extremum or at the stop point
        t_bad = None
        t_lo = t_seg
        for te, ye in zip(sol.t_events[2], sol.y_events[2]):
            if te <= t_seg or te > t_stop:
                continue
            if sv * ye[1] < 0.0:
                t_bad = float(te)
                break
            t_lo = float(te)
        if t_bad is None and not sol.t_events[0].size:
            y_stop = sol.sol(t_stop)
            if sv * y_stop[1] < 0.0:
                t_bad = t_stop
        if t_bad is not None:
            tt = np.linspace(t_lo, t_bad, 257)
            vv = sv * sol.sol(tt)[1]
            pos = np.nonzero(vv > 0.0)[0]
            if pos.size == 0:
                raise RuntimeError("Bouc-Wen: could not bracket grazing crossing at t=%g" % t_bad)
            j = pos[-1]
            from scipy.optimize import brentq
            t_root = brentq(lambda q: sol.sol(q)[1], tt[j], tt[j + 1], xtol=1e-15, rtol=4 * np.finfo(float).eps)
            keep = int(np.searchsorted(np.asarray(sol.t), t_root, side="right")) if len(sol.t) else 0
            if keep:
                out[idx:idx + keep] = np.asarray(sol.y)[:, :keep].T
                idx += keep
            t = float(t_root)
            state = np.array(sol.sol(t), dtype=float)
            sv = -sv
            state[1] = sv * TINY
            n_graze += 1
            continue
        m_out = len(sol.t)
        if m_out:
            out[idx:idx + m_out] = np.asarray(sol.y).T
            idx += m_out
        if sol.status == 1:
            if sol.t_events[0].size:
                t = float(sol.t_events[0][0])
                state = np.array(sol.y_events[0][0], dtype=float)
                sv = -sv
                state[1] = sv * TINY
                n_ev_v += 1
            else:
                t = float(sol.t_events[1][0])
                state = np.array(sol.y_events[1][0], dtype=float)
                sz = -sz
                state[2] = sz * TINY
                n_ev_z += 1
        else:
            break
    if idx != n:
        raise RuntimeError("Bouc-Wen: not all samples produced")
    stats = dict(segments=n_seg, velocity_zero_events=n_ev_v, z_zero_events=n_ev_z,
                 grazing_crossings_recovered=n_graze, nfev=int(nfev))
    return out, stats


def record_bouc_wen(outdir):
    ms = Multisine(BW_FS, BW_NPER, 5.0, 150.0, BW_RMS, BW_PHASE_SEED)
    n = BW_NPER * BW_PERIODS
    t = np.arange(n) / BW_FS
    u = ms.samples(n)
    timings = {}
    t0 = time.time()
    X, st = simulate_bouc_wen(ms, t, RTOL_MAIN)
    timings["main"] = time.time() - t0
    t0 = time.time()
    Xc, stc = simulate_bouc_wen(ms, t, RTOL_CHECK)
    timings["check"] = time.time() - t0
    y_clean = X[:, 0]
    noise = np.random.default_rng(BW_NOISE_SEED).normal(0.0, BW_NOISE_STD, n)
    y = y_clean + noise
    write_csv(os.path.join(outdir, "bouc_wen.csv"), ["t", "u", "y"], [t, u, y])

    p = BW
    ss = slice(BW_NPER, n)  # periods 2..5 (steady state)
    rms_y_clean = rms(y_clean)
    dy = np.max(np.abs(Xc[:, 0] - y_clean))
    k_lin = p["k"] + p["alpha"]
    wn = np.sqrt(k_lin / p["m"])
    gpd = p["gamma"] + p["delta"]
    gmd = p["gamma"] - p["delta"]
    # transient check: difference between last two periods
    per_diff = np.max(np.abs(y_clean[3 * BW_NPER:4 * BW_NPER] - y_clean[4 * BW_NPER:5 * BW_NPER]))
    truth = {
        "description": "Bouc-Wen hysteretic oscillator (Noel & Schoukens benchmark form)",
        "columns": {"t": "time [s], t = n/fs from 0", "u": "input force [N] (exact multisine sample)",
                    "y": "displacement [m] with additive white Gaussian noise"},
        "equations": [
            "m*y'' + c*y' + k*y + z = u(t)",
            "z' = alpha*y' - beta*(gamma*|y'|*|z|^(nu-1)*z + delta*y'*|z|^nu)",
            "y(0) = y'(0) = z(0) = 0",
        ],
        "parameters": {"m_kg": p["m"], "c_Ns_per_m": p["c"], "k_N_per_m": p["k"], "alpha_N_per_m": p["alpha"],
                       "beta_per_m": p["beta"], "gamma": p["gamma"], "delta": p["delta"], "nu": p["nu"]},
        "input": dict(ms.describe(), periods=BW_PERIODS, n_samples=n,
                      note="the first period is a transient and is kept in the file"),
        "sample_rate_Hz": BW_FS,
        "noise": {"on": "y", "type": "additive white Gaussian", "std_m": BW_NOISE_STD,
                  "generator": "numpy.random.default_rng(%d).normal(0, %g, n_samples)" % (BW_NOISE_SEED, BW_NOISE_STD),
                  "seed": BW_NOISE_SEED},
        "integration": {"solver": "scipy.integrate.solve_ivp DOP853", "rtol": RTOL_MAIN,
                        "atol": (ATOL_FRAC * RTOL_MAIN * BW_SCALE).tolist(),
                        "atol_rule": "atol_i = %g * rtol * scale_i, scale = [1e-3 m, 0.3 m/s, 60 N]" % ATOL_FRAC,
                        "non_smoothness": "signs of y' and z frozen per segment; terminal events at y'=0 and z=0 "
                                          "restart the integration with the flipped sign (vector field is continuous, "
                                          "no sliding mode)",
                        "stats": st},
        "small_amplitude_linear_approximation": {
            "note": "for vanishing amplitude the loop has zero area: dz/dy -> alpha, so the hysteretic force acts "
                    "as a spring alpha and dissipates nothing",
            "equation": "m*y'' + c*y' + (k + alpha)*y = u",
            "stiffness_N_per_m": k_lin,
            "natural_frequency_Hz": float(wn / TWO_PI),
            "natural_frequency_rad_s": float(wn),
            "damping_ratio": float(p["c"] / (2.0 * np.sqrt(p["m"] * k_lin))),
        },
        "large_amplitude_behaviour": {
            "gamma_plus_delta": gpd,
            "gamma_minus_delta": gmd,
            "formal_saturation_alpha_over_beta_gamma_plus_delta_N": p["alpha"] / (p["beta"] * gpd),
            "saturation": "none: gamma+delta = -0.3 < 0, so the formal limit alpha/(beta*(gamma+delta)) = -166.7 N is "
                          "negative and is not an asymptote. On loading (y'*z > 0) dz/dy = alpha + beta*|gamma+delta|*|z| "
                          "= alpha + 300*|z| grows with |z|: the loop HARDENS (the hysteretic force grows without bound, "
                          "exponentially in y on monotone loading from the origin: z = alpha/(beta*|gamma+delta|)*"
                          "(exp(beta*|gamma+delta|*y) - 1) = 166.67*(exp(300*y) - 1) N). On unloading (y'*z < 0) "
                          "dz/dy = alpha + beta*(gamma-delta)*|z| = alpha + 1900*|z| (steeper still), so the loop is "
                          "traversed in the dissipative sense (loading branch above unloading branch).",
            "loading_tangent_stiffness": "alpha + beta*|gamma+delta|*|z| = 5e4 + 300*|z| N/m",
            "unloading_tangent_stiffness": "alpha + beta*(gamma-delta)*|z| = 5e4 + 1900*|z| N/m",
        },
        "output_statistics": {
            "rms_y_clean_m": rms_y_clean,
            "rms_y_noisy_m": rms(y),
            "rms_y_clean_steady_state_periods_2_to_5_m": rms(y_clean[ss]),
            "max_abs_y_clean_m": float(np.max(np.abs(y_clean))),
            "max_abs_z_N": float(np.max(np.abs(X[:, 2]))),
            "rms_z_N": rms(X[:, 2]),
            "rms_u_N": rms(u),
            "max_abs_y_diff_period4_vs_period5_m": float(per_diff),
            "max_beta_abs_gpd_abs_y": float(p["beta"] * abs(gpd) * np.max(np.abs(y_clean))),
        },
        "self_check": {
            "rtol_main": RTOL_MAIN, "rtol_check": RTOL_CHECK,
            "max_abs_diff_y_samples_m": float(dy),
            "max_abs_diff_y_over_rms_y": float(dy / rms_y_clean),
            "max_abs_diff_z_over_rms_z": float(np.max(np.abs(Xc[:, 2] - X[:, 2])) / rms(X[:, 2])),
            "check_run_stats": stc,
        },
    }
    return truth, timings


# ----------------------------------------------------------------------------
# Record 2: friction-dominated positioning stage under PD control
# ----------------------------------------------------------------------------
ST = dict(m=0.95, Fv=213.0, Fc=20.4, F0=-3.1)
ST_KP = 1.6e4
ST_ZETA_TARGET = 1.0
# Kd chosen so that the continuous-time linear loop m s^2 + (Fv+Kd) s + Kp has
# damping ratio 1 (critical damping): Kd = 2 sqrt(Kp m) - Fv = 33.57, rounded.
ST_KD = 34.0
ST_TS = 1e-3
ST_N = 24000
ST_Q_PER_M = 1e6          # encoder counts per metre (resolution 1e-6 m)
ST_SCALE = np.array([0.05, 0.2])  # typical |x| [m], |x'| [m/s]
ST_REF = dict(a1=0.05, f1=0.3, a2=0.02, f2=0.77, t_start=1.0, ramp=2.0, t_stop=23.0)


def smootherstep(s):
    s = np.clip(s, 0.0, 1.0)
    return s * s * s * (s * (6.0 * s - 15.0) + 10.0)


def stage_reference(t):
    R = ST_REF
    w = smootherstep((t - R["t_start"]) / R["ramp"]) * smootherstep((R["t_stop"] - t) / R["ramp"])
    tau = t - R["t_start"]
    return w * (R["a1"] * np.sin(TWO_PI * R["f1"] * tau) + R["a2"] * np.sin(TWO_PI * R["f2"] * tau))


def _advance_ivp(x, v, F, rtol, acc):
    """Integrate m x'' = F - Fv x' - Fc sign(x') over one control interval [0, Ts]
    with F = u - F0 constant.  Returns (x, v) at the end of the interval."""
    m, Fv, Fc = ST["m"], ST["Fv"], ST["Fc"]
    atol = ATOL_FRAC * rtol * ST_SCALE
    tau = 0.0
    while True:
        if v == 0.0:
            if abs(F) <= Fc:                 # stick: static friction balances F
                acc["stuck_time"] += ST_TS - tau
                return x, 0.0
            s = 1.0 if F > 0 else -1.0       # break away in the direction of F
        else:
            s = 1.0 if v > 0 else -1.0
        if acc["last_dir"] != 0.0 and s != acc["last_dir"]:
            acc["reversals"] += 1
        acc["last_dir"] = s

        def rhs(t, y, s=s):
            return np.array([y[1], (F - Fv * y[1] - Fc * s) / m])

        def ev(t, y):
            return y[1]
        ev.terminal = True
        ev.direction = -s
        sol = solve_ivp(rhs, (tau, ST_TS), np.array([x, v]), method="DOP853", rtol=rtol, atol=atol,
                        events=ev)
        acc["nfev"] += sol.nfev
        if sol.status < 0:
            raise RuntimeError("stage integration failed: " + sol.message)
        if sol.status == 1:                  # velocity reached zero inside the interval
            tau = float(sol.t_events[0][0])
            x = float(sol.y_events[0][0][0])
            v = 0.0
            acc["zero_velocity_events"] += 1
            if abs(F) <= Fc:
                acc["stick_events"] += 1
            continue
        return float(sol.y[0, -1]), float(sol.y[1, -1])


def _advance_exact(x, v, F, rtol, acc):
    """Closed-form solution of the same piecewise-linear problem (cross-check)."""
    m, Fv, Fc = ST["m"], ST["Fv"], ST["Fc"]
    tc = m / Fv
    tau = 0.0
    while True:
        if v == 0.0:
            if abs(F) <= Fc:
                acc["stuck_time"] += ST_TS - tau
                return x, 0.0
            s = 1.0 if F > 0 else -1.0
        else:
            s = 1.0 if v > 0 else -1.0
        if acc["last_dir"] != 0.0 and s != acc["last_dir"]:
            acc["reversals"] += 1
        acc["last_dir"] = s
        vinf = (F - s * Fc) / Fv
        h = ST_TS - tau
        if s * vinf < 0.0:
            tz = tc * np.log((v - vinf) / (-vinf))
            if tz <= h:
                x = x + vinf * tz + (v - vinf) * tc * (-np.expm1(-tz / tc))
                v = 0.0
                tau += tz
                acc["zero_velocity_events"] += 1
                if abs(F) <= Fc:
                    acc["stick_events"] += 1
                continue
        e = -np.expm1(-h / tc)
        return x + vinf * h + (v - vinf) * tc * e, vinf + (v - vinf) * (1.0 - e)


def simulate_stage(rtol, exact=False):
    advance = _advance_exact if exact else _advance_ivp
    Kp, Kd, F0 = ST_KP, ST_KD, ST["F0"]
    n = ST_N
    t = np.arange(n) * ST_TS
    r = stage_reference(t)
    u = np.empty(n)
    xm = np.empty(n)
    xtrue = np.empty(n)
    vtrue = np.empty(n)
    counts = np.empty(n, dtype=np.int64)
    acc = dict(stuck_time=0.0, reversals=0, last_dir=0.0, zero_velocity_events=0, stick_events=0, nfev=0)
    x, v = 0.0, 0.0
    c_prev = 0
    for i in range(n):
        xtrue[i] = x
        vtrue[i] = v
        c = int(np.round(x * ST_Q_PER_M))      # nearest encoder count
        counts[i] = c
        xm[i] = c / ST_Q_PER_M
        vm = (c - c_prev) / ST_Q_PER_M / ST_TS   # backward difference of measured position
        u[i] = Kp * (r[i] - xm[i]) - Kd * vm
        c_prev = c
        x, v = advance(x, v, u[i] - F0, rtol, acc)
    return dict(t=t, r=r, u=u, xm=xm, x=xtrue, v=vtrue, counts=counts, acc=acc)


def stage_loop_poles():
    """Discrete closed-loop poles of the linear part (Coulomb friction and
    quantisation ignored): ZOH plant m x'' + Fv x' = u, controller
    u[n] = Kp (r - x[n]) - Kd (x[n] - x[n-1]) / Ts."""
    m, Fv = ST["m"], ST["Fv"]
    Ts, Kp, Kd = ST_TS, ST_KP, ST_KD
    a = Fv / m
    e = np.exp(-a * Ts)
    # plant ZOH: [x; v]+ = Ad [x; v] + Bd u
    Ad = np.array([[1.0, (1 - e) / a], [0.0, e]])
    Bd = np.array([(Ts - (1 - e) / a) / (a * m), (1 - e) / (a * m)])
    # augmented state [x, v, x_prev]; u = -Kp x - Kd (x - x_prev)/Ts
    Kx = -(Kp + Kd / Ts)
    Kxp = Kd / Ts
    A = np.zeros((3, 3))
    A[0:2, 0:2] = Ad
    A[0:2, 0] += Bd * Kx
    A[0:2, 2] += Bd * Kxp
    A[2, 0] = 1.0
    z = np.linalg.eigvals(A)
    res = []
    for zi in sorted(z, key=lambda q: -abs(q)):
        if abs(zi) < 1e-12:
            res.append({"z": [0.0, 0.0], "note": "delay pole at origin"})
            continue
        s = np.log(zi) / Ts
        wn = abs(s)
        res.append({"z": [float(zi.real), float(zi.imag)], "s_equiv_rad_s": [float(s.real), float(s.imag)],
                    "wn_rad_s": float(wn), "zeta": float(-s.real / wn)})
    return res


def record_stage(outdir):
    timings = {}
    t0 = time.time()
    A = simulate_stage(RTOL_MAIN)
    timings["main"] = time.time() - t0
    t0 = time.time()
    B = simulate_stage(RTOL_CHECK)
    timings["check"] = time.time() - t0
    t0 = time.time()
    E = simulate_stage(None, exact=True)
    timings["closed_form"] = time.time() - t0
    write_csv(os.path.join(outdir, "friction_stage.csv"), ["t", "u", "x"], [A["t"], A["u"], A["xm"]])

    p = ST
    rms_x = rms(A["xm"])
    stuck_samples = int(np.sum(A["v"] == 0.0))
    # distance of the true position from the nearest quantisation threshold (in m)
    frac = A["x"] * ST_Q_PER_M
    dist_thr = np.abs(np.abs(frac - np.floor(frac)) - 0.5) / ST_Q_PER_M
    kd_crit = 2.0 * np.sqrt(ST_KP * p["m"]) - p["Fv"]
    zeta_cont = (p["Fv"] + ST_KD) / (2.0 * np.sqrt(ST_KP * p["m"]))
    R = ST_REF

    def cmp(X, Y):
        return {
            "max_abs_diff_x_quantised_m": float(np.max(np.abs(X["xm"] - Y["xm"]))),
            "max_abs_diff_x_quantised_over_rms_x": float(np.max(np.abs(X["xm"] - Y["xm"])) / rms_x),
            "max_abs_diff_x_unquantised_m": float(np.max(np.abs(X["x"] - Y["x"]))),
            "max_abs_diff_x_unquantised_over_rms_x": float(np.max(np.abs(X["x"] - Y["x"])) / rms_x),
            "max_abs_diff_u_N": float(np.max(np.abs(X["u"] - Y["u"]))),
            "n_samples_encoder_count_differs": int(np.sum(X["counts"] != Y["counts"])),
        }

    truth = {
        "description": "friction-dominated positioning stage (moving mass) under discrete PD position control",
        "columns": {"t": "time [s], t = n*Ts", "u": "motor force [N] applied (zero-order hold) on [t_n, t_n+Ts)",
                    "x": "encoder position [m] at t_n, quantised to 1e-6 m (nearest count), before u[n] is computed"},
        "equations": [
            "m*x'' = u - Fv*x' - Fc*sign(x') - F0          (x' != 0)",
            "x' = 0 held (stick) while |u - F0| <= Fc      (x' = 0)",
            "break-away from stick in the direction of sign(u - F0) when |u - F0| > Fc",
            "x_meas[n] = round(x(t_n)/q)*q, q = 1e-6 m",
            "u[n] = Kp*(r(t_n) - x_meas[n]) - Kd*(x_meas[n] - x_meas[n-1])/Ts,  x_meas[-1] = 0",
            "u(t) = u[n] for t in [t_n, t_n + Ts)",
            "x(0) = x'(0) = 0",
        ],
        "parameters": {"m_kg": p["m"], "Fv_Ns_per_m": p["Fv"], "Fc_N": p["Fc"], "F0_N": p["F0"],
                       "static_friction_level_N": p["Fc"],
                       "note": "no Stribeck effect: the stick threshold equals the Coulomb level Fc; the constant "
                               "offset F0 = -3.1 N enters as -F0, i.e. a +3.1 N force on the mass"},
        "controller": {"Kp_N_per_m": ST_KP, "Kd_Ns_per_m": ST_KD, "Ts_s": ST_TS,
                       "derivative": "backward difference of the quantised position, no filter",
                       "computation_delay": "none (u[n] applied from t_n)",
                       "Kd_choice": "critical damping of the continuous linear loop m s^2 + (Fv+Kd) s + Kp: "
                                    "Kd = 2*sqrt(Kp*m) - Fv = %.3f, rounded to %g" % (kd_crit, ST_KD),
                       "zeta_continuous_linear_loop": float(zeta_cont),
                       "wn_continuous_linear_loop_rad_s": float(np.sqrt(ST_KP / p["m"])),
                       "discrete_linear_loop_poles": stage_loop_poles(),
                       "quantisation": "encoder resolution 1e-6 m, round to nearest count"},
        "reference": {"formula": "r(t) = w(t)*(a1*sin(2*pi*f1*(t-t0)) + a2*sin(2*pi*f2*(t-t0))), "
                                 "w(t) = S((t-t0)/T_r)*S((t1-t)/T_r), S(s) = 6s^5-15s^4+10s^3 on [0,1] "
                                 "(0 below, 1 above)",
                      "a1_m": R["a1"], "f1_Hz": R["f1"], "a2_m": R["a2"], "f2_Hz": R["f2"],
                      "t0_s": R["t_start"], "t1_s": R["t_stop"], "T_r_s": R["ramp"],
                      "note": "r = 0 on [0, 1] s and [23, 24) s (dwell at rest); not in the CSV"},
        "sample_rate_Hz": 1.0 / ST_TS,
        "duration_s": ST_N * ST_TS,
        "n_samples": ST_N,
        "noise": "none besides the encoder quantisation (1e-6 m) of x; u is exact (the force actually applied)",
        "integration": {"solver": "scipy.integrate.solve_ivp DOP853, one call per control interval and per "
                                  "motion phase", "rtol": RTOL_MAIN,
                        "atol": (ATOL_FRAC * RTOL_MAIN * ST_SCALE).tolist(),
                        "atol_rule": "atol_i = %g * rtol * scale_i, scale = [0.05 m, 0.2 m/s]" % ATOL_FRAC,
                        "non_smoothness": "sign(x') frozen per phase; terminal event at x'=0 (direction leaving "
                                          "the current sign); at the event x' is set to 0 and the stick test "
                                          "|u-F0| <= Fc decides stick (rest of the interval, since u is constant) "
                                          "or reversal (Filippov/Karnopp stick-slip)",
                        "nfev": int(A["acc"]["nfev"])},
        "output_statistics": {
            "rms_x_m": rms_x,
            "max_abs_x_m": float(np.max(np.abs(A["xm"]))),
            "rms_u_N": rms(A["u"]),
            "max_abs_u_N": float(np.max(np.abs(A["u"]))),
            "rms_tracking_error_m": rms(A["r"] - A["x"]),
        },
        "stick_slip": {
            "fraction_samples_stuck": stuck_samples / ST_N,
            "stuck_definition": "velocity exactly zero at the sample instant t_n (state before u[n] is applied)",
            "n_samples_stuck": stuck_samples,
            "fraction_samples_stuck_while_reference_moves_1s_to_23s": float(np.mean(A["v"][1000:23000] == 0.0)),
            "fraction_time_stuck": A["acc"]["stuck_time"] / (ST_N * ST_TS),
            "velocity_reversals": int(A["acc"]["reversals"]),
            "reversal_definition": "number of changes of the direction of motion between consecutive motion "
                                   "(slip) phases, whether through a stick phase or a direct reversal",
            "zero_velocity_events_during_motion": int(A["acc"]["zero_velocity_events"]),
            "stick_events_during_motion": int(A["acc"]["stick_events"]),
        },
        "self_check": {
            "rtol_main": RTOL_MAIN, "rtol_check": RTOL_CHECK,
            "main_vs_check": cmp(A, B),
            "main_vs_closed_form": cmp(A, E),
            "closed_form_stick_slip": {"fraction_time_stuck": E["acc"]["stuck_time"] / (ST_N * ST_TS),
                                       "velocity_reversals": int(E["acc"]["reversals"])},
            "min_distance_true_x_to_quantisation_threshold_m": float(np.min(dist_thr)),
            "note": "the recorded x is quantised, so any integration difference shows up either as 0 or as >= 1e-6 m; "
                    "the unquantised difference and the distance to the nearest threshold show the margin",
        },
    }
    return truth, timings


# ----------------------------------------------------------------------------
# Record 3: Duffing oscillator (hardening)
# ----------------------------------------------------------------------------
DF = dict(m=1.0, c=0.8, k=400.0, k3=4e6)
DF_FS = 200.0
DF_NPER = 4096
DF_PERIODS = 4
DF_RMS = 0.266            # N; chosen with --search-duffing-rms (see README)
DF_PHASE_SEED = 33
DF_NOISE_STD = 1e-6
DF_NOISE_SEED = 3
DF_SCALE = np.array([3e-3, 0.05])


def simulate_duffing(u_fun, t_grid, rtol):
    p = DF
    m, c, k, k3 = p["m"], p["c"], p["k"], p["k3"]

    def rhs(t, s):
        y, v = s
        return np.array([v, (u_fun(t) - c * v - k * y - k3 * y ** 3) / m])

    sol = solve_ivp(rhs, (0.0, float(t_grid[-1])), np.zeros(2), method="DOP853", rtol=rtol,
                    atol=ATOL_FRAC * rtol * DF_SCALE, t_eval=t_grid)
    if sol.status != 0:
        raise RuntimeError("Duffing integration failed: " + sol.message)
    return sol.y.T, int(sol.nfev)


def search_duffing_rms():
    n = DF_NPER * DF_PERIODS
    t = np.arange(n) / DF_FS
    target = 0.3 * DF["k"] / DF["k3"]

    def ratio(a):
        ms = Multisine(DF_FS, DF_NPER, 1.0, 15.0, a, DF_PHASE_SEED)
        X, _ = simulate_duffing(ms, t, 1e-7)
        return DF["k3"] * np.max(np.abs(X[:, 0])) ** 2 / DF["k"]

    lo, hi = 0.05, 2.0
    for _ in range(20):
        mid = 0.5 * (lo + hi)
        if ratio(mid) < 0.3:
            lo = mid
        else:
            hi = mid
    print("rms for ratio 0.3:", 0.5 * (lo + hi), "target y_peak", np.sqrt(target))
    for a in (round(0.5 * (lo + hi), 2), round(0.5 * (lo + hi), 3)):
        print(a, ratio(a))


def record_duffing(outdir):
    ms = Multisine(DF_FS, DF_NPER, 1.0, 15.0, DF_RMS, DF_PHASE_SEED)
    n = DF_NPER * DF_PERIODS
    t = np.arange(n) / DF_FS
    u = ms.samples(n)
    timings = {}
    t0 = time.time()
    X, nfev = simulate_duffing(ms, t, RTOL_MAIN)
    timings["main"] = time.time() - t0
    t0 = time.time()
    Xc, nfevc = simulate_duffing(ms, t, RTOL_CHECK)
    timings["check"] = time.time() - t0
    y_clean = X[:, 0]
    y = y_clean + np.random.default_rng(DF_NOISE_SEED).normal(0.0, DF_NOISE_STD, n)
    write_csv(os.path.join(outdir, "duffing_hardening.csv"), ["t", "u", "y"], [t, u, y])
    p = DF
    ypk = float(np.max(np.abs(y_clean)))
    ypk_ss = float(np.max(np.abs(y_clean[DF_NPER:])))
    rms_y = rms(y_clean)
    dy = float(np.max(np.abs(Xc[:, 0] - y_clean)))
    wn = np.sqrt(p["k"] / p["m"])
    truth = {
        "description": "hardening Duffing oscillator",
        "columns": {"t": "time [s], t = n/fs from 0", "u": "input force [N] (exact multisine sample)",
                    "y": "displacement [m] with additive white Gaussian noise"},
        "equations": ["m*y'' + c*y' + k*y + k3*y^3 = u(t)", "y(0) = y'(0) = 0"],
        "parameters": {"m_kg": p["m"], "c_Ns_per_m": p["c"], "k_N_per_m": p["k"], "k3_N_per_m3": p["k3"]},
        "linear_part": {"natural_frequency_Hz": float(wn / TWO_PI), "damping_ratio": float(p["c"] / (2 * np.sqrt(p["k"] * p["m"])))},
        "input": dict(ms.describe(), periods=DF_PERIODS, n_samples=n,
                      rms_choice="RMS %g N chosen (bisection on the RMS, then rounded) so that k3*y_peak^3 is about "
                                 "30%% of k*y_peak, y_peak = max |y| (noise-free) over the whole record" % DF_RMS),
        "sample_rate_Hz": DF_FS,
        "noise": {"on": "y", "type": "additive white Gaussian", "std_m": DF_NOISE_STD,
                  "generator": "numpy.random.default_rng(%d).normal(0, %g, n_samples)" % (DF_NOISE_SEED, DF_NOISE_STD),
                  "seed": DF_NOISE_SEED},
        "integration": {"solver": "scipy.integrate.solve_ivp DOP853 (smooth right-hand side, single call)",
                        "rtol": RTOL_MAIN, "atol": (ATOL_FRAC * RTOL_MAIN * DF_SCALE).tolist(),
                        "atol_rule": "atol_i = %g * rtol * scale_i, scale = [3e-3 m, 0.05 m/s]" % ATOL_FRAC,
                        "nfev": nfev},
        "output_statistics": {
            "rms_y_clean_m": rms_y,
            "rms_y_noisy_m": rms(y),
            "rms_y_clean_steady_state_periods_2_to_4_m": rms(y_clean[DF_NPER:]),
            "max_abs_y_clean_m": ypk,
            "max_abs_y_clean_periods_2_to_4_m": ypk_ss,
            "k3_ypk2_over_k_whole_record": float(p["k3"] * ypk ** 2 / p["k"]),
            "k3_ypk2_over_k_periods_2_to_4": float(p["k3"] * ypk_ss ** 2 / p["k"]),
            "rms_k3_y3_over_rms_k_y": float(rms(p["k3"] * y_clean ** 3) / rms(p["k"] * y_clean)),
            "rms_u_N": rms(u),
            "max_abs_y_diff_period3_vs_period4_m": float(np.max(np.abs(y_clean[2 * DF_NPER:3 * DF_NPER] - y_clean[3 * DF_NPER:]))),
        },
        "self_check": {"rtol_main": RTOL_MAIN, "rtol_check": RTOL_CHECK,
                       "max_abs_diff_y_samples_m": dy,
                       "max_abs_diff_y_over_rms_y": dy / rms_y,
                       "nfev_check": nfevc},
    }
    return truth, timings


def main(argv):
    if len(argv) == 2 and argv[1] == "--search-duffing-rms":
        search_duffing_rms()
        return 0
    if len(argv) != 2:
        print(__doc__)
        return 2
    outdir = argv[1]
    os.makedirs(outdir, exist_ok=True)
    t_start = time.time()
    truth = {
        "generator": "tests/oracle/real_like/generate.py",
        "versions": {"python": sys.version.split()[0], "numpy": np.__version__, "scipy": scipy.__version__},
    }
    all_timings = {}
    for name, fn in (("friction_stage.csv", record_stage),
                     ("duffing_hardening.csv", record_duffing),
                     ("bouc_wen.csv", record_bouc_wen)):
        t0 = time.time()
        tr, tm = fn(outdir)
        truth[name] = tr
        all_timings[name] = tm
        print("%-24s done in %.1f s %s" % (name, time.time() - t0, {k: round(v, 1) for k, v in tm.items()}),
              flush=True)
    with open(os.path.join(outdir, "truth.json"), "w") as f:
        json.dump(truth, f, indent=2)
        f.write("\n")
    print("total %.1f s" % (time.time() - t_start))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
