//! One record prepared for the output-error fits of a diagnosis: its input as a
//! function of time, the samples scored, the output scales, the model's starting point, and the
//! simulations and fits of the initial state on it.

use std::sync::Arc;

use htfid_estimate::{levenberg_marquardt_with_jacobian, LmOptions};
use htfid_hybrid::{simulate, HybridSystem, Options};
use htfid_lang::{output_sensitivities_with_input, ForwardError, InputFn, Model, Site};
use htfid_orbit::ShootingOptions;

use super::ModelFitOptions;
use crate::boundary::{Boundary, BoundaryEffect};
use crate::interp::{Interpolation, SampledSignal};
use crate::noise::{input_noise_level, with_white_noise};
use crate::sensor::Sensor;
use crate::term::{StateStats, TermEffect};
use crate::{DiagnoseError, TimeSeries};

pub(super) fn sim_failure(reason: impl ToString) -> DiagnoseError {
    DiagnoseError::Simulation {
        time: f64::NAN,
        reason: reason.to_string(),
    }
}

/// The state at the record's start: on the model's limit cycle (input off) at phase
/// `t0 mod T` when it has a forcing period, else its `[initial]` state.
fn start_state(
    model: &Model,
    t0: f64,
    opts: &Options,
) -> Result<(htfid_lang::Mode, Vec<f64>), DiagnoseError> {
    match model.period() {
        Some(period) => {
            let shooting = ShootingOptions::default();
            let cycle =
                model
                    .limit_cycle(&shooting, opts)
                    .map_err(|e| DiagnoseError::StartState {
                        rtol: opts.rtol,
                        reason: e.to_string(),
                    })?;
            let traj = simulate(
                model,
                cycle.mode0,
                0.0,
                &cycle.state0,
                t0.rem_euclid(period),
                &[],
                opts,
            )
            .map_err(sim_failure)?;
            Ok((traj.final_mode, traj.final_state))
        }
        None => Ok((model.initial_mode(), model.initial_state().to_vec())),
    }
}

/// Spans of the configured simulation's range of a state by which a fitted initial state may
/// lie outside it ([`state_box`]).
const STATE_BOX_SPANS: f64 = 10.0;

/// Bounds of a fitted initial state: the range each state covers when the configured model is
/// simulated from its start `guess` over the record (`samples`), widened by
/// [`STATE_BOX_SPANS`] times that range on each side. Where a start's influence dies out before
/// the scored samples, the output barely depends on it and an unbounded fit can wander to
/// absurd values (a position of -2.5e5 m on a record of millimetres), whose simulation is stiff
/// or fails; the bound keeps such a start among the states the system visits. A state that does
/// not move in that simulation stays unbounded.
pub(super) fn state_box(guess: &[f64], samples: &[Vec<f64>]) -> Vec<(f64, f64)> {
    guess
        .iter()
        .enumerate()
        .map(|(i, &g)| {
            let (lo, hi) = samples
                .iter()
                .filter_map(|x| x.get(i).copied())
                .filter(|v| v.is_finite())
                .fold((g, g), |(lo, hi), v| (lo.min(v), hi.max(v)));
            let pad = STATE_BOX_SPANS * (hi - lo);
            if pad > 0.0 && pad.is_finite() {
                (lo - pad, hi + pad)
            } else {
                (f64::NEG_INFINITY, f64::INFINITY)
            }
        })
        .collect()
}

/// Share of the scored samples on which the initial state is fitted first
/// ([`Prepared::fit_state`]).
const FIRST_HORIZON: f64 = 1.0 / 64.0;

/// Fewest samples of the first horizon of the initial state's fit.
const MIN_HORIZON_SAMPLES: usize = 50;

/// Simulates `model` driven by the record's input from `(mode, x0)` at the record's first
/// time, in the record's own (absolute) times, over its first `upto` samples.
fn simulate_outputs(
    model: &Model,
    rec: &TimeSeries,
    input: &InputFn,
    (mode, x0): (htfid_lang::Mode, &[f64]),
    opts: &Options,
    upto: usize,
) -> Result<Vec<Vec<f64>>, DiagnoseError> {
    let t0 = rec.time()[0];
    let times = &rec.time()[..upto.clamp(1, rec.len())];
    let driven = model.with_input(Some(input.clone()));
    let end = *times.last().unwrap_or(&t0);
    // A fitted start can lie across a switching surface from the guess's mode.
    let mode = driven.start_mode(mode, t0, x0);
    let traj = simulate(&driven, mode, t0, x0, end, times, opts).map_err(|e| {
        DiagnoseError::Simulation {
            time: end,
            reason: e.to_string(),
        }
    })?;
    let p = model.outputs().len();
    let mut out = vec![vec![0.0; times.len()]; p];
    let mut y = vec![0.0; p];
    for (i, &t) in times.iter().enumerate() {
        // Outputs that read the input see the applied one.
        let u = input(t);
        driven.eval_outputs(traj.modes[i], t, traj.state(i), u, &mut y);
        for (column, v) in out.iter_mut().zip(&y) {
            column[i] = *v;
        }
    }
    Ok(out)
}

/// A fit's residual function: the scaled residuals at a point, or why they failed.
type Residual<'a> = dyn Fn(&[f64], &mut [f64]) -> Result<(), String> + 'a;

/// Central differences (one-sided against a bound) of `residuals` at `p`, where they are
/// `r`, for the columns `cols` of `jac` (column-major, `r.len()` rows): for the parameters no
/// forward sensitivity covers (a boundary effect's lag, delay or sensor), and for every
/// parameter when the motion slides along a switching surface (or the simulation with
/// sensitivities fails). The step of parameter `j` is
/// `step * max(|p_j|, typical_j)`.
pub(super) fn difference_columns(
    residuals: &Residual<'_>,
    p: &[f64],
    r: &[f64],
    cols: &[usize],
    (step, typical, bounds): (f64, &[f64], &[(f64, f64)]),
    jac: &mut [f64],
) -> Result<(), String> {
    let m = r.len();
    let (mut up, mut down) = (vec![0.0; m], vec![0.0; m]);
    for &j in cols {
        let h = step * p[j].abs().max(typical[j]);
        let (lo, hi) = bounds[j];
        let mut q = p.to_vec();
        let plus = p[j] + h <= hi && {
            q[j] = p[j] + h;
            residuals(&q, &mut up).is_ok()
        };
        let minus = p[j] - h >= lo && {
            q[j] = p[j] - h;
            residuals(&q, &mut down).is_ok()
        };
        let col = &mut jac[j * m..(j + 1) * m];
        match (plus, minus) {
            (true, true) => {
                for i in 0..m {
                    col[i] = (up[i] - down[i]) / (2.0 * h);
                }
            }
            (true, false) => {
                for i in 0..m {
                    col[i] = (up[i] - r[i]) / h;
                }
            }
            (false, true) => {
                for i in 0..m {
                    col[i] = (r[i] - down[i]) / h;
                }
            }
            (false, false) => {
                return Err(format!(
                    "parameter {j} at {}: the simulation failed on both sides",
                    p[j]
                ))
            }
        }
    }
    Ok(())
}

/// One record prepared for output-error fits: its input as a function of time, the samples
/// scored, the output scales, and the model's starting point.
pub(super) struct Prepared<'a> {
    pub(super) rec: &'a TimeSeries,
    pub(super) signal: Arc<SampledSignal>,
    pub(super) dt: f64,
    pub(super) rows: std::ops::Range<usize>,
    pub(super) scale: Vec<f64>,
    pub(super) mode0: htfid_lang::Mode,
    pub(super) guess: Vec<f64>,
    pub(super) sim_opts: Options,
    /// Bounds of every fitted initial state ([`state_box`]).
    pub(super) state_box: Vec<(f64, f64)>,
}

impl<'a> Prepared<'a> {
    pub(super) fn new(
        model: &Model,
        rec: &'a TimeSeries,
        rows_end: usize,
        opts: &ModelFitOptions,
    ) -> Result<Self, DiagnoseError> {
        let n = rec.len();
        crate::record::check_length(n)?;
        if rec.outputs().len() != model.outputs().len() {
            return Err(DiagnoseError::InvalidOption {
                name: "outputs",
                expected: "one measured column per model output",
                value: rec.outputs().len() as f64,
            });
        }
        let dt = rec.dt();
        let skip = ((opts.burn_in / dt).ceil() as usize).min(n / 4);
        let rows = skip..rows_end.min(n);
        for (o, y) in rec.outputs().iter().enumerate() {
            let name = model.outputs()[o].name.as_str();
            crate::record::check_varies(y, std::slice::from_ref(&rows), &format!("scored {name}"))?;
        }
        let scale: Vec<f64> = rec
            .outputs()
            .iter()
            .map(|y| {
                let part = &y[rows.clone()];
                let m = part.iter().sum::<f64>() / part.len() as f64;
                let v = part.iter().map(|v| (v - m).powi(2)).sum::<f64>() / part.len() as f64;
                v.sqrt().max(f64::MIN_POSITIVE)
            })
            .collect();
        let signal = Arc::new(SampledSignal::new(
            rec.time()[0],
            dt,
            rec.input(),
            Interpolation::CubicSpline,
        ));
        let sim_opts = opts.integrator();
        let (mode0, guess) = start_state(model, rec.time()[0], &sim_opts)?;
        let mut prepared = Prepared {
            rec,
            signal,
            dt,
            rows,
            scale,
            state_box: vec![(f64::NEG_INFINITY, f64::INFINITY); guess.len()],
            mode0,
            guess,
            sim_opts,
        };
        if let Ok(samples) = prepared.state_samples(model, &prepared.guess) {
            prepared.state_box = state_box(&prepared.guess, &samples.x);
        }
        Ok(prepared)
    }

    /// The states of `model` from `x0` at (at most about 2000 of) the scored samples, with
    /// their modes, times and inputs.
    pub(super) fn state_samples(
        &self,
        model: &Model,
        x0: &[f64],
    ) -> Result<StateSamples, DiagnoseError> {
        let input = Boundary::default().input(&self.signal);
        let driven = model.with_input(Some(input.clone()));
        let stride = (self.rows.len() / 2000).max(1);
        let times: Vec<f64> = self
            .rows
            .clone()
            .step_by(stride)
            .map(|i| self.rec.time()[i])
            .collect();
        let (t0, end) = (
            self.rec.time()[0],
            *times.last().unwrap_or(&self.rec.time()[0]),
        );
        let mode = driven.start_mode(self.mode0, t0, x0);
        let traj =
            simulate(&driven, mode, t0, x0, end, &times, &self.sim_opts).map_err(sim_failure)?;
        Ok(StateSamples {
            modes: traj.modes.clone(),
            x: (0..times.len()).map(|i| traj.state(i).to_vec()).collect(),
            u: times.iter().map(|&t| input(t)).collect(),
            t: times,
        })
    }

    /// `model` with its parameter `name` at the best of 0 and +-0.03, 0.1, 0.3, 1 and 3 times
    /// `scale`, by the output error from `x0` (a moved switching surface: the cost is not
    /// convex in the shift, and the neutral start may sit in the wrong valley).
    ///
    /// With `surface` (the parameter moves a switching surface), 0 is never the start: where
    /// the field is continuous across the unmoved surface (a damper switching at zero
    /// velocity), the output's derivative by the shift vanishes there, so a fit with exact
    /// derivatives could not leave it; the better of the two smallest steps is taken instead,
    /// from which a fit returns to 0 if that is the optimum.
    pub(super) fn best_shift(
        &self,
        model: &Model,
        name: &str,
        scale: f64,
        x0: &[f64],
        surface: bool,
    ) -> Model {
        let steps: &[f64] = if surface {
            &[0.03, -0.03, 0.1, -0.1, 0.3, -0.3, 1.0, -1.0, 3.0, -3.0]
        } else {
            &[0.0, 0.03, -0.03, 0.1, -0.1, 0.3, -0.3, 1.0, -1.0, 3.0, -3.0]
        };
        let points: Vec<Vec<f64>> = steps.iter().map(|&step| vec![step * scale]).collect();
        self.best_point(model, &[name.to_string()], &points, x0)
    }

    /// `model` with its parameters `names` at the best of `points` (each a value per name), by
    /// the output error from `x0`; `model` itself when none simulates.
    pub(super) fn best_point(
        &self,
        model: &Model,
        names: &[String],
        points: &[Vec<f64>],
        x0: &[f64],
    ) -> Model {
        let mut r = vec![0.0; self.residual_len()];
        let mut best = (f64::INFINITY, model.clone());
        for point in points {
            let values: Vec<(&str, f64)> = names
                .iter()
                .map(String::as_str)
                .zip(point.iter().copied())
                .collect();
            let Ok(m) = model.with_parameters(&values) else {
                continue;
            };
            if let Ok(sim) = self.simulate(&m, x0, &Boundary::default()) {
                self.fill(&sim, &mut r);
                let cost: f64 = r.iter().map(|v| v * v).sum();
                if cost < best.0 {
                    best = (cost, m);
                }
            }
        }
        best.1
    }

    /// The relative step of the fits' central differences. A simulation at relative tolerance
    /// `rtol` moves by about `rtol` when a parameter's change makes the integrator choose other
    /// steps, so differences must be taken with that noise, not rounding, in mind: the step
    /// that balances it against the central difference's `O(h^2)` error is `rtol^(1/3)`
    /// (2e-3 at the default 1e-8), where machine precision would give 6e-6 and derivatives
    /// with errors of tens of percent.
    pub(super) fn fd_step(&self) -> f64 {
        self.sim_opts.rtol.cbrt()
    }

    pub(super) fn residual_len(&self) -> usize {
        self.rec.outputs().len() * self.rows.len()
    }

    /// The recorded outputs `model` gives from `x0` with the boundary `b`.
    pub(super) fn simulate(
        &self,
        model: &Model,
        x0: &[f64],
        b: &Boundary,
    ) -> Result<Vec<Vec<f64>>, DiagnoseError> {
        self.simulate_upto(model, x0, b, self.rec.len())
    }

    /// [`Prepared::simulate`] over the first `upto` samples only.
    pub(super) fn simulate_upto(
        &self,
        model: &Model,
        x0: &[f64],
        b: &Boundary,
        upto: usize,
    ) -> Result<Vec<Vec<f64>>, DiagnoseError> {
        let input = b.input(&self.signal);
        let mut y = simulate_outputs(
            model,
            self.rec,
            &input,
            (self.mode0, x0),
            &self.sim_opts,
            upto,
        )?;
        b.outputs(self.dt, &mut y);
        Ok(y)
    }

    pub(super) fn fill(&self, sim: &[Vec<f64>], r: &mut [f64]) {
        self.fill_rows(sim, r, self.rows.clone());
    }

    /// Scaled residuals on `rows`, output by output.
    pub(super) fn fill_rows(&self, sim: &[Vec<f64>], r: &mut [f64], rows: std::ops::Range<usize>) {
        let len = rows.len();
        for o in 0..self.rec.outputs().len() {
            for (j, i) in rows.clone().enumerate() {
                r[o * len + j] = (sim[o][i] - self.rec.outputs()[o][i]) / self.scale[o];
            }
        }
    }

    /// The exact derivatives of the scaled residuals on `rows` by the parameters `names` of
    /// `model` and by the initial state `x0`, from forward sensitivities
    /// ([`output_sensitivities`]) simulated over the first `upto` samples with the boundary
    /// `b` (its sensors are linear in the outputs up to their offsets, so they map the
    /// derivatives by their linear part). The input's `directions` add columns for changes of
    /// the input (`Boundary::input_direction`). Column `i` of the result (`names` first, then
    /// the directions, then the states) goes to column `at[i]` of `jac` (column-major, one
    /// column per fitted value).
    /// Returns the model's outputs before the sensors, for the sensors' own columns
    /// ([`Prepared::sensor_columns`]).
    #[allow(clippy::too_many_arguments)] // reason: the model, the point, the rows and the target
    pub(super) fn sensitivities(
        &self,
        model: &Model,
        (names, directions): (&[&str], &[InputFn]),
        x0: &[f64],
        b: &Boundary,
        upto: usize,
        rows: std::ops::Range<usize>,
        at: &[usize],
        jac: &mut [f64],
    ) -> Result<Vec<Vec<f64>>, ForwardError> {
        let driven = model.with_input(Some(b.input(&self.signal)));
        let t0 = self.rec.time()[0];
        let times = &self.rec.time()[..upto.clamp(1, self.rec.len())];
        let mode = driven.start_mode(self.mode0, t0, x0);
        let sens = output_sensitivities_with_input(
            &driven,
            names,
            directions,
            true,
            mode,
            t0,
            x0,
            times,
            &self.sim_opts,
        )?;
        let len = rows.len();
        let m = self.rec.outputs().len() * len;
        for (mut column, &j) in sens.columns.into_iter().zip(at) {
            for (o, sensor) in b.sensors.iter().enumerate() {
                let linear = Sensor { b: 0.0, ..*sensor };
                linear.apply(self.dt, &mut column[o]);
            }
            let target = &mut jac[j * m..(j + 1) * m];
            for (o, y) in column.iter().enumerate() {
                for (k, i) in rows.clone().enumerate() {
                    target[o * len + k] = y[i] / self.scale[o];
                }
            }
        }
        Ok(sens.outputs)
    }

    /// The exact columns of the output-side boundary effects among `effects` (their
    /// parameters from column `first` of `jac` on, in [`Boundary::with_all`]'s order), from
    /// the model's outputs `raw` before the sensors of `b`: a reading is `b + g L(y)`, `L` the
    /// sensor's low-pass, so `d/db = 1`, `d/dg = L(y)` and `d/dtau_s = g dL/dtau_s (y)`
    /// ([`Sensor::tau_derivative`]). Returns the columns it did not fill: the input side's
    /// (an offset, delay or lag of the input), whose columns the sensitivities carry
    /// ([`Prepared::sensitivities`] with their directions).
    pub(super) fn sensor_columns(
        &self,
        raw: &[Vec<f64>],
        (effects, b, first): (&[BoundaryEffect], &Boundary, usize),
        rows: std::ops::Range<usize>,
        jac: &mut [f64],
    ) -> Vec<usize> {
        let outputs = self.rec.outputs().len();
        let len = rows.len();
        let m = outputs * len;
        let mut left = Vec::new();
        let mut at = first;
        for &effect in effects {
            let n = effect.parameter_count(outputs);
            match effect {
                BoundaryEffect::SensorOffsetGain => {
                    for o in 0..outputs {
                        let mut lagged = raw[o].clone();
                        Sensor {
                            b: 0.0,
                            g: 1.0,
                            ..b.sensors[o]
                        }
                        .apply(self.dt, &mut lagged);
                        let (offset, gain) = (at + 2 * o, at + 2 * o + 1);
                        jac[offset * m..(offset + 1) * m].fill(0.0);
                        jac[gain * m..(gain + 1) * m].fill(0.0);
                        for (k, i) in rows.clone().enumerate() {
                            jac[offset * m + o * len + k] = 1.0 / self.scale[o];
                            jac[gain * m + o * len + k] = lagged[i] / self.scale[o];
                        }
                    }
                }
                BoundaryEffect::SensorLag => {
                    let column = &mut jac[at * m..(at + 1) * m];
                    for o in 0..outputs {
                        let d = b.sensors[o].tau_derivative(self.dt, &raw[o]);
                        for (k, i) in rows.clone().enumerate() {
                            column[o * len + k] = d[i] / self.scale[o];
                        }
                    }
                }
                BoundaryEffect::InputOffset
                | BoundaryEffect::InputDelay
                | BoundaryEffect::ActuatorLag => left.extend(at..at + n),
            }
            at += n;
        }
        left
    }

    /// The initial state that best fits the scored samples with `model`'s parameters fixed:
    /// the record starts wherever the measured system was, so neither the configured nor the
    /// refitted model is charged with a start nobody specified.
    ///
    /// Over a long record the output depends on the start through many switches and its cost
    /// has narrow valleys far from the guess (the model's limit cycle), where the iteration
    /// stalls. The start is therefore fitted on a growing horizon: the first
    /// [`FIRST_HORIZON`] of the scored samples, then four times as many, until all; each fit
    /// starts from the last.
    pub(super) fn fit_state(
        &self,
        model: &Model,
        x0: &[f64],
        b: &Boundary,
    ) -> Result<Vec<f64>, DiagnoseError> {
        let typical: Vec<f64> = x0.iter().map(|v| v.abs().max(1e-3)).collect();
        let lm = LmOptions {
            scales: Some(typical.clone()),
            bounds: Some(self.state_box.clone()),
            ..LmOptions::default()
        };
        let outputs = self.rec.outputs().len();
        let full = self.rows.clone();
        let first = ((full.len() as f64 * FIRST_HORIZON).ceil() as usize)
            .max(MIN_HORIZON_SAMPLES)
            .min(full.len());
        let mut x = x0.to_vec();
        let mut len = first;
        loop {
            let rows = full.start..full.start + len;
            let residuals = |z: &[f64], r: &mut [f64]| -> Result<(), String> {
                let sim = self
                    .simulate_upto(model, z, b, rows.end)
                    .map_err(|e| e.to_string())?;
                self.fill_rows(&sim, r, rows.clone());
                Ok(())
            };
            let every: Vec<usize> = (0..x.len()).collect();
            let bounds = &self.state_box;
            // Once the sensitivities fail (the motion slides), the rest of the fit differences.
            let failed = std::cell::Cell::new(false);
            let jacobian = |z: &[f64], r: &[f64], jac: &mut [f64]| -> Result<(), String> {
                let exact = !failed.get()
                    && self
                        .sensitivities(model, (&[], &[]), z, b, rows.end, rows.clone(), &every, jac)
                        .is_ok();
                failed.set(!exact);
                if exact {
                    return Ok(());
                }
                difference_columns(
                    &residuals,
                    z,
                    r,
                    &every,
                    (self.fd_step(), &typical, bounds),
                    jac,
                )
            };
            x = levenberg_marquardt_with_jacobian(
                &residuals,
                jacobian,
                &x,
                outputs * rows.len(),
                &lm,
            )
            .map(|f| f.params)
            .map_err(|e| DiagnoseError::NominalFit {
                reason: format!("initial state: {e}"),
            })?;
            if len == full.len() {
                return Ok(x);
            }
            len = (4 * len).min(full.len());
        }
    }

    /// The input's white-noise level on the scored rows ([`input_noise_level`]) and the RMS
    /// response of `model` (from `x0`) to white noise of that level added to the input, in
    /// NRMSE units over the outputs; `None` where the level cannot be told from the input or a
    /// simulation fails.
    pub(super) fn input_noise(
        &self,
        model: &Model,
        x0: &[f64],
        opts: &ModelFitOptions,
    ) -> Option<crate::InputNoise> {
        let u = self.rec.input();
        let sigma = input_noise_level(
            &[&u[self.rows.clone()]],
            opts.noise_band,
            opts.input_noise_share,
            opts.input_noise_flatness,
        )?;
        let noisy = with_white_noise(u, sigma)?;
        let signal = Arc::new(SampledSignal::new(
            self.rec.time()[0],
            self.dt,
            &noisy,
            Interpolation::CubicSpline,
        ));
        let ideal = Boundary::default();
        let clean = self.simulate(model, x0, &ideal).ok()?;
        let driven = simulate_outputs(
            model,
            self.rec,
            &ideal.input(&signal),
            (self.mode0, x0),
            &self.sim_opts,
            self.rec.len(),
        )
        .ok()?;
        let n = self.rows.len().max(1) as f64;
        let mean_square = (0..clean.len())
            .map(|o| {
                self.rows
                    .clone()
                    .map(|i| ((driven[o][i] - clean[o][i]) / self.scale[o]).powi(2))
                    .sum::<f64>()
                    / n
            })
            .sum::<f64>()
            / clean.len().max(1) as f64;
        let propagated = mean_square.sqrt();
        propagated
            .is_finite()
            .then_some(crate::InputNoise { sigma, propagated })
    }

    /// Per output: RMS error and RMS error over the output's scale, on `range`.
    pub(super) fn errors(
        &self,
        sim: &[Vec<f64>],
        range: std::ops::Range<usize>,
    ) -> (Vec<f64>, Vec<f64>) {
        let n = range.len().max(1) as f64;
        (0..self.rec.outputs().len())
            .map(|o| {
                let rms = (range
                    .clone()
                    .map(|i| (sim[o][i] - self.rec.outputs()[o][i]).powi(2))
                    .sum::<f64>()
                    / n)
                    .sqrt();
                (rms, rms / self.scale[o])
            })
            .unzip()
    }
}

/// A model's states at samples of a record: where a term's parameters are scaled.
pub(super) struct StateSamples {
    pub(super) t: Vec<f64>,
    pub(super) modes: Vec<htfid_lang::Mode>,
    pub(super) x: Vec<Vec<f64>>,
    pub(super) u: Vec<f64>,
}

impl StateSamples {
    /// The smallest and the largest value of state `j` on these samples.
    pub(super) fn range(&self, j: usize) -> (f64, f64) {
        self.x
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
                (lo.min(x[j]), hi.max(x[j]))
            })
    }

    /// What each of `model`'s states does on these samples (the library's [`StateStats`]).
    pub(super) fn stats(&self, model: &Model, signal: &Arc<SampledSignal>) -> Vec<StateStats> {
        let n = model.states().len();
        let driven = model.with_input(Some(Boundary::default().input(signal)));
        let count = self.x.len().max(1) as f64;
        let pairs = crate::term::velocity_pairs(model);
        let mut jac = vec![0.0; n * n];
        // The RMS of -d(V')/dQ for every pair, from the model's exact Jacobian.
        let mut stiffness = vec![0.0; n];
        for i in 0..self.x.len() {
            if !driven.jacobian(self.modes[i], self.t[i], &self.x[i], &mut jac) {
                continue;
            }
            for &(q, v) in &pairs {
                stiffness[q] += jac[v * n + q].powi(2) / count;
            }
        }
        (0..n)
            .map(|j| {
                let mut values: Vec<f64> = self.x.iter().map(|x| x[j]).collect();
                let mean = values.iter().sum::<f64>() / count;
                let spread =
                    (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / count).sqrt();
                values.sort_by(f64::total_cmp);
                let at = |p: f64| {
                    values
                        .get(((values.len().max(1) - 1) as f64 * p).round() as usize)
                        .copied()
                        .unwrap_or(mean)
                };
                StateStats {
                    mean,
                    spread,
                    quantiles: [0.01, 0.03, 0.1, 0.3, 0.7, 0.9, 0.97, 0.99].map(at),
                    stiffness: stiffness[j].sqrt(),
                }
            })
            .collect()
    }

    /// The size of a meaningful value of each of `term`'s parameters in `model` (extended by
    /// it): the RMS of the expressions the term joins (a state's equation, a guard) over the
    /// RMS of their exact derivative by the parameter, on these samples. A parameter that
    /// changes nothing here gets 1.
    pub(super) fn term_scales(
        &self,
        model: &Model,
        signal: &Arc<SampledSignal>,
        term: &TermEffect,
    ) -> Vec<f64> {
        let names = term.parameter_names();
        let refs: Vec<&str> = names.iter().map(String::as_str).collect();
        let k = refs.len();
        let Ok(sens) = model.parameter_sensitivity(&refs) else {
            return vec![1.0; k];
        };
        let input = Boundary::default().input(signal);
        let driven = model.with_input(Some(input));
        let n = model.states().len();
        let guards = model.guard_names();
        let (mut size, mut slope) = (vec![0.0; k], vec![0.0; k]);
        let mut f = vec![0.0; n];
        let mut dfdp = vec![0.0; n * k];
        let mut dhdp = vec![0.0; k];
        for (site, _) in &term.extension.terms {
            for i in 0..self.t.len() {
                let (t, x, u, mode) = (self.t[i], &self.x[i], self.u[i], self.modes[i]);
                match site {
                    Site::Flow { state, mode: only } => {
                        if only.as_deref().is_some_and(|m| m != model.mode_name(mode)) {
                            continue;
                        }
                        let Some(s) = model.states().iter().position(|q| q.name == *state) else {
                            continue;
                        };
                        driven.vector_field(mode, t, x, &mut f);
                        sens.flow(mode, t, x, u, &mut dfdp);
                        for j in 0..k {
                            size[j] += f[s] * f[s];
                            slope[j] += dfdp[s * k + j].powi(2);
                        }
                    }
                    Site::Guard { name } => {
                        let Some(g) = guards.iter().position(|h| h == name) else {
                            continue;
                        };
                        let h = model.guard_value(g, t, x, u);
                        sens.guard(g, t, x, u, &mut dhdp);
                        for j in 0..k {
                            size[j] += h * h;
                            slope[j] += dhdp[j].powi(2);
                        }
                    }
                }
            }
        }
        size.iter()
            .zip(&slope)
            .map(|(a, b)| {
                let v = (a / b).sqrt();
                if v.is_finite() && v > 0.0 {
                    v
                } else {
                    1.0
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A damped oscillator driven by a sum of sines, with the given outputs (position `x`,
    /// velocity `v`), and a record of 1200 samples at 100 Hz whose outputs are sines (what the
    /// residuals compare with; their values do not matter to a derivative).
    fn oscillator(outputs: &str) -> (Model, TimeSeries) {
        let model = Model::parse(&format!(
            r#"
            states = ["x", "v"]
            parameters = {{ k = 4.0, c = 0.5 }}
            flow = {{ x = "v", v = "-k*x - c*v + u" }}
            outputs = {outputs}
            initial = {{ x = 0.1, v = 0.0 }}
            "#
        ))
        .unwrap();
        let time: Vec<f64> = (0..1200).map(|i| i as f64 * 0.01).collect();
        let u: Vec<f64> = time
            .iter()
            .map(|t| (1.1 * t).sin() + 0.5 * (3.7 * t + 0.2).sin())
            .collect();
        let ys: Vec<Vec<f64>> = (0..model.outputs().len())
            .map(|o| {
                time.iter()
                    .map(|t| 0.2 * (1.1 * t - 0.3 + 1.5 * o as f64).sin())
                    .collect()
            })
            .collect();
        let rec = TimeSeries::with_outputs(time, u, ys, "test").unwrap();
        (model, rec)
    }

    /// The sensors' exact columns (offset and gain per output, one lag for both) against
    /// central differences of the scaled residuals themselves (simulation, sensors, scaling:
    /// a second method), on a two-output model driven by a sum of sines. The readings are
    /// linear in `b` and `g`, so their differences are exact to rounding; the lag's central
    /// difference of step `1e-4 tau` leaves `O(h^2)` (`~1e-8` relative) and a rounding of
    /// `~1e-13 / h`. Tolerance: `1e-6` of each column's largest entry.
    #[test]
    fn sensor_columns_are_the_derivatives_of_the_residuals() {
        let (model, rec) = oscillator(r#"{ x = "x", v = "v" }"#);
        let n = rec.len();
        let est = Prepared::new(&model, &rec, n, &ModelFitOptions::default()).unwrap();
        let effects = [BoundaryEffect::SensorOffsetGain, BoundaryEffect::SensorLag];
        // b_x, g_x, b_v, g_v, tau_s.
        let p = [0.01, 1.1, -0.02, 0.9, 0.03];
        let x0 = [0.1, 0.0];
        let residuals = |p: &[f64]| -> Vec<f64> {
            let b = Boundary::with_all(&effects, p, 2);
            let sim = est.simulate(&model, &x0, &b).unwrap();
            let mut r = vec![0.0; est.residual_len()];
            est.fill(&sim, &mut r);
            r
        };
        let m = est.residual_len();
        let mut jac = vec![0.0; m * (p.len() + 2)];
        let b = Boundary::with_all(&effects, &p, 2);
        let raw = est
            .sensitivities(
                &model,
                (&[], &[]),
                &x0,
                &b,
                rec.len(),
                est.rows.clone(),
                &[5, 6],
                &mut jac,
            )
            .unwrap();
        let left = est.sensor_columns(&raw, (&effects, &b, 0), est.rows.clone(), &mut jac);
        assert!(left.is_empty(), "{left:?}");
        for j in 0..p.len() {
            let h = if j == 4 { 1e-4 * p[4] } else { 1e-4 };
            let (mut up, mut down) = (p, p);
            up[j] += h;
            down[j] -= h;
            let (ru, rd) = (residuals(&up), residuals(&down));
            let column = &jac[j * m..(j + 1) * m];
            let scale = column.iter().map(|v| v.abs()).fold(0.0, f64::max);
            assert!(scale > 0.0, "column {j} is zero");
            for i in 0..m {
                let fd = (ru[i] - rd[i]) / (2.0 * h);
                assert!(
                    (column[i] - fd).abs() <= 1e-6 * scale,
                    "column {j}, row {i}: {} against {fd}",
                    column[i]
                );
            }
        }
    }

    /// The input side's columns (an offset, a delay and an actuator's lag of the input) from
    /// the sensitivities along the input's directions, against central differences of the
    /// residuals extrapolated (`O(h^4)`). The simulation itself moves with a delay or a lag:
    /// its steps cross the knots of the input's spline (where its third derivative jumps) at
    /// other places, which leaves a noise of about `1e-9` of the outputs even at `rtol =
    /// 1e-12` (measured: differences at `1.3e-5` s scattered by `1e-4` of a column). Steps of
    /// `1e-3` (of the offset, and in s of the delay and the lag) bring that noise to `1e-6`,
    /// the extrapolation's truncation `h^4` times the fifth derivatives stays far below.
    /// Tolerance: `1e-5` of each column's largest entry.
    #[test]
    fn input_columns_are_the_derivatives_of_the_residuals() {
        let (model, rec) = oscillator(r#"{ x = "x" }"#);
        let n = rec.len();
        let opts = ModelFitOptions {
            rtol: 1e-12,
            ..ModelFitOptions::default()
        };
        let est = Prepared::new(&model, &rec, n, &opts).unwrap();
        let effects = [
            BoundaryEffect::InputOffset,
            BoundaryEffect::InputDelay,
            BoundaryEffect::ActuatorLag,
        ];
        let p = [0.05, 0.013, 0.02];
        let x0 = [0.1, 0.0];
        let residuals = |p: &[f64]| -> Vec<f64> {
            let b = Boundary::with_all(&effects, p, 1);
            let sim = est.simulate(&model, &x0, &b).unwrap();
            let mut r = vec![0.0; est.residual_len()];
            est.fill(&sim, &mut r);
            r
        };
        let m = est.residual_len();
        let mut jac = vec![0.0; m * (p.len() + 2)];
        let b = Boundary::with_all(&effects, &p, 1);
        let directions: Vec<InputFn> = effects
            .iter()
            .map(|&e| b.input_direction(e, &est.signal).unwrap())
            .collect();
        let raw = est
            .sensitivities(
                &model,
                (&[], &directions),
                &x0,
                &b,
                rec.len(),
                est.rows.clone(),
                &[0, 1, 2, 3, 4],
                &mut jac,
            )
            .unwrap();
        assert_eq!(
            est.sensor_columns(&raw, (&effects, &b, 0), est.rows.clone(), &mut jac),
            vec![0, 1, 2]
        );
        for (j, h) in [1e-3, 1e-3, 1e-3].into_iter().enumerate() {
            let central = |h: f64| -> Vec<f64> {
                let (mut up, mut down) = (p, p);
                up[j] += h;
                down[j] -= h;
                let (ru, rd) = (residuals(&up), residuals(&down));
                ru.iter()
                    .zip(&rd)
                    .map(|(a, b)| (a - b) / (2.0 * h))
                    .collect()
            };
            let (wide, narrow) = (central(h), central(h / 2.0));
            let column = &jac[j * m..(j + 1) * m];
            let scale = column.iter().map(|v| v.abs()).fold(0.0, f64::max);
            assert!(scale > 0.0, "column {j} is zero");
            for i in 0..m {
                let fd = (4.0 * narrow[i] - wide[i]) / 3.0;
                assert!(
                    (column[i] - fd).abs() <= 1e-5 * scale,
                    "column {j}, row {i}: {} against {fd}",
                    column[i]
                );
            }
        }
    }
}
