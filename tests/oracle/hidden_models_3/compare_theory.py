#!/usr/bin/env python3
"""Compare `htfid theory` output directories with the oracle's JSON (nominal parameters).

Usage: python3 compare_theory.py MODEL OUTDIR
  OUTDIR from: htfid theory theory-MODEL.toml --omega <the oracle's omegas> --out OUTDIR
"""
import json
import os
import sys

import numpy as np

name, outdir = sys.argv[1], sys.argv[2]
HERE = os.path.dirname(os.path.abspath(__file__))
orc = json.load(open(os.path.join(HERE, f"{name}.json")))["nominal"]
summ = json.load(open(os.path.join(outdir, "summary.json")))
lc = summ["limit_cycle"]
res = {}
print("period", lc["period"], "oracle", orc["period"])
x_h = np.array(lc["state_phase0"])
x_o = np.array(orc["state_phase0"])
print("mode_phase0", lc["mode_phase0"], "oracle", orc["mode_phase0"])
print("state_phase0 htfid", x_h, "\n             oracle", x_o)
res["orbit_max_abs_diff"] = float(np.max(np.abs(x_h - x_o)))
print("orbit |diff|max", res["orbit_max_abs_diff"])
ev_h = lc.get("events", [])
print("events htfid", [(round(e["time"], 9), e["guard"], e["from"], e["to"]) for e in ev_h])
print("events oracle", [(round(e["time"], 9), e["frm"], e["to"]) for e in orc["events"]])
if len(ev_h) == len(orc["events"]):
    res["event_time_max_diff"] = max(abs(a["time"] - b["time"]) for a, b in zip(ev_h, orc["events"]))
    print("event time |diff|max", res["event_time_max_diff"])


def mults(lst):
    return sorted([complex(*z) for z in lst], key=lambda z: (round(abs(z), 9), z.imag))


mo = mults(orc["floquet_multipliers"])
for key, lst in [("limit_cycle", lc["floquet_multipliers"]), ("ltp", summ["ltp"]["floquet_multipliers"])]:
    mh = mults(lst)
    # match as sets
    d = max(min(abs(a - b) for b in mo) for a in mh)
    res[f"floquet_{key}_max_diff"] = float(d)
    print(f"floquet ({key}) htfid", np.round(mh, 12), "max diff", d)
print("floquet oracle", np.round(mo, 12))
M_h = np.array(lc["period_map_jacobian"]).reshape(len(x_o), len(x_o))
res["monodromy_max_diff"] = float(np.max(np.abs(M_h - np.array(orc["monodromy"]))))
print("period-map Jacobian |diff|max", res["monodromy_max_diff"])
# saltations
if ev_h and "saltation" in ev_h[0]:
    print("htfid saltation of the first event:", ev_h[0]["saltation"])

outs = list(orc["htf"].keys())
for oi, o in enumerate(outs):
    f = "theory.csv" if oi == 0 else f"theory_{o}.csv"
    if len(outs) > 1 and os.path.exists(os.path.join(outdir, f"theory_{o}.csv")):
        f = f"theory_{o}.csv"
    rows = np.genfromtxt(os.path.join(outdir, f), delimiter=",", names=True)
    scale = max(abs(complex(r[1], r[2])) for hh in orc["htf"][o].values() for r in hh)
    worst = 0.0
    worst_rel_each = 0.0
    for n, lst in orc["htf"][o].items():
        for w, re, im in lst:
            sel = (np.abs(rows["omega"] - w) < 1e-9 * max(1, w)) & (rows["n"] == int(n))
            if not sel.any():
                print("missing", o, n, w)
                continue
            r = rows[sel][0]
            gh = complex(r["re"], r["im"])
            go = complex(re, im)
            worst = max(worst, abs(gh - go) / scale)
            if abs(go) > 1e-6 * scale:
                worst_rel_each = max(worst_rel_each, abs(gh - go) / abs(go))
    res[f"htf_{o}_max_diff_over_max_abs_g"] = worst
    res[f"htf_{o}_max_pointwise_rel_diff"] = worst_rel_each
    print(f"HTF output {o} ({f}): max |G_htfid - G_oracle| / max|G| = {worst:.3e}; "
          f"worst pointwise relative (|G| > 1e-6 max|G|) {worst_rel_each:.3e}; max|G| = {scale:.4e}")
json.dump(res, open(os.path.join(HERE, "htfid_out", f"compare-theory-{name}.json"), "w"), indent=1)
