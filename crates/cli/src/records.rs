//! Measured records read for the commands: one CSV, an input column and an output column, with
//! the config's time column or sample rate and time-step tolerance.

use std::path::Path;

use anyhow::{Context, Result};
use htfid_data::{read_csv, CsvSpec, TimeSeries};

/// How a config names the columns of its record.
#[derive(Debug, Clone, Copy)]
pub struct Columns<'a> {
    pub input: &'a str,
    pub output: &'a str,
    /// The time column, or `None` with `sample_rate`.
    pub time: Option<&'a str>,
    pub sample_rate: Option<f64>,
    /// Relative tolerance on the time step (`data.time_tolerance`).
    pub time_tolerance: f64,
}

/// Reads `file`; errors name the config and the key that relaxes the time-step check.
pub fn read_record(config: &Path, file: &Path, c: Columns<'_>) -> Result<TimeSeries> {
    let mut spec = CsvSpec::default()
        .with_columns(c.input.to_string(), c.output.to_string())
        .with_min_samples(64)
        .with_time_tolerance(c.time_tolerance);
    spec = match (c.time, c.sample_rate) {
        (Some(t), _) => spec.with_time_column(t.to_string()),
        (None, Some(fs)) => spec.with_sample_rate(fs, 0.0),
        (None, None) => spec,
    };
    read_csv(file, &spec).with_context(|| {
        format!(
            "{}: [data] file (a non-uniform time step can be allowed with data.time_tolerance, \
             now {:e})",
            config.display(),
            c.time_tolerance
        )
    })
}

/// The time scale a record must resolve: the period of the dynamics the command looks for.
#[derive(Debug, Clone, Copy)]
pub struct TimeScale<'a> {
    /// The period, s.
    pub period: f64,
    /// What it is, for the message: "one natural period of the nominal model (...)".
    pub what: &'a str,
}

/// The key that fixes a record in the wrong time unit: the sample rate, or the time column.
pub fn unit_hint(sample_rate: Option<f64>) -> &'static str {
    if sample_rate.is_some() {
        "check data.sample_rate (Hz)"
    } else {
        "check that the time column (data.time) is in seconds"
    }
}

/// Refuses a record whose time scale cannot hold the dynamics of `scale`, before any work: a
/// record shorter than one period, or sampled at intervals longer than half of it (below the
/// Nyquist rate). Both usually mean a sample rate or a time column in the wrong unit
/// (milliseconds read as seconds make every step and the record 1000 times too long), and
/// working on such a record fits noise or integrates for hours.
pub fn check_time_scale(
    config: &Path,
    dt: f64,
    samples: usize,
    scale: TimeScale<'_>,
    hint: &str,
) -> Result<()> {
    let duration = dt * samples.saturating_sub(1) as f64;
    let what = scale.what;
    let period = scale.period;
    if duration < period {
        anyhow::bail!(
            "{}: the record lasts {duration:.3e} s, shorter than {what} ({period:.3} s): {hint}",
            config.display()
        );
    }
    if dt > period / 2.0 {
        anyhow::bail!(
            "{}: the record is sampled every {dt:.3e} s, more than half of {what} ({period:.3} \
             s): its Nyquist frequency ({:.3e} rad/s) is below {:.3} rad/s: {hint}",
            config.display(),
            std::f64::consts::PI / dt,
            2.0 * std::f64::consts::PI / period
        );
    }
    Ok(())
}
