//! Direct estimation at the lines of a periodic multisine.

use std::collections::HashMap;
use std::f64::consts::PI;

use num_complex::Complex64;
use rustfft::FftPlanner;

use crate::error::{Error, Result};
use crate::estimate::{HtfEstimate, Method};
use crate::record::{check_record, validate_harmonics, validate_period, Spectrum};
use htfid_data::TimeSeries;

/// Tolerance on "whole number" of periods and samples, as for records.
const WHOLE_TOL: f64 = 1e-6;
/// A line whose mean input is below this fraction of the largest input bin is unexcited.
const UNEXCITED: f64 = 1e-10;

/// The excited lines of a periodic multisine.
#[derive(Debug, Clone, PartialEq)]
pub struct LineSpec {
    multisine_period: f64,
    lines: Vec<usize>,
}

impl LineSpec {
    /// `lines` are DFT bins of one multisine period: line `b` is at `2 pi b / multisine_period`
    /// rad/s. Lines must be `>= 1` and distinct; the period must be positive and, when used, a
    /// whole number of system periods and of samples.
    pub fn new(multisine_period: f64, lines: Vec<usize>) -> Result<Self> {
        validate_period(multisine_period)?;
        if lines.is_empty() {
            return Err(Error::InvalidOption {
                name: "lines",
                value: 0.0,
                reason: "at least one line is needed",
            });
        }
        for (i, &b) in lines.iter().enumerate() {
            if b == 0 {
                return Err(Error::InvalidOption {
                    name: "lines",
                    value: 0.0,
                    reason: "lines must be >= 1 (DC carries no harmonic information)",
                });
            }
            if lines[..i].contains(&b) {
                return Err(Error::DuplicateLine { line: b });
            }
        }
        Ok(Self {
            multisine_period,
            lines,
        })
    }

    /// Multisine period, s.
    pub fn multisine_period(&self) -> f64 {
        self.multisine_period
    }

    /// Excited lines (bins of one multisine period).
    pub fn lines(&self) -> &[usize] {
        &self.lines
    }
}

/// Estimates `G_n` at the output frequencies reached by the lines of a periodic multisine from a
/// steady-state record of `M >= 1` whole multisine periods.
///
/// With `Q` system periods per multisine period, line `b` reaches output bin `b + nQ` through
/// harmonic `n`, so `G_n(j w_{b+nQ}) = Y[b + nQ] / U[b]`; its mirror gives
/// `G_n(j(n wp - w_b)) = Y[-b + nQ] / conj(U[b])` (this output frequency may be negative). Every
/// `(signed line, harmonic)` pair must reach its own bin, otherwise [`Error::LineCollision`].
/// Each period is transformed with absolute-time phase; `Y` and `U` are averaged over periods and
/// the standard error is the period-to-period scatter of `Y`,
/// `sqrt(sum_m |Y_m - Y_mean|^2 / (M (M - 1))) / |U_mean|`, with `M - 1` complex degrees of freedom.
/// With a single period (`M = 1`) the output noise level is instead the mean power of the output
/// bins whose residue modulo the period belongs to no line or mirror (they receive no linear
/// response at any harmonic) and that hold no orbit harmonic; when every residue is taken, the
/// bins no estimated (line, harmonic) pair reaches, which also hold the response through
/// harmonics outside `harmonics` and so overstate the noise (NaN when no bin is left).
/// The input is taken as noise free, and output bins are assumed to receive nothing from
/// harmonics outside `harmonics` (unmodelled harmonics alias onto modelled bins).
pub fn periodic_lines(
    record: &TimeSeries,
    period: f64,
    lines: &LineSpec,
    harmonics: &[i32],
) -> Result<HtfEstimate> {
    estimate(record, None, period, lines, harmonics)
}

/// As [`periodic_lines`], from a record driven by `+u` and one driven by `-u` at the same orbit
/// phases (their starts differ by a whole number of periods, else
/// [`Error::PairPhaseMismatch`]; the inputs must agree in time measured from each record's
/// start). Both records are referenced to the plus record's start time. Each period uses `U = (U+ - U-) / 2` and `Y = (Y+ - Y-) / 2`: the linear response
/// survives while every even-order term of a nonlinear response (equal for `+u` and `-u`)
/// cancels.
pub fn periodic_lines_paired(
    plus: &TimeSeries,
    minus: &TimeSeries,
    period: f64,
    lines: &LineSpec,
    harmonics: &[i32],
) -> Result<HtfEstimate> {
    if plus.len() != minus.len() || (plus.dt() - minus.dt()).abs() > 1e-12 * plus.dt() {
        return Err(Error::PairMismatch {
            plus_samples: plus.len(),
            plus_dt: plus.dt(),
            minus_samples: minus.len(),
            minus_dt: minus.dt(),
        });
    }
    let shift = (minus.time()[0] - plus.time()[0]) / period;
    if (shift - shift.round()).abs() > WHOLE_TOL {
        return Err(Error::PairPhaseMismatch {
            plus_start: plus.time()[0],
            minus_start: minus.time()[0],
            period,
        });
    }
    estimate(plus, Some(minus), period, lines, harmonics)
}

fn whole(x: f64) -> Option<usize> {
    let r = x.round();
    (r >= 1.0 && (x - r).abs() <= WHOLE_TOL).then_some(r as usize)
}

fn estimate(
    plus: &TimeSeries,
    minus: Option<&TimeSeries>,
    period: f64,
    spec: &LineSpec,
    harmonics: &[i32],
) -> Result<HtfEstimate> {
    check_record(plus)?;
    if let Some(m) = minus {
        check_record(m)?;
    }
    validate_period(period)?;
    validate_harmonics(harmonics)?;
    let dt = plus.dt();
    let tm = spec.multisine_period;
    let q = whole(tm / period).ok_or(Error::MultisineNotWholePeriods {
        multisine_period: tm,
        period,
        ratio: tm / period,
    })? as i64;
    let nm = whole(tm / dt).ok_or(Error::MultisineNotWholeSamples {
        multisine_period: tm,
        dt,
        ratio: tm / dt,
    })?;
    if plus.len() % nm != 0 {
        return Err(Error::NotWholeMultisinePeriods {
            samples: plus.len(),
            period_samples: nm,
        });
    }
    let periods = plus.len() / nm;
    if periods < 1 {
        return Err(Error::TooFewPeriods {
            periods,
            minimum: 1,
        });
    }
    let below_nyquist = |k: i64| 2 * k.unsigned_abs() < nm as u64;
    let dw = 2.0 * PI / (nm as f64 * dt);
    for &b in &spec.lines {
        if !below_nyquist(b as i64) {
            return Err(Error::InvalidLine {
                line: b,
                nyquist_bin: nm / 2,
            });
        }
    }
    // Every (signed line, harmonic) pair and its output bin; no bin may be reached twice.
    let mut targets: Vec<(usize, i64, usize, i64)> = Vec::new(); // (line idx, sign, harmonic idx, bin)
    let mut owner: HashMap<i64, (i64, i32)> = HashMap::new();
    for (li, &b) in spec.lines.iter().enumerate() {
        for sign in [1i64, -1] {
            let s = sign * b as i64;
            for (hi, &n) in harmonics.iter().enumerate() {
                let bin = s + i64::from(n) * q;
                if !below_nyquist(bin) {
                    return Err(Error::BeyondNyquist {
                        omega: bin as f64 * dw,
                        n,
                        needed: bin as f64 * dw,
                        nyquist: PI / dt,
                    });
                }
                if let Some(&(line_b, n_b)) = owner.get(&bin) {
                    return Err(Error::LineCollision {
                        bin,
                        line_a: line_b,
                        n_a: n_b,
                        line_b: s,
                        n_b: n,
                    });
                }
                owner.insert(bin, (s, n));
                targets.push((li, sign, hi, bin));
            }
        }
    }
    let fft = FftPlanner::new().plan_fft_forward(nm);
    let nl = spec.lines.len();
    let nt = targets.len();
    // Per period: U at the lines, Y at the targets.
    let mut u_lines = vec![Complex64::new(0.0, 0.0); periods * nl];
    let mut y_bins = vec![Complex64::new(0.0, 0.0); periods * nt];
    // Largest input bin anywhere, the reference for "this line is not excited".
    let mut largest = 0.0f64;
    // With one period there is no period-to-period scatter: the noise level is taken from the
    // output bins that no (line, harmonic) pair reaches and that hold no orbit harmonic.
    let mut free_power = 0.0f64;
    let mut free_bins = 0usize;
    for m in 0..periods {
        let range = m * nm..(m + 1) * nm;
        let t0 = plus.time()[0] + (m * nm) as f64 * dt;
        let mut su = Spectrum::new(&plus.input()[range.clone()], dt, t0, &fft);
        let mut sy = Spectrum::new(&plus.output()[range.clone()], dt, t0, &fft);
        if let Some(minus) = minus {
            // The minus record is referenced to the plus record's start: both start at the same
            // orbit phase (checked below), so the LTP response is the same in local time, and
            // only with a common time reference do the even-order responses, equal in local
            // time, cancel in the half difference.
            let t0m = t0;
            let mu = Spectrum::new(&minus.input()[range.clone()], dt, t0m, &fft);
            let my = Spectrum::new(&minus.output()[range], dt, t0m, &fft);
            su = su.half_difference(&mu);
            sy = sy.half_difference(&my);
        }
        for (li, &b) in spec.lines.iter().enumerate() {
            u_lines[m * nl + li] = su.at(b as i64);
        }
        largest = (1..=(nm as i64 - 1) / 2)
            .map(|k| su.at(k).norm())
            .fold(largest, f64::max);
        for (ti, t) in targets.iter().enumerate() {
            y_bins[m * nt + ti] = sy.at(t.3);
        }
        if periods == 1 {
            // Bins whose residue modulo the period no line (or mirror) has receive no linear
            // response at any harmonic, not only at the estimated ones: pure noise (plus
            // odd-order distortion). Without such residues, fall back to the bins no estimated
            // (line, harmonic) pair reaches.
            let line_residues: std::collections::HashSet<i64> = spec
                .lines
                .iter()
                .flat_map(|&b| [(b as i64).rem_euclid(q), (-(b as i64)).rem_euclid(q)])
                .collect();
            let any_free_residue = (1..q).any(|r| !line_residues.contains(&r));
            for k in 1..=(nm as i64 - 1) / 2 {
                let free = if any_free_residue {
                    k % q != 0 && !line_residues.contains(&k.rem_euclid(q))
                } else {
                    k % q != 0 && !owner.contains_key(&k) && !owner.contains_key(&-k)
                };
                if free {
                    free_power += sy.at(k).norm_sqr();
                    free_bins += 1;
                }
            }
        }
    }
    let mean = |v: &[Complex64], stride: usize, i: usize| -> Complex64 {
        (0..periods).map(|m| v[m * stride + i]).sum::<Complex64>() / periods as f64
    };
    let u_mean: Vec<Complex64> = (0..nl).map(|li| mean(&u_lines, nl, li)).collect();
    for (li, u) in u_mean.iter().enumerate() {
        if u.norm() <= UNEXCITED * largest {
            return Err(Error::LineNotExcited {
                line: spec.lines[li],
                magnitude: u.norm(),
                largest,
            });
        }
    }
    let h = harmonics.len();
    let mut rows: Vec<Vec<(f64, Complex64, f64)>> = vec![Vec::new(); h];
    for (ti, &(li, sign, hi, bin)) in targets.iter().enumerate() {
        let y_mean = mean(&y_bins, nt, ti);
        let scatter: f64 = (0..periods)
            .map(|m| (y_bins[m * nt + ti] - y_mean).norm_sqr())
            .sum();
        let var_mean = if periods >= 2 {
            scatter / (periods * (periods - 1)) as f64
        } else if free_bins > 0 {
            free_power / free_bins as f64
        } else {
            f64::NAN
        };
        let u = if sign > 0 {
            u_mean[li]
        } else {
            u_mean[li].conj()
        };
        rows[hi].push((bin as f64 * dw, y_mean / u, var_mean.sqrt() / u.norm()));
    }
    for r in &mut rows {
        r.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    let method = if minus.is_some() {
        Method::PeriodicLinesPaired
    } else {
        Method::PeriodicLines
    };
    Ok(HtfEstimate::new(
        method,
        harmonics.to_vec(),
        rows.iter()
            .map(|r| r.iter().map(|v| v.0).collect())
            .collect(),
        rows.iter()
            .map(|r| r.iter().map(|v| v.1).collect())
            .collect(),
        rows.iter()
            .map(|r| r.iter().map(|v| v.2).collect())
            .collect(),
    )?
    .with_dof((periods - 1) as f64))
}
