#!/usr/bin/env python3
"""`htfid run CONFIG --no-plots` against the NumPy/SciPy pipeline, side by side.

Alternates rounds of the two on the same machine, so that both see the same load: each round
runs the htfid command `--runs` times (into a scratch directory, replaced each time as a user's
rerun replaces it) and the NumPy pipeline once, each timed from here as a whole process
(`time.perf_counter` around `subprocess.run`). Prints every round and then the minimum and the
median of each, and their ratios.

    cargo build --release --locked -p htfid
    python3 docs/experiments/side_by_side.py [--rounds 3] [--runs 30] [--config configs/paper.toml]

The machine's speed drifts by 10 % within minutes; compare only figures of one invocation.
"""
import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent.parent


def timed(cmd):
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--runs", type=int, default=30, help="htfid runs per round")
    ap.add_argument("--config", default=str(ROOT / "configs" / "paper.toml"))
    ap.add_argument("--htfid", default=str(ROOT / "target" / "release" / "htfid"))
    args = ap.parse_args()
    if not Path(args.htfid).is_file():
        sys.exit(f"{args.htfid} not found: build it with `cargo build --release --locked -p htfid`")
    numpy_cmd = [sys.executable, str(ROOT / "docs" / "experiments" / "numpy_pipeline.py"), args.config]
    rust, numpy = [], []
    with tempfile.TemporaryDirectory() as scratch:
        rust_cmd = [args.htfid, "run", args.config, "--no-plots", "--out", scratch, "--force", "-q"]
        timed(rust_cmd)  # the first run creates the directory; every later one replaces it
        for r in range(args.rounds):
            round_rust = [timed(rust_cmd) for _ in range(args.runs)]
            round_numpy = timed(numpy_cmd)
            rust += round_rust
            numpy.append(round_numpy)
            print(f"round {r + 1}: htfid min {min(round_rust) * 1e3:.1f} ms, median "
                  f"{statistics.median(round_rust) * 1e3:.1f} ms; NumPy {round_numpy:.2f} s")
    r_min, r_med = min(rust), statistics.median(rust)
    n_min, n_med = min(numpy), statistics.median(numpy)
    print(f"htfid: min {r_min * 1e3:.1f} ms, median {r_med * 1e3:.1f} ms ({len(rust)} runs)")
    print(f"NumPy: min {n_min:.2f} s, median {n_med:.2f} s ({len(numpy)} runs)")
    print(f"ratio: {n_min / r_min:.0f}x between minima, {n_med / r_med:.0f}x between medians")


if __name__ == "__main__":
    main()
