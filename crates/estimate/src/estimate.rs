//! The result type shared by all non-parametric estimators.

use std::fmt;

use num_complex::Complex64;
use serde::Serialize;

use crate::error::{Error, Result};

/// Which estimator produced an [`HtfEstimate`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
#[non_exhaustive]
pub enum Method {
    /// Single-record smoothness-regularised least squares ([`siddiqi`](crate::siddiqi)).
    Siddiqi,
    /// Per-bin least squares over several records.
    MultiExperiment,
    /// Several records, ridge-regularised per bin.
    MultiExperimentRidge,
    /// Several records, smoothness-regularised across bins.
    MultiExperimentSmooth,
    /// Several records with local polynomial transient suppression.
    MultiExperimentLpm,
    /// Ratios at the lines of a periodic multisine.
    PeriodicLines,
    /// Periodic lines from a `+u` / `-u` record pair.
    PeriodicLinesPaired,
}

impl Method {
    /// Short kebab-case name, as written to files.
    pub fn as_str(&self) -> &'static str {
        match self {
            Self::Siddiqi => "siddiqi",
            Self::MultiExperiment => "multi-experiment",
            Self::MultiExperimentRidge => "multi-experiment-ridge",
            Self::MultiExperimentSmooth => "multi-experiment-smooth",
            Self::MultiExperimentLpm => "multi-experiment-lpm",
            Self::PeriodicLines => "periodic-lines",
            Self::PeriodicLinesPaired => "periodic-lines-paired",
        }
    }
}

impl Method {
    /// The bias a noise-free re-run of the experiment measures for this estimator: the
    /// nonlinear distortion of a line estimator (only its odd orders when `+u` / `-u` pairs
    /// cancel the even ones); `None` for the estimators that carry their own bias estimate
    /// ([`HtfEstimate::bias`]).
    pub fn distortion(&self) -> Option<BiasSource> {
        match self {
            Self::PeriodicLinesPaired => Some(BiasSource::PairingDistortion),
            Self::PeriodicLines => Some(BiasSource::NonlinearDistortion),
            _ => None,
        }
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Where a systematic error (bias) of an HTF estimate comes from, when it has a known source
/// that can be estimated ([`HtfEstimate::bias`]); written to files in snake case.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum BiasSource {
    /// The odd-order (third and higher) nonlinear response that a `+u` / `-u` pairing cannot
    /// cancel ([`periodic_lines_paired`](crate::periodic_lines_paired)).
    PairingDistortion,
    /// The nonlinear response of an unpaired estimate (even and odd orders).
    NonlinearDistortion,
    /// The smoothing bias of a regularised estimator: the penalty flattens the curvature of
    /// `G_n` ([`siddiqi`](crate::siddiqi), the regularised multi-experiment estimators).
    Smoothing,
}

impl BiasSource {
    /// Snake-case name, as written to files.
    pub fn as_str(&self) -> &'static str {
        match self {
            Self::PairingDistortion => "pairing_distortion",
            Self::NonlinearDistortion => "nonlinear_distortion",
            Self::Smoothing => "smoothing",
        }
    }
}

/// Estimated harmonic transfer functions `G_n(j omega)` at output frequencies `omega`.
///
/// For each harmonic `harmonics[i]` there are parallel arrays of output frequencies (rad/s,
/// ascending), complex values and standard errors. A standard error is
/// `sqrt(E|G_hat - E G_hat|^2)`, the spread of the complex estimate (each of the real and
/// imaginary parts has about `stderr / sqrt(2)` when the noise is circular); `NaN` means that no
/// residual degrees of freedom were left to estimate it and `inf` that the bin was rank
/// deficient.
#[derive(Debug, Clone, Serialize)]
pub struct HtfEstimate {
    harmonics: Vec<i32>,
    omegas: Vec<Vec<f64>>,
    values: Vec<Vec<Complex64>>,
    stderr: Vec<Vec<f64>>,
    cond: Option<Vec<f64>>,
    alpha: Option<f64>,
    alpha_effective: Option<f64>,
    dof: Option<f64>,
    bias: Option<(BiasSource, Vec<Vec<Complex64>>)>,
    method: Method,
}

/// One row of an estimate, as written to CSV (`omega,n,re,im,stderr`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct HtfRow {
    /// Output frequency, rad/s.
    pub omega: f64,
    /// Harmonic index.
    pub n: i32,
    /// `G_n(j omega)`.
    pub value: Complex64,
    /// Standard error of `value` (see [`HtfEstimate`]).
    pub stderr: f64,
}

/// All values of one harmonic.
#[derive(Debug, Clone, Copy)]
pub struct HarmonicSeries<'a> {
    /// Harmonic index.
    pub n: i32,
    /// Output frequencies, rad/s.
    pub omegas: &'a [f64],
    /// Estimates.
    pub values: &'a [Complex64],
    /// Standard errors.
    pub stderr: &'a [f64],
}

/// The level, in standard errors, that noise alone passes at any of `points` independent
/// frequencies with probability `false_alarm` (in `(0, 1)`), and never below 2.
///
/// A circular complex estimate's noise `e` with `E|e|^2 = stderr^2` has `|e|^2 / stderr^2`
/// exponentially distributed, so `|e| > t stderr` with probability `exp(-t^2)`; over `points`
/// frequencies the chance that any passes is at most `points exp(-t^2)` (Bonferroni), which is
/// `false_alarm` at `t = sqrt(ln(points / false_alarm))`.
pub fn band_level(points: usize, false_alarm: f64) -> f64 {
    (points.max(1) as f64 / false_alarm).ln().sqrt().max(2.0)
}

impl HarmonicSeries<'_> {
    /// The largest `|G_n|` among the values that stand out of their noise over the whole
    /// band: above [`band_level`]`(points, false_alarm)` standard errors. `None` when none does
    /// (or no value has a positive, finite standard error).
    pub fn largest_significant(&self, false_alarm: f64) -> Option<f64> {
        let level = band_level(self.values.len(), false_alarm);
        self.values
            .iter()
            .zip(self.stderr)
            .filter(|(v, &s)| s > 0.0 && s.is_finite() && v.norm() > level * s)
            .map(|(v, _)| v.norm())
            .reduce(f64::max)
    }
}

impl HtfEstimate {
    /// Assembles an estimate, checking that every harmonic has one value and one standard error
    /// per frequency.
    pub fn new(
        method: Method,
        harmonics: Vec<i32>,
        omegas: Vec<Vec<f64>>,
        values: Vec<Vec<Complex64>>,
        stderr: Vec<Vec<f64>>,
    ) -> Result<Self> {
        crate::record::validate_harmonics(&harmonics)?;
        let h = harmonics.len();
        for (what, found) in [
            ("omegas", omegas.len()),
            ("values", values.len()),
            ("stderr", stderr.len()),
        ] {
            if found != h {
                return Err(Error::InconsistentEstimate {
                    what,
                    found,
                    expected: h,
                });
            }
        }
        for i in 0..h {
            let expected = omegas[i].len();
            for (what, found) in [("values", values[i].len()), ("stderr", stderr[i].len())] {
                if found != expected {
                    return Err(Error::InconsistentEstimate {
                        what,
                        found,
                        expected,
                    });
                }
            }
        }
        Ok(Self {
            harmonics,
            omegas,
            values,
            stderr,
            cond: None,
            alpha: None,
            alpha_effective: None,
            dof: None,
            bias: None,
            method,
        })
    }

    /// The rows whose output frequency lies in `band` (inclusive), per harmonic. Condition
    /// numbers, smoothing weights and bias estimates are dropped: they belong to the full grid.
    pub fn within_band(&self, band: (f64, f64)) -> Result<Self> {
        let inside = |w: &f64| *w >= band.0 && *w <= band.1;
        let mut omegas = Vec::with_capacity(self.harmonics.len());
        let mut values = Vec::with_capacity(self.harmonics.len());
        let mut stderr = Vec::with_capacity(self.harmonics.len());
        for i in 0..self.harmonics.len() {
            let keep: Vec<usize> = (0..self.omegas[i].len())
                .filter(|&j| inside(&self.omegas[i][j]))
                .collect();
            omegas.push(keep.iter().map(|&j| self.omegas[i][j]).collect());
            values.push(keep.iter().map(|&j| self.values[i][j]).collect());
            stderr.push(keep.iter().map(|&j| self.stderr[i][j]).collect());
        }
        Self::new(self.method, self.harmonics.clone(), omegas, values, stderr)
    }

    /// Attaches per-bin condition numbers; all harmonics must share one frequency grid of the
    /// same length.
    pub fn with_cond(mut self, cond: Vec<f64>) -> Result<Self> {
        for om in &self.omegas {
            if om.len() != cond.len() {
                return Err(Error::InconsistentEstimate {
                    what: "cond",
                    found: cond.len(),
                    expected: om.len(),
                });
            }
        }
        self.cond = Some(cond);
        Ok(self)
    }

    /// Records the regularisation weight: `alpha` as the user states it (dimensionless) and the
    /// weight actually used in the normal equations.
    pub fn with_alpha(mut self, alpha: f64, alpha_effective: f64) -> Self {
        self.alpha = Some(alpha);
        self.alpha_effective = Some(alpha_effective);
        self
    }

    /// Records the residual degrees of freedom behind the standard errors.
    pub fn with_dof(mut self, dof: f64) -> Self {
        self.dof = Some(dof);
        self
    }

    /// Attaches an estimate of the systematic error `E[G_hat] - G` at every value (aligned with
    /// the values of every harmonic) and its source.
    pub fn with_bias(mut self, source: BiasSource, bias: Vec<Vec<Complex64>>) -> Result<Self> {
        if bias.len() != self.harmonics.len() {
            return Err(Error::InconsistentEstimate {
                what: "bias",
                found: bias.len(),
                expected: self.harmonics.len(),
            });
        }
        for (b, om) in bias.iter().zip(&self.omegas) {
            if b.len() != om.len() {
                return Err(Error::InconsistentEstimate {
                    what: "bias",
                    found: b.len(),
                    expected: om.len(),
                });
            }
        }
        self.bias = Some((source, bias));
        Ok(self)
    }

    /// The estimated systematic error `E[G_hat] - G` per harmonic (aligned with the values) and
    /// its source, when the estimator knows one ([`BiasSource`]). The standard errors do not
    /// include it.
    pub fn bias(&self) -> Option<(BiasSource, &[Vec<Complex64>])> {
        self.bias.as_ref().map(|(s, b)| (*s, b.as_slice()))
    }

    /// The estimated bias at `omega` of harmonic `n` (the value estimated nearest to `omega`,
    /// within `1e-9` relative), when there is one.
    pub fn bias_at(&self, n: i32, omega: f64) -> Option<Complex64> {
        let (_, bias) = self.bias.as_ref()?;
        let i = self.harmonics.iter().position(|&m| m == n)?;
        let j = self.omegas[i]
            .iter()
            .position(|&w| (w - omega).abs() <= 1e-9 * omega.abs().max(1.0))?;
        Some(bias[i][j])
    }

    /// Harmonic indices, in the order given to the estimator.
    pub fn harmonics(&self) -> &[i32] {
        &self.harmonics
    }

    /// The values of harmonic `n`, if it was estimated.
    pub fn harmonic(&self, n: i32) -> Option<HarmonicSeries<'_>> {
        let i = self.harmonics.iter().position(|&m| m == n)?;
        Some(HarmonicSeries {
            n,
            omegas: &self.omegas[i],
            values: &self.values[i],
            stderr: &self.stderr[i],
        })
    }

    /// Every value as `(omega, n, G, stderr)`, harmonic by harmonic, ascending in `omega`.
    pub fn rows(&self) -> impl Iterator<Item = HtfRow> + '_ {
        self.harmonics.iter().enumerate().flat_map(move |(i, &n)| {
            self.omegas[i]
                .iter()
                .zip(&self.values[i])
                .zip(&self.stderr[i])
                .map(move |((&omega, &value), &stderr)| HtfRow {
                    omega,
                    n,
                    value,
                    stderr,
                })
        })
    }

    /// Condition number of the per-bin least-squares problem (multi-experiment estimators),
    /// aligned with every harmonic's frequencies.
    pub fn cond(&self) -> Option<&[f64]> {
        self.cond.as_deref()
    }

    /// Dimensionless regularisation weight, when one was used.
    pub fn alpha(&self) -> Option<f64> {
        self.alpha
    }

    /// The weight as used in the normal equations (`alpha` times the mean diagonal of the data
    /// Gram matrix).
    pub fn alpha_effective(&self) -> Option<f64> {
        self.alpha_effective
    }

    /// Residual degrees of freedom (complex) behind the standard errors; for pooled per-bin
    /// estimates, the smallest over the bins.
    pub fn dof(&self) -> Option<f64> {
        self.dof
    }

    /// The estimator that produced this estimate.
    pub fn method(&self) -> Method {
        self.method
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_walk_harmonics_then_frequencies() {
        let est = HtfEstimate::new(
            Method::PeriodicLines,
            vec![0, 1],
            vec![vec![1.0, 2.0], vec![3.0]],
            vec![
                vec![Complex64::new(1.0, 0.0), Complex64::new(2.0, 0.0)],
                vec![Complex64::new(0.0, 3.0)],
            ],
            vec![vec![0.1, 0.2], vec![0.3]],
        )
        .unwrap();
        let rows: Vec<(i32, f64)> = est.rows().map(|r| (r.n, r.omega)).collect();
        assert_eq!(rows, [(0, 1.0), (0, 2.0), (1, 3.0)]);
        assert!(est.with_cond(vec![1.0, 1.0]).is_err());
    }

    #[test]
    fn inconsistent_lengths_are_rejected() {
        let e = HtfEstimate::new(
            Method::Siddiqi,
            vec![0],
            vec![vec![1.0, 2.0]],
            vec![vec![Complex64::new(1.0, 0.0)]],
            vec![vec![0.1, 0.2]],
        )
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "estimate arrays are inconsistent: values has length 1, expected 2"
        );
    }
}
