//! Measured records read for the commands: a file of any format `htfid-data` reads (CSV,
//! `.npy`, `.npz`, MAT-file), an input column and an output column, with the config's time
//! column or sample rate, time-step tolerance and format keys (`delimiter`, `matrix`,
//! `columns`, `units`), which every `[data]` table shares.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{anyhow, Result};
use htfid_data::{read_record as read_any, DataError, Delimiter, RecordSpec, TimeSeries};
use serde_json::Value;
use toml::Spanned;

use crate::config::{quote_list, ConfigError, Source};

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
    /// `data.delimiter`, `data.matrix`, `data.columns`.
    pub format: &'a DataFormat,
}

/// The format keys of a `[data]` table, resolved.
#[derive(Debug, Clone, Default)]
pub struct DataFormat {
    /// `None`: not set (comma-separated).
    pub delimiter: Option<Delimiter>,
    pub matrix: Option<String>,
    pub columns: Option<Vec<String>>,
    /// Unit of each column that has one, by column name (`data.units`).
    pub units: BTreeMap<String, String>,
}

impl DataFormat {
    /// The unit of `column`, if the config gives one.
    pub fn unit(&self, column: &str) -> Option<&str> {
        self.units.get(column).map(String::as_str)
    }

    /// `data.units` as a JSON object (empty when none are given).
    pub fn units_json(&self) -> Value {
        Value::Object(
            self.units
                .iter()
                .map(|(k, v)| (k.clone(), Value::String(v.clone())))
                .collect(),
        )
    }
}

/// The raw format keys of a `[data]` table, borrowed from whichever config kind holds them.
#[derive(Debug, Clone, Copy)]
pub struct RawFormat<'a> {
    pub delimiter: &'a Option<Spanned<String>>,
    pub matrix: &'a Option<Spanned<String>>,
    pub columns: &'a Option<Spanned<Vec<String>>>,
    pub units: &'a Option<Spanned<BTreeMap<String, String>>>,
}

/// The [`RawFormat`] of a raw `[data]` table `d` (every kind names the keys alike).
#[macro_export]
macro_rules! raw_format {
    ($d:expr) => {
        $crate::records::RawFormat {
            delimiter: &$d.delimiter,
            matrix: &$d.matrix,
            columns: &$d.columns,
            units: &$d.units,
        }
    };
}

/// Checks the format keys; `used` are the columns the config reads (time, input, outputs),
/// the only ones a unit can be given for.
pub fn resolve_format(
    src: &Source,
    raw: RawFormat<'_>,
    used: &[&str],
) -> Result<DataFormat, ConfigError> {
    let delimiter = match raw.delimiter {
        Some(d) => Some(Delimiter::parse(d.get_ref()).ok_or_else(|| {
            src.error(
                Some(&d.span()),
                "data.delimiter",
                format!(
                    "must be one of {} (got \"{}\")",
                    quote_list(&[",", ";", "tab", "whitespace", "auto"]),
                    d.get_ref()
                ),
            )
        })?),
        None => None,
    };
    let matrix = match raw.matrix {
        Some(m) if m.get_ref().trim().is_empty() => {
            return Err(src.error(
                Some(&m.span()),
                "data.matrix",
                "must name a .npz member or MAT-file variable",
            ))
        }
        Some(m) => Some(m.get_ref().clone()),
        None => None,
    };
    let columns = match raw.columns {
        Some(c) => {
            let names = c.get_ref();
            if names.is_empty() {
                return Err(src.error(
                    Some(&c.span()),
                    "data.columns",
                    "must name the matrix's columns in order (got an empty list)",
                ));
            }
            for (i, n) in names.iter().enumerate() {
                if n.trim().is_empty() {
                    return Err(src.error(
                        Some(&c.span()),
                        "data.columns",
                        format!("name {} is empty", i + 1),
                    ));
                }
                if names[..i].contains(n) {
                    return Err(src.error(
                        Some(&c.span()),
                        "data.columns",
                        format!("\"{n}\" is listed twice"),
                    ));
                }
            }
            Some(names.clone())
        }
        None => None,
    };
    let units = match raw.units {
        Some(u) => {
            for (column, unit) in u.get_ref() {
                if !used.contains(&column.as_str()) {
                    return Err(src.error(
                        Some(&u.span()),
                        "data.units",
                        format!(
                            "\"{column}\" is not a column this config reads ({}): if it was renamed in \
                             data.input, data.output(s) or data.time, rename it here too, else \
                             remove it",
                            quote_list(used)
                        ),
                    ));
                }
                if unit.trim().is_empty() {
                    return Err(src.error(
                        Some(&u.span()),
                        "data.units",
                        format!("the unit of \"{column}\" is empty"),
                    ));
                }
            }
            u.get_ref().clone()
        }
        None => BTreeMap::new(),
    };
    Ok(DataFormat {
        delimiter,
        matrix,
        columns,
        units,
    })
}

/// Reads `file`; errors name the config and the key that changes what went wrong.
pub fn read_record(config: &Path, file: &Path, c: Columns<'_>) -> Result<TimeSeries> {
    let mut spec = RecordSpec::default()
        .with_columns(c.input.to_string(), c.output.to_string())
        .with_min_samples(64)
        .with_time_tolerance(c.time_tolerance);
    spec = match (c.time, c.sample_rate) {
        (Some(t), _) => spec.with_time_column(t.to_string()),
        (None, Some(fs)) => spec.with_sample_rate(fs, 0.0),
        (None, None) => spec,
    };
    if let Some(d) = c.format.delimiter {
        spec = spec.with_delimiter(d);
    }
    spec.matrix.clone_from(&c.format.matrix);
    spec.columns.clone_from(&c.format.columns);
    let config_path = config;
    read_any(file, &spec).map_err(|e| {
        let config = config_path.display();
        let context = match &e {
            DataError::NonUniformTime {
                found_dt,
                expected_dt,
                ..
            } if htfid_data::missing_samples(*found_dt, *expected_dt).is_some() => {
                format!("{config}: [data] file")
            }
            DataError::NonUniformTime { .. } => format!(
                "{config}: [data] file (a non-uniform time step can be allowed with \
                 data.time_tolerance, now {:e})",
                c.time_tolerance
            ),
            DataError::LooksDelimited { found, .. } => format!(
                "{config}: [data] file (set data.delimiter = {} in the config)",
                Delimiter::for_char(*found).map_or("\"auto\"", Delimiter::describe)
            ),
            DataError::MissingColumn { column, .. } => {
                // The key that named the missing column, and how it may be written in [data].
                let (key, written): (&str, &[&str]) = if Some(column.as_str()) == c.time {
                    ("data.time", &["time"])
                } else if column == c.input {
                    ("data.input", &["input"])
                } else if column == c.output {
                    ("data.output (or data.outputs)", &["output", "outputs"])
                } else {
                    ("data", &[])
                };
                // Its line in the config, as every other config error gives it.
                let at = std::fs::read_to_string(config_path)
                    .ok()
                    .and_then(|text| {
                        let src = crate::config::Source {
                            path: config_path.to_path_buf(),
                            text,
                        };
                        let span = written
                            .iter()
                            .find_map(|name| src.key_location("data", name))?;
                        Some(format!(":{}:{}", src.line_of(&span), src.column_of(&span)))
                    })
                    .unwrap_or_default();
                format!("{config}{at}: {key}: the column it names is not in the file")
            }
            DataError::NoSuchColumn { .. }
            | DataError::NoSuchMatrix { .. }
            | DataError::WhichMatrix { .. }
            | DataError::ColumnNames { .. } => format!(
                "{config}: [data] file (data.matrix and data.columns name a matrix and its \
                 columns)"
            ),
            _ => format!("{config}: [data] file"),
        };
        anyhow!(e).context(context)
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
