//! `report.md`: what a command found, for a person. The decision comes first, in one
//! paragraph; then the numbers behind it, in tables, with units and to the precision their
//! standard errors allow (`crate::number`); a cell without a value reads `—` and a footnote
//! says why. Paths are relative to the directory htfid ran in.
//!
//! Like the summary on the terminal (`crate::results`), a report is written from the JSON the
//! command writes, so the two never disagree and no science is redone here.

use std::fmt::Write as _;
use std::path::{Component, Path, PathBuf};

use serde_json::Value;

pub use htfid_number::MISSING;
use htfid_number::{percent, sig, Quantity};

/// A Markdown document with numbered footnotes.
#[derive(Debug, Default)]
pub struct Report {
    text: String,
    notes: Vec<String>,
}

impl Report {
    /// A report titled `title`.
    pub fn new(title: &str) -> Self {
        let mut r = Report::default();
        let _ = writeln!(r.text, "# {title}\n");
        r
    }

    /// A section heading.
    pub fn section(&mut self, title: &str) {
        let _ = writeln!(self.text, "## {title}\n");
    }

    /// A paragraph.
    pub fn para(&mut self, text: &str) {
        let _ = writeln!(self.text, "{}\n", text.trim());
    }

    /// A bulleted list; nothing when `items` is empty.
    pub fn list(&mut self, items: &[String]) {
        if items.is_empty() {
            return;
        }
        for item in items {
            let _ = writeln!(self.text, "- {item}");
        }
        self.text.push('\n');
    }

    /// A table; `|` in cells is escaped.
    pub fn table(&mut self, header: &[&str], rows: &[Vec<String>]) {
        let cell = |c: &str| c.replace('|', "\\|");
        let _ = writeln!(
            self.text,
            "| {} |",
            header
                .iter()
                .map(|h| cell(h))
                .collect::<Vec<_>>()
                .join(" | ")
        );
        let _ = writeln!(self.text, "|{}", "---|".repeat(header.len()));
        for row in rows {
            let _ = writeln!(
                self.text,
                "| {} |",
                row.iter().map(|c| cell(c)).collect::<Vec<_>>().join(" | ")
            );
        }
        self.text.push('\n');
    }

    /// A figure with its caption.
    pub fn figure(&mut self, file: &str, caption: &str) {
        let _ = writeln!(self.text, "![{caption}]({file})\n");
    }

    /// The footnote marker for `note` (`[^1]`), the note listed once at the end.
    pub fn note(&mut self, note: &str) -> String {
        let i = match self.notes.iter().position(|n| n == note) {
            Some(i) => i,
            None => {
                self.notes.push(note.to_string());
                self.notes.len() - 1
            }
        };
        format!("[^{}]", i + 1)
    }

    /// `MISSING` with a footnote saying why.
    pub fn missing(&mut self, why: &str) -> String {
        format!("{MISSING}{}", self.note(why))
    }

    /// Raw Markdown, for a section another module writes.
    pub fn push(&mut self, markdown: &str) {
        self.text.push_str(markdown);
        if !markdown.ends_with('\n') {
            self.text.push('\n');
        }
    }

    /// The document, footnotes last.
    pub fn finish(mut self) -> String {
        for (i, n) in self.notes.iter().enumerate() {
            let _ = writeln!(self.text, "[^{}]: {n}", i + 1);
        }
        if !self.notes.is_empty() {
            self.text.push('\n');
        }
        // One trailing newline.
        while self.text.ends_with("\n\n") {
            self.text.pop();
        }
        self.text
    }
}

/// How an estimate of a harmonic compares with the exact theory: the median error over the
/// band below `AGREES` of `max |G_n|` agrees, below `APPROXIMATE` roughly, above it fails.
const AGREES: f64 = 0.01;
const APPROXIMATE: f64 = 0.05;
/// Share of frequencies where a complex estimate of zero exceeds twice its standard error by
/// chance (`exp(-4)`, for a circular Gaussian error): below about twice that, noise alone.
const CHANCE: f64 = 0.05;

/// A parameter of the fit: its configured (true) value and unit.
pub struct ParamInfo {
    pub configured: Option<f64>,
    pub unit: Option<String>,
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}

fn strings(v: &Value) -> Vec<String> {
    v.as_array()
        .into_iter()
        .flatten()
        .filter_map(|x| x.as_str().map(str::to_string))
        .collect()
}

fn harmonic_keys(v: &Value) -> Vec<i64> {
    let mut ns: Vec<i64> = v
        .as_object()
        .into_iter()
        .flat_map(|m| m.keys().filter_map(|k| k.parse().ok()))
        .collect();
    ns.sort_unstable();
    ns
}

/// `G_-1, G_0 and G_1`.
fn g_list(ns: &[i64]) -> String {
    let names: Vec<String> = ns.iter().map(|n| format!("G_{n}")).collect();
    match names.len() {
        0 => String::new(),
        1 => names[0].clone(),
        k => format!("{} and {}", names[..k - 1].join(", "), names[k - 1]),
    }
}

/// `report.md` of `htfid run` (the hopper or a model file): what the experiment resolved,
/// the fitted parameters against the configured ones, the errors against the exact theory.
pub fn run(
    summary: &Value,
    config: &Path,
    fitted: &[String],
    param: &dyn Fn(&str) -> ParamInfo,
    g_unit: Option<&str>,
    plots: bool,
) -> String {
    let name = summary["name"].as_str().unwrap_or("");
    let mut r = Report::new(&format!(
        "{name}: HTFs and parameters identified from a simulated experiment"
    ));
    let estimators = strings(&summary["estimation"]["estimators"]);
    let outputs = strings(&summary["htf"]["outputs"]);
    // Error keys: `<estimator>` for the first output, `<estimator>_<output>` for the others.
    let error_key = |estimator: &str, o: usize| -> String {
        if o == 0 {
            estimator.to_string()
        } else {
            format!("{estimator}_{}", outputs[o])
        }
    };
    let first = estimators.first().cloned().unwrap_or_default();

    // The decision: which harmonics the first estimator resolves, and what the fit recovers.
    let errors = &summary["errors"][&first];
    let ns = harmonic_keys(errors);
    let median = |n: i64| f(&errors[n.to_string()]["median"]);
    let worst = |n: i64| f(&errors[n.to_string()]["max"]);
    let agree: Vec<i64> = ns.iter().copied().filter(|&n| median(n) < AGREES).collect();
    let rough: Vec<i64> = ns
        .iter()
        .copied()
        .filter(|&n| (AGREES..APPROXIMATE).contains(&median(n)))
        .collect();
    let fail: Vec<i64> = ns
        .iter()
        .copied()
        .filter(|&n| median(n) >= APPROXIMATE || median(n).is_nan())
        .collect();
    let mut decision = String::new();
    let of_output = if outputs.len() > 1 {
        format!(" of output `{}`", outputs[0])
    } else {
        String::new()
    };
    if !agree.is_empty() {
        let _ = write!(
            decision,
            "The `{first}` estimates of {}{of_output} agree with the exact theory (median error \
             below {} of the largest |G_n| over the band). ",
            g_list(&agree),
            percent(AGREES, 1)
        );
    }
    if !rough.is_empty() {
        let _ = write!(
            decision,
            "{} {} only roughly (median error {}). ",
            g_list(&rough),
            if rough.len() == 1 { "agrees" } else { "agree" },
            join_and(
                &rough
                    .iter()
                    .map(|&n| percent(median(n), 2))
                    .collect::<Vec<_>>()
            )
        );
    }
    if !fail.is_empty() {
        let _ = write!(
            decision,
            "{} {} not resolved by this experiment (median error {}, worst {}){}. ",
            g_list(&fail),
            if fail.len() == 1 { "is" } else { "are" },
            join_and(
                &fail
                    .iter()
                    .map(|&n| percent(median(n), 2))
                    .collect::<Vec<_>>()
            ),
            join_and(
                &fail
                    .iter()
                    .map(|&n| percent(worst(n), 2))
                    .collect::<Vec<_>>()
            ),
            aliasing_cause(summary, &fail)
        );
    }
    let fit = &summary["fit"][&first];
    let recovered: Vec<String> = fitted
        .iter()
        .filter(|p| !fit[p.as_str()].is_null())
        .map(|p| {
            let info = param(p);
            let value = f(&fit[p.as_str()]);
            let stderr = f(&fit[format!("{p}_stderr")]);
            let shown = Quantity::new(value)
                .stderr(stderr)
                .unit(info.unit.as_deref())
                .to_string();
            match info.configured {
                Some(c) if stderr.is_finite() && stderr > 0.0 && c != 0.0 => format!(
                    "`{p}` = {shown} (configured {}: {} off, {} standard errors)",
                    Quantity::new(c).unit(info.unit.as_deref()),
                    percent(((value - c) / c).abs(), 2),
                    sig(((value - c) / stderr).abs(), 2)
                ),
                Some(c) => format!(
                    "`{p}` = {shown} (configured {})",
                    Quantity::new(c).unit(info.unit.as_deref())
                ),
                None => format!("`{p}` = {shown}"),
            }
        })
        .collect();
    if !recovered.is_empty() {
        let harmonics = fit["harmonics"]
            .as_array()
            .map(|a| a.iter().filter_map(Value::as_i64).collect::<Vec<_>>())
            .unwrap_or_default();
        let _ = write!(
            decision,
            "The fit of the model to the `{first}` estimates of {} gives {}.",
            g_list(&harmonics),
            join_and(&recovered)
        );
    }
    r.para(&decision);

    // The experiment.
    r.section("The experiment");
    let lc = &summary["limit_cycle"];
    let largest = crate::results::largest_floquet(summary);
    let sim = &summary["simulation"];
    let excitation = if !summary["design"].is_null() {
        "a designed periodic multisine".to_string()
    } else {
        match sim["excitation_segments"].as_array().map(Vec::len) {
            Some(1) => "one chirp".to_string(),
            Some(k) => format!("a train of {k} phase-shifted chirps"),
            None => "the configured excitation".to_string(),
        }
    };
    r.list(&[
        format!("Config: `{}`.", shown_path(config)),
        format!(
            "Limit cycle: period {}, largest Floquet multiplier |μ| = {} (stable below 1).",
            Quantity::new(f(&lc["period"])).unit(Some("s")),
            sig(largest, 3)
        ),
        format!(
            "Simulated record: {} at {}, {} samples, excited by {excitation}.",
            Quantity::new(f(&sim["t_end"])).unit(Some("s")),
            Quantity::new(f(&sim["sample_rate"])).unit(Some("Hz")),
            sim["samples"]
        ),
        format!(
            "Estimated: {} over {}–{} rad/s with the {} estimator{}.",
            g_list(&harmonic_keys_of_list(&summary["estimation"]["harmonics"])),
            sig(f(&summary["estimation"]["band"][0]), 3),
            sig(f(&summary["estimation"]["band"][1]), 3),
            estimators
                .iter()
                .map(|e| format!("`{e}`"))
                .collect::<Vec<_>>()
                .join(" and "),
            if estimators.len() == 1 { "" } else { "s" }
        ),
    ]);

    // The parameters.
    r.section("The fitted parameters");
    let mut rows = Vec::new();
    for p in fitted {
        let info = param(p);
        for e in &estimators {
            let fit = &summary["fit"][e];
            if fit[p.as_str()].is_null() {
                continue;
            }
            let value = f(&fit[p.as_str()]);
            let stderr = f(&fit[format!("{p}_stderr")]);
            let unit = info.unit.as_deref();
            let distance = match info.configured {
                Some(c) if stderr.is_finite() && stderr > 0.0 => sig((value - c) / stderr, 2),
                Some(_) => r.missing(
                    "no standard error: the fit left no residual degrees of freedom, or its \
                     covariance is singular",
                ),
                None => r.missing("the config gives no value to compare with"),
            };
            rows.push(vec![
                format!("`{p}`"),
                format!("`{e}`"),
                Quantity::new(value).stderr(stderr).unit(unit).to_string(),
                info.configured.map_or_else(
                    || MISSING.to_string(),
                    |c| Quantity::new(c).unit(unit).to_string(),
                ),
                distance,
            ]);
        }
    }
    r.table(
        &[
            "parameter",
            "fitted to",
            "fitted value ± standard error",
            "configured",
            "fitted − configured, in standard errors",
        ],
        &rows,
    );
    r.para(
        "The configured values are the truth the experiment was simulated with. A fit within \
         about 2 standard errors of them recovers the parameters; a larger distance that is \
         tiny in % (below about 0.01 %) comes from the numerical tolerances of the simulation \
         and the theory rather than from the data.",
    );

    // The HTF errors.
    r.section("The estimates against the exact theory");
    r.para(&format!(
        "Error of an estimate at one frequency: `|Ĝ_n − G_n| / max |G_n|`, the distance to the \
         exact HTF `G_n` relative to the largest `|G_n|` over the band, in %. The table gives \
         its median and its worst value over the band's frequencies; the largest magnitude of \
         `G_n` over the band is in {}.",
        g_unit.map_or("output units per input unit".to_string(), |u| u.to_string())
    ));
    let mut header: Vec<String> = vec!["n".into(), "largest magnitude of G_n".into()];
    let mut columns: Vec<(String, &Value)> = Vec::new();
    for e in &estimators {
        for o in 0..outputs.len().max(1) {
            let label = if outputs.len() > 1 {
                format!("{e} ({})", outputs[o])
            } else {
                e.clone()
            };
            columns.push((label, &summary["errors"][error_key(e, o)]));
        }
    }
    for (label, _) in &columns {
        header.push(format!("`{label}`: median / worst error"));
    }
    let all_ns: Vec<i64> = {
        let mut v: Vec<i64> = columns.iter().flat_map(|(_, e)| harmonic_keys(e)).collect();
        v.sort_unstable();
        v.dedup();
        v
    };
    let mut rows = Vec::new();
    for n in all_ns {
        let key = n.to_string();
        let scale = columns
            .first()
            .map_or(f64::NAN, |(_, e)| f(&e[&key]["max_abs_g"]));
        let mut row = vec![format!("{n}"), sig(scale, 3)];
        for (_, e) in &columns {
            let h = &e[&key];
            row.push(if h.is_null() {
                r.missing("this harmonic was not estimated for this output")
            } else {
                format!(
                    "{} / {}",
                    percent(f(&h["median"]), 2),
                    percent(f(&h["max"]), 2)
                )
            });
        }
        rows.push(row);
    }
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    r.table(&header, &rows);
    if plots {
        r.figure(
            "htf_g0.png",
            "G_0: estimates against the exact theory, 95 % confidence regions shaded",
        );
        r.figure(
            "htf_harmonics.png",
            "|G_n| per harmonic: estimates against the exact theory",
        );
    }
    r.finish()
}

fn harmonic_keys_of_list(v: &Value) -> Vec<i64> {
    v.as_array()
        .into_iter()
        .flatten()
        .filter_map(Value::as_i64)
        .collect()
}

/// `a, b and c`.
pub fn join_and(items: &[String]) -> String {
    match items.len() {
        0 => String::new(),
        1 => items[0].clone(),
        k => format!("{} and {}", items[..k - 1].join(", "), items[k - 1]),
    }
}

/// Why the failing harmonics fail, when the experiment's aliasing report says: another
/// harmonic of comparable size shares their output bins.
fn aliasing_cause(summary: &Value, fail: &[i64]) -> String {
    let by = &summary["aliasing"]["by_harmonic"];
    let mut causes = Vec::new();
    for n in fail {
        let Some(aliases) = by[n.to_string()]["aliases"].as_array() else {
            continue;
        };
        let strong: Vec<String> = aliases
            .iter()
            .filter(|a| f(&a["relative_to_estimated"]) >= 0.1)
            .map(|a| {
                format!(
                    "G_{} ({} the size of G_{n})",
                    a["harmonic"],
                    percent(f(&a["relative_to_estimated"]), 2)
                )
            })
            .collect();
        if !strong.is_empty() {
            causes.push(format!("{} on those of G_{n}", join_and(&strong)));
        }
    }
    if causes.is_empty() {
        String::new()
    } else {
        format!(
            ": with this excitation, harmonics that are not estimated land on the same output \
             frequencies, {}",
            causes.join("; ")
        )
    }
}

/// `report.md` of `htfid estimate`: which harmonics the record resolves, then the period,
/// the record and the notes on what it cannot resolve.
pub fn estimate(summary: &Value, config: &Path, data: &Path, plots: &[String]) -> String {
    let name = summary["name"].as_str().unwrap_or("");
    let mut r = Report::new(&format!("{name}: HTFs estimated from measured data"));
    let units = &summary["units"];
    let p = &summary["period"];
    let rec = &summary["record"];
    let mut decision = String::new();
    for e in summary["estimates"].as_array().into_iter().flatten() {
        let output = e["output"].as_str().unwrap_or("");
        let by_n = &e["harmonics"];
        let ns = harmonic_keys(by_n);
        let share = |n: i64| {
            let h = &by_n[n.to_string()];
            f(&h["significant_points"]) / f(&h["points"])
        };
        let resolved: Vec<i64> = ns.iter().copied().filter(|&n| share(n) >= 0.5).collect();
        let partly: Vec<i64> = ns
            .iter()
            .copied()
            .filter(|&n| (CHANCE..0.5).contains(&share(n)))
            .collect();
        let floor: Vec<i64> = ns
            .iter()
            .copied()
            .filter(|&n| share(n) < CHANCE || share(n).is_nan())
            .collect();
        let shares =
            |ns: &[i64]| join_and(&ns.iter().map(|&n| percent(share(n), 2)).collect::<Vec<_>>());
        let mut parts = Vec::new();
        if !resolved.is_empty() {
            parts.push(format!(
                "resolves {} over most of the band (significant at {} of its frequencies)",
                g_list(&resolved),
                shares(&resolved)
            ));
        }
        if !partly.is_empty() {
            parts.push(format!(
                "resolves {} only in part of the band (significant at {})",
                g_list(&partly),
                shares(&partly)
            ));
        }
        if !floor.is_empty() {
            parts.push(format!(
                "does not lift {} above the noise floor (significant at {}, about what noise \
                 alone gives)",
                g_list(&floor),
                shares(&floor)
            ));
        }
        let _ = write!(
            decision,
            "For output `{output}`, the record {}. ",
            join_and(&parts)
        );
    }
    if summary["estimates"]
        .as_array()
        .is_some_and(|e| !e.is_empty())
    {
        decision.push_str(
            "An estimate is significant at a frequency where its magnitude exceeds twice its \
             standard error; noise alone does so at about 2 % of the frequencies. ",
        );
    }
    let notes = strings(&summary["checks"]["notes"]);
    let _ = write!(
        decision,
        "{}",
        if notes.is_empty() {
            "The checks of the record (number of periods, excited band, aliasing past the \
             Nyquist frequency) found no limit of the experiment."
                .to_string()
        } else {
            format!(
                "The checks found {} limit{} of the experiment, listed below.",
                notes.len(),
                if notes.len() == 1 { "" } else { "s" }
            )
        }
    );
    r.para(&decision);

    r.section("The record");
    let band = summary["checks"]["excited_band"]
        .as_array()
        .filter(|b| b.len() == 2)
        .map_or_else(
            || "no broadband excitation found".to_string(),
            |b| format!("{}–{} rad/s", sig(f(&b[0]), 3), sig(f(&b[1]), 3)),
        );
    let source = p["source"].as_str().unwrap_or("");
    r.list(&[
        format!("Config: `{}`; data: `{}`.", shown_path(config), shown_path(data)),
        format!(
            "Period: {} ({source}{}).",
            Quantity::new(f(&p["value"])).unit(Some("s")),
            p["periodic_share"].as_f64().map_or(String::new(), |s| format!(
                "; the periodic part carries {} of the first output's variance",
                percent(s, 3)
            ))
        ),
        format!(
            "Record: {} from t = {} at {}, {} samples, {} periods; frequency resolution {}, Nyquist frequency {}.",
            Quantity::new(f(&rec["duration"])).unit(Some("s")),
            Quantity::new(f(&rec["start"])).unit(Some("s")),
            Quantity::new(f(&rec["sample_rate"])).unit(Some("Hz")),
            rec["samples"],
            sig(f(&rec["periods"]), 4),
            Quantity::new(f(&rec["frequency_resolution"])).digits(3).unit(Some("rad/s")),
            Quantity::new(f(&rec["nyquist"])).digits(3).unit(Some("rad/s")),
        ),
        format!("Excited band (input spectrum within 40 dB of its peak): {band}."),
    ]);
    if !notes.is_empty() {
        r.section("What the experiment cannot resolve");
        r.list(&notes);
    }

    r.section("The estimates");
    let input = units[summary["estimation"]["input"].as_str().unwrap_or("")].as_str();
    for e in summary["estimates"].as_array().into_iter().flatten() {
        let output = e["output"].as_str().unwrap_or("");
        let unit = match (units[output].as_str(), input) {
            (Some(y), Some(u)) => format!("{y}/{u}"),
            _ => "output units per input unit".to_string(),
        };
        r.para(&format!(
            "Output `{output}` (Siddiqi's estimator, smoothness weight α = {}): per harmonic the \
             largest magnitude of `G_n` over the band in {unit} where it stands out of its noise \
             (above the level noise alone reaches anywhere in the band with probability 5 %, \
             `sqrt(ln(points / 0.05))` standard errors; – where it nowhere does), \
             the median over the band of its \
             magnitude over its standard error, at how many frequencies it is significant, and \
             the largest smoothing bias over the standard error. The standard errors are the \
             noise's; the smoothing also biases the estimate where `G_n` curves (near a \
             resonance), and the estimator estimates that bias (it recovers most, not all, of \
             it): where the ratio nears or passes 1 the confidence region understates the error \
             there, and a smaller α trades bias for noise.",
            sig(f(&e["alpha"]), 3)
        ));
        let by_n = &e["harmonics"];
        let rows: Vec<Vec<String>> = harmonic_keys(by_n)
            .into_iter()
            .map(|n| {
                let h = &by_n[n.to_string()];
                vec![
                    n.to_string(),
                    h["max_abs_g_significant"]
                        .as_f64()
                        .map_or("–".to_string(), |v| sig(v, 3)),
                    sig(f(&h["median_abs_g_over_stderr"]), 2),
                    format!("{} of {}", h["significant_points"], h["points"]),
                    h["max_bias_over_stderr"]
                        .as_f64()
                        .map_or("–".to_string(), |b| sig(b, 2)),
                ]
            })
            .collect();
        r.table(
            &[
                "n",
                "largest significant |G_n|",
                "median magnitude / standard error",
                "significant at",
                "largest smoothing bias / standard error",
            ],
            &rows,
        );
    }
    for file in plots {
        r.figure(file, "|G_n| per harmonic with its 95 % confidence region");
    }
    r.finish()
}

/// `path` as a reader wants to see it: `..` and `.` resolved, relative to the working
/// directory when it lies inside it (`data/hopper-protocol.csv`, not
/// `configs/../data/hopper-protocol.csv`), absolute otherwise.
pub fn shown_path(path: &Path) -> String {
    let cwd = std::env::current_dir().ok();
    let absolute = match &cwd {
        Some(cwd) if path.is_relative() => cwd.join(path),
        _ => path.to_path_buf(),
    };
    let clean = normalise(&absolute);
    let shown = cwd
        .map(|c| normalise(&c))
        .and_then(|c| clean.strip_prefix(c).ok().map(Path::to_path_buf))
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(clean);
    shown.display().to_string()
}

/// `.` and `..` resolved lexically (no symbolic links followed: the path need not exist).
fn normalise(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                if !out.pop() {
                    out.push("..");
                }
            }
            other => out.push(other.as_os_str()),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_read_without_detours() {
        let cwd = std::env::current_dir().unwrap();
        assert_eq!(
            shown_path(Path::new("configs/../data/hopper-protocol.csv")),
            "data/hopper-protocol.csv"
        );
        assert_eq!(
            shown_path(&cwd.join("./configs/./paper.toml")),
            "configs/paper.toml"
        );
        assert_eq!(shown_path(Path::new("/tmp/x/../y.csv")), "/tmp/y.csv");
    }

    #[test]
    fn footnotes_are_numbered_once_and_listed_last() {
        let mut r = Report::new("T");
        let a = r.missing("no standard error: too few degrees of freedom");
        let b = r.missing("no standard error: too few degrees of freedom");
        let c = r.note("another");
        r.table(&["x", "y|z"], &[vec![a.clone(), c.clone()]]);
        assert_eq!(
            (a.as_str(), b.as_str(), c.as_str()),
            ("—[^1]", "—[^1]", "[^2]")
        );
        assert_eq!(
            r.finish(),
            "# T\n\n| x | y\\|z |\n|---|---|\n| —[^1] | [^2] |\n\n\
             [^1]: no standard error: too few degrees of freedom\n[^2]: another\n"
        );
    }
}
