//! The data's harmonic transfer functions against the models': Siddiqi's estimator, at a
//! fixed weight, on the held-out record's excited periods and on each model's simulation with
//! the measured input. The estimator is linear in the output, so the difference of two
//! estimates is the estimate of the residual's response; it is measured per harmonic against
//! the estimate's noise.

use std::f64::consts::PI;

use htfid_estimate::{deviation_record, siddiqi, split_periodic, Alpha, HtfEstimate};
use num_complex::Complex64;

use crate::{DiagnoseError, TimeSeries};

/// A difference counts as outside the estimate's noise beyond this many standard errors.
pub const DIFFERENCE_SIGMAS: f64 = 2.0;

/// Fewest whole excited periods the estimate is made from.
const MIN_PERIODS: usize = 10;

/// The measured HTF of one harmonic minus each model's, at the estimate's frequencies.
#[derive(Debug, Clone, PartialEq)]
pub struct HarmonicDifference {
    /// The harmonic `n`.
    pub n: i32,
    /// Output frequencies of the estimate, rad/s.
    pub omega: Vec<f64>,
    /// Standard errors of the estimate.
    pub stderr: Vec<f64>,
    /// Measured minus the nominal model's exact `G_n`.
    pub nominal: Vec<Complex64>,
    /// Measured minus the extended model's exact `G_n`.
    pub extended: Vec<Complex64>,
}

impl HarmonicDifference {
    /// Share of the bins (with a finite standard error) where `|d| > DIFFERENCE_SIGMAS stderr`.
    fn outside(d: &[Complex64], se: &[f64]) -> f64 {
        let n = se.iter().filter(|s| s.is_finite()).count();
        if n == 0 {
            return 0.0;
        }
        let out = d
            .iter()
            .zip(se)
            .filter(|(g, s)| s.is_finite() && g.norm() > DIFFERENCE_SIGMAS * **s)
            .count();
        out as f64 / n as f64
    }

    /// Share of the bins where the nominal model misses the data beyond the noise.
    pub fn nominal_outside(&self) -> f64 {
        Self::outside(&self.nominal, &self.stderr)
    }

    /// Share of the bins where the extended model misses the data beyond the noise.
    pub fn extended_outside(&self) -> f64 {
        Self::outside(&self.extended, &self.stderr)
    }
}

/// Samples per forcing period: an error unless it is a whole number (the split and the
/// estimator need `N dt = P T` exactly).
fn samples_per_period(period: f64, dt: f64) -> Result<usize, DiagnoseError> {
    let per = period / dt;
    if (per - per.round()).abs() > 1e-6 {
        return Err(htf_error(format!(
            "the forcing period {period} s is {per:.4} samples, not a whole number"
        )));
    }
    Ok(per.round() as usize)
}

fn htf_error(reason: impl Into<String>) -> DiagnoseError {
    DiagnoseError::Htf {
        reason: reason.into(),
    }
}

/// Harmonics of a diagnosis's HTF comparison.
pub const ESTIMATED_HARMONICS: [i32; 5] = [-2, -1, 0, 1, 2];
/// Siddiqi's weight of that comparison.
pub const ESTIMATED_ALPHA: f64 = 1.0;

/// One output's HTFs estimated from a record against those estimated from models' simulations.
#[derive(Debug, Clone)]
pub struct EstimatedComparison {
    /// Output-frequency band of the estimates, rad/s.
    pub band: (f64, f64),
    /// Whole periods the estimates read.
    pub periods: usize,
    /// Siddiqi's estimate from the measured output.
    pub measured: HtfEstimate,
    /// The same estimator, with the same weight, on the nominal model's simulated output.
    pub nominal: HtfEstimate,
    /// And on the extended model's, when there is one.
    pub extended: Option<HtfEstimate>,
    /// Per harmonic, measured minus each model at the estimate's frequencies (the extended
    /// model's equal to the nominal's without one).
    pub differences: Vec<HarmonicDifference>,
}

/// Every output's HTFs estimated from `record` over `rows` (from the first period boundary in
/// them, whole periods of `period`, at least 10), against the HTFs that the same estimator,
/// with the same weight and the same input, estimates from the models' simulated outputs on
/// those samples (`nominal[o]`, `extended[o]`, every sample of the record). Siddiqi's
/// estimate about the period average, `G_-2 .. G_2` over output frequencies from a sixth of the
/// pumping frequency `wp` to six times it (at most 0.8 of the Nyquist frequency less `2 wp`),
/// weight [`ESTIMATED_ALPHA`].
///
/// The estimator with a fixed weight is linear in the output, and the input is shared, so each
/// difference is the estimate of the residual's response to the excitation: what the model
/// misses, harmonic by harmonic, with the estimator's leakage and bias common to both sides.
/// That works for any model (a delay or a sensor on its boundary included) without its limit
/// cycle or linearisation.
///
/// # Errors
/// [`DiagnoseError::Htf`] when the period is not a whole number of samples, fewer than 10
/// whole periods lie in `rows`, the band is empty, or an estimate fails.
pub fn estimated_comparison(
    record: &TimeSeries,
    rows: std::ops::Range<usize>,
    period: f64,
    nominal: &[Vec<f64>],
    extended: Option<&[Vec<f64>]>,
) -> Result<Vec<EstimatedComparison>, DiagnoseError> {
    let dt = record.dt();
    let per = samples_per_period(period, dt)?;
    let wp = 2.0 * PI / period;
    let top = ESTIMATED_HARMONICS
        .iter()
        .map(|n| n.abs())
        .max()
        .unwrap_or(0) as f64;
    let band = (wp / 6.0, (6.0 * wp).min(0.8 * PI / dt - top * wp));
    if band.1.partial_cmp(&band.0) != Some(std::cmp::Ordering::Greater) {
        return Err(htf_error(format!(
            "no band: the pumping frequency {wp:.4} rad/s lies too close to the Nyquist \
             frequency for G_-2 .. G_2"
        )));
    }
    // From the first period boundary in `rows`, whole periods.
    let t = record.time();
    let r0 = rows.start.min(record.len());
    let phase = (t[r0] / dt).round().rem_euclid(per as f64) as usize;
    let offset = (per - phase) % per;
    let start = r0 + offset;
    let periods = rows.end.min(record.len()).saturating_sub(start) / per;
    if periods < MIN_PERIODS {
        return Err(htf_error(format!(
            "{periods} whole forcing periods held out, at least {MIN_PERIODS} needed"
        )));
    }
    let end = start + periods * per;
    let t_start = t[start];
    let estimate_error = |e: htfid_estimate::Error| htf_error(e.to_string());
    let u = split_periodic(&record.input()[start..end], dt, t_start, period, 5)
        .map_err(estimate_error)?;
    let estimate = |y: &[f64]| -> Result<HtfEstimate, DiagnoseError> {
        let x = split_periodic(&y[start..end], dt, t_start, period, 10).map_err(estimate_error)?;
        let rec = deviation_record(u.deviation.clone(), x.deviation, dt, t_start)
            .map_err(estimate_error)?;
        siddiqi(
            &rec,
            period,
            &ESTIMATED_HARMONICS,
            band,
            Alpha::Fixed(ESTIMATED_ALPHA),
        )
        .map_err(estimate_error)
    };
    record
        .outputs()
        .iter()
        .enumerate()
        .map(|(o, y)| {
            let measured = estimate(y)?;
            let nom = estimate(&nominal[o])?;
            let ext = extended.map(|e| estimate(&e[o])).transpose()?;
            let differences = ESTIMATED_HARMONICS
                .iter()
                .map(|&n| {
                    let rows: Vec<_> = measured.rows().filter(|r| r.n == n).collect();
                    let minus = |m: &HtfEstimate| -> Vec<Complex64> {
                        rows.iter()
                            .zip(m.rows().filter(|r| r.n == n))
                            .map(|(r, g)| r.value - g.value)
                            .collect()
                    };
                    let d_nom = minus(&nom);
                    HarmonicDifference {
                        n,
                        omega: rows.iter().map(|r| r.omega).collect(),
                        stderr: rows.iter().map(|r| r.stderr).collect(),
                        extended: ext.as_ref().map_or_else(|| d_nom.clone(), minus),
                        nominal: d_nom,
                    }
                })
                .collect();
            Ok(EstimatedComparison {
                band,
                periods,
                measured,
                nominal: nom,
                extended: ext,
                differences,
            })
        })
        .collect()
}
