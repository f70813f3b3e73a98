//! Output-error fits: the parameter vector of a model, the residual function, the
//! Levenberg-Marquardt call and standard errors that allow for correlated residuals.

use std::ops::Range;
use std::sync::Arc;

use htfid_estimate::{
    levenberg_marquardt_batch, levenberg_marquardt_with_jacobian, FdScheme, LmOptions, LmStop,
};
use htfid_model::{DamperLaw, Effects, Hopper, HopperParams};
use nalgebra::DMatrix;
use rayon::prelude::*;

use crate::effect::Slot;
use crate::select::likelihood_ratio;
use crate::sim::{
    sensitivities_hold, simulate_positions_batch, simulate_positions_with, simulate_sensitivities,
    Extent, ExtraForce, Force, MeasuredForce, Param, SimFailure, SimLane, SimMethod, Stepping,
    JACOBIAN_COARSENING, MAX_SENSITIVITIES,
};
use crate::{Sensor, TimeSeries};

/// Relative finite-difference step of the Jacobians.
const FD_STEP: f64 = 1e-7;
/// Step of [`Context::score`]'s derivative, in typical sizes: large beside the integration's
/// rounding, small beside the curvature of any effect at its absent value.
const SCORE_STEP: f64 = 1e-4;
/// Refits allowed when the fitted model needs a finer integration than its start.
const MAX_REFITS: usize = 2;

/// A stretch of the record simulated from its own initial state; the first `skip` samples
/// (the burn-in) are left out of every cost and score.
#[derive(Debug, Clone)]
pub(crate) struct Segment {
    pub range: Range<usize>,
    pub skip: usize,
    /// Position and velocity at `range.start` estimated from the data.
    pub init: [f64; 2],
}

impl Segment {
    pub(crate) fn scored(&self) -> Range<usize> {
        self.range.start + self.skip..self.range.end
    }
}

/// Typical sizes of the data, for parameter scales.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Scales {
    pub x_std: f64,
    pub v_std: f64,
    pub f_std: f64,
}

/// Everything a fit needs that does not change between candidates.
#[derive(Debug)]
pub(crate) struct Context<'a> {
    pub record: &'a TimeSeries,
    pub input: MeasuredForce,
    pub damper: DamperLaw,
    pub method: SimMethod,
    pub extent: Extent,
    pub scales: Scales,
    pub fit: Vec<Segment>,
    pub validation: Vec<Segment>,
    pub fit_initial_state: bool,
    pub max_iterations: usize,
    /// Smallest likelihood-ratio improvement of a step that continues a fit
    /// ([`crate::DiagnoseOptions::fit_tolerance`]).
    pub fit_tolerance: f64,
    /// The nominal's forcing period when it is forced (the forcing is in the measured force).
    pub forcing_period: Option<f64>,
    /// The range every fit keeps the mass in: [`MASS_RANGE`] times the configured mass either
    /// way.
    pub mass_range: (f64, f64),
}

/// A fitted mass stays within this factor of the configured one either way. Without a bound
/// the output-error fit of a nominal far from the data (a free mass without the friction that
/// holds the real one) can shrink the mass towards zero, where the model turns first order
/// and ever finer integration steps are needed; a factor of 100 is no constraint on a mass
/// that is merely unknown.
pub(crate) const MASS_RANGE: f64 = 100.0;

/// A point in model space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ModelPoint {
    pub params: HopperParams,
    pub effects: Effects,
    pub sensor: Sensor,
}

impl ModelPoint {
    pub(crate) fn get(&self, s: Slot) -> f64 {
        s.get(self)
    }

    pub(crate) fn set(&mut self, s: Slot, v: f64) {
        s.set(self, v);
    }
}

/// A model ready to simulate on the record: the hopper driven by the measured force, and its
/// sensor.
pub(crate) struct Driven {
    pub hopper: Hopper,
    /// The force `hopper` reads, for the simulation to read directly.
    pub force: Option<Force>,
    pub sensor: Sensor,
    /// A force beyond the library's terms (a formula from the term search), if any.
    pub extra: Option<Arc<ExtraForce>>,
}

/// The result of one output-error fit.
#[derive(Debug, Clone)]
pub(crate) struct FitResult {
    pub point: ModelPoint,
    pub slots: Vec<Slot>,
    pub values: Vec<f64>,
    /// Standard errors of `values`, allowing for correlated residuals (see [`hac_stderr`]).
    pub stderr: Vec<f64>,
    /// Whether each value ended on its lower bound (its standard error is then meaningless).
    pub at_bound: Vec<bool>,
    /// Initial states of the fit segments used in the fit.
    pub init: Vec<[f64; 2]>,
    /// Per value, how much the residuals' correlation inflates its variance (`>= 1`).
    pub inflation: Vec<f64>,
    pub rss: f64,
    pub bic: f64,
    pub stepping: Stepping,
    pub evaluations: usize,
    /// The fit stopped at its iteration limit (`max_iterations`) before a tolerance was met.
    pub at_limit: bool,
}

/// How the vector of fitted numbers maps to a model.
#[derive(Debug, Clone)]
struct Layout {
    slots: Vec<Slot>,
    log: Vec<bool>,
    n_init: usize,
}

impl Layout {
    fn len(&self) -> usize {
        self.slots.len() + 2 * self.n_init
    }

    fn point(&self, base: &ModelPoint, u: &[f64]) -> ModelPoint {
        let mut p = *base;
        for (i, &s) in self.slots.iter().enumerate() {
            let v = if self.log[i] { u[i].exp() } else { u[i] };
            p.set(s, v);
        }
        p
    }

    fn init(&self, segs: &[Segment], u: &[f64]) -> Vec<[f64; 2]> {
        let off = self.slots.len();
        segs.iter()
            .enumerate()
            .map(|(k, s)| {
                if k < self.n_init {
                    [s.init[0] + u[off + 2 * k], s.init[1] + u[off + 2 * k + 1]]
                } else {
                    s.init
                }
            })
            .collect()
    }
}

impl Context<'_> {
    /// The Levenberg-Marquardt `ftol` of a fit of `n` samples: a step that lowers the cost by
    /// the fraction `f` improves the likelihood ratio by `n ln(1 / (1 - f))`, about `n f`, so
    /// `fit_tolerance / n` ends the fit at a step worth less than `fit_tolerance`.
    pub(crate) fn step_tolerance(&self, n: usize) -> f64 {
        self.fit_tolerance / n.max(1) as f64
    }

    pub(crate) fn hopper(&self, p: &ModelPoint) -> Result<Driven, String> {
        let (hopper, force) = self
            .input
            .drive_with(p.params, self.damper, p.effects)
            .map_err(|e| e.to_string())?;
        Ok(Driven {
            hopper,
            force: Some(force),
            sensor: p.sensor,
            extra: None,
        })
    }

    pub(crate) fn stepping(&self, p: &ModelPoint) -> Stepping {
        Stepping::resolve(
            self.method,
            &p.params,
            &p.effects,
            &self.extent,
            self.record.dt(),
        )
    }

    /// The resolution a fit's Jacobian at `p` is simulated at: an oscillation resolved
    /// [`JACOBIAN_COARSENING`] times more coarsely than [`Context::stepping`] does, a decay as
    /// finely (its bound, `decay h <= 10 max_rate_step = 2`, already lies near RK4's
    /// stability limit of 2.8 on the real axis).
    pub(crate) fn jacobian_stepping(&self, p: &ModelPoint) -> Stepping {
        Stepping::resolve_coarsened(
            self.method,
            &p.params,
            &p.effects,
            &self.extent,
            self.record.dt(),
            JACOBIAN_COARSENING,
        )
    }

    /// Number of scored samples of the fit segments.
    pub(crate) fn n_fit(&self) -> usize {
        self.fit.iter().map(|s| s.scored().len()).sum()
    }

    /// Simulates a segment from `init`; returns the simulated readings of the whole range.
    pub(crate) fn simulate(
        &self,
        model: &Driven,
        seg: &Segment,
        init: [f64; 2],
        stepping: &Stepping,
        out: &mut Vec<f64>,
    ) -> Result<(), SimFailure> {
        out.resize(seg.range.len(), 0.0);
        let t0 = self.record.time()[seg.range.start];
        simulate_positions_with(
            &model.hopper,
            model.force.as_ref(),
            model.extra.as_deref(),
            t0,
            init,
            self.record.dt(),
            stepping,
            out,
        )?;
        model.sensor.apply(self.record.dt(), out);
        Ok(())
    }

    /// Residuals `simulated - measured` over the scored samples of `segs`, concatenated.
    pub(crate) fn residuals(
        &self,
        hopper: &Driven,
        segs: &[Segment],
        init: &[[f64; 2]],
        stepping: &Stepping,
        r: &mut [f64],
    ) -> Result<(), SimFailure> {
        self.residuals_batch(&[Some(hopper)], segs, &[init], stepping, &mut [r])
            .pop()
            .unwrap_or(Ok(()))
    }

    /// [`Context::residuals`] for several models at once (one result per model), simulated in
    /// lockstep: the same residuals as one by one. A model that is `None` (one that could not
    /// be built) is skipped: its residuals stay as they were and its result is `Ok`, for the
    /// caller to replace with the reason.
    pub(crate) fn residuals_batch(
        &self,
        models: &[Option<&Driven>],
        segs: &[Segment],
        inits: &[&[[f64; 2]]],
        stepping: &Stepping,
        outs: &mut [&mut [f64]],
    ) -> Vec<Result<(), SimFailure>> {
        let x = self.record.output();
        let dt = self.record.dt();
        let mut results: Vec<Result<(), SimFailure>> = models.iter().map(|_| Ok(())).collect();
        let mut bufs = vec![Vec::new(); models.len()];
        let mut at = 0;
        for (k, seg) in segs.iter().enumerate() {
            let live: Vec<usize> = (0..models.len())
                .filter(|&i| models[i].is_some() && results[i].is_ok())
                .collect();
            let mut lanes: Vec<SimLane<'_>> = Vec::with_capacity(live.len());
            for (i, buf) in bufs.iter_mut().enumerate() {
                let Some(m) = models[i].filter(|_| results[i].is_ok()) else {
                    continue;
                };
                buf.resize(seg.range.len(), 0.0);
                lanes.push(SimLane {
                    hopper: &m.hopper,
                    force: m.force.as_ref(),
                    extra: m.extra.as_deref(),
                    xv0: inits[i][k],
                    out: buf,
                });
            }
            let t0 = self.record.time()[seg.range.start];
            let done = simulate_positions_batch(&mut lanes, t0, dt, stepping);
            drop(lanes);
            let scored = seg.scored();
            let n = scored.len();
            for (&i, result) in live.iter().zip(done) {
                if let Err(e) = result {
                    results[i] = Err(e);
                    continue;
                }
                let buf = &mut bufs[i];
                if let Some(m) = models[i] {
                    m.sensor.apply(dt, buf);
                }
                for (j, ri) in outs[i][at..at + n].iter_mut().enumerate() {
                    *ri = buf[seg.skip + j] - x[scored.start + j];
                }
            }
            at += n;
        }
        results
    }

    /// Sum of squared fit residuals with initial states from the data; `None` when the model
    /// cannot be simulated.
    pub(crate) fn fit_cost(&self, p: &ModelPoint) -> Option<f64> {
        self.fit_costs(std::slice::from_ref(p)).pop().flatten()
    }

    /// [`Context::fit_cost`] of every point: points that need the same integration step are
    /// simulated in lockstep, a few at a time ([`Context::residuals_batch`], the same numbers
    /// bit for bit as one at a time), and the batches in parallel.
    pub(crate) fn fit_costs(&self, points: &[ModelPoint]) -> Vec<Option<f64>> {
        let steppings = points.iter().map(|p| self.stepping(p)).collect();
        self.costs_on(points, &self.fit, steppings)
    }

    /// The costs a grid of starting points is ranked by: [`Context::fit_costs`] over the
    /// leading `samples` scored samples of the fit segments, simulated at the Jacobian's
    /// coarser steps ([`Context::jacobian_stepping`]). A grid only picks where fits start;
    /// the fits run over the whole fit segments at the full step.
    pub(crate) fn ranking_costs(&self, points: &[ModelPoint], samples: usize) -> Vec<Option<f64>> {
        let steppings = points.iter().map(|p| self.jacobian_stepping(p)).collect();
        self.costs_on(points, &self.leading(samples), steppings)
    }

    /// The fit segments cut to their leading `samples` scored samples in all (the whole of
    /// them where they hold fewer).
    fn leading(&self, samples: usize) -> Vec<Segment> {
        let mut left = samples;
        let mut out = Vec::new();
        for seg in &self.fit {
            if left == 0 {
                break;
            }
            let n = seg.scored().len().min(left);
            left -= n;
            out.push(Segment {
                range: seg.range.start..seg.range.start + seg.skip + n,
                ..seg.clone()
            });
        }
        out
    }

    /// [`Context::fit_costs`] over the segments `segs` (the fit segments or a part of them),
    /// each point simulated at its own stepping.
    fn costs_on(
        &self,
        points: &[ModelPoint],
        segs: &[Segment],
        steppings: Vec<Stepping>,
    ) -> Vec<Option<f64>> {
        /// Lanes per batch: beyond four the lockstep gains little, and smaller batches
        /// keep both cores busy.
        const LANES: usize = 4;
        let mut groups: Vec<Vec<usize>> = Vec::new();
        for (i, st) in steppings.iter().enumerate() {
            match groups
                .iter_mut()
                .find(|g| g.len() < LANES && same_stepping(&steppings[g[0]], st))
            {
                Some(g) => g.push(i),
                None => groups.push(vec![i]),
            }
        }
        // The finest steps first, so that the longest batches do not start last.
        groups.sort_by_key(|g| std::cmp::Reverse(substeps(&steppings[g[0]])));
        let init: Vec<[f64; 2]> = segs.iter().map(|s| s.init).collect();
        let n: usize = segs.iter().map(|s| s.scored().len()).sum();
        let costs: Vec<Vec<(usize, Option<f64>)>> = groups
            .par_iter()
            .map(|g| {
                let models: Vec<Result<Driven, String>> =
                    g.iter().map(|&i| self.hopper(&points[i])).collect();
                let driven: Vec<Option<&Driven>> = models.iter().map(|m| m.as_ref().ok()).collect();
                let inits: Vec<&[[f64; 2]]> = g.iter().map(|_| init.as_slice()).collect();
                let mut rs = vec![vec![0.0; n]; g.len()];
                let mut outs: Vec<&mut [f64]> = rs.iter_mut().map(Vec::as_mut_slice).collect();
                let done = self.residuals_batch(&driven, segs, &inits, &steppings[g[0]], &mut outs);
                g.iter()
                    .zip(done)
                    .zip(&rs)
                    .zip(&driven)
                    .map(|(((&i, d), r), m)| {
                        let c: f64 = r.iter().map(|v| v * v).sum();
                        (i, (m.is_some() && d.is_ok() && c.is_finite()).then_some(c))
                    })
                    .collect()
            })
            .collect();
        let mut out = vec![None; points.len()];
        for (i, c) in costs.into_iter().flatten() {
            out[i] = c;
        }
        out
    }

    /// The score statistic of freeing `s` beside the fitted model `at`, which holds it at its
    /// absent value: the likelihood ratio that a Gauss-Newton step of `s` alone would gain,
    /// `n ln(rss / (rss - (J r)^2 / (J J)))`, with `J` the residuals' derivative by `s` (a
    /// forward difference of `SCORE_STEP` typical sizes). Zero where the cost rises as `s`
    /// leaves a lower bound it sits on. The other parameters held where they are and the
    /// residuals taken as independent, it is a screen, not the test; `None` where a model
    /// cannot be simulated.
    pub(crate) fn score(&self, at: &FitResult, s: Slot) -> Option<f64> {
        let v = at.point.get(s);
        let h = SCORE_STEP
            * if s.log_scaled() && v > 0.0 {
                v
            } else {
                self.typical(s, &at.point)
            };
        let mut moved = at.point;
        moved.set(s, v + h);
        let (base, step) = (self.hopper(&at.point).ok()?, self.hopper(&moved).ok()?);
        let n = self.n_fit();
        let (mut r0, mut r1) = (vec![0.0; n], vec![0.0; n]);
        let done = self.residuals_batch(
            &[Some(&base), Some(&step)],
            &self.fit,
            &[&at.init, &at.init],
            &at.stepping,
            &mut [&mut r0, &mut r1],
        );
        if done.iter().any(Result::is_err) {
            return None;
        }
        let (mut g, mut jj, mut rss) = (0.0, 0.0, 0.0);
        for (a, b) in r0.iter().zip(&r1) {
            let j = (b - a) / h;
            g += j * a;
            jj += j * j;
            rss += a * a;
        }
        let on_bound = v <= s.lower_bound();
        if !(jj > 0.0 && rss > 0.0) || (on_bound && g >= 0.0) {
            return Some(0.0);
        }
        let gain = (g * g / jj).min(rss * (1.0 - 1e-12));
        Some(likelihood_ratio(rss, rss - gain, n, 1.0))
    }

    /// Typical size of a parameter, for finite-difference steps.
    fn typical(&self, s: Slot, p: &ModelPoint) -> f64 {
        let sc = &self.scales;
        let force = (p.params.k * sc.x_std).max(sc.f_std).max(f64::MIN_POSITIVE);
        let v = match s {
            Slot::M | Slot::K | Slot::C => 1.0,
            Slot::X0 => sc.x_std.max(p.params.x0.abs()),
            Slot::InputOffset => force,
            Slot::K3 => force / sc.x_std.powi(3),
            Slot::Mu => force,
            Slot::CF => force / sc.v_std,
            Slot::C2 => force / (sc.v_std * sc.v_std),
            Slot::Tau | Slot::Delay => self.record.dt(),
            Slot::VTh => sc.v_std,
            Slot::XStop => sc.x_std,
            Slot::KStop => p.params.k,
            Slot::TauS => self.record.dt(),
            Slot::SensorB => sc.x_std,
            Slot::SensorG => 1.0,
        };
        if v.is_finite() && v > 0.0 {
            v
        } else {
            1.0
        }
    }

    /// Output-error fit of `slots` from `start` (which must hold the starting values).
    pub(crate) fn fit(&self, start: &ModelPoint, slots: &[Slot]) -> Result<FitResult, String> {
        let first = *start;
        let mut start = *start;
        let mut stepping = self.stepping(&start);
        let mut evaluations = 0;
        for _ in 0..=MAX_REFITS {
            let result = self.fit_once(&start, slots, &stepping)?;
            evaluations += result.evaluations;
            let needed = self.stepping(&result.point);
            if stepping.covers(&needed) {
                return Ok(FitResult {
                    evaluations,
                    ..result
                });
            }
            start = result.point;
            stepping = needed;
        }
        // Where the fit went, parameter by parameter.
        let moves: Vec<String> = slots
            .iter()
            .map(|&s| {
                format!(
                    "{} {} -> {}",
                    s.name(),
                    htfid_number::sig(first.get(s), 3),
                    htfid_number::sig(start.get(s), 3)
                )
            })
            .collect();
        let mass = if slots.contains(&Slot::M) && start.get(Slot::M) < first.get(Slot::M) {
            "; a shrinking mass turns the model first order: leave `m` out of `free` (a free \
             mass, k = 0, simulated open loop drifts away from a mass held by friction), or \
             fit shorter ranges"
        } else {
            ""
        };
        Err(format!(
            "the fitted model kept needing a finer integration step ({}): a stiffening \
             contact, a vanishing lag or a shrinking mass; bound the parameter or start it \
             nearer the data{mass}",
            moves.join(", ")
        ))
    }

    fn fit_once(
        &self,
        start: &ModelPoint,
        slots: &[Slot],
        stepping: &Stepping,
    ) -> Result<FitResult, String> {
        let layout = Layout {
            slots: slots.to_vec(),
            log: slots
                .iter()
                .map(|&s| s.log_scaled() && start.get(s) > 0.0)
                .collect(),
            n_init: if self.fit_initial_state {
                self.fit.len()
            } else {
                0
            },
        };
        let np = layout.len();
        let mut u0 = Vec::with_capacity(np);
        let mut typical = Vec::with_capacity(np);
        let mut bounds = Vec::with_capacity(np);
        for (i, &s) in slots.iter().enumerate() {
            let v = start.get(s);
            if layout.log[i] {
                let (lo, hi) = if s == Slot::M {
                    (self.mass_range.0.ln(), self.mass_range.1.ln())
                } else {
                    (f64::NEG_INFINITY, f64::INFINITY)
                };
                u0.push(v.ln().clamp(lo, hi));
                typical.push(1.0);
                bounds.push((lo, hi));
            } else {
                let lower = s.lower_bound();
                u0.push(v.max(lower));
                typical.push(self.typical(s, start));
                bounds.push((lower, f64::INFINITY));
            }
        }
        for _ in 0..layout.n_init {
            u0.push(0.0);
            u0.push(0.0);
            typical.push(1e-2 * self.scales.x_std);
            typical.push(1e-2 * self.scales.v_std);
            bounds.push((f64::NEG_INFINITY, f64::INFINITY));
            bounds.push((f64::NEG_INFINITY, f64::INFINITY));
        }
        let n = self.n_fit();
        if n <= np {
            return Err(format!(
                "{n} fitted samples cannot determine {np} parameters; fit a longer range or free \
                 fewer parameters"
            ));
        }
        // The points of a Jacobian are simulated together ([`Context::residuals_batch`]).
        let residual_fn = |points: &[&[f64]], outs: &mut [&mut [f64]]| {
            let models: Vec<Result<Driven, String>> = points
                .iter()
                .map(|u| self.hopper(&layout.point(start, u)))
                .collect();
            let inits: Vec<Vec<[f64; 2]>> =
                points.iter().map(|u| layout.init(&self.fit, u)).collect();
            let driven: Vec<Option<&Driven>> = models.iter().map(|m| m.as_ref().ok()).collect();
            let init: Vec<&[[f64; 2]]> = inits.iter().map(Vec::as_slice).collect();
            let done = self.residuals_batch(&driven, &self.fit, &init, stepping, outs);
            models
                .iter()
                .zip(done)
                .map(|(m, d)| match m {
                    Err(e) => Err(e.clone()),
                    Ok(_) => d.map_err(|e| format!("t = {} s: {}", e.time, e.reason)),
                })
                .collect::<Vec<Result<(), String>>>()
        };
        let opts = LmOptions {
            max_iter: self.max_iterations,
            ftol: self.step_tolerance(n),
            xtol: 1e-9,
            gtol: 1e-7,
            fd_scheme: FdScheme::Forward,
            fd_step: Some(FD_STEP),
            scales: Some(typical.clone()),
            bounds: Some(bounds.clone()),
            lambda0: 1e-3,
            extend_steps: true,
        };
        let plan = self.columns(start, &layout, stepping);
        let lm = match &plan {
            // Exact columns from one simulation with sensitivities, differences for the rest.
            Some(plan) => levenberg_marquardt_with_jacobian(
                |u: &[f64], r: &mut [f64]| {
                    residual_fn(&[u], &mut [r])
                        .pop()
                        .unwrap_or_else(|| Err("no residuals".to_string()))
                },
                |u: &[f64], r: &[f64], jac: &mut [f64]| {
                    // The sensitivities' coarser steps at this point; the residuals and
                    // differences keep the fit's, and so do the sensitivities where the
                    // coarser simulation fails (a fitted initial state far outside the data,
                    // whose burn-in the rates of `jacobian_stepping` do not foresee).
                    let coarse = self.jacobian_stepping(&layout.point(start, u));
                    let mut at = |st: &Stepping| {
                        self.jacobian(start, &layout, plan, st, &opts, u, r, jac, &residual_fn)
                    };
                    match at(&coarse) {
                        Err(_) if !same_stepping(&coarse, stepping) => at(stepping),
                        done => done,
                    }
                },
                &u0,
                n,
                &opts,
            ),
            None => levenberg_marquardt_batch(residual_fn, &u0, n, &opts),
        }
        .map_err(|e| {
            let names: Vec<&str> = slots.iter().map(|s| s.name()).collect();
            format!("{e}; {}", fit_advice(&e, &names))
        })?;
        let u = lm.params;
        // The Jacobian at the optimum, as the iteration formed it last (one-sided at a bound,
        // the other side where one fails to simulate).
        let jac = DMatrix::from_fn(n, np, |i, j| lm.jacobian[i][j]);
        let (se_u, inflation) = hac(&jac, &lm.residuals, &segment_lengths(&self.fit));
        let point = layout.point(start, &u);
        let mut values = Vec::with_capacity(slots.len());
        let mut stderr = Vec::with_capacity(slots.len());
        let mut at_bound = Vec::with_capacity(slots.len());
        for (i, &s) in slots.iter().enumerate() {
            let v = point.get(s);
            values.push(v);
            stderr.push(if layout.log[i] { v * se_u[i] } else { se_u[i] });
            let lower = bounds[i].0;
            at_bound.push(lower.is_finite() && u[i] <= lower + 1e-9 * typical[i]);
        }
        let rss = lm.cost;
        Ok(FitResult {
            point,
            slots: slots.to_vec(),
            values,
            stderr,
            at_bound,
            init: layout.init(&self.fit, &u),
            inflation: inflation[..slots.len()].to_vec(),
            rss,
            bic: bic(rss, n, np),
            stepping: stepping.clone(),
            evaluations: lm.evaluations,
            at_limit: lm.stop == LmStop::MaxIterations,
        })
    }
}

/// Whether two points are simulated with the same integration step (and so can share a
/// batch).
fn same_stepping(a: &Stepping, b: &Stepping) -> bool {
    match (a, b) {
        (Stepping::Fixed { substeps: x }, Stepping::Fixed { substeps: y }) => x == y,
        _ => false,
    }
}

/// Sub-steps per sample of a fixed stepping (an adaptive one counts as the finest).
fn substeps(s: &Stepping) -> usize {
    match s {
        Stepping::Fixed { substeps } => *substeps,
        Stepping::Adaptive(_) => usize::MAX,
    }
}

/// How a column of a fit's Jacobian is formed: the derivative of a model parameter or of a
/// segment's initial state from the simulation with sensitivities, the sensor's offset and
/// gain directly, or a forward difference.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Column {
    Model(Param),
    Initial {
        segment: usize,
        param: Param,
    },
    SensorOffset,
    SensorGain,
    /// The sensor's time constant, by differentiating its low-pass
    /// ([`Sensor::tau_derivative`]).
    SensorLag,
    Difference,
}

/// A parameter's derivative that the simulation with sensitivities carries, if any.
fn sensitivity_of(s: Slot) -> Option<Param> {
    Some(match s {
        Slot::M => Param::M,
        Slot::K => Param::K,
        Slot::C => Param::C,
        Slot::CF => Param::CF,
        Slot::X0 => Param::X0,
        Slot::InputOffset => Param::InputOffset,
        Slot::K3 => Param::K3,
        Slot::C2 => Param::C2,
        Slot::XStop => Param::XStop,
        Slot::KStop => Param::KStop,
        // A delay moves the force's time, an actuator lag filters it: their columns are forced
        // by the force's derivatives (`Force::rate`, `Force::tau_derivative`).
        Slot::Delay => Param::Delay,
        Slot::Tau => Param::Tau,
        // A sensor lag filters the output: its column is [`Column::SensorLag`].
        Slot::TauS => return None,
        // Friction and a damper threshold change the force law where the sensitivities do
        // not hold (`sim::sensitivities_hold`); `Context::columns` keeps differences then.
        Slot::Mu | Slot::VTh => return None,
        Slot::SensorB | Slot::SensorG => return None,
    })
}

impl Context<'_> {
    /// How each column of the Jacobian of a fit of `layout` from `start` is formed, or `None`
    /// to take forward differences of all of them: fixed steps, a model whose force is
    /// continuous across its guards at every point the fit can reach (no friction or damper
    /// threshold in it or free; an actuator lag acts on the force before the model reads it,
    /// see `MeasuredForce::drive`), and at least one column worth the simulation.
    fn columns(
        &self,
        start: &ModelPoint,
        layout: &Layout,
        stepping: &Stepping,
    ) -> Option<Vec<Column>> {
        let Stepping::Fixed { .. } = stepping else {
            return None;
        };
        let changes_law = |s: &Slot| matches!(s, Slot::Mu | Slot::VTh);
        let driven = Effects {
            tau: 0.0,
            ..start.effects
        };
        if !sensitivities_hold(&driven) || layout.slots.iter().any(changes_law) {
            return None;
        }
        let mut columns: Vec<Column> = layout
            .slots
            .iter()
            .map(|&s| match s {
                Slot::SensorB => Column::SensorOffset,
                Slot::SensorG => Column::SensorGain,
                Slot::TauS => Column::SensorLag,
                _ => sensitivity_of(s).map_or(Column::Difference, Column::Model),
            })
            .collect();
        for segment in 0..layout.n_init {
            columns.push(Column::Initial {
                segment,
                param: Param::Position,
            });
            columns.push(Column::Initial {
                segment,
                param: Param::Velocity,
            });
        }
        let integrated = |columns: &[Column]| {
            columns
                .iter()
                .filter(|c| matches!(c, Column::Model(_) | Column::Initial { .. }))
                .count()
        };
        // Over the cap, the delay's and the lag's columns are differenced first.
        if integrated(&columns) > MAX_SENSITIVITIES {
            for c in &mut columns {
                if matches!(c, Column::Model(Param::Delay | Param::Tau)) {
                    *c = Column::Difference;
                }
            }
        }
        // The sensor's lag needs the simulation's positions, not a column of its own.
        let simulated = integrated(&columns) + usize::from(columns.contains(&Column::SensorLag));
        (simulated > 0 && integrated(&columns) <= MAX_SENSITIVITIES).then_some(columns)
    }

    /// The Jacobian (`n x np`, column-major) of the fit residuals at `u`, where they are `r`,
    /// its columns formed as `plan` says: one simulation with sensitivities per segment at
    /// `stepping` (the fits pass [`Context::jacobian_stepping`]'s coarser one), passed
    /// through the sensor as the positions are (its low-pass and gain are linear), and
    /// forward differences (the batch of [`Context::residuals_batch`]) for the rest, with the
    /// step rule of the fits' difference Jacobians.
    #[allow(clippy::too_many_arguments)] // reason: the fit's layout, plan and options
    fn jacobian<R>(
        &self,
        start: &ModelPoint,
        layout: &Layout,
        plan: &[Column],
        stepping: &Stepping,
        opts: &LmOptions,
        u: &[f64],
        r: &[f64],
        jac: &mut [f64],
        residuals: &R,
    ) -> Result<(), String>
    where
        R: Fn(&[&[f64]], &mut [&mut [f64]]) -> Vec<Result<(), String>>,
    {
        let Stepping::Fixed { substeps } = stepping else {
            return Err("sensitivities need fixed steps".to_string());
        };
        let n = r.len();
        let point = layout.point(start, u);
        let model = self.hopper(&point)?;
        let force = model
            .force
            .as_ref()
            .ok_or_else(|| "the model reads no measured force".to_string())?;
        let inits = layout.init(&self.fit, u);
        let dt = self.record.dt();
        let sensor = point.sensor;
        let (mut positions, mut sens) = (Vec::new(), Vec::new());
        let mut at = 0;
        for (k, seg) in self.fit.iter().enumerate() {
            let len = seg.range.len();
            // This segment's simulated columns: the model's, and its own initial state's.
            let cols: Vec<(usize, Param)> = plan
                .iter()
                .enumerate()
                .filter_map(|(j, c)| match *c {
                    Column::Model(p) => Some((j, p)),
                    Column::Initial { segment, param } if segment == k => Some((j, param)),
                    _ => None,
                })
                .collect();
            let params: Vec<Param> = cols.iter().map(|&(_, p)| p).collect();
            positions.resize(len, 0.0);
            sens.resize(len * params.len(), 0.0);
            let t0 = self.record.time()[seg.range.start];
            simulate_sensitivities(
                &model.hopper,
                force,
                t0,
                inits[k],
                dt,
                *substeps,
                &params,
                &mut positions,
                &mut sens,
            )
            .map_err(|e| format!("t = {} s: {}", e.time, e.reason))?;
            // The sensor reads `y = b + g L(x)`, `L` its low-pass, which is linear: the
            // derivatives pass through `L` and `g` as the positions do, and `L(x)` is the
            // derivative by `g`.
            let low_pass = Sensor {
                b: 0.0,
                g: 1.0,
                ..sensor
            };
            // The lag's column, from the positions before the sensor.
            let lag = plan
                .contains(&Column::SensorLag)
                .then(|| sensor.tau_derivative(dt, &positions));
            low_pass.apply(dt, &mut positions);
            for column in sens.chunks_mut(len) {
                low_pass.apply(dt, column);
            }
            let scored = seg.skip..len;
            let rows = at..at + scored.len();
            for (j, c) in plan.iter().enumerate() {
                let out = &mut jac[j * n..(j + 1) * n][rows.clone()];
                match *c {
                    Column::SensorOffset => out.fill(1.0),
                    Column::SensorGain => out.copy_from_slice(&positions[scored.clone()]),
                    Column::SensorLag => {
                        let column =
                            &lag.as_deref().expect("computed for the plan")[scored.clone()];
                        // A time constant fitted as a logarithm: `d/du = v d/dv`.
                        let chain = if j < layout.slots.len() && layout.log[j] {
                            u[j].exp()
                        } else {
                            1.0
                        };
                        for (o, &d) in out.iter_mut().zip(column) {
                            *o = chain * d;
                        }
                    }
                    Column::Initial { segment, .. } if segment != k => out.fill(0.0),
                    Column::Model(_) | Column::Initial { .. } => {
                        let i = cols.iter().position(|&(jj, _)| jj == j).expect("listed");
                        let column = &sens[i * len..(i + 1) * len][scored.clone()];
                        // A scale parameter fitted as a logarithm: `d/du = v d/dv`.
                        let chain = sensor.g
                            * if j < layout.slots.len() && layout.log[j] {
                                u[j].exp()
                            } else {
                                1.0
                            };
                        for (o, &d) in out.iter_mut().zip(column) {
                            *o = chain * d;
                        }
                    }
                    Column::Difference => {}
                }
            }
            at += scored.len();
        }
        // The rest by forward differences, all points in one batch.
        let fd: Vec<usize> = (0..plan.len())
            .filter(|&j| plan[j] == Column::Difference)
            .collect();
        if fd.is_empty() {
            return Ok(());
        }
        let step = opts.fd_step.unwrap_or(FD_STEP);
        let typical = opts.scales.as_deref();
        let bounds = opts.bounds.as_deref();
        let mut points = Vec::with_capacity(fd.len());
        let mut steps = Vec::with_capacity(fd.len());
        for &j in &fd {
            let mut h = step * u[j].abs().max(typical.map_or(1.0, |t| t[j]));
            if bounds.is_some_and(|b| u[j] + h > b[j].1) {
                h = -h;
            }
            let mut p = u.to_vec();
            p[j] += h;
            points.push(p);
            steps.push(h);
        }
        let mut outs = vec![vec![0.0; n]; fd.len()];
        let refs: Vec<&[f64]> = points.iter().map(Vec::as_slice).collect();
        let mut out_refs: Vec<&mut [f64]> = outs.iter_mut().map(Vec::as_mut_slice).collect();
        for result in residuals(&refs, &mut out_refs) {
            result?;
        }
        for ((&j, h), moved) in fd.iter().zip(&steps).zip(&outs) {
            for (o, (a, b)) in jac[j * n..(j + 1) * n].iter_mut().zip(moved.iter().zip(r)) {
                *o = (a - b) / h;
            }
        }
        Ok(())
    }
}

/// `N ln(RSS / N) + p ln N`.
pub(crate) fn bic(rss: f64, n: usize, p: usize) -> f64 {
    let nf = n as f64;
    nf * (rss.max(f64::MIN_POSITIVE) / nf).ln() + p as f64 * nf.ln()
}

fn segment_lengths(segs: &[Segment]) -> Vec<usize> {
    segs.iter().map(|s| s.scored().len()).collect()
}

/// Standard errors of least-squares parameters that allow for serially correlated residuals:
/// the Newey-West (Bartlett-kernel) sandwich. With `A = (J^T J)^+` and the score series
/// `h_t = A J_t^T r_t`, the variance of parameter `i` is
/// `sum_{|k| <= L} (1 - |k|/(L+1)) sum_t h_{i,t} h_{i,t+k}`, lags never crossing a segment
/// boundary, `L = ceil(sqrt(n_segment))`. The result is never below the classical
/// `s^2 A_ii` (`s^2 = RSS / (N - p)`): white residuals keep the classical error, a model error
/// that leaves structured residuals can only widen it. A parameter the data do not determine
/// (a null direction of `J`) gets an infinite error.
#[cfg(test)]
pub(crate) fn hac_stderr(jac: &DMatrix<f64>, r: &[f64], seg_lens: &[usize]) -> Vec<f64> {
    hac(jac, r, seg_lens).0
}

/// [`hac_stderr`] and, per parameter, the factor `>= 1` by which the residuals' correlation
/// inflates its variance over the classical one (1 for an undetermined parameter).
pub(crate) fn hac(jac: &DMatrix<f64>, r: &[f64], seg_lens: &[usize]) -> (Vec<f64>, Vec<f64>) {
    let (n, p) = jac.shape();
    let jtj = jac.tr_mul(jac);
    // Scale to unit diagonal first: parameters differ in size by many orders (a contact
    // stiffness against a contact position), and a tolerance on the unscaled matrix would call
    // a well-determined small column undetermined.
    let d: Vec<f64> = (0..p)
        .map(|i| {
            let v = jtj[(i, i)];
            if v > 0.0 && v.is_finite() {
                1.0 / v.sqrt()
            } else {
                0.0
            }
        })
        .collect();
    let scaled = DMatrix::from_fn(p, p, |i, j| jtj[(i, j)] * d[i] * d[j]);
    // nalgebra's SVD panics on non-finite entries: no finite standard errors then.
    if !scaled.iter().all(|v| v.is_finite()) {
        return (vec![f64::INFINITY; p], vec![1.0; p]);
    }
    let svd = scaled.svd(true, true);
    let tol = 1e-12 * p as f64;
    let Ok(b) = svd.pseudo_inverse(tol) else {
        return (vec![f64::INFINITY; p], vec![1.0; p]);
    };
    let a = DMatrix::from_fn(p, p, |i, j| b[(i, j)] * d[i] * d[j]);
    // A direction with no information: its pseudo-inverse is zero, report it as unknown.
    let undetermined: Vec<bool> = (0..p)
        .map(|i| d[i] <= 0.0 || a[(i, i)].is_nan() || a[(i, i)] <= 0.0)
        .collect();
    let rss: f64 = r.iter().map(|v| v * v).sum();
    let s2 = rss / (n.saturating_sub(p)).max(1) as f64;
    let mut h = vec![0.0; n];
    let mut out = Vec::with_capacity(p);
    let mut inflation = Vec::with_capacity(p);
    for i in 0..p {
        if undetermined[i] {
            out.push(f64::INFINITY);
            inflation.push(1.0);
            continue;
        }
        for (t, ht) in h.iter_mut().enumerate() {
            let mut s = 0.0;
            for j in 0..p {
                s += a[(i, j)] * jac[(t, j)];
            }
            *ht = s * r[t];
        }
        let mut var = 0.0;
        let mut at = 0;
        for &len in seg_lens {
            let seg = &h[at..at + len];
            at += len;
            let lags = ((len as f64).sqrt().ceil() as usize).min(len.saturating_sub(1));
            var += dot(seg, seg);
            for k in 1..=lags {
                let w = 1.0 - k as f64 / (lags + 1) as f64;
                var += 2.0 * w * dot(&seg[..len - k], &seg[k..]);
            }
        }
        let classical = s2 * a[(i, i)];
        out.push(var.max(classical).sqrt());
        inflation.push(if classical > 0.0 {
            (var / classical).max(1.0)
        } else {
            1.0
        });
    }
    (out, inflation)
}

/// `sum a_i b_i` over the shorter of the two, in eight interleaved partial sums (which the
/// processor adds side by side, where one running sum waits on every addition).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail: f64 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in ca.zip(cb) {
        for i in 0..8 {
            acc[i] += x[i] * y[i];
        }
    }
    acc.iter().sum::<f64>() + tail
}

/// What to try when the output-error fit of the parameters `names` fails with `e`.
fn fit_advice(e: &htfid_estimate::Error, names: &[&str]) -> String {
    use htfid_estimate::Error;
    let list = names.join(", ");
    match e {
        Error::ResidualFailed { .. } | Error::NonFiniteResidual { .. } => format!(
            "the model cannot be simulated from the starting values of {list}: check the \
             configured parameters and their units, or start them nearer the data"
        ),
        Error::JacobianFailed { .. } => format!(
            "a parameter of {list} sits where a small change stops the simulation: bound it \
             away from there or start it elsewhere"
        ),
        Error::InvalidStart { .. } | Error::InvalidBounds { .. } => format!(
            "a starting value of {list} lies outside its physical range: check the configured \
             value and its sign"
        ),
        _ => format!(
            "check the scaling of {list} (values many decades apart) and their starting values"
        ),
    }
}

#[cfg(test)]
mod tests {

    #[test]
    fn a_failed_fit_says_what_to_try_for_each_kind_of_failure() {
        use htfid_estimate::Error;
        let cases = [
            (
                Error::ResidualFailed {
                    message: "t = 3 s: non-finite state".into(),
                },
                "cannot be simulated from the starting values of k3, tau",
            ),
            (
                Error::JacobianFailed {
                    index: 1,
                    value: 0.0,
                },
                "bound it",
            ),
            (
                Error::InvalidStart {
                    index: 0,
                    value: -1.0,
                    lower: 0.0,
                    upper: 1.0,
                },
                "its sign",
            ),
        ];
        for (e, want) in cases {
            let advice = fit_advice(&e, &["k3", "tau"]);
            assert!(advice.contains(want), "{e}: {advice}");
        }
    }
    use super::*;
    use approx::assert_relative_eq;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    /// The residuals' function of [`jacobian_case`] at a stepping.
    type CaseResiduals<'a> =
        dyn Fn(&Stepping, &[&[f64]], &mut [&mut [f64]]) -> Vec<Result<(), String>> + 'a;

    /// A record that crosses the damper switch and the contact many times, `dt` apart, with
    /// a model holding every effect the sensitivities carry, two fit segments, a sensor's
    /// offset, gain and low-pass, and a delay: `body` gets the context, the model, the fit's
    /// layout, its parameters `u` and their typical sizes, and the residuals' function at a
    /// stepping.
    fn jacobian_case(
        dt: f64,
        damper: DamperLaw,
        lag: bool,
        body: impl FnOnce(&Context<'_>, &ModelPoint, &Layout, &[f64], &[f64], &CaseResiduals<'_>),
    ) {
        use crate::interp::Interpolation;
        use htfid_model::HardStop;
        let n = 1500;
        let ts: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
        let fs: Vec<f64> = ts
            .iter()
            .map(|t| 3.0 * (1.3 * t).sin() + 1.5 * (4.1 * t + 0.3).sin() + 0.7 * (9.0 * t).cos())
            .collect();
        let xs: Vec<f64> = ts.iter().map(|t| 0.2 * (1.3 * t - 0.4).sin()).collect();
        let record = TimeSeries::new(ts, fs.clone(), xs, "test").unwrap();
        let segment = |range: Range<usize>| Segment {
            init: [0.05, -0.1],
            skip: 20,
            range,
        };
        let ctx = Context {
            record: &record,
            input: MeasuredForce::new(0.0, dt, &fs, Interpolation::CubicSpline),
            damper,
            method: SimMethod::FixedStep { max_rate_step: 0.2 },
            extent: Extent {
                x_min: -0.3,
                x_max: 0.3,
                v_max: 1.0,
            },
            scales: Scales {
                x_std: 0.15,
                v_std: 0.3,
                f_std: 2.0,
            },
            fit: vec![segment(0..700), segment(700..1500)],
            validation: Vec::new(),
            fit_initial_state: true,
            max_iterations: 10,
            fit_tolerance: 0.01,
            forcing_period: None,
            mass_range: (1e-3, 1e3),
        };
        let start = ModelPoint {
            params: HopperParams {
                m: 1.2,
                k: 20.0,
                c: 0.8,
                g: 9.81,
                x0: 0.4,
                forcing_amplitude: 0.0,
                period: 1.0,
            },
            effects: Effects {
                k3: 30.0,
                c_f: 0.3,
                c2: 0.5,
                input_offset: 0.2,
                delay: 0.013,
                tau: if lag { 0.03 } else { 0.0 },
                hard_stop: Some(HardStop {
                    x_stop: 0.02,
                    k_stop: 60.0,
                }),
                ..Effects::default()
            },
            sensor: Sensor {
                tau_s: 0.02,
                b: 0.01,
                g: 1.1,
            },
        };
        // Every slot the sensitivities carry; with the actuator's lag, its time constant and
        // fewer of the others (at most `MAX_SENSITIVITIES` simulated columns).
        let slots = if lag {
            vec![
                Slot::M,
                Slot::K,
                Slot::C,
                Slot::X0,
                Slot::InputOffset,
                Slot::XStop,
                Slot::SensorG,
                Slot::TauS,
                Slot::Delay,
                Slot::Tau,
            ]
        } else {
            vec![
                Slot::M,
                Slot::K,
                Slot::C,
                Slot::CF,
                Slot::X0,
                Slot::InputOffset,
                Slot::K3,
                Slot::C2,
                Slot::XStop,
                Slot::KStop,
                Slot::SensorB,
                Slot::SensorG,
                Slot::TauS,
                Slot::Delay,
            ]
        };
        let layout = Layout {
            log: slots.iter().map(|s| s.log_scaled()).collect(),
            slots,
            n_init: 2,
        };
        let mut u: Vec<f64> = layout
            .slots
            .iter()
            .zip(&layout.log)
            .map(|(&s, &log)| if log { start.get(s).ln() } else { start.get(s) })
            .collect();
        u.extend([0.01, -0.02, 0.0, 0.03]);
        let typical: Vec<f64> = layout
            .slots
            .iter()
            .zip(&layout.log)
            .map(|(&s, &log)| if log { 1.0 } else { ctx.typical(s, &start) })
            .chain([0.01, 0.01, 0.01, 0.01])
            .collect();
        let residuals = |stepping: &Stepping, points: &[&[f64]], outs: &mut [&mut [f64]]| {
            points
                .iter()
                .zip(outs.iter_mut())
                .map(|(u, out)| {
                    let model = ctx.hopper(&layout.point(&start, u))?;
                    let init = layout.init(&ctx.fit, u);
                    ctx.residuals(&model, &ctx.fit, &init, stepping, out)
                        .map_err(|e| e.reason)
                })
                .collect::<Vec<Result<(), String>>>()
        };
        body(&ctx, &start, &layout, &u, &typical, &residuals);
    }

    /// The Jacobian of [`jacobian_case`] at `stepping`, its residuals' differences at
    /// `difference_stepping` (column-major), with its plan.
    fn case_jacobian(
        ctx: &Context<'_>,
        start: &ModelPoint,
        layout: &Layout,
        u: &[f64],
        typical: &[f64],
        residuals: &CaseResiduals<'_>,
        stepping: &Stepping,
        difference_stepping: &Stepping,
    ) -> (Vec<Column>, Vec<f64>) {
        let plan = ctx
            .columns(start, layout, stepping)
            .expect("sensitivities hold");
        let m = ctx.n_fit();
        let at = |points: &[&[f64]], outs: &mut [&mut [f64]]| {
            residuals(difference_stepping, points, outs)
        };
        let mut r = vec![0.0; m];
        at(&[u], &mut [&mut r])[0].clone().unwrap();
        let opts = LmOptions {
            fd_step: Some(1e-7),
            scales: Some(typical.to_vec()),
            ..LmOptions::default()
        };
        let mut jac = vec![0.0; m * u.len()];
        ctx.jacobian(start, layout, &plan, stepping, &opts, u, &r, &mut jac, &at)
            .unwrap();
        (plan, jac)
    }

    /// Central differences (step `1e-5` typical sizes) of [`jacobian_case`]'s residuals at
    /// `stepping`, column-major: the plain simulation, a second method.
    fn central_differences(
        residuals: &CaseResiduals<'_>,
        stepping: &Stepping,
        u: &[f64],
        typical: &[f64],
        m: usize,
    ) -> Vec<f64> {
        let mut out = vec![0.0; m * u.len()];
        for (j, column) in out.chunks_mut(m).enumerate() {
            let h = 1e-5 * u[j].abs().max(typical[j]);
            let (mut up, mut down) = (u.to_vec(), u.to_vec());
            up[j] += h;
            down[j] -= h;
            let (mut ru, mut rd) = (vec![0.0; m], vec![0.0; m]);
            for result in residuals(stepping, &[&up, &down], &mut [&mut ru, &mut rd]) {
                result.unwrap();
            }
            for (o, (a, b)) in column.iter_mut().zip(ru.iter().zip(&rd)) {
                *o = (a - b) / (2.0 * h);
            }
        }
        out
    }

    /// The largest magnitude in `v`.
    fn largest(v: &[f64]) -> f64 {
        v.iter().fold(0.0_f64, |a, x| a.max(x.abs()))
    }

    /// The largest magnitude of `a - b`, entry by entry.
    fn largest_difference(a: &[f64], b: &[f64]) -> f64 {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0_f64, f64::max)
    }

    /// The Jacobian from forward sensitivities against central differences of the residuals
    /// (the plain simulation, a second method), column by column, for every parameter the
    /// sensitivities carry, both segments' initial states, the sensor's offset, gain and
    /// low-pass (its time constant's column from the low-pass's own derivative), a delay, an
    /// actuator's lag (in a second case with fewer columns) and both damper laws, on a
    /// record that
    /// crosses the damper switch and the contact many times.
    ///
    /// Tolerance: `1e-6` of the column's largest entry. At 16 sub-steps per sample
    /// (`omega h = 0.02` at most) the integrated variational equation and the derivative of
    /// the discrete map differ by about RK4's relative error, `(omega h)^4 / 120 = 1e-9`; the
    /// central difference of step `1e-5` typical sizes leaves a truncation error that
    /// measured 6e-8 at most (it falls a hundredfold from a step of `1e-4`, so it is the
    /// difference's, not the sensitivities'), and a rounding error near `1e-11`. A term left
    /// out of a derivative, or a contact's stiffness taken on the wrong side of its edge at a
    /// split step (5e-4 before the side became part of the chart), is far larger. (A column
    /// still differenced would be a forward difference of step `1e-7`, the fits' own: `1e-5`.)
    /// (`c_f` acts only while the damper is off: its column is zero with it always on.)
    #[test]
    fn forward_sensitivities_give_the_jacobian_of_the_simulated_residuals() {
        for damper in [DamperLaw::Switching, DamperLaw::AlwaysOn] {
            for lag in [false, true] {
                jacobian_case(
                    0.01,
                    damper,
                    lag,
                    |ctx, start, layout, u, typical, residuals| {
                        let stepping = Stepping::Fixed { substeps: 16 };
                        let (plan, jac) = case_jacobian(
                            ctx, start, layout, u, typical, residuals, &stepping, &stepping,
                        );
                        assert_eq!(
                            plan.last(),
                            Some(&Column::Initial {
                                segment: 1,
                                param: Param::Velocity
                            })
                        );
                        assert!(plan.contains(&Column::SensorLag), "{plan:?}");
                        let m = ctx.n_fit();
                        let truth = central_differences(residuals, &stepping, u, typical, m);
                        for j in 0..u.len() {
                            let column = &jac[j * m..(j + 1) * m];
                            let scale = largest(column);
                            let worst = largest_difference(column, &truth[j * m..(j + 1) * m]);
                            assert!(
                                scale > 0.0 || plan[j] == Column::Model(Param::CF),
                                "{damper:?} column {j} ({:?}) is zero",
                                plan[j]
                            );
                            let tolerance = if plan[j] == Column::Difference {
                                1e-5
                            } else {
                                1e-6
                            };
                            assert!(
                                worst <= tolerance * scale,
                                "{damper:?} column {j} ({:?}): off by {worst:.3e} of {scale:.3e}",
                                plan[j]
                            );
                        }
                        // The delay's column and, with the actuator's lag, the lag's are forced by the
                        // force's derivatives, not differenced.
                        assert!(plan.contains(&Column::Model(Param::Delay)), "{plan:?}");
                        assert_eq!(lag, plan.contains(&Column::Model(Param::Tau)), "{plan:?}");
                    },
                );
            }
        }
    }

    /// The fits' Jacobian, simulated at the coarser steps of [`Context::jacobian_stepping`],
    /// against central differences of the plain simulation at eight times the fit's own
    /// sub-steps (a second method, at a step whose own error is negligible), on a record
    /// sampled so coarsely that the oscillation sets the step (`omega dt` near 0.8).
    ///
    /// Tolerance: `TOL` of the column's largest entry. At `omega h <= 0.4` RK4's phase error
    /// is about `(omega h)^4 / 120 = 2e-4` per radian, and the motion remembers its past for
    /// `omega / decay`, here about 16 radians (`omega` near 11 rad/s, the dampers' decay near
    /// 0.7 per second): a few parts in a thousand. An unstable or wrongly switched coarse
    /// simulation is off by the column's whole size.
    #[test]
    fn the_jacobians_coarser_steps_stay_within_rk4s_error_of_fine_ones() {
        const TOL: f64 = 1e-2;
        for damper in [DamperLaw::Switching, DamperLaw::AlwaysOn] {
            jacobian_case(
                0.07,
                damper,
                false,
                |ctx, start, layout, u, typical, residuals| {
                    let fit = ctx.stepping(start);
                    let coarse = ctx.jacobian_stepping(start);
                    let (Stepping::Fixed { substeps: s_fit }, Stepping::Fixed { substeps: s_jac }) =
                        (&fit, &coarse)
                    else {
                        panic!("fixed steps expected");
                    };
                    assert!(s_jac < s_fit, "{s_jac} sub-steps against the fit's {s_fit}");
                    let fine = Stepping::Fixed {
                        substeps: 8 * s_fit,
                    };
                    let (plan, jac) =
                        case_jacobian(ctx, start, layout, u, typical, residuals, &coarse, &fit);
                    let m = ctx.n_fit();
                    let reference = central_differences(residuals, &fine, u, typical, m);
                    let mut worst_all = 0.0_f64;
                    for (j, c) in plan.iter().enumerate() {
                        let column = &jac[j * m..(j + 1) * m];
                        let truth = &reference[j * m..(j + 1) * m];
                        let scale = largest(truth);
                        if scale == 0.0 {
                            continue;
                        }
                        let worst = largest_difference(column, truth);
                        worst_all = worst_all.max(worst / scale);
                        assert!(
                            worst <= TOL * scale,
                            "{damper:?} column {j} ({c:?}): off by {worst:.3e} of {scale:.3e}"
                        );
                    }
                    eprintln!(
                        "{damper:?}: {s_jac} against {s_fit} sub-steps, worst {worst_all:.2e}"
                    );
                },
            );
        }
    }

    #[test]
    fn hac_matches_the_classical_error_for_white_residuals_and_widens_for_correlated_ones() {
        // Straight-line fit y = a + b t. For white noise the sandwich and the classical error
        // agree to sampling error (about 1/sqrt(L) relative; 15 % allows it), and the classical
        // error of the intercept is s / sqrt(n) exactly for a centred regressor.
        let n = 4000;
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let normal = Normal::new(0.0, 1.0).unwrap();
        let jac = DMatrix::from_fn(n, 2, |t, j| {
            if j == 0 {
                1.0
            } else {
                (t as f64 - (n - 1) as f64 / 2.0) / n as f64
            }
        });
        let white: Vec<f64> = (0..n).map(|_| normal.sample(&mut rng)).collect();
        let se = hac_stderr(&jac, &white, &[n]);
        let s = (white.iter().map(|v| v * v).sum::<f64>() / (n - 2) as f64).sqrt();
        assert_relative_eq!(se[0], s / (n as f64).sqrt(), max_relative = 0.15);
        // AR(1) residuals with coefficient 0.9 inflate the variance of a mean by
        // (1 + 0.9) / (1 - 0.9) = 19, so the error grows by about sqrt(19) = 4.4; the
        // truncated kernel recovers most of it: require more than a factor 2.5.
        let mut e = 0.0;
        let ar: Vec<f64> = (0..n)
            .map(|_| {
                e = 0.9 * e + normal.sample(&mut rng);
                e
            })
            .collect();
        let se_ar = hac_stderr(&jac, &ar, &[n]);
        let s_ar = (ar.iter().map(|v| v * v).sum::<f64>() / (n - 2) as f64).sqrt();
        assert!(se_ar[0] > 2.5 * s_ar / (n as f64).sqrt(), "{}", se_ar[0]);
    }
}
