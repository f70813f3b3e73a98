//! Fixed-step integration with located events: RK4 on a uniform sample grid, for fits whose
//! cost must be a smooth function of the parameters.

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
/// guard that just fired is not watched again within the same step. The output is therefore a
/// smooth function of the system's parameters between switches, which makes this method suited
/// to fits; its error is that of RK4 with step `dt / substeps` (no error control: choose
/// `substeps` from the system's fastest rate). [`simulate`](crate::simulate) is the adaptive,
/// error-controlled reference.
///
/// # Errors
/// [`HybridError::DimensionMismatch`] for a state of the wrong length (or a system larger than
/// [`FIXED_STEP_MAX_DIM`]), [`HybridError::NonFiniteState`], [`HybridError::Chattering`]
/// when more than 8 transitions fall within one step, and [`HybridError::SlidingUnsupported`]
/// where the motion would slide along a declared switching surface
/// ([`HybridSystem::sliding_chart`]): this method does not slide, use
/// [`simulate`](crate::simulate).
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
    let mut st = Stepper {
        sys,
        n,
        mode: mode0,
        x: [0.0; MAX_DIM],
        f: [0.0; MAX_DIM],
    };
    st.x[..n].copy_from_slice(x0);
    sys.vector_field(mode0, t0, &st.x[..n], &mut st.f[..n]);
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

struct Stepper<'a, S: HybridSystem + ?Sized> {
    sys: &'a S,
    n: usize,
    mode: S::Mode,
    x: [f64; MAX_DIM],
    /// Vector field at `x` in `mode`.
    f: [f64; MAX_DIM],
}

impl<S: HybridSystem + ?Sized> Stepper<'_, S> {
    fn advance(&mut self, ta: f64, tb: f64) -> Result<(), HybridError> {
        let n = self.n;
        let mut t = ta;
        // The guard that just fired sits at zero at the restart; it is not watched again within
        // the same sub-step (a guard with either crossing direction would otherwise fire again
        // at once).
        let mut fired: Option<usize> = None;
        for _ in 0..=MAX_EVENTS_PER_STEP {
            let h = tb - t;
            let mut xb = [0.0; MAX_DIM];
            rk4_step(self.sys, self.mode, t, &self.x, &self.f, h, n, &mut xb);
            if !xb[..n].iter().all(|v| v.is_finite()) {
                return Err(HybridError::NonFiniteState { time: tb });
            }
            let mut fb = [0.0; MAX_DIM];
            self.sys.vector_field(self.mode, tb, &xb[..n], &mut fb[..n]);
            let mut first: Option<(f64, usize)> = None;
            for g in 0..self.sys.num_guards(self.mode) {
                if fired == Some(g) {
                    continue;
                }
                let ga = self.sys.guard(self.mode, g, t, &self.x[..n]);
                let gb = self.sys.guard(self.mode, g, tb, &xb[..n]);
                if !self.sys.guard_direction(self.mode, g).accepts(ga, gb) {
                    continue;
                }
                let (xa, fa) = (&self.x, &self.f);
                let mut buf = [0.0; MAX_DIM];
                let theta = locate(
                    |th| {
                        hermite(xa, fa, &xb, &fb, h, th, n, &mut buf);
                        self.sys.guard(self.mode, g, t + th * h, &buf[..n])
                    },
                    ga,
                    gb,
                );
                if first.map_or(true, |(th0, _)| theta < th0) {
                    first = Some((theta, g));
                }
            }
            let Some((theta, guard)) = first else {
                self.x = xb;
                self.f = fb;
                return Ok(());
            };
            let te = t + theta * h;
            let mut xe = [0.0; MAX_DIM];
            rk4_step(self.sys, self.mode, t, &self.x, &self.f, te - t, n, &mut xe);
            if let Some(to) = self.sys.sliding_chart(self.mode, guard) {
                // This method does not slide: where the far side's field points back into the
                // surface, stepping on would chatter or pass through it in the wrong chart.
                let (mut fa, mut fb) = ([0.0; MAX_DIM], [0.0; MAX_DIM]);
                let (mut grad, mut xs) = ([0.0; MAX_DIM], [0.0; MAX_DIM]);
                self.sys.vector_field(self.mode, te, &xe[..n], &mut fa[..n]);
                self.sys.vector_field(to, te, &xe[..n], &mut fb[..n]);
                let (a, b, _) = crate::sliding::normal_speeds(
                    self.sys,
                    self.mode,
                    guard,
                    te,
                    &xe[..n],
                    &fa[..n],
                    Some(&fb[..n]),
                    &mut grad[..n],
                    &mut xs[..n],
                );
                if a * b < 0.0 {
                    return Err(HybridError::SlidingUnsupported { time: te, guard });
                }
            }
            self.mode = self.sys.transition(self.mode, guard, te, &mut xe[..n]);
            fired = Some(guard);
            self.x = xe;
            self.sys
                .vector_field(self.mode, te, &self.x[..n], &mut self.f[..n]);
            t = te;
        }
        Err(HybridError::Chattering {
            time: t,
            events: MAX_EVENTS_PER_STEP + 1,
        })
    }
}

#[inline]
fn rk4_step<S: HybridSystem + ?Sized>(
    sys: &S,
    mode: S::Mode,
    t: f64,
    x: &[f64; MAX_DIM],
    f0: &[f64; MAX_DIM],
    h: f64,
    n: usize,
    out: &mut [f64; MAX_DIM],
) {
    let mut tmp = [0.0; MAX_DIM];
    let mut k2 = [0.0; MAX_DIM];
    let mut k3 = [0.0; MAX_DIM];
    let mut k4 = [0.0; MAX_DIM];
    let half = 0.5 * h;
    for i in 0..n {
        tmp[i] = x[i] + half * f0[i];
    }
    sys.vector_field(mode, t + half, &tmp[..n], &mut k2[..n]);
    for i in 0..n {
        tmp[i] = x[i] + half * k2[i];
    }
    sys.vector_field(mode, t + half, &tmp[..n], &mut k3[..n]);
    for i in 0..n {
        tmp[i] = x[i] + h * k3[i];
    }
    sys.vector_field(mode, t + h, &tmp[..n], &mut k4[..n]);
    let sixth = h / 6.0;
    for i in 0..n {
        out[i] = x[i] + sixth * (f0[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
    }
}

/// Cubic Hermite interpolant of a step of length `h` at fraction `th`.
#[inline]
fn hermite(
    xa: &[f64; MAX_DIM],
    fa: &[f64; MAX_DIM],
    xb: &[f64; MAX_DIM],
    fb: &[f64; MAX_DIM],
    h: f64,
    th: f64,
    n: usize,
    out: &mut [f64; MAX_DIM],
) {
    let s = 1.0 - th;
    let h00 = (1.0 + 2.0 * th) * s * s;
    let h10 = th * s * s;
    let h01 = th * th * (3.0 - 2.0 * th);
    let h11 = -th * th * s;
    for i in 0..n {
        out[i] = h00 * xa[i] + h10 * h * fa[i] + h01 * xb[i] + h11 * h * fb[i];
    }
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
