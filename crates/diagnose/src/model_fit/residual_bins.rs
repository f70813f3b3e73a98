//! Where in the state and in the forcing cycle a model's equations miss the data: the
//! residual of every second-order pair of states (a position `q` that an output reads, its
//! velocity `v` with `q' = v` in every mode), measured acceleration minus the model's `v'`,
//! binned against position, velocity and forcing phase on the held-out data.
//!
//! At each held-out sample the measured position (the output, a sensor's offset and gain
//! undone) gives the acceleration and the velocity by five-point central differences; the
//! model's `v'` is evaluated there, at the measured position and velocity, the model's other
//! states as its simulation from the fitted initial state has them, in the mode that admits
//! the measured state (the simulated one where it does), driven by the measured input as the
//! diagnosis drives it (through the fitted input offset, delay or lag). The difference is
//! smoothed by the kernel with which the Savitzky-Golay second derivative smooths a true
//! acceleration, so both sides see one smoothing, and binned by the Savitzky-Golay position
//! and velocity ([`BinnedResidual`]). A force the model lacks, over the mass, shows here as a
//! function of the state: a cubic spring against position, friction as a step against
//! velocity, a damper missing in one mode on one side of zero velocity.

use std::ops::Range;

use htfid_expr::Expr;
use htfid_hybrid::HybridSystem;
use htfid_lang::{Mode, Model};
use serde::Serialize;

use super::prepared::Prepared;
use crate::boundary::Boundary;
use crate::deriv::{
    acceleration_kernel, five_point, savitzky_golay, smoothed_at, window_half_width,
};
use crate::evidence::{quantile_range, BinnedResidual, ResidualSamples};
use crate::DiagnoseError;

/// Blocks of this many natural periods are the independent units of the standard errors of
/// a model without a forcing period (with one, a block is one forcing period).
const NATURAL_PERIODS_PER_BLOCK: f64 = 10.0;

/// The binned residual of one second-order pair, for the refitted and the final model.
#[derive(Debug, Clone, Serialize)]
pub struct PairResidual {
    /// The output read as the position.
    pub output: String,
    /// The position state `q`.
    pub position: String,
    /// The velocity state `v` (`q' = v`).
    pub velocity: String,
    /// Length of the blocks taken as independent in the standard errors (s): one forcing
    /// period, or ten natural periods of the refitted model without one.
    pub block_s: f64,
    /// The refitted model's residual.
    pub nominal: BinnedResidual,
    /// The final model's (with the chosen effects), sharing the refitted one's bins; `None`
    /// when no effect is chosen.
    pub extended: Option<BinnedResidual>,
}

/// A model as the diagnosis simulates it on the held-out data: its equations, its boundary
/// and its fitted initial state on the estimation record.
pub(super) struct Simulated<'m> {
    pub model: &'m Model,
    pub boundary: &'m Boundary,
    pub x0: &'m [f64],
}

/// A model's simulation on the held-out samples.
pub(super) struct Held {
    /// The model driven by the input through its boundary.
    pub driven: Model,
    /// The mode at each sample.
    pub modes: Vec<Mode>,
    /// The state at each sample.
    pub states: Vec<Vec<f64>>,
    /// Times of the transitions whose reset moves the state (impacts).
    pub jumps: Vec<f64>,
}

impl Held {
    /// Whether a smoothing window of `reach` (s) either side of `t` meets an impact.
    pub(super) fn near_impact(&self, t: f64, reach: f64) -> bool {
        let from = self.jumps.partition_point(|&j| j < t - reach);
        self.jumps.get(from).is_some_and(|&j| j <= t + reach)
    }
}

/// The second-order pairs `(output, q, v)` of `model` whose equation error the diagnosis bins
/// ([`PairResidual`]): an output that is exactly state `q`, whose derivative is state `v` in
/// every mode.
pub fn second_order_pairs(model: &Model) -> Vec<(usize, usize, usize)> {
    let states = model.states();
    crate::term::velocity_pairs(model)
        .into_iter()
        .filter_map(|(q, v)| {
            let o = model
                .outputs()
                .iter()
                .position(|o| o.expr == Expr::var(&states[q].name))?;
            Some((o, q, v))
        })
        .collect()
}

/// The binned residual of every second-order pair of `nominal`'s model, and of `extended`
/// with the same bins, on the held-out data: on `val` when there is a separate held-out
/// record (each model from its own fitted initial state there), else on `est` from sample
/// `cut` on. Empty when the model has no such pair.
pub(super) fn residual_bins(
    est: &Prepared<'_>,
    val: Option<&Prepared<'_>>,
    cut: usize,
    nominal: &Simulated<'_>,
    extended: Option<&Simulated<'_>>,
) -> Result<Vec<PairResidual>, DiagnoseError> {
    let found = second_order_pairs(nominal.model);
    if found.is_empty() {
        return Ok(Vec::new());
    }
    let period = nominal.model.period().filter(|p| *p > 0.0 && p.is_finite());
    // The held-out samples: a separate record's scored rows, or the estimation record's tail.
    let (on, rows) = match val {
        Some(v) => (v, v.rows.clone()),
        None => (est, cut..est.rec.len()),
    };
    let held_out = |s: &Simulated<'_>| -> Result<Held, DiagnoseError> {
        let x0 = match val {
            Some(v) => v.fit_state(s.model, &v.guess, s.boundary)?,
            None => s.x0.to_vec(),
        };
        on.states_on(s.model, &x0, s.boundary, rows.clone())
    };
    let nominal_states = held_out(nominal)?;
    // The final model's bins are left out, the refitted one's kept, when it fails to simulate.
    let extended_states = extended.and_then(|s| held_out(s).ok());
    let dt = on.dt;
    let mut out = Vec::new();
    for (o, q, v) in found {
        let y = &on.rec.outputs()[o][rows.clone()];
        let t = &on.rec.time()[rows.clone()];
        let omega = natural_rate(q, v, t, &nominal_states);
        // The smoother's pass band reaches twice that frequency.
        let half = window_half_width(resolved_frequency(omega, period, dt), dt);
        let block_s = match period {
            Some(p) => p,
            None if omega > 0.0 => NATURAL_PERIODS_PER_BLOCK * 2.0 * std::f64::consts::PI / omega,
            None => NATURAL_PERIODS_PER_BLOCK * (2 * half + 1) as f64 * dt,
        };
        let samples = |s: &Simulated<'_>, held: &Held| {
            let position = undo_sensor(s.boundary, o, y);
            pair_residual((q, v), t, &position, dt, held, half)
        };
        let nom = samples(nominal, &nominal_states);
        let (xr, vr) = (quantile_range(&nom.x), quantile_range(&nom.v));
        let bin = |r: &ResidualSamples| BinnedResidual::new(r, block_s, period, Some(xr), Some(vr));
        let ext = match (extended, &extended_states) {
            (Some(e), Some(states)) => Some(bin(&samples(e, states))),
            _ => None,
        };
        let states = nominal.model.states();
        out.push(PairResidual {
            output: nominal.model.outputs()[o].name.clone(),
            position: states[q].name.clone(),
            velocity: states[v].name.clone(),
            block_s,
            nominal: bin(&nom),
            extended: ext,
        });
    }
    Ok(out)
}

/// The frequency (Hz) to which the evidence of a pair whose natural rate is `omega` (rad/s)
/// is resolved: the natural frequency; without a restoring force, five times the forcing
/// frequency (short beside the flights between impacts), else a twentieth of the sampling rate.
pub(super) fn resolved_frequency(omega: f64, period: Option<f64>, dt: f64) -> f64 {
    if omega > 0.0 {
        omega / (2.0 * std::f64::consts::PI)
    } else {
        period.map_or(0.05 / dt, |p| 5.0 / p)
    }
}

/// The measured output `y` with output `o`'s sensor offset and gain undone (a sensor lag is
/// not: it shows as a residual).
fn undo_sensor(b: &Boundary, o: usize, y: &[f64]) -> Vec<f64> {
    match b.sensors.get(o) {
        Some(s) => y.iter().map(|&v| (v - s.b) / s.g).collect(),
        None => y.to_vec(),
    }
}

/// The pair's natural rate (rad/s) on the samples: the root of the RMS of `-d(v')/dq` over
/// the simulated states, 0 when the model has no restoring force there.
pub(super) fn natural_rate(q: usize, v: usize, t: &[f64], held: &Held) -> f64 {
    let (driven, modes, states) = (&held.driven, &held.modes, &held.states);
    let n = driven.states().len();
    let mut jac = vec![0.0; n * n];
    let stride = (states.len() / 2000).max(1);
    let (mut sum, mut count) = (0.0, 0usize);
    for i in (0..states.len()).step_by(stride) {
        if driven.jacobian(modes[i], t[i], &states[i], &mut jac) {
            sum += jac[v * n + q].powi(2);
            count += 1;
        }
    }
    if count == 0 {
        return 0.0;
    }
    (sum / count as f64).sqrt().sqrt()
}

/// The equation error of the pair `(q, v)` of the model of `held` at every sample whose smoothing window
/// lies inside the record and clear of the model's impacts (two samples beyond the window
/// either side): measured acceleration minus the model's `v'`, smoothed (see the module's
/// docs). `x` is the measured position at times `t`; `held` the model's simulation there.
fn pair_residual(
    (q, v): (usize, usize),
    t: &[f64],
    x: &[f64],
    dt: f64,
    held: &Held,
    half: usize,
) -> ResidualSamples {
    let (driven, modes, states) = (&held.driven, &held.modes, &held.states);
    let reach = (half + 4) as f64 * dt;
    let n = x.len();
    let mut d = vec![0.0; driven.states().len()];
    let error: Vec<f64> = (0..n)
        .map(|k| {
            if k < 2 || k + 2 >= n {
                return f64::NAN;
            }
            let (vel, acc) = five_point(x, k, dt);
            let mut s = states[k].clone();
            s[q] = x[k];
            s[v] = vel;
            let mode = driven.start_mode(modes[k], t[k], &s);
            driven.vector_field(mode, t[k], &s, &mut d);
            acc - d[v]
        })
        .collect();
    let kernel = acceleration_kernel(half, dt);
    let mut out = ResidualSamples::default();
    for (k, kin) in savitzky_golay(x, 0, n, dt, half, 4) {
        if k < half + 2 || k + half + 2 >= n || held.near_impact(t[k], reach) {
            continue;
        }
        let smoothed = smoothed_at(&kernel, &error, k);
        if !smoothed.is_finite() {
            continue;
        }
        out.t.push(t[k]);
        out.x.push(kin.x);
        out.v.push(kin.v);
        out.residual.push(smoothed);
    }
    out
}

impl Prepared<'_> {
    /// The modes and states of `model` (driven through boundary `b`) from `x0` at the
    /// record's start, at every sample of `rows`, and the times of its resets that move the
    /// state.
    pub(super) fn states_on(
        &self,
        model: &Model,
        x0: &[f64],
        b: &Boundary,
        rows: Range<usize>,
    ) -> Result<Held, DiagnoseError> {
        let driven = model.with_input(Some(b.input(&self.signal)));
        let times: Vec<f64> = rows.map(|i| self.rec.time()[i]).collect();
        let t0 = self.rec.time()[0];
        let end = *times.last().unwrap_or(&t0);
        let mode = driven.start_mode(self.mode0, t0, x0);
        let traj = htfid_hybrid::simulate(&driven, mode, t0, x0, end, &times, &self.sim_opts)
            .map_err(super::prepared::sim_failure)?;
        // The transitions whose reset moves the state: impacts, whose acceleration no
        // difference of samples resolves.
        let jumps = traj
            .events
            .iter()
            .filter(|e| e.kind == htfid_hybrid::EventKind::Transition)
            .filter(|e| {
                let mut after = e.state.clone();
                driven.transition(e.from, e.guard, e.time, &mut after);
                after
                    .iter()
                    .zip(&e.state)
                    .any(|(a, b)| (a - b).abs() > 1e-12 * (1.0 + b.abs()))
            })
            .map(|e| e.time)
            .collect();
        let states = (0..times.len()).map(|i| traj.state(i).to_vec()).collect();
        Ok(Held {
            driven,
            modes: traj.modes,
            states,
            jumps,
        })
    }
}
