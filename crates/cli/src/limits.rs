//! Resource limits, checked before any work: a config that would need more memory than
//! `--max-memory`, or more integration steps than `simulation.max_steps`, is refused with the
//! key that decides it, the estimate and the limit. The estimates come from the crates that
//! own the sizes (`htfid_hybrid::trajectory_bytes`, `htfid_hybrid::min_steps`,
//! `htfid_excite::design_size`, `htfid_estimate::estimator_bytes`, `HtfGrid::bytes_for`);
//! this module only adds them up and names the key.

use std::fmt;
use std::path::Path;
use std::sync::OnceLock;

use anyhow::{bail, Result};
use htfid_excite::TrainLayout;
use htfid_hybrid::HybridSystem;
use htfid_theory::HtfGrid;

use crate::settings::{Estimator, Excitation, Settings, System, Waveform};

/// Default of `--max-memory`: 4 GB, what a laptop can spare beside a desktop.
pub const DEFAULT_MAX_MEMORY: u64 = 4_000_000_000;

/// Process-wide limits from the command line. They are set once in `main`, before any command
/// runs, and read where a command knows its sizes; a global keeps every command's signature
/// free of a parameter that only the checks read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Bytes of the largest arrays a command may hold.
    pub max_memory: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_memory: DEFAULT_MAX_MEMORY,
        }
    }
}

static LIMITS: OnceLock<Limits> = OnceLock::new();

/// Sets the process's limits; a second call is ignored (there is one command line).
pub fn set(limits: Limits) {
    let _ = LIMITS.set(limits);
}

/// The process's limits (the defaults when `set` was never called, as in unit tests).
pub fn get() -> Limits {
    LIMITS.get().copied().unwrap_or_default()
}

/// Parses a size such as `8G`, `512MB`, `1.5T`, `2GiB` or `4000000000` (bytes). `K`, `M`,
/// `G`, `T` are powers of 1000; `Ki`, `Mi`, `Gi`, `Ti` powers of 1024; a trailing `B` is
/// optional.
pub fn parse_size(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == 'e' || c == 'E' || c == '+'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let value: f64 = number.parse().map_err(|_| {
        format!("expected a size such as 8G, 512M or 4000000000 (bytes) (got \"{text}\")")
    })?;
    let unit = unit.trim();
    let unit = unit
        .strip_suffix('B')
        .or_else(|| unit.strip_suffix('b'))
        .unwrap_or(unit);
    let scale = match unit.to_ascii_uppercase().as_str() {
        "" => 1.0,
        "K" => 1e3,
        "M" => 1e6,
        "G" => 1e9,
        "T" => 1e12,
        "KI" => 1024.0,
        "MI" => 1024f64.powi(2),
        "GI" => 1024f64.powi(3),
        "TI" => 1024f64.powi(4),
        _ => {
            return Err(format!(
                "unknown unit \"{unit}\": use K, M, G, T (powers of 1000) or Ki, Mi, Gi, Ti \
                 (powers of 1024) (got \"{text}\")"
            ))
        }
    };
    let bytes = value * scale;
    if !(1.0..1.8e19).contains(&bytes) {
        return Err(format!(
            "must be at least 1 byte and below 18 EB (got \"{text}\")"
        ));
    }
    Ok(bytes as u64)
}

/// A byte count for people: `2.4 TB`, `512 MB` (powers of 1000, as `--max-memory` reads them).
pub struct Bytes(pub u64);

impl fmt::Display for Bytes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let b = self.0 as f64;
        for (scale, unit) in [
            (1e15, "PB"),
            (1e12, "TB"),
            (1e9, "GB"),
            (1e6, "MB"),
            (1e3, "kB"),
        ] {
            if b >= scale {
                let v = b / scale;
                return if v >= 100.0 || (v - v.round()).abs() < 0.05 {
                    write!(f, "{v:.0} {unit}")
                } else {
                    write!(f, "{v:.1} {unit}")
                };
            }
        }
        write!(f, "{} bytes", self.0)
    }
}

/// A config value as it would be written: `1e9`, `0.45`, `100`.
pub fn value(v: f64) -> String {
    if v != 0.0 && (v.abs() >= 1e6 || v.abs() < 1e-3) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// An estimate to three significant digits: `3.01e11`, `2.35e6`, `301`.
pub fn approx(v: f64) -> String {
    if v != 0.0 && (v.abs() >= 1e6 || v.abs() < 1e-3) {
        let s = format!("{v:.2e}");
        match s.split_once('e') {
            Some((m, e)) => {
                let m = m.trim_end_matches('0').trim_end_matches('.');
                format!("{m}e{e}")
            }
            None => s,
        }
    } else {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

/// What a command does with an experiment config, for sizing it.
#[derive(Debug, Clone, Copy)]
pub enum Stage<'a> {
    /// `htfid simulate`: the limit cycle and the record.
    Simulate,
    /// `htfid theory`: the HTF grid over `omegas` frequencies (no record).
    Theory { omegas: &'a [f64] },
    /// `htfid run`: the record, the estimators and the theory grid.
    Run,
}

/// The record an experiment simulates: where it ends, how many samples, and the key whose value
/// makes it long.
#[derive(Debug, Clone)]
pub struct RecordSize {
    /// End of the record, s (a whole number of periods, as `Settings::record_grid` makes it).
    pub end: f64,
    /// Samples on the record's grid.
    pub samples: u64,
    /// The key (and its value) that sets the record's length.
    pub length_key: (String, f64),
}

/// The size of an experiment's record, from its settings alone (nothing is built).
pub fn record_size(settings: &Settings) -> RecordSize {
    let start = settings.settle_time();
    let settle_key = (
        "simulation.settle_periods".to_string(),
        settings.settle_periods as f64,
    );
    let (excitation_end, length_key) = match &settings.excitation {
        Excitation::None => (start, settle_key.clone()),
        Excitation::ChirpTrain {
            waveform,
            duration,
            copies,
            ..
        } => {
            let end = TrainLayout {
                duration: *duration,
                copies: *copies,
                period: settings.period,
                start,
                min_gap: 0.0,
            }
            .end();
            let key = if *waveform == Waveform::Paper {
                ("excitation.copies".to_string(), *copies as f64)
            } else {
                ("excitation.duration".to_string(), *duration)
            };
            (end, key)
        }
        Excitation::MultisineDesign { spacing, .. } => {
            let end = crate::signals::design_spec(settings)
                .and_then(|spec| htfid_excite::design_size(&spec).ok())
                .map_or(start, |size| start + size.min_record);
            (end, ("excitation.spacing".to_string(), *spacing))
        }
    };
    // The same rounding as `Settings::record_grid`, without building the grid.
    let period = settings.period;
    let end = start + ((excitation_end - start).max(0.0) / period - 1e-9).ceil() * period;
    let end = end.max(period);
    let samples = (end * settings.sample_rate + 1e-9).floor() + 1.0;
    let samples = if samples.is_finite() && samples < 1.8e19 {
        samples as u64
    } else {
        u64::MAX
    };
    // A long settling, not the excitation, sets the length when it is the larger part.
    let length_key = if start > excitation_end - start {
        settle_key
    } else {
        length_key
    };
    RecordSize {
        end,
        samples,
        length_key,
    }
}

/// State dimension and output count of the simulated system (the hopper's effects add at most
/// one state, its actuator lag).
fn system_shape(system: &System) -> (usize, usize) {
    match system {
        System::Hopper { .. } => (3, 1),
        System::Model(model) => (model.dim(), model.outputs().len()),
    }
}

/// Refuses an experiment whose `stage` would need more memory than `--max-memory` or more
/// integration steps than `simulation.max_steps`. Runs before any file is opened or any orbit
/// is searched.
pub fn check_experiment(settings: &Settings, stage: Stage) -> Result<()> {
    let limit = get().max_memory;
    let path = settings.path.display();
    let raise = "raise with --max-memory";
    let (dim, outputs) = system_shape(&settings.system);
    let theory_grid = |omegas: usize, harmonics: usize| {
        HtfGrid::bytes_for(omegas, harmonics).saturating_mul(outputs as u64)
    };
    if let Stage::Theory { omegas } = stage {
        let bytes = theory_grid(omegas.len(), settings.theory.harmonics.len());
        if bytes > limit {
            bail!(
                "{path}: theory.points = {} needs about {} for the HTF grid ({} harmonics, {} \
                 output(s)) (limit {}; {raise})",
                omegas.len(),
                Bytes(bytes),
                settings.theory.harmonics.len(),
                outputs,
                Bytes(limit)
            );
        }
        return Ok(());
    }
    let record = record_size(settings);
    let design = crate::signals::design_spec(settings)
        .and_then(|spec| htfid_excite::design_size(&spec).ok());
    if let (
        Some(size),
        Excitation::MultisineDesign {
            spacing, omega_max, ..
        },
    ) = (&design, &settings.excitation)
    {
        let nyquist = std::f64::consts::PI * settings.sample_rate;
        if size.min_top_line >= nyquist {
            // The first line sits at half the spacing; otherwise the band sets the top line.
            let (key, v) = if spacing / 2.0 >= size.min_top_line {
                ("excitation.spacing", *spacing)
            } else {
                ("excitation.omega_max", *omega_max)
            };
            bail!(
                "{path}: {key} = {} puts input lines at {} rad/s or above, beyond the Nyquist \
                 frequency of simulation.sample_rate = {} Hz ({} rad/s): lower {key} or raise \
                 simulation.sample_rate",
                value(v),
                approx(size.min_top_line),
                value(settings.sample_rate),
                approx(nyquist)
            );
        }
    }
    // Per sample: the trajectory (grid, states, chart), the caller's grid, the input and the
    // forcing, and every output with its orbit.
    let per_sample = htfid_hybrid::trajectory_bytes(dim, 1, 8) + 8 * (3 + 2 * outputs as u64);
    // The design's peak search samples one multisine period finely.
    let peak = design.map_or(0.0, |d| 8.0 * d.min_peak_samples);
    let series = record
        .samples
        .saturating_mul(per_sample)
        .saturating_add(if peak < 1.8e19 { peak as u64 } else { u64::MAX });
    if series > limit {
        // At the default rate the record would fit: the rate is what is out of scale.
        let at_default_rate = series as f64 * (100.0 / settings.sample_rate);
        let (key, v) = if settings.sample_rate > 100.0 && at_default_rate <= limit as f64 {
            ("simulation.sample_rate".to_string(), settings.sample_rate)
        } else {
            record.length_key.clone()
        };
        bail!(
            "{path}: {key} = {} needs about {} for the time series ({} samples over {} s at \
             {} Hz) (limit {}; {raise})",
            value(v),
            Bytes(series),
            approx(record.samples as f64),
            approx(record.end),
            value(settings.sample_rate),
            Bytes(limit)
        );
    }
    let steps = htfid_hybrid::min_steps(record.end, settings.period);
    let max_steps = settings.integrator.max_steps;
    if steps > max_steps as f64 {
        let (key, v) = &record.length_key;
        bail!(
            "{path}: {key} = {} needs at least {} integration steps for a record of {} s \
             ({} per forcing period of {} s) (limit {}; raise simulation.max_steps)",
            value(*v),
            approx(steps),
            approx(record.end),
            htfid_hybrid::MIN_STEPS_PER_PERIOD,
            value(settings.period),
            max_steps
        );
    }
    if let Stage::Run = stage {
        let e = &settings.estimation;
        let dt = 1.0 / settings.sample_rate;
        let harmonics = e.harmonics.len();
        let mut estimators = 0u64;
        for est in &e.estimators {
            let bytes = match (est, &settings.excitation) {
                (
                    Estimator::Multi,
                    Excitation::ChirpTrain {
                        duration, copies, ..
                    },
                ) => {
                    let per_copy = (duration * settings.sample_rate).ceil() as u64 + 1;
                    htfid_estimate::estimator_bytes(*copies, per_copy, dt, harmonics, e.band)
                }
                _ => htfid_estimate::estimator_bytes(1, record.samples, dt, harmonics, e.band),
            };
            estimators = estimators.max(bytes);
        }
        let estimators = estimators.saturating_mul(outputs as u64);
        let grid = theory_grid(
            settings.theory.omegas.len(),
            settings.theory.harmonics.len(),
        );
        let total = series.saturating_add(estimators).saturating_add(grid);
        if total > limit {
            let (key, v) = if grid > estimators {
                (
                    "theory.points".to_string(),
                    settings.theory.omegas.len() as f64,
                )
            } else {
                record.length_key.clone()
            };
            bail!(
                "{path}: {key} = {} needs about {} for the time series, the estimators and the \
                 HTF grid ({} + {} + {}) (limit {}; {raise})",
                value(v),
                Bytes(total),
                Bytes(series),
                Bytes(estimators),
                Bytes(grid),
                Bytes(limit)
            );
        }
    }
    Ok(())
}

/// What a failed simulation was run for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Simulated {
    /// The unexcited orbit.
    Orbit,
    /// The experiment, with the configured input.
    Experiment,
}

impl std::fmt::Display for Simulated {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Simulated::Orbit => "the unexcited orbit",
            Simulated::Experiment => "the experiment",
        })
    }
}

/// A failed integration located in the config: its file, what was simulated, and the key to
/// raise when the step cap stopped it.
pub fn integration_failed(
    settings: &Settings,
    what: Simulated,
    e: htfid_hybrid::HybridError,
) -> anyhow::Error {
    let hint = if matches!(e, htfid_hybrid::HybridError::MaxStepsExceeded { .. }) {
        format!(
            " (simulation.max_steps = {}; raise it)",
            settings.integrator.max_steps
        )
    } else if let (Simulated::Experiment, Some(amplitude)) = (what, settings.excitation.amplitude())
    {
        // The unexcited orbit simulated, so the input is the first suspect.
        format!(
            " (excitation.amplitude = {amplitude:e}; the orbit without input simulates, so \
             the input may drive the system out of the behaviour the model describes)"
        )
    } else {
        String::new()
    };
    anyhow::anyhow!(
        "{}: simulation of {what} failed: {e}{hint}",
        settings.path.display()
    )
}

/// As [`integration_failed`] for a step of `htfid-experiment`: a failed integration gets its
/// hint, anything else its own message.
pub fn experiment_failed(
    settings: &Settings,
    what: Simulated,
    e: htfid_experiment::ExperimentError,
) -> anyhow::Error {
    match e {
        htfid_experiment::ExperimentError::Simulation(h) => integration_failed(settings, what, h),
        other => anyhow::anyhow!(
            "{}: simulation of {what} failed: {other}",
            settings.path.display()
        ),
    }
}

/// Refuses measured data whose file alone would need more memory than `--max-memory` to read:
/// about twice the file's size (the text, then the parsed columns). A missing file is left to
/// the reader, which names it.
pub fn check_data_file(config: &Path, key: &str, file: &Path) -> Result<()> {
    let limit = get().max_memory;
    let Ok(meta) = std::fs::metadata(file) else {
        return Ok(());
    };
    let bytes = meta.len().saturating_mul(2);
    if bytes > limit {
        bail!(
            "{}: {key} = \"{}\" needs about {} to read ({} file) (limit {}; raise with \
             --max-memory)",
            config.display(),
            file.display(),
            Bytes(bytes),
            Bytes(meta.len()),
            Bytes(limit)
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_units() {
        assert_eq!(parse_size("8G"), Ok(8_000_000_000));
        assert_eq!(parse_size("512MB"), Ok(512_000_000));
        assert_eq!(parse_size("2GiB"), Ok(2 * 1024 * 1024 * 1024));
        assert_eq!(parse_size("1.5T"), Ok(1_500_000_000_000));
        assert_eq!(parse_size("4000000000"), Ok(4_000_000_000));
        assert_eq!(parse_size(" 16 k"), Ok(16_000));
        for bad in ["", "G", "8X", "-1G", "0", "nan", "1e30"] {
            assert!(parse_size(bad).is_err(), "{bad:?} parsed");
        }
    }

    #[test]
    fn bytes_read_like_the_flag() {
        assert_eq!(Bytes(2_400_000_000_000).to_string(), "2.4 TB");
        assert_eq!(Bytes(4_000_000_000).to_string(), "4 GB");
        assert_eq!(Bytes(512).to_string(), "512 bytes");
        assert_eq!(Bytes(123_456_789).to_string(), "123 MB");
    }

    #[test]
    fn values_read_like_toml() {
        assert_eq!(value(1e9), "1e9");
        assert_eq!(value(1e-4), "1e-4");
        assert_eq!(value(0.45), "0.45");
        assert_eq!(value(100.0), "100");
        assert_eq!(approx(3.01000000001e11), "3.01e11");
        assert_eq!(approx(9.000000031e9), "9e9");
        assert_eq!(approx(301.0), "301");
        assert_eq!(approx(0.5), "0.5");
    }

    #[test]
    fn a_grid_of_a_million_points_is_sized_by_points_and_harmonics() {
        // 1e6 frequencies x 101 harmonics of complex doubles.
        let b = HtfGrid::bytes_for(1_000_000, 101);
        assert!(b >= 1_000_000 * 101 * 16, "{b}");
    }
}
