//! HTFs from a measured record alone, without a model: the period given or found in the data,
//! the record cut to whole periods, its period average (the orbit) removed from the input and
//! every output, Siddiqi's estimator on the deviations, and what the record allows: enough
//! periods, the band the input excites, the harmonics that read unexcited input frequencies or
//! alias past the Nyquist frequency, and the harmonics outside the set that the response
//! carries.
//!
//! Two steps, so that a caller can weigh the work before doing it: [`PeriodicRecord::plan`]
//! fixes the period, the locked sample step and the whole periods from the first output, and
//! [`PeriodicRecord::estimate`] estimates every output.

use std::f64::consts::PI;

use num_complex::Complex64;
use rustfft::FftPlanner;

use crate::{
    deviation_record, estimate_period, locked_step, outer_harmonics, siddiqi, split_periodic,
    Alpha, Error, HtfEstimate, OuterHarmonic, PeriodEstimate,
};

/// Fewer periods than this and an estimate rests on few degrees of freedom per bin; the
/// check of the harmonics outside the set is then not made (its standard errors would rest on
/// too few).
pub const MIN_PERIODS: usize = 20;

/// An added harmonic significant at more than this share of the band's bins (noise alone:
/// about 2 %) carries the response.
pub const OUTER_SIGNIFICANT_SHARE: f64 = 0.1;

/// Share of a harmonic's frequencies, reading unexcited input frequencies, above which they
/// are reported.
pub const UNEXCITED_SHARE: f64 = 0.05;

/// Probability that noise alone reaches the level of
/// [`HarmonicSummary::max_abs_g_significant`] at any of a harmonic's frequencies.
pub const BAND_FALSE_ALARM: f64 = 0.05;

/// Largest drift, in periods over the record, of a given period against the data's own
/// before the given period is put to the test: a twentieth of a period smears the harmonics'
/// phases by 18 degrees at the fundamental and more at the harmonics.
const GIVEN_PERIOD_DRIFT: f64 = 0.05;

/// Share of the first output's variance its orbit must carry at its own period for that period
/// to overrule a given one.
const CLEAR_ORBIT_SHARE: f64 = 0.5;

/// Share of the orbit's variance at the data's own period that a given period must still
/// explain (a period of the data's orbit, or a multiple of it, explains all of it; a period
/// off by a fraction of a period over the record smears the orbit's harmonics out of its
/// average).
const GIVEN_PERIOD_SHARE: f64 = 0.9;

/// Fewest samples a record needs (the period search's own minimum).
pub const MIN_SAMPLES: usize = 64;

/// How the period is known.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PeriodChoice {
    /// Given, s.
    Given(f64),
    /// Estimated from the first output ([`estimate_period`]).
    Estimate,
}

/// What to estimate.
#[derive(Debug, Clone)]
pub struct DataSpec {
    /// The harmonics `n` of `G_n`.
    pub harmonics: Vec<i32>,
    /// Output-frequency band, rad/s.
    pub band: (f64, f64),
    /// Siddiqi's smoothness weight.
    pub alpha: Alpha,
    /// Harmonics of the period average kept as the input's orbit; the outputs keep twice as
    /// many. The split removes every multiple of the pumping frequency regardless.
    pub orbit_harmonics: usize,
    /// Harmonics added on each side of the set to check that it holds the response (0: no
    /// check).
    pub outer_harmonics: i32,
}

impl DataSpec {
    /// `G_-3 .. G_3` over `band` with `alpha`, orbits of 5 (input) and 10 (outputs)
    /// harmonics, two harmonics checked on each side.
    pub fn new(harmonics: Vec<i32>, band: (f64, f64), alpha: Alpha) -> Self {
        DataSpec {
            harmonics,
            band,
            alpha,
            orbit_harmonics: 5,
            outer_harmonics: 2,
        }
    }
}

/// Why HTFs could not be estimated from a record.
#[non_exhaustive]
#[derive(Debug, thiserror::Error)]
pub enum FromDataError {
    /// The record is shorter than [`MIN_SAMPLES`].
    #[error("the record holds {samples} samples; at least {MIN_SAMPLES} are needed")]
    TooShort {
        /// Samples given.
        samples: usize,
    },
    /// A given period that holds no whole number of samples.
    #[error("the period {period} s is {per_period:.4} samples of {dt} s, not a whole number")]
    PeriodNotWhole {
        /// The period, s.
        period: f64,
        /// The record's step, s.
        dt: f64,
        /// Samples per period.
        per_period: f64,
    },
    /// No period could be found in the first output.
    #[error("the period could not be estimated from the first output: {0}")]
    PeriodNotFound(#[source] Error),
    /// The period found holds no whole number of samples.
    #[error("the estimated period {period:.9} s is {per_period:.4} samples, not a whole number")]
    EstimatedPeriodNotWhole {
        /// The period found, s.
        period: f64,
        /// Samples per period.
        per_period: f64,
    },
    /// Fewer than two whole periods.
    #[error("the record holds {periods} period(s) of {period} s; at least 2 are needed")]
    TooFewPeriods {
        /// Whole periods in the record.
        periods: usize,
        /// The period, s.
        period: f64,
    },
    /// The band and harmonics read input frequencies at or beyond the Nyquist frequency.
    #[error("the band with harmonics up to {largest} needs input up to {needed} rad/s, at or beyond the Nyquist frequency {nyquist} rad/s")]
    BeyondNyquist {
        /// Largest `|n|` of the set.
        largest: i32,
        /// Highest input frequency read, rad/s.
        needed: f64,
        /// The record's Nyquist frequency, rad/s.
        nyquist: f64,
    },
    /// The data contradict a given period.
    #[error("the given period {given} s is contradicted by the first output's own, {} s", own.period)]
    PeriodContradicted {
        /// The period given, s.
        given: f64,
        /// The first output's own period.
        own: PeriodEstimate,
        /// Share of the first output's variance its period average at `given` carries.
        given_share: f64,
        /// Periods in the record.
        periods: f64,
        /// How far the two periods part over the record, in periods.
        drift: f64,
    },
    /// An input or output holds fewer samples than the plan reads.
    #[error("{signal} holds {samples} samples; the plan reads {needed}")]
    Length {
        /// The input or which output.
        signal: Signal,
        /// Samples given.
        samples: usize,
        /// Samples the plan reads ([`PeriodicRecord::samples`]).
        needed: usize,
    },
    /// An input or output could not be split into its orbit and the rest.
    #[error("{signal}: period average: {source}")]
    Split {
        /// The input or which output.
        signal: Signal,
        /// The split's error.
        #[source]
        source: Error,
    },
    /// Siddiqi's estimator failed on an output.
    #[error("Siddiqi's estimator on output {output}: {source}")]
    Estimator {
        /// The output's index.
        output: usize,
        /// The estimator's error.
        #[source]
        source: Error,
    },
}

/// The input or one of the outputs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Signal {
    /// The input.
    Input,
    /// Output `o`.
    Output(usize),
}

impl std::fmt::Display for Signal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Signal::Input => write!(f, "input"),
            Signal::Output(o) => write!(f, "output {o}"),
        }
    }
}

/// A record's period and the whole periods of it the estimate reads.
#[derive(Debug, Clone)]
pub struct PeriodicRecord {
    /// The period, s.
    pub period: f64,
    /// The period as found in the data, when it was not given.
    pub estimated: Option<PeriodEstimate>,
    /// The sample step, s, locked to the period (`period / samples per period`).
    pub dt: f64,
    /// Samples read: whole periods.
    pub samples: usize,
    /// Whole periods read.
    pub periods: usize,
}

impl PeriodicRecord {
    /// Fixes the period (given, or estimated from `first_output` and snapped to a whole number
    /// of samples), the sample step locked to it, and the whole periods of a record of
    /// `first_output.len()` samples `dt` apart; refuses a band and harmonics that read input
    /// beyond the Nyquist frequency.
    ///
    /// # Errors
    /// [`FromDataError`]: too short, a period of no whole number of samples (given or found),
    /// no period found, fewer than two periods, the band beyond Nyquist.
    pub fn plan(
        first_output: &[f64],
        dt: f64,
        period: PeriodChoice,
        spec: &DataSpec,
    ) -> Result<Self, FromDataError> {
        let available = first_output.len();
        if available < MIN_SAMPLES {
            return Err(FromDataError::TooShort { samples: available });
        }
        let (period, estimated, dt) = match period {
            PeriodChoice::Given(t) => {
                let step = locked_step(t, dt, available).ok_or(FromDataError::PeriodNotWhole {
                    period: t,
                    dt,
                    per_period: t / dt,
                })?;
                (t, None, step)
            }
            PeriodChoice::Estimate => {
                let est =
                    estimate_period(first_output, dt).map_err(FromDataError::PeriodNotFound)?;
                let per = est.period / dt;
                let snapped = per.round();
                // The estimate is far better than a hundredth of a sample on any record with a
                // clear orbit; a larger offset means the sampling is not locked to the period.
                if (per - snapped).abs() > 0.01 {
                    return Err(FromDataError::EstimatedPeriodNotWhole {
                        period: est.period,
                        per_period: per,
                    });
                }
                (snapped * dt, Some(est), dt)
            }
        };
        let per_period = (period / dt).round() as usize;
        let periods = available / per_period.max(1);
        if periods < 2 {
            return Err(FromDataError::TooFewPeriods { periods, period });
        }
        let plan = PeriodicRecord {
            period,
            estimated,
            dt,
            samples: periods * per_period,
            periods,
        };
        let needed = plan.highest_input_frequency(spec);
        let nyquist = PI / dt;
        if needed >= nyquist {
            return Err(FromDataError::BeyondNyquist {
                largest: spec.harmonics.iter().map(|n| n.abs()).max().unwrap_or(0),
                needed,
                nyquist,
            });
        }
        Ok(plan)
    }

    /// The pumping frequency `2 pi / T`, rad/s.
    pub fn pumping_frequency(&self) -> f64 {
        2.0 * PI / self.period
    }

    /// The Nyquist frequency, rad/s.
    pub fn nyquist(&self) -> f64 {
        PI / self.dt
    }

    /// The frequency resolution of the record read, rad/s.
    pub fn resolution(&self) -> f64 {
        2.0 * PI / (self.samples as f64 * self.dt)
    }

    /// The highest input frequency `|w - n wp|` the band and harmonics read, rad/s.
    fn highest_input_frequency(&self, spec: &DataSpec) -> f64 {
        let wp = self.pumping_frequency();
        let (lo, hi) = spec.band;
        spec.harmonics
            .iter()
            .map(|&n| {
                let shift = f64::from(n) * wp;
                (lo - shift).abs().max((hi - shift).abs())
            })
            .fold(0.0, f64::max)
    }

    /// Estimates every output's HTFs: the input `u` and the `outputs` (the first is the one
    /// the plan was made from), sampled from absolute time `t_start`, each at least
    /// [`PeriodicRecord::samples`] long; their first `samples` are read.
    ///
    /// # Errors
    /// [`FromDataError`]: a signal shorter than the plan, a split or an estimate that fails, a
    /// given period the first output contradicts.
    pub fn estimate(
        &self,
        t_start: f64,
        u: &[f64],
        outputs: &[&[f64]],
        spec: &DataSpec,
    ) -> Result<DataEstimate, FromDataError> {
        let (n, dt, period) = (self.samples, self.dt, self.period);
        let signals = std::iter::once((Signal::Input, u.len())).chain(
            outputs
                .iter()
                .enumerate()
                .map(|(o, y)| (Signal::Output(o), y.len())),
        );
        for (signal, samples) in signals {
            if samples < n {
                return Err(FromDataError::Length {
                    signal,
                    samples,
                    needed: n,
                });
            }
        }
        let input = split_periodic(&u[..n], dt, t_start, period, spec.orbit_harmonics).map_err(
            |source| FromDataError::Split {
                signal: Signal::Input,
                source,
            },
        )?;
        let mut estimated = Vec::with_capacity(outputs.len());
        for (o, y) in outputs.iter().enumerate() {
            let split = split_periodic(&y[..n], dt, t_start, period, 2 * spec.orbit_harmonics)
                .map_err(|source| FromDataError::Split {
                    signal: Signal::Output(o),
                    source,
                })?;
            if o == 0 && self.estimated.is_none() {
                self.check_given_period(y, &split.deviation)?;
            }
            let record = deviation_record(input.deviation.clone(), split.deviation, dt, t_start)
                .map_err(|source| FromDataError::Estimator { output: o, source })?;
            let estimate = siddiqi(&record, period, &spec.harmonics, spec.band, spec.alpha)
                .map_err(|source| FromDataError::Estimator { output: o, source })?;
            // Harmonics beyond the set that carry the response bias the ones estimated.
            let outer = if spec.outer_harmonics > 0 {
                outer_harmonics(
                    &record,
                    period,
                    &spec.harmonics,
                    spec.band,
                    spec.alpha,
                    spec.outer_harmonics,
                )
                .map_err(|e| e.to_string())
            } else {
                Ok(Vec::new())
            };
            estimated.push(OutputEstimate {
                summaries: spec
                    .harmonics
                    .iter()
                    .map(|&k| HarmonicSummary::of(&estimate, k))
                    .collect(),
                estimate,
                orbit: split.harmonics,
                outer,
            });
        }
        let excited = excited_band(&input.deviation, dt);
        let unexcited = match (excited, estimated.first()) {
            (Some(band), Some(first)) => unexcited_ranges(
                &first.estimate,
                self.pumping_frequency(),
                band,
                self.resolution(),
            ),
            _ => Vec::new(),
        };
        let nyquist = self.nyquist();
        let wp = self.pumping_frequency();
        let (lo, hi) = spec.band;
        let aliased = spec
            .harmonics
            .iter()
            .copied()
            .filter(|&k| hi - f64::from(k) * wp > nyquist || lo - f64::from(k) * wp < -nyquist)
            .collect();
        Ok(DataEstimate {
            input_orbit: input.harmonics,
            outputs: estimated,
            excited_band: excited,
            unexcited,
            aliased,
        })
    }

    /// Refuses a given period that the data contradict: where the first output's own period
    /// (with a clear orbit) parts from the given one by more than [`GIVEN_PERIOD_DRIFT`]
    /// periods over the record, and the period average at the given period carries less
    /// than [`GIVEN_PERIOD_SHARE`] of the variance the orbit carries at its own period, every
    /// harmonic would be read at the wrong frequency and the estimate would be confident
    /// nonsense. `deviation` is the first output's samples read, their period average
    /// removed. (On a short record the own period may come out a multiple of the true one;
    /// the true one then explains as much, and passes.)
    fn check_given_period(&self, output: &[f64], deviation: &[f64]) -> Result<(), FromDataError> {
        let Ok(own) = estimate_period(output, self.dt) else {
            return Ok(());
        };
        let n = deviation.len();
        let periods = n as f64 * self.dt / self.period;
        let drift = (self.period - own.period).abs() / own.period * periods;
        if own.periodic_share < CLEAR_ORBIT_SHARE || drift <= GIVEN_PERIOD_DRIFT {
            return Ok(());
        }
        let y = &output[..n];
        let mean = y.iter().sum::<f64>() / n as f64;
        let total: f64 = y.iter().map(|v| (v - mean).powi(2)).sum();
        let left: f64 = deviation.iter().map(|v| v * v).sum();
        let given = if total > 0.0 { 1.0 - left / total } else { 1.0 };
        if given >= GIVEN_PERIOD_SHARE * own.periodic_share {
            return Ok(());
        }
        Err(FromDataError::PeriodContradicted {
            given: self.period,
            own,
            given_share: given,
            periods,
            drift,
        })
    }
}

/// Every output's HTFs from the data and what the record allows.
#[derive(Debug, Clone)]
pub struct DataEstimate {
    /// Fourier coefficients `c_k` of the input's periodic part in absolute time
    /// ([`crate::PeriodicSplit::harmonics`]).
    pub input_orbit: Vec<Complex64>,
    /// Per output.
    pub outputs: Vec<OutputEstimate>,
    /// The band (rad/s) where the input's spectrum (its orbit removed) lies within 40 dB of
    /// its peak; `None` for an input without broadband content.
    pub excited_band: Option<(f64, f64)>,
    /// Per harmonic, the ranges of output frequencies (rad/s) whose input frequency
    /// `|w - n wp|` lies more than a frequency bin outside the excited band, where they cover
    /// more than [`UNEXCITED_SHARE`] of the harmonic's frequencies (the first output's grid;
    /// every output shares it).
    pub unexcited: Vec<(i32, Vec<(f64, f64)>)>,
    /// Harmonics that map part of the band past the Nyquist frequency: they alias.
    pub aliased: Vec<i32>,
}

/// One output's estimate.
#[derive(Debug, Clone)]
pub struct OutputEstimate {
    /// Siddiqi's estimate.
    pub estimate: HtfEstimate,
    /// Fourier coefficients of the output's periodic part (its orbit) in absolute time.
    pub orbit: Vec<Complex64>,
    /// The harmonics outside the set, estimated beside it, or why they could not be.
    pub outer: Result<Vec<OuterHarmonic>, String>,
    /// Per harmonic of the set, in its order.
    pub summaries: Vec<HarmonicSummary>,
}

impl OutputEstimate {
    /// The harmonics outside the set that the response carries: significant at more than
    /// [`OUTER_SIGNIFICANT_SHARE`] of the band.
    pub fn carried_outside(&self) -> Vec<&OuterHarmonic> {
        self.outer
            .as_deref()
            .unwrap_or_default()
            .iter()
            .filter(|h| h.significant_share > OUTER_SIGNIFICANT_SHARE)
            .collect()
    }
}

/// How one harmonic of an estimate stands against its noise.
#[derive(Debug, Clone, Copy)]
pub struct HarmonicSummary {
    /// The harmonic.
    pub n: i32,
    /// Largest `|G_n|` over the band.
    pub max_abs_g: f64,
    /// The level noise alone reaches at any of its frequencies with probability
    /// [`BAND_FALSE_ALARM`], where the estimate stands out of it; NaN otherwise.
    pub max_abs_g_significant: f64,
    /// Median of `|G_n| / stderr`.
    pub median_abs_g_over_stderr: f64,
    /// Frequencies where `|G_n| > 2 stderr`.
    pub significant_points: usize,
    /// Frequencies estimated.
    pub points: usize,
    /// Largest estimated smoothing bias over the noise-only standard error; NaN without one.
    pub max_bias_over_stderr: f64,
}

impl HarmonicSummary {
    fn of(e: &HtfEstimate, k: i32) -> Self {
        let rows: Vec<_> = e.rows().filter(|r| r.n == k).collect();
        let max = rows.iter().map(|r| r.value.norm()).fold(0.0, f64::max);
        let max_significant = e
            .harmonic(k)
            .and_then(|h| h.largest_significant(BAND_FALSE_ALARM))
            .unwrap_or(f64::NAN);
        let mut snr: Vec<f64> = rows
            .iter()
            .filter(|r| r.stderr > 0.0)
            .map(|r| r.value.norm() / r.stderr)
            .collect();
        snr.sort_by(f64::total_cmp);
        let significant = snr.iter().filter(|&&s| s > 2.0).count();
        // The smoothing bias the estimator estimates beside its values (one per row, in the
        // rows' order), against the noise-only standard errors.
        let bias = e
            .bias()
            .zip(e.harmonics().iter().position(|&m| m == k))
            .map_or(f64::NAN, |((_, b), i)| {
                rows.iter()
                    .zip(&b[i])
                    .filter(|(r, _)| r.stderr > 0.0)
                    .map(|(r, b)| b.norm() / r.stderr)
                    .fold(f64::NAN, f64::max)
            });
        HarmonicSummary {
            n: k,
            max_abs_g: max,
            max_abs_g_significant: max_significant,
            median_abs_g_over_stderr: snr.get(snr.len() / 2).copied().unwrap_or(f64::NAN),
            significant_points: significant,
            points: rows.len(),
            max_bias_over_stderr: bias,
        }
    }
}

/// A signal's periodic part at time `t` from its Fourier coefficients `c` in absolute time
/// (`c_0 + 2 Re sum c_k exp(j k wp t)`).
pub fn periodic_value(c: &[Complex64], wp: f64, t: f64) -> f64 {
    c.iter().enumerate().fold(0.0, |acc, (k, ck)| {
        let z = ck * Complex64::from_polar(1.0, k as f64 * wp * t);
        acc + if k == 0 { z.re } else { 2.0 * z.re }
    })
}

/// The band (rad/s) where the spectrum of `u` lies within 40 dB of its peak: from the lowest
/// to the highest frequency bin above that level, the record Hann-windowed first so that a
/// strong line's leakage falls below it within a few bins; `None` for a signal without
/// content.
pub fn excited_band(u: &[f64], dt: f64) -> Option<(f64, f64)> {
    let n = u.len();
    let mut buf: Vec<Complex64> = u
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            let w = 0.5 - 0.5 * (2.0 * PI * i as f64 / n as f64).cos();
            Complex64::new(w * v, 0.0)
        })
        .collect();
    FftPlanner::new().plan_fft_forward(n).process(&mut buf);
    let power: Vec<f64> = buf[1..n / 2].iter().map(|z| z.norm_sqr()).collect();
    let peak = power.iter().copied().fold(0.0, f64::max);
    if peak.is_nan() || peak <= 0.0 {
        return None;
    }
    let first = power.iter().position(|&p| p >= 1e-4 * peak)?;
    let last = power.iter().rposition(|&p| p >= 1e-4 * peak)?;
    let bin = 2.0 * PI / (n as f64 * dt);
    Some(((first + 1) as f64 * bin, (last + 1) as f64 * bin))
}

/// Per harmonic of `e`, the ranges of its output frequencies `w` (rad/s) whose input frequency
/// `|w - n wp|` lies more than a frequency bin outside the excited band `(lo, hi)`, where they
/// cover more than [`UNEXCITED_SHARE`] of the harmonic's frequencies.
fn unexcited_ranges(
    e: &HtfEstimate,
    wp: f64,
    (lo, hi): (f64, f64),
    bin: f64,
) -> Vec<(i32, Vec<(f64, f64)>)> {
    let mut out = Vec::new();
    for &n in e.harmonics() {
        let rows: Vec<f64> = e.rows().filter(|r| r.n == n).map(|r| r.omega).collect();
        let outside = |w: f64| {
            let input = (w - f64::from(n) * wp).abs();
            input < lo - bin || input > hi + bin
        };
        let count = rows.iter().filter(|&&w| outside(w)).count();
        if rows.is_empty() || (count as f64) <= UNEXCITED_SHARE * rows.len() as f64 {
            continue;
        }
        let mut ranges: Vec<(f64, f64)> = Vec::new();
        let mut open: Option<(f64, f64)> = None;
        for &w in &rows {
            match (outside(w), open.as_mut()) {
                (true, Some(range)) => range.1 = w,
                (true, None) => open = Some((w, w)),
                (false, Some(_)) => ranges.extend(open.take()),
                (false, None) => {}
            }
        }
        ranges.extend(open);
        out.push((n, ranges));
    }
    out
}
