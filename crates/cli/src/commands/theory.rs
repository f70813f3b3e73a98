//! `htfid theory CONFIG`: linearisation about the orbit and the harmonic transfer functions of
//! every output, for any configured model ([`Subject`]).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use htfid_plot::Style;
use htfid_theory::{HarmonicTransferFunction, HtfGrid, TruncatedHtf};
use num_complex::Complex64;
use serde_json::json;

use crate::commands::simulate::head_summary;
use crate::output::{json_text, open, resolve_dir};
use crate::plots::{self, Curve};
use crate::progress::Stages;
use crate::settings::Settings;
use crate::subject::{about_orbit, ltp_json, with_subject, Subject};

/// Parses `--omega 2,3.5,10`.
fn parse_omegas(list: &str) -> Result<Vec<f64>> {
    let mut out = Vec::new();
    for (i, item) in list.split(',').enumerate() {
        let item = item.trim();
        let w: f64 = item
            .parse()
            .with_context(|| format!("--omega: item {} ({item:?}) is not a number", i + 1))?;
        if !w.is_finite() {
            bail!("--omega: item {} ({item}) is not finite", i + 1);
        }
        out.push(w);
    }
    if out.is_empty() {
        bail!("--omega: give at least one frequency in rad/s, e.g. --omega 2,5,13.5");
    }
    Ok(out)
}

/// The columns of `theory.csv`.
pub const THEORY_HEADER: &[&str] = &["omega", "n", "re", "im"];

pub fn write_theory_csv(out: &mut htfid_data::OutputDir, name: &str, grid: &HtfGrid) -> Result<()> {
    fill_theory_csv(out.csv(name, THEORY_HEADER)?, grid)
}

/// Writes the rows of `theory.csv` into `csv` (opened with [`THEORY_HEADER`]).
pub fn fill_theory_csv(mut csv: htfid_data::CsvWriter, grid: &HtfGrid) -> Result<()> {
    for (i, &w) in grid.omegas.iter().enumerate() {
        for (j, &n) in grid.harmonics.iter().enumerate() {
            let g = grid.values[i * grid.harmonics.len() + j];
            csv.write_row(&[w, f64::from(n), g.re, g.im])?;
        }
    }
    csv.finish()?;
    Ok(())
}

pub fn run(
    config: &Path,
    omega: Option<String>,
    truncate: Option<usize>,
    out: Option<PathBuf>,
    force: bool,
    no_plots: bool,
) -> Result<()> {
    let settings = Settings::from_file(config)?;
    let omegas = match &omega {
        Some(list) => parse_omegas(list)?,
        None => settings.theory.omegas.clone(),
    };
    crate::limits::check_experiment(&settings, crate::limits::Stage::Theory { omegas: &omegas })?;
    if let Some(n) = truncate {
        if n > 200 {
            bail!("--truncate {n}: at most 200 harmonics (the exact HTF needs no truncation)");
        }
    }
    let command = TheoryCommand {
        omegas: &omegas,
        truncate,
        no_plots,
    };
    with_subject!(&settings, |subject| command
        .run(&settings, subject, out, force))
}

/// What `htfid theory` was asked for beyond the config.
struct TheoryCommand<'a> {
    omegas: &'a [f64],
    /// Wereley's truncated harmonic state space of this order instead of the exact HTF.
    truncate: Option<usize>,
    no_plots: bool,
}

impl TheoryCommand<'_> {
    fn run<S: Subject>(
        &self,
        settings: &Settings,
        subject: &S,
        out: Option<PathBuf>,
        force: bool,
    ) -> Result<()> {
        let outputs = subject.output_names();
        let mut names: Vec<String> = vec!["theory.csv".into(), "summary.json".into()];
        if outputs.len() > 1 {
            names.extend(outputs.iter().map(|o| format!("theory_{o}.csv")));
        }
        // Figures of the first output under the plain names, of every further one with its
        // name.
        let suffixes: Vec<String> = (0..outputs.len()).map(|o| suffix(&outputs, o)).collect();
        if !self.no_plots {
            for suffix in &suffixes {
                for stem in ["theory_g0", "theory_harmonics", "theory_phases"] {
                    names.push(format!("{stem}{suffix}.svg"));
                    names.push(format!("{stem}{suffix}.png"));
                }
            }
        }
        let name_refs: Vec<&str> = names.iter().map(String::as_str).collect();
        let dir = resolve_dir(out, &settings.name);
        let mut outdir = open(&dir, force, &name_refs)?;
        let mut stages = Stages::new();
        let (cycle, htf) = about_orbit(settings, subject, &mut stages)?;
        let harmonics = settings.theory.harmonics.clone();
        let omegas = self.omegas;
        let (grids, mut method) = match self.truncate {
            None => (
                stages
                    .run("HTF", || htf.grids(&harmonics, omegas))
                    .context("harmonic transfer functions")?,
                json!({"method": subject.method_name(htf.method())}),
            ),
            Some(n) => {
                let lti = &htf
                    .linearisation()
                    .context(
                        "--truncate: this model's linearisation is not constant within each \
                         mode, so it has no harmonic state space to truncate; its HTF is \
                         computed exactly (leave out --truncate)",
                    )?
                    .piecewise;
                let grids = stages.run("truncated HTF", || -> Result<Vec<HtfGrid>> {
                    (0..outputs.len())
                        .map(|o| {
                            let t = TruncatedHtf::new(&lti.channel(o, 0)?, n)
                                .context("truncated HTF (Wereley's harmonic state space)")?;
                            Ok(t.grid(&harmonics, omegas))
                        })
                        .collect()
                })?;
                (grids, json!({"method": "truncated", "truncation": n}))
            }
        };
        stages.run("write outputs", || -> Result<()> {
            write_theory_csv(&mut outdir, "theory.csv", &grids[0])?;
            if outputs.len() > 1 {
                for (o, grid) in outputs.iter().zip(&grids) {
                    write_theory_csv(&mut outdir, &format!("theory_{o}.csv"), grid)?;
                }
            }
            Ok(())
        })?;
        if !self.no_plots {
            // Each output's figures; its name in the title where there are several.
            stages.run("plots", || -> Result<()> {
                for ((output, suffix), grid) in outputs.iter().zip(&suffixes).zip(&grids) {
                    let title = if outputs.len() > 1 {
                        format!("{} (output {output})", settings.name)
                    } else {
                        settings.name.clone()
                    };
                    theory_plots(&mut outdir, &title, suffix, settings, grid)?;
                }
                Ok(())
            })?;
        }
        method["harmonics"] = json!(harmonics);
        method["points"] = json!(omegas.len());
        let mut summary = head_summary(settings, subject, &cycle)?;
        summary["ltp"] = ltp_json(subject, &htf, &cycle);
        summary["htf"] = subject.theory_htf_json(method, &grids);
        summary["timings_ms"] = stages.to_json();
        outdir.write_text("summary.json", &json_text(&summary))?;
        let written = outdir.commit()?;
        crate::results::theory(&summary, &dir, &written);
        Ok(())
    }
}

/// The first output keeps the single-output file names; others get their name appended.
pub(crate) fn suffix(outputs: &[String], o: usize) -> String {
    if o == 0 {
        String::new()
    } else {
        format!("_{}", outputs[o])
    }
}

fn column(grid: &HtfGrid, n: i32) -> Vec<Complex64> {
    let j = grid
        .harmonics
        .iter()
        .position(|&h| h == n)
        .expect("harmonic in grid");
    (0..grid.omegas.len())
        .map(|i| grid.values[i * grid.harmonics.len() + j])
        .collect()
}

/// The theory figures of `grid` (`theory_g0{suffix}`, `theory_harmonics{suffix}`,
/// `theory_phases{suffix}`), titled `title` (the config's name, with the output's where a model
/// has several).
pub fn theory_plots(
    out: &mut htfid_data::OutputDir,
    title: &str,
    suffix: &str,
    settings: &Settings,
    grid: &HtfGrid,
) -> Result<()> {
    // Plots need positive, increasing frequencies; a user's --omega list may be anything.
    if grid.omegas.len() < 2
        || grid.omegas.windows(2).any(|w| w[1] <= w[0])
        || grid.omegas[0] <= 0.0
    {
        return Ok(());
    }
    let cols: Vec<(i32, Vec<Complex64>)> = settings
        .theory
        .plot_harmonics
        .iter()
        .filter(|n| grid.harmonics.contains(n))
        .map(|&n| (n, column(grid, n)))
        .collect();
    if let Some((_, g0)) = cols.iter().find(|(n, _)| *n == 0) {
        let fig = plots::bode(
            &format!("{title}: G_0, theory"),
            &[Curve {
                label: "theory",
                omega: &grid.omegas,
                values: g0,
                style: Style::Line,
                stderr: None,
            }],
        );
        plots::write(out, &format!("theory_g0{suffix}"), &fig)?;
    }
    let per: Vec<(i32, Vec<Curve<'_>>)> = cols
        .iter()
        .map(|(n, v)| {
            (
                *n,
                vec![Curve {
                    label: "theory",
                    omega: &grid.omegas,
                    values: v,
                    style: Style::Line,
                    stderr: None,
                }],
            )
        })
        .collect();
    let fig = plots::harmonics(&format!("{title}: |G_n|, theory"), &per);
    plots::write(out, &format!("theory_harmonics{suffix}"), &fig)?;
    let fig = plots::harmonic_phases(&format!("{title}: phase of G_n, theory"), &per);
    plots::write(out, &format!("theory_phases{suffix}"), &fig)?;
    Ok(())
}
