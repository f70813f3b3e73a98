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
    let samples = out.len();
    let write = |i: usize, x: &[f64]| out[i] = x[component];
    // One copy per dimension: the state lives in arrays of exactly its length, so the
    // stage loops unroll and nothing beyond the state is copied or zeroed.
    match n {
        1 => simulate_fixed_step_states::<S, 1>(sys, mode0, t0, x0, dt, substeps, samples, write),
        2 => simulate_fixed_step_states::<S, 2>(sys, mode0, t0, x0, dt, substeps, samples, write),
        3 => simulate_fixed_step_states::<S, 3>(sys, mode0, t0, x0, dt, substeps, samples, write),
        4 => simulate_fixed_step_states::<S, 4>(sys, mode0, t0, x0, dt, substeps, samples, write),
        5 => simulate_fixed_step_states::<S, 5>(sys, mode0, t0, x0, dt, substeps, samples, write),
        6 => simulate_fixed_step_states::<S, 6>(sys, mode0, t0, x0, dt, substeps, samples, write),
        7 => simulate_fixed_step_states::<S, 7>(sys, mode0, t0, x0, dt, substeps, samples, write),
        _ => simulate_fixed_step_states::<S, MAX_DIM>(
            sys, mode0, t0, x0, dt, substeps, samples, write,
        ),
    }
}

/// [`simulate_fixed_step`] for a system of dimension `N` (given at compile time, so that a
/// larger state, one with sensitivities appended say, still lives in arrays of exactly its
/// length), handing the whole state at every sample to `write(i, x)` (sample
/// `i = 0..samples`). The same steps, crossings and sliding as [`simulate_fixed_step`]; only
/// what is written differs.
///
/// # Errors
/// As [`simulate_fixed_step`]; a system whose dimension is not `N`, or a start of another
/// length, is a [`HybridError::DimensionMismatch`].
#[allow(clippy::too_many_arguments)] // reason: the system, its start, the grid and the writer
#[inline]
pub fn simulate_fixed_step_states<S: HybridSystem + ?Sized, const N: usize>(
    sys: &S,
    mode0: S::Mode,
    t0: f64,
    x0: &[f64],
    dt: f64,
    substeps: usize,
    samples: usize,
    mut write: impl FnMut(usize, &[f64]),
) -> Result<(), HybridError> {
    if sys.dim() != N || x0.len() != N {
        return Err(HybridError::DimensionMismatch {
            expected: N,
            found: if sys.dim() == N { x0.len() } else { sys.dim() },
        });
    }
    let mut st = Stepper::<S, N> {
        sys,
        mode: mode0,
        x: [0.0; N],
        f: [0.0; N],
        slide: None,
    };
    st.x.copy_from_slice(x0);
    sys.vector_field(mode0, t0, &st.x, &mut st.f);
    if samples == 0 {
        return Ok(());
    }
    write(0, &st.x);
    let substeps = substeps.max(1);
    let h = dt / substeps as f64;
    let mut j = 0usize;
    for i in 1..samples {
        for _ in 0..substeps {
            // Times from the step count, so they do not drift over a long record.
            let ta = t0 + j as f64 * h;
            j += 1;
            let tb = t0 + j as f64 * h;
            st.advance(ta, tb)?;
        }
        write(i, &st.x);
    }
    Ok(())
}

/// One simulation of a batch run by [`simulate_fixed_step_batch`]: a system, its starting mode
/// and state, and the samples to write.
pub struct FixedStepLane<'a, S: HybridSystem + ?Sized> {
    /// The system simulated.
    pub system: &'a S,
    /// The starting mode.
    pub mode0: S::Mode,
    /// The starting state.
    pub x0: &'a [f64],
    /// The samples written, as [`simulate_fixed_step`] writes them.
    pub out: &'a mut [f64],
}

impl<S: HybridSystem + ?Sized> std::fmt::Debug for FixedStepLane<'_, S> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FixedStepLane")
            .field("mode0", &self.mode0)
            .field("x0", &self.x0)
            .field("samples", &self.out.len())
            .finish_non_exhaustive()
    }
}

/// [`simulate_fixed_step`] for several systems of one type on the same grid, stepped in
/// lockstep: every lane gets exactly the samples and the result (bit for bit) that its own
/// [`simulate_fixed_step`] call would give. A lane that fails stops there; the others go on.
///
/// A single simulation waits on itself: each Runge-Kutta stage needs the one before. Stepping
/// independent lanes together (the perturbed models of a finite-difference Jacobian, say) lets
/// the processor overlap them; three or more lanes of a two-state model run in about half the
/// time of their serial simulations. Lanes of different dimension or sample count are simulated
/// one after another.
pub fn simulate_fixed_step_batch<S: HybridSystem + ?Sized>(
    lanes: &mut [FixedStepLane<'_, S>],
    t0: f64,
    dt: f64,
    substeps: usize,
    component: usize,
) -> Vec<Result<(), HybridError>> {
    let Some(first) = lanes.first() else {
        return Vec::new();
    };
    let (n, len) = (first.system.dim(), first.out.len());
    let uniform = n <= MAX_DIM
        && n > 0
        && component < n
        && lanes
            .iter()
            .all(|l| l.system.dim() == n && l.x0.len() == n && l.out.len() == len);
    if !uniform || lanes.len() == 1 {
        return lanes
            .iter_mut()
            .map(|l| {
                simulate_fixed_step(l.system, l.mode0, t0, l.x0, dt, substeps, component, l.out)
            })
            .collect();
    }
    match n {
        1 => run_batch::<S, 1>(lanes, t0, dt, substeps, component),
        2 => run_batch::<S, 2>(lanes, t0, dt, substeps, component),
        3 => run_batch::<S, 3>(lanes, t0, dt, substeps, component),
        4 => run_batch::<S, 4>(lanes, t0, dt, substeps, component),
        5 => run_batch::<S, 5>(lanes, t0, dt, substeps, component),
        6 => run_batch::<S, 6>(lanes, t0, dt, substeps, component),
        7 => run_batch::<S, 7>(lanes, t0, dt, substeps, component),
        _ => run_batch::<S, MAX_DIM>(lanes, t0, dt, substeps, component),
    }
}

/// [`simulate_fixed_step_batch`] for lanes of dimension `N`, all with the same sample count.
///
/// Kept apart from the single simulation ([`simulate_fixed_step_states`]) on purpose: one loop
/// serving both (a single simulation as a batch of one lane) left the single simulation as
/// fast but made the lockstep 50 % slower per lane (`cargo bench -p htfid-hybrid --bench
/// fixed`: 11.7 ms against 7.7 ms for four lanes).
fn run_batch<S: HybridSystem + ?Sized, const N: usize>(
    lanes: &mut [FixedStepLane<'_, S>],
    t0: f64,
    dt: f64,
    substeps: usize,
    component: usize,
) -> Vec<Result<(), HybridError>> {
    let mut results: Vec<Result<(), HybridError>> = lanes.iter().map(|_| Ok(())).collect();
    let mut steppers: Vec<Option<Stepper<'_, S, N>>> = lanes
        .iter()
        .map(|l| {
            let mut st = Stepper {
                sys: l.system,
                mode: l.mode0,
                x: [0.0; N],
                f: [0.0; N],
                slide: None,
            };
            st.x.copy_from_slice(l.x0);
            l.system.vector_field(l.mode0, t0, &st.x, &mut st.f);
            Some(st)
        })
        .collect();
    let len = lanes[0].out.len();
    if len == 0 {
        return results;
    }
    for (l, st) in lanes.iter_mut().zip(&steppers) {
        if let Some(st) = st {
            l.out[0] = st.x[component];
        }
    }
    let substeps = substeps.max(1);
    let h = dt / substeps as f64;
    let mut j = 0usize;
    for i in 1..len {
        for _ in 0..substeps {
            // Times from the step count, as in `simulate_fixed_step_states`.
            let ta = t0 + j as f64 * h;
            j += 1;
            let tb = t0 + j as f64 * h;
            for (slot, result) in steppers.iter_mut().zip(results.iter_mut()) {
                if let Some(st) = slot {
                    if let Err(e) = st.advance(ta, tb) {
                        *result = Err(e);
                        *slot = None;
                    }
                }
            }
        }
        for (l, st) in lanes.iter_mut().zip(&steppers) {
            if let Some(st) = st {
                l.out[i] = st.x[component];
            }
        }
    }
    results
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

/// The outcome of one trial step. The states are written to the caller's arrays (see
/// [`trial`]), which keeps them in registers: an enum carrying them would pass them through
/// memory in halves and read them back whole, and the processor stalls on every such read.
enum Trial {
    /// The step reached its end without a crossing.
    Reached,
    /// Guard `guard` (of the chart stepped in) fired at `te`.
    Event { te: f64, guard: usize },
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
            let (mut xb, mut fb) = ([0.0; N], [0.0; N]);
            let trial = match &self.slide {
                None => trial(
                    self.sys, self.mode, t, tb, &self.x, &self.f, fired, &mut xb, &mut fb,
                ),
                Some(fl) => trial(
                    fl, self.mode, t, tb, &self.x, &self.f, fired, &mut xb, &mut fb,
                ),
            }?;
            match trial {
                Trial::Reached => {
                    self.x = xb;
                    self.f = fb;
                    return Ok(());
                }
                Trial::Event { te, guard } => {
                    fired = self.event(te, guard, xb);
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
/// guard (other than `skip`) located on the step's cubic Hermite interpolant. Reached, the
/// step leaves the state and field at `tb` in `xb` and `fb`; at an event, the state there in
/// `xb`.
#[inline]
#[allow(clippy::too_many_arguments)] // reason: the step, its start and its two outputs
fn trial<H: HybridSystem + ?Sized, const N: usize>(
    sys: &H,
    mode: H::Mode,
    t: f64,
    tb: f64,
    x: &[f64; N],
    f: &[f64; N],
    skip: Option<usize>,
    xb: &mut [f64; N],
    fb: &mut [f64; N],
) -> Result<Trial, HybridError> {
    let h = tb - t;
    *xb = rk4_step(sys, mode, t, x, f, h);
    if !xb.iter().all(|v| v.is_finite()) {
        return Err(HybridError::NonFiniteState { time: tb });
    }
    sys.vector_field(mode, tb, xb, fb);
    let mut first: Option<(f64, usize)> = None;
    for g in 0..sys.num_guards(mode) {
        if skip == Some(g) {
            continue;
        }
        let ga = sys.guard(mode, g, t, x);
        let gb = sys.guard(mode, g, tb, xb);
        if !sys.guard_direction(mode, g).accepts(ga, gb) {
            continue;
        }
        let theta = locate(
            |th| {
                let buf = hermite(x, f, xb, fb, h, th);
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
        return Ok(Trial::Reached);
    };
    let te = t + theta * h;
    *xb = rk4_step(sys, mode, t, x, f, te - t);
    Ok(Trial::Event { te, guard })
}

#[inline(always)]
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

    /// A ball bouncing on a floor that follows `floor(t)`, dropped from `height`: a lane of
    /// its own per floor, so the lanes' events fall in different steps.
    struct Floor {
        amplitude: f64,
        restitution: f64,
    }
    impl HybridSystem for Floor {
        type Mode = ();
        fn dim(&self) -> usize {
            2
        }
        fn vector_field(&self, _m: (), _t: f64, x: &[f64], d: &mut [f64]) {
            d[0] = x[1];
            d[1] = -9.81 - 0.3 * x[1];
        }
        fn num_guards(&self, _m: ()) -> usize {
            1
        }
        fn guard(&self, _m: (), _i: usize, t: f64, x: &[f64]) -> f64 {
            x[0] - self.amplitude * (7.0 * t).sin()
        }
        fn guard_direction(&self, _m: (), _i: usize) -> Crossing {
            Crossing::Falling
        }
        fn transition(&self, m: (), _i: usize, t: f64, x: &mut [f64]) -> Self::Mode {
            let floor_speed = 7.0 * self.amplitude * (7.0 * t).cos();
            x[1] = floor_speed - self.restitution * (x[1] - floor_speed);
            m
        }
    }

    #[test]
    fn a_batch_gives_each_lane_its_own_simulation_bit_for_bit() {
        // Lanes with impacts at different times, one that blows up (an infinite restitution
        // makes the state non-finite at its first impact) and one that starts higher: every
        // lane must equal its serial run exactly, the failing one with the same error.
        let systems = [
            Floor {
                amplitude: 0.05,
                restitution: 0.8,
            },
            Floor {
                amplitude: 0.02,
                restitution: 0.6,
            },
            Floor {
                amplitude: 0.05,
                restitution: f64::INFINITY,
            },
            Floor {
                amplitude: 0.0,
                restitution: 0.9,
            },
        ];
        let starts = [[1.0, 0.0], [0.7, 0.5], [1.0, 0.0], [1.3, -0.2]];
        let (dt, n, substeps) = (0.01, 200, 3);
        let mut serial = vec![vec![0.0; n]; systems.len()];
        let mut serial_ok = Vec::new();
        for ((sys, x0), out) in systems.iter().zip(&starts).zip(serial.iter_mut()) {
            serial_ok.push(simulate_fixed_step(sys, (), 0.1, x0, dt, substeps, 0, out).is_ok());
        }
        assert_eq!(serial_ok, [true, true, false, true]);
        let mut batch = vec![vec![0.0; n]; systems.len()];
        let mut lanes: Vec<FixedStepLane<'_, Floor>> = systems
            .iter()
            .zip(&starts)
            .zip(batch.iter_mut())
            .map(|((system, x0), out)| FixedStepLane {
                system,
                mode0: (),
                x0,
                out,
            })
            .collect();
        let results = simulate_fixed_step_batch(&mut lanes, 0.1, dt, substeps, 0);
        let ok: Vec<bool> = results.iter().map(|r| r.is_ok()).collect();
        assert_eq!(ok, serial_ok);
        assert!(matches!(
            results[2],
            Err(HybridError::NonFiniteState { .. })
        ));
        for (lane, (a, b)) in serial.iter().zip(&batch).enumerate() {
            for (i, (x, y)) in a.iter().zip(b).enumerate() {
                assert_eq!(
                    x.to_bits(),
                    y.to_bits(),
                    "lane {lane}, sample {i}: {x} vs {y}"
                );
            }
        }
    }

    #[test]
    fn root_finder_finds_a_simple_root() {
        let r = locate(|t| t * t - 0.3, -0.3, 0.7);
        assert_abs_diff_eq!(r, 0.3f64.sqrt(), epsilon = 1e-13);
    }
}
