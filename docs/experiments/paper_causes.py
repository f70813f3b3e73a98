#!/usr/bin/env python3
"""Ablation experiments behind docs/paper-reproduction.md.

Runs `htfid run` on variants of configs/paper.toml and configs/paper-improved.toml and prints,
per variant, the worst error of G_-2 and G_2 in 12-15 rad/s and over 1-40 rad/s (relative to
max|G_n| over 1-40 rad/s, against the exact theory), and the fitted c.

Usage (from the project root, after `cargo build --release`):
    python3 docs/experiments/paper_causes.py
Standard library only.
"""
import csv
import json
import os
import re
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
EXE = os.path.join(ROOT, "target", "release", "htfid")


def edit(text, replacements):
    for old, new in replacements:
        if old not in text:
            sys.exit(f"config lacks {old!r}")
        text = text.replace(old, new, 1)
    return text


def run(config_text, tmp, name):
    path = os.path.join(tmp, name + ".toml")
    with open(path, "w") as f:
        f.write(config_text)
    out = os.path.join(tmp, name)
    subprocess.run([EXE, "run", path, "--out", out, "--no-plots", "--force"], check=True,
                   stderr=subprocess.DEVNULL)
    return out


def theory_at(config_path, omegas, tmp):
    out = os.path.join(tmp, "theory")
    subprocess.run([EXE, "theory", config_path, "--omega", ",".join(repr(w) for w in omegas),
                    "--out", out, "--no-plots", "--force"], check=True, stderr=subprocess.DEVNULL)
    g = {}
    for r in csv.DictReader(open(os.path.join(out, "theory.csv"))):
        g[(float(r["omega"]), int(float(r["n"])))] = complex(float(r["re"]), float(r["im"]))
    return g


def errors(out, estimator, tmp):
    rows = list(csv.DictReader(open(os.path.join(out, f"estimate_{estimator}.csv"))))
    omegas = sorted({float(r["omega"]) for r in rows})
    g = theory_at(os.path.join(ROOT, "configs", "paper.toml"), omegas, tmp)
    summary = json.load(open(os.path.join(out, "summary.json")))
    result = {}
    for n in (-2, 2):
        scale = summary["errors"][estimator][str(n)]["max_abs_g"]
        band = [abs(complex(float(r["re"]), float(r["im"])) - g[(float(r["omega"]), n)]) / scale
                for r in rows if int(float(r["n"])) == n and 12.0 <= float(r["omega"]) <= 15.0]
        result[n] = (max(band) if band else float("nan"),
                     summary["errors"][estimator][str(n)]["max"])
    return result, summary["fit"][estimator]["c"], summary["fit"][estimator]["k"]


def main():
    paper = open(os.path.join(ROOT, "configs", "paper.toml")).read()
    improved = open(os.path.join(ROOT, "configs", "paper-improved.toml")).read()
    chirp = 'waveform = "paper"    # u = 0.004 sin(14 pi t^2 / 30), exactly as printed'
    linear = lambda amp, dur: (chirp, f'waveform = "linear"\nf_start_hz = 0.0\nf_end_hz = 14.0\n'
                                      f'duration = {dur}\namplitude = {amp}')
    variants = [
        ("paper: 9 chirps of 30 s, amplitude 0.004", paper, [], "multi"),
        ("paper, amplitude 0.0004 (switch nonlinearity /10)", paper, [linear(0.0004, 30.0)], "multi"),
        ("paper, amplitude 0.00004", paper, [linear(0.00004, 30.0)], "multi"),
        ("paper, 120 s chirps (less leakage)", paper, [linear(0.004, 120.0)], "multi"),
        ("paper, 120 s chirps, amplitude 0.00004", paper, [linear(0.00004, 120.0)], "multi"),
        ("paper, 15 phase shifts (aliases n+-15)", paper, [("copies = 9", "copies = 15")], "multi"),
        ("paper, 15 shifts, 120 s, amplitude 0.00004", paper,
         [("copies = 9", "copies = 15"), linear(0.00004, 120.0)], "multi"),
        ("design, single +u block (no sign reversal)", improved,
         [('even_order = "sign_reversal"', 'even_order = "unprotected"')], "lines"),
        ("design, +u and -u blocks (paper-improved.toml)", improved, [], "lines"),
    ]
    with tempfile.TemporaryDirectory() as tmp:
        print("| experiment | G_-2 max err 12-15 | G_2 max err 12-15 | G_-2 max err 1-40 | G_2 max err 1-40 | c_hat | k_hat |")
        print("|---|---|---|---|---|---|---|")
        for i, (label, base, reps, est) in enumerate(variants):
            out = run(edit(base, reps), tmp, f"v{i}")
            e, c, k = errors(out, est, tmp)
            print(f"| {label} | {e[-2][0]:.2e} | {e[2][0]:.2e} | {e[-2][1]:.2e} | {e[2][1]:.2e} | {c:.5f} | {k:.4f} |")


if __name__ == "__main__":
    main()
