#!/usr/bin/env python3
"""Compare an `htfid estimate` CSV with the oracle's HTFs at the TRUE parameters.

Usage: python3 compare_estimate.py ESTIMATE.csv ORACLE_AT.json OUTPUT_INDEX LABEL
  ORACLE_AT.json from: python3 oracle.py --at ESTIMATE.csv --model NAME --which truth --out ...
Prints per harmonic: the share of frequencies where |G_hat - G_true| <= 1.96 stderr and
<= 3 stderr (for a complex Gaussian estimate with total standard error stderr, i.e.
E|G_hat - G|^2 = stderr^2, the share within r*stderr is 1 - exp(-r^2): 97.9 % at 1.96,
99.99 % at 3; if stderr is per real/imag part instead, 85 % at 1.96 and 98.9 % at 3), the
median normalised error, and the error relative to max|G_n|.
"""
import json
import sys

import numpy as np

est_path, orc_path, oi, label = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
est = np.genfromtxt(est_path, delimiter=",", names=True)
orc = json.load(open(orc_path))
p = len(orc["outputs"])
true = {}
for r in orc["rows"]:
    w, n = r[0], int(r[1])
    true[(round(w, 9), n)] = complex(r[2 + oi], r[2 + p + oi])
res = {}
print(f"{label}: n  points  within1.96se  within3se  median|err|/se  median|err|/max|G_n|  "
      f"max|G_true|  median|G_true|/se")
for n in sorted(set(est["n"].astype(int)) & {-2, -1, 0, 1, 2}):
    rows = est[est["n"] == n]
    g = rows["re"] + 1j * rows["im"]
    gt = np.array([true[(round(w, 9), n)] for w in rows["omega"]])
    se = rows["stderr"]
    e = np.abs(g - gt)
    z = e / se
    mx = np.max(np.abs(gt))
    # where the truth is significant
    sig = np.abs(gt) > 2 * se
    res[str(n)] = dict(points=len(rows), within_1_96=float(np.mean(z <= 1.96)),
                       within_3=float(np.mean(z <= 3)), median_z=float(np.median(z)),
                       median_err_over_max=float(np.median(e) / mx),
                       max_abs_g_true=float(mx),
                       median_true_over_se=float(np.median(np.abs(gt) / se)),
                       true_significant_share=float(np.mean(sig)),
                       worst_z=float(np.max(z)),
                       worst_z_omega=float(rows["omega"][np.argmax(z)]))
    print(f"   {n:2d} {len(rows):6d}   {np.mean(z <= 1.96):8.3f}   {np.mean(z <= 3):8.3f}   "
          f"{np.median(z):8.3f}     {np.median(e) / mx:8.4f}       {mx:.3e}    "
          f"{np.median(np.abs(gt) / se):.2f}   worst z {np.max(z):.1f} at {rows['omega'][np.argmax(z)]:.2f}")
import os
json.dump(res, open(os.path.join(os.path.dirname(os.path.abspath(__file__)), "htfid_out", f"compare-estimate-{label}.json"), "w"), indent=1)
