//! Configs of `htfid estimate`: HTFs from measured data alone, no model. Every key is
//! documented in `docs/config.md`.

use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use crate::config::{load, ConfigError, Kind, Source};
use crate::raw_format;
use crate::records::{resolve_format, DataFormat};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawEstimateConfig {
    name: Option<Spanned<String>>,
    data: RawEstimateData,
    period: RawPeriod,
    estimation: Option<RawEstimate>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawEstimateData {
    file: Spanned<String>,
    time: Option<Spanned<String>>,
    sample_rate: Option<Spanned<f64>>,
    input: Spanned<String>,
    outputs: Spanned<Vec<String>>,
    start: Option<Spanned<f64>>,
    time_tolerance: Option<Spanned<f64>>,
    delimiter: Option<Spanned<String>>,
    matrix: Option<Spanned<String>>,
    columns: Option<Spanned<Vec<String>>>,
    units: Option<Spanned<std::collections::BTreeMap<String, String>>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPeriod {
    value: Spanned<toml::Value>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawEstimate {
    harmonics: Option<Spanned<Vec<i64>>>,
    omega_min: Option<Spanned<f64>>,
    omega_max: Option<Spanned<f64>>,
    alpha: Option<Spanned<toml::Value>>,
}

/// How the pumping period is known.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PeriodSetting {
    /// Given in the config, s.
    Given(f64),
    /// Estimated from the first output.
    Estimate,
}

/// Resolved settings of one `htfid estimate` run.
#[derive(Debug, Clone)]
pub struct EstimateSettings {
    pub name: String,
    pub path: PathBuf,
    pub file: PathBuf,
    pub time: Option<String>,
    pub sample_rate: Option<f64>,
    pub input: String,
    pub outputs: Vec<String>,
    pub start: f64,
    pub time_tolerance: f64,
    pub period: PeriodSetting,
    pub harmonics: Vec<i32>,
    pub band: (f64, f64),
    /// `None`: generalised cross-validation.
    pub alpha: Option<f64>,
    /// `data.delimiter`, `data.matrix`, `data.columns`, `data.units`.
    pub format: DataFormat,
}

impl EstimateSettings {
    /// Loads and checks a config; `data` replaces `[data] file`.
    pub fn from_file(path: &Path, data: Option<PathBuf>) -> Result<Self, ConfigError> {
        let (raw, src): (RawEstimateConfig, Source) = load(path, Kind::Estimate)?;
        let name = src.run_name(raw.name.as_ref(), "estimate")?;
        let d = &raw.data;
        let dir = path.parent().unwrap_or(Path::new("."));
        let file = data.unwrap_or_else(|| dir.join(d.file.get_ref()));
        if d.time.is_some() == d.sample_rate.is_some() {
            return Err(src.error(
                Some(&d.file.span()),
                "data",
                "give exactly one of `time` (the time column) and `sample_rate` (Hz)",
            ));
        }
        let sample_rate = match &d.sample_rate {
            Some(v) => Some(src.positive(v, "data.sample_rate")?),
            None => None,
        };
        if d.outputs.get_ref().is_empty() {
            return Err(src.error(
                Some(&d.outputs.span()),
                "data.outputs",
                "must name at least one output column",
            ));
        }
        for (i, o) in d.outputs.get_ref().iter().enumerate() {
            if o == d.input.get_ref() {
                return Err(src.error(
                    Some(&d.outputs.span()),
                    "data.outputs",
                    format!("\"{o}\" is also the input column"),
                ));
            }
            if d.outputs.get_ref()[..i].contains(o) {
                return Err(src.error(
                    Some(&d.outputs.span()),
                    "data.outputs",
                    format!("\"{o}\" is listed twice"),
                ));
            }
        }
        let mut used: Vec<&str> = vec![d.input.get_ref()];
        used.extend(d.outputs.get_ref().iter().map(String::as_str));
        used.extend(d.time.as_ref().map(|t| t.get_ref().as_str()));
        let format = resolve_format(&src, raw_format!(d), &used)?;
        let start = match &d.start {
            Some(v) => src.number(v, "data.start", "a finite time (s)", |_| true)?,
            None => f64::NEG_INFINITY,
        };
        let time_tolerance = match &d.time_tolerance {
            Some(v) => src.number(v, "data.time_tolerance", "in [0, 0.1]", |x| {
                (0.0..=0.1).contains(&x)
            })?,
            None => htfid_data::DEFAULT_TIME_TOLERANCE,
        };
        let period = match raw.period.value.get_ref() {
            toml::Value::String(s) if s == "estimate" => PeriodSetting::Estimate,
            toml::Value::Float(f) if f.is_finite() && *f > 0.0 => PeriodSetting::Given(*f),
            toml::Value::Integer(i) if *i > 0 => PeriodSetting::Given(*i as f64),
            other => {
                return Err(src.error(
                    Some(&raw.period.value.span()),
                    "period.value",
                    format!("must be a period > 0 in s or \"estimate\" (got {other})"),
                ))
            }
        };
        let e = raw.estimation.as_ref();
        let harmonics = match e.and_then(|e| e.harmonics.as_ref()) {
            Some(h) => {
                let mut out = Vec::new();
                for &n in h.get_ref() {
                    if !(-20..=20).contains(&n) || out.contains(&(n as i32)) {
                        return Err(src.error(
                            Some(&h.span()),
                            "estimation.harmonics",
                            format!("harmonics must be distinct and in -20..=20 (got {n})"),
                        ));
                    }
                    out.push(n as i32);
                }
                if out.is_empty() {
                    return Err(src.error(
                        Some(&h.span()),
                        "estimation.harmonics",
                        "must list at least one harmonic",
                    ));
                }
                out
            }
            None => (-3..=3).collect(),
        };
        let lo = match e.and_then(|e| e.omega_min.as_ref()) {
            Some(v) => src.number(v, "estimation.omega_min", "> 0 (rad/s)", |x| x > 0.0)?,
            None => 1.0,
        };
        let hi = match e.and_then(|e| e.omega_max.as_ref()) {
            Some(v) => src.number(
                v,
                "estimation.omega_max",
                &format!("> omega_min ({lo})"),
                |x| x > lo,
            )?,
            None => 40.0,
        };
        let alpha = match e.and_then(|e| e.alpha.as_ref()) {
            None => Some(1.0),
            Some(v) => crate::settings::smoothness_weight(&src, v)?,
        };
        Ok(EstimateSettings {
            name,
            path: path.to_path_buf(),
            file,
            time: d.time.as_ref().map(|t| t.get_ref().clone()),
            sample_rate,
            input: d.input.get_ref().clone(),
            outputs: d.outputs.get_ref().clone(),
            start,
            time_tolerance,
            period,
            harmonics,
            band: (lo, hi),
            alpha,
            format,
        })
    }
}
