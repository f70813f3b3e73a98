use std::ops::Range;
use std::path::{Path, PathBuf};

use crate::error::{ColumnId, DataError, Location};

/// Default relative tolerance on the sample step, see [`CsvSpec::time_tolerance`](crate::CsvSpec).
pub const DEFAULT_TIME_TOLERANCE: f64 = 1e-6;

/// A uniformly sampled input/output record.
///
/// Invariants, checked by every constructor: at least 2 samples; `time`, `input` and `output`
/// have equal lengths; all values finite; `time` strictly increasing with a uniform step `dt`
/// (in s) within the tolerance the data were read with. Times are absolute: `time[0]` is the
/// time of the first sample as recorded, not shifted to zero.
#[derive(Debug, Clone, PartialEq)]
pub struct TimeSeries {
    time: Vec<f64>,
    input: Vec<f64>,
    output: Vec<f64>,
    dt: f64,
    source: PathBuf,
}

impl TimeSeries {
    /// Builds a series from explicit sample times, checking the invariants with the default
    /// relative tolerance [`DEFAULT_TIME_TOLERANCE`]. `source` names where the data came from
    /// (used in messages); errors give 0-based sample indices ([`Location::Row`]).
    pub fn new(
        time: Vec<f64>,
        input: Vec<f64>,
        output: Vec<f64>,
        source: impl Into<PathBuf>,
    ) -> Result<Self, DataError> {
        let source = source.into();
        check_lengths(
            &source,
            time.len(),
            &[("input", &input), ("output", &output)],
        )?;
        check_count(&source, time.len(), 2)?;
        for (name, values) in [("time", &time), ("input", &input), ("output", &output)] {
            check_finite_slice(&source, name, values)?;
        }
        let dt = check_uniform(&time, DEFAULT_TIME_TOLERANCE, f64::EPSILON).map_err(|fault| {
            fault.into_error(&source, ColumnId::Name("time".into()), Location::Row)
        })?;
        Ok(Self::from_checked(time, input, output, dt, source))
    }

    /// Builds a series sampled at `rate_hz` starting at `start` s: `time[k] = start + k / rate_hz`.
    pub fn from_sample_rate(
        rate_hz: f64,
        start: f64,
        input: Vec<f64>,
        output: Vec<f64>,
        source: impl Into<PathBuf>,
    ) -> Result<Self, DataError> {
        let source = source.into();
        let dt = check_rate(rate_hz, start)?;
        check_lengths(&source, input.len(), &[("output", &output)])?;
        check_count(&source, input.len(), 2)?;
        for (name, values) in [("input", &input), ("output", &output)] {
            check_finite_slice(&source, name, values)?;
        }
        let time = uniform_times(start, dt, input.len());
        Ok(Self::from_checked(time, input, output, dt, source))
    }

    /// Assembles a series whose invariants the caller has already established.
    pub(crate) fn from_checked(
        time: Vec<f64>,
        input: Vec<f64>,
        output: Vec<f64>,
        dt: f64,
        source: PathBuf,
    ) -> Self {
        Self {
            time,
            input,
            output,
            dt,
            source,
        }
    }

    /// Sample times in s (absolute, strictly increasing, uniform).
    pub fn time(&self) -> &[f64] {
        &self.time
    }

    /// The input (excitation, e.g. applied force in N) per sample.
    pub fn input(&self) -> &[f64] {
        &self.input
    }

    /// The output (response, e.g. position in m) per sample.
    pub fn output(&self) -> &[f64] {
        &self.output
    }

    /// The sample step in s. Read from a time column it is `(t_last - t_first) / (len - 1)`,
    /// the least noisy estimate; from a sample rate it is `1 / rate`.
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// The sample rate `1 / dt` in Hz.
    pub fn sample_rate(&self) -> f64 {
        1.0 / self.dt
    }

    /// Where the data came from.
    pub fn source(&self) -> &Path {
        &self.source
    }

    /// Number of samples (at least 2).
    pub fn len(&self) -> usize {
        self.time.len()
    }

    /// Always `false`: a series holds at least 2 samples.
    pub fn is_empty(&self) -> bool {
        self.time.is_empty()
    }

    /// The samples `range` (0-based, end exclusive), keeping their absolute times and `dt`.
    /// The range must lie within the series and hold at least 2 samples.
    pub fn slice(&self, range: Range<usize>) -> Result<Self, DataError> {
        let Range { start, end } = range;
        if start > end || end > self.len() || end - start < 2 {
            return Err(DataError::InvalidRange {
                start,
                end,
                len: self.len(),
            });
        }
        Ok(Self::from_checked(
            self.time[start..end].to_vec(),
            self.input[start..end].to_vec(),
            self.output[start..end].to_vec(),
            self.dt,
            self.source.clone(),
        ))
    }
}

/// Why a time vector is not uniformly sampled, by 0-based sample index.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum TimeFault {
    NonMonotonic {
        index: usize,
        previous: f64,
        found: f64,
    },
    NonUniform {
        index: usize,
        found_dt: f64,
        expected_dt: f64,
        tolerance: f64,
    },
}

impl TimeFault {
    /// Attaches file, column and a mapping from sample index to location.
    pub(crate) fn into_error(
        self,
        path: &Path,
        column: ColumnId,
        locate: impl Fn(usize) -> Location,
    ) -> DataError {
        match self {
            TimeFault::NonMonotonic {
                index,
                previous,
                found,
            } => DataError::NonMonotonicTime {
                path: path.to_path_buf(),
                location: locate(index),
                column,
                previous,
                found,
            },
            TimeFault::NonUniform {
                index,
                found_dt,
                expected_dt,
                tolerance,
            } => DataError::NonUniformTime {
                path: path.to_path_buf(),
                location: locate(index),
                column,
                found_dt,
                expected_dt,
                tolerance,
            },
        }
    }
}

/// Checks that `time` (at least 2 finite values, stored with machine epsilon `eps`: `f64::EPSILON`,
/// or `f32::EPSILON` for times read from `float32`) is strictly increasing with a uniform step and
/// returns that step.
///
/// The reference step is the median increment, so a single gap or glitch is reported at the
/// sample where it happens rather than smeared into a mean that every step then misses. A step
/// passes when `|step - median| <= tolerance * median + 4 eps max(|t_i|, |t_(i-1)|)`: the second
/// term is the rounding floor of differencing two stored times, which dominates for large absolute
/// times (e.g. Unix timestamps) and would otherwise reject perfectly sampled data.
pub(crate) fn check_uniform(time: &[f64], tolerance: f64, eps: f64) -> Result<f64, TimeFault> {
    debug_assert!(time.len() >= 2);
    let mut steps = Vec::with_capacity(time.len() - 1);
    for (i, pair) in time.windows(2).enumerate() {
        if pair[1] <= pair[0] {
            return Err(TimeFault::NonMonotonic {
                index: i + 1,
                previous: pair[0],
                found: pair[1],
            });
        }
        steps.push(pair[1] - pair[0]);
    }
    // The lower median for an even count: gaps (lost samples) are likelier than extra samples,
    // so ties go to the smaller step.
    let mid = (steps.len() - 1) / 2;
    let (_, &mut median, _) = steps.select_nth_unstable_by(mid, f64::total_cmp);
    for (i, pair) in time.windows(2).enumerate() {
        let step = pair[1] - pair[0];
        let floor = 4.0 * eps * pair[0].abs().max(pair[1].abs());
        if (step - median).abs() > tolerance * median + floor {
            return Err(TimeFault::NonUniform {
                index: i + 1,
                found_dt: step,
                expected_dt: median,
                tolerance,
            });
        }
    }
    let n = time.len();
    Ok((time[n - 1] - time[0]) / (n - 1) as f64)
}

/// Validates a sample rate and start time, returning the step `1 / rate_hz`.
pub(crate) fn check_rate(rate_hz: f64, start: f64) -> Result<f64, DataError> {
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        return Err(DataError::InvalidSampleRate { rate_hz });
    }
    if !start.is_finite() {
        return Err(DataError::InvalidStartTime { start });
    }
    Ok(1.0 / rate_hz)
}

pub(crate) fn check_tolerance(tolerance: f64) -> Result<(), DataError> {
    if tolerance.is_finite() && tolerance >= 0.0 {
        Ok(())
    } else {
        Err(DataError::InvalidTolerance { tolerance })
    }
}

/// `start + k dt` for each sample; multiplying rather than accumulating keeps the error of
/// late samples at one rounding instead of `k`.
pub(crate) fn uniform_times(start: f64, dt: f64, n: usize) -> Vec<f64> {
    (0..n).map(|k| start + k as f64 * dt).collect()
}

pub(crate) fn check_count(path: &Path, found: usize, min: usize) -> Result<(), DataError> {
    if found < min {
        return Err(DataError::TooFewSamples {
            path: path.to_path_buf(),
            found,
            min,
        });
    }
    Ok(())
}

fn check_lengths(
    path: &Path,
    expected: usize,
    columns: &[(&str, &[f64])],
) -> Result<(), DataError> {
    for &(name, values) in columns {
        if values.len() != expected {
            return Err(DataError::LengthMismatch {
                path: path.to_path_buf(),
                column: name.to_owned(),
                expected,
                found: values.len(),
            });
        }
    }
    Ok(())
}

fn check_finite_slice(path: &Path, name: &str, values: &[f64]) -> Result<(), DataError> {
    match values.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(row) => Err(DataError::NonFinite {
            path: path.to_path_buf(),
            location: Location::Row(row),
            column: ColumnId::Name(name.to_owned()),
            value: values[row].to_string(),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn uniform_step_is_end_to_end_mean() {
        let t: Vec<f64> = (0..11).map(|k| 2.0 + 0.1 * k as f64).collect();
        let dt = check_uniform(&t, 1e-6, f64::EPSILON).unwrap();
        // 0.1 * k carries one rounding per sample; 1e-14 is a few ulps of the times.
        assert_relative_eq!(dt, 0.1, max_relative = 1e-14);
    }

    #[test]
    fn single_gap_is_reported_where_it_is() {
        let mut t: Vec<f64> = (0..20).map(|k| k as f64 * 0.5).collect();
        for v in &mut t[7..] {
            *v += 0.5;
        }
        match check_uniform(&t, 1e-6, f64::EPSILON) {
            Err(TimeFault::NonUniform {
                index,
                found_dt,
                expected_dt,
                ..
            }) => {
                assert_eq!(index, 7);
                assert_relative_eq!(found_dt, 1.0);
                assert_relative_eq!(expected_dt, 0.5);
            }
            other => panic!("expected a non-uniform fault, got {other:?}"),
        }
    }

    #[test]
    fn large_absolute_times_pass_at_the_rounding_floor() {
        // Unix-epoch times: adjacent f64 values near 1.7e9 are 2.4e-7 s apart, so steps of
        // 1e-3 s carry rounding of about 2e-4 relative, far above 1e-6.
        let t: Vec<f64> = (0..1000).map(|k| 1.7e9 + k as f64 * 1e-3).collect();
        let dt = check_uniform(&t, 1e-6, f64::EPSILON).unwrap();
        assert_relative_eq!(dt, 1e-3, max_relative = 1e-6);
    }

    #[test]
    fn repeated_time_is_non_monotonic() {
        let t = [0.0, 1.0, 1.0, 2.0];
        assert_eq!(
            check_uniform(&t, 1e-6, f64::EPSILON),
            Err(TimeFault::NonMonotonic {
                index: 2,
                previous: 1.0,
                found: 1.0
            })
        );
    }
}
