//! The results on standard output: a short, aligned summary at the end of every command.
//!
//! Everything shown is read from the JSON the command writes (`summary.json`,
//! `diagnosis.json`), so the terminal and the files never disagree and no science is redone
//! here. Numbers are formatted by `crate::number`: 4 significant digits, a value with a
//! standard error to the precision the error allows.

use std::path::{Path, PathBuf};

use serde_json::Value;

use htfid_number::{percent, sig, Quantity};

/// Label column, then values; a value may span several lines.
#[derive(Debug)]
struct Table {
    title: String,
    rows: Vec<(String, Vec<String>)>,
}

impl Table {
    fn new(title: String) -> Self {
        Table {
            title,
            rows: Vec::new(),
        }
    }

    fn row(&mut self, label: &str, value: impl Into<String>) {
        self.rows.push((label.to_string(), vec![value.into()]));
    }

    fn rows(&mut self, label: &str, lines: Vec<String>) {
        if !lines.is_empty() {
            self.rows.push((label.to_string(), lines));
        }
    }

    fn print(&self) {
        let width = self
            .rows
            .iter()
            .map(|(l, _)| l.chars().count())
            .max()
            .unwrap_or(0);
        let mut text = format!("{}\n", self.title);
        for (label, lines) in &self.rows {
            for (i, line) in lines.iter().enumerate() {
                let l = if i == 0 { label.as_str() } else { "" };
                text.push_str(&format!("  {l:<width$}  {line}\n"));
            }
        }
        print!("{text}");
    }
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}

/// `value ± stderr unit`, to the precision the standard error allows.
fn pm(value: f64, stderr: f64, unit: Option<&str>) -> String {
    Quantity::new(value).stderr(stderr).unit(unit).to_string()
}

fn pct(x: f64) -> String {
    percent(x, 3)
}

/// Where the results are: the directory as given (relative to the working directory when it is
/// inside it) and the number of files.
fn location(dir: &Path, files: &[PathBuf]) -> String {
    let shown = std::env::current_dir()
        .ok()
        .and_then(|cwd| dir.strip_prefix(cwd).ok().map(Path::to_path_buf))
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or_else(|| dir.to_path_buf());
    let n = files.len();
    format!(
        "{}/ ({n} file{})",
        shown.display().to_string().trim_end_matches('/'),
        if n == 1 { "" } else { "s" }
    )
}

fn title(command: &str, summary: &Value) -> String {
    let name = summary["name"].as_str().unwrap_or("");
    let ms = f(&summary["timings_ms"]["total"]);
    if ms.is_finite() {
        format!("htfid {command} {name}: done in {} s", sig(ms / 1e3, 3))
    } else {
        format!("htfid {command} {name}: done")
    }
}

/// The largest modulus of the orbit's Floquet multipliers (`[re, im]` pairs) in a
/// `summary.json`; NaN when there are none.
pub fn largest_floquet(summary: &Value) -> f64 {
    summary["limit_cycle"]["floquet_multipliers"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|m| Some(f(m.get(0)?).hypot(f(m.get(1)?))))
        .fold(f64::NAN, f64::max)
}

/// Period, and the largest Floquet multiplier's modulus (stability of the orbit).
fn limit_cycle(t: &mut Table, summary: &Value) {
    let lc = &summary["limit_cycle"];
    let mut text = format!("period {} s", sig(f(&lc["period"]), 4));
    let largest = largest_floquet(summary);
    if largest.is_finite() {
        text.push_str(&format!(
            ", largest Floquet multiplier |μ| {}",
            sig(largest, 4)
        ));
    }
    t.row("limit cycle", text);
    let silent: Vec<&str> = lc["guards_not_firing"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(Value::as_str)
        .collect();
    if !silent.is_empty() {
        t.row(
            "note",
            format!(
                "guard{} {} never fire{} on the orbit (a threshold beyond the motion, or a \
                 direction the wrong way round?)",
                if silent.len() > 1 { "s" } else { "" },
                silent
                    .iter()
                    .map(|g| format!("`{g}`"))
                    .collect::<Vec<_>>()
                    .join(", "),
                if silent.len() > 1 { "" } else { "s" }
            ),
        );
    }
}

fn simulation(t: &mut Table, summary: &Value) {
    let s = &summary["simulation"];
    if s.is_null() {
        return;
    }
    t.row(
        "simulation",
        format!(
            "{} s at {} Hz: {} samples, {} switches",
            sig(f(&s["t_end"]), 4),
            sig(f(&s["sample_rate"]), 4),
            s["samples"],
            s["switches"]
        ),
    );
}

/// `htfid simulate`.
pub fn simulate(summary: &Value, dir: &Path, files: &[PathBuf]) {
    let mut t = Table::new(title("simulate", summary));
    limit_cycle(&mut t, summary);
    simulation(&mut t, summary);
    t.row("results", location(dir, files));
    t.print();
}

/// `htfid theory`.
pub fn theory(summary: &Value, dir: &Path, files: &[PathBuf]) {
    let mut t = Table::new(title("theory", summary));
    limit_cycle(&mut t, summary);
    let h = &summary["htf"];
    let method = match h["truncation"].as_u64() {
        Some(n) => format!("truncated at {n} harmonics"),
        None => h["method"].as_str().unwrap_or("exact").replace('_', " "),
    };
    let max_abs = match &h["max_abs"] {
        Value::Array(per_output) => per_output
            .iter()
            .enumerate()
            .map(|(i, v)| match h["outputs"][i].as_str() {
                Some(output) if per_output.len() > 1 => format!("{} ({output})", sig(f(v), 4)),
                _ => sig(f(v), 4),
            })
            .collect::<Vec<_>>()
            .join(", "),
        v => sig(f(v), 4),
    };
    t.row(
        "HTF",
        format!(
            "{method}, harmonics {}, {}, max |G_n| {max_abs}",
            harmonics(&h["harmonics"]),
            match h["points"].as_u64() {
                Some(1) => "1 frequency".to_string(),
                _ => format!("{} frequencies", h["points"]),
            }
        ),
    );
    t.row("results", location(dir, files));
    t.print();
}

fn harmonics(v: &Value) -> String {
    let ns: Vec<i64> = v
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(Value::as_i64)
        .collect();
    match (ns.first(), ns.last()) {
        (Some(a), Some(b)) if ns.len() > 2 && (b - a) as usize + 1 == ns.len() => {
            format!("{a}..{b}")
        }
        _ => ns.iter().map(i64::to_string).collect::<Vec<_>>().join(", "),
    }
}

/// `htfid run`: the fits with standard errors and the HTF errors against the exact theory, in
/// the config's order of estimators and of `fitted` parameters. `unit` gives a parameter's unit.
pub fn run(
    summary: &Value,
    fitted: &[String],
    unit: &dyn Fn(&str) -> Option<String>,
    dir: &Path,
    files: &[PathBuf],
) {
    let mut t = Table::new(title("run", summary));
    limit_cycle(&mut t, summary);
    simulation(&mut t, summary);
    let estimators: Vec<&str> = summary["estimation"]["estimators"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(Value::as_str)
        .collect();
    for estimator in &estimators {
        let fit = &summary["fit"][estimator];
        let lines: Vec<String> = fitted
            .iter()
            .filter(|name| !fit[name.as_str()].is_null())
            .map(|name| {
                let stderr = f(&fit[format!("{name}_stderr")]);
                let u = unit(name);
                format!(
                    "{name} = {}",
                    pm(f(&fit[name.as_str()]), stderr, u.as_deref())
                )
            })
            .collect();
        t.rows(&format!("fit ({estimator})"), lines);
        t.rows(
            &format!("uncertainty ({estimator})"),
            uncertainty_lines(&fit["uncertainty"], fitted, unit),
        );
    }
    // Error keys: `<estimator>` for the first output, `<estimator>_<output>` for the others.
    let outputs: Vec<&str> = summary["htf"]["outputs"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(Value::as_str)
        .collect();
    let mut columns = Vec::new();
    for estimator in &estimators {
        if outputs.len() > 1 {
            for (i, output) in outputs.iter().enumerate() {
                let key = if i == 0 {
                    estimator.to_string()
                } else {
                    format!("{estimator}_{output}")
                };
                columns.push((format!("{estimator} ({output})"), &summary["errors"][key]));
            }
        } else {
            columns.push((estimator.to_string(), &summary["errors"][estimator]));
        }
    }
    t.rows("HTF error", error_table(&columns));
    t.row("results", location(dir, files));
    t.print();
}

/// One line per parameter of `fit.<estimator>.uncertainty`: the interval's half width at its
/// level, the components, and which dominates (`docs/outputs.md`).
fn uncertainty_lines(
    u: &Value,
    fitted: &[String],
    unit: &dyn Fn(&str) -> Option<String>,
) -> Vec<String> {
    let Some(params) = u["parameters"].as_object() else {
        return Vec::new();
    };
    let source = u["htf_bias_source"].as_str().map(|s| s.replace('_', " "));
    let level = f(&u["level"]);
    fitted
        .iter()
        .filter_map(|name| {
            let p = params.get(name)?;
            let unit = unit(name).map_or(String::new(), |u| format!(" {u}"));
            let mut parts = vec![format!("noise {}", sig(f(&p["noise"]), 3))];
            if let Some(source) = &source {
                parts.push(format!("{source} {}", sig(f(&p["htf_bias"]), 3)));
            }
            parts.push(format!("structure {}", sig(f(&p["structure"]), 3)));
            Some(format!(
                "{name} ± {}{unit} at {} ({}): {} dominates",
                sig(f(&p["half_width"]), 3),
                pct(level),
                parts.join(", "),
                p["dominant"].as_str().unwrap_or("?").replace('_', " ")
            ))
        })
        .collect()
}

/// Per harmonic (rows) and estimate (columns): median and max over the band of
/// `|G_hat_n - G_n| / max|G_n|`.
fn error_table(columns: &[(String, &Value)]) -> Vec<String> {
    let mut ns: Vec<i64> = columns
        .iter()
        .filter_map(|(_, e)| e.as_object())
        .flat_map(|m| m.keys().filter_map(|k| k.parse().ok()))
        .collect();
    ns.sort_unstable();
    ns.dedup();
    if ns.is_empty() {
        return Vec::new();
    }
    let cell = |e: &Value, n: i64| -> String {
        let h = &e[n.to_string()];
        if h.is_null() {
            "-".into()
        } else {
            format!("{} / {}", pct(f(&h["median"])), pct(f(&h["max"])))
        }
    };
    let columns: Vec<(&String, Vec<String>)> = columns
        .iter()
        .map(|(name, e)| (name, ns.iter().map(|&n| cell(e, n)).collect()))
        .collect();
    let widths: Vec<usize> = columns
        .iter()
        .map(|(name, cells)| {
            cells
                .iter()
                .map(|c| c.chars().count())
                .chain([name.chars().count()])
                .max()
                .unwrap_or(0)
        })
        .collect();
    let mut lines = vec![format!(
        "relative to max|G_n|, median / max over the band\n{:>4}  {}",
        "n",
        columns
            .iter()
            .zip(&widths)
            .map(|((name, _), w)| format!("{name:>w$}"))
            .collect::<Vec<_>>()
            .join("  ")
    )];
    for (i, n) in ns.iter().enumerate() {
        lines.push(format!(
            "{n:>4}  {}",
            columns
                .iter()
                .zip(&widths)
                .map(|((_, cells), w)| format!("{:>w$}", cells[i]))
                .collect::<Vec<_>>()
                .join("  ")
        ));
    }
    // The first entry holds two lines; split so every line is a row of the table.
    lines
        .into_iter()
        .flat_map(|l| l.lines().map(str::to_string).collect::<Vec<_>>())
        .collect()
}

/// `htfid estimate`: period, record, what was resolved, and the notes on what was not.
pub fn estimate(summary: &Value, dir: &Path, files: &[PathBuf]) {
    let mut t = Table::new(title("estimate", summary));
    let p = &summary["period"];
    let mut period = format!(
        "{} s ({})",
        sig(f(&p["value"]), 4),
        p["source"].as_str().unwrap_or("")
    );
    if let Some(share) = p["periodic_share"].as_f64() {
        period.push_str(&format!(", periodic share of the output {}", pct(share)));
    }
    t.row("period", period);
    let r = &summary["record"];
    t.row(
        "record",
        format!(
            "{} s at {} Hz: {} samples, {} periods",
            sig(f(&r["duration"]), 4),
            sig(f(&r["sample_rate"]), 4),
            r["samples"],
            sig(f(&r["periods"]), 4)
        ),
    );
    if let Some([lo, hi]) = summary["checks"]["excited_band"]
        .as_array()
        .map(Vec::as_slice)
    {
        t.row(
            "excited band",
            format!("{} - {} rad/s", sig(f(lo), 4), sig(f(hi), 4)),
        );
    }
    for e in summary["estimates"].as_array().into_iter().flatten() {
        let output = e["output"].as_str().unwrap_or("");
        let Some(by_n) = e["harmonics"].as_object() else {
            continue;
        };
        let mut ns: Vec<(i64, &Value)> = by_n
            .iter()
            .filter_map(|(k, v)| Some((k.parse().ok()?, v)))
            .collect();
        ns.sort_by_key(|(n, _)| *n);
        let mut lines = vec![format!(
            "{:>4}  {:>17}  {:>17}",
            "n", "max |G_n| (sig.)", "significant (>2σ)"
        )];
        for (n, h) in ns {
            // The largest where the estimate stands out of its noise ("–" where it nowhere
            // does): elsewhere the modulus is the noise's.
            let largest = h["max_abs_g_significant"]
                .as_f64()
                .map_or("–".to_string(), |v| sig(v, 4));
            lines.push(format!(
                "{n:>4}  {largest:>17}  {:>17}",
                format!("{} of {}", h["significant_points"], h["points"])
            ));
        }
        t.rows(&format!("HTF of {output}"), lines);
    }
    let notes: Vec<String> = summary["checks"]["notes"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|n| n.as_str().map(str::to_string))
        .collect();
    t.rows("notes", notes);
    t.row("results", location(dir, files));
    t.print();
}

/// `htfid diagnose`: the cause, the refitted parameters and the gain.
pub fn diagnose(d: &Value, unit: &dyn Fn(&str) -> Option<String>, dir: &Path, files: &[PathBuf]) {
    let mut t = Table::new(format!(
        "htfid diagnose {}: model {}",
        d["name"].as_str().unwrap_or(""),
        d["model"].as_str().unwrap_or("")
    ));
    t.row("cause", d["cause"].as_str().unwrap_or("?"));
    // Every cause with its share of the explained held-out error, strongest first.
    let causes: Vec<String> = d["causes"]
        .as_array()
        .into_iter()
        .flatten()
        .map(|c| {
            format!(
                "{} ({})",
                c["effect"].as_str().unwrap_or("?"),
                pct(f(&c["gain_share"]))
            )
        })
        .collect();
    if causes.len() > 1 {
        t.row("causes", causes.join(", "));
    }
    // Nothing free: no refit to show beside the configured model.
    let refit = d["options"]["free"]
        .as_array()
        .is_some_and(|free| !free.is_empty());
    if d["extended"].is_object() {
        t.row(
            "gain",
            format!(
                "{} lower held-out NRMSE with the named effects than {}",
                pct(f(&d["gain"])),
                if refit { "refitted" } else { "as configured" }
            ),
        );
    }
    let gain = f(&d["refit_gain"]);
    if refit {
        t.row(
            "refit",
            if gain < 0.0 {
                format!(
                    "{} higher held-out NRMSE refitted than configured",
                    pct(-gain)
                )
            } else {
                format!(
                    "{} lower held-out NRMSE refitted than configured",
                    pct(gain)
                )
            },
        );
    }
    // Each refitted parameter against its configured value (`context` after the value).
    let changes = |list: &Value, context: &str| -> Vec<String> {
        list.as_array()
            .into_iter()
            .flatten()
            .map(|p| {
                let name = p["name"].as_str().unwrap_or("?");
                format!(
                    "{name} = {}{context} (configured {}, z = {})",
                    pm(f(&p["fitted"]), f(&p["stderr"]), unit(name).as_deref()),
                    sig(f(&p["configured"]), 4),
                    sig(f(&p["z"]), 3)
                )
            })
            .collect()
    };
    t.rows("parameters", changes(&d["refit_parameters"], ""));
    let beside = &d["parameters_beside"];
    if beside["named"].as_bool() == Some(true) {
        t.rows(
            "parameter error",
            changes(&beside["moved"], " beside the effects"),
        );
    }
    for (label, key) in [("configured", "configured"), ("refitted", "refitted")]
        .into_iter()
        .take(if refit { 2 } else { 1 })
    {
        let per_output: Vec<String> = d[key]["nrmse_validation"]
            .as_array()
            .into_iter()
            .flatten()
            .map(|v| pct(f(v)))
            .collect();
        t.row(label, format!("held-out NRMSE {}", per_output.join(", ")));
    }
    // The chosen effects' fit: every parameter of it, the refitted free ones included.
    let extended = &d["extended"];
    if let Some(effect) = extended["effect"].as_str() {
        t.row(
            "extended",
            format!(
                "{effect}: held-out NRMSE {} (mean over the outputs)",
                pct(f(&extended["nrmse_validation"]))
            ),
        );
        let lines = extended["parameters"]
            .as_object()
            .into_iter()
            .flatten()
            .map(|(name, v)| {
                format!(
                    "{name} = {}",
                    pm(
                        f(v),
                        f(&extended["stderr"][name.as_str()]),
                        unit(name).as_deref()
                    )
                )
            })
            .collect();
        t.rows("  fitted", lines);
    }
    t.row("results", location(dir, files));
    t.print();
}

/// Units of the built-in hopper's parameters and of the diagnosis effects' parameters
/// (`docs/outputs.md`).
pub fn hopper_unit(name: &str) -> Option<&'static str> {
    Some(match name {
        "m" => "kg",
        "k" | "k_stop" => "N/m",
        "c" | "c_f" => "N s/m",
        "g" => "m/s^2",
        "x0" | "x_stop" => "m",
        "forcing_amplitude" | "mu" => "N",
        "period" | "tau" | "delay" => "s",
        "k3" => "N/m^3",
        "c2" => "N s^2/m^2",
        "v_th" => "m/s",
        _ => return None,
    })
}
