"""The four models, as used by models_oracle.py (see README.md for the equations)."""
import numpy as np

from hybrid_core import Guard


def bouncing_ball(g=9.81, e=0.8, T=0.25, A=0.01):
    w = 2 * np.pi / T
    s = lambda t: A * np.sin(w * t)  # noqa: E731
    sd = lambda t: A * w * np.cos(w * t)  # noqa: E731
    sdd = lambda t: -A * w * w * np.sin(w * t)  # noqa: E731
    f = lambda t, x, u: np.array([x[1], -g + u])  # noqa: E731
    Am = lambda t, x: np.array([[0.0, 1.0], [0.0, 0.0]])  # noqa: E731
    Bm = lambda t, x: np.array([0.0, 1.0])  # noqa: E731
    impact = Guard("impact",
                   h=lambda t, x: x[0] - s(t),
                   dh_dx=lambda t, x: np.array([1.0, 0.0]),
                   dh_dt=lambda t, x: -sd(t),
                   target="flight",
                   reset=lambda t, x: np.array([x[0], (1 + e) * sd(t) - e * x[1]]),
                   DR=lambda t, x: np.array([[1.0, 0.0], [0.0, -e]]),
                   dR_dt=lambda t, x: np.array([0.0, (1 + e) * sdd(t)]))
    return dict(name="bouncing_ball", n=2, T=T, C=np.array([[1.0, 0.0]]),
                params=dict(g=g, e=e, T=T, A=A),
                modes={"flight": dict(f=f, A=Am, B=Bm, guards=[impact])},
                table=(s, sd, sdd))


def flight_hopper(m=1.0, g=9.81, k=1000.0, c=10.0, L0=0.5, a=100.0, T=0.5):
    w = 2 * np.pi / T
    F = lambda t: a * (1 - np.cos(w * t)) / 2  # noqa: E731
    Fd = lambda t: a * w * np.sin(w * t) / 2  # noqa: E731
    grf = lambda t, x: k * (L0 - x[0]) - c * x[1] + F(t)  # noqa: E731
    f_fl = lambda t, x, u: np.array([x[1], -g + u / m])  # noqa: E731
    f_st = lambda t, x, u: np.array([x[1], -g + (grf(t, x) + u) / m])  # noqa: E731
    A_fl = lambda t, x: np.array([[0.0, 1.0], [0.0, 0.0]])  # noqa: E731
    A_st = lambda t, x: np.array([[0.0, 1.0], [-k / m, -c / m]])  # noqa: E731
    Bm = lambda t, x: np.array([0.0, 1.0 / m])  # noqa: E731
    touchdown = Guard("touchdown", h=lambda t, x: x[0] - L0,
                      dh_dx=lambda t, x: np.array([1.0, 0.0]),
                      dh_dt=lambda t, x: 0.0, target="stance")
    liftoff = Guard("liftoff", h=grf,
                    dh_dx=lambda t, x: np.array([-k, -c]),
                    dh_dt=lambda t, x: Fd(t), target="flight")
    return dict(name="flight_hopper", n=2, T=T, C=np.array([[1.0, 0.0]]),
                params=dict(m=m, g=g, k=k, c=c, L0=L0, a=a, T=T),
                modes={"flight": dict(f=f_fl, A=A_fl, B=Bm, guards=[touchdown]),
                       "stance": dict(f=f_st, A=A_st, B=Bm, guards=[liftoff])},
                thrust=F, grf=grf)


def two_dof(m1=1.0, m2=0.5, k1=200.0, k2=100.0, k3=5000.0, c1=2.0, c2=0.5, a=20.0, T=1.0):
    w = 2 * np.pi / T

    def mk(sw):
        def f(t, x, u):
            x1, v1, x2, v2 = x
            a1 = (-k1 * x1 - k3 * x1 ** 3 - k2 * (x1 - x2) - c1 * sw * v1 - c2 * (v1 - v2)
                  + a * np.cos(w * t) + u) / m1
            a2 = (-k2 * (x2 - x1) - c2 * (v2 - v1)) / m2
            return np.array([v1, a1, v2, a2])

        def A(t, x):
            x1 = x[0]
            return np.array([[0.0, 1.0, 0.0, 0.0],
                             [(-k1 - 3 * k3 * x1 * x1 - k2) / m1, (-c1 * sw - c2) / m1,
                              k2 / m1, c2 / m1],
                             [0.0, 0.0, 0.0, 1.0],
                             [k2 / m2, c2 / m2, -k2 / m2, -c2 / m2]])
        return f, A

    f_up, A_up = mk(1.0)
    f_dn, A_dn = mk(0.0)
    Bm = lambda t, x: np.array([0.0, 1.0 / m1, 0.0, 0.0])  # noqa: E731
    up2dn = Guard("v1_falling", h=lambda t, x: x[1],
                  dh_dx=lambda t, x: np.array([0.0, 1.0, 0.0, 0.0]),
                  dh_dt=lambda t, x: 0.0, target="down")
    dn2up = Guard("v1_rising", h=lambda t, x: -x[1],
                  dh_dx=lambda t, x: np.array([0.0, -1.0, 0.0, 0.0]),
                  dh_dt=lambda t, x: 0.0, target="up")
    return dict(name="two_dof", n=4, T=T, C=np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]]),
                params=dict(m1=m1, m2=m2, k1=k1, k2=k2, k3=k3, c1=c1, c2=c2, a=a, T=T),
                modes={"up": dict(f=f_up, A=A_up, B=Bm, guards=[up2dn]),
                       "down": dict(f=f_dn, A=A_dn, B=Bm, guards=[dn2up])})


def closed_loop_friction(m=2.0, kp=400.0, kd=20.0, Fc=2.0, vs=0.01, b=1.0, R=0.05, T=1.0):
    w = 2 * np.pi / T

    def f(t, x, u):
        return np.array([x[1], (kp * (R * np.sin(w * t) + u - x[0]) - kd * x[1]
                                - Fc * np.tanh(x[1] / vs) - b * x[1]) / m])

    def A(t, x):
        sech2 = 1.0 / np.cosh(x[1] / vs) ** 2
        return np.array([[0.0, 1.0], [-kp / m, -(kd + b + Fc / vs * sech2) / m]])

    Bm = lambda t, x: np.array([0.0, kp / m])  # noqa: E731
    return dict(name="closed_loop_friction", n=2, T=T, C=np.array([[1.0, 0.0]]),
                params=dict(m=m, kp=kp, kd=kd, Fc=Fc, vs=vs, b=b, R=R, T=T),
                modes={"single": dict(f=f, A=A, B=Bm, guards=[])})
