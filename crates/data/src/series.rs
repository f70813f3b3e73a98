use std::ops::Range;
use std::path::{Path, PathBuf};

use crate::error::{ColumnId, DataError, Location};

/// Default relative tolerance on the sample step, see [`CsvSpec::time_tolerance`](crate::CsvSpec).
pub const DEFAULT_TIME_TOLERANCE: f64 = 1e-6;

/// A uniformly sampled record: one input and one or more outputs at common sample times. The
/// one record type of htfid: read from files here, simulated by `htfid-experiment`, diagnosed
/// by `htfid-diagnose`.
///
/// Invariants, checked by every constructor: at least 2 samples; at least one output; `time`,
/// `input` and every output have equal lengths; all values finite; `time` strictly increasing
/// with a uniform step `dt` (in s) within the tolerance the data were read with. Times are
/// absolute: `time[0]` is the time of the first sample as recorded, not shifted to zero.
#[derive(Debug, Clone, PartialEq)]
pub struct TimeSeries {
    time: Vec<f64>,
    input: Vec<f64>,
    outputs: Vec<Vec<f64>>,
    dt: f64,
    source: PathBuf,
}

impl TimeSeries {
    /// Builds a one-output series from explicit sample times, checking the invariants with the
    /// default relative tolerance [`DEFAULT_TIME_TOLERANCE`]. `source` names where the data
    /// came from (used in messages); errors give 0-based sample indices ([`Location::Row`]).
    pub fn new(
        time: Vec<f64>,
        input: Vec<f64>,
        output: Vec<f64>,
        source: impl Into<PathBuf>,
    ) -> Result<Self, DataError> {
        Self::with_outputs(time, input, vec![output], source)
    }

    /// [`new`](Self::new) with any number (at least one) of outputs.
    pub fn with_outputs(
        time: Vec<f64>,
        input: Vec<f64>,
        outputs: Vec<Vec<f64>>,
        source: impl Into<PathBuf>,
    ) -> Result<Self, DataError> {
        let source = source.into();
        check_columns(&source, Some(&time), &input, &outputs)?;
        let dt = check_uniform(&time, DEFAULT_TIME_TOLERANCE, f64::EPSILON).map_err(|fault| {
            fault.into_error(&source, ColumnId::Name("time".into()), Location::Row)
        })?;
        Ok(Self::from_checked(time, input, outputs, dt, source))
    }

    /// Builds a one-output series sampled at `rate_hz` starting at `start` s:
    /// `time[k] = start + k / rate_hz`.
    pub fn from_sample_rate(
        rate_hz: f64,
        start: f64,
        input: Vec<f64>,
        output: Vec<f64>,
        source: impl Into<PathBuf>,
    ) -> Result<Self, DataError> {
        let dt = check_rate(rate_hz, start)?;
        Self::from_step(start, dt, input, vec![output], source)
    }

    /// Builds a series sampled every `dt` s from `start` s, `time[k] = start + k dt`, with any
    /// number (at least one) of outputs: the record of a simulation on a uniform grid.
    pub fn from_step(
        start: f64,
        dt: f64,
        input: Vec<f64>,
        outputs: Vec<Vec<f64>>,
        source: impl Into<PathBuf>,
    ) -> Result<Self, DataError> {
        let source = source.into();
        if !(dt.is_finite() && dt > 0.0) {
            return Err(DataError::InvalidStep { dt });
        }
        if !start.is_finite() {
            return Err(DataError::InvalidStartTime { start });
        }
        check_columns(&source, None, &input, &outputs)?;
        let time = uniform_times(start, dt, input.len());
        Ok(Self::from_checked(time, input, outputs, dt, source))
    }

    /// One series holding the outputs of all of `parts`, in order: the same record read once
    /// per output column. Every part must have the same times and input.
    pub fn join_outputs(parts: Vec<TimeSeries>) -> Result<Self, DataError> {
        let mut parts = parts.into_iter();
        let Some(mut joined) = parts.next() else {
            return Err(DataError::NoOutputs {
                path: PathBuf::new(),
            });
        };
        for part in parts {
            if part.time != joined.time || part.input != joined.input {
                return Err(DataError::OutputsDisagree {
                    path: part.source,
                    output: joined.outputs.len(),
                });
            }
            joined.outputs.extend(part.outputs);
        }
        Ok(joined)
    }

    /// Assembles a series whose invariants the caller has already established.
    pub(crate) fn from_checked(
        time: Vec<f64>,
        input: Vec<f64>,
        outputs: Vec<Vec<f64>>,
        dt: f64,
        source: PathBuf,
    ) -> Self {
        Self {
            time,
            input,
            outputs,
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

    /// The first output (response, e.g. position in m) per sample.
    pub fn output(&self) -> &[f64] {
        &self.outputs[0]
    }

    /// Every output, each per sample.
    pub fn outputs(&self) -> &[Vec<f64>] {
        &self.outputs
    }

    /// The record of output `o` alone (same times, input and source), `None` past the last
    /// output.
    pub fn output_series(&self, o: usize) -> Option<Self> {
        let y = self.outputs.get(o)?;
        Some(Self::from_checked(
            self.time.clone(),
            self.input.clone(),
            vec![y.clone()],
            self.dt,
            self.source.clone(),
        ))
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
            self.outputs
                .iter()
                .map(|y| y[start..end].to_vec())
                .collect(),
            self.dt,
            self.source.clone(),
        ))
    }
}

/// How messages name output `o` (0-based): `output` for the first, `output 2` and on after it.
fn output_name(o: usize) -> String {
    if o == 0 {
        "output".to_string()
    } else {
        format!("output {}", o + 1)
    }
}

/// The invariants of a record's columns: at least one output, every column as long as the
/// input (and `time`, when given), at least 2 samples, all values finite (`time` first).
fn check_columns(
    source: &Path,
    time: Option<&[f64]>,
    input: &[f64],
    outputs: &[Vec<f64>],
) -> Result<(), DataError> {
    if outputs.is_empty() {
        return Err(DataError::NoOutputs {
            path: source.to_path_buf(),
        });
    }
    let names: Vec<String> = (0..outputs.len()).map(output_name).collect();
    let mut named: Vec<(&str, &[f64])> = vec![("input", input)];
    named.extend(
        names
            .iter()
            .map(String::as_str)
            .zip(outputs.iter().map(Vec::as_slice)),
    );
    let n = time.map_or(input.len(), <[f64]>::len);
    check_lengths(source, n, &named)?;
    check_count(source, n, 2)?;
    if let Some(time) = time {
        check_finite_slice(source, "time", time)?;
    }
    for (name, values) in &named {
        check_finite_slice(source, name, values)?;
    }
    Ok(())
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

    /// Several outputs: built at once or joined from one read per column, sliced together,
    /// taken apart again; a join of records with other times or inputs is refused by output.
    #[test]
    fn a_record_holds_several_outputs() {
        let t: Vec<f64> = (0..6).map(|k| 0.5 + 0.25 * k as f64).collect();
        let u: Vec<f64> = (0..6).map(|k| k as f64).collect();
        let (y1, y2): (Vec<f64>, Vec<f64>) = (0..6).map(|k| (k as f64 * 2.0, -(k as f64))).unzip();
        let both =
            TimeSeries::with_outputs(t.clone(), u.clone(), vec![y1.clone(), y2.clone()], "r")
                .unwrap();
        assert_eq!(both.outputs().len(), 2);
        assert_eq!(both.output(), &y1[..]);
        let joined = TimeSeries::join_outputs(vec![
            TimeSeries::new(t.clone(), u.clone(), y1.clone(), "r").unwrap(),
            TimeSeries::new(t.clone(), u.clone(), y2.clone(), "r").unwrap(),
        ])
        .unwrap();
        assert_eq!(joined, both);
        let part = both.slice(2..5).unwrap();
        assert_eq!(part.outputs()[1], vec![-2.0, -3.0, -4.0]);
        assert_eq!(both.output_series(1).unwrap().output(), &y2[..]);
        assert!(both.output_series(2).is_none());
        // The same grid from its step: times start + k dt exactly.
        let stepped =
            TimeSeries::from_step(0.5, 0.25, u.clone(), vec![y1.clone(), y2], "r").unwrap();
        assert_eq!(stepped.time(), &t[..]);
        assert_eq!(stepped.dt().to_bits(), 0.25f64.to_bits());
        let other_input: Vec<f64> = u.iter().map(|v| v + 1.0).collect();
        let err = TimeSeries::join_outputs(vec![
            TimeSeries::new(t.clone(), u, y1.clone(), "a.csv").unwrap(),
            TimeSeries::new(t.clone(), other_input, y1.clone(), "b.csv").unwrap(),
        ])
        .unwrap_err();
        assert_eq!(
            err.to_string(),
            "b.csv: output 2 was read with other times or another input than the outputs before it"
        );
        let err = TimeSeries::with_outputs(t.clone(), vec![0.0; 6], vec![], "r").unwrap_err();
        assert_eq!(err.to_string(), "r: a record needs at least one output");
        let err =
            TimeSeries::with_outputs(t, vec![0.0; 6], vec![y1, vec![0.0; 5]], "r").unwrap_err();
        assert_eq!(
            err.to_string(),
            "r: column \"output 2\" has 5 values, the time vector has 6"
        );
        let err =
            TimeSeries::from_step(0.0, 0.0, vec![0.0; 3], vec![vec![0.0; 3]], "r").unwrap_err();
        assert_eq!(
            err.to_string(),
            "sample step must be finite and > 0 (got 0 s)"
        );
    }

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
