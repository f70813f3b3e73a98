"""Closed-form (mpmath) orbits and monodromies for bouncing_ball and flight_hopper."""
import mpmath as mp

MP_DPS = 30
mp.mp.dps = MP_DPS


def ball_closed_form(g, e, T, A, root=+1):
    """Period-1 orbit: cos(w t_i) = g T (1 - e) / (2 (1 + e) A w); root = sign of sin(w t_i)."""
    g, e, T, A = (mp.mpf(str(z)) for z in (g, e, T, A))
    w = 2 * mp.pi / T
    cth = g * T * (1 - e) / (2 * (1 + e) * A * w)
    th = mp.acos(cth) if root > 0 else 2 * mp.pi - mp.acos(cth)
    ti = th / w
    yi = A * mp.sin(w * ti)
    sd = A * w * mp.cos(w * ti)
    sdd = -A * w * w * mp.sin(w * ti)
    vm = -g * T / 2
    vp = (1 + e) * sd - e * vm
    # state at phase 0 (flight before the impact at ti in (0, T))
    y0 = yi - vm * ti - g * ti ** 2 / 2
    v0 = vm + g * ti
    Phi = lambda tau: mp.matrix([[1, tau], [0, 1]])  # noqa: E731
    S = mp.matrix([[-e, 0], [(1 + e) * (g + sdd) / (sd - vm), -e]])
    M = Phi(T - ti) * S * Phi(ti)
    ev = sorted(mp.eig(M, left=False, right=False), key=lambda z: (-abs(z), -mp.im(z)))
    return dict(t_impact=ti, y_impact=yi, v_minus=vm, v_plus=vp, y0=y0, v0=v0, S=S,
                monodromy=M, floquet=ev, cos=cth, sin=mp.sin(th))


class StanceMode:
    """m y'' = -m g + k (L0 - y) - c y' + a (1 - cos(w t)) / 2 in closed form."""

    def __init__(self, m, g, k, c, L0, a, T):
        self.m, self.g, self.k, self.c, self.L0, self.a = m, g, k, c, L0, a
        self.w = 2 * mp.pi / T
        self.M = mp.matrix([[0, 1], [-k / m, -c / m]])
        self.Xc = mp.matrix([L0 + (a / 2 - m * g) / k, 0])
        self.Z = mp.lu_solve(mp.mpc(0, 1) * self.w * mp.eye(2) - self.M,
                             mp.matrix([0, -a / (2 * m)]))
        lam, V = mp.eig(self.M)
        self.lam, self.V, self.Vi = lam, V, mp.inverse(V)

    def particular(self, t):
        z = mp.expj(self.w * t)
        return mp.matrix([self.Xc[i] + mp.re(self.Z[i] * z) for i in range(2)])

    def expm(self, tau):
        E = self.V * mp.diag([mp.exp(l * tau) for l in self.lam]) * self.Vi
        return mp.matrix([[mp.re(E[i, j]) for j in range(2)] for i in range(2)])

    def propagate(self, t1, X1, t):
        return self.particular(t) + self.expm(t - t1) * (X1 - self.particular(t1))

    def grf(self, t, X):
        return self.k * (self.L0 - X[0]) - self.c * X[1] + self.a * (1 - mp.cos(self.w * t)) / 2


def hopper_closed_form(m, g, k, c, L0, a, T, guess):
    m, g, k, c, L0, a, T = (mp.mpf(str(z)) for z in (m, g, k, c, L0, a, T))
    st = StanceMode(m, g, k, c, L0, a, T)

    def F(t_td, v_td, t_lo):
        X = st.propagate(t_td, mp.matrix([L0, v_td]), t_lo)
        tau = t_td + T - t_lo
        return [st.grf(t_lo, X), X[0] + X[1] * tau - g * tau ** 2 / 2 - L0,
                X[1] - g * tau - v_td]

    sol = mp.findroot(F, tuple(mp.mpf(z) for z in guess), tol=mp.mpf(10) ** (-2 * MP_DPS + 4))
    t_td, v_td, t_lo = sol[0], sol[1], sol[2]
    res = max(abs(r) for r in F(t_td, v_td, t_lo))
    X_lo = st.propagate(t_td, mp.matrix([L0, v_td]), t_lo)
    # state at phase 0: flight that ends with the touchdown at t_td in (0, T)
    y0 = L0 - v_td * t_td - g * t_td ** 2 / 2
    v0 = v_td + g * t_td
    # monodromy: flight 0..t_td, S_td, stance t_td..t_lo, S_lo, flight t_lo..T
    Phi = lambda tau: mp.matrix([[1, tau], [0, 1]])  # noqa: E731
    grf_td = -c * v_td + a * (1 - mp.cos(st.w * t_td)) / 2
    S_td = mp.matrix([[1, 0], [grf_td / (m * v_td), 1]])
    # liftoff saltation: f+ - f- = (0, -GRF/m) = 0 on the guard -> identity
    S_lo = mp.eye(2)
    Mono = Phi(T - t_lo) * S_lo * mp.expm(st.M * (t_lo - t_td)) * S_td * Phi(t_td)
    ev = sorted(mp.eig(Mono, left=False, right=False), key=lambda z: (-abs(z), -mp.im(z)))
    # sign checks: GRF > 0 strictly inside stance, y > L0 strictly inside flight before touchdown
    bad = 0
    nchk = 400
    for i in range(1, nchk):
        tt = t_td + (t_lo - t_td) * i / nchk
        bad += st.grf(tt, st.propagate(t_td, mp.matrix([L0, v_td]), tt)) <= 0
        tau = (t_td + T - t_lo) * i / nchk
        bad += X_lo[0] + X_lo[1] * tau - g * tau ** 2 / 2 - L0 <= 0 and X_lo[1] - g * tau < 0
    return dict(t_td=t_td, v_td=v_td, t_lo=t_lo, X_lo=X_lo, y0=y0, v0=v0, S_td=S_td,
                monodromy=Mono, floquet=ev, residual=res, sign_violations=int(bad),
                stance_duration=t_lo - t_td)
