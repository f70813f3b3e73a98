//! One experiment, any estimator: where each estimator reads its records in one uniformly
//! sampled input-output signal, as the excitation laid them out.
//!
//! Siddiqi's estimator reads whole periods from the start of the excitation to the end of the
//! signal; the multi-experiment estimator reads each phase-shifted copy of a chirp train; the
//! line estimators read the measured blocks of a periodic multisine (a `+u` block and, when the
//! design pairs it, a `-u` block). Times are absolute: the estimators reference phases to them,
//! so a window that starts between samples shifts the window, never the phase.

use crate::error::{Error, Result};
use crate::estimate::HtfEstimate;
use crate::lines::{periodic_lines, periodic_lines_paired, LineSpec};
use crate::multi::{multi_experiment, MultiOptions};
use crate::record::deviation_record;
use crate::siddiqi::{siddiqi, SiddiqiDesign};
use crate::smooth::Alpha;
use htfid_data::TimeSeries;

/// How far a window's length may be from a whole number of samples, in samples.
const WHOLE_SAMPLE_TOL: f64 = 1e-6;

/// A uniformly sampled input-output signal: `u[i]` and `y[i]` at `t_start + i * dt`. The output
/// is a deviation from the unexcited orbit.
#[derive(Debug, Clone, Copy)]
pub struct Sampled<'a> {
    /// Input samples.
    pub u: &'a [f64],
    /// Output samples (deviation from the orbit).
    pub y: &'a [f64],
    /// Sample interval, s.
    pub dt: f64,
    /// Time of the first sample, s.
    pub t_start: f64,
}

/// A multisine's measured windows (`[start, end)`, absolute times), with its lines.
#[derive(Debug, Clone)]
pub struct LineWindows {
    /// The multisine's period and excited lines.
    pub spec: LineSpec,
    /// The `+u` block's measured window.
    pub positive: (f64, f64),
    /// The `-u` block's measured window, when the design pairs the blocks.
    pub negative: Option<(f64, f64)>,
}

/// Where the excitation lies in the signal.
#[derive(Debug, Clone, Default)]
pub struct Layout {
    /// Start of the excited part, s: Siddiqi's estimator reads whole periods from here.
    pub excited_from: f64,
    /// A chirp train's copies: each copy's start, s, and the copies' common length, s.
    pub copies: Option<(Vec<f64>, f64)>,
    /// A periodic multisine's measured blocks.
    pub lines: Option<LineWindows>,
}

/// The estimator to run, with its options.
#[derive(Debug, Clone)]
pub enum Estimator {
    /// Siddiqi's regularised single-record estimator.
    Siddiqi(Alpha),
    /// The multi-experiment estimator over a chirp train's copies.
    Multi(MultiOptions),
    /// The periodic-multisine line estimator (paired when the layout has a `-u` block).
    Lines,
}

impl Estimator {
    /// The estimator's name in configs and file names.
    pub fn name(&self) -> &'static str {
        match self {
            Estimator::Siddiqi(_) => "siddiqi",
            Estimator::Multi(_) => "multi",
            Estimator::Lines => "lines",
        }
    }
}

/// The frequency response the estimators are asked for.
#[derive(Debug, Clone, Copy)]
pub struct Request<'a> {
    /// The pumping period, s.
    pub period: f64,
    /// Harmonics to estimate.
    pub harmonics: &'a [i32],
    /// Output frequency band, rad/s.
    pub band: (f64, f64),
}

/// Estimates the HTFs of `signal` with `estimator`, reading the records `layout` names.
/// Line estimates keep only the rows whose output frequency lies in the band (the line
/// estimator also returns mirror images at other frequencies).
pub fn estimate_experiment(
    signal: &Sampled<'_>,
    layout: &Layout,
    request: &Request<'_>,
    estimator: &Estimator,
) -> Result<HtfEstimate> {
    let Request {
        period,
        harmonics,
        band,
    } = *request;
    if !(period.is_finite() && period > 0.0) {
        return Err(Error::InvalidPeriod { period });
    }
    match estimator {
        Estimator::Siddiqi(alpha) => {
            let (start, duration) =
                siddiqi_window(signal.u.len(), signal.dt, signal.t_start, layout, request)?;
            let rec = window(signal, start, duration)?;
            siddiqi(&rec, period, harmonics, band, *alpha)
        }
        Estimator::Multi(options) => {
            let (starts, duration) = layout.copies.as_ref().ok_or(Error::MissingLayout {
                estimator: "multi",
                needs: "a chirp train's phase-shifted copies",
            })?;
            let periods = (duration / period).floor();
            if periods < 1.0 {
                return Err(Error::CopyShorterThanPeriod {
                    duration: *duration,
                    period,
                });
            }
            let records = starts
                .iter()
                .map(|&s| window(signal, s, periods * period))
                .collect::<Result<Vec<_>>>()?;
            multi_experiment(&records, period, harmonics, band, options)
        }
        Estimator::Lines => {
            let lines = layout.lines.as_ref().ok_or(Error::MissingLayout {
                estimator: "lines",
                needs: "a periodic multisine design",
            })?;
            let (a, b) = lines.positive;
            let plus = window(signal, a, b - a)?;
            let e = match lines.negative {
                Some((a, b)) => {
                    let minus = window(signal, a, b - a)?;
                    periodic_lines_paired(&plus, &minus, period, &lines.spec, harmonics)?
                }
                None => periodic_lines(&plus, period, &lines.spec, harmonics)?,
            };
            e.within_band(band)
        }
    }
}

/// An experiment's estimator prepared from its input before the output is known (while the
/// experiment runs, or once for several outputs of one input): what can be done with the
/// input alone is done in [`Design::new`], the rest in [`Design::estimate`]. For Siddiqi's
/// estimator at a fixed weight that is most of the work ([`SiddiqiDesign`]); the other
/// estimators keep the input and do everything in [`Design::estimate`]. Either way
/// `Design::new(..)?.estimate(y)` equals [`estimate_experiment`] on the same signal, bit for
/// bit.
#[derive(Debug)]
pub struct Design {
    u: Vec<f64>,
    dt: f64,
    t_start: f64,
    layout: Layout,
    period: f64,
    harmonics: Vec<i32>,
    band: (f64, f64),
    estimator: Estimator,
    /// Siddiqi's estimator prepared, with the start and length of its window.
    siddiqi: Option<(SiddiqiDesign, f64, f64)>,
}

impl Design {
    /// Prepares `estimator` for the input `u` sampled at `dt` from `t_start`, laid out as
    /// `layout` says.
    ///
    /// # Errors
    /// As [`estimate_experiment`], for what the input alone can tell.
    pub fn new(
        (u, dt, t_start): (&[f64], f64, f64),
        layout: &Layout,
        request: &Request<'_>,
        estimator: &Estimator,
    ) -> Result<Self> {
        let siddiqi = match estimator {
            Estimator::Siddiqi(Alpha::Fixed(alpha)) => {
                let (start, duration) = siddiqi_window(u.len(), dt, t_start, layout, request)?;
                // The output is not read: the input stands in for it.
                let signal = Sampled {
                    u,
                    y: u,
                    dt,
                    t_start,
                };
                let rec = window(&signal, start, duration)?;
                let design = SiddiqiDesign::new(
                    &rec,
                    request.period,
                    request.harmonics,
                    request.band,
                    *alpha,
                )?;
                Some((design, start, duration))
            }
            _ => None,
        };
        Ok(Self {
            u: u.to_vec(),
            dt,
            t_start,
            layout: layout.clone(),
            period: request.period,
            harmonics: request.harmonics.to_vec(),
            band: request.band,
            estimator: estimator.clone(),
            siddiqi,
        })
    }

    /// The input it was prepared from.
    pub fn input(&self) -> &[f64] {
        &self.u
    }

    /// The `(n, omega)` of the estimate's rows, in the order of [`HtfEstimate::rows`], when
    /// the input alone fixes them (Siddiqi's estimator at a fixed weight); `None` otherwise.
    pub fn points(&self) -> Option<Vec<(i32, f64)>> {
        self.siddiqi.as_ref().map(|(design, _, _)| design.points())
    }

    /// The estimate from the output `y` (a deviation from the orbit, sampled with the input).
    ///
    /// # Errors
    /// As [`estimate_experiment`].
    pub fn estimate(&self, y: &[f64]) -> Result<HtfEstimate> {
        let signal = Sampled {
            u: &self.u,
            y,
            dt: self.dt,
            t_start: self.t_start,
        };
        match &self.siddiqi {
            Some((design, start, duration)) => {
                design.estimate(&window(&signal, *start, *duration)?)
            }
            None => {
                let request = Request {
                    period: self.period,
                    harmonics: &self.harmonics,
                    band: self.band,
                };
                estimate_experiment(&signal, &self.layout, &request, &self.estimator)
            }
        }
    }
}

/// The window Siddiqi's estimator reads: whole periods from the start of the excitation to
/// the end of the signal.
fn siddiqi_window(
    samples: usize,
    dt: f64,
    t_start: f64,
    layout: &Layout,
    request: &Request<'_>,
) -> Result<(f64, f64)> {
    let period = request.period;
    if !(period.is_finite() && period > 0.0) {
        return Err(Error::InvalidPeriod { period });
    }
    let end = t_start + samples as f64 * dt;
    let periods = ((end - layout.excited_from) / period + 1e-9).floor();
    Ok((layout.excited_from, periods * period))
}

/// The record of `duration` seconds (a whole number of samples) from the first sample at or
/// after `start`.
fn window(signal: &Sampled<'_>, start: f64, duration: f64) -> Result<TimeSeries> {
    let dt = signal.dt;
    if !(dt.is_finite() && dt > 0.0) {
        return Err(Error::InvalidTimeStep { dt });
    }
    let i0 = ((start - signal.t_start) / dt - WHOLE_SAMPLE_TOL)
        .ceil()
        .max(0.0) as usize;
    let n = (duration / dt).round() as usize;
    if (n as f64 * dt - duration).abs() > WHOLE_SAMPLE_TOL * dt {
        return Err(Error::WindowNotWholeSamples { duration, dt });
    }
    let end = signal.t_start + signal.u.len() as f64 * dt;
    if i0 + n > signal.u.len() || signal.y.len() != signal.u.len() {
        return Err(Error::WindowOutsideSignal {
            start,
            end: start + duration,
            signal_end: end,
        });
    }
    deviation_record(
        signal.u[i0..i0 + n].to_vec(),
        signal.y[i0..i0 + n].to_vec(),
        dt,
        signal.t_start + i0 as f64 * dt,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `u = y = samples` at `dt` from `t_start`.
    fn signal(samples: &[f64], dt: f64, t_start: f64) -> Sampled<'_> {
        Sampled {
            u: samples,
            y: samples,
            dt,
            t_start,
        }
    }

    /// A window's start snaps to the first sample at or after it and keeps absolute time.
    #[test]
    fn a_window_starts_at_the_first_sample_at_or_after_its_start() {
        let u: Vec<f64> = (0..100).map(f64::from).collect();
        let s = signal(&u, 0.1, 1.0);
        let r = window(&s, 2.05, 1.0).unwrap();
        assert_eq!(r.len(), 10);
        assert!((r.input()[0] - 11.0).abs() < 1e-12, "{}", r.input()[0]);
        assert!((r.time()[0] - 2.1).abs() < 1e-12);
    }

    #[test]
    fn a_window_past_the_end_or_between_samples_is_refused() {
        let u = vec![0.0; 100];
        let s = signal(&u, 0.1, 0.0);
        assert!(matches!(
            window(&s, 5.0, 6.0),
            Err(Error::WindowOutsideSignal { .. })
        ));
        assert!(matches!(
            window(&s, 0.0, 1.05),
            Err(Error::WindowNotWholeSamples { .. })
        ));
    }

    #[test]
    fn an_estimator_without_its_layout_says_what_it_needs() {
        let u = vec![0.0; 100];
        let s = signal(&u, 0.1, 0.0);
        let request = Request {
            period: 1.0,
            harmonics: &[0],
            band: (1.0, 10.0),
        };
        let err = estimate_experiment(
            &s,
            &Layout::default(),
            &request,
            &Estimator::Multi(MultiOptions::default()),
        )
        .unwrap_err();
        assert!(err.to_string().contains("chirp train"), "{err}");
    }
}
