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
