#!/usr/bin/env python3
"""Independent oracle for the round-3 hidden models (numpy/scipy only).

For each model, at the parameter values written in its model file (nominal) and at the true
values used to generate the measured record (truth):
  - forcing period, mode and state of the periodic orbit at t = 0 (phase 0 of the forcing),
  - the orbit's events in one period,
  - Floquet multipliers: eigenvalues of the monodromy (variational equations with a saltation
    matrix at every guard), checked against central differences of the period map,
  - HTFs G_n(j omega), n = -2..2, at output frequencies omega, for every output, in htfid's
    convention Y(jw) = sum_n G_n(jw) U(jw - j n wp) (docs/outputs.md), computed as the steady
    periodic response of the linearised hybrid system to u = exp(j w_in t),
    w_in = omega - n wp, and checked by brute force (the nonlinear model driven by
    +-eps cos(w_in t), w_in a rational multiple of wp, DFT of the steady response).

Usage:
  python3 oracle.py                 # writes relay_oscillator.json and contact_pair.json
  python3 oracle.py --at FILE.csv --model NAME --which truth|nominal --out OUT.json
                                    # HTFs at the (omega, n) rows of an htfid CSV
"""
import argparse
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import hybrid  # noqa: E402
import models  # noqa: E402

HARM = [-2, -1, 0, 1, 2]

SETUP = {
    "relay_oscillator": dict(
        cls=models.Relay,
        nominal=dict(m=1.0, k=100.0, c=4.0, F=3.0, delta=0.05, a=20.0, T=1.0),
        truth=dict(k=104.0, c=3.2),
        start=("push", [0.1, 0.0]),
        omegas=[1.5, 3.0, 5.0, 8.0, 12.0, 17.0, 23.0, 30.0, 40.0],
        brute=[(3, 5), (7, 5), (11, 5)],
        eps=0.01,
        spp=2048,
    ),
    "contact_pair": dict(
        cls=models.ContactPair,
        nominal=dict(m1=1.0, m2=0.5, k1=400.0, c1=2.0, k2=150.0, c2=1.0, kc=1.0e6, cc=20.0,
                     gap=0.005, a=12.0, T=0.5),
        truth=dict(k2=156.0, cc=16.0),
        start=("open", [0.0, 0.0, 0.0, 0.0]),
        omegas=[2.0, 5.0, 9.0, 15.0, 22.0, 30.0, 40.0, 55.0],
        brute=[(3, 5), (7, 5), (11, 5)],
        eps=0.00125,
        spp=8192,
    ),
    # added after `htfid diagnose` failed on contact_pair (Hertz contact): the same pair with a
    # linear (Kelvin-Voigt) contact, to test the diagnosis of a 4-state, 2-output model.
    "contact_pair_linear": dict(
        cls=lambda **kw: models.ContactPair(linear=1.0, **kw),
        nominal=dict(m1=1.0, m2=0.5, k1=400.0, c1=2.0, k2=150.0, c2=1.0, kc=2.0e4, cc=20.0,
                     gap=0.005, a=12.0, T=0.5),
        truth=dict(k2=156.0, cc=16.0),
        start=("open", [0.0, 0.0, 0.0, 0.0]),
        omegas=[2.0, 5.0, 9.0, 15.0, 22.0, 30.0, 40.0, 55.0],
        brute=[(3, 5)],
        eps=0.00125,
        spp=8192,
    ),
}


def cplx(z):
    return [float(np.real(z)), float(np.imag(z))]


def floquet_fd(model, mode, x0, T, h=1e-6):
    n = model.n
    J = np.zeros((n, n))
    scale = np.maximum(np.abs(x0), 1e-2)
    for i in range(n):
        dx = np.zeros(n)
        dx[i] = h * scale[i]
        _, xp, _ = hybrid.one_period(model, mode, x0 + dx, T)
        _, xm, _ = hybrid.one_period(model, mode, x0 - dx, T)
        J[:, i] = (xp - xm) / (2 * dx[i])
    return J


def sort_mult(ev):
    ev = sorted(ev, key=lambda z: (-abs(z), -z.imag))
    return ev


def analyse(name, which, check=True, log=print):
    s = SETUP[name]
    params = dict(s["nominal"])
    if which == "truth":
        params.update(s["truth"])
    model = s["cls"](**params)
    T = model.T
    wp = 2 * np.pi / T
    t0 = time.time()
    mode, x0, evs, res = hybrid.find_orbit(model, s["start"][0], s["start"][1], T)
    M = hybrid.monodromy(model, mode, x0, T)
    mult = sort_mult(list(np.linalg.eigvals(M)))
    out = dict(model=name, which=which, parameters=params, period=T,
               pumping_frequency=wp, mode_phase0=mode, state_phase0=list(map(float, x0)),
               periodicity_residual=float(res),
               events=[dict(time=float(e[0]), frm=e[1], to=e[2],
                            state_before=list(map(float, e[3]))) for e in evs],
               monodromy=M.tolist(),
               floquet_multipliers=[cplx(z) for z in mult])
    log(f"[{name}/{which}] orbit x0={x0} mode={mode} events={len(evs)} res={res:.2e}")
    log(f"[{name}/{which}] multipliers {np.round(mult, 12)}")
    if check:
        J = floquet_fd(model, mode, x0, T)
        mfd = sort_mult(list(np.linalg.eigvals(J)))
        out["floquet_multipliers_fd"] = [cplx(z) for z in mfd]
        out["monodromy_fd_max_diff"] = float(np.max(np.abs(J - M)))
        log(f"[{name}/{which}] |M - M_fd| = {out['monodromy_fd_max_diff']:.2e}")
    G = hybrid.htf_grid(model, mode, x0, T, s["omegas"], HARM)
    htf = {}
    for o, oname in enumerate(model.outputs):
        htf[oname] = {str(h): [[w, *cplx(G[i, k, o])] for i, w in enumerate(s["omegas"])]
                      for k, h in enumerate(HARM)}
    out["htf"] = htf
    out["htf_note"] = ("G_n(j omega) rows [omega, re, im]; omega is the output frequency; "
                       "Y(jw) = sum_n G_n(jw) U(jw - j n wp)")
    if check:
        bf = []
        pcs = hybrid.pieces(model, mode, x0, T)
        for (p, q) in s["brute"]:
            w_in = p / q * wp
            lin = hybrid.htf_column(model, mode, x0, T, w_in, HARM, M=M, pcs=pcs)
            brute = hybrid.brute_force_htf(model, mode, x0, T, p, q, s["eps"], HARM,
                                           settle_periods=12, samples_per_period=s["spp"])
            for h in HARM:
                for o, oname in enumerate(model.outputs):
                    a, b = lin[h][o], brute[h][o]
                    bf.append(dict(w_in=w_in, n=h, omega=w_in + h * wp, output=oname,
                                   variational=cplx(a), brute_force=cplx(b),
                                   abs_diff=float(abs(a - b))))
        scale = {o: max(abs(complex(*r[1:])) for hh in htf[o].values() for r in hh)
                 for o in model.outputs}
        worst = max(e["abs_diff"] / scale[e["output"]] for e in bf)
        out["brute_force_check"] = dict(eps=s["eps"], points=bf,
                                        worst_diff_over_max_abs_g=worst)
        log(f"[{name}/{which}] brute force vs variational: worst |diff|/max|G| = {worst:.2e}")
    out["elapsed_s"] = time.time() - t0
    return out


def at_csv(name, which, path, outpath, output_index=0):
    """HTFs at the (omega, n) rows of an htfid CSV (omega,n,re,im[,stderr])."""
    s = SETUP[name]
    params = dict(s["nominal"])
    if which == "truth":
        params.update(s["truth"])
    model = s["cls"](**params)
    T = model.T
    wp = 2 * np.pi / T
    mode, x0, evs, res = hybrid.find_orbit(model, s["start"][0], s["start"][1], T)
    M = hybrid.monodromy(model, mode, x0, T)
    pcs = hybrid.pieces(model, mode, x0, T)
    rows = np.genfromtxt(path, delimiter=",", names=True)
    cache = {}
    res_rows = []
    for r in rows:
        w, n = float(r["omega"]), int(r["n"])
        if n not in HARM:
            continue
        w_in = w - n * wp
        key = round(w_in, 12)
        if key not in cache:
            cache[key] = hybrid.htf_column(model, mode, x0, T, w_in, HARM, M=M, pcs=pcs)
        g = cache[key][n]
        res_rows.append([w, n, *[float(v) for v in np.real(g)], *[float(v) for v in np.imag(g)]])
    json.dump(dict(model=name, which=which, source=path, outputs=model.outputs,
                   columns="omega, n, re per output..., im per output...", rows=res_rows),
              open(outpath, "w"))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--at")
    ap.add_argument("--model")
    ap.add_argument("--which", default="truth")
    ap.add_argument("--out")
    ap.add_argument("--only")
    a = ap.parse_args()
    if a.at:
        at_csv(a.model, a.which, a.at, a.out)
        return
    for name in SETUP:
        if a.only and name != a.only:
            continue
        res = dict(nominal=analyse(name, "nominal"), truth=analyse(name, "truth"))
        with open(os.path.join(HERE, f"{name}.json"), "w") as f:
            json.dump(res, f, indent=1)


if __name__ == "__main__":
    main()
