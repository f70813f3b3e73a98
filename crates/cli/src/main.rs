//! `htfid`: identify rhythmic hybrid systems through harmonic transfer functions.
//!
//! Commands (each reads a TOML experiment config, see `docs/config.md`):
//! - `htfid simulate CONFIG`: limit cycle and the excited time series;
//! - `htfid theory CONFIG`: linearisation about the orbit and the harmonic transfer functions;
//! - `htfid run CONFIG`: the whole pipeline: simulate, estimate, fit, compare with theory;
//! - `htfid estimate CONFIG`: HTFs from measured data alone;
//! - `htfid diagnose CONFIG`: measured data against the model: what is wrong and why.
//!
//! Each ends with its results on stdout; progress goes to stderr (silenced by `--quiet`).
//! Output directories are handled by `htfid_data::OutputDir` (one run at a time, a manifest,
//! reruns replacing their own results): `docs/outputs.md`.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod commands;
mod config;
mod estimate_config;
mod limits;
mod model_diagnose_config;
mod output;
mod plots;
mod progress;
mod records;
mod report;
mod results;
mod settings;
mod signals;
mod subject;
mod validation;

#[derive(Debug, Parser)]
#[command(
    name = "htfid",
    version,
    about = "Harmonic transfer functions of rhythmic hybrid systems"
)]
struct Cli {
    /// Print no progress on stderr (errors still go there); the results summary stays on stdout.
    #[arg(long, short, global = true)]
    quiet: bool,
    #[command(subcommand)]
    command: Command,
    /// Largest memory a command may plan to use, e.g. 8G, 512M, 16GiB (default 4G); a config
    /// that needs more is refused before any work.
    #[arg(long, global = true, value_name = "SIZE", value_parser = limits::parse_size)]
    max_memory: Option<u64>,
}

#[derive(Debug, clap::Args)]
struct OutArgs {
    /// Output directory (default: out/NAME, NAME being the config's name).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Replace files in the output directory that htfid's earlier results there do not
    /// account for (files of other programs, or edited since), and the earlier results as a
    /// whole. Without it a rerun still replaces its own earlier results.
    #[arg(long)]
    force: bool,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Find the limit cycle and simulate the configured experiment.
    Simulate {
        /// Experiment config (TOML).
        config: PathBuf,
        #[command(flatten)]
        out: OutArgs,
    },
    /// Linearise about the orbit and compute the harmonic transfer functions.
    Theory {
        /// Experiment config (TOML).
        config: PathBuf,
        /// Comma-separated frequencies in rad/s, negative ones allowed (default: the config's
        /// grid).
        #[arg(long, value_name = "LIST", allow_hyphen_values = true)]
        omega: Option<String>,
        /// Use Wereley's harmonic state space truncated at N harmonics instead of the exact HTF.
        #[arg(long, value_name = "N")]
        truncate: Option<usize>,
        /// Skip the figures.
        #[arg(long)]
        no_plots: bool,
        #[command(flatten)]
        out: OutArgs,
    },
    /// The whole pipeline: simulate, estimate the HTFs, fit, compare with theory.
    Run {
        /// Experiment config (TOML).
        config: PathBuf,
        /// Skip the figures.
        #[arg(long)]
        no_plots: bool,
        #[command(flatten)]
        out: OutArgs,
    },
    /// Estimate HTFs from measured data alone (no model): period, orbit, estimates, checks.
    Estimate {
        /// Estimate config (TOML).
        config: PathBuf,
        /// Measured data (CSV, .npy, .npz or MAT-file), overriding the config's data file.
        #[arg(long, value_name = "FILE")]
        data: Option<PathBuf>,
        #[command(flatten)]
        out: OutArgs,
    },
    /// Compare measured data with the model: what is wrong, the cause, the extended model.
    Diagnose {
        /// Diagnosis config (TOML).
        config: PathBuf,
        /// Measured data (CSV, .npy, .npz or MAT-file), overriding the config's data file.
        #[arg(long, value_name = "FILE")]
        data: Option<PathBuf>,
        #[command(flatten)]
        out: OutArgs,
    },
}

/// Exit status after SIGINT, SIGTERM or SIGHUP (the shell's 128 + SIGINT).
const INTERRUPTED: i32 = 130;

fn main() -> ExitCode {
    let cli = Cli::parse();
    limits::set(limits::Limits {
        max_memory: cli.max_memory.unwrap_or(limits::DEFAULT_MAX_MEMORY),
    });
    progress::init(cli.quiet);
    // A stopped run removes its unfinished output rather than leaving a staging directory; a
    // commit under way finishes first (abandon_all waits for it), so the output directory
    // holds either the earlier results or the whole new run.
    if let Err(e) = ctrlc::set_handler(|| {
        let dirs = htfid_data::OutputDir::abandon_all();
        progress::clear();
        for dir in dirs {
            eprintln!(
                "htfid: stopped; nothing of this run was written to {}",
                dir.display()
            );
        }
        std::process::exit(INTERRUPTED);
    }) {
        eprintln!("warning: cannot handle SIGINT/SIGTERM ({e}); a stopped run may leave a hidden .htfid-staging-* directory, which the next run there removes");
    }
    let result = match cli.command {
        Command::Simulate { config, out } => commands::simulate::run(&config, out.out, out.force),
        Command::Theory {
            config,
            omega,
            truncate,
            no_plots,
            out,
        } => commands::theory::run(&config, omega, truncate, out.out, out.force, no_plots),
        Command::Run {
            config,
            no_plots,
            out,
        } => commands::run::run(&config, out.out, out.force, no_plots),
        Command::Estimate { config, data, out } => {
            commands::estimate::run(&config, data, out.out, out.force)
        }
        Command::Diagnose { config, data, out } => {
            commands::diagnose::run(&config, data, out.out, out.force)
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            progress::clear();
            eprintln!("error: {}", error_text(&e));
            ExitCode::FAILURE
        }
    }
}

/// The error and its causes on one line, each cause only once (library errors often repeat
/// their source in their own message).
fn error_text(e: &anyhow::Error) -> String {
    let mut text = e.to_string();
    for cause in e.chain().skip(1) {
        let c = cause.to_string();
        if !text.contains(&c) {
            text.push_str(": ");
            text.push_str(&c);
        }
    }
    text
}
