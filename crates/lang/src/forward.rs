//! Forward sensitivities: the derivatives of a model's simulated outputs with respect to some
//! of its parameters and to its initial state, integrated beside the state with the same
//! integrator (one simulation instead of one per parameter, and exact to the integrator's
//! tolerance instead of a finite difference's truncation and noise).
//!
//! Between guards the sensitivity `S = dx/dtheta` (`n x m`, `theta` the parameters and then,
//! optionally, the initial state) follows `S' = A S + [df/dp, 0]` with `A = df/dx`, from
//! `S(t0) = [0, I]`. At a guard crossed at time `tau`, with `h` the guard, `R` the reset and
//! `f-`, `f+` the vector fields before and after, the crossing time moves by
//! `tau_theta = -(h_x S- + [h_p, 0]) / (h_x f- + h_t)`, and
//! `S+ = R_x (S- + f- tau_theta) + [R_p, 0] + (R_t - f+) tau_theta`, that is the saltation
//! matrix applied to `S-` (built by `htfid_orbit::transition_jump`) plus the parameter terms. Every derivative is symbolic (the model's own, and
//! [`Model::parameter_sensitivity`]). The outputs' derivatives are `dy/dtheta = C S +
//! [dy/dp, 0]`.
//!
//! A state that slides along a switching surface (Filippov) has sensitivities this does not
//! cover: [`output_sensitivities`] then fails with [`ForwardError::Sliding`], and a caller
//! falls back to differences.

use std::cell::RefCell;

use htfid_hybrid::{simulate, Crossing, HybridSystem, Options, Trajectory};
use htfid_orbit::{transition_jump, LimitCycle};
use nalgebra::{DMatrix, DVector};

use crate::model::{InputFn, Mode, Model, ParameterSensitivity};
use crate::ModelError;

/// Why forward sensitivities could not be computed.
#[derive(Debug, thiserror::Error)]
pub enum ForwardError {
    /// A name that is not one of the model's parameters.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The simulation failed.
    #[error("the simulation with sensitivities failed: {0}")]
    Simulation(String),
    /// The motion slid along a switching surface, where these sensitivities do not hold.
    #[error(
        "the motion slides along a switching surface from t = {0} s, where forward \
         sensitivities do not hold"
    )]
    Sliding(f64),
    /// The orbit has a Floquet multiplier of 1 (or one so close that `I - M` is singular):
    /// its periodic sensitivity is undefined.
    #[error(
        "the orbit's monodromy has a Floquet multiplier of 1: its sensitivity to the \
         parameters is undefined"
    )]
    UnitMultiplier,
}

/// A model's outputs on a grid and their derivatives with respect to parameters and,
/// optionally, the initial state.
#[derive(Debug, Clone)]
pub struct OutputSensitivities {
    /// `outputs[o][i]`: output `o` at grid time `i`.
    pub outputs: Vec<Vec<f64>>,
    /// `columns[j][o][i]`: the derivative of output `o` at grid time `i` by the `j`-th of the
    /// parameters, then (when asked for) by each initial state.
    pub columns: Vec<Vec<Vec<f64>>>,
}

/// The model and its state with the sensitivities appended, `n (1 + m)` entries:
/// `[x, S row by row]`.
pub(crate) struct Augmented<'a> {
    model: &'a Model,
    sens: ParameterSensitivity,
    /// The derivatives by the input, with the input's directions: a column `k + j` follows a
    /// change `directions[j](t)` of the input.
    input: Option<(ParameterSensitivity, &'a [InputFn])>,
    /// Parameters (`k`), their columns and the input's (`kq`), all columns (`m`).
    k: usize,
    kq: usize,
    m: usize,
    n: usize,
    scratch: RefCell<Scratch>,
}

#[derive(Default)]
struct Scratch {
    a: Vec<f64>,
    fp: Vec<f64>,
    one: Vec<f64>,
    /// `df/dp` before the input's columns are spread beside it.
    by_params: Vec<f64>,
    /// The input's directions at the stage's time.
    w: Vec<f64>,
}

impl<'a> Augmented<'a> {
    /// The model with the sensitivities to the parameters of `sens` beside its state (no input
    /// directions, no initial state's columns).
    pub(crate) fn for_parameters(model: &'a Model, sens: ParameterSensitivity) -> Self {
        let k = sens.parameters().len();
        Augmented {
            model,
            sens,
            input: None,
            k,
            kq: k,
            m: k,
            n: model.dim(),
            scratch: RefCell::new(Scratch::default()),
        }
    }
}

impl Augmented<'_> {
    fn u(&self, t: f64) -> f64 {
        self.model.input_value(t)
    }

    /// The input's directions at `t`, into `w` (emptied first; none without the input's
    /// columns).
    fn directions_into(&self, t: f64, w: &mut Vec<f64>) {
        w.clear();
        if let Some((_, directions)) = &self.input {
            w.extend(directions.iter().map(|d| d(t)));
        }
    }

    /// The parameter terms of every column `j < kq` into `out` (`rows x kq`, row-major): the
    /// parameters' `k` columns from `by_params` (`rows x k`), the input's from `by_input`
    /// (`rows x 1`) times each direction `w`.
    fn spread(&self, rows: usize, by_params: &[f64], by_input: &[f64], w: &[f64], out: &mut [f64]) {
        let (k, kq) = (self.k, self.kq);
        for i in 0..rows {
            for j in 0..k {
                out[i * kq + j] = by_params[i * k + j];
            }
            for (jj, wj) in w.iter().enumerate() {
                out[i * kq + k + jj] = by_input[i] * wj;
            }
        }
    }
}

impl HybridSystem for Augmented<'_> {
    type Mode = Mode;

    fn dim(&self) -> usize {
        self.n * (1 + self.m)
    }

    fn vector_field(&self, mode: Mode, t: f64, x: &[f64], dxdt: &mut [f64]) {
        let (n, k, kq, m) = (self.n, self.k, self.kq, self.m);
        let (state, s) = x.split_at(n);
        // The input is read once per stage: it is the measured signal read between its
        // samples (and lagged), which costs as much as the model's own field.
        let u = self.u(t);
        let mut scratch = self.scratch.borrow_mut();
        let Scratch {
            a,
            fp,
            one,
            by_params,
            w,
        } = &mut *scratch;
        a.resize(n * n, 0.0);
        fp.resize(n * kq.max(1), 0.0);
        self.model
            .field_and_jacobian(mode, t, state, u, &mut dxdt[..n], a);
        if let Some((input, _)) = &self.input {
            by_params.resize(n * k, 0.0);
            if k > 0 {
                self.sens.flow(mode, t, state, u, by_params);
            }
            one.resize(n, 0.0);
            input.flow(mode, t, state, u, one);
            self.directions_into(t, w);
            self.spread(n, by_params, one, w, fp);
        } else if k > 0 {
            self.sens.flow(mode, t, state, u, fp);
        }
        let ds = &mut dxdt[n..];
        for i in 0..n {
            for j in 0..m {
                let mut acc = if j < kq { fp[i * kq + j] } else { 0.0 };
                for l in 0..n {
                    acc += a[i * n + l] * s[l * m + j];
                }
                ds[i * m + j] = acc;
            }
        }
    }

    fn num_guards(&self, mode: Mode) -> usize {
        self.model.num_guards(mode)
    }

    fn guard(&self, mode: Mode, index: usize, t: f64, x: &[f64]) -> f64 {
        self.model.guard(mode, index, t, &x[..self.n])
    }

    fn guard_direction(&self, mode: Mode, index: usize) -> Crossing {
        self.model.guard_direction(mode, index)
    }

    fn sliding_chart(&self, mode: Mode, index: usize) -> Option<Mode> {
        self.model.sliding_chart(mode, index)
    }

    /// The state through the model's reset; the sensitivities through the saltation matrix
    /// (`htfid_orbit::transition_jump`) with the parameter terms:
    /// `S+ = DR S- + jump (h_x S- + h_p) / speed + R_p`.
    fn transition(&self, mode: Mode, index: usize, t: f64, x: &mut [f64]) -> Mode {
        self.cross(mode, index, t, x, &mut [])
    }
}

impl Augmented<'_> {
    /// [`HybridSystem::transition`] of the state with its sensitivities, and the rate at which
    /// the crossing's time moves along each of the first `dtau.len()` columns.
    pub(crate) fn cross(
        &self,
        mode: Mode,
        index: usize,
        t: f64,
        x: &mut [f64],
        dtau: &mut [f64],
    ) -> Mode {
        let (n, k, m) = (self.n, self.kq, self.m);
        let u = self.u(t);
        let before: Vec<f64> = x[..n].to_vec();
        let g = self.model.global_guard(mode, index);
        let jump = transition_jump(self.model, mode, index, t, &before);
        let (mut h_p, mut r_p) = (vec![0.0; k], vec![0.0; n * k]);
        let (mut h_params, mut r_params) = (vec![0.0; self.k], vec![0.0; n * self.k]);
        if self.k > 0 {
            self.sens.guard(g, t, &before, u, &mut h_params);
            self.sens.reset(g, t, &before, u, &mut r_params);
        }
        if let Some((input, _)) = &self.input {
            let (mut h_u, mut r_u) = (vec![0.0; 1], vec![0.0; n]);
            input.guard(g, t, &before, u, &mut h_u);
            input.reset(g, t, &before, u, &mut r_u);
            let mut w = Vec::new();
            self.directions_into(t, &mut w);
            self.spread(1, &h_params, &h_u, &w, &mut h_p);
            self.spread(n, &r_params, &r_u, &w, &mut r_p);
        } else {
            h_p.copy_from_slice(&h_params);
            r_p.copy_from_slice(&r_params);
        }
        x[..n].copy_from_slice(&jump.x_plus);
        let s = &mut x[n..];
        // A grazing crossing (zero speed) moves no crossing time: the sensitivities then pass
        // as the reset's Jacobian maps them.
        let moves = jump.speed != 0.0 && jump.speed.is_finite();
        let before_s = s.to_vec();
        for j in 0..m {
            let hs = (0..n)
                .map(|l| jump.guard_gradient[l] * before_s[l * m + j])
                .sum::<f64>()
                + if j < k { h_p[j] } else { 0.0 };
            let shift = if moves { hs / jump.speed } else { 0.0 };
            if let Some(rate) = dtau.get_mut(j) {
                *rate = -shift;
            }
            for i in 0..n {
                let mut acc = jump.jump[i] * shift;
                if j < k {
                    acc += r_p[i * k + j];
                }
                for l in 0..n {
                    acc += jump.reset_jacobian[(i, l)] * before_s[l * m + j];
                }
                s[i * m + j] = acc;
            }
        }
        jump.to
    }
}

/// Simulates `model` (driven by its own input) from `(mode0, x0)` at `t0` and returns its
/// outputs on `grid` with their exact derivatives by the parameters `params` and, when
/// `initial_state` holds, by each entry of `x0` (after the parameters' columns).
///
/// ```
/// use std::sync::Arc;
/// use htfid_hybrid::Options;
/// use htfid_lang::{output_sensitivities, Model};
///
/// let model = Model::parse(r#"
///     states = ["x", "v"]
///     parameters = { k = 4.0, c = 0.5 }
///     flow = { x = "v", v = "-k*x - c*v + u" }
///     outputs = { x = "x" }
///     initial = { x = 1.0, v = 0.0 }
/// "#)?
/// .with_input(Some(Arc::new(|t: f64| (2.0 * t).sin())));
/// let grid: Vec<f64> = (0..=100).map(|i| 0.05 * i as f64).collect();
/// let mode = model.initial_mode();
/// let s = output_sensitivities(&model, &["k"], true, mode, 0.0, &[1.0, 0.0], &grid,
///                              &Options::default())?;
/// // Columns: d x / d k, then d x / d x(0) and d x / d v(0); at t = 0 only d x / d x(0) is 1.
/// assert_eq!(s.columns.len(), 3);
/// assert_eq!(s.columns[1][0][0], 1.0);
/// assert_eq!(s.columns[0][0][0], 0.0);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`ForwardError`].
#[allow(clippy::too_many_arguments)] // reason: the model, what to differentiate and the grid
pub fn output_sensitivities(
    model: &Model,
    params: &[&str],
    initial_state: bool,
    mode0: Mode,
    t0: f64,
    x0: &[f64],
    grid: &[f64],
    opts: &Options,
) -> Result<OutputSensitivities, ForwardError> {
    output_sensitivities_with_input(model, params, &[], initial_state, mode0, t0, x0, grid, opts)
}

/// [`output_sensitivities`] with columns for changes of the input as well, after the
/// parameters' and before the initial state's: the column of `directions[j]` follows the
/// input changed by `directions[j](t)` (the derivative of the input by whatever moves it: 1
/// for an offset, `-u'(t - d)` for a delay `d`), through the model's exact derivatives by its
/// input (`Model::input_sensitivity`) in its flows, guards, resets and outputs.
///
/// # Errors
/// [`ForwardError`].
#[allow(clippy::too_many_arguments)] // reason: the model, what to differentiate and the grid
pub fn output_sensitivities_with_input(
    model: &Model,
    params: &[&str],
    directions: &[InputFn],
    initial_state: bool,
    mode0: Mode,
    t0: f64,
    x0: &[f64],
    grid: &[f64],
    opts: &Options,
) -> Result<OutputSensitivities, ForwardError> {
    let sens = model.parameter_sensitivity(params)?;
    let input = if directions.is_empty() {
        None
    } else {
        Some((model.input_sensitivity()?, directions))
    };
    let n = model.dim();
    let k = params.len();
    let kq = k + directions.len();
    let m = kq + if initial_state { n } else { 0 };
    let sys = Augmented {
        model,
        sens: sens.clone(),
        input: input.clone(),
        k,
        kq,
        m,
        n,
        scratch: RefCell::new(Scratch::default()),
    };
    let mut start = vec![0.0; n * (1 + m)];
    start[..n].copy_from_slice(x0);
    if initial_state {
        for i in 0..n {
            start[n + i * m + kq + i] = 1.0;
        }
    }
    let end = grid.last().copied().unwrap_or(t0);
    let traj = simulate(&sys, mode0, t0, &start, end, grid, opts)
        .map_err(|e| ForwardError::Simulation(e.to_string()))?;
    if let Some(slide) = traj.sliding.first() {
        return Err(ForwardError::Sliding(slide.start));
    }
    let p = model.outputs().len();
    let mut outputs = vec![vec![0.0; grid.len()]; p];
    let mut columns = vec![vec![vec![0.0; grid.len()]; p]; m];
    let mut y = vec![0.0; p];
    let mut c = vec![0.0; p * n];
    let mut yp = vec![0.0; p * kq];
    let mut y_params = vec![0.0; p * k];
    let mut y_u = vec![0.0; p];
    let mut w = Vec::with_capacity(directions.len());
    for (i, &t) in grid.iter().enumerate() {
        let u = model.input_value(t);
        let state = traj.state(i);
        let (x, s) = state.split_at(n);
        model.eval_outputs(traj.modes[i], t, x, u, &mut y);
        model.output_state_jacobian(t, x, u, &mut c);
        if k > 0 {
            sens.output(t, x, u, &mut y_params);
        }
        if let Some((input, _)) = &input {
            input.output(t, x, u, &mut y_u);
            sys.directions_into(t, &mut w);
            sys.spread(p, &y_params, &y_u, &w, &mut yp);
        } else {
            yp.copy_from_slice(&y_params);
        }
        for o in 0..p {
            outputs[o][i] = y[o];
            for (j, column) in columns.iter_mut().enumerate() {
                let mut acc = if j < kq { yp[o * kq + j] } else { 0.0 };
                for l in 0..n {
                    acc += c[o * n + l] * s[l * m + j];
                }
                column[o][i] = acc;
            }
        }
    }
    Ok(OutputSensitivities { outputs, columns })
}

/// The orbit's own periodic sensitivity to `params` at the start of `cycle` (a limit cycle of
/// `model`, its input off): `dx/dp` at `cycle.t0`, `n x k` row by row.
///
/// The sensitivity `z = dx/dp` of the periodic orbit (the period fixed by the forcing) is the
/// periodic solution of `z' = A z + df/dp` with the guards' jumps: one period from `z = 0`
/// gives the particular end `z_T`, and `(I - M) z(t0) = z_T` with `M = cycle.jacobian`, the
/// monodromy.
///
/// # Errors
/// [`ForwardError`]: an unknown name, a failed or sliding simulation, a unit multiplier.
pub(crate) fn periodic_start(
    model: &Model,
    params: &[&str],
    cycle: &LimitCycle<Mode>,
    opts: &Options,
) -> Result<Vec<f64>, ForwardError> {
    let (n, k) = (model.dim(), params.len());
    let particular = one_period(model, params, cycle, &vec![0.0; n * k], opts)?;
    let lu = (DMatrix::<f64>::identity(n, n) - &cycle.jacobian).lu();
    let mut start = vec![0.0; n * k];
    for j in 0..k {
        let column = DVector::from_fn(n, |l, _| particular.final_state[n + l * k + j]);
        let periodic = lu.solve(&column).ok_or(ForwardError::UnitMultiplier)?;
        for l in 0..n {
            start[l * k + j] = periodic[l];
        }
    }
    Ok(start)
}

/// One period of `cycle` with the orbit's periodic sensitivity to `params` beside it
/// ([`periodic_start`]): the state `[x, dx/dp row by row]` (`n (1 + k)` entries) along the
/// orbit, its events carrying the sensitivities just before each reset.
///
/// # Errors
/// As [`periodic_start`].
pub(crate) fn periodic_sensitivity(
    model: &Model,
    params: &[&str],
    cycle: &LimitCycle<Mode>,
    opts: &Options,
) -> Result<Trajectory<Mode>, ForwardError> {
    let start = periodic_start(model, params, cycle, opts)?;
    one_period(model, params, cycle, &start, opts)
}

/// One period of `cycle` from its start with the sensitivities `z0` (`n x k`) beside it.
fn one_period(
    model: &Model,
    params: &[&str],
    cycle: &LimitCycle<Mode>,
    z0: &[f64],
    opts: &Options,
) -> Result<Trajectory<Mode>, ForwardError> {
    let sys = Augmented::for_parameters(model, model.parameter_sensitivity(params)?);
    let mut start = cycle.state0.clone();
    start.extend_from_slice(z0);
    let end = cycle.t0 + cycle.period;
    let traj = simulate(&sys, cycle.mode0, cycle.t0, &start, end, &[], opts)
        .map_err(|e| ForwardError::Simulation(e.to_string()))?;
    match traj.sliding.first() {
        Some(slide) => Err(ForwardError::Sliding(slide.start)),
        None => Ok(traj),
    }
}
