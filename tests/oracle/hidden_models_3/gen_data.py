#!/usr/bin/env python3
"""Synthetic "measured" records of the round-3 models (numpy/scipy only).

The model, at its TRUE parameters (which differ from the model file's), is driven by its own
periodic forcing plus a random-phase multisine u(t) whose lines lie on every frequency bin of
the record (period = the record's length) inside the band, except the multiples of the
forcing frequency (those would be removed with the orbit).  The multisine is on from a pre-roll
of `preroll` forcing periods before t = 0 (starting on the orbit), so the record is the steady
response; t = 0 is phase 0 of the forcing.  White Gaussian noise of known std is added to
every output.  Columns: t, u, then the outputs by name.

Usage: python3 gen_data.py [relay_oscillator|contact_pair]   (default: both)
"""
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import hybrid  # noqa: E402
import oracle  # noqa: E402

GEN = {
    "relay_oscillator": dict(periods=200, fs=200.0, band=(0.2, 60.0), u_rms=0.3,
                             noise_std=5e-5, seed=31, preroll=20),
    "contact_pair": dict(periods=150, fs=500.0, band=(0.2, 90.0), u_rms=0.1,
                         noise_std=1e-5, seed=32, preroll=30),
    "contact_pair_linear": dict(periods=150, fs=500.0, band=(0.2, 90.0), u_rms=0.1,
                                noise_std=1e-5, seed=33, preroll=30),
}


class Multisine:
    def __init__(self, freqs, amps, phases):
        self.f = np.asarray(freqs)
        self.a = np.asarray(amps)
        self.p = np.asarray(phases)

    def __call__(self, t):
        if np.ndim(t) == 0:
            return float(np.dot(self.a, np.cos(self.f * t + self.p)))
        t = np.asarray(t)
        out = np.empty(len(t))
        for i0 in range(0, len(t), 2000):
            tt = t[i0:i0 + 2000]
            out[i0:i0 + 2000] = np.cos(np.outer(tt, self.f) + self.p) @ self.a
        return out


def make(name):
    g = GEN[name]
    s = oracle.SETUP[name]
    params = dict(s["nominal"])
    params.update(s["truth"])
    model = s["cls"](**params)
    T = model.T
    wp = 2 * np.pi / T
    L = g["periods"] * T
    N = int(round(L * g["fs"]))
    rng = np.random.default_rng(g["seed"])
    df = 2 * np.pi / L
    ks = np.arange(int(np.ceil(g["band"][0] / df)), int(np.floor(g["band"][1] / df)) + 1)
    ks = ks[ks % g["periods"] != 0]  # skip multiples of the forcing frequency
    freqs = ks * df
    phases = rng.uniform(0, 2 * np.pi, len(ks))
    amp = g["u_rms"] * np.sqrt(2.0 / len(ks))
    amps = np.full(len(ks), amp)
    u = Multisine(freqs, amps, phases)
    # orbit at the truth
    mode, x0, evs, res = hybrid.find_orbit(model, s["start"][0], s["start"][1], T)
    t_pre = -g["preroll"] * T
    t_grid = np.arange(N) / g["fs"]
    t0 = time.time()
    mode1, x1, ev_pre = hybrid.simulate(model, mode, t_pre, x0, 0.0, u=u, rtol=1e-11, atol=1e-13)
    _, _, ev_rec, X, modes = hybrid.simulate(model, mode1, 0.0, x1, t_grid[-1] + 0.5 / g["fs"],
                                             u=u, dense_t=t_grid, rtol=1e-11, atol=1e-13)
    elapsed = time.time() - t0
    Y = np.array([model.y(t_grid[i], X[i], 0.0) for i in range(N)])
    noise = rng.normal(0.0, g["noise_std"], Y.shape)
    Ym = Y + noise
    uu = u(t_grid)
    cols = ["t", "u"] + model.outputs
    data = np.column_stack([t_grid, uu, Ym])
    path = os.path.join(HERE, f"{name}-record.csv")
    with open(path, "w") as f:
        f.write(",".join(cols) + "\n")
        for row in data:
            f.write(",".join(repr(float(v)) for v in row) + "\n")
    # per-period events count, the excursion from the orbit
    tt = np.arange(N) / g["fs"]
    _, _, _, Xo, _ = hybrid.simulate(model, mode, 0.0, x0, tt[-1] + 0.5 / g["fs"], dense_t=tt)
    dev = Y - np.array([model.y(tt[i], Xo[i], 0.0) for i in range(N)])
    truth = dict(
        model=name, model_file=f"{name}.toml", record=os.path.basename(path),
        columns=cols, sample_rate=g["fs"], samples=N, duration=N / g["fs"],
        forcing_periods=g["periods"], forcing_period=T,
        time_origin="t = 0 is phase 0 of the model's forcing; the record starts in steady state",
        true_parameters=params,
        model_file_parameters=s["nominal"],
        planted_errors={k: dict(file=s["nominal"][k], truth=v,
                                relative=(v - s["nominal"][k]) / s["nominal"][k])
                        for k, v in s["truth"].items()},
        noise=dict(kind="white Gaussian, added to every output column", std=g["noise_std"],
                   seed=g["seed"]),
        input=dict(kind="random-phase multisine, u(t) = sum_l A cos(w_l t + phi_l)",
                   u_rms=g["u_rms"], amplitude_per_line=amp, lines=len(ks),
                   line_spacing_rad_s=df, band_rad_s=list(g["band"]),
                   note=("lines on every bin k*2pi/L of the record length L inside the band, "
                         "except multiples of the forcing frequency; on from t = -preroll*T"),
                   preroll_periods=g["preroll"],
                   omegas=freqs.tolist(), phases=phases.tolist()),
        orbit_state_phase0=list(map(float, x0)), orbit_mode_phase0=mode,
        events_in_record=len(ev_rec), events_per_period_on_orbit=len(evs),
        response_rms_deviation_from_orbit=list(map(float, np.sqrt(np.mean(dev ** 2, axis=0)))),
        output_std=list(map(float, np.std(Ym, axis=0))),
        integrator=dict(method="DOP853 (scipy)", rtol=1e-11, atol=1e-13, events="located"),
        simulation_seconds=elapsed,
    )
    json.dump(truth, open(os.path.join(HERE, f"{name}-truth.json"), "w"), indent=1)
    print(name, "samples", N, "events", len(ev_rec), "expected", len(evs) * g["periods"],
          "dev rms", truth["response_rms_deviation_from_orbit"], "noise", g["noise_std"],
          f"{elapsed:.1f}s")


if __name__ == "__main__":
    names = sys.argv[1:] or list(GEN)
    for n in names:
        make(n)
