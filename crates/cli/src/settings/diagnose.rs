//! Diagnosis configs (`htfid diagnose`): the measured record, the nominal model and the
//! decision thresholds.

use std::path::{Path, PathBuf};

use htfid_model::{DamperLaw, HopperParams};
use serde::Deserialize;
use toml::Spanned;

use super::{check_hopper_scales, damper_law, HopperSpans, Num, OptNum, RawForcing};
use crate::config::{load, ConfigError, Kind, Source};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawDiagnoseConfig {
    pub name: Option<Spanned<String>>,
    pub data: RawData,
    pub model: RawNominal,
    pub forcing: Option<RawForcing>,
    pub diagnose: Option<RawDiagnoseOptions>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawData {
    pub file: Spanned<String>,
    pub time: Option<Spanned<String>>,
    pub sample_rate: OptNum,
    pub input: Option<Spanned<String>>,
    pub output: Option<Spanned<String>>,
    pub fit: Option<Spanned<Vec<[i64; 2]>>>,
    pub validation: Option<Spanned<Vec<[i64; 2]>>>,
    pub test: Option<Spanned<Vec<[i64; 2]>>>,
    pub time_tolerance: OptNum,
    pub delimiter: Option<Spanned<String>>,
    pub matrix: Option<Spanned<String>>,
    pub columns: Option<Spanned<Vec<String>>>,
    pub units: Option<Spanned<std::collections::BTreeMap<String, String>>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawNominal {
    pub m: Num,
    pub k: Num,
    pub c: Num,
    pub g: Option<Num>,
    pub x0: Option<Num>,
    pub damper: Option<Spanned<String>>,
    pub input_offset: OptNum,
    pub free: Option<Spanned<Vec<String>>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawDiagnoseOptions {
    pub candidates: Option<Spanned<Vec<String>>>,
    pub significance_sigma: OptNum,
    pub min_gain: OptNum,
    pub burn_in: OptNum,
    pub fit_initial_state: Option<Spanned<bool>>,
    pub alpha: OptNum,
    pub max_effects: OptNum,
    pub bic_margin: OptNum,
    pub unexplained_ratio: OptNum,
    pub min_explained: OptNum,
    pub fit_tolerance: OptNum,
    pub input_noise_share: OptNum,
    pub input_noise_flatness: OptNum,
    pub noise_band: Option<Spanned<Vec<f64>>>,
    pub resolution: OptNum,
    pub max_delay_periods: OptNum,
    pub max_iterations: OptNum,
}

/// Where the measured data are and how to read them.
#[derive(Debug, Clone)]
pub struct DataSettings {
    pub file: PathBuf,
    pub time: Option<String>,
    pub sample_rate: Option<f64>,
    pub input: String,
    pub output: String,
    pub fit: Vec<std::ops::Range<usize>>,
    pub validation: Vec<std::ops::Range<usize>>,
    /// Extra held-out ranges reported separately (for example a benchmark's test sections).
    pub test: Vec<std::ops::Range<usize>>,
    /// Relative tolerance on the time step.
    pub time_tolerance: f64,
    /// `data.delimiter`, `data.matrix`, `data.columns`, `data.units`.
    pub format: crate::records::DataFormat,
}

#[derive(Debug, Clone)]
pub struct DiagnoseSettings {
    pub name: String,
    pub path: PathBuf,
    pub data: DataSettings,
    pub params: HopperParams,
    pub damper: DamperLaw,
    pub input_offset: f64,
    pub free: Vec<String>,
    pub candidates: Option<Vec<String>>,
    pub significance_sigma: Option<f64>,
    pub min_gain: Option<f64>,
    pub burn_in: Option<f64>,
    pub fit_initial_state: Option<bool>,
    /// The decision's thresholds (`diagnose.alpha`, ...), when set.
    pub thresholds: Thresholds,
}

/// The diagnosis's decision thresholds as set in the config (`None`: the library default).
#[derive(Debug, Clone, Default)]
pub struct Thresholds {
    pub alpha: Option<f64>,
    pub max_effects: Option<usize>,
    pub bic_margin: Option<f64>,
    pub unexplained_ratio: Option<f64>,
    pub min_explained: Option<f64>,
    pub fit_tolerance: Option<f64>,
    pub input_noise_share: Option<f64>,
    pub input_noise_flatness: Option<f64>,
    pub noise_band: Option<(f64, f64)>,
    pub resolution: Option<f64>,
    pub max_delay_periods: Option<f64>,
    pub max_iterations: Option<usize>,
}

fn ranges(
    src: &Source,
    v: &Option<Spanned<Vec<[i64; 2]>>>,
    key: &str,
) -> Result<Vec<std::ops::Range<usize>>, ConfigError> {
    let Some(list) = v else {
        return Ok(Vec::new());
    };
    let mut out = Vec::new();
    for [a, b] in list.get_ref() {
        if *a < 0 || b <= a {
            return Err(src.error(
                Some(&list.span()),
                key,
                format!(
                    "ranges are [start, end) sample indices with 0 <= start < end (got [{a}, {b}])"
                ),
            ));
        }
        out.push(*a as usize..*b as usize);
    }
    Ok(out)
}

impl DiagnoseSettings {
    pub fn from_file(path: &Path) -> Result<DiagnoseSettings, ConfigError> {
        let (raw, src): (RawDiagnoseConfig, Source) = load(path, Kind::Diagnosis)?;
        let name = src.run_name(raw.name.as_ref(), "diagnosis")?;
        let d = &raw.data;
        // A relative data path is relative to the config file's folder.
        let file = {
            let p = PathBuf::from(d.file.get_ref());
            if p.is_absolute() {
                p
            } else {
                path.parent().unwrap_or(Path::new(".")).join(p)
            }
        };
        let sample_rate = match &d.sample_rate {
            Some(v) => Some(src.positive(v, "data.sample_rate")?),
            None => None,
        };
        if sample_rate.is_some() && d.time.is_some() {
            return Err(src.error(
                d.time.as_ref().map(|t| t.span()).as_ref(),
                "data.time",
                "give either a time column or data.sample_rate, not both",
            ));
        }
        let time = match (&d.time, sample_rate) {
            (Some(t), _) => Some(t.get_ref().clone()),
            (None, Some(_)) => None,
            (None, None) => Some("t".to_string()),
        };
        let input = d.input.as_ref().map_or("f".into(), |v| v.get_ref().clone());
        let output = d
            .output
            .as_ref()
            .map_or("x".into(), |v| v.get_ref().clone());
        if input == output {
            let span = d.output.as_ref().or(d.input.as_ref()).map(|v| v.span());
            return Err(src.error(
                span.as_ref(),
                "data.output",
                format!("\"{output}\" is also the input column; the output must be another column"),
            ));
        }
        let used: Vec<&str> = [Some(input.as_str()), Some(output.as_str()), time.as_deref()]
            .into_iter()
            .flatten()
            .collect();
        let format = crate::records::resolve_format(&src, crate::raw_format!(d), &used)?;
        let data = DataSettings {
            format,
            file,
            time,
            sample_rate,
            input,
            output,
            fit: ranges(&src, &d.fit, "data.fit")?,
            validation: ranges(&src, &d.validation, "data.validation")?,
            test: ranges(&src, &d.test, "data.test")?,
            time_tolerance: src.opt_number(
                &d.time_tolerance,
                htfid_data::DEFAULT_TIME_TOLERANCE,
                "data.time_tolerance",
                "in [0, 0.1]",
                |v| (0.0..=0.1).contains(&v),
            )?,
        };
        for t in &data.test {
            if let Some(f) = data.fit.iter().find(|f| f.start < t.end && t.start < f.end) {
                return Err(src.error(
                    d.test.as_ref().map(|v| v.span()).as_ref(),
                    "data.test",
                    format!(
                        "test range [{}, {}) overlaps fit range [{}, {}): held-out data must not be fitted",
                        t.start, t.end, f.start, f.end
                    ),
                ));
            }
        }
        let m = &raw.model;
        let zero = |v: &Option<Num>, key: &str| -> Result<f64, ConfigError> {
            match v {
                Some(v) => src.finite(v, key),
                None => Ok(0.0),
            }
        };
        let (amplitude, period) = match &raw.forcing {
            Some(f) => (
                src.finite(&f.amplitude, "forcing.amplitude")?,
                src.positive(&f.period, "forcing.period")?,
            ),
            None => (0.0, 1.0),
        };
        let params = HopperParams {
            m: src.positive(&m.m, "model.m")?,
            k: src.non_negative(&m.k, "model.k")?,
            c: src.non_negative(&m.c, "model.c")?,
            g: zero(&m.g, "model.g")?,
            x0: zero(&m.x0, "model.x0")?,
            forcing_amplitude: amplitude,
            period,
        };
        if params.k == 0.0 && params.c == 0.0 {
            return Err(src.error(
                Some(&m.k.span()),
                "model.k",
                "k = 0 is a free mass, which needs damping (c > 0) for a time scale: give c, or \
                 a stiffness k > 0"
                    .to_string(),
            ));
        }
        check_hopper_scales(
            &src,
            &params,
            raw.forcing.is_some(),
            &HopperSpans {
                m: Some(m.m.span()),
                k: Some(m.k.span()),
                c: Some(m.c.span()),
                g: m.g.as_ref().map(Spanned::span),
                x0: m.x0.as_ref().map(Spanned::span),
                amplitude: raw.forcing.as_ref().map(|f| f.amplitude.span()),
            },
        )?;
        let damper = damper_law(&src, m.damper.as_ref())?;
        let input_offset = src.opt_number(
            &m.input_offset,
            0.0,
            "model.input_offset",
            "a finite number",
            |_| true,
        )?;
        let free = match &m.free {
            None => vec!["k".to_string(), "c".to_string()],
            Some(list) => {
                for f in list.get_ref() {
                    if !["m", "k", "c", "x0", "input_offset"].contains(&f.as_str()) {
                        return Err(src.error(Some(&list.span()), "model.free", format!("unknown parameter \"{f}\"; expected any of \"m\", \"k\", \"c\", \"x0\", \"input_offset\"")));
                    }
                }
                list.get_ref().clone()
            }
        };
        let o = raw.diagnose.as_ref();
        let candidates = match o.and_then(|o| o.candidates.as_ref()) {
            None => None,
            Some(list) => {
                for c in list.get_ref() {
                    if c.parse::<htfid_diagnose::Effect>().is_err() {
                        return Err(src.error(
                            Some(&list.span()),
                            "diagnose.candidates",
                            format!(
                                "unknown effect \"{c}\"; the library has {}",
                                crate::config::quote_list(
                                    &htfid_diagnose::Effect::ALL
                                        .iter()
                                        .map(|e| e.name())
                                        .collect::<Vec<_>>()
                                )
                            ),
                        ));
                    }
                }
                Some(list.get_ref().clone())
            }
        };
        let opt = |v: Option<&OptNum>,
                   key: &str,
                   expected: &str,
                   ok: fn(f64) -> bool|
         -> Result<Option<f64>, ConfigError> {
            match v.and_then(|v| v.as_ref()) {
                Some(v) => Ok(Some(src.number(v, key, expected, ok)?)),
                None => Ok(None),
            }
        };
        Ok(DiagnoseSettings {
            name,
            path: path.to_path_buf(),
            data,
            params,
            damper,
            input_offset,
            free,
            candidates,
            significance_sigma: opt(
                o.map(|o| &o.significance_sigma),
                "diagnose.significance_sigma",
                "> 0",
                |v| v > 0.0,
            )?,
            min_gain: opt(
                o.map(|o| &o.min_gain),
                "diagnose.min_gain",
                "in [0, 1)",
                |v| (0.0..1.0).contains(&v),
            )?,
            burn_in: opt(o.map(|o| &o.burn_in), "diagnose.burn_in", ">= 0 (s)", |v| {
                v >= 0.0
            })?,
            fit_initial_state: o
                .and_then(|o| o.fit_initial_state.as_ref())
                .map(|v| *v.get_ref()),
            thresholds: Thresholds {
                alpha: opt(o.map(|o| &o.alpha), "diagnose.alpha", "in (0, 0.5)", |v| {
                    v > 0.0 && v < 0.5
                })?,
                max_effects: opt(
                    o.map(|o| &o.max_effects),
                    "diagnose.max_effects",
                    "a whole number from 1 to 13",
                    |v| v.fract() == 0.0 && (1.0..=13.0).contains(&v),
                )?
                .map(|v| v as usize),
                bic_margin: opt(
                    o.map(|o| &o.bic_margin),
                    "diagnose.bic_margin",
                    ">= 0",
                    |v| v >= 0.0,
                )?,
                unexplained_ratio: opt(
                    o.map(|o| &o.unexplained_ratio),
                    "diagnose.unexplained_ratio",
                    ">= 1",
                    |v| v >= 1.0,
                )?,
                min_explained: opt(
                    o.map(|o| &o.min_explained),
                    "diagnose.min_explained",
                    "in [0, 1]",
                    |v| (0.0..=1.0).contains(&v),
                )?,
                fit_tolerance: opt(
                    o.map(|o| &o.fit_tolerance),
                    "diagnose.fit_tolerance",
                    "> 0",
                    |v| v > 0.0,
                )?,
                input_noise_share: opt(
                    o.map(|o| &o.input_noise_share),
                    "diagnose.input_noise_share",
                    "in [0, 1]",
                    |v| (0.0..=1.0).contains(&v),
                )?,
                input_noise_flatness: opt(
                    o.map(|o| &o.input_noise_flatness),
                    "diagnose.input_noise_flatness",
                    ">= 1",
                    |v| v >= 1.0,
                )?,
                noise_band: o
                    .and_then(|o| o.noise_band.as_ref())
                    .map(|b| src.band(b, "diagnose.noise_band"))
                    .transpose()?,
                resolution: opt(
                    o.map(|o| &o.resolution),
                    "diagnose.resolution",
                    ">= 0",
                    |v| v >= 0.0,
                )?,
                max_delay_periods: opt(
                    o.map(|o| &o.max_delay_periods),
                    "diagnose.max_delay_periods",
                    "in (0, 1]",
                    |v| v > 0.0 && v <= 1.0,
                )?,
                max_iterations: opt(
                    o.map(|o| &o.max_iterations),
                    "diagnose.max_iterations",
                    "a whole number from 1 to 10000",
                    |v| v.fract() == 0.0 && (1.0..=10_000.0).contains(&v),
                )?
                .map(|v| v as usize),
            },
        })
    }
}
