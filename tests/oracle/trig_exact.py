"""Errors of htfid-trig's sine and cosine against the exact values, and the C library's beside.

Reads lines `x sin(x) cos(x)` (from `cargo run --release -p htfid-trig --example points`) on
standard input and evaluates sin and cos at each x with mpmath at 160 bits: the exact values
to far beyond a double's precision. Prints, per range of |x|, the largest error in units in the
last place of the exact value and the largest absolute error, for htfid-trig and for Python's
math.sin and math.cos (the C library's). Exits with status 1 if htfid-trig is more than 1.5
ulp or 1.2e-16 from an exact value.

    cargo run --release -p htfid-trig --example points | python3 tests/oracle/trig_exact.py
"""
import math
import sys

from mpmath import mp, mpf, sin, cos

mp.prec = 160
ULP_LIMIT = 1.5
ABS_LIMIT = 1.2e-16


def error(value, exact):
    """(error in ulps of the exact value, absolute error)."""
    e = abs(mpf(value) - exact)
    return float(e / math.ulp(float(abs(exact)))), float(e)


worst = {}
for line in sys.stdin:
    x, s, c = (float(t) for t in line.split())
    band = "|x| <= 1" if abs(x) <= 1 else ("|x| <= 2000" if abs(x) <= 2000 else "|x| <= 1e6")
    es, ec = sin(mpf(x)), cos(mpf(x))
    for name, v, exact in (
        ("htfid-trig sin", s, es),
        ("htfid-trig cos", c, ec),
        ("C library sin", math.sin(x), es),
        ("C library cos", math.cos(x), ec),
    ):
        u, a = error(v, exact)
        w = worst.get((band, name), (0.0, 0.0))
        worst[(band, name)] = (max(w[0], u), max(w[1], a))

failed = False
for (band, name), (u, a) in sorted(worst.items()):
    print(f"{band:12} {name:15} max {u:.3f} ulp, max abs {a:.2e}")
    if name.startswith("htfid") and (u > ULP_LIMIT or a > ABS_LIMIT):
        failed = True
sys.exit(1 if failed else 0)
