//! `htfid-truth --out DIR [--seed S] [--n N] [--no-effect-rms]`: write a catalogue of
//! ground-truth records as `DIR/record-XXX.csv` plus `DIR/manifest.json`.
//!
//! The binary only parses arguments and writes files; everything else is in the library.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use htfid_truth::{catalogue, core_size, effect_rms, generate, Error, Label, Scenario};
use serde::Serialize;

const USAGE: &str = "usage: htfid-truth --out DIR [--seed S] [--n N] [--no-effect-rms]
  --out DIR         folder to write record-XXX.csv and manifest.json into (created)
  --seed S          catalogue seed (default 1)
  --n N             number of records (default: the core catalogue, every cell once)
  --no-effect-rms   skip the two extra simulations per record that measure effect_rms_m";

struct Args {
    out: PathBuf,
    seed: u64,
    n: usize,
    effect_rms: bool,
}

fn parse_args(args: &[String]) -> Result<Args, String> {
    let mut out = None;
    let mut seed = 1;
    let mut n = core_size();
    let mut effect_rms = true;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut value = |name: &str| {
            it.next()
                .cloned()
                .ok_or_else(|| format!("{name} needs a value"))
        };
        match a.as_str() {
            "--out" => out = Some(PathBuf::from(value("--out")?)),
            "--seed" => {
                let v = value("--seed")?;
                seed = v
                    .parse()
                    .map_err(|_| format!("--seed must be an unsigned integer (got {v})"))?;
            }
            "--n" => {
                let v = value("--n")?;
                n = v
                    .parse()
                    .map_err(|_| format!("--n must be an unsigned integer (got {v})"))?;
            }
            "--no-effect-rms" => effect_rms = false,
            "-h" | "--help" => return Err(String::new()),
            other => return Err(format!("unknown argument {other}")),
        }
    }
    let out = out.ok_or("--out is required")?;
    Ok(Args {
        out,
        seed,
        n,
        effect_rms,
    })
}

/// One manifest entry.
#[derive(Serialize)]
struct Entry {
    file: String,
    scenario: Scenario,
    label: Label,
    samples: usize,
    /// RMS change of the noise-free measured x caused by the effects, m (absent if skipped).
    #[serde(skip_serializing_if = "Option::is_none")]
    effect_rms_m: Option<f64>,
}

#[derive(Serialize)]
struct Manifest {
    generator: &'static str,
    version: &'static str,
    seed: u64,
    n: usize,
    columns: [&'static str; 3],
    records: Vec<Entry>,
}

fn write_one(dir: &Path, i: usize, s: &Scenario, with_rms: bool) -> Result<Entry, Error> {
    let file = format!("record-{i:03}.csv");
    let rec = generate(s)?;
    rec.write_csv(&dir.join(&file))?;
    let effect_rms_m = if with_rms && s.label().effects.is_empty() {
        Some(0.0)
    } else if with_rms {
        Some(effect_rms(s)?)
    } else {
        None
    };
    Ok(Entry {
        file,
        scenario: s.clone(),
        label: rec.label,
        samples: rec.t.len(),
        effect_rms_m,
    })
}

fn run(args: &Args) -> Result<(), String> {
    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("cannot create {}: {e}", args.out.display()))?;
    let scenarios = catalogue(args.seed, args.n);
    let workers = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .clamp(1, scenarios.len().max(1));
    // Records are independent: split them over the cores, keep catalogue order in the manifest.
    let results: Vec<(usize, Result<Entry, Error>)> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..workers)
            .map(|w| {
                let scenarios = &scenarios;
                scope.spawn(move || {
                    (w..scenarios.len())
                        .step_by(workers)
                        .map(|i| (i, write_one(&args.out, i, &scenarios[i], args.effect_rms)))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().expect("a record worker panicked"))
            .collect()
    });
    let mut results = results;
    results.sort_by_key(|r| r.0);
    let mut records = Vec::with_capacity(results.len());
    for (i, r) in results {
        records.push(r.map_err(|e| format!("record {i} ({}): {e}", scenarios[i].name))?);
    }
    let manifest = Manifest {
        generator: "htfid-truth",
        version: env!("CARGO_PKG_VERSION"),
        seed: args.seed,
        n: args.n,
        columns: ["t", "f", "x"],
        records,
    };
    let path = args.out.join("manifest.json");
    let text =
        serde_json::to_string_pretty(&manifest).map_err(|e| format!("{}: {e}", path.display()))?;
    std::fs::write(&path, text + "\n").map_err(|e| format!("{}: {e}", path.display()))?;
    println!(
        "wrote {} records and {}",
        manifest.records.len(),
        path.display()
    );
    Ok(())
}

fn main() -> ExitCode {
    let argv: Vec<String> = std::env::args().skip(1).collect();
    let args = match parse_args(&argv) {
        Ok(a) => a,
        Err(msg) if msg.is_empty() => {
            println!("{USAGE}");
            return ExitCode::SUCCESS;
        }
        Err(msg) => {
            eprintln!("error: {msg}\n{USAGE}");
            return ExitCode::from(2);
        }
    };
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(msg) => {
            eprintln!("error: {msg}");
            ExitCode::FAILURE
        }
    }
}
