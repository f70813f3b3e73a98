//! `htfid`: identify rhythmic hybrid systems through harmonic transfer functions.
//!
//! Commands (each reads a TOML experiment config, see `docs/config.md`):
//! - `htfid simulate CONFIG`: limit cycle and the excited time series;
//! - `htfid theory CONFIG`: linearisation about the orbit and the harmonic transfer functions;
//! - `htfid run CONFIG`: the whole pipeline: simulate, estimate, fit, compare with theory;
//! - `htfid estimate CONFIG`: HTFs from measured data alone;
//! - `htfid diagnose CONFIG`: measured data against the model: what is wrong and why.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod commands;
mod config;
mod estimate_config;
mod model_diagnose_config;
mod output;
mod plots;
mod progress;
mod records;
mod settings;
mod signals;

#[derive(Debug, Parser)]
#[command(
    name = "htfid",
    version,
    about = "Harmonic transfer functions of rhythmic hybrid systems"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, clap::Args)]
struct OutArgs {
    /// Output directory (default: out/NAME, NAME being the config's name).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Replace output files that already exist in the output directory.
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
        /// Comma-separated frequencies in rad/s (default: the config's grid).
        #[arg(long, value_name = "LIST")]
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

fn main() -> ExitCode {
    let cli = Cli::parse();
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
