//! Variational equations with saltation, and finite-difference fallbacks for the derivatives a
//! system does not supply.

use htfid_hybrid::{Crossing, HybridSystem};
use nalgebra::{DMatrix, DVector};

/// Relative finite-difference step for central differences: the cube root of machine epsilon
/// balances truncation (h^2) against rounding (eps/h) error.
const FD_REL: f64 = 6.0e-6;

fn fd_step(x: f64) -> f64 {
    FD_REL * x.abs().max(1.0)
}

/// `df/dx` of chart `mode` at `(t, x)`: the system's own Jacobian where it supplies one,
/// central finite differences otherwise.
pub fn vector_field_jacobian<S: HybridSystem>(
    sys: &S,
    mode: S::Mode,
    t: f64,
    x: &[f64],
) -> DMatrix<f64> {
    let n = sys.dim();
    let mut jac = vec![0.0; n * n];
    if sys.jacobian(mode, t, x, &mut jac) {
        return DMatrix::from_row_slice(n, n, &jac);
    }
    let mut xp = x.to_vec();
    let (mut fp, mut fm) = (vec![0.0; n], vec![0.0; n]);
    let mut out = DMatrix::zeros(n, n);
    for j in 0..n {
        let h = fd_step(x[j]);
        xp[j] = x[j] + h;
        sys.vector_field(mode, t, &xp, &mut fp);
        xp[j] = x[j] - h;
        sys.vector_field(mode, t, &xp, &mut fm);
        xp[j] = x[j];
        for i in 0..n {
            out[(i, j)] = (fp[i] - fm[i]) / (2.0 * h);
        }
    }
    out
}

/// Gradient of guard `index` of `mode` with respect to `x`, and its partial derivative with
/// respect to time at fixed `x`: the system's own [`HybridSystem::guard_gradient`] and
/// [`HybridSystem::guard_time_derivative`] where it supplies them, central finite differences
/// otherwise.
pub fn guard_gradient<S: HybridSystem>(
    sys: &S,
    mode: S::Mode,
    index: usize,
    t: f64,
    x: &[f64],
) -> (DVector<f64>, f64) {
    let n = sys.dim();
    let mut grad = vec![0.0; n];
    if !sys.guard_gradient(mode, index, t, x, &mut grad) {
        let mut xp = x.to_vec();
        for j in 0..n {
            let h = fd_step(x[j]);
            xp[j] = x[j] + h;
            let gp = sys.guard(mode, index, t, &xp);
            xp[j] = x[j] - h;
            let gm = sys.guard(mode, index, t, &xp);
            xp[j] = x[j];
            grad[j] = (gp - gm) / (2.0 * h);
        }
    }
    let dhdt = sys
        .guard_time_derivative(mode, index, t, x)
        .unwrap_or_else(|| {
            let ht = fd_step(t);
            (sys.guard(mode, index, t + ht, x) - sys.guard(mode, index, t - ht, x)) / (2.0 * ht)
        });
    (DVector::from_vec(grad), dhdt)
}

/// Jacobian of the reset map of guard `index` of `mode` at `(t, x)`.
pub fn reset_jacobian<S: HybridSystem>(
    sys: &S,
    mode: S::Mode,
    index: usize,
    t: f64,
    x: &[f64],
) -> DMatrix<f64> {
    let n = sys.dim();
    let mut jac = vec![0.0; n * n];
    if sys.reset_jacobian(mode, index, t, x, &mut jac) {
        return DMatrix::from_row_slice(n, n, &jac);
    }
    let mut out = DMatrix::zeros(n, n);
    let (mut xp, mut xm) = (x.to_vec(), x.to_vec());
    for j in 0..n {
        let h = fd_step(x[j]);
        xp.copy_from_slice(x);
        xm.copy_from_slice(x);
        xp[j] += h;
        xm[j] -= h;
        sys.transition(mode, index, t, &mut xp);
        sys.transition(mode, index, t, &mut xm);
        for i in 0..n {
            out[(i, j)] = (xp[i] - xm[i]) / (2.0 * h);
        }
    }
    out
}

/// `dR/dt` at fixed `x`: the system's own where it supplies it, else central differences
/// (exactly zero when the reset ignores `t`).
fn reset_time_derivative<S: HybridSystem>(
    sys: &S,
    mode: S::Mode,
    index: usize,
    t: f64,
    x: &[f64],
) -> DVector<f64> {
    let mut exact = vec![0.0; x.len()];
    if sys.reset_time_derivative(mode, index, t, x, &mut exact) {
        return DVector::from_vec(exact);
    }
    let h = fd_step(t);
    let (mut xp, mut xm) = (x.to_vec(), x.to_vec());
    sys.transition(mode, index, t + h, &mut xp);
    sys.transition(mode, index, t - h, &mut xm);
    DVector::from_iterator(
        x.len(),
        xp.iter().zip(&xm).map(|(p, m)| (p - m) / (2.0 * h)),
    )
}

/// What a transition through guard `index` from chart `from` at time `t` (pre-event state
/// `x_minus`) does to nearby motions: the post-event state and chart, the reset's Jacobian
/// `DR`, the jump `f_to(x+) - DR f_from(x-) - dR/dt` of the field, the guard's gradient and the
/// crossing speed `grad(h) . f_from(x-) + dh/dt`. [`saltation`] is built from them; a
/// sensitivity to a parameter that moves the guard adds `jump dh/dp / speed` to it.
#[derive(Debug, Clone)]
pub struct TransitionJump<M> {
    /// The state after the reset.
    pub x_plus: Vec<f64>,
    /// The chart after the transition.
    pub to: M,
    /// `DR`, the reset's Jacobian at `x_minus`.
    pub reset_jacobian: DMatrix<f64>,
    /// `f_to(x+) - DR f_from(x-) - dR/dt`.
    pub jump: DVector<f64>,
    /// `grad(h)` at `x_minus`.
    pub guard_gradient: DVector<f64>,
    /// `grad(h) . f_from(x-) + dh/dt`; zero for a grazing trajectory.
    pub speed: f64,
}

/// The pieces of the transition through guard `index` from chart `from` at time `t`, pre-event
/// state `x_minus` ([`TransitionJump`]). `dR/dt` is the partial derivative of the reset with
/// respect to time at fixed `x` (a reset that involves a moving surface's velocity, as for a
/// ball hitting a vibrating table): the system's own, else central differences in `t`, which
/// give exactly zero for resets that do not read `t`.
pub fn transition_jump<S: HybridSystem>(
    sys: &S,
    from: S::Mode,
    index: usize,
    t: f64,
    x_minus: &[f64],
) -> TransitionJump<S::Mode> {
    let n = sys.dim();
    let mut x_plus = x_minus.to_vec();
    let to = sys.transition(from, index, t, &mut x_plus);
    let dr = reset_jacobian(sys, from, index, t, x_minus);
    let mut f_minus = vec![0.0; n];
    let mut f_plus = vec![0.0; n];
    sys.vector_field(from, t, x_minus, &mut f_minus);
    sys.vector_field(to, t, &x_plus, &mut f_plus);
    let f_minus = DVector::from_vec(f_minus);
    let f_plus = DVector::from_vec(f_plus);
    let (grad, dhdt) = guard_gradient(sys, from, index, t, x_minus);
    let speed = grad.dot(&f_minus) + dhdt;
    let jump = &f_plus - &dr * &f_minus - reset_time_derivative(sys, from, index, t, x_minus);
    TransitionJump {
        x_plus,
        to,
        reset_jacobian: dr,
        jump,
        guard_gradient: grad,
        speed,
    }
}

/// The saltation matrix of the transition through guard `index` from chart `from` at time `t`,
/// pre-event state `x_minus`. Returns the matrix and the post-event chart.
///
/// `S = DR + (f_to(x+) - DR f_from(x-) - dR/dt) grad(h)^T / (grad(h) . f_from(x-) + dh/dt)`,
/// from [`transition_jump`]. A transversality failure (denominator zero: a grazing trajectory)
/// gives non-finite entries; callers see them through the `NonFiniteState` check of the
/// integrator.
pub fn saltation<S: HybridSystem>(
    sys: &S,
    from: S::Mode,
    index: usize,
    t: f64,
    x_minus: &[f64],
) -> (DMatrix<f64>, S::Mode) {
    let j = transition_jump(sys, from, index, t, x_minus);
    let s = &j.reset_jacobian + (&j.jump * j.guard_gradient.transpose()) / j.speed;
    (s, j.to)
}

/// A hybrid system augmented with its variational equations: the state is `[x, Phi]` with
/// `Phi` the `n x n` sensitivity `dx(t)/dx(t0)` stored row-major. At each transition `Phi` is
/// multiplied by the saltation matrix, so after integrating over a time span `Phi` is the
/// Jacobian of the flow map, jumps included.
#[derive(Debug)]
pub struct Variational<'a, S> {
    inner: &'a S,
}

impl<'a, S: HybridSystem> Variational<'a, S> {
    /// Wraps `inner`.
    pub fn new(inner: &'a S) -> Self {
        Variational { inner }
    }

    /// The initial augmented state `[x0, I]`.
    pub fn initial_state(&self, x0: &[f64]) -> Vec<f64> {
        let n = self.inner.dim();
        let mut z = vec![0.0; n + n * n];
        z[..n].copy_from_slice(x0);
        for i in 0..n {
            z[n + i * n + i] = 1.0;
        }
        z
    }
}

impl<S: HybridSystem> HybridSystem for Variational<'_, S> {
    type Mode = S::Mode;

    fn dim(&self) -> usize {
        let n = self.inner.dim();
        n + n * n
    }

    fn vector_field(&self, mode: S::Mode, t: f64, z: &[f64], dz: &mut [f64]) {
        let n = self.inner.dim();
        let (x, phi) = z.split_at(n);
        let (dx, dphi) = dz.split_at_mut(n);
        self.inner.vector_field(mode, t, x, dx);
        let a = vector_field_jacobian(self.inner, mode, t, x);
        for i in 0..n {
            for j in 0..n {
                let mut acc = 0.0;
                for l in 0..n {
                    acc += a[(i, l)] * phi[l * n + j];
                }
                dphi[i * n + j] = acc;
            }
        }
    }

    fn num_guards(&self, mode: S::Mode) -> usize {
        self.inner.num_guards(mode)
    }

    fn guard(&self, mode: S::Mode, index: usize, t: f64, z: &[f64]) -> f64 {
        self.inner.guard(mode, index, t, &z[..self.inner.dim()])
    }

    fn guard_direction(&self, mode: S::Mode, index: usize) -> Crossing {
        self.inner.guard_direction(mode, index)
    }

    /// Forwarded, so that the state part slides exactly as the system alone does. The
    /// sensitivity part is then not the flow's Jacobian (the saltation at the start and end of
    /// sliding and the derivative of the Filippov coefficient are not applied):
    /// [`period_map`](crate::period_map) replaces it by differences of the period map.
    fn sliding_chart(&self, mode: S::Mode, index: usize) -> Option<S::Mode> {
        self.inner.sliding_chart(mode, index)
    }

    fn guard_gradient(
        &self,
        mode: S::Mode,
        index: usize,
        t: f64,
        z: &[f64],
        grad: &mut [f64],
    ) -> bool {
        let n = self.inner.dim();
        if !self
            .inner
            .guard_gradient(mode, index, t, &z[..n], &mut grad[..n])
        {
            return false;
        }
        grad[n..].iter_mut().for_each(|v| *v = 0.0);
        true
    }

    fn guard_time_derivative(&self, mode: S::Mode, index: usize, t: f64, z: &[f64]) -> Option<f64> {
        self.inner
            .guard_time_derivative(mode, index, t, &z[..self.inner.dim()])
    }

    fn transition(&self, mode: S::Mode, index: usize, t: f64, z: &mut [f64]) -> S::Mode {
        let n = self.inner.dim();
        let (s, to) = saltation(self.inner, mode, index, t, &z[..n]);
        let phi = DMatrix::from_row_slice(n, n, &z[n..]);
        let phi_plus = s * phi;
        let (x, phi_out) = z.split_at_mut(n);
        let to_check = self.inner.transition(mode, index, t, x);
        debug_assert_eq!(to_check, to, "transition must be deterministic");
        for i in 0..n {
            for j in 0..n {
                phi_out[i * n + j] = phi_plus[(i, j)];
            }
        }
        to
    }
}
