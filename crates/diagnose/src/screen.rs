//! Equation-error screening: starting values from a regression of the residual acceleration.
//!
//! The measured position is smoothed and differentiated (Savitzky-Golay); the model's
//! acceleration is evaluated on the smoothed states with the measured force, and the
//! difference is regressed on the derivatives of the acceleration with respect to the
//! parameters (finite differences of the model's own vector field). Parameters that do not
//! enter linearly near zero (a switching threshold, a contact position) are searched on a grid.

use htfid_estimate::golden_min;
use htfid_hybrid::HybridSystem;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use crate::deriv::{savitzky_golay, Kinematics};
use crate::effect::Slot;
use crate::fit::{Context, ModelPoint, Segment};
use crate::ranges::windows;
use crate::Effect;

/// Most samples used by the regression (evenly thinned beyond).
const MAX_SAMPLES: usize = 20_000;

#[derive(Debug)]
pub(crate) struct Screening<'c, 'a> {
    ctx: &'c Context<'a>,
    samples: Vec<(f64, Kinematics)>,
    /// Half-width (samples) of the smoothing window.
    half: usize,
}

impl<'c, 'a> Screening<'c, 'a> {
    pub(crate) fn new(ctx: &'c Context<'a>, half: usize) -> Self {
        let t = ctx.record.time();
        let x = ctx.record.output();
        let mut samples = Vec::new();
        for seg in &ctx.fit {
            let r = seg.scored();
            for (k, kin) in savitzky_golay(x, r.start, r.end, ctx.record.dt(), half, 4) {
                samples.push((t[k], kin));
            }
        }
        let stride = samples.len().div_ceil(MAX_SAMPLES).max(1);
        let samples = samples.into_iter().step_by(stride).collect();
        Screening { ctx, samples, half }
    }

    /// Smoothed kinematics (for the data's extent).
    pub(crate) fn samples(&self) -> &[(f64, Kinematics)] {
        &self.samples
    }

    /// Model accelerations at the smoothed states (the lag state is not modelled here).
    fn accelerations(&self, p: &ModelPoint) -> Option<Vec<f64>> {
        let mut p = *p;
        p.effects.tau = 0.0;
        let hopper = self.ctx.hopper(&p).ok()?.hopper;
        let mut d = [0.0; 2];
        Some(
            self.samples
                .iter()
                .map(|&(t, k)| {
                    hopper.vector_field(hopper.mode_of(k.v), t, &[k.x, k.v], &mut d);
                    d[1]
                })
                .collect(),
        )
    }

    /// Least squares of the residual acceleration on the acceleration's sensitivities to
    /// `slots`: the corrections and the residual sum of squares.
    fn regress(&self, p: &ModelPoint, slots: &[Slot]) -> Option<(Vec<f64>, f64)> {
        let a0 = self.accelerations(p)?;
        let y: Vec<f64> = self
            .samples
            .iter()
            .zip(&a0)
            .map(|((_, k), a)| k.a - a)
            .collect();
        if slots.is_empty() {
            return Some((Vec::new(), y.iter().map(|v| v * v).sum()));
        }
        let n = y.len();
        if n <= slots.len() {
            return None;
        }
        let mut x = DMatrix::zeros(n, slots.len());
        for (j, &s) in slots.iter().enumerate() {
            let v = p.get(s);
            let h = 1e-6 * v.abs().max(self.typical(s, p));
            let mut q = *p;
            q.set(s, v + h);
            let a1 = self.accelerations(&q)?;
            for i in 0..n {
                x[(i, j)] = (a1[i] - a0[i]) / h;
            }
        }
        let yv = DVector::from_vec(y);
        // nalgebra's SVD panics on non-finite entries: such a regression has no answer.
        if !(x.iter().all(|v| v.is_finite()) && yv.iter().all(|v| v.is_finite())) {
            return None;
        }
        let beta = x.clone().svd(true, true).solve(&yv, 1e-12).ok()?;
        let rss = (&yv - &x * &beta).norm_squared();
        Some((beta.iter().copied().collect(), rss))
    }

    fn typical(&self, s: Slot, p: &ModelPoint) -> f64 {
        let sc = &self.ctx.scales;
        let force = (p.params.k * sc.x_std).max(sc.f_std);
        match s {
            Slot::M | Slot::K | Slot::C | Slot::X0 | Slot::InputOffset => 1e-3,
            Slot::K3 => force / sc.x_std.powi(3),
            Slot::Mu => force,
            Slot::CF => force / sc.v_std,
            Slot::C2 => force / (sc.v_std * sc.v_std),
            Slot::Tau | Slot::Delay => self.ctx.record.dt(),
            Slot::VTh => sc.v_std,
            Slot::XStop => sc.x_std,
            Slot::KStop => p.params.k,
            Slot::TauS => self.ctx.record.dt(),
            Slot::SensorB => sc.x_std,
            Slot::SensorG => 1e-3,
        }
    }

    /// Refines the free parameters of the nominal model by a few Gauss-Newton steps of the
    /// equation error (each change limited to a factor 3 for positive parameters).
    pub(crate) fn refine_nominal(&self, p: &ModelPoint, free: &[Slot]) -> ModelPoint {
        let mut q = *p;
        for _ in 0..5 {
            let Some((beta, _)) = self.regress(&q, free) else {
                break;
            };
            for (&s, &b) in free.iter().zip(&beta) {
                let v = q.get(s);
                q.set(s, limited(s, v, v + b));
            }
        }
        q
    }

    /// Starting points for `effect`: one from [`Screening::start`], except for the two effects
    /// whose cost has several minima.
    ///
    /// - A switching threshold changes the force only while `|x'| < |v_th|`, too briefly for the
    ///   smoothed acceleration to resolve, and its effect grows about quadratically on both
    ///   sides of zero: the best threshold of each sign on a grid of output-error costs starts a
    ///   fit of its own, and so does the best on short windows of the record
    ///   ([`Screening::threshold_on_windows`]), for a threshold among the speed's extremes.
    /// - A contact position: for each of a grid of low quantiles of the position, the contact
    ///   stiffness comes from the regression; the two grid points of lowest output-error cost
    ///   start fits.
    /// - A lag or delay: beside the regression's first-order estimate, a grid across decades
    ///   (0.3 to 1000 sample intervals, up to a tenth of the record) is scored by output error;
    ///   the best start fits, and so does the best one at least a factor 3 away from it.
    /// - Any other effect starts from the regression ([`Screening::start`]); where that start
    ///   fits the record worse than `base` itself (the effect absent), from `base` as well.
    pub(crate) fn starts(
        &self,
        base: &ModelPoint,
        free: &[Slot],
        effect: Effect,
    ) -> Vec<ModelPoint> {
        // Grid points with their side (a threshold's sign; 0 where all compete), scored by
        // output-error cost in parallel below.
        let mut grid: Vec<(ModelPoint, i8)> = Vec::new();
        match effect {
            Effect::SwitchThreshold => {
                // Thresholds up to nine tenths of the largest measured speed: a threshold
                // close to it (the damper off only near the fastest motion) changes the force
                // on the whole stroke.
                let v_max = self.ctx.extent.v_max;
                let v0 = base.get(Slot::VTh);
                for q in [0.01, 0.03, 0.06, 0.1, 0.16, 0.25, 0.35, 0.5, 0.65, 0.8, 0.9] {
                    for side in [-1i8, 1] {
                        let mut p = *base;
                        p.set(Slot::VTh, v0 + f64::from(side) * q * v_max);
                        grid.push((p, side));
                    }
                }
            }
            Effect::HardStop => {
                let mut xs: Vec<f64> = self.samples.iter().map(|(_, k)| k.x).collect();
                xs.sort_by(f64::total_cmp);
                if let (Some(&lowest), false) = (xs.first(), xs.is_empty()) {
                    let quantiles = [0.0, 0.002, 0.005, 0.01, 0.02, 0.035, 0.05, 0.1, 0.2, 0.3];
                    for (i, q) in quantiles.into_iter().enumerate() {
                        let x_stop = if i == 0 {
                            lowest
                        } else {
                            xs[((xs.len() - 1) as f64 * q) as usize]
                        };
                        let mut p = *base;
                        p.set(Slot::XStop, x_stop);
                        p.set(Slot::KStop, 0.0);
                        let mut slots = free.to_vec();
                        slots.push(Slot::KStop);
                        let regressed = self
                            .regress(&p, &slots)
                            .map(|(b, _)| b[free.len()])
                            .filter(|k| *k > 0.0);
                        // The smoothed acceleration blurs a brief, stiff contact, so the
                        // regression's stiffness competes with stiffnesses across decades of
                        // the spring's.
                        let k = p.params.k;
                        for k_stop in regressed
                            .into_iter()
                            .chain([0.1 * k, k, 10.0 * k, 100.0 * k])
                        {
                            p.set(Slot::KStop, k_stop);
                            // Every grid point competes with every other: side 0.
                            grid.push((p, 0));
                        }
                    }
                }
            }
            Effect::ActuatorLag | Effect::InputDelay | Effect::SensorLag => {
                let slot = lag_slot(effect);
                grid.push((self.start(base, free, effect), 0));
                // Lags and delays across decades, up to a tenth of the record.
                let dt = self.ctx.record.dt();
                let longest = 0.1 * dt * self.ctx.record.len() as f64;
                for steps in [0.3, 1.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1000.0] {
                    let v = steps * dt;
                    if v > longest {
                        break;
                    }
                    let mut p = *base;
                    p.set(slot, v);
                    grid.push((p, 0));
                }
            }
            _ => {
                // The regression's start can lie in another basin than the model before it
                // (a cubic spring regressed beside a contact whose fit is still settling):
                // where it fits worse than that model, a second fit starts from the model
                // itself, with the effect absent, so that the better of the two can only
                // improve on it. The regression's start stays: from a worse start a fit can
                // still find the better optimum (a wrong stiffness beside a contact).
                let regressed = self.start(base, free, effect);
                let worse = match (self.ctx.fit_cost(&regressed), self.ctx.fit_cost(base)) {
                    (Some(r), Some(b)) => r > b,
                    (None, Some(_)) => true,
                    _ => false,
                };
                return if worse {
                    vec![regressed, *base]
                } else {
                    vec![regressed]
                };
            }
        }
        let points: Vec<ModelPoint> = grid.iter().map(|(p, _)| *p).collect();
        let mut scored: Vec<(f64, ModelPoint, i8)> = self
            .ctx
            .ranking_costs(&points, self.grid_samples(base))
            .into_iter()
            .zip(grid)
            .filter_map(|(c, (p, side))| c.map(|c| (c, p, side)))
            .collect();
        scored.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut starts: Vec<ModelPoint> = Vec::new();
        match effect {
            Effect::SwitchThreshold => {
                for side in [-1i8, 1] {
                    if let Some((_, p, _)) = scored.iter().find(|s| s.2 == side) {
                        starts.push(*p);
                    }
                }
                if let Some(p) = self.threshold_on_windows(base) {
                    starts.push(p);
                }
            }
            Effect::ActuatorLag | Effect::InputDelay | Effect::SensorLag => {
                // The best start, and the best one at least a factor 3 away from it (another
                // basin), if any.
                let slot = lag_slot(effect);
                if let Some(&(_, best, _)) = scored.first() {
                    starts.push(best);
                    let b = best.get(slot);
                    if let Some(&(_, other, _)) = scored.iter().find(|s| {
                        let v = s.1.get(slot);
                        v > 3.0 * b || 3.0 * v < b
                    }) {
                        starts.push(other);
                    }
                }
            }
            _ => starts.extend(scored.iter().take(2).map(|s| s.1)),
        }
        if starts.is_empty() {
            starts.push(self.start(base, free, effect));
        }
        starts
    }

    /// The switching threshold of least error on short windows of the record, each simulated
    /// from the data's own state at its start (two natural periods long).
    ///
    /// Where the threshold lies among the velocity's extremes (a large threshold, reached in
    /// some periods and not in others), whether a period switches decides the motion after
    /// it, and the output error over the whole record is rough in the threshold: minima a
    /// fraction of a percent of the threshold wide, which no grid finds. On short windows the
    /// error cannot compound and is smooth: thresholds at 16 quantiles of each sign's measured
    /// speeds are scored on the windows, and the best is refined by golden-section search
    /// between its neighbours. The windows start from smoothed states and leave the answer a
    /// few tenths of a percent off, still outside the record's narrow minimum: it is polished
    /// on a grid of the whole record's error spanning 1 % of the threshold either side, in
    /// steps of a twelfth of a percent. `None` when there is nothing to score.
    fn threshold_on_windows(&self, base: &ModelPoint) -> Option<ModelPoint> {
        const QUANTILES: usize = 16;
        const GOLDEN_STEPS: usize = 16;
        const FINE_STEPS: usize = 24;
        let windows = windows(
            self.ctx.record,
            &self.ctx.fit,
            self.window_len(base),
            self.half,
        );
        if windows.is_empty() {
            return None;
        }
        let cost = |v: f64| {
            let mut p = *base;
            p.set(Slot::VTh, v);
            self.window_cost(&p, &windows).unwrap_or(f64::INFINITY)
        };
        // Candidate thresholds: quantiles of each sign's speeds, in increasing order.
        let mut grid: Vec<f64> = Vec::new();
        for side in [-1.0f64, 1.0] {
            let mut speeds: Vec<f64> = self
                .samples
                .iter()
                .map(|(_, k)| side * k.v)
                .filter(|v| *v > 0.0 && v.is_finite())
                .collect();
            if speeds.len() < QUANTILES {
                continue;
            }
            speeds.sort_by(f64::total_cmp);
            for i in 0..QUANTILES {
                let q = (i as f64 + 0.5) / QUANTILES as f64;
                grid.push(side * speeds[((speeds.len() - 1) as f64 * q) as usize]);
            }
        }
        grid.push(0.0);
        grid.sort_by(f64::total_cmp);
        grid.dedup();
        let costs: Vec<f64> = grid.par_iter().map(|&v| cost(v)).collect();
        let (best, &best_cost) = costs.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1))?;
        if !best_cost.is_finite() {
            return None;
        }
        // Golden-section search between the best grid point's neighbours, GOLDEN_STEPS steps.
        let lo = if best > 0 { grid[best - 1] } else { grid[best] };
        let hi = grid.get(best + 1).copied().unwrap_or(grid[best]);
        let shrink = (0.5 * (5f64.sqrt() - 1.0)).powi(GOLDEN_STEPS as i32);
        let (v, c) = golden_min(cost, lo, hi, (1.0 + 1e-9) * shrink * (hi - lo));
        let v_best = if c < best_cost { v } else { grid[best] };
        // The whole record's error is rough in a large threshold: the window's answer, a
        // little off from the smoothed starting states, is polished on a fine grid of the
        // record's own error around it.
        let span = 0.01 * v_best.abs().max(0.1 * self.ctx.scales.v_std);
        let fine: Vec<f64> = (0..=FINE_STEPS)
            .map(|i| v_best + span * (2.0 * i as f64 / FINE_STEPS as f64 - 1.0))
            .collect();
        let polished = fine
            .par_iter()
            .filter_map(|&v| {
                let mut p = *base;
                p.set(Slot::VTh, v);
                self.ctx.fit_cost(&p).map(|c| (c, p))
            })
            .min_by(|a, b| a.0.total_cmp(&b.0))?;
        Some(polished.1)
    }

    /// Scored samples a grid of starting points is ranked on: the leading [`GRID_PERIODS`]
    /// periods of the fit ranges (the longer of `base`'s natural period and the forcing
    /// period), at least [`GRID_MIN_SAMPLES`]. The grid only picks where fits start, which
    /// then run over the whole fit ranges.
    fn grid_samples(&self, base: &ModelPoint) -> usize {
        let natural = natural_period(base).unwrap_or(0.0);
        let period = natural.max(self.ctx.forcing_period.unwrap_or(0.0));
        let n = GRID_PERIODS * period / self.ctx.record.dt();
        if n.is_finite() && n > 0.0 {
            (n as usize).max(GRID_MIN_SAMPLES)
        } else {
            usize::MAX
        }
    }

    /// Samples in a window of two natural periods of `base` (of the forcing period, or 100
    /// samples, where it has no natural period), between 10 and 2000.
    fn window_len(&self, base: &ModelPoint) -> usize {
        let dt = self.ctx.record.dt();
        let period =
            natural_period(base).unwrap_or_else(|| self.ctx.forcing_period.unwrap_or(100.0 * dt));
        ((2.0 * period / dt).round() as usize).clamp(10, 2000)
    }

    /// Held-out RMS errors of `before` and `after` on windows of the held-out ranges, two
    /// natural periods of `before` long, each simulated from the data's smoothed state with
    /// that state's error projected out ([`Screening::window_cost`]): a prediction a few
    /// periods ahead, whose error cannot compound over the held-out range. `None` without
    /// windows or where either model cannot be simulated on them.
    pub(crate) fn held_out_on_windows(
        &self,
        before: &ModelPoint,
        after: &ModelPoint,
    ) -> Option<(f64, f64)> {
        let windows = windows(
            self.ctx.record,
            &self.ctx.validation,
            self.window_len(before),
            self.half,
        );
        let n: usize = windows.iter().map(|w| w.scored().len()).sum();
        if n == 0 {
            return None;
        }
        let (b, a) = rayon::join(
            || self.window_cost(before, &windows),
            || self.window_cost(after, &windows),
        );
        let rms = |c: f64| (c / n as f64).sqrt();
        Some((rms(b?), rms(a?)))
    }

    /// Output error on `windows` with each window's error in its starting state taken out:
    /// the residual of every window is projected off its sensitivities to the starting
    /// position and velocity (finite differences, simulated beside it), which a small error
    /// in the starting state adds to first order. The data's state at a window's start is
    /// smoothed and slightly off; uncorrected, that error would outweigh the threshold's.
    fn window_cost(&self, p: &ModelPoint, windows: &[Segment]) -> Option<f64> {
        let driven = self.ctx.hopper(p).ok()?;
        let stepping = self.ctx.stepping(p);
        let sc = &self.ctx.scales;
        let (hx, hv) = (1e-4 * sc.x_std.max(1e-12), 1e-4 * sc.v_std.max(1e-12));
        let inits: [Vec<[f64; 2]>; 3] = [
            windows.iter().map(|s| s.init).collect(),
            windows
                .iter()
                .map(|s| [s.init[0] + hx, s.init[1]])
                .collect(),
            windows
                .iter()
                .map(|s| [s.init[0], s.init[1] + hv])
                .collect(),
        ];
        let n: usize = windows.iter().map(|s| s.scored().len()).sum();
        let [mut r0, mut rx, mut rv] = [(); 3].map(|()| vec![0.0; n]);
        let done = self.ctx.residuals_batch(
            &[Some(&driven); 3],
            windows,
            &[&inits[0], &inits[1], &inits[2]],
            &stepping,
            &mut [r0.as_mut_slice(), rx.as_mut_slice(), rv.as_mut_slice()],
        );
        if done.iter().any(Result::is_err) {
            return None;
        }
        let mut total = 0.0;
        let mut at = 0;
        for w in windows {
            let span = at..at + w.scored().len();
            at = span.end;
            // Least squares on the two sensitivities by their 2x2 normal equations.
            let (mut s11, mut s12, mut s22, mut b1, mut b2, mut rr) =
                (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
            for i in span {
                let (f1, f2, ri) = (rx[i] - r0[i], rv[i] - r0[i], r0[i]);
                s11 += f1 * f1;
                s12 += f1 * f2;
                s22 += f2 * f2;
                b1 += f1 * ri;
                b2 += f2 * ri;
                rr += ri * ri;
            }
            let det = s11 * s22 - s12 * s12;
            let explained = if det > 1e-12 * s11 * s22 && det > 0.0 {
                (s22 * b1 * b1 - 2.0 * s12 * b1 * b2 + s11 * b2 * b2) / det
            } else {
                0.0
            };
            total += (rr - explained).max(0.0);
        }
        total.is_finite().then_some(total)
    }

    /// A starting point for `effect`: the nominal fit with the effect's parameters from the
    /// regression (free nominal parameters regressed jointly but kept at their fitted values).
    pub(crate) fn start(&self, base: &ModelPoint, free: &[Slot], effect: Effect) -> ModelPoint {
        let mut p = *base;
        let dt = self.ctx.record.dt();
        let joint = |p: &ModelPoint, extra: &[Slot]| {
            let mut slots = free.to_vec();
            slots.extend_from_slice(extra);
            self.regress(p, &slots)
                .map(|(b, rss)| (b[free.len()..].to_vec(), rss))
        };
        match effect {
            Effect::SwitchThreshold => {
                // A threshold changes the force only while |x'| < |v_th|, too briefly for the
                // smoothed acceleration to resolve: searched in [`Screening::starts`].
            }
            Effect::HardStop => {
                // Searched on a grid of contact positions in [`Screening::starts`]; this is
                // the fallback: contact at the lowest smoothed position.
                let x_low = self
                    .samples
                    .iter()
                    .map(|(_, k)| k.x)
                    .fold(f64::INFINITY, f64::min);
                p.set(Slot::XStop, if x_low.is_finite() { x_low } else { 0.0 });
                p.set(Slot::KStop, 0.1 * p.params.k);
            }
            Effect::ActuatorLag | Effect::InputDelay | Effect::SensorLag => {
                // To first order a lag and a delay of the force both shift it by `-tau f'`,
                // and a sensor's lag shifts the reading by about as much.
                let b = joint(&p, &[Slot::Delay]).map_or(0.0, |(b, _)| b[0]);
                match effect {
                    Effect::ActuatorLag => p.set(Slot::Tau, b.max(0.1 * dt)),
                    Effect::SensorLag => p.set(Slot::TauS, b.max(0.1 * dt)),
                    _ => p.set(Slot::Delay, b.max(0.0)),
                }
            }
            Effect::SensorOffsetGain => {
                // Linear in the reading: the fit finds them from the ideal sensor at once.
            }
            _ => {
                let slots = effect.slots(free);
                if let Some((b, _)) = joint(&p, &slots) {
                    for (&s, &bi) in slots.iter().zip(&b) {
                        let v = p.get(s);
                        p.set(s, limited(s, v, v + bi));
                    }
                }
            }
        }
        p
    }
}

/// The natural period `2 pi sqrt(m / k)` of `p`'s linear spring, where it has one.
fn natural_period(p: &ModelPoint) -> Option<f64> {
    let (m, k) = (p.params.m, p.params.k);
    (k > 0.0 && m > 0.0).then(|| std::f64::consts::TAU * (m / k).sqrt())
}

/// Periods of the record a grid of starting points is ranked on ([`Screening::grid_samples`]).
const GRID_PERIODS: f64 = 2000.0;

/// The fewest scored samples a grid of starting points is ranked on.
const GRID_MIN_SAMPLES: usize = 4096;

/// The parameter of a lag or delay effect.
fn lag_slot(effect: Effect) -> Slot {
    match effect {
        Effect::ActuatorLag => Slot::Tau,
        Effect::SensorLag => Slot::TauS,
        _ => Slot::Delay,
    }
}

/// A new value kept in the physical range and, for positive scale parameters, within a factor
/// 3 of the old.
fn limited(s: Slot, old: f64, new: f64) -> f64 {
    if !new.is_finite() {
        return old;
    }
    if s.log_scaled() && old > 0.0 {
        return new.clamp(old / 3.0, old * 3.0);
    }
    new.max(s.lower_bound())
}
