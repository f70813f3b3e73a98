//! `htfid run CONFIG`: the whole pipeline for any configured model ([`Subject`]): settle onto
//! the limit cycle, excite, simulate, estimate the HTFs of every output, fit the model's
//! parameters, and compare everything with the exact theory.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use htfid_estimate::{
    Alpha, Design, HtfEstimate, Layout, LineSpec, LineWindows, Method, MultiOptions, Request,
    UncertaintyBudget,
};
use htfid_excite::{alias_sizes, Polarity};
use htfid_experiment::distortion_bootstrap;
use htfid_identify::{budget_with_bias, errors_against, fit_to_htf, HtfFit, HtfFitSpec};
use htfid_orbit::LimitCycle;
use htfid_plot::Style;
use htfid_theory::{HarmonicTransferFunction, HtfChannel, Tabulated};
use num_complex::Complex64;
use serde_json::{json, Value};

use crate::commands::simulate::{
    base_summary, experiment_grid, experiment_input, fill_limit_cycle, limit_cycle_csv,
    sample_input, simulate_on, simulate_with_columns, write_timeseries, InputColumns, Record,
};
use crate::commands::theory::{fill_theory_csv, suffix, THEORY_HEADER};
use crate::output::{json_text, open, resolve_dir};
use crate::plots::{self, Curve};
use crate::progress::Stages;
use crate::settings::{AlphaSetting, Estimator, Excitation, Settings};
use crate::signals::Built;
use crate::subject::{about_orbit, ltp_json, with_subject, Subject};

pub fn run(config: &Path, out: Option<PathBuf>, force: bool, no_plots: bool) -> Result<()> {
    let settings = Settings::from_file(config)?;
    if settings.excitation == Excitation::None {
        bail!(
            "{}: [excitation] kind = \"none\": there is nothing to estimate from; \
             use kind = \"chirp_train\" or \"multisine_design\" (or `htfid simulate`)",
            settings.path.display()
        );
    }
    crate::limits::check_experiment(&settings, crate::limits::Stage::Run)?;
    with_subject!(&settings, |subject| run_on(
        &settings, subject, out, force, no_plots
    ))
}

/// Every file `run` writes for `outputs`.
fn file_names(settings: &Settings, outputs: &[String], no_plots: bool) -> Vec<String> {
    let mut names: Vec<String> = [
        "timeseries.csv",
        "limit_cycle.csv",
        "theory.csv",
        "summary.json",
        "report.md",
    ]
    .map(String::from)
    .to_vec();
    if outputs.len() > 1 {
        names.extend(outputs.iter().map(|o| format!("theory_{o}.csv")));
    }
    for est in &settings.estimation.estimators {
        for o in 0..outputs.len() {
            names.push(format!("estimate_{}{}.csv", est.name(), suffix(outputs, o)));
        }
    }
    if !no_plots {
        for stem in ["htf_g0", "htf_harmonics"] {
            names.push(format!("{stem}.svg"));
            names.push(format!("{stem}.png"));
        }
    }
    names
}

fn run_on<S: Subject>(
    settings: &Settings,
    subject: &S,
    out: Option<PathBuf>,
    force: bool,
    no_plots: bool,
) -> Result<()> {
    let outputs = subject.output_names();
    let names = file_names(settings, &outputs, no_plots);
    let name_refs: Vec<&str> = names.iter().map(String::as_str).collect();
    let dir = resolve_dir(out, &settings.name);
    let mut outdir = open(&dir, force, &name_refs)?;
    let mut stages = Stages::new();

    let (cycle, htf) = about_orbit(settings, subject, &mut stages)?;
    let channels = (0..outputs.len())
        .map(|o| htf.channel(o))
        .collect::<Result<Vec<_>, _>>()?;

    // The HTF's tables and the sampled orbit need only the orbit, the estimators' preparation
    // only the input: they are done on the second core while the experiment is simulated.
    let mut theory_csvs = vec![outdir.csv("theory.csv", THEORY_HEADER)?];
    if outputs.len() > 1 {
        for o in &outputs {
            theory_csvs.push(outdir.csv(&format!("theory_{o}.csv"), THEORY_HEADER)?);
        }
    }
    let cycle_csv = limit_cycle_csv(&mut outdir, subject)?;
    let (excitation, grid) = experiment_grid(settings)?;
    let (rec, side) = std::thread::scope(|scope| -> Result<_> {
        let (htf, cycle, channels) = (&htf, &cycle, &channels);
        let (columns_tx, columns_rx) = std::sync::mpsc::channel();
        let side = scope.spawn(move || -> Result<Beside<'_>> {
            let mut local = Stages::silent();
            // The input is known before the output: its columns of the record are made here,
            // while the simulation runs, and the estimators are prepared from it.
            let input = experiment_input(settings);
            if let Ok((_, grid, u)) = &input {
                // The simulation makes them itself should this thread fail.
                let _ = columns_tx.send(InputColumns::new(subject, grid, u.clone()));
            }
            let grids = local
                .run("HTF", || {
                    htf.grids(&settings.theory.harmonics, &settings.theory.omegas)
                })
                .context("harmonic transfer functions")?;
            local.run("write theory", || -> Result<()> {
                // `theory.csv` is the first output's table; with several outputs each also
                // has its own.
                let mut csvs = theory_csvs.into_iter();
                if let Some(first) = csvs.next() {
                    fill_theory_csv(first, &grids[0])?;
                }
                for (csv, grid) in csvs.zip(&grids) {
                    fill_theory_csv(csv, grid)?;
                }
                fill_limit_cycle(cycle_csv, settings, subject, cycle)
            })?;
            // The estimators' work on the input alone (`htfid_estimate::Design`); should it
            // fail, the chains prepare them again from the simulated input and say why.
            let designs = local
                .run("prepare estimators", || prepare_all(settings, input?))
                .ok();
            // Each output's HTF at the rows an estimate will have, where the input fixes
            // them, for its errors.
            let truths = local.run("HTF at the estimates", || {
                let htfs: Vec<&(dyn HarmonicTransferFunction + Sync)> = channels
                    .iter()
                    .map(|c| c as &(dyn HarmonicTransferFunction + Sync))
                    .collect();
                truths_at(&htfs, designs.as_deref())
            });
            // What the copies cannot separate, for the summary.
            let aliased = local.run("aliasing", || aliasing(settings, &channels[0]))?;
            Ok(Beside {
                stages: local,
                designs,
                truths,
                aliased,
            })
        });
        let columns = |excitation: &Built, grid: &[f64]| {
            columns_rx.recv().unwrap_or_else(|_| {
                InputColumns::new(subject, grid, sample_input(excitation, grid))
            })
        };
        let rec = simulate_with_columns(
            settings,
            subject,
            cycle,
            (excitation, grid),
            columns,
            &mut stages,
        );
        let side = side.join().expect("the theory writer does not panic");
        Ok((rec?, side?))
    })?;
    let Beside {
        stages: side,
        designs,
        truths,
        aliased,
    } = side;
    stages.absorb(side);
    let deviation = stages.run("orbit deviation", || {
        orbit_deviation(settings, subject, &cycle, &rec)
    })?;

    // The time series is the largest file; it is written on the second core while the
    // estimators and fits run, one thread per estimator.
    let ts_path = outdir.path_for("timeseries.csv")?;
    let est_csvs = settings
        .estimation
        .estimators
        .iter()
        .map(|est| {
            (0..outputs.len())
                .map(|o| {
                    let name = format!("estimate_{}{}.csv", est.name(), suffix(&outputs, o));
                    outdir.csv(&name, ESTIMATE_HEADER)
                })
                .collect::<Result<Vec<_>, _>>()
        })
        .collect::<Result<Vec<_>, _>>()?;
    let rec_ref = &rec;
    let found = std::thread::scope(|scope| -> Result<_> {
        let writer = scope.spawn(move || write_timeseries(&ts_path, subject, rec_ref));
        let experiment = Experiment {
            settings,
            subject,
            cycle: &cycle,
            rec: rec_ref,
        };
        let found = experiment.estimate_and_fit(
            &channels,
            &deviation,
            est_csvs,
            (designs, truths),
            &mut stages,
        );
        writer.join().expect("the CSV writer does not panic")?;
        found
    })?;
    let Found {
        estimates,
        errors,
        fits,
        alpha,
    } = found;
    let g_unit = subject.htf_unit();
    if !no_plots {
        stages.run("plots", || {
            run_plots(
                &mut outdir,
                settings,
                &channels[0],
                &estimates[0],
                g_unit.as_deref(),
            )
        })?;
    }
    let mut summary = base_summary(settings, subject, &cycle, &rec)?;
    summary["ltp"] = ltp_json(subject, &htf, &cycle);
    if subject.run_htf_block() {
        summary["htf"] = json!({"method": subject.method_name(htf.method()), "outputs": outputs});
    }
    summary["alpha"] = Value::Object(alpha);
    summary["fit"] = Value::Object(fits);
    summary["errors"] = Value::Object(errors);
    summary["estimation"] = json!({
        "harmonics": settings.estimation.harmonics,
        "band": [settings.estimation.band.0, settings.estimation.band.1],
        "estimators": settings.estimation.estimators.iter().map(|e| e.name()).collect::<Vec<_>>(),
        "noise_output_std": settings.noise.map_or(0.0, |n| n.output_std),
    });
    if let Some(a) = aliased {
        summary["aliasing"] = a;
    }
    if let Some(d) = &rec.excitation.design {
        summary["design"] = serde_json::to_value(d.report())?;
    }
    summary["timings_ms"] = stages.to_json();
    outdir.write_text("summary.json", &json_text(&summary))?;
    let info = |name: &str| subject.parameter_info(name);
    outdir.write_text(
        "report.md",
        &crate::report::run(
            &summary,
            &settings.path,
            &settings.estimation.fit,
            &info,
            g_unit.as_deref(),
            !no_plots,
        ),
    )?;
    let written = outdir.commit()?;
    let unit = |name: &str| subject.parameter_unit(name);
    crate::results::run(&summary, &settings.estimation.fit, &unit, &dir, &written);
    Ok(())
}

/// What the second core computes while the experiment is simulated.
struct Beside<'a> {
    stages: Stages,
    /// The estimators prepared from the input.
    designs: Option<Vec<Prepared>>,
    /// Each output's HTF at the rows the estimates will have.
    truths: Truths<'a>,
    /// The aliasing table of `summary.json`.
    aliased: Option<Value>,
}

/// What the estimators see: each output minus its value on the unexcited orbit
/// (`htfid_experiment::orbit_deviation`).
fn orbit_deviation<S: Subject>(
    settings: &Settings,
    subject: &S,
    cycle: &LimitCycle<S::Mode>,
    rec: &Record<S>,
) -> Result<Vec<Vec<f64>>> {
    htfid_experiment::orbit_deviation(
        subject,
        cycle,
        rec.record.time(),
        rec.record.outputs(),
        &settings.integrator,
    )
    .map_err(|e| crate::limits::experiment_failed(settings, crate::limits::Simulated::Orbit, e))
}

type Estimates = Vec<Vec<(Estimator, HtfEstimate)>>;
type JsonMap = serde_json::Map<String, Value>;

/// The estimates per output and estimator and the `summary.json` blocks made from them.
struct Found {
    estimates: Estimates,
    errors: JsonMap,
    fits: JsonMap,
    alpha: JsonMap,
}

/// One simulated experiment on a model, from its orbit.
struct Experiment<'a, S: Subject> {
    settings: &'a Settings,
    subject: &'a S,
    cycle: &'a LimitCycle<S::Mode>,
    rec: &'a Record<S>,
}

/// One estimator's results: its estimates of every output, their errors against the exact
/// HTFs, and the parametric fit to all of them with its uncertainty budget.
struct Chain {
    estimates: Vec<HtfEstimate>,
    errors: Vec<Value>,
    fit: Value,
}

impl<S: Subject> Experiment<'_, S> {
    /// Estimates per output and estimator, their errors against the theory, and the fits
    /// (one per estimator, to the estimates of every output together), each estimator's on
    /// a thread of its own, which also writes its estimates into `csvs` (one per output).
    fn estimate_and_fit(
        &self,
        channels: &[HtfChannel<'_, '_, S>],
        deviation: &[Vec<f64>],
        csvs: Vec<Vec<htfid_data::CsvWriter>>,
        (designs, truths): (Option<Vec<Prepared>>, Truths<'_>),
        stages: &mut Stages,
    ) -> Result<Found> {
        let settings = self.settings;
        let outputs = self.subject.output_names();
        let mut designs = designs.map(Vec::into_iter);
        let mut truths = truths.into_iter();
        let chains = std::thread::scope(|scope| {
            let handles: Vec<_> = settings
                .estimation
                .estimators
                .iter()
                .zip(csvs)
                .map(|(&est, csvs)| {
                    let prepared = designs.as_mut().and_then(Iterator::next);
                    let truth = truths.next().flatten();
                    scope.spawn(move || {
                        let mut local = Stages::silent();
                        let found = self.chain(
                            channels,
                            deviation,
                            (est, csvs, prepared, truth),
                            &mut local,
                        );
                        (local, found)
                    })
                })
                .collect();
            handles
                .into_iter()
                .map(|h| h.join().expect("an estimator chain does not panic"))
                .collect::<Vec<_>>()
        });
        let mut found = Found {
            estimates: vec![Vec::new(); outputs.len()],
            errors: JsonMap::new(),
            fits: JsonMap::new(),
            alpha: JsonMap::new(),
        };
        for ((local, chain), &est) in chains.into_iter().zip(&settings.estimation.estimators) {
            stages.absorb(local);
            let chain = chain?;
            if let Some(a) = chain.estimates[0].alpha() {
                found.alpha.insert(
                    est.name().into(),
                    json!({"alpha": a, "alpha_effective": chain.estimates[0].alpha_effective()}),
                );
            }
            for (o, (e, err)) in chain.estimates.into_iter().zip(chain.errors).enumerate() {
                found
                    .errors
                    .insert(format!("{}{}", est.name(), suffix(&outputs, o)), err);
                found.estimates[o].push((est, e));
            }
            found.fits.insert(est.name().into(), chain.fit);
        }
        Ok(found)
    }

    /// Estimates, errors, fit and uncertainty of one estimator, timed in `stages`; the errors
    /// against the theory and the estimates' files (`csvs`) are done on a thread of their own
    /// while the fit runs.
    fn chain(
        &self,
        channels: &[HtfChannel<'_, '_, S>],
        deviation: &[Vec<f64>],
        (est, csvs, prepared, truth): (
            Estimator,
            Vec<htfid_data::CsvWriter>,
            Option<Prepared>,
            Option<Vec<Tabulated<'_>>>,
        ),
        stages: &mut Stages,
    ) -> Result<Chain> {
        let (settings, rec) = (self.settings, self.rec);
        let outputs = self.subject.output_names();
        // Every output is estimated with the estimator prepared once from the input: during
        // the simulation from the same input, checked sample by sample, or here.
        let input = rec.record.input();
        let prepared = match prepared.filter(|p| p.serves(input)) {
            Some(p) => p,
            None => stages
                .run(&format!("prepare ({})", est.name()), || {
                    design(settings, (rec.record.time(), input), &rec.excitation, est)
                })
                .with_context(|| format!("estimator \"{}\" failed", est.name()))?,
        };
        let mut estimates = Vec::new();
        for (o, y) in deviation.iter().enumerate() {
            let label = if outputs.len() > 1 {
                format!("estimate ({}, {})", est.name(), outputs[o])
            } else {
                format!("estimate ({})", est.name())
            };
            let e = stages
                .run(&label, || prepared.estimate(y))
                .with_context(|| format!("estimator \"{}\" failed", est.name()))?;
            estimates.push(e);
        }
        let (errors, fit) = std::thread::scope(|scope| -> Result<_> {
            let estimates = &estimates;
            let side = scope.spawn(move || -> Result<(Stages, Vec<Value>)> {
                let mut local = Stages::silent();
                let errors = local.run(&format!("errors ({})", est.name()), || {
                    estimates
                        .iter()
                        .enumerate()
                        .map(|(o, e)| match &truth {
                            Some(truth) => harmonic_errors(settings, &truth[o], e),
                            None => harmonic_errors(settings, &channels[o], e),
                        })
                        .collect()
                });
                local.run(&format!("write estimate ({})", est.name()), || {
                    csvs.into_iter()
                        .zip(estimates)
                        .try_for_each(|(csv, e)| fill_estimate_csv(csv, e))
                })?;
                Ok((local, errors))
            });
            let of_outputs: Vec<(usize, &HtfEstimate)> = estimates.iter().enumerate().collect();
            let fit = stages
                .run(&format!("fit ({})", est.name()), || {
                    Ok::<_, anyhow::Error>(fit_to_htf(
                        self.subject,
                        self.cycle,
                        &of_outputs,
                        &fit_spec(settings),
                        &settings.integrator,
                    )?)
                })
                .with_context(|| {
                    format!("parametric fit to the \"{}\" estimates failed", est.name())
                });
            let (local, errors) = side.join().expect("the estimate writer does not panic")?;
            stages.absorb(local);
            Ok((errors, fit?))
        })?;
        let mut json = fit_json(settings, &fit);
        json["uncertainty"] = stages.run(&format!("uncertainty ({})", est.name()), || {
            budget_json(&fit, estimates[0].method(), || self.bootstrap(est, &fit))
        });
        Ok(Chain {
            estimates,
            errors,
            fit: json,
        })
    }

    /// The error the estimator and fit make without noise on the fitted model
    /// (`htfid_experiment::distortion_bootstrap`): the experiment simulated again on it
    /// without noise, estimated per output the same way. Returns the HTF error at every
    /// fitted point and the parameter error.
    fn bootstrap(&self, est: Estimator, fit: &HtfFit) -> Result<(Vec<Complex64>, Vec<f64>)> {
        let mut again = self.settings.clone();
        again.noise = None;
        let b = distortion_bootstrap(
            self.subject,
            self.cycle,
            fit,
            &fit_spec(self.settings),
            &again.integrator,
            |fitted: &S, orbit: &LimitCycle<S::Mode>| -> Result<Vec<HtfEstimate>> {
                let mut quiet = Stages::silent();
                let rec = simulate_on(&again, fitted, orbit, &mut quiet)?;
                // One estimator, prepared once from the input, for every output.
                let input = (rec.record.time(), rec.record.input());
                let prepared = design(&again, input, &rec.excitation, est)?;
                orbit_deviation(&again, fitted, orbit, &rec)?
                    .iter()
                    .map(|y| prepared.estimate(y))
                    .collect()
            },
        )?;
        Ok((b.htf_bias, b.parameter_bias))
    }
}

/// Per configured estimator, each output's HTF at its estimate's rows when the input fixes
/// them (`htfid_estimate::Design::points`).
pub(crate) type Truths<'a> = Vec<Option<Vec<Tabulated<'a>>>>;

/// The truths of `designs` for the HTFs `htfs`, one per output (none when the designs could not
/// be prepared).
pub(crate) fn truths_at<'a>(
    htfs: &[&'a (dyn HarmonicTransferFunction + Sync)],
    designs: Option<&[Prepared]>,
) -> Truths<'a> {
    designs
        .unwrap_or_default()
        .iter()
        .map(|p| {
            p.points()
                .map(|points| htfs.iter().map(|&h| Tabulated::new(h, &points)).collect())
        })
        .collect()
}

/// An estimator prepared from the experiment's input before its output is known
/// (`htfid_estimate::Design`), with what a failure should name.
#[derive(Debug)]
pub(crate) struct Prepared {
    design: Design,
    context: String,
}

impl Prepared {
    /// The estimate from the output `y`.
    pub(crate) fn estimate(&self, y: &[f64]) -> Result<HtfEstimate> {
        self.design.estimate(y).context(self.context.clone())
    }

    /// The `(n, omega)` of its estimates' rows, when the input fixes them.
    pub(crate) fn points(&self) -> Option<Vec<(i32, f64)>> {
        self.design.points()
    }

    /// Whether it was prepared from the input `u`, sample by sample, bit for bit.
    pub(crate) fn serves(&self, u: &[f64]) -> bool {
        let input = self.design.input();
        input.len() == u.len() && input.iter().zip(u).all(|(a, b)| a.to_bits() == b.to_bits())
    }
}

/// Every configured estimator prepared from the configured experiment's input, computed as
/// the simulation computes it ([`experiment_input`]).
pub(crate) fn prepare_all(
    settings: &Settings,
    (excitation, grid, u): (Built, Vec<f64>, Vec<f64>),
) -> Result<Vec<Prepared>> {
    settings
        .estimation
        .estimators
        .iter()
        .map(|&est| design(settings, (&grid, &u), &excitation, est))
        .collect()
}

/// `est` prepared from the input `u` (sampled at `t`) of the configured experiment.
pub(crate) fn design(
    settings: &Settings,
    (t, u): (&[f64], &[f64]),
    excitation: &Built,
    est: Estimator,
) -> Result<Prepared> {
    let mut layout = Layout {
        excited_from: settings.settle_time(),
        ..Layout::default()
    };
    if let Excitation::ChirpTrain { duration, .. } = settings.excitation {
        layout.copies = Some((
            excitation.segments.iter().map(|s| s.start).collect(),
            duration,
        ));
    }
    if let Some(design) = &excitation.design {
        let spec = LineSpec::new(
            design.multisine_period(),
            design.lines().iter().map(|l| l.bin as usize).collect(),
        )?;
        let block = |p: Polarity| {
            design
                .blocks()
                .iter()
                .find(|b| b.polarity == p)
                .map(|b| (b.measure_start, b.end))
        };
        layout.lines = Some(LineWindows {
            spec,
            positive: block(Polarity::Positive).context("the design has no positive block")?,
            negative: block(Polarity::Negative),
        });
    }
    let (estimator, alpha_text) = match est {
        Estimator::Siddiqi => match settings.estimation.alpha {
            AlphaSetting::Fixed(a) => (
                htfid_estimate::Estimator::Siddiqi(Alpha::Fixed(a)),
                format!(", estimation.alpha = {a}"),
            ),
            AlphaSetting::Gcv => (
                htfid_estimate::Estimator::Siddiqi(Alpha::Gcv),
                ", estimation.alpha = \"gcv\"".to_string(),
            ),
        },
        Estimator::Multi => (
            htfid_estimate::Estimator::Multi(MultiOptions::default()),
            String::new(),
        ),
        Estimator::Lines => (htfid_estimate::Estimator::Lines, String::new()),
    };
    let request = Request {
        period: settings.period,
        harmonics: &settings.estimation.harmonics,
        band: settings.estimation.band,
    };
    let context = format!(
        "{}: the {} estimator (simulation.sample_rate = {} Hz{alpha_text})",
        settings.path.display(),
        est.name(),
        settings.sample_rate
    );
    let input = (
        u,
        1.0 / settings.sample_rate,
        t.first().copied().unwrap_or(0.0),
    );
    let design =
        Design::new(input, &layout, &request, &estimator).with_context(|| context.clone())?;
    Ok(Prepared { design, context })
}

/// Writes an estimate CSV (`estimate_*.csv`): rows `omega,n,re,im,stderr`.
pub(crate) fn write_estimate_csv(
    out: &mut htfid_data::OutputDir,
    name: &str,
    e: &HtfEstimate,
) -> Result<()> {
    fill_estimate_csv(out.csv(name, ESTIMATE_HEADER)?, e)
}

/// The columns of `estimate_<estimator>.csv`.
pub(crate) const ESTIMATE_HEADER: &[&str] = &["omega", "n", "re", "im", "stderr"];

/// Writes the rows of `estimate_<estimator>.csv` into `csv` (opened with [`ESTIMATE_HEADER`]).
pub(crate) fn fill_estimate_csv(mut csv: htfid_data::CsvWriter, e: &HtfEstimate) -> Result<()> {
    for r in e.rows() {
        csv.write_row(&[r.omega, f64::from(r.n), r.value.re, r.value.im, r.stderr])?;
    }
    csv.finish()?;
    Ok(())
}

/// Per harmonic: median and max of `|G_hat_n - G_n| / max|G_n|` over the band
/// (`htfid_identify::errors_against`), as `errors.<estimator>` of `summary.json`.
pub(crate) fn harmonic_errors(
    settings: &Settings,
    exact: &dyn HarmonicTransferFunction,
    e: &HtfEstimate,
) -> Value {
    let mut out = serde_json::Map::new();
    for h in errors_against(exact, e, settings.estimation.band) {
        out.insert(
            h.n.to_string(),
            json!({"median": h.median, "max": h.max, "max_abs_g": h.max_abs_g, "points": h.points}),
        );
    }
    Value::Object(out)
}

/// `fit.<estimator>.uncertainty` of `summary.json`: the fit's error budget (`htfid_identify`):
/// noise, the estimator's known bias, structure. A line estimator's distortion (what a `+u` /
/// `-u` pairing leaves, or all of the nonlinear response without pairing) is the error the
/// estimator makes on the same experiment simulated without noise on the fitted model, which
/// `bootstrap` runs (a parametric bootstrap); the regularised estimators carry their own
/// estimate of their smoothing bias. The fit stands without its budget (a rank-deficient
/// Jacobian, a failed re-run): the reason is recorded instead.
pub(crate) fn budget_json(
    fit: &HtfFit,
    method: Method,
    bootstrap: impl FnOnce() -> Result<(Vec<Complex64>, Vec<f64>)>,
) -> Value {
    let budget = match method.distortion() {
        Some(source) => bootstrap()
            .and_then(|(d, p)| Ok(budget_with_bias(fit, source, &d, Some(&p))?))
            .map(|b| (b, Some("bootstrap"))),
        None => fit
            .uncertainty
            .clone()
            .context("the fit's Jacobian is rank deficient: no error budget exists")
            .map(|b| {
                let method = b.htf_bias_source.map(|_| "curvature");
                (b, method)
            }),
    };
    match budget {
        Ok((b, method)) => uncertainty_json(&fit.parameters, &b, method),
        Err(err) => json!({ "error": format!("{err:#}") }),
    }
}

/// `fit.<estimator>.uncertainty` of `summary.json` (docs/outputs.md).
pub(crate) fn uncertainty_json(
    names: &[String],
    b: &UncertaintyBudget,
    bias_method: Option<&str>,
) -> Value {
    let mut parameters = serde_json::Map::new();
    for (name, p) in names.iter().zip(&b.parameters) {
        parameters.insert(
            name.clone(),
            json!({
                "noise": p.noise,
                "htf_bias": p.htf_bias,
                "htf_bias_estimate": p.htf_bias_estimate,
                "structure": p.structure,
                "total": p.total,
                "effective_dof": if p.effective_dof.is_finite() { json!(p.effective_dof) } else { Value::Null },
                "coverage_factor": p.coverage_factor,
                "half_width": p.half_width,
                "dominant": p.dominant.as_str(),
            }),
        );
    }
    json!({
        "level": b.level,
        "htf_bias_source": b.htf_bias_source.map(|s| s.as_str()),
        "htf_bias_method": bias_method,
        "chi2_per_dof": b.chi2_per_dof,
        "chi2_per_dof_corrected": b.chi2_per_dof_corrected,
        "clusters": b.clusters,
        "parameters": parameters,
    })
}

/// The configured parametric fit: parameters, harmonics and band.
pub(crate) fn fit_spec(settings: &Settings) -> HtfFitSpec {
    HtfFitSpec::new(
        settings.estimation.fit.clone(),
        settings.estimation.fit_harmonics.clone(),
        settings.estimation.band,
    )
}

/// `fit.<estimator>` of `summary.json` (docs/outputs.md), without its `uncertainty`.
pub(crate) fn fit_json(settings: &Settings, fit: &HtfFit) -> Value {
    let mut out = serde_json::Map::new();
    for (i, name) in fit.parameters.iter().enumerate() {
        out.insert(name.clone(), json!(fit.values[i]));
        out.insert(format!("{name}_stderr"), json!(fit.stderr[i]));
    }
    out.insert("harmonics".into(), json!(settings.estimation.fit_harmonics));
    out.insert("points".into(), json!(fit.points));
    out.insert("iterations".into(), json!(fit.iterations));
    out.insert("cost".into(), json!(fit.cost));
    out.insert("stop".into(), json!(fit.stop));
    out.insert("jacobian".into(), json!(fit.jacobian_method));
    Value::Object(out)
}

/// Markers drawn per harmonic and estimator, at most.
const MAX_MARKERS: usize = 120;

/// Which harmonics the chirp train's phase shifts cannot tell apart, with their sizes
/// (`htfid_excite::alias_sizes`, each harmonic's largest `|G_m|` of the exact HTF over 200
/// frequencies of the band).
pub(crate) fn aliasing(
    settings: &Settings,
    exact: &dyn HarmonicTransferFunction,
) -> Result<Option<Value>> {
    let Excitation::ChirpTrain { copies, .. } = settings.excitation else {
        return Ok(None);
    };
    let (lo, hi) = settings.estimation.band;
    let omegas = crate::settings::log_grid(lo, hi, 200);
    let sized = alias_sizes(copies, &settings.estimation.harmonics, 10, |harmonics| {
        let grid = exact.grid(harmonics, &omegas);
        harmonics.iter().map(|&n| grid.peak(n)).collect()
    })?;
    let by_harmonic: serde_json::Map<String, Value> = sized
        .by_harmonic
        .iter()
        .map(|h| {
            (
                h.harmonic.to_string(),
                json!({"max_abs_g": h.max_abs_g, "aliases": h.aliases}),
            )
        })
        .collect();
    Ok(Some(
        json!({"copies": sized.copies, "n_max": sized.n_max, "by_harmonic": by_harmonic}),
    ))
}

pub(crate) fn run_plots(
    out: &mut htfid_data::OutputDir,
    settings: &Settings,
    theory: &dyn HarmonicTransferFunction,
    estimates: &[(Estimator, HtfEstimate)],
    unit: Option<&str>,
) -> Result<()> {
    let (lo, hi) = settings.estimation.band;
    let omegas = crate::settings::log_grid(lo, hi, 600);
    let harmonics = &settings.estimation.harmonics;
    let grid = theory.grid(harmonics, &omegas);
    let theory_vals: Vec<(i32, Vec<Complex64>)> = harmonics
        .iter()
        .map(|&n| (n, grid.harmonic(n).unwrap_or_default()))
        .collect();
    type Series = (String, Vec<f64>, Vec<Complex64>, Vec<f64>);
    let est_vals: Vec<(i32, Vec<Series>)> = harmonics
        .iter()
        .map(|&n| {
            let per: Vec<Series> = estimates
                .iter()
                .map(|(est, e)| {
                    let all: Vec<_> = e.rows().filter(|r| r.n == n).collect();
                    let stride = if all.len() > 3 * MAX_MARKERS {
                        1
                    } else {
                        all.len().div_ceil(MAX_MARKERS).max(1)
                    };
                    let rows: Vec<_> = all.into_iter().step_by(stride).collect();
                    (
                        format!("estimate ({})", est.name()),
                        rows.iter().map(|r| r.omega).collect(),
                        rows.iter().map(|r| r.value).collect(),
                        rows.iter().map(|r| r.stderr).collect(),
                    )
                })
                .collect();
            (n, per)
        })
        .collect();
    // Dense estimates (one per DFT bin) are drawn as lines, sparse ones as markers (at most
    // MAX_MARKERS per harmonic); the theory is drawn last so it stays visible on top.
    let curves_for = |n: i32| -> Vec<Curve<'_>> {
        let mut c = Vec::new();
        for (m, per) in &est_vals {
            if *m == n {
                for (label, w, v, se) in per {
                    let style = if w.len() > 3 * MAX_MARKERS {
                        Style::Line
                    } else {
                        Style::Markers
                    };
                    c.push(Curve {
                        label,
                        omega: w,
                        values: v,
                        style,
                        stderr: Some(se),
                    });
                }
            }
        }
        for (m, v) in &theory_vals {
            if *m == n {
                c.push(Curve {
                    label: "theory (exact)",
                    omega: &omegas,
                    values: v,
                    style: Style::Line,
                    stderr: None,
                });
            }
        }
        c
    };
    if harmonics.contains(&0) {
        let fig = plots::with_htf_unit(
            plots::bode(
                &format!("{}: G_0, estimate against theory", settings.name),
                &curves_for(0),
            ),
            unit,
        );
        plots::write(out, "htf_g0", &fig)?;
    }
    let per: Vec<(i32, Vec<Curve<'_>>)> = harmonics.iter().map(|&n| (n, curves_for(n))).collect();
    let fig = plots::with_htf_unit(
        plots::harmonics(
            &format!("{}: |G_n|, estimates against theory", settings.name),
            &per,
        ),
        unit,
    );
    plots::write(out, "htf_harmonics", &fig)?;
    Ok(())
}
