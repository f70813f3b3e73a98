//! Fixed-step integration with located events: RK4 on a uniform sample grid, for fits whose
//! cost must be a smooth function of the parameters.

use crate::sliding::{self, Filippov};
use crate::{HybridError, HybridSystem};

/// Largest state dimension of [`simulate_fixed_step`] (its buffers live on the stack).
pub const FIXED_STEP_MAX_DIM: usize = 8;
const MAX_DIM: usize = FIXED_STEP_MAX_DIM;
/// Transitions allowed within one step before the motion counts as chattering.
const MAX_EVENTS_PER_STEP: usize = 8;

/// Fixed-step integration: classical fourth-order Runge-Kutta on a uniform grid of
/// `out.len()` samples `dt` apart from `t0`, with `substeps` equal steps per sample, for a
/// hybrid system of dimension at most [`FIXED_STEP_MAX_DIM`]. Writes state component
/// `component` at each sample (sample 0 is the initial state).
///
/// A guard crossing in its direction within a step is located (Illinois false position to
/// `1e-14` of the step) on the cubic Hermite interpolant of the step; the step is then redone
/// up to the crossing, the reset applied, and the rest of the step taken in the new chart. The
/// guard that just fired is not watched again within the same step. At a declared switching
/// surface ([`HybridSystem::sliding_chart`]) whose far side's field points back into it, the
/// state is projected onto the surface and slides on it with Filippov's field, as in
/// [`simulate`](crate::simulate) (crate docs, "Sliding"); the exit conditions are located like
/// any crossing, to the same `1e-14` of the step. The output is therefore a
/// smooth function of the system's parameters between switches, which makes this method suited
/// to fits; its error is that of RK4 with step `dt / substeps` (no error control: choose
/// `substeps` from the system's fastest rate). [`simulate`](crate::simulate) is the adaptive,
/// error-controlled reference.
///
/// # Errors
/// [`HybridError::DimensionMismatch`] for a state of the wrong length (or a system larger than
/// [`FIXED_STEP_MAX_DIM`]), [`HybridError::NonFiniteState`], and [`HybridError::Chattering`]
/// when more than 8 transitions fall within one step. A state that starts on a switching
/// surface starts in `mode0`'s chart (the adaptive method's start rule is not applied).
pub fn simulate_fixed_step<S: HybridSystem + ?Sized>(
    sys: &S,
    mode0: S::Mode,
    t0: f64,
    x0: &[f64],
    dt: f64,
    substeps: usize,
    component: usize,
    out: &mut [f64],
) -> Result<(), HybridError> {
    let n = sys.dim();
    if n > MAX_DIM || x0.len() != n || n == 0 || component >= n {
        return Err(HybridError::DimensionMismatch {
            expected: n.min(MAX_DIM),
            found: x0.len(),
        });
    }
    // One copy per dimension: the state lives in arrays of exactly its length, so the
    // stage loops unroll and nothing beyond the state is copied or zeroed.
    match n {
        1 => run::<S, 1>(sys, mode0, t0, x0, dt, substeps, component, out),
        2 => run::<S, 2>(sys, mode0, t0, x0, dt, substeps, component, out),
        3 => run::<S, 3>(sys, mode0, t0, x0, dt, substeps, component, out),
        4 => run::<S, 4>(sys, mode0, t0, x0, dt, substeps, component, out),
        5 => run::<S, 5>(sys, mode0, t0, x0, dt, substeps, component, out),
        6 => run::<S, 6>(sys, mode0, t0, x0, dt, substeps, component, out),
        7 => run::<S, 7>(sys, mode0, t0, x0, dt, substeps, component, out),
        _ => run::<S, MAX_DIM>(sys, mode0, t0, x0, dt, substeps, component, out),
    }
}

/// [`simulate_fixed_step`] for a system of dimension `N`.
#[allow(clippy::too_many_arguments)] // reason: the arguments of `simulate_fixed_step`
fn run<S: HybridSystem + ?Sized, const N: usize>(
    sys: &S,
    mode0: S::Mode,
    t0: f64,
    x0: &[f64],
    dt: f64,
    substeps: usize,
    component: usize,
    out: &mut [f64],
) -> Result<(), HybridError> {
    let mut st = Stepper::<S, N> {
        sys,
        mode: mode0,
        x: [0.0; N],
        f: [0.0; N],
        slide: None,
    };
    st.x.copy_from_slice(x0);
    sys.vector_field(mode0, t0, &st.x, &mut st.f);
    let Some((first, rest)) = out.split_first_mut() else {
        return Ok(());
    };
    *first = st.x[component];
    let substeps = substeps.max(1);
    let h = dt / substeps as f64;
    let mut j = 0usize;
    for slot in rest {
        for _ in 0..substeps {
            // Times from the step count, so they do not drift over a long record.
            let ta = t0 + j as f64 * h;
            j += 1;
            let tb = t0 + j as f64 * h;
            st.advance(ta, tb)?;
        }
        *slot = st.x[component];
    }
    Ok(())
}

struct Stepper<'a, S: HybridSystem + ?Sized, const N: usize> {
    sys: &'a S,
    mode: S::Mode,
    x: [f64; N],
    /// Vector field at `x` in `mode` (the sliding field while sliding).
    f: [f64; N],
    /// The sliding motion, while the state slides along a switching surface.
    slide: Option<Filippov<'a, S>>,
}

/// The outcome of one trial step.
enum Trial<const N: usize> {
    /// The step reached its end without a crossing: the state and field there.
    Reached([f64; N], [f64; N]),
    /// Guard `guard` (of the chart stepped in) fired at `te`, with the state `xe` there.
    Event { te: f64, guard: usize, xe: [f64; N] },
}

impl<'a, S: HybridSystem + ?Sized, const N: usize> Stepper<'a, S, N> {
    #[inline]
    fn advance(&mut self, ta: f64, tb: f64) -> Result<(), HybridError> {
        let mut t = ta;
        // The guard that just fired sits at zero at the restart; it is not watched again within
        // the same sub-step (a guard with either crossing direction would otherwise fire again
        // at once).
        let mut fired: Option<usize> = None;
        for _ in 0..=MAX_EVENTS_PER_STEP {
            let trial = match &self.slide {
                None => trial(self.sys, self.mode, t, tb, &self.x, &self.f, fired),
                Some(fl) => trial(fl, self.mode, t, tb, &self.x, &self.f, fired),
            }?;
            match trial {
                Trial::Reached(xb, fb) => {
                    self.x = xb;
                    self.f = fb;
                    return Ok(());
                }
                Trial::Event { te, guard, xe } => {
                    fired = self.event(te, guard, xe);
                    t = te;
                }
            }
        }
        Err(HybridError::Chattering {
            time: t,
            events: MAX_EVENTS_PER_STEP + 1,
        })
    }

    /// Applies the event of guard `guard` at `(te, xe)`: a transition, the start of sliding
    /// along a switching surface whose far side's field points back into it, or, while
    /// sliding, its end. Returns the guard of the new chart that sits at zero.
    #[inline(never)]
    fn event(&mut self, te: f64, guard: usize, mut xe: [f64; N]) -> Option<usize> {
        if let Some(fl) = self.slide.take() {
            // Wrapper guard 0 leaves into the arrival chart, 1 into the far side's, `k >= 2`
            // is another guard of the arrival chart, whose transition follows at once.
            let (from, to, surface) = (fl.from, fl.to, fl.guard);
            let next = match guard {
                0 => {
                    self.mode = from;
                    Some(surface)
                }
                1 => {
                    self.mode = to;
                    // The same surface seen from the far side.
                    (0..self.sys.num_guards(to))
                        .find(|&j| self.sys.sliding_chart(to, j) == Some(from))
                }
                k => {
                    let inner = fl.inner_guard(k);
                    self.mode = self.sys.transition(from, inner, te, &mut xe);
                    Some(inner)
                }
            };
            self.restart(te, xe);
            return next;
        }
        if let Some(to) = self.sys.sliding_chart(self.mode, guard) {
            let (mut grad, mut xs) = ([0.0; N], [0.0; N]);
            let mut on = xe;
            sliding::project(self.sys, self.mode, guard, te, &mut on, &mut grad, &mut xs);
            let fl = Filippov::new(self.sys, self.mode, to, guard, 1.0);
            let (a, b) = fl.speeds(te, &on);
            if a * b < 0.0 {
                // Both fields push into the surface: the state slides on it.
                self.slide = Some(Filippov::new(self.sys, self.mode, to, guard, a.signum()));
                self.restart(te, on);
                return None;
            }
        }
        self.mode = self.sys.transition(self.mode, guard, te, &mut xe);
        self.restart(te, xe);
        Some(guard)
    }

    /// Restarts at `(t, x)` in the current chart (or sliding motion).
    fn restart(&mut self, t: f64, x: [f64; N]) {
        self.x = x;
        match &self.slide {
            None => self.sys.vector_field(self.mode, t, &self.x, &mut self.f),
            Some(fl) => fl.vector_field(self.mode, t, &self.x, &mut self.f),
        }
    }
}

/// One RK4 step of `sys` in chart `mode` from `(t, x)` to `tb`, with the first crossing of a
/// guard (other than `skip`) located on the step's cubic Hermite interpolant.
#[inline]
fn trial<H: HybridSystem + ?Sized, const N: usize>(
    sys: &H,
    mode: H::Mode,
    t: f64,
    tb: f64,
    x: &[f64; N],
    f: &[f64; N],
    skip: Option<usize>,
) -> Result<Trial<N>, HybridError> {
    let h = tb - t;
    let xb = rk4_step(sys, mode, t, x, f, h);
    if !xb.iter().all(|v| v.is_finite()) {
        return Err(HybridError::NonFiniteState { time: tb });
    }
    let mut fb = [0.0; N];
    sys.vector_field(mode, tb, &xb, &mut fb);
    let mut first: Option<(f64, usize)> = None;
    for g in 0..sys.num_guards(mode) {
        if skip == Some(g) {
            continue;
        }
        let ga = sys.guard(mode, g, t, x);
        let gb = sys.guard(mode, g, tb, &xb);
        if !sys.guard_direction(mode, g).accepts(ga, gb) {
            continue;
        }
        let theta = locate(
            |th| {
                let buf = hermite(x, f, &xb, &fb, h, th);
                sys.guard(mode, g, t + th * h, &buf)
            },
            ga,
            gb,
        );
        if first.map_or(true, |(th0, _)| theta < th0) {
            first = Some((theta, g));
        }
    }
    let Some((theta, guard)) = first else {
        return Ok(Trial::Reached(xb, fb));
    };
    let te = t + theta * h;
    let xe = rk4_step(sys, mode, t, x, f, te - t);
    Ok(Trial::Event { te, guard, xe })
}

#[inline]
fn rk4_step<S: HybridSystem + ?Sized, const N: usize>(
    sys: &S,
    mode: S::Mode,
    t: f64,
    x: &[f64; N],
    f0: &[f64; N],
    h: f64,
) -> [f64; N] {
    let mut tmp = [0.0; N];
    let mut k2 = [0.0; N];
    let mut k3 = [0.0; N];
    let mut k4 = [0.0; N];
    let half = 0.5 * h;
    for i in 0..N {
        tmp[i] = x[i] + half * f0[i];
    }
    sys.vector_field(mode, t + half, &tmp, &mut k2);
    for i in 0..N {
        tmp[i] = x[i] + half * k2[i];
    }
    sys.vector_field(mode, t + half, &tmp, &mut k3);
    for i in 0..N {
        tmp[i] = x[i] + h * k3[i];
    }
    sys.vector_field(mode, t + h, &tmp, &mut k4);
    let sixth = h / 6.0;
    let mut out = [0.0; N];
    for i in 0..N {
        out[i] = x[i] + sixth * (f0[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
    }
    out
}

/// Cubic Hermite interpolant of a step of length `h` at fraction `th`.
#[inline]
fn hermite<const N: usize>(
    xa: &[f64; N],
    fa: &[f64; N],
    xb: &[f64; N],
    fb: &[f64; N],
    h: f64,
    th: f64,
) -> [f64; N] {
    let s = 1.0 - th;
    let h00 = (1.0 + 2.0 * th) * s * s;
    let h10 = th * s * s;
    let h01 = th * th * (3.0 - 2.0 * th);
    let h11 = -th * th * s;
    let mut out = [0.0; N];
    for i in 0..N {
        out[i] = h00 * xa[i] + h10 * h * fa[i] + h01 * xb[i] + h11 * h * fb[i];
    }
    out
}

/// Root of `g` on `[0, 1]` given `g(0) = ga` and `g(1) = gb` of opposite signs (or `gb`
/// zero): Illinois false position to `1e-14`.
fn locate(mut g: impl FnMut(f64) -> f64, ga: f64, gb: f64) -> f64 {
    let (mut a, mut fa, mut b, mut fb) = (0.0_f64, ga, 1.0_f64, gb);
    if fb.is_nan() || fb.abs() <= 0.0 {
        return 1.0;
    }
    let mut side = 0i8;
    let mut c = 1.0;
    for _ in 0..100 {
        if b - a <= 1e-14 {
            return b;
        }
        let mut next = (a * fb - b * fa) / (fb - fa);
        if !(next > a && next < b) {
            next = 0.5 * (a + b);
        }
        let converged = (next - c).abs() <= 1e-15;
        c = next;
        let fc = g(c);
        if converged || fc.is_nan() || fc.abs() <= 0.0 {
            return c;
        }
        if (fc > 0.0) == (fb > 0.0) {
            b = c;
            fb = fc;
            if side == -1 {
                fa *= 0.5;
            }
            side = -1;
        } else {
            a = c;
            fa = fc;
            if side == 1 {
                fb *= 0.5;
            }
            side = 1;
        }
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Crossing;
    use approx::assert_abs_diff_eq;

    /// A bouncing ball: x'' = -g, velocity reversed with restitution at x = 0.
    struct Ball;
    impl HybridSystem for Ball {
        type Mode = ();
        fn dim(&self) -> usize {
            2
        }
        fn vector_field(&self, _m: (), _t: f64, _x: &[f64], d: &mut [f64]) {
            d[0] = _x[1];
            d[1] = -9.81;
        }
        fn num_guards(&self, _m: ()) -> usize {
            1
        }
        fn guard(&self, _m: (), _i: usize, _t: f64, x: &[f64]) -> f64 {
            x[0]
        }
        fn guard_direction(&self, _m: (), _i: usize) -> Crossing {
            Crossing::Falling
        }
        fn transition(&self, m: (), _i: usize, _t: f64, x: &mut [f64]) -> Self::Mode {
            x[1] *= -0.8;
            m
        }
    }

    #[test]
    fn bouncing_ball_matches_the_closed_form() {
        // Dropped from 1 m: impact at t1 = sqrt(2/9.81), rebound speed 0.8 * 9.81 * t1.
        // Between events the motion is a parabola, which RK4 integrates exactly, and the
        // Hermite interpolant of a parabola is exact, so only root finding (1e-14) and rounding
        // remain: 1e-10 m is generous.
        let g: f64 = 9.81;
        let t1 = (2.0 / g).sqrt();
        let v1 = 0.8 * g * t1;
        let dt = 0.01;
        let mut out = vec![0.0; 60];
        simulate_fixed_step(&Ball, (), 0.0, &[1.0, 0.0], dt, 1, 0, &mut out).unwrap();
        for (i, &x) in out.iter().enumerate() {
            let t = i as f64 * dt;
            let exact = if t < t1 {
                1.0 - 0.5 * g * t * t
            } else {
                let s = t - t1;
                v1 * s - 0.5 * g * s * s
            };
            assert_abs_diff_eq!(x, exact, epsilon = 1e-10);
        }
    }

    #[test]
    fn root_finder_finds_a_simple_root() {
        let r = locate(|t| t * t - 0.3, -0.3, 0.7);
        assert_abs_diff_eq!(r, 0.3f64.sqrt(), epsilon = 1e-13);
    }
}
