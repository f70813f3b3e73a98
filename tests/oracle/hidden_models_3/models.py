"""The two round-3 models written out by hand (vector fields, Jacobians, guards, outputs).

relay_oscillator: a damped oscillator under a hysteretic relay (bang-bang) controller,
  m x'' = -k x - c x' + r F + a cos(2 pi t / T) + u,   r = +1 in mode `push`, -1 in `pull`;
  push -> pull when x rises through +delta, pull -> push when x falls through -delta.
  Output: x.

contact_pair: two masses on their own springs and dampers, mass 1 forced; a one-sided
  Hertz contact with a linear damper acts between them while they overlap,
  d = x1 - x2 - gap, fc = kc pos(d)^1.5 + cc (v1 - v2) while closed, 0 while open;
  m1 v1' = -k1 x1 - c1 v1 - fc + a cos(2 pi t / T) + u,  m2 v2' = -k2 x2 - c2 v2 + fc;
  open -> closed when d rises through 0, closed -> open when d falls through 0.
  Outputs: x1, x2.
  contact_pair_linear (parameter linear = 1): the same with a linear (Kelvin-Voigt) contact,
  fc = kc d + cc (v1 - v2) while closed (added after htfid diagnose failed on the Hertz one).
"""
import numpy as np


class Relay:
    name = "relay_oscillator"
    modes = ["push", "pull"]
    n = 2
    p_out = 1
    outputs = ["x"]
    defaults = dict(m=1.0, k=100.0, c=4.0, F=3.0, delta=0.05, a=20.0, T=1.0)

    def __init__(self, **kw):
        self.p = dict(self.defaults)
        self.p.update(kw)
        P = self.p
        self.guards = {
            "push": [dict(to="pull", direction="rising",
                          h=lambda t, x: x[0] - P["delta"],
                          grad=lambda t, x: np.array([1.0, 0.0]),
                          dhdt=lambda t, x: 0.0)],
            "pull": [dict(to="push", direction="falling",
                          h=lambda t, x: x[0] + P["delta"],
                          grad=lambda t, x: np.array([1.0, 0.0]),
                          dhdt=lambda t, x: 0.0)],
        }

    @property
    def T(self):
        return self.p["T"]

    def guards_from(self, mode):
        return self.guards[mode]

    def forcing(self, t):
        return self.p["a"] * np.cos(2 * np.pi * t / self.p["T"])

    def f(self, mode, t, x, u):
        P = self.p
        r = 1.0 if mode == "push" else -1.0
        return np.array([x[1], (-P["k"] * x[0] - P["c"] * x[1] + r * P["F"] + self.forcing(t) + u) / P["m"]])

    def A(self, mode, t, x):
        P = self.p
        return np.array([[0.0, 1.0], [-P["k"] / P["m"], -P["c"] / P["m"]]])

    def B(self, mode, t, x):
        return np.array([0.0, 1.0 / self.p["m"]])

    def C(self, mode, t, x):
        return np.array([[1.0, 0.0]])

    def D(self, mode, t, x):
        return np.array([0.0])

    def y(self, t, x, u):
        return np.array([x[0]])


class ContactPair:
    name = "contact_pair"
    modes = ["open", "closed"]
    n = 4
    p_out = 2
    outputs = ["x1", "x2"]
    defaults = dict(m1=1.0, m2=0.5, k1=400.0, c1=2.0, k2=250.0, c2=1.0,
                    kc=2.0e5, cc=20.0, gap=0.01, a=30.0, T=0.5, linear=0.0)

    def __init__(self, **kw):
        self.p = dict(self.defaults)
        self.p.update(kw)
        P = self.p
        dgrad = np.array([1.0, 0.0, -1.0, 0.0])
        self.guards = {
            "open": [dict(to="closed", direction="rising",
                          h=lambda t, x: x[0] - x[2] - P["gap"],
                          grad=lambda t, x: dgrad, dhdt=lambda t, x: 0.0)],
            "closed": [dict(to="open", direction="falling",
                            h=lambda t, x: x[0] - x[2] - P["gap"],
                            grad=lambda t, x: dgrad, dhdt=lambda t, x: 0.0)],
        }

    @property
    def T(self):
        return self.p["T"]

    def guards_from(self, mode):
        return self.guards[mode]

    def forcing(self, t):
        return self.p["a"] * np.cos(2 * np.pi * t / self.p["T"])

    def fc(self, mode, x):
        if mode == "open":
            return 0.0
        P = self.p
        d = x[0] - x[2] - P["gap"]
        if P["linear"]:
            return P["kc"] * d + P["cc"] * (x[1] - x[3])
        return P["kc"] * max(d, 0.0) ** 1.5 + P["cc"] * (x[1] - x[3])

    def f(self, mode, t, x, u):
        P = self.p
        fc = self.fc(mode, x)
        return np.array([
            x[1],
            (-P["k1"] * x[0] - P["c1"] * x[1] - fc + self.forcing(t) + u) / P["m1"],
            x[3],
            (-P["k2"] * x[2] - P["c2"] * x[3] + fc) / P["m2"],
        ])

    def A(self, mode, t, x):
        P = self.p
        A = np.zeros((4, 4))
        A[0, 1] = 1.0
        A[2, 3] = 1.0
        A[1, 0] = -P["k1"] / P["m1"]
        A[1, 1] = -P["c1"] / P["m1"]
        A[3, 2] = -P["k2"] / P["m2"]
        A[3, 3] = -P["c2"] / P["m2"]
        if mode == "closed":
            d = x[0] - x[2] - P["gap"]
            dfd = P["kc"] if P["linear"] else 1.5 * P["kc"] * max(d, 0.0) ** 0.5  # d fc / d d
            # fc depends on x1 (+dfd), x2 (-dfd), v1 (+cc), v2 (-cc)
            g = np.array([dfd, P["cc"], -dfd, -P["cc"]])
            A[1] -= g / P["m1"]
            A[3] += g / P["m2"]
        return A

    def B(self, mode, t, x):
        return np.array([0.0, 1.0 / self.p["m1"], 0.0, 0.0])

    def C(self, mode, t, x):
        return np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]])

    def D(self, mode, t, x):
        return np.array([0.0, 0.0])

    def y(self, t, x, u):
        return np.array([x[0], x[2]])
