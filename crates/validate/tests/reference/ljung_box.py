"""Reference values for crates/validate/tests/truth.rs, computed once with numpy and scipy.

Run: python3 ljung_box.py  (numpy 2.4.6, scipy 1.17.1 when the values were taken).
The Ljung-Box statistic is written out from its definition (statsmodels' acorr_ljungbox
computes the same sum); the p-value is scipy.stats.chi2.sf.
"""
import numpy as np
from scipy.stats import chi2

n = 200
i = np.arange(n)
lags = 10
# A strongly correlated series, then a weakly correlated one (p-value of moderate size).
for name, x in [
    ("strong", np.sin(0.37 * i) + ((i * 7919) % 113) / 113.0),
    ("weak", 0.1 * np.sin(0.37 * i) + ((i * 7919) % 113) / 113.0),
]:
    c = x - x.mean()
    c0 = np.dot(c, c)
    r = np.array([np.dot(c[: n - k], c[k:]) / c0 for k in range(1, lags + 1)])
    q = n * (n + 2) * np.sum(r**2 / (n - np.arange(1, lags + 1)))
    print(name, "r1..r3 =", repr(r[0]), repr(r[1]), repr(r[2]))
    print(name, "Q =", repr(q))
    print(name, "p =", repr(chi2.sf(q, lags)))
for x_, k in [(3.0, 1), (7.5, 5), (30.0, 25), (40.0, 25), (12.3, 11)]:
    print(f"chi2.sf({x_}, {k}) =", repr(chi2.sf(x_, k)))
