//! `htfid theory CONFIG`: linearisation about the orbit and the harmonic transfer functions.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use htfid_ltp::{linearise, square_wave_fourier, Floquet, Linearisation};
use htfid_model::{Hopper, HopperMode, HopperOrbit};
use htfid_plot::Style;
use htfid_theory::{ExactHtf, HarmonicTransferFunction, HtfGrid, TruncatedHtf};
use num_complex::Complex64;
use serde_json::{json, Value};

use crate::commands::simulate::{hopper_and_orbit, limit_cycle_json};
use crate::output::{json_text, open, resolve_dir};
use crate::plots::{self, Curve};
use crate::progress::Stages;
use crate::settings::{Settings, System};

/// Samples of `A(t)` kept along the orbit (the piecewise model uses quadrature, not these).
const LINEAR_SAMPLES: usize = 256;

/// The LTP model of the configured hopper and its exact HTF.
pub struct Theory {
    pub orbit: HopperOrbit,
    pub linearisation: Linearisation<HopperMode>,
    pub exact: ExactHtf,
}

pub fn build(settings: &Settings, stages: &mut Stages) -> Result<Theory> {
    let (hopper, orbit) = hopper_and_orbit(settings, stages)?;
    from_orbit(settings, hopper, orbit, stages)
}

pub fn from_orbit(
    settings: &Settings,
    hopper: Hopper,
    orbit: HopperOrbit,
    stages: &mut Stages,
) -> Result<Theory> {
    let linearisation = stages
        .run("linearise", || {
            linearise(&hopper, &orbit.cycle, LINEAR_SAMPLES, &settings.integrator)
        })
        .context("linearisation about the orbit failed")?;
    let exact = ExactHtf::new(&linearisation.piecewise).context("exact HTF")?;
    Ok(Theory {
        orbit,
        linearisation,
        exact,
    })
}

/// The `ltp` block of `summary.json`.
pub fn ltp_json(theory: &Theory) -> Value {
    let lti = &theory.linearisation.piecewise;
    let floquet = Floquet::new(lti);
    let mono = lti.monodromy_from(0.0);
    let matrix = |m: &nalgebra::DMatrix<f64>| -> Vec<Vec<f64>> {
        (0..m.nrows())
            .map(|i| (0..m.ncols()).map(|j| m[(i, j)]).collect())
            .collect()
    };
    let orbit = &theory.orbit;
    let period = orbit.cycle.period;
    let s_fourier: Vec<[f64; 2]> = (0..=10)
        .map(|n| {
            let c = if orbit.duty >= 1.0 {
                if n == 0 {
                    Complex64::new(1.0, 0.0)
                } else {
                    Complex64::new(0.0, 0.0)
                }
            } else {
                square_wave_fourier(orbit.t_on, orbit.t_off, period, n)
            };
            [c.re, c.im]
        })
        .collect();
    let pieces: Vec<Value> = lti
        .pieces()
        .iter()
        .enumerate()
        .map(|(i, p)| {
            json!({
                "start": lti.piece_start(i),
                "duration": p.duration(),
                "a": matrix(p.a()),
                "jump": p.jump().map(matrix),
            })
        })
        .collect();
    json!({
        "monodromy": matrix(&mono),
        "floquet_multipliers": floquet.multipliers().iter().map(|m| [m.re, m.im]).collect::<Vec<_>>(),
        "floquet_exponents": floquet.exponents().iter().map(|m| [m.re, m.im]).collect::<Vec<_>>(),
        "monodromy_determinant": mono.determinant(),
        "liouville_determinant": lti.liouville_determinant(),
        "s_fourier": s_fourier,
        "switches": theory.linearisation.switches.iter().map(|s| json!({
            "time": s.time,
            "from": s.from,
            "to": s.to,
            "saltation": matrix(&s.saltation),
        })).collect::<Vec<_>>(),
        "pieces": pieces,
    })
}

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

/// Writes a theory CSV (`theory.csv`): rows `omega,n,re,im`.
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
    if let System::Model(model) = &settings.system {
        if truncate.is_some() {
            bail!("--truncate: model-language models use their exact HTF (no truncation)");
        }
        return crate::commands::models::theory_model(
            &settings, model, &omegas, out, force, no_plots,
        );
    }
    if let Some(n) = truncate {
        if n > 200 {
            bail!("--truncate {n}: at most 200 harmonics (the exact HTF needs no truncation)");
        }
    }
    let dir = resolve_dir(out, &settings.name);
    let mut names = vec!["theory.csv", "summary.json"];
    if !no_plots {
        names.extend([
            "theory_g0.svg",
            "theory_g0.png",
            "theory_harmonics.svg",
            "theory_harmonics.png",
            "theory_phases.svg",
            "theory_phases.png",
        ]);
    }
    let mut outdir = open(&dir, force, &names)?;
    let mut stages = Stages::new();
    let theory = build(&settings, &mut stages)?;
    let harmonics = settings.theory.harmonics.clone();
    let (grid, method) = match truncate {
        None => (
            stages.run("exact HTF", || theory.exact.grid(&harmonics, &omegas)),
            json!({"method": "exact"}),
        ),
        Some(n) => {
            let t = TruncatedHtf::new(&theory.linearisation.piecewise, n)
                .context("truncated HTF (Wereley's harmonic state space)")?;
            (
                stages.run("truncated HTF", || t.grid(&harmonics, &omegas)),
                json!({"method": "truncated", "truncation": n}),
            )
        }
    };
    stages.run("write outputs", || {
        write_theory_csv(&mut outdir, "theory.csv", &grid)
    })?;
    if !no_plots {
        stages.run("plots", || {
            theory_plots(&mut outdir, &settings.name, "", &settings, &grid)
        })?;
    }
    let mut htf = method;
    htf["harmonics"] = json!(harmonics);
    htf["points"] = json!(omegas.len());
    htf["max_abs"] = json!(grid.max_abs());
    let summary = json!({
        "name": settings.name,
        "config": settings.path.display().to_string(),
        "htfid_version": env!("CARGO_PKG_VERSION"),
        "limit_cycle": limit_cycle_json(&theory.orbit),
        "ltp": ltp_json(&theory),
        "htf": htf,
        "timings_ms": stages.to_json(),
    });
    outdir.write_text("summary.json", &json_text(&summary))?;
    let written = outdir.commit()?;
    crate::results::theory(&summary, &dir, &written);
    Ok(())
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
