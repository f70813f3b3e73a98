"""Independent hybrid-hopper simulator, written from docs/config.md and docs/diagnosis.md only.

Nominal (docs/config.md, "[model]: the built-in hopper"):
    m x'' = -m g - c s x' - k (x - x0) + f(t),   s = 1 while x' > 0 (x' > v_th with a threshold)
Effects (docs/config.md "[effects]", docs/diagnosis.md step 4, docs/config.md model-file section):
    k3      : -k3 (x - x0)^3
    mu      : -mu sign(x'), sticking at x' = 0 while |other forces| <= mu
    mu_pos/mu_neg (asymmetric): -mu_pos while x'>0, +mu_neg while x'<0
    c_f     : -c_f x' while the damper is off
    c2      : -c2 x' |x'|
    tau     : tau a' = f_in - a, the mass receives a
    delay   : f_in(t) = f(t - delay)
    v_th    : damper on while x' > v_th
    x_stop,k_stop : -k_stop (x - x_stop) while x < x_stop
    input_offset : + const force
    sensor_lag (tau_s): tau_s s' = x - s, recorded s
    sensor offset/gain (b, gain): recorded b + gain * x
Outside the library:
    backlash (play operator of width b_bl on the force), second mode (m2,k2,c2m relative),
    xv force (-a_xv (x - x_eq) x'), slowly varying pump amplitude (recorded force keeps A = 1).
"""
import numpy as np
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline

NOM = dict(m=1.0, k=200.0, c=2.0, g=9.81, x0=0.2, A=1.0, T=1.0)


class Multisine:
    def __init__(self, rms=0.1, fmin=0.2, fmax=10.0, df=0.1, seed=0, t_on=-20.0, ramp=5.0):
        rng = np.random.default_rng(seed)
        self.fr = np.arange(fmin, fmax + 1e-9, df)
        self.w = 2 * np.pi * self.fr
        self.ph = rng.uniform(0, 2 * np.pi, len(self.fr))
        self.amp = rms * np.sqrt(2.0 / len(self.fr)) * np.ones(len(self.fr))
        self.t_on, self.ramp = t_on, ramp

    def win(self, t):
        s = np.clip((t - self.t_on) / self.ramp, 0.0, 1.0)
        return s * s * (3 - 2 * s)

    def dwin(self, t):
        s = (t - self.t_on) / self.ramp
        if s <= 0 or s >= 1:
            return 0.0
        return 6 * s * (1 - s) / self.ramp

    def u(self, t):
        t = np.asarray(t, dtype=float)
        val = np.sin(np.multiply.outer(t, self.w) + self.ph) @ self.amp
        return self.win(t) * val

    def du(self, t):
        val = np.sin(t * self.w + self.ph) @ self.amp
        dval = np.cos(t * self.w + self.ph) @ (self.amp * self.w)
        return self.dwin(t) * val + self.win(t) * dval


class Truth:
    def __init__(self, eff=None, nom=None, exc=None, splinef=None):
        self.p = dict(NOM)
        if nom:
            self.p.update(nom)
        self.e = dict(eff or {})
        self.exc = exc
        self.splinef = splinef  # (CubicSpline of recorded f for t >= 0) for htfid comparisons

    # recorded (measured) force
    def f_rec(self, t):
        p = self.p
        if self.splinef is not None:
            return p['A'] * np.cos(2 * np.pi * t / p['T']) if t < 0 else float(self.splinef(t))
        return p['A'] * np.cos(2 * np.pi * t / p['T']) + float(self.exc.u(t))

    def f_true(self, t):
        """force the actuator actually produces (before delay/lag/backlash)"""
        p, e = self.p, self.e
        if 'amp_mod' in e:  # slowly varying pump amplitude, not in the recorded force
            am, per = e['amp_mod']
            return p['A'] * (1 + am * np.sin(2 * np.pi * t / per)) * np.cos(2 * np.pi * t / p['T']) + float(self.exc.u(t))
        return self.f_rec(t)

    def df_true(self, t):
        p = self.p
        w = 2 * np.pi / p['T']
        return -p['A'] * w * np.sin(w * t) + self.exc.du(t)

    # state: [x, v, a(lag), s(sensor), q, qd (second mode, relative)]
    def simulate(self, t_start, t_samples, rtol=1e-10, atol=1e-12):
        p, e = self.p, self.e
        m, k, c, g, x0 = p['m'], p['k'], p['c'], p['g'], p['x0']
        k3 = e.get('k3', 0.0)
        mu_pos = e.get('mu_pos', e.get('mu', 0.0))
        mu_neg = e.get('mu_neg', e.get('mu', 0.0))
        fric = (mu_pos != 0.0) or (mu_neg != 0.0)
        c_f = e.get('c_f', 0.0)
        c2 = e.get('c2', 0.0)
        tau = e.get('tau', 0.0)
        delay = e.get('delay', 0.0)
        v_th = e.get('v_th', 0.0)
        x_stop = e.get('x_stop', None)
        k_stop = e.get('k_stop', 0.0)
        off = e.get('input_offset', 0.0)
        tau_s = e.get('tau_s', 0.0)
        a_xv = e.get('a_xv', 0.0)
        x_eq = x0 - m * g / k
        m2, k2, c2m = e.get('m2', 0.0), e.get('k2', 0.0), e.get('c2m', 0.0)
        bl = e.get('backlash', 0.0)

        def f_in(t):
            return self.f_true(t - delay)

        # discrete modes
        st = dict(damper=False, dirn=-1, stick=False, contact=False, bl_mode=0, bl_F=0.0)

        def drive(t, a):
            """force entering the mass (after delay, lag, backlash, offset)"""
            if tau > 0:
                F = a
            else:
                F = f_in(t)
            if bl > 0:
                if st['bl_mode'] == 1:
                    F = F - bl
                elif st['bl_mode'] == -1:
                    F = F + bl
                else:
                    F = st['bl_F']
            return F + off

        def other_force(t, y):
            x, v = y[0], y[1]
            F = -m * g - k * (x - x0) - k3 * (x - x0) ** 3 + drive(t, y[2])
            if st['contact']:
                F += -k_stop * (x - x_stop)
            F += -c2 * v * abs(v) - a_xv * (x - x_eq) * v
            F += (c if st['damper'] else c_f) * (-v)
            if m2 > 0:
                F += k2 * y[4] + c2m * y[5]
            return F

        def rhs(t, y):
            x, v = y[0], y[1]
            dy = np.zeros_like(y)
            if st['stick']:
                acc = 0.0
            else:
                F = other_force(t, y)
                if fric:
                    F += -mu_pos if st['dirn'] > 0 else mu_neg
                acc = F / m
                dy[0] = v
            dy[1] = acc
            if tau > 0:
                dy[2] = (f_in(t) - y[2]) / tau
            if tau_s > 0:
                dy[3] = (x - y[3]) / tau_s
            if m2 > 0:
                # m2 (x'' + q'') = -k2 q - c2m q'
                dy[4] = y[5]
                dy[5] = (-k2 * y[4] - c2m * y[5]) / m2 - acc
            return dy

        # events
        def ev_damper(t, y):
            return y[1] - v_th
        def ev_v0(t, y):
            return y[1]
        def ev_contact(t, y):
            return y[0] - x_stop
        def ev_stick_up(t, y):
            return other_force(t, y) - mu_pos
        def ev_stick_dn(t, y):
            return other_force(t, y) + mu_neg
        def ev_bl_engage_up(t, y):
            return (drive_raw(t, y) - st['bl_F']) - bl
        def ev_bl_engage_dn(t, y):
            return (drive_raw(t, y) - st['bl_F']) + bl
        def ev_bl_release(t, y):
            return dfr(t)

        def drive_raw(t, y):
            return y[2] if tau > 0 else f_in(t)

        def dfr(t):
            if tau > 0:
                raise NotImplementedError
            return self.df_true(t - delay)

        for ev in (ev_damper, ev_v0, ev_contact, ev_stick_up, ev_stick_dn, ev_bl_engage_up,
                   ev_bl_engage_dn, ev_bl_release):
            ev.terminal = True

        y = np.zeros(6)
        y[0] = x_eq
        y[2] = f_in(t_start)
        y[3] = x_eq
        if bl > 0:
            st['bl_F'] = f_in(t_start)
        st['damper'] = y[1] > v_th
        st['contact'] = x_stop is not None and y[0] < x_stop
        t = t_start
        t_end = t_samples[-1]
        out = np.full((len(t_samples), 6), np.nan)
        nsw = 0
        while t < t_end:
            evs = []
            if not st['stick']:
                ev_damper.direction = -1 if st['damper'] else 1
                evs.append(('damper', ev_damper))
                if fric and not (v_th == 0.0):
                    ev_v0.direction = -1 if st['dirn'] > 0 else 1
                    evs.append(('v0', ev_v0))
                if x_stop is not None:
                    ev_contact.direction = 1 if st['contact'] else -1
                    evs.append(('contact', ev_contact))
            else:
                ev_stick_up.direction = 1
                ev_stick_dn.direction = -1
                evs += [('su', ev_stick_up), ('sd', ev_stick_dn)]
            if bl > 0:
                if st['bl_mode'] == 0:
                    ev_bl_engage_up.direction = 1
                    ev_bl_engage_dn.direction = -1
                    evs += [('blu', ev_bl_engage_up), ('bld', ev_bl_engage_dn)]
                else:
                    ev_bl_release.direction = -1 if st['bl_mode'] == 1 else 1
                    evs.append(('blr', ev_bl_release))
            mask = (t_samples > t) & (t_samples <= t_end)
            sol = solve_ivp(rhs, (t, t_end), y, method='DOP853', rtol=rtol, atol=atol,
                            events=[f for _, f in evs], dense_output=True, max_step=0.05)
            t_new = sol.t[-1]
            sel = mask & (t_samples <= t_new)
            if sel.any():
                out[sel] = sol.sol(t_samples[sel]).T
            y = sol.y[:, -1].copy()
            t = t_new
            if sol.status != 1:
                break
            nsw += 1
            # which events fired
            fired = [name for (name, _), te in zip(evs, sol.t_events) if len(te) and abs(te[-1] - t) < 1e-12]
            for name in fired:
                if name == 'damper':
                    st['damper'] = not st['damper']
                    if fric and v_th == 0.0:
                        self._v0(st, t, y, other_force, mu_pos, mu_neg)
                elif name == 'v0':
                    self._v0(st, t, y, other_force, mu_pos, mu_neg)
                elif name == 'contact':
                    st['contact'] = not st['contact']
                elif name == 'su':
                    st['stick'] = False; st['dirn'] = 1; st['damper'] = v_th <= 0.0
                elif name == 'sd':
                    st['stick'] = False; st['dirn'] = -1
                    st['damper'] = v_th < 0
                elif name == 'blu':
                    st['bl_mode'] = 1
                elif name == 'bld':
                    st['bl_mode'] = -1
                elif name == 'blr':
                    st['bl_F'] = drive_raw(t, y) - bl * st['bl_mode']
                    st['bl_mode'] = 0
        self.nsw = nsw
        return out

    @staticmethod
    def _v0(st, t, y, other_force, mu_pos, mu_neg):
        y[1] = 0.0
        st['stick'] = False
        F = other_force(t, y)
        if -mu_neg <= F <= mu_pos:
            st['stick'] = True
        else:
            st['dirn'] = 1 if F > mu_pos else -1


def measure(truth, states, noise, seed):
    e = truth.e
    x = states[:, 0].copy()
    if e.get('tau_s', 0.0) > 0:
        x = states[:, 3].copy()
    x = e.get('sensor_offset', 0.0) + e.get('sensor_gain', 1.0) * x
    rng = np.random.default_rng(seed)
    return x + noise * rng.standard_normal(len(x))
