use crate::DiagnoseError;

/// Smallest record the diagnosis accepts.
pub(crate) const MIN_SAMPLES: usize = 32;

/// Relative tolerance on the uniformity of the sample step.
const TIME_TOLERANCE: f64 = 1e-6;

/// A measured record: sample times `t` (s, absolute, uniform step), the total applied force
/// `f` (N, the input) and the position `x` (m, the output).
///
/// Invariants checked by every constructor: equal lengths of at least 32 samples, finite
/// values, strictly increasing times whose steps agree with the mean step to a relative
/// `1e-6` (plus the rounding of differencing two stored times).
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    t: Vec<f64>,
    f: Vec<f64>,
    x: Vec<f64>,
    dt: f64,
}

impl Record {
    /// A record from explicit times.
    pub fn new(t: Vec<f64>, f: Vec<f64>, x: Vec<f64>) -> Result<Self, DiagnoseError> {
        check_columns(&t, &f, &x)?;
        let n = t.len();
        let dt = (t[n - 1] - t[0]) / (n - 1) as f64;
        if dt <= 0.0 {
            return Err(DiagnoseError::NonUniformTime {
                index: 0,
                step: t[1] - t[0],
                dt,
                tolerance: TIME_TOLERANCE,
            });
        }
        for i in 0..n - 1 {
            let step = t[i + 1] - t[i];
            let rounding = 4.0 * f64::EPSILON * t[i].abs().max(t[i + 1].abs());
            if (step - dt).abs() > TIME_TOLERANCE * dt + rounding {
                return Err(DiagnoseError::NonUniformTime {
                    index: i,
                    step,
                    dt,
                    tolerance: TIME_TOLERANCE,
                });
            }
        }
        Ok(Record { t, f, x, dt })
    }

    /// A record sampled at `rate_hz` from `start` s: `t_k = start + k / rate_hz`.
    pub fn from_sample_rate(
        rate_hz: f64,
        start: f64,
        f: Vec<f64>,
        x: Vec<f64>,
    ) -> Result<Self, DiagnoseError> {
        if !(rate_hz.is_finite() && rate_hz > 0.0) {
            return Err(DiagnoseError::InvalidOption {
                name: "rate_hz",
                expected: "> 0 and finite",
                value: rate_hz,
            });
        }
        if !start.is_finite() {
            return Err(DiagnoseError::InvalidOption {
                name: "start",
                expected: "finite",
                value: start,
            });
        }
        let dt = 1.0 / rate_hz;
        let t: Vec<f64> = (0..f.len()).map(|k| start + k as f64 * dt).collect();
        check_columns(&t, &f, &x)?;
        Ok(Record { t, f, x, dt })
    }

    /// The record of a [`TimeSeries`](htfid_data::TimeSeries): its input is the force, its
    /// output the position.
    pub fn from_series(series: &htfid_data::TimeSeries) -> Result<Self, DiagnoseError> {
        // The series was checked where it was read, with the tolerance its reader was given:
        // checking again here with another tolerance would reject what the user allowed.
        let (t, f, x) = (
            series.time().to_vec(),
            series.input().to_vec(),
            series.output().to_vec(),
        );
        check_columns(&t, &f, &x)?;
        Ok(Record {
            t,
            f,
            x,
            dt: series.dt(),
        })
    }

    /// Sample times (s).
    pub fn t(&self) -> &[f64] {
        &self.t
    }

    /// Applied force (N).
    pub fn f(&self) -> &[f64] {
        &self.f
    }

    /// Position (m).
    pub fn x(&self) -> &[f64] {
        &self.x
    }

    /// Sample step (s): `(t_last - t_first) / (len - 1)`.
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Always `false`: a record holds at least 32 samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }
}

fn check_columns(t: &[f64], f: &[f64], x: &[f64]) -> Result<(), DiagnoseError> {
    for (column, values) in [("f", f), ("x", x)] {
        if values.len() != t.len() {
            return Err(DiagnoseError::LengthMismatch {
                column,
                expected: t.len(),
                found: values.len(),
            });
        }
    }
    if t.len() < MIN_SAMPLES {
        return Err(DiagnoseError::TooShort {
            min: MIN_SAMPLES,
            found: t.len(),
        });
    }
    for (column, values) in [("t", t), ("f", f), ("x", x)] {
        if let Some(index) = values.iter().position(|v| !v.is_finite()) {
            return Err(DiagnoseError::NonFinite {
                column,
                index,
                value: values[index],
            });
        }
    }
    Ok(())
}

/// [`DiagnoseError::ConstantOutput`] when `y` holds one value throughout all of `ranges`.
pub(crate) fn check_varies(
    y: &[f64],
    ranges: &[std::ops::Range<usize>],
    which: &str,
) -> Result<(), DiagnoseError> {
    let mut values = ranges.iter().flat_map(|r| y[r.clone()].iter().copied());
    let Some(first) = values.next() else {
        return Ok(());
    };
    // Exactly one value: a sensor that never changes, not a small motion.
    if values.all(|v| v.to_bits() == first.to_bits()) {
        let start = ranges.iter().map(|r| r.start).min().unwrap_or(0);
        let end = ranges.iter().map(|r| r.end).max().unwrap_or(0);
        return Err(DiagnoseError::ConstantOutput {
            which: which.to_string(),
            start,
            end,
            value: first,
        });
    }
    Ok(())
}
