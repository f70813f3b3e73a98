//! The true system: continuous state, discrete modes, vector field, guards and the Filippov
//! rules that pick the mode after an event.

use crate::dopri;
use crate::error::Error;
use crate::input::Drive;
use crate::scenario::{Effect, Scenario, FORCING_AMPLITUDE, FORCING_PERIOD};

/// Length of the continuous state.
pub const NX: usize = 7;
/// The continuous state; see the index constants.
pub type State = [f64; NX];

/// Position of mass 1, m.
pub const X: usize = 0;
/// Velocity of mass 1, m/s.
pub const V: usize = 1;
/// Actuator-lag output (applied force), N.
pub const FA: usize = 2;
/// Sensor-lag output (lagged position), m.
pub const XM: usize = 3;
/// Second mode: link extension from its static value, m.
pub const Q: usize = 4;
/// Second mode: rate of `Q`, m/s.
pub const W: usize = 5;
/// Backlash output while disengaged, N.
pub const YB: usize = 6;

/// Guard values within this of zero count as "on the surface" (SI units of each guard).
const ON_SURFACE: f64 = 1e-10;
/// How far ahead a candidate mode's guards are checked after an event, s. Long enough that
/// the curvature term decides at grazing contacts, short enough that a guard rate above
/// ~1e-6 (SI) decides everywhere else.
const LOOKAHEAD: f64 = 1e-6;

/// Damper switch state `s`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Damper {
    /// `s = 1`: `v > v_th`.
    On,
    /// `s = 0`: `v < v_th`.
    Off,
    /// Filippov sliding on `v = v_th` (possible only when the force jumps there).
    Slide,
}

/// Friction state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Friction {
    /// No friction effect.
    Absent,
    /// Sliding with `v > 0`.
    Pos,
    /// Sliding with `v < 0`.
    Neg,
    /// Stuck: `v = 0` held while the other forces stay inside the friction band.
    Stick,
}

/// Hard-stop state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stop {
    /// No hard stop.
    Absent,
    /// `x > x_stop`.
    Free,
    /// `x < x_stop`: the stop pushes.
    Contact,
}

/// Backlash state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lash {
    /// No backlash.
    Absent,
    /// Output held (state `YB`) while the input moves inside the gap.
    Free,
    /// Driven upward: output = input - gap / 2.
    Up,
    /// Driven downward: output = input + gap / 2.
    Down,
}

/// The discrete state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Modes {
    /// Damper.
    pub damper: Damper,
    /// Friction.
    pub friction: Friction,
    /// Hard stop.
    pub stop: Stop,
    /// Backlash.
    pub lash: Lash,
}

/// The resolved true system: parameters after errors, and every effect as numbers.
/// Build it from a [`Scenario`] with [`Plant::new`]; fields are public so tests can set up
/// reference problems (e.g. a different forcing amplitude).
#[derive(Clone, Debug)]
pub struct Plant {
    /// True total mass, kg.
    pub m: f64,
    /// True stiffness, N/m.
    pub k: f64,
    /// True damper coefficient, N s/m.
    pub c: f64,
    /// True gravity, m/s^2.
    pub g: f64,
    /// True spring rest length, m.
    pub x0: f64,
    /// Cubic stiffness, N/m^3.
    pub k3: f64,
    /// Friction `(mu_pos, mu_neg)`, N, if any.
    pub friction: Option<(f64, f64)>,
    /// Flight damping, N s/m.
    pub c_f: f64,
    /// Quadratic drag, N s^2/m^2.
    pub drag: f64,
    /// Actuator time constant, s, if any.
    pub actuator_tau: Option<f64>,
    /// Input delay, s.
    pub delay: f64,
    /// Input offset, N.
    pub offset: f64,
    /// Damper switching velocity, m/s.
    pub v_th: f64,
    /// Hard stop `(k_stop, x_stop)`, if any.
    pub stop: Option<(f64, f64)>,
    /// Sensor time constant, s, if any.
    pub sensor_tau: Option<f64>,
    /// Sensor gain.
    pub gain: f64,
    /// Sensor offset, m.
    pub bias: f64,
    /// Backlash total width, N, if any.
    pub gap: Option<f64>,
    /// Second mode `(m2, k2, c2)`, if any.
    pub second: Option<(f64, f64, f64)>,
    /// Position-velocity force coefficient, N s/m^2.
    pub pos_vel: f64,
    pub(crate) drive: Drive,
}

impl Plant {
    /// Resolve a scenario into the true system.
    ///
    /// # Errors
    /// Whatever [`Scenario::validate`] reports, and [`Error::InvalidParameter`] when a second
    /// mode's mass is not below the true mass.
    pub fn new(s: &Scenario) -> Result<Plant, Error> {
        s.validate()?;
        let pe = &s.parameter_errors;
        let [m, k, c, g, x0] = pe
            .entries()
            .map(|(_, frac, nominal)| nominal * (1.0 + frac));
        let mut p = Plant {
            m,
            k,
            c,
            g,
            x0,
            k3: 0.0,
            friction: None,
            c_f: 0.0,
            drag: 0.0,
            actuator_tau: None,
            delay: 0.0,
            offset: 0.0,
            v_th: 0.0,
            stop: None,
            sensor_tau: None,
            gain: 1.0,
            bias: 0.0,
            gap: None,
            second: None,
            pos_vel: 0.0,
            drive: Drive::new(
                &s.excitation,
                FORCING_AMPLITUDE,
                FORCING_PERIOD,
                None,
                s.settle_s,
                s.record_s,
            ),
        };
        let mut slow = None;
        for (i, e) in s.effects.iter().enumerate() {
            match *e {
                Effect::CubicStiffness { k3 } => p.k3 = k3,
                Effect::CoulombFriction { mu } => p.friction = Some((mu, mu)),
                Effect::AsymmetricFriction { mu_pos, mu_neg } => {
                    p.friction = Some((mu_pos, mu_neg));
                }
                Effect::FlightDamping { c_f } => p.c_f = c_f,
                Effect::QuadraticDrag { c2 } => p.drag = c2,
                Effect::ActuatorLag { tau } => p.actuator_tau = Some(tau),
                Effect::InputDelay { delay } => p.delay = delay,
                Effect::InputOffset { offset } => p.offset = offset,
                Effect::SwitchThreshold { v_th } => p.v_th = v_th,
                Effect::HardStop { k_stop, x_stop } => p.stop = Some((k_stop, x_stop)),
                Effect::SensorLag { tau_s } => p.sensor_tau = Some(tau_s),
                Effect::SensorOffsetGain { b, gain } => {
                    p.bias = b;
                    p.gain = gain;
                }
                Effect::Backlash { gap } => p.gap = Some(gap),
                Effect::SecondMode { m2, k2, c2 } => {
                    if m2 >= 0.9 * m {
                        return Err(Error::InvalidParameter {
                            name: format!("effects[{i}].m2"),
                            requirement: "< 0.9 m (the true mass)",
                            value: m2,
                        });
                    }
                    p.second = Some((m2, k2, c2));
                }
                Effect::PosVelForce { a } => p.pos_vel = a,
                Effect::SlowForcingAmplitude { depth, period } => slow = Some((depth, period)),
            }
        }
        p.drive = Drive::new(
            &s.excitation,
            FORCING_AMPLITUDE,
            FORCING_PERIOD,
            slow,
            s.settle_s,
            s.record_s,
        );
        Ok(p)
    }

    /// Static equilibrium of the nominal-structure spring, `x0 - m g / k` (true parameters).
    pub fn x_eq(&self) -> f64 {
        self.x0 - self.m * self.g / self.k
    }

    /// Mass of body 1 (the measured body), kg.
    fn m1(&self) -> f64 {
        self.m - self.second.map_or(0.0, |s| s.0)
    }

    /// The recorded (commanded) force at time `t`.
    pub fn commanded_force(&self, t: f64) -> f64 {
        self.drive.commanded(t)
    }

    /// Excitation breakpoints in simulation time (shifted by the input delay).
    pub(crate) fn breaks(&self) -> Vec<f64> {
        self.drive.breaks().iter().map(|b| b + self.delay).collect()
    }

    /// Input to the backlash (delayed, offset, true command) and its time derivative.
    fn lash_input(&self, t: f64, seg: usize) -> (f64, f64) {
        let (u, du) = self.drive.true_command(t - self.delay, seg);
        (u + self.offset, du)
    }

    /// Backlash output (input to the actuator lag).
    fn lash_output(&self, t: f64, seg: usize, y: &State, lash: Lash) -> f64 {
        let (u, _) = self.lash_input(t, seg);
        let r = self.gap.unwrap_or(0.0) / 2.0;
        match lash {
            Lash::Absent => u,
            Lash::Free => y[YB],
            Lash::Up => u - r,
            Lash::Down => u + r,
        }
    }

    /// Force applied to mass 1 by the actuator.
    fn applied(&self, t: f64, seg: usize, y: &State, lash: Lash) -> f64 {
        match self.actuator_tau {
            Some(_) => y[FA],
            None => self.lash_output(t, seg, y, lash),
        }
    }

    /// All forces on mass 1 that are continuous in `v` (everything but damper and friction).
    fn continuous_force(&self, t: f64, seg: usize, y: &State, modes: Modes) -> f64 {
        let (x, v) = (y[X], y[V]);
        let dx = x - self.x0;
        let mut f = -self.m * self.g
            - self.k * dx
            - self.k3 * dx * dx * dx
            - self.drag * v * v.abs()
            - self.pos_vel * (x - self.x_eq()) * v
            + self.applied(t, seg, y, modes.lash);
        if let (Some((k_stop, x_stop)), Stop::Contact) = (self.stop, modes.stop) {
            f -= k_stop * (x - x_stop);
        }
        if let Some((_, k2, c2)) = self.second {
            f += k2 * y[Q] + c2 * y[W];
        }
        f
    }

    /// Damper plus flight damping at velocity `v` with switch value `s`.
    fn damping_force(&self, v: f64, s: f64) -> f64 {
        -self.c * s * v - self.c_f * (1.0 - s) * v
    }

    /// Friction force while sliding in the given direction.
    fn friction_force(&self, friction: Friction) -> f64 {
        match (self.friction, friction) {
            (Some((mu_pos, _)), Friction::Pos) => -mu_pos,
            (Some((_, mu_neg)), Friction::Neg) => mu_neg,
            _ => 0.0,
        }
    }

    /// Acceleration of mass 1 with the given friction direction and damper value `s`,
    /// evaluated at velocity `v` (used for the Filippov tests on the surfaces).
    fn accel_with(
        &self,
        t: f64,
        seg: usize,
        y: &State,
        modes: Modes,
        v: f64,
        s: f64,
        friction: Friction,
    ) -> f64 {
        let mut yv = *y;
        yv[V] = v;
        (self.continuous_force(t, seg, &yv, modes)
            + self.damping_force(v, s)
            + self.friction_force(friction))
            / self.m1()
    }

    /// The velocity at which the damper switches, and whether the force jumps there
    /// (only then can the flow slide along it).
    fn damper_jumps(&self) -> bool {
        (self.c - self.c_f) * self.v_th != 0.0
    }

    /// Direction of friction to use away from `v = 0` for surface tests at `v = v_th`.
    fn friction_at(&self, v: f64) -> Friction {
        match self.friction {
            None => Friction::Absent,
            Some(_) if v > 0.0 => Friction::Pos,
            Some(_) => Friction::Neg,
        }
    }

    /// Time derivative of the state in the given modes.
    pub(crate) fn deriv(&self, t: f64, seg: usize, y: &State, modes: Modes) -> State {
        let mut d = [0.0; NX];
        let (dx, dv) = match (modes.friction, modes.damper) {
            (Friction::Stick, _) => (0.0, 0.0),
            (_, Damper::Slide) => (self.v_th, 0.0),
            (fr, dm) => {
                let s = if dm == Damper::On { 1.0 } else { 0.0 };
                (y[V], self.accel_with(t, seg, y, modes, y[V], s, fr))
            }
        };
        d[X] = dx;
        d[V] = dv;
        if let Some(tau) = self.actuator_tau {
            d[FA] = (self.lash_output(t, seg, y, modes.lash) - y[FA]) / tau;
        }
        if let Some(tau_s) = self.sensor_tau {
            d[XM] = (y[X] - y[XM]) / tau_s;
        }
        if let Some((m2, k2, c2)) = self.second {
            d[Q] = y[W];
            d[W] = (-k2 * y[Q] - c2 * y[W]) / m2 - dv;
        }
        d
    }

    /// Guard functions of the current modes: the modes stay valid while every value is >= 0.
    pub(crate) fn guards(&self, t: f64, seg: usize, y: &State, modes: Modes) -> Guards {
        let mut g = Guards::default();
        let v = y[V];
        match modes.damper {
            Damper::On => g.push(v - self.v_th),
            Damper::Off => g.push(self.v_th - v),
            Damper::Slide => {
                let fr = self.friction_at(self.v_th);
                g.push(-self.accel_with(t, seg, y, modes, self.v_th, 1.0, fr));
                g.push(self.accel_with(t, seg, y, modes, self.v_th, 0.0, fr));
            }
        }
        match modes.friction {
            Friction::Absent => {}
            Friction::Pos => g.push(v),
            Friction::Neg => g.push(-v),
            Friction::Stick => {
                g.push(-self.accel_with(t, seg, y, modes, 0.0, 0.0, Friction::Pos));
                g.push(self.accel_with(t, seg, y, modes, 0.0, 0.0, Friction::Neg));
            }
        }
        if let Some((_, x_stop)) = self.stop {
            match modes.stop {
                Stop::Contact => g.push(x_stop - y[X]),
                _ => g.push(y[X] - x_stop),
            }
        }
        if let Some(gap) = self.gap {
            let r = gap / 2.0;
            let (u, du) = self.lash_input(t, seg);
            match modes.lash {
                Lash::Free => {
                    g.push(r - (u - y[YB]));
                    g.push(r + (u - y[YB]));
                }
                Lash::Up => g.push(du),
                Lash::Down => g.push(-du),
                Lash::Absent => {}
            }
        }
        g
    }

    /// Initial modes before resolution (any valid guess).
    pub(crate) fn initial_modes(&self) -> Modes {
        Modes {
            damper: Damper::On,
            friction: if self.friction.is_some() {
                Friction::Pos
            } else {
                Friction::Absent
            },
            stop: if self.stop.is_some() {
                Stop::Free
            } else {
                Stop::Absent
            },
            lash: if self.gap.is_some() {
                Lash::Free
            } else {
                Lash::Absent
            },
        }
    }

    /// The state at `t = start` from which the paper protocol starts: `x = x0 - m g / k`,
    /// `v = 0`, actuator and sensor at steady values, second mode at rest, backlash output at
    /// `input - gap / 2`.
    pub fn rest_state(&self, t: f64) -> State {
        let seg = self.segment(t);
        let (u, _) = self.lash_input(t, seg);
        let r = self.gap.unwrap_or(0.0) / 2.0;
        let mut y = [0.0; NX];
        y[X] = self.x_eq();
        y[XM] = y[X];
        y[YB] = u - r;
        y[FA] = if self.gap.is_some() { u - r } else { u };
        y
    }

    /// Segment of simulation time `t` (breakpoints shifted by the delay).
    pub(crate) fn segment(&self, t: f64) -> usize {
        self.breaks().partition_point(|&b| b <= t)
    }

    /// Pick the discrete modes consistent with the state at `t`, projecting the state onto the
    /// chosen surface (`v = 0` when stuck, `v = v_th` when sliding, backlash output continuous).
    ///
    /// A candidate is consistent when each of its guards is clearly positive, or on the surface
    /// and not decreasing along the candidate's own flow. This is Filippov's rule for the
    /// velocity surfaces and the play operator's rule for the backlash. Candidates are tried
    /// in order of how few components differ from `previous`.
    ///
    /// `prev_seg` is the segment the state was integrated in (it differs from `seg` right at
    /// an excitation breakpoint, where the backlash output is carried across a jump).
    pub(crate) fn resolve(
        &self,
        t: f64,
        seg: usize,
        prev_seg: usize,
        y: &State,
        previous: Modes,
    ) -> Result<(Modes, State), Error> {
        let dampers: &[Damper] = if self.damper_jumps() {
            &[Damper::On, Damper::Off, Damper::Slide]
        } else {
            &[Damper::On, Damper::Off]
        };
        let frictions: &[Friction] = if self.friction.is_some() {
            &[Friction::Pos, Friction::Neg, Friction::Stick]
        } else {
            &[Friction::Absent]
        };
        let stops: &[Stop] = if self.stop.is_some() {
            &[Stop::Free, Stop::Contact]
        } else {
            &[Stop::Absent]
        };
        let lashes: &[Lash] = if self.gap.is_some() {
            &[Lash::Free, Lash::Up, Lash::Down]
        } else {
            &[Lash::Absent]
        };
        // The backlash output is continuous except where its input jumps past the gap.
        let r = self.gap.unwrap_or(0.0) / 2.0;
        let (u, _) = self.lash_input(t, seg);
        let lash_target = self
            .lash_output(t, prev_seg, y, previous.lash)
            .clamp(u - r, u + r);

        let mut candidates = Vec::with_capacity(54);
        for &damper in dampers {
            for &friction in frictions {
                for &stop in stops {
                    for &lash in lashes {
                        candidates.push(Modes {
                            damper,
                            friction,
                            stop,
                            lash,
                        });
                    }
                }
            }
        }
        let differing = |m: &Modes| {
            usize::from(m.damper != previous.damper)
                + usize::from(m.friction != previous.friction)
                + usize::from(m.stop != previous.stop)
                + usize::from(m.lash != previous.lash)
        };
        candidates.sort_by_key(differing);

        'candidate: for modes in candidates {
            let mut z = *y;
            if modes.friction == Friction::Stick && modes.damper == Damper::Slide {
                continue;
            }
            if modes.friction == Friction::Stick {
                if z[V].abs() > ON_SURFACE {
                    continue;
                }
                z[V] = 0.0;
            }
            if modes.damper == Damper::Slide {
                if (z[V] - self.v_th).abs() > ON_SURFACE {
                    continue;
                }
                z[V] = self.v_th;
            }
            match modes.lash {
                Lash::Free => z[YB] = lash_target,
                Lash::Up if (u - r - lash_target).abs() > ON_SURFACE => continue,
                Lash::Down if (u + r - lash_target).abs() > ON_SURFACE => continue,
                _ => {}
            }
            // Look ahead along the candidate's own flow with a full 5th-order step, so that
            // a grazing start (guard and its rate both ~0) is judged by its curvature.
            let g0 = self.guards(t, seg, &z, modes);
            let f = |tt: f64, yy: &State| self.deriv(tt, seg, yy, modes);
            let z1 = dopri::step(&f, t, &z, &f(t, &z), LOOKAHEAD).y1;
            let g1 = self.guards(t + LOOKAHEAD, seg, &z1, modes);
            for (a, b) in g0.values().iter().zip(g1.values()) {
                let ok = *a > ON_SURFACE || (*a >= -ON_SURFACE && b >= a);
                if !ok {
                    continue 'candidate;
                }
            }
            return Ok((modes, z));
        }
        Err(Error::NoConsistentMode {
            time: t,
            x: y[X],
            v: y[V],
        })
    }

    /// The measured position for a state (before noise).
    pub(crate) fn measured(&self, y: &State) -> f64 {
        let x = if self.sensor_tau.is_some() {
            y[XM]
        } else {
            y[X]
        };
        self.gain * x + self.bias
    }
}

/// Guard values of one mode combination (at most 8).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Guards {
    n: usize,
    v: [f64; 8],
}

impl Guards {
    fn push(&mut self, g: f64) {
        self.v[self.n] = g;
        self.n += 1;
    }

    pub(crate) fn values(&self) -> &[f64] {
        &self.v[..self.n]
    }
}
