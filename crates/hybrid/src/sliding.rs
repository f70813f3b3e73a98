//! Filippov sliding along a switching surface ([`HybridSystem::sliding_chart`]).
//!
//! While the motion slides along guard `i` between charts `A` (the chart it arrived in) and
//! `B`, the integrator steps the convex combination `f_s = (1 - alpha) f_A + alpha f_B` with
//! `alpha = a / (a - b)`, where `a` and `b` are the normal speeds `dg/dt` of the guard along
//! `f_A` and `f_B`. That choice makes `dg/dt = 0` along `f_s`, so the state stays on the
//! surface. Sliding lasts while `a` and `b` keep the opposite signs they had at entry
//! (`alpha` in `(0, 1)`); the two exit conditions are guards of the [`Filippov`] system
//! (`sigma a` and `-sigma b`, both falling), so they are located like any crossing.

use std::cell::{Cell, RefCell};

use crate::{Crossing, HybridSystem};

/// Relative step of the finite differences used where a system supplies no guard gradient:
/// the cube root of machine epsilon balances truncation (`d^2`) against rounding (`eps / d`).
const FD_REL: f64 = 6.0e-6;

/// Work buffers of the sliding field (the trait's methods take `&self`).
#[derive(Debug)]
struct Buffers {
    fa: Vec<f64>,
    fb: Vec<f64>,
    grad: Vec<f64>,
    xs: Vec<f64>,
}

/// The sliding motion along guard `guard` between charts `from` and `to`, seen as a hybrid
/// system: one chart, the Filippov field, and the exit conditions as guards.
///
/// Guards: 0 is `sigma a` (falls to zero when the field of `from` stops pushing into the
/// surface: the motion leaves into `from`), 1 is `-sigma b` (the field of `to` stops pushing
/// into it: the motion leaves into `to`), `2..` are the other guards of `from`, which stay
/// active while sliding.
pub(crate) struct Filippov<'s, S: HybridSystem + ?Sized> {
    sys: &'s S,
    pub(crate) from: S::Mode,
    pub(crate) to: S::Mode,
    pub(crate) guard: usize,
    /// Sign of `a` at entry: `from`'s field pushes toward the surface in this direction.
    sigma: f64,
    buf: RefCell<Buffers>,
    /// Evaluations made inside trait calls, collected by the integrator into its counters.
    pub(crate) rhs_evals: Cell<u64>,
    pub(crate) guard_evals: Cell<u64>,
}

impl<'s, S: HybridSystem + ?Sized> Filippov<'s, S> {
    pub(crate) fn new(sys: &'s S, from: S::Mode, to: S::Mode, guard: usize, sigma: f64) -> Self {
        let n = sys.dim();
        Filippov {
            sys,
            from,
            to,
            guard,
            sigma,
            buf: RefCell::new(Buffers {
                fa: vec![0.0; n],
                fb: vec![0.0; n],
                grad: vec![0.0; n],
                xs: vec![0.0; n],
            }),
            rhs_evals: Cell::new(0),
            guard_evals: Cell::new(0),
        }
    }

    /// The guard of `from` behind wrapper guard `k >= 2`.
    pub(crate) fn inner_guard(&self, k: usize) -> usize {
        let j = k - 2;
        if j < self.guard {
            j
        } else {
            j + 1
        }
    }

    /// The guard index to report for wrapper guard `k`: the surface for the exit conditions.
    pub(crate) fn reported_guard(&self, k: usize) -> usize {
        if k < 2 {
            self.guard
        } else {
            self.inner_guard(k)
        }
    }

    /// `(a, b)` at `(t, x)`, with both fields evaluated.
    pub(crate) fn speeds(&self, t: f64, x: &[f64]) -> (f64, f64) {
        let mut guard = self.buf.borrow_mut();
        let b = &mut *guard;
        self.sys.vector_field(self.from, t, x, &mut b.fa);
        self.sys.vector_field(self.to, t, x, &mut b.fb);
        self.rhs_evals.set(self.rhs_evals.get() + 2);
        let (sa, sb, evals) = normal_speeds(
            self.sys,
            self.from,
            self.guard,
            t,
            x,
            &b.fa,
            Some(&b.fb),
            &mut b.grad,
            &mut b.xs,
        );
        self.guard_evals.set(self.guard_evals.get() + evals);
        (sa, sb)
    }

    /// One normal speed: of `from` (`which_to == false`) or of `to`.
    fn one_speed(&self, which_to: bool, t: f64, x: &[f64]) -> f64 {
        let mut guard = self.buf.borrow_mut();
        let b = &mut *guard;
        let mode = if which_to { self.to } else { self.from };
        self.sys.vector_field(mode, t, x, &mut b.fa);
        self.rhs_evals.set(self.rhs_evals.get() + 1);
        let (s, _, evals) = normal_speeds(
            self.sys,
            self.from,
            self.guard,
            t,
            x,
            &b.fa,
            None,
            &mut b.grad,
            &mut b.xs,
        );
        self.guard_evals.set(self.guard_evals.get() + evals);
        s
    }
}

impl<S: HybridSystem + ?Sized> HybridSystem for Filippov<'_, S> {
    type Mode = S::Mode;

    fn dim(&self) -> usize {
        self.sys.dim()
    }

    fn vector_field(&self, _mode: S::Mode, t: f64, x: &[f64], dxdt: &mut [f64]) {
        let mut guard = self.buf.borrow_mut();
        let b = &mut *guard;
        self.sys.vector_field(self.from, t, x, dxdt);
        self.sys.vector_field(self.to, t, x, &mut b.fb);
        // The trait call counts one evaluation; the second one is counted here.
        self.rhs_evals.set(self.rhs_evals.get() + 1);
        let (sa, sb, evals) = normal_speeds(
            self.sys,
            self.from,
            self.guard,
            t,
            x,
            dxdt,
            Some(&b.fb),
            &mut b.grad,
            &mut b.xs,
        );
        self.guard_evals.set(self.guard_evals.get() + evals);
        // While sliding, sa and sb have opposite signs, so the denominator is bounded away
        // from zero; past an exit (a stage beyond a located root) the formula stays smooth.
        let alpha = sa / (sa - sb);
        for (d, fb) in dxdt.iter_mut().zip(&b.fb) {
            *d += alpha * (fb - *d);
        }
    }

    fn num_guards(&self, _mode: S::Mode) -> usize {
        2 + self.sys.num_guards(self.from).saturating_sub(1)
    }

    fn guard(&self, _mode: S::Mode, index: usize, t: f64, x: &[f64]) -> f64 {
        match index {
            0 => self.sigma * self.one_speed(false, t, x),
            1 => -self.sigma * self.one_speed(true, t, x),
            k => self.sys.guard(self.from, self.inner_guard(k), t, x),
        }
    }

    fn guard_direction(&self, _mode: S::Mode, index: usize) -> Crossing {
        match index {
            0 | 1 => Crossing::Falling,
            k => self.sys.guard_direction(self.from, self.inner_guard(k)),
        }
    }
}

/// Normal speeds `dg/dt` of guard `index` of `mode` along `fa` (and `fb`) at `(t, x)`, and
/// the guard evaluations spent. Uses the system's gradient and time derivative where it
/// supplies them (exact for the surfaces of this workspace), central differences otherwise.
#[allow(clippy::too_many_arguments)] // reason: buffers are passed in so that nothing allocates
pub(crate) fn normal_speeds<S: HybridSystem + ?Sized>(
    sys: &S,
    mode: S::Mode,
    index: usize,
    t: f64,
    x: &[f64],
    fa: &[f64],
    fb: Option<&[f64]>,
    grad: &mut [f64],
    xs: &mut [f64],
) -> (f64, f64, u64) {
    let dt = FD_REL * t.abs().max(1.0);
    if sys.guard_gradient(mode, index, t, x, grad) {
        let (gt, evals) = match sys.guard_time_derivative(mode, index, t, x) {
            Some(v) => (v, 0),
            // Exactly zero for guards that do not read t.
            None => (
                (sys.guard(mode, index, t + dt, x) - sys.guard(mode, index, t - dt, x))
                    / (2.0 * dt),
                2,
            ),
        };
        let dot = |f: &[f64]| grad.iter().zip(f).map(|(g, v)| g * v).sum::<f64>() + gt;
        let a = dot(fa);
        let b = fb.map_or(f64::NAN, dot);
        return (a, b, evals);
    }
    let scale = x.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
    let mut along = |f: &[f64]| {
        let fmax = f.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        // Move the state by about FD_REL of its scale, and time by no more than FD_REL of its.
        let d = if fmax > 0.0 {
            (FD_REL * scale / fmax).min(dt)
        } else {
            dt
        };
        for ((s, xi), fi) in xs.iter_mut().zip(x).zip(f) {
            *s = xi + d * fi;
        }
        let gp = sys.guard(mode, index, t + d, xs);
        for ((s, xi), fi) in xs.iter_mut().zip(x).zip(f) {
            *s = xi - d * fi;
        }
        let gm = sys.guard(mode, index, t - d, xs);
        (gp - gm) / (2.0 * d)
    };
    let a = along(fa);
    let (b, evals) = match fb {
        Some(f) => (along(f), 4),
        None => (f64::NAN, 2),
    };
    (a, b, evals)
}

/// Moves `x` onto the zero set of guard `index` of `mode` along the guard's gradient (Newton
/// steps of `g(x - s grad) = 0`), where the system supplies the gradient. The crossing was
/// located within `event_tol`, so the state starts a distance of order `event_tol` times the
/// crossing speed off the surface; without the projection that offset would persist through
/// the whole sliding interval. Returns the guard evaluations spent.
pub(crate) fn project<S: HybridSystem + ?Sized>(
    sys: &S,
    mode: S::Mode,
    index: usize,
    t: f64,
    x: &mut [f64],
    grad: &mut [f64],
    xs: &mut [f64],
) -> u64 {
    let mut evals = 1;
    let mut g = sys.guard(mode, index, t, x);
    for _ in 0..3 {
        if g == 0.0 || !sys.guard_gradient(mode, index, t, x, grad) {
            break;
        }
        let norm2: f64 = grad.iter().map(|v| v * v).sum();
        if !(norm2 > 0.0 && norm2.is_finite()) {
            break;
        }
        for ((s, xi), gi) in xs.iter_mut().zip(x.iter()).zip(grad.iter()) {
            *s = xi - g * gi / norm2;
        }
        let g_new = sys.guard(mode, index, t, xs);
        evals += 1;
        // Keep a step only if it brings the state closer to the surface.
        if g_new.is_nan() || g_new.abs() >= g.abs() {
            break;
        }
        x.copy_from_slice(xs);
        g = g_new;
    }
    evals
}
