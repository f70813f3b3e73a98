//! The diagnosis's settings ([`DiagnoseOptions`]).

use std::ops::Range;

use serde::{Deserialize, Serialize};

use crate::interp::Interpolation;
use crate::sim::SimMethod;
use crate::{DiagnoseError, Effect};

/// Settings of [`diagnose`](crate::diagnose()). Every field has a default ([`DiagnoseOptions::default`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DiagnoseOptions {
    /// Sample-index ranges (0-based, end exclusive) the models are fitted on. Empty: the first
    /// 70 % of the record.
    pub fit: Vec<Range<usize>>,
    /// Held-out sample-index ranges the models are judged on; must not overlap `fit`. Empty:
    /// the last 30 % of the record.
    pub validation: Vec<Range<usize>>,
    /// Time (s) at the start of every range that is simulated but left out of costs and
    /// scores, so the transient from the estimated initial state dies out. `None`: four decay
    /// times `2 m / c` of the nominal model (with `c` halved for the switching damper, which
    /// is on about half the time), at most a quarter of the shortest range.
    pub burn_in_s: Option<f64>,
    /// The effects tried. Default: the whole library, [`Effect::ALL`].
    pub candidates: Vec<Effect>,
    /// A refitted free parameter of the nominal model that lies this many standard errors from
    /// its configured value is a `parameter_error` finding, `> 0`. Default 5.
    pub significance_sigma: f64,
    /// Smallest relative reduction of the held-out error, `1 - rmse_after / rmse_before`, for
    /// an effect to be added (and for a refit of the configured parameters to count), in
    /// `[0, 1)`. Default 0.05.
    pub min_gain: f64,
    /// Evidence margin in BIC units: first-round candidates whose fits lie within this margin
    /// of the best one's (and are not nested in it) are its rivals, and the answer is
    /// `ambiguous` unless the selection adds them too, `>= 0`. Default 10 ("very strong" on
    /// Kass and Raftery's scale).
    pub bic_margin: f64,
    /// A held-out RMSE above this multiple of the noise floor is "clear residual structure",
    /// `>= 1`. Default 5 (effects in the library fitted to data they describe leave about 1 to
    /// 1.5 times the floor; effects outside it mimicked by library ones, 4 to 80 times).
    pub unexplained_ratio: f64,
    /// Fraction of the nominal's excess error (above the noise floor, in mean square) the
    /// selected effects must remove when their residual is still above `unexplained_ratio`
    /// times the noise floor; otherwise the answer is `unexplained`, in `[0, 1]`. Default
    /// 0.999 (a residual 3 % of the nominal's, in RMS).
    pub min_explained: f64,
    /// How the measured force is read between samples. Default: cubic spline.
    pub interpolation: Interpolation,
    /// How models are simulated. Default: fixed-step RK4 with `max_rate_step = 0.2`.
    pub sim: SimMethod,
    /// Fit the position and velocity at the start of every fit range (two extra parameters per
    /// range, starting from the data's estimate) instead of keeping the data's estimate. Default
    /// `true`: at a record's first sample the estimate is one-sided and can be biased enough
    /// to leave a transient longer than the burn-in. Validation ranges always start from the
    /// data's estimate.
    pub fit_initial_state: bool,
    /// Most Levenberg-Marquardt iterations per fit, `>= 1`. Default 40.
    pub max_iterations: usize,
    /// A fit ends when a step improves the fit by less than this in likelihood-ratio units,
    /// `n ln(rss_before / rss_after)` with `n` the fitted samples, `> 0`. Default 0.01: a
    /// hundredth of a unit of log-likelihood on the scale where an effect needs a ratio near 15
    /// to be added, so a fit that stops here decides as the exact optimum would, and a
    /// parameter creeping towards a bound (a lag shrinking on a log scale, 1e-6 of the cost per
    /// step) stops instead of using every iteration.
    pub fit_tolerance: f64,
    /// Band of the residual spectrum whose level is the noise floor, as fractions of the
    /// Nyquist frequency, `0 < lo < hi <= 1`. Default (0.6, 0.95).
    pub noise_band: (f64, f64),
    /// Level of the nested-model test that admits an effect (the probability that an absent
    /// effect passes it on white residuals), in `(0, 0.5)`. Default 1e-4.
    pub alpha: f64,
    /// Most effects named together, `>= 1`. Default 3.
    pub max_effects: usize,
    /// Resolution of the simulation relative to the spread of the measured output, `>= 0`:
    /// the noise floor used by the decision is never below `resolution * std(x)`. The force is
    /// known only at its samples, and its interpolation alone leaves simulated outputs in
    /// error by about this much on the paper's protocol, so a residual this small is not
    /// evidence of structure. Default 1e-4.
    pub resolution: f64,
    /// The measured input's own noise, read from the same band of its spectrum as the
    /// output's, is propagated through the nominal model into the noise floor (a perfect model
    /// driven by a noisy force leaves that much error), unless white noise of that level would
    /// carry more than this share of the input's variance: an input with content up to its
    /// Nyquist frequency, whose noise no spectrum tells from it. In `[0, 1]`; 0 leaves the
    /// input's noise out. Default 0.1.
    pub input_noise_share: f64,
    /// The input's noise band is read as white noise only where it is this flat: the highest
    /// of its four quarters' levels at most this multiple of the lowest, `>= 1`. Default 1.5
    /// (the quarters of white noise scatter by about 5 % on short records; the tail of an
    /// excitation's spectrum falls by a factor 3 or more across the band).
    pub input_noise_flatness: f64,
    /// A fitted input delay of at least this many forcing periods is not an actuator's: delayed
    /// that far the measured force lines the periodic forcing up with itself again. In
    /// `(0, 1]`; default 0.25. Records without a forcing period are not limited.
    pub max_delay_periods: f64,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            fit: Vec::new(),
            validation: Vec::new(),
            burn_in_s: None,
            candidates: Effect::ALL.to_vec(),
            significance_sigma: 5.0,
            min_gain: 0.05,
            bic_margin: 10.0,
            unexplained_ratio: 5.0,
            min_explained: 0.999,
            interpolation: Interpolation::default(),
            sim: SimMethod::default(),
            fit_initial_state: true,
            max_iterations: 40,
            fit_tolerance: 0.01,
            noise_band: (0.6, 0.95),
            alpha: 1e-4,
            max_effects: 3,
            resolution: 1e-4,
            input_noise_share: 0.1,
            input_noise_flatness: crate::noise::WHITE_SPREAD,
            max_delay_periods: 0.25,
        }
    }
}

impl DiagnoseOptions {
    /// Checks every range-free option; ranges are checked against the record in [`diagnose`](crate::diagnose()).
    pub fn validate(&self) -> Result<(), DiagnoseError> {
        let bad = |name, expected, value| {
            Err(DiagnoseError::InvalidOption {
                name,
                expected,
                value,
            })
        };
        if let Some(b) = self.burn_in_s {
            if !(b.is_finite() && b >= 0.0) {
                return bad("burn_in_s", ">= 0 and finite", b);
            }
        }
        if !(self.significance_sigma.is_finite() && self.significance_sigma > 0.0) {
            return bad(
                "significance_sigma",
                "> 0 and finite",
                self.significance_sigma,
            );
        }
        if !(self.min_gain >= 0.0 && self.min_gain < 1.0) {
            return bad("min_gain", "in [0, 1)", self.min_gain);
        }
        if !(self.bic_margin.is_finite() && self.bic_margin >= 0.0) {
            return bad("bic_margin", ">= 0 and finite", self.bic_margin);
        }
        if !(self.unexplained_ratio.is_finite() && self.unexplained_ratio >= 1.0) {
            return bad(
                "unexplained_ratio",
                ">= 1 and finite",
                self.unexplained_ratio,
            );
        }
        if !(0.0..=1.0).contains(&self.min_explained) {
            return bad("min_explained", "in [0, 1]", self.min_explained);
        }
        if self.max_iterations == 0 {
            return bad("max_iterations", ">= 1", 0.0);
        }
        if !(self.fit_tolerance.is_finite() && self.fit_tolerance > 0.0) {
            return bad("fit_tolerance", "> 0 and finite", self.fit_tolerance);
        }
        if !(self.alpha > 0.0 && self.alpha < 0.5) {
            return bad("alpha", "in (0, 0.5)", self.alpha);
        }
        if !(self.resolution.is_finite() && self.resolution >= 0.0) {
            return bad("resolution", ">= 0 and finite", self.resolution);
        }
        if !(0.0..=1.0).contains(&self.input_noise_share) {
            return bad("input_noise_share", "in [0, 1]", self.input_noise_share);
        }
        if !(self.max_delay_periods > 0.0 && self.max_delay_periods <= 1.0) {
            return bad("max_delay_periods", "in (0, 1]", self.max_delay_periods);
        }
        if self.max_effects == 0 {
            return bad("max_effects", ">= 1", 0.0);
        }
        crate::noise::check_reading(self.noise_band, self.input_noise_flatness)?;
        match self.sim {
            SimMethod::FixedStep { max_rate_step } => {
                if !(max_rate_step.is_finite() && max_rate_step > 0.0) {
                    return bad("sim.max_rate_step", "> 0 and finite", max_rate_step);
                }
            }
            SimMethod::Adaptive { rtol } => {
                if !(rtol.is_finite() && rtol > 0.0) {
                    return bad("sim.rtol", "> 0 and finite", rtol);
                }
            }
        }
        for (i, e) in self.candidates.iter().enumerate() {
            if self.candidates[..i].contains(e) {
                return Err(DiagnoseError::DuplicateCandidate { name: e.name() });
            }
        }
        Ok(())
    }
}
