//! Equation-error screening: starting values from a regression of the residual acceleration.
//!
//! The measured position is smoothed and differentiated (Savitzky-Golay); the model's
//! acceleration is evaluated on the smoothed states with the measured force, and the
//! difference is regressed on the derivatives of the acceleration with respect to the
//! parameters (finite differences of the model's own vector field). Parameters that do not
//! enter linearly near zero (a switching threshold, a contact position) are searched on a grid.

use htfid_hybrid::HybridSystem;
use nalgebra::{DMatrix, DVector};

use crate::deriv::{savitzky_golay, Kinematics};
use crate::effect::Slot;
use crate::fit::{Context, ModelPoint};
use crate::Effect;

/// Most samples used by the regression (evenly thinned beyond).
const MAX_SAMPLES: usize = 20_000;

#[derive(Debug)]
pub(crate) struct Screening<'c, 'a> {
    ctx: &'c Context<'a>,
    samples: Vec<(f64, Kinematics)>,
}

impl<'c, 'a> Screening<'c, 'a> {
    pub(crate) fn new(ctx: &'c Context<'a>, half: usize) -> Self {
        let t = ctx.record.t();
        let x = ctx.record.x();
        let mut samples = Vec::new();
        for seg in &ctx.fit {
            let r = seg.scored();
            for (k, kin) in savitzky_golay(x, r.start, r.end, ctx.record.dt(), half, 4) {
                samples.push((t[k], kin));
            }
        }
        let stride = samples.len().div_ceil(MAX_SAMPLES).max(1);
        let samples = samples.into_iter().step_by(stride).collect();
        Screening { ctx, samples }
    }

    /// Smoothed kinematics (for the data's extent).
    pub(crate) fn samples(&self) -> &[(f64, Kinematics)] {
        &self.samples
    }

    /// Model accelerations at the smoothed states (the lag state is not modelled here).
    fn accelerations(&self, p: &ModelPoint) -> Option<Vec<f64>> {
        let mut p = *p;
        p.effects.tau = 0.0;
        let hopper = self.ctx.hopper(&p).ok()?;
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

    /// Starting points for `effect`. One from [`Screening::start`], except for a switching
    /// threshold: its effect grows about quadratically on both sides of zero, so the best
    /// threshold of each sign on a grid of output-error costs starts a fit of its own.
    pub(crate) fn starts(
        &self,
        base: &ModelPoint,
        free: &[Slot],
        effect: Effect,
    ) -> Vec<ModelPoint> {
        if effect != Effect::SwitchThreshold {
            return vec![self.start(base, free, effect)];
        }
        let v_std = self.ctx.scales.v_std;
        let v0 = base.get(Slot::VTh);
        let mut best = [(f64::INFINITY, None), (f64::INFINITY, None)];
        for q in [0.02, 0.05, 0.1, 0.2, 0.35] {
            for (side, sign) in [(0, -1.0), (1, 1.0)] {
                let mut p = *base;
                p.set(Slot::VTh, v0 + sign * q * v_std);
                if let Some(c) = self.ctx.fit_cost(&p) {
                    if c < best[side].0 {
                        best[side] = (c, Some(p));
                    }
                }
            }
        }
        let starts: Vec<ModelPoint> = best.into_iter().filter_map(|(_, p)| p).collect();
        if starts.is_empty() {
            vec![*base]
        } else {
            starts
        }
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
                let mut xs: Vec<f64> = self.samples.iter().map(|(_, k)| k.x).collect();
                xs.sort_by(f64::total_cmp);
                let mut best: Option<(f64, f64, f64)> = None;
                if !xs.is_empty() {
                    for q in [0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.3] {
                        let x_stop = xs[((xs.len() - 1) as f64 * q) as usize];
                        let mut trial = p;
                        trial.set(Slot::XStop, x_stop);
                        trial.set(Slot::KStop, 0.0);
                        if let Some((b, rss)) = joint(&trial, &[Slot::KStop]) {
                            if b[0] > 0.0 && best.map_or(true, |(r, _, _)| rss < r) {
                                best = Some((rss, x_stop, b[0]));
                            }
                        }
                    }
                }
                let (x_stop, k_stop) = match best {
                    Some((_, xs0, ks)) => (xs0, ks),
                    None => (xs.first().copied().unwrap_or(0.0), 0.1 * p.params.k),
                };
                p.set(Slot::XStop, x_stop);
                p.set(Slot::KStop, k_stop);
            }
            Effect::ActuatorLag | Effect::InputDelay => {
                // To first order a lag and a delay both shift the force by `-tau f'`.
                let b = joint(&p, &[Slot::Delay]).map_or(0.0, |(b, _)| b[0]);
                if effect == Effect::ActuatorLag {
                    p.set(Slot::Tau, b.max(0.1 * dt));
                } else {
                    p.set(Slot::Delay, b.max(0.0));
                }
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
