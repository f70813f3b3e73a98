//! Where a candidate term's output-error fit starts: the least-squares estimate of its
//! parameters, and of the free parameters beside it, from the equation error on the
//! estimation record.
//!
//! An output-error fit of a term that starts at zero (the model as it was) walks a cost that,
//! on a long record of a lightly damped system, is far from convex: each change of the term
//! shifts the phase of thousands of cycles, and the refitted free parameters have taken up what
//! of the term they could. On Silverbox (about 7 300 fitted cycles of a 68 Hz resonance) the
//! fit of a cubic spring from zero stopped after one step, and the diagnosis named the wrong
//! effect. The equation error has no such memory: at each sample, the measured acceleration
//! less the model's `v'` at the measured position and velocity is linear in a term's
//! coefficients, so one least-squares solve estimates them. The estimate is biased by the
//! noise of the differentiated output and by the other states, taken from the simulation; it
//! is a start, and the output-error fit from the better of it and zero decides.

use htfid_hybrid::HybridSystem;
use htfid_lang::Model;
use nalgebra::{DMatrix, DVector};

use super::prepared::Prepared;
use super::residual_bins::{natural_rate, resolved_frequency, second_order_pairs};
use crate::boundary::Boundary;
use crate::deriv::SpectralLowPass;

/// Most samples of the estimation record the regression reads per pair (evenly spaced):
/// enough for a few coefficients, and the solve stays far below a simulation's cost.
const MAX_ROWS: usize = 20_000;

impl Prepared<'_> {
    /// `model`, or `model` with `free` and `added` at their equation-error estimate
    /// ([`Prepared::equation_error_start`]) when that has the lower output error from `x0`.
    pub(super) fn better_with_equation_error(
        &self,
        model: &Model,
        free: &[String],
        added: &[String],
        x0: &[f64],
    ) -> Model {
        let Some(estimate) = self.equation_error_start(model, free, added, x0) else {
            return model.clone();
        };
        let names: Vec<String> = free.iter().chain(added).cloned().collect();
        let current: Option<Vec<f64>> = names.iter().map(|n| model.parameter(n)).collect();
        match current {
            Some(current) => self.best_point(model, &names, &[current, estimate], x0),
            None => model.clone(),
        }
    }

    /// The start of an output-error fit of the parameters `added` beside `free` (parameters of
    /// `model`, fitted before without `added`), from the state `x0` at the record's start:
    /// their equation-error estimate, each clamped to its bounds.
    ///
    /// For every second-order pair the measured position is low-passed and differentiated
    /// exactly in the spectrum ([`SpectralLowPass`]), the model's `v'` is read at the measured
    /// position and velocity (the other states from the simulation) and low-passed alike, and
    /// the difference is regressed on `v'`'s exact derivatives by the parameters, low-passed
    /// alike: one Gauss-Newton step from their values in `model`, exact when the equations are
    /// linear in them, as every library term's coefficient is. The samples within the
    /// filter's ringing of the record's ends and of an impact are left out. A free parameter
    /// that does not enter the pairs' equations keeps its value. `None` when the model has no
    /// second-order pair, fails to simulate, or one of `added` does not enter the pairs'
    /// equations.
    fn equation_error_start(
        &self,
        model: &Model,
        free: &[String],
        added: &[String],
        x0: &[f64],
    ) -> Option<Vec<f64>> {
        let pairs = second_order_pairs(model);
        if pairs.is_empty() || added.is_empty() {
            return None;
        }
        let names: Vec<String> = free.iter().chain(added).cloned().collect();
        let refs: Vec<&str> = names.iter().map(String::as_str).collect();
        let sens = model.parameter_sensitivity(&refs).ok()?;
        let boundary = Boundary::default();
        let held = self
            .states_on(model, x0, &boundary, self.rows.clone())
            .ok()?;
        let input = boundary.input(&self.signal);
        let (n, k) = (model.states().len(), names.len());
        let period = model.period().filter(|p| *p > 0.0 && p.is_finite());
        let t = &self.rec.time()[self.rows.clone()];
        let len = t.len();
        let (mut rows, mut rhs) = (Vec::new(), Vec::new());
        let mut f = vec![0.0; n];
        let mut df = vec![0.0; n * k];
        for (o, q, v) in pairs {
            let x = &self.rec.outputs()[o][self.rows.clone()];
            // The band: up to twice the resolved frequency, at most 0.6 of Nyquist; the
            // velocity at which the model is read passes everything the band does.
            let f_n = resolved_frequency(natural_rate(q, v, t, &held), period, self.dt);
            let nyquist = 0.5 / self.dt;
            let pass = (2.0 * f_n).min(0.6 * nyquist);
            let band = SpectralLowPass {
                pass,
                stop: (1.5 * pass).min(0.8 * nyquist),
            };
            let wide = SpectralLowPass {
                pass: 0.8 * nyquist,
                stop: nyquist,
            };
            let acc = band.apply(x, self.dt, 2);
            let vel = wide.apply(x, self.dt, 1);
            // The model's v' and its derivatives by the parameters at every sample.
            let mut model_dv = vec![0.0; len];
            let mut columns = vec![vec![0.0; len]; k];
            for i in 0..len {
                let mut s = held.states[i].clone();
                s[q] = x[i];
                s[v] = vel[i];
                let mode = held.driven.start_mode(held.modes[i], t[i], &s);
                held.driven.vector_field(mode, t[i], &s, &mut f);
                sens.flow(mode, t[i], &s, input(t[i]), &mut df);
                model_dv[i] = f[v];
                for (j, column) in columns.iter_mut().enumerate() {
                    column[i] = df[v * k + j];
                }
            }
            let model_dv = band.apply(&model_dv, self.dt, 0);
            let columns: Vec<Vec<f64>> =
                columns.iter().map(|c| band.apply(c, self.dt, 0)).collect();
            let edge = band.edge(self.dt).max(wide.edge(self.dt));
            let reach = edge as f64 * self.dt;
            let (first, last) = (edge, len.saturating_sub(edge));
            if last <= first {
                continue;
            }
            let stride = ((last - first) / MAX_ROWS).max(1);
            // Each pair weighted by its acceleration's RMS, so outputs in other units or of
            // other sizes count alike.
            let rms = (acc[first..last].iter().map(|a| a * a).sum::<f64>() / (last - first) as f64)
                .sqrt();
            if !(rms > 0.0 && rms.is_finite()) {
                continue;
            }
            for i in (first..last).step_by(stride) {
                if held.near_impact(t[i], reach) {
                    continue;
                }
                let e = (acc[i] - model_dv[i]) / rms;
                let row: Vec<f64> = columns.iter().map(|c| c[i] / rms).collect();
                if e.is_finite() && row.iter().all(|c| c.is_finite()) {
                    rhs.push(e);
                    rows.extend(row);
                }
            }
        }
        let m = rhs.len();
        if m <= k {
            return None;
        }
        let a = DMatrix::from_row_slice(m, k, &rows);
        let rhs = DVector::from_vec(rhs);
        let solvable: Vec<usize> = (0..k)
            .filter(|&j| a.column(j).norm() > 0.0 || j >= free.len())
            .collect();
        let step = least_squares(&a.select_columns(&solvable), &rhs)?;
        names
            .iter()
            .enumerate()
            .map(|(j, name)| {
                let p = &model.parameters()[model.parameter_index(name)?];
                let moved = solvable
                    .iter()
                    .position(|&i| i == j)
                    .map_or(0.0, |i| step[i]);
                let value = model.parameter(name)? + moved;
                value.is_finite().then(|| value.clamp(p.min, p.max))
            })
            .collect()
    }
}

/// The least-squares solution of `a x = b`, each column scaled to unit norm so that
/// coefficients of different sizes solve alike; `None` when a column vanishes or is not finite.
fn least_squares(a: &DMatrix<f64>, b: &DVector<f64>) -> Option<DVector<f64>> {
    let k = a.ncols();
    let norms: Vec<f64> = (0..k).map(|j| a.column(j).norm()).collect();
    if norms.iter().any(|c| !(*c > 0.0 && c.is_finite())) {
        return None;
    }
    let scaled = DMatrix::from_fn(a.nrows(), k, |i, j| a[(i, j)] / norms[j]);
    let x = scaled.svd(true, true).solve(b, 1e-10).ok()?;
    Some(DVector::from_fn(k, |j, _| x[j] / norms[j]))
}
