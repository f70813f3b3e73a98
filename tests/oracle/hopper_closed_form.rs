//! Closed-form oracle for the periodic orbit of the forced vertical hopper.
//!
//! The model (paper, section V-A) is
//!
//! ```text
//! m x'' = -m g - c s v - k (x - x0) + a cos(2 pi t / T),   v = x',
//! s = 1 while v > 0 (damper on, "stance"), s = 0 otherwise ("flight").
//! ```
//!
//! Times are absolute: `t = 0` (mod `T`) is phase 0 of the forcing.
//!
//! # Derivation
//!
//! Within one mode the equation is linear with constant coefficients,
//! `x'' + gamma x' + w0^2 x = w0^2 xe + (a/m) cos(wp t)` with `w0^2 = k/m`,
//! `gamma = c s / m`, `wp = 2 pi / T` and the rest position `xe = x0 - m g / k`.
//! Its general solution is particular plus homogeneous:
//!
//! ```text
//! X(t) = Xp(t) + exp(M (t - t1)) (X(t1) - Xp(t1)),    X = (x, v),
//! xp(t) = xe + Re(P exp(j wp t)),   P = (a/m) / (w0^2 - wp^2 + j gamma wp),
//! M = [[0, 1], [-w0^2, -gamma]],
//! exp(M tau) = exp(mu tau) (cos(wd tau) I + sin(wd tau)/wd (M - mu I)),
//! mu = -gamma/2,   wd^2 = w0^2 - gamma^2/4
//! ```
//!
//! (the last line is Cayley-Hamilton: `(M - mu I)^2 = -wd^2 I`; the hyperbolic
//! and critical forms are used when `wd^2 <= 0`).
//!
//! The orbit is parametrised by the upward zero crossing of `v` (damper turns
//! on) at time `t_on` with `x(t_on) = x_on`, `v(t_on) = 0`.  From there the
//! damped solution is followed until its velocity first returns to zero at
//! `t_off` (scan for the sign change, bisect, then Newton on the closed-form
//! `v(t)` with the closed-form `v'(t)`, so the root is exact to the last bit),
//! then the free solution is followed until its velocity next rises through
//! zero at `t_on'`, with `x_on'`.  The periodicity conditions
//! `t_on' = t_on + T`, `x_on' = x_on` are solved by forward iteration of this
//! return map (a stable orbit attracts it) followed by Newton with a
//! central-difference Jacobian.  The Jacobian only steers Newton; the fixed
//! point itself is as accurate as the closed-form residual.
//!
//! The monodromy matrix over one forcing period from phase 0 is the ordered
//! product of the two constant-mode exponentials over the pieces of `[0, T]`
//! between `t_on` and `t_off`.  No saltation factor appears: the vector fields
//! of the two modes differ by `(0, -c v / m)`, which vanishes on the switching
//! surface `v = 0`, so the saltation matrix is the identity.
//!
//! Floquet multipliers are the monodromy eigenvalues as `(re, im)`, ordered
//! by decreasing modulus; a complex pair is listed with positive imaginary
//! part first.

// Included by `#[path]` into test crates that each use only part of the oracle.
#![allow(dead_code)]

use std::f64::consts::PI;

/// Parameters of the forced hopper, in SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HopperParams {
    /// Mass (kg).
    pub m: f64,
    /// Spring stiffness (N/m).
    pub k: f64,
    /// Damping coefficient while the damper is on (N s/m).
    pub c: f64,
    /// Gravity (m/s^2).
    pub g: f64,
    /// Spring rest length (m).
    pub x0: f64,
    /// Forcing amplitude (N); forcing is `a cos(2 pi t / period)`.
    pub a: f64,
    /// Forcing period (s).
    pub period: f64,
}

/// The period-one orbit of the hopper and its linearisation.
#[derive(Debug, Clone, Copy)]
pub struct OracleOrbit {
    /// Phase in `[0, T)` of the upward zero crossing of `v` (damper turns on).
    pub t_on: f64,
    /// Phase in `[0, T)` of the downward zero crossing of `v` (damper turns off).
    pub t_off: f64,
    /// Position at forcing phase 0.
    pub x_phase0: f64,
    /// Velocity at forcing phase 0.
    pub v_phase0: f64,
    /// Floquet multipliers `(re, im)`, decreasing modulus, `+im` first in a pair.
    pub floquet: [(f64, f64); 2],
    /// State transition matrix of the linearisation from phase 0 to phase `T`.
    pub monodromy: [[f64; 2]; 2],
    /// Position at `t_on` (velocity is zero there).
    pub x_on: f64,
    /// Position at `t_off` (velocity is zero there).
    pub x_off: f64,
    /// Parameters the orbit was computed for.
    pub params: HopperParams,
}

impl OracleOrbit {
    /// Fraction of the period during which the damper is on.
    pub fn duty(&self) -> f64 {
        (self.t_off - self.t_on).rem_euclid(self.params.period) / self.params.period
    }

    /// Whether the damper is on at absolute time `t` (on over `[t_on, t_off)` mod `T`).
    pub fn damper_on(&self, t: f64) -> bool {
        let p = &self.params;
        (t - self.t_on).rem_euclid(p.period) < self.duty() * p.period
    }

    /// Orbit state `[x, v]` at absolute time `t`, in closed form.
    pub fn state(&self, t: f64) -> [f64; 2] {
        let p = &self.params;
        if self.damper_on(t) {
            let start = t - (t - self.t_on).rem_euclid(p.period);
            Mode::new(p, true).propagate(start, [self.x_on, 0.0], t)
        } else {
            let start = t - (t - self.t_off).rem_euclid(p.period);
            Mode::new(p, false).propagate(start, [self.x_off, 0.0], t)
        }
    }
}

/// Orbit state `[x, v]` at absolute time `t` (same as [`OracleOrbit::state`]).
pub fn hopper_state(orbit: &OracleOrbit, t: f64) -> [f64; 2] {
    orbit.state(t)
}

/// Closed-form exponential `exp(M tau)` of a mode's constant system matrix
/// `M = [[0, 1], [-k/m, -c s/m]]`; `damped` selects `s = 1`.
pub fn mode_exponential(m: f64, k: f64, c: f64, damped: bool, tau: f64) -> [[f64; 2]; 2] {
    let gamma = if damped { c / m } else { 0.0 };
    expm_companion(k / m, gamma, tau)
}

/// Period-one orbit of the hopper with forcing `a cos(2 pi t / period)`.
///
/// # Panics
///
/// Panics when the parameters are not positive and finite (`c >= 0`, `a != 0`),
/// when the flight mode is resonant with the forcing, or when no orbit with
/// exactly one damper-on and one damper-off switch per period is found.  This
/// is a test oracle: failing loudly is the point.
pub fn hopper_orbit(m: f64, k: f64, c: f64, g: f64, x0: f64, a: f64, period: f64) -> OracleOrbit {
    let p = HopperParams {
        m,
        k,
        c,
        g,
        x0,
        a,
        period,
    };
    assert!(
        m > 0.0 && k > 0.0 && c >= 0.0 && period > 0.0,
        "hopper_orbit needs m > 0, k > 0, c >= 0, period > 0 (got {p:?})"
    );
    assert!(
        [g, x0, a].iter().all(|x| x.is_finite()) && a != 0.0,
        "hopper_orbit needs finite g, x0 and a != 0 (got {p:?})"
    );
    let wp = 2.0 * PI / period;
    assert!(
        ((k / m) - wp * wp).abs() > 1e-9 * (k / m),
        "flight mode is resonant with the forcing: k/m = {} equals wp^2 = {}",
        k / m,
        wp * wp
    );

    let damped = Mode::new(&p, true);
    let free = Mode::new(&p, false);

    // Start at phase 0 below the rest position so the acceleration is upward
    // whatever the forcing phase: w0^2 (xe - x) = 2|a|/m > |a cos|/m.
    let mut t_on = 0.0;
    let mut x_on = damped.xe - 2.0 * a.abs() / k;
    for _ in 0..2000 {
        let r = return_map(&p, &damped, &free, t_on, x_on);
        let dt = r.t_next - t_on - period;
        let dx = r.x_next - x_on;
        t_on = r.t_next.rem_euclid(period);
        x_on = r.x_next;
        if dt.abs() < 1e-10 * period && dx.abs() < 1e-10 * x_scale(&p) {
            break;
        }
    }

    // Newton polish of the residual (t_next - t_on - T, x_next - x_on).
    let ht = 1e-6 * period;
    let hx = 1e-6 * x_scale(&p);
    let residual = |t: f64, x: f64| {
        let r = return_map(&p, &damped, &free, t, x);
        [r.t_next - t - period, r.x_next - x]
    };
    for _ in 0..50 {
        let r0 = residual(t_on, x_on);
        let rtp = residual(t_on + ht, x_on);
        let rtm = residual(t_on - ht, x_on);
        let rxp = residual(t_on, x_on + hx);
        let rxm = residual(t_on, x_on - hx);
        let j = [
            [
                (rtp[0] - rtm[0]) / (2.0 * ht),
                (rxp[0] - rxm[0]) / (2.0 * hx),
            ],
            [
                (rtp[1] - rtm[1]) / (2.0 * ht),
                (rxp[1] - rxm[1]) / (2.0 * hx),
            ],
        ];
        let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
        let dt = (j[1][1] * r0[0] - j[0][1] * r0[1]) / det;
        let dx = (-j[1][0] * r0[0] + j[0][0] * r0[1]) / det;
        t_on -= dt;
        x_on -= dx;
        if dt.abs() < 1e-15 * period && dx.abs() < 1e-15 * x_scale(&p) {
            break;
        }
    }
    let r_final = residual(t_on, x_on);
    assert!(
        r_final[0].abs() < 1e-12 * period && r_final[1].abs() < 1e-12 * x_scale(&p),
        "hopper orbit Newton did not converge: residual {r_final:?}"
    );

    let r = return_map(&p, &damped, &free, t_on, x_on);
    let t_on = t_on.rem_euclid(period);
    let t_off = r.t_off.rem_euclid(period);

    let mut orbit = OracleOrbit {
        t_on,
        t_off,
        x_phase0: 0.0,
        v_phase0: 0.0,
        floquet: [(0.0, 0.0); 2],
        monodromy: [[0.0; 2]; 2],
        x_on,
        x_off: r.x_off,
        params: p,
    };
    let s0 = orbit.state(0.0);
    orbit.x_phase0 = s0[0];
    orbit.v_phase0 = s0[1];
    orbit.monodromy = monodromy(&p, t_on, t_off);
    orbit.floquet = eig2(&orbit.monodromy);
    orbit
}

/// Typical size of position excursions, used to scale tolerances and steps.
fn x_scale(p: &HopperParams) -> f64 {
    (p.a.abs() + p.m * p.g.abs()) / p.k
}

struct ReturnMap {
    t_off: f64,
    x_off: f64,
    t_next: f64,
    x_next: f64,
}

/// One stance (damped) plus one flight (free) phase from an upward crossing.
fn return_map(p: &HopperParams, damped: &Mode, free: &Mode, t_on: f64, x_on: f64) -> ReturnMap {
    let horizon = 4.0 * p.period.max(2.0 * PI / damped.w0sq.sqrt());
    let (t_off, s_off) = next_zero(damped, t_on, [x_on, 0.0], 1.0, horizon)
        .unwrap_or_else(|| panic!("damper never turns off after t_on = {t_on}, x_on = {x_on}"));
    let (t_next, s_next) = next_zero(free, t_off, [s_off[0], 0.0], -1.0, horizon)
        .unwrap_or_else(|| panic!("damper never turns on after t_off = {t_off}"));
    ReturnMap {
        t_off,
        x_off: s_off[0],
        t_next,
        x_next: s_next[0],
    }
}

/// First time after `t1` at which the closed-form velocity leaves the sign
/// `sign` (+1: falls through zero, -1: rises through zero), with the state there.
fn next_zero(
    mode: &Mode,
    t1: f64,
    x1: [f64; 2],
    sign: f64,
    horizon: f64,
) -> Option<(f64, [f64; 2])> {
    // 256 samples per shortest relevant oscillation.  A pair of zeros closer
    // than one sample would be missed; that needs v to nearly graze zero, which
    // the transversal orbits this oracle is meant for do not do.
    let shortest = (2.0 * PI / mode.w0sq.sqrt()).min(2.0 * PI / mode.wp);
    let h = shortest / 256.0;
    let n = (horizon / h).ceil() as usize;
    let vel = |t: f64| mode.propagate(t1, x1, t)[1];
    let mut lo = t1;
    let mut hi = None;
    for i in 1..=n {
        let t = t1 + i as f64 * h;
        if sign * vel(t) <= 0.0 {
            hi = Some(t);
            break;
        }
        lo = t;
    }
    let mut hi = hi?;
    // Bisection keeps `lo` on the `sign` side (or at the start) and `hi` past the zero.
    while hi - lo > 1e-9 * h {
        let mid = 0.5 * (lo + hi);
        if sign * vel(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    // Newton on v(t) with v'(t) from the equation of motion, kept inside the bracket.
    let mut t = 0.5 * (lo + hi);
    for _ in 0..8 {
        let s = mode.propagate(t1, x1, t);
        let acc = mode.accel(t, s);
        let next = (t - s[1] / acc).clamp(lo, hi);
        let step = next - t;
        t = next;
        if step.abs() <= 2.0 * f64::EPSILON * t.abs().max(h) {
            break;
        }
    }
    Some((t, mode.propagate(t1, x1, t)))
}

/// One constant-coefficient mode: `x'' + gamma x' + w0sq (x - xe) = (a/m) cos(wp t)`.
#[derive(Debug, Clone, Copy)]
struct Mode {
    w0sq: f64,
    gamma: f64,
    xe: f64,
    wp: f64,
    a_over_m: f64,
    /// Complex amplitude of the sinusoidal particular solution.
    p_re: f64,
    p_im: f64,
}

impl Mode {
    fn new(p: &HopperParams, damped: bool) -> Mode {
        let w0sq = p.k / p.m;
        let gamma = if damped { p.c / p.m } else { 0.0 };
        let wp = 2.0 * PI / p.period;
        let a_over_m = p.a / p.m;
        let dr = w0sq - wp * wp;
        let di = gamma * wp;
        let d2 = dr * dr + di * di;
        Mode {
            w0sq,
            gamma,
            xe: p.x0 - p.m * p.g / p.k,
            wp,
            a_over_m,
            p_re: a_over_m * dr / d2,
            p_im: -a_over_m * di / d2,
        }
    }

    fn particular(&self, t: f64) -> [f64; 2] {
        let (s, c) = (self.wp * t).sin_cos();
        [
            self.xe + self.p_re * c - self.p_im * s,
            -self.wp * (self.p_re * s + self.p_im * c),
        ]
    }

    fn accel(&self, t: f64, s: [f64; 2]) -> f64 {
        -self.w0sq * (s[0] - self.xe) - self.gamma * s[1] + self.a_over_m * (self.wp * t).cos()
    }

    fn propagate(&self, t1: f64, x1: [f64; 2], t: f64) -> [f64; 2] {
        let xp1 = self.particular(t1);
        let xp = self.particular(t);
        let e = expm_companion(self.w0sq, self.gamma, t - t1);
        let h = [x1[0] - xp1[0], x1[1] - xp1[1]];
        [
            xp[0] + e[0][0] * h[0] + e[0][1] * h[1],
            xp[1] + e[1][0] * h[0] + e[1][1] * h[1],
        ]
    }
}

/// `exp(M tau)` for `M = [[0, 1], [-w0sq, -gamma]]` by Cayley-Hamilton.
fn expm_companion(w0sq: f64, gamma: f64, tau: f64) -> [[f64; 2]; 2] {
    let mu = -0.5 * gamma;
    let wd2 = w0sq - 0.25 * gamma * gamma;
    let (ch, sh) = if wd2 > 0.0 {
        let wd = wd2.sqrt();
        ((wd * tau).cos(), (wd * tau).sin() / wd)
    } else if wd2 < 0.0 {
        let r = (-wd2).sqrt();
        ((r * tau).cosh(), (r * tau).sinh() / r)
    } else {
        (1.0, tau)
    };
    let ex = (mu * tau).exp();
    // M - mu I = [[gamma/2, 1], [-w0sq, -gamma/2]].
    [
        [ex * (ch + sh * 0.5 * gamma), ex * sh],
        [ex * (-sh * w0sq), ex * (ch - sh * 0.5 * gamma)],
    ]
}

fn matmul(a: &[[f64; 2]; 2], b: &[[f64; 2]; 2]) -> [[f64; 2]; 2] {
    let mut r = [[0.0; 2]; 2];
    for i in 0..2 {
        for j in 0..2 {
            r[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j];
        }
    }
    r
}

/// Ordered product of mode exponentials over the pieces of `[0, T]`.
fn monodromy(p: &HopperParams, t_on: f64, t_off: f64) -> [[f64; 2]; 2] {
    let mut cuts = [0.0, t_on, t_off, p.period];
    cuts.sort_by(f64::total_cmp);
    let duty_len = (t_off - t_on).rem_euclid(p.period);
    let mut phi = [[1.0, 0.0], [0.0, 1.0]];
    for w in cuts.windows(2) {
        let len = w[1] - w[0];
        if len <= 0.0 {
            continue;
        }
        let mid = 0.5 * (w[0] + w[1]);
        let on = (mid - t_on).rem_euclid(p.period) < duty_len;
        let e = mode_exponential(p.m, p.k, p.c, on, len);
        phi = matmul(&e, &phi);
    }
    phi
}

/// Eigenvalues of a real 2x2 matrix, ordered as documented on [`OracleOrbit::floquet`].
fn eig2(a: &[[f64; 2]; 2]) -> [(f64, f64); 2] {
    let half_tr = 0.5 * (a[0][0] + a[1][1]);
    let det = a[0][0] * a[1][1] - a[0][1] * a[1][0];
    let disc = half_tr * half_tr - det;
    if disc < 0.0 {
        let im = (-disc).sqrt();
        [(half_tr, im), (half_tr, -im)]
    } else {
        // Stable pair: the larger-modulus root directly, the other from the product.
        let big = half_tr + half_tr.signum() * disc.sqrt();
        let small = if big == 0.0 { 0.0 } else { det / big };
        [(big, 0.0), (small, 0.0)]
    }
}
