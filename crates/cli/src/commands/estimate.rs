//! `htfid estimate CONFIG [--data FILE]`: HTFs from measured data alone, no model. The period
//! is given or estimated, the orbit is the period average of the record (input and outputs),
//! and Siddiqi's estimator takes the deviations. The science is in `htfid-estimate`
//! (`estimate_period`, `split_periodic`, `siddiqi`); this file reads, checks, writes.

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use htfid_data::TimeSeries;
use htfid_estimate::{
    deviation_record, estimate_period, locked_step, outer_harmonics, siddiqi, split_periodic,
    Alpha, HtfEstimate, OuterHarmonic,
};
use htfid_plot::Style;
use num_complex::Complex64;
use serde_json::{json, Value};

use crate::commands::run::write_estimate_csv;
use crate::estimate_config::{EstimateSettings, PeriodSetting};
use crate::output::{json_text, open, resolve_dir};
use crate::plots::{self, Curve};
use crate::progress::Stages;
use crate::records::{read_record, Columns};

/// Harmonics added on each side of the estimated set to check that it holds the response.
const OUTER_HARMONICS: i32 = 2;
/// An added harmonic significant at more than this share of the band's bins (noise alone:
/// about 2 %) carries the response, and the notes say so.
const OUTER_SIGNIFICANT_SHARE: f64 = 0.1;

/// Fewer periods than this and the estimate is called short in the checks.
const MIN_PERIODS: usize = 20;
/// Probability that noise alone reaches the level of `max_abs_g_significant` at any of a
/// harmonic's frequencies.
const BAND_FALSE_ALARM: f64 = 0.05;
/// Share of a harmonic's frequencies, reading unexcited input frequencies, above which a note
/// names them.
const UNEXCITED_SHARE: f64 = 0.05;

/// The sample step with which the given `period` holds a whole number of samples
/// (`htfid_estimate::locked_step`), or an error naming `period.value` with two sample rates to
/// resample the record to.
fn whole_samples(settings: &EstimateSettings, period: f64, dt: f64, samples: usize) -> Result<f64> {
    if let Some(step) = locked_step(period, dt, samples) {
        return Ok(step);
    }
    let per = period / dt;
    // Six significant digits, without trailing zeros.
    let short = |x: f64| {
        let scale = 10f64.powi(5 - x.abs().log10().floor() as i32);
        (x * scale).round() / scale
    };
    let rate = |m: f64| short(m / period);
    let (below, above) = (per.floor().max(1.0), per.floor().max(1.0) + 1.0);
    bail!(
        "{}: period.value = {period} s is {per:.4} samples of the record's step {} s, not a \
         whole number: the period average and Siddiqi's estimator need a whole number of \
         samples per period. Resample the record so that a period holds one, e.g. at {} Hz \
         ({below} samples per period) or {} Hz ({above}), or check period.value",
        settings.path.display(),
        short(dt),
        rate(below),
        rate(above)
    )
}

/// Largest drift, in periods over the record, of the given period against the data's own
/// before the given period is put to the test below: a twentieth of a period smears the
/// harmonics' phases by 18 degrees at the fundamental and more at the harmonics.
const GIVEN_PERIOD_DRIFT: f64 = 0.05;

/// Share of the first output's variance its orbit must carry at its own period for that period
/// to overrule a given one.
const CLEAR_ORBIT_SHARE: f64 = 0.5;

/// Share of the orbit's variance at the data's own period that the given period must still
/// explain (a period of the data's orbit, or a multiple of it, explains all of it; a period
/// off by a fraction of a period over the record smears the orbit's harmonics out of its
/// average).
const GIVEN_PERIOD_SHARE: f64 = 0.9;

/// Refuses a given period that the data contradict: where the first output's own period
/// (`htfid_estimate::estimate_period` on `output`, with a clear orbit) parts from `period` by
/// more than [`GIVEN_PERIOD_DRIFT`] periods over the record, and the period average at
/// `period` carries less than [`GIVEN_PERIOD_SHARE`] of the variance the orbit carries at its
/// own period, every harmonic would be read at the wrong frequency and the estimate would be
/// confident nonsense. `deviation` is the first `deviation.len()` samples of `output` with
/// their period average at `period` removed (the split the estimator reads). (On a short
/// record the own period may come out a multiple of the true one; the true one then explains
/// as much, and passes.)
fn check_given_period(
    settings: &EstimateSettings,
    period: f64,
    output: &[f64],
    deviation: &[f64],
    dt: f64,
) -> Result<()> {
    let Ok(own) = estimate_period(output, dt) else {
        return Ok(());
    };
    let n = deviation.len();
    let periods = n as f64 * dt / period;
    let drift = (period - own.period).abs() / own.period * periods;
    if own.periodic_share < CLEAR_ORBIT_SHARE || drift <= GIVEN_PERIOD_DRIFT {
        return Ok(());
    }
    let y = &output[..n];
    let mean = y.iter().sum::<f64>() / n as f64;
    let total: f64 = y.iter().map(|v| (v - mean).powi(2)).sum();
    let left: f64 = deviation.iter().map(|v| v * v).sum();
    let given = if total > 0.0 { 1.0 - left / total } else { 1.0 };
    if given >= GIVEN_PERIOD_SHARE * own.periodic_share {
        return Ok(());
    }
    bail!(
        "{}: period.value = {period} s, but the first output's own period is {} s: its orbit \
         carries {} of the output's variance there and {} at the given period, and over the {} \
         periods of the record the two periods part by {} periods, so every harmonic would be \
         read at the wrong frequency. Correct period.value, or set it to \"estimate\"",
        settings.path.display(),
        htfid_number::sig(own.period, 9),
        htfid_number::percent(own.periodic_share, 3),
        htfid_number::percent(given, 3),
        htfid_number::sig(periods, 3),
        htfid_number::sig(drift, 3)
    )
}

fn read(settings: &EstimateSettings, output: &str) -> Result<TimeSeries> {
    let columns = Columns {
        input: &settings.input,
        output,
        time: settings.time.as_deref(),
        sample_rate: settings.sample_rate,
        time_tolerance: settings.time_tolerance,
        format: &settings.format,
    };
    read_record(&settings.path, &settings.file, columns)
}

pub fn run(config: &Path, data: Option<PathBuf>, out: Option<PathBuf>, force: bool) -> Result<()> {
    let settings = EstimateSettings::from_file(config, data)?;
    crate::limits::check_data_file(&settings.path, "data.file", &settings.file)?;
    let outputs = &settings.outputs;
    let suffix = |o: usize| {
        if o == 0 {
            String::new()
        } else {
            format!("_{}", outputs[o])
        }
    };
    let mut names: Vec<String> = vec![
        "summary.json".into(),
        "orbit.csv".into(),
        "report.md".into(),
    ];
    for o in 0..outputs.len() {
        names.push(format!("estimate_siddiqi{}.csv", suffix(o)));
        names.push(format!("estimate_harmonics{}.svg", suffix(o)));
        names.push(format!("estimate_harmonics{}.png", suffix(o)));
    }
    let name_refs: Vec<&str> = names.iter().map(String::as_str).collect();
    let dir = resolve_dir(out, &settings.name);
    let mut outdir = open(&dir, force, &name_refs)?;
    let mut stages = Stages::new();

    let series: Vec<TimeSeries> = stages.run("read data", || {
        outputs
            .iter()
            .map(|o| read(&settings, o))
            .collect::<Result<Vec<_>>>()
    })?;
    let first = &series[0];
    let dt = first.dt();
    let hint = crate::records::unit_hint(settings.sample_rate);
    if let PeriodSetting::Given(t) = settings.period {
        crate::records::check_time_scale(
            &settings.path,
            dt,
            first.len(),
            crate::records::TimeScale {
                period: t,
                what: "the period (period.value)",
            },
            hint,
        )?;
    }
    let i0 = first.time().partition_point(|&t| t < settings.start);
    if first.len() - i0 < 64 {
        bail!(
            "{}: data.start = {} leaves {} samples; at least 64 are needed",
            settings.path.display(),
            settings.start,
            first.len() - i0
        );
    }

    // The period: given, or estimated from the first output and snapped to a whole number of
    // samples (the split and the estimator need N dt = P T exactly).
    let (period, estimated, dt) = match settings.period {
        PeriodSetting::Given(t) => {
            let step = whole_samples(&settings, t, dt, first.len() - i0)?;
            (t, None, step)
        }
        PeriodSetting::Estimate => {
            let est = stages
                .run("estimate period", || {
                    estimate_period(&first.output()[i0..], dt)
                })
                .context("the period could not be estimated from the first output")?;
            let per = est.period / dt;
            let snapped = per.round();
            // The estimate is far better than a hundredth of a sample on any record with a
            // clear orbit; a larger offset means the sampling is not locked to the period.
            if (per - snapped).abs() > 0.01 {
                bail!(
                    "{}: the estimated period {:.9} s is {per:.4} samples, not a whole number; \
                     give period.value (s), or resample the data so that a period holds a whole \
                     number of samples",
                    settings.path.display(),
                    est.period
                );
            }
            (snapped * dt, Some(est), dt)
        }
    };
    let per_period = (period / dt).round() as usize;
    let available = first.len() - i0;
    let periods = available / per_period.max(1);
    if periods < 2 {
        bail!(
            "{}: the record after data.start holds {periods} period(s) of {period} s; at least \
             2 are needed (and {MIN_PERIODS} for a usable estimate)",
            settings.path.display()
        );
    }
    let n = periods * per_period;
    let t_start = first.time()[i0];
    check_band(&settings, dt, period, n, hint)?;

    let u_split = split_periodic(&first.input()[i0..i0 + n], dt, t_start, period, 5)
        .context("input: period average")?;
    let mut estimates: Vec<HtfEstimate> = Vec::new();
    let mut outer: Vec<Vec<OuterHarmonic>> = Vec::new();
    let mut unchecked: Vec<String> = Vec::new();
    let mut orbits = Vec::new();
    for (o, s) in series.iter().enumerate() {
        let y_split = split_periodic(&s.output()[i0..i0 + n], dt, t_start, period, 10)
            .with_context(|| format!("output {}: period average", outputs[o]))?;
        if o == 0 && estimated.is_none() {
            check_given_period(&settings, period, &s.output()[i0..], &y_split.deviation, dt)?;
        }
        let record = deviation_record(
            u_split.deviation.clone(),
            y_split.deviation.clone(),
            dt,
            t_start,
        )?;
        let alpha = settings.alpha.map_or(Alpha::Gcv, Alpha::Fixed);
        let e = stages
            .run(&format!("estimate ({})", outputs[o]), || {
                siddiqi(&record, period, &settings.harmonics, settings.band, alpha)
            })
            .with_context(|| {
                format!(
                    "{}: Siddiqi's estimator on output {} (estimation.alpha = {})",
                    settings.path.display(),
                    outputs[o],
                    settings
                        .alpha
                        .map_or("\"gcv\"".to_string(), |a| a.to_string())
                )
            })?;
        estimates.push(e);
        // Harmonics beyond the set that carry the response bias the ones estimated.
        let checked = stages.run(
            &format!("harmonics beyond the set ({})", outputs[o]),
            || {
                outer_harmonics(
                    &record,
                    period,
                    &settings.harmonics,
                    settings.band,
                    alpha,
                    OUTER_HARMONICS,
                )
            },
        );
        match checked {
            Ok(list) => outer.push(list),
            Err(e) => {
                unchecked.push(format!(
                    "output {}: harmonics beyond estimation.harmonics could not be checked: {e}",
                    outputs[o]
                ));
                outer.push(Vec::new());
            }
        }
        orbits.push(y_split);
    }

    // What the experiment allows.
    let wp = 2.0 * PI / period;
    let nyquist = PI / dt;
    let resolution = 2.0 * PI / (n as f64 * dt);
    let excited = excited_band(&u_split.deviation, dt);
    let mut notes: Vec<String> = Vec::new();
    if periods < MIN_PERIODS {
        notes.push(format!(
            "only {periods} periods: the estimate has few degrees of freedom per bin"
        ));
    }
    let (lo, hi) = settings.band;
    if let Some((a, b)) = excited {
        if a > lo * 1.05 || b < hi * 0.95 {
            notes.push(format!(
                "the input excites {a:.3}-{b:.3} rad/s (within 40 dB of its peak), not the whole \
                 band {lo}-{hi} rad/s: outside it the estimates rest on regularisation alone"
            ));
        }
    } else {
        notes.push("the input has no broadband content apart from its periodic part".into());
    }
    // Per harmonic, the output frequencies whose input frequency `w - n wp` the input does
    // not excite (the grid is the first output's; every output shares it).
    let unexcited: Vec<(i32, Vec<(f64, f64)>)> = match (excited, estimates.first()) {
        (Some(band), Some(e)) => unexcited_ranges(e, wp, band, resolution),
        _ => Vec::new(),
    };
    if !unexcited.is_empty() {
        notes.push(format!(
            "{}: the input frequencies these read (w - n wp) lie outside the excited band; \
             there the estimates rest on regularisation and noise alone",
            unexcited
                .iter()
                .map(|(n, ranges)| format!(
                    "G_{n} at {}",
                    ranges
                        .iter()
                        .map(|(a, b)| format!("{a:.3}-{b:.3} rad/s"))
                        .collect::<Vec<_>>()
                        .join(", ")
                ))
                .collect::<Vec<_>>()
                .join("; ")
        ));
    }
    let unresolved: Vec<i32> = settings
        .harmonics
        .iter()
        .copied()
        .filter(|&k| hi - f64::from(k) * wp > nyquist || lo - f64::from(k) * wp < -nyquist)
        .collect();
    if !unresolved.is_empty() {
        notes.push(format!(
            "harmonics {unresolved:?} map part of the band past the Nyquist frequency \
             ({nyquist:.1} rad/s): they alias and cannot be resolved at this sample rate"
        ));
    }
    notes.append(&mut unchecked);
    // With few periods the standard errors the check weighs against rest on few residual
    // degrees of freedom: its claims would be noise (a 5-period record named G_-4 and G_4 over
    // the whole band where they are 1e-5 of G_0).
    let checkable = periods >= MIN_PERIODS;
    if !checkable && outer.iter().any(|l| !l.is_empty()) {
        notes.push(format!(
            "with only {periods} periods (fewer than {MIN_PERIODS}) the harmonics outside \
             estimation.harmonics cannot be checked: their standard errors rest on too few \
             degrees of freedom (summary.json keeps the numbers)"
        ));
    }
    for (o, list) in outer.iter().enumerate().filter(|_| checkable) {
        let carried: Vec<&OuterHarmonic> = list
            .iter()
            .filter(|h| h.significant_share > OUTER_SIGNIFICANT_SHARE)
            .collect();
        if !carried.is_empty() {
            notes.push(format!(
                "output {}: the response carries harmonics outside estimation.harmonics ({}), \
                 significant where estimated beside the others; left out, they are absorbed \
                 by the harmonics estimated as a bias their standard errors do not show: add \
                 them to estimation.harmonics (an orbit with impacts carries every harmonic: \
                 add until those beyond stay near the noise's 2 %, or read the estimates as \
                 biased by them)",
                outputs[o],
                carried
                    .iter()
                    .map(|h| format!(
                        "G_{} at {:.0} % of the band",
                        h.n,
                        100.0 * h.significant_share
                    ))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
    }
    if hi > nyquist {
        notes.push(format!(
            "estimation.omega_max = {hi} rad/s is above the Nyquist frequency {nyquist:.1} rad/s"
        ));
    }

    stages.run("write outputs", || -> Result<()> {
        for (o, e) in estimates.iter().enumerate() {
            write_estimate_csv(
                &mut outdir,
                &format!("estimate_siddiqi{}.csv", suffix(o)),
                e,
            )?;
        }
        // One period of the measured orbit (the periodic part), from its harmonics.
        let mut header = vec!["phase".to_string(), settings.input.clone()];
        header.extend(outputs.iter().cloned());
        let header_refs: Vec<&str> = header.iter().map(String::as_str).collect();
        let mut csv = outdir.csv("orbit.csv", &header_refs)?;
        let eval = |c: &[Complex64], t: f64| {
            c.iter().enumerate().fold(0.0, |acc, (k, ck)| {
                let z = ck * Complex64::from_polar(1.0, k as f64 * wp * t);
                acc + if k == 0 { z.re } else { 2.0 * z.re }
            })
        };
        let samples = 200;
        for i in 0..samples {
            let t = period * i as f64 / samples as f64;
            let mut row = vec![t, eval(&u_split.harmonics, t)];
            row.extend(orbits.iter().map(|y| eval(&y.harmonics, t)));
            csv.write_row(&row)?;
        }
        csv.finish()?;
        for (o, e) in estimates.iter().enumerate() {
            let fig = figure(&settings, &outputs[o], e);
            plots::write(
                &mut outdir,
                &format!("estimate_harmonics{}", suffix(o)),
                &fig,
            )?;
        }
        Ok(())
    })?;

    let per_output: Vec<Value> = estimates
        .iter()
        .zip(outputs)
        .map(|(e, name)| {
            let by_n: serde_json::Map<String, Value> = settings
                .harmonics
                .iter()
                .map(|&k| {
                    let rows: Vec<_> = e.rows().filter(|r| r.n == k).collect();
                    let max = rows.iter().map(|r| r.value.norm()).fold(0.0, f64::max);
                    // Where the estimate stands out of its noise over the whole band.
                    let max_significant = e
                        .harmonic(k)
                        .and_then(|h| h.largest_significant(BAND_FALSE_ALARM))
                        .unwrap_or(f64::NAN);
                    let mut snr: Vec<f64> = rows
                        .iter()
                        .filter(|r| r.stderr > 0.0)
                        .map(|r| r.value.norm() / r.stderr)
                        .collect();
                    snr.sort_by(f64::total_cmp);
                    let significant = snr.iter().filter(|&&s| s > 2.0).count();
                    // The smoothing bias the estimator estimates beside its values (one per
                    // row, in the rows' order), against the noise-only standard errors.
                    let bias = e
                        .bias()
                        .zip(e.harmonics().iter().position(|&m| m == k))
                        .map_or(f64::NAN, |((_, b), i)| {
                            rows.iter()
                                .zip(&b[i])
                                .filter(|(r, _)| r.stderr > 0.0)
                                .map(|(r, b)| b.norm() / r.stderr)
                                .fold(f64::NAN, f64::max)
                        });
                    (
                        k.to_string(),
                        json!({
                            "max_abs_g": max,
                            "max_abs_g_significant": max_significant,
                            "median_abs_g_over_stderr": snr.get(snr.len() / 2).copied().unwrap_or(f64::NAN),
                            "significant_points": significant,
                            "points": rows.len(),
                            "max_bias_over_stderr": bias,
                        }),
                    )
                })
                .collect();
            json!({"output": name, "alpha": e.alpha(), "alpha_effective": e.alpha_effective(), "harmonics": by_n})
        })
        .collect();
    let summary = json!({
        "name": settings.name,
        "config": settings.path.display().to_string(),
        "data": settings.file.display().to_string(),
        "units": settings.format.units_json(),
        "htfid_version": env!("CARGO_PKG_VERSION"),
        "period": {
            "value": period,
            "source": if estimated.is_some() { "estimated" } else { "given" },
            "estimated": estimated.map(|e| e.period),
            "periodic_share": estimated.map(|e| e.periodic_share),
            "pumping_frequency": wp,
        },
        "record": {
            "start": t_start,
            "samples": n,
            "sample_rate": 1.0 / dt,
            "duration": n as f64 * dt,
            "periods": periods,
            "frequency_resolution": resolution,
            "nyquist": nyquist,
        },
        "checks": {
            "excited_band": excited.map(|(a, b)| [a, b]),
            "unexcited": unexcited.iter().map(|(n, ranges)| json!({
                "n": n,
                "omega": ranges.iter().map(|&(a, b)| [a, b]).collect::<Vec<_>>(),
            })).collect::<Vec<_>>(),
            "notes": notes,
            "outer_harmonics": outer.iter().zip(outputs).map(|(list, name)| json!({
                "output": name,
                "harmonics": list.iter().map(|h| json!({
                    "n": h.n,
                    "significant_share": h.significant_share,
                    "max_abs_g": h.max_abs,
                })).collect::<Vec<_>>(),
            })).collect::<Vec<_>>(),
        },
        "estimation": {
            "estimator": "siddiqi",
            "input": settings.input,
            "harmonics": settings.harmonics,
            "band": [lo, hi],
        },
        "estimates": per_output,
        "timings_ms": stages.to_json(),
    });
    outdir.write_text("summary.json", &json_text(&summary))?;
    let plots: Vec<String> = (0..outputs.len())
        .map(|o| format!("estimate_harmonics{}.png", suffix(o)))
        .collect();
    outdir.write_text(
        "report.md",
        &crate::report::estimate(&summary, &settings.path, &settings.file, &plots),
    )?;
    // The notes are part of the results: printed with them on stdout.
    let written = outdir.commit()?;
    crate::results::estimate(&summary, &dir, &written);
    Ok(())
}

/// The band (rad/s) where the input's spectrum lies within 40 dB of its peak: from the lowest
/// to the highest frequency bin above that level, the record Hann-windowed first so that a
/// strong line's leakage falls below it within a few bins; `None` for an input without
/// content.
fn excited_band(u: &[f64], dt: f64) -> Option<(f64, f64)> {
    let n = u.len();
    let mut buf: Vec<Complex64> = u
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            let w = 0.5 - 0.5 * (2.0 * PI * i as f64 / n as f64).cos();
            Complex64::new(w * v, 0.0)
        })
        .collect();
    rustfft::FftPlanner::new()
        .plan_fft_forward(n)
        .process(&mut buf);
    let power: Vec<f64> = buf[1..n / 2].iter().map(|z| z.norm_sqr()).collect();
    let peak = power.iter().copied().fold(0.0, f64::max);
    if peak.is_nan() || peak <= 0.0 {
        return None;
    }
    let first = power.iter().position(|&p| p >= 1e-4 * peak)?;
    let last = power.iter().rposition(|&p| p >= 1e-4 * peak)?;
    let bin = 2.0 * PI / (n as f64 * dt);
    Some(((first + 1) as f64 * bin, (last + 1) as f64 * bin))
}

/// Per harmonic of `e`, the ranges of its output frequencies `w` (rad/s) whose input frequency
/// `|w - n wp|` lies more than a frequency bin outside the excited band `(lo, hi)`, where they
/// cover more than [`UNEXCITED_SHARE`] of the harmonic's frequencies.
fn unexcited_ranges(
    e: &HtfEstimate,
    wp: f64,
    (lo, hi): (f64, f64),
    bin: f64,
) -> Vec<(i32, Vec<(f64, f64)>)> {
    let mut out = Vec::new();
    for &n in e.harmonics() {
        let rows: Vec<f64> = e.rows().filter(|r| r.n == n).map(|r| r.omega).collect();
        let outside = |w: f64| {
            let input = (w - f64::from(n) * wp).abs();
            input < lo - bin || input > hi + bin
        };
        let count = rows.iter().filter(|&&w| outside(w)).count();
        if rows.is_empty() || (count as f64) <= UNEXCITED_SHARE * rows.len() as f64 {
            continue;
        }
        let mut ranges: Vec<(f64, f64)> = Vec::new();
        let mut open: Option<(f64, f64)> = None;
        for &w in &rows {
            match (outside(w), open.as_mut()) {
                (true, Some(range)) => range.1 = w,
                (true, None) => open = Some((w, w)),
                (false, Some(_)) => ranges.extend(open.take()),
                (false, None) => {}
            }
        }
        ranges.extend(open);
        out.push((n, ranges));
    }
    out
}

/// `|G_n|` of one output with its 95 % confidence region (`|G| +- 1.96 stderr`) shaded and
/// the estimates that are not significant (`|G| < 2 stderr`) faded.
fn figure(settings: &EstimateSettings, output: &str, e: &HtfEstimate) -> htfid_plot::Figure {
    type Series = (Vec<f64>, Vec<Complex64>, Vec<f64>);
    let series: Vec<(i32, Series)> = settings
        .harmonics
        .iter()
        .map(|&k| {
            let rows: Vec<_> = e.rows().filter(|r| r.n == k).collect();
            (
                k,
                (
                    rows.iter().map(|r| r.omega).collect(),
                    rows.iter().map(|r| r.value).collect(),
                    rows.iter().map(|r| r.stderr).collect(),
                ),
            )
        })
        .collect();
    let per: Vec<(i32, Vec<Curve<'_>>)> = series
        .iter()
        .map(|(k, (w, g, se))| {
            (
                *k,
                vec![Curve {
                    label: "estimate (Siddiqi)",
                    omega: w,
                    values: g,
                    style: Style::Line,
                    stderr: Some(se),
                }],
            )
        })
        .collect();
    // |G_n| carries the output's unit per the input's (data.units), when both are given.
    let f = &settings.format;
    let unit = match (f.unit(output), f.unit(&settings.input)) {
        (Some(y), Some(u)) => format!(", dB re 1 {y}/{u}"),
        _ => String::new(),
    };
    plots::harmonics(
        &format!(
            "{}: |G_n| of {output} from data (Siddiqi{unit})",
            settings.name
        ),
        &per,
    )
}

/// Refuses, before any transform, a band the record cannot resolve and an estimate that cannot
/// fit in `--max-memory`. Every output frequency `w` of the band with harmonic `n` needs input
/// at `w - n wp` below the Nyquist frequency; a record whose time column is in milliseconds
/// fails this (its Nyquist frequency is a thousand times too low).
fn check_band(
    settings: &EstimateSettings,
    dt: f64,
    period: f64,
    samples: usize,
    hint: &str,
) -> Result<()> {
    let wp = 2.0 * PI / period;
    let (lo, hi) = settings.band;
    let needed = settings
        .harmonics
        .iter()
        .map(|&n| {
            let shift = f64::from(n) * wp;
            (lo - shift).abs().max((hi - shift).abs())
        })
        .fold(0.0, f64::max);
    let nyquist = PI / dt;
    if needed >= nyquist {
        bail!(
            "{}: estimation.omega_max = {hi} with harmonics up to {} needs input up to \
             {needed:.3} rad/s, at or beyond the record's Nyquist frequency {nyquist:.3e} rad/s \
             (sampled every {dt:.3e} s): narrow the band (estimation.omega_min, omega_max) or \
             the harmonics, or {hint}",
            settings.path.display(),
            settings
                .harmonics
                .iter()
                .map(|n| n.abs())
                .max()
                .unwrap_or(0)
        );
    }
    let limit = crate::limits::get().max_memory;
    let estimator = htfid_estimate::estimator_bytes(
        1,
        samples as u64,
        dt,
        settings.harmonics.len(),
        settings.band,
    );
    // The records of every output stay in memory beside the estimator (time, input, output,
    // and the periodic split of each).
    let records = (samples as u64)
        .saturating_mul(8 * 5)
        .saturating_mul(settings.outputs.len() as u64);
    let total = estimator.saturating_add(records);
    if total > limit {
        bail!(
            "{}: data.file = \"{}\" ({} samples after data.start) needs about {} for the \
             estimate (limit {}; raise with --max-memory, or narrow the band or set data.start)",
            settings.path.display(),
            settings.file.display(),
            samples,
            crate::limits::Bytes(total),
            crate::limits::Bytes(limit)
        );
    }
    Ok(())
}
