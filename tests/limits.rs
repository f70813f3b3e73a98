//! Resource limits: configs that would need more memory or steps than allowed are refused
//! before any work, with the file, the key, the estimate and the limit, and write nothing.
//! None of these tests times anything: a refusal before work is visible in what is (not)
//! printed and written.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn htfid(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_htfid"))
        .args(args)
        .current_dir(root())
        .output()
        .expect("the htfid binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// `configs/NAME.toml` with textual replacements, written into `dir` as `edited.toml`.
fn edited(dir: &Path, name: &str, edits: &[(&str, &str)]) -> PathBuf {
    let mut text = fs::read_to_string(root().join("configs").join(name)).unwrap();
    for (from, to) in edits {
        assert!(text.contains(from), "{name} contains {from:?}");
        text = text.replacen(from, to, 1);
    }
    let path = dir.join("edited.toml");
    fs::write(&path, text).unwrap();
    path
}

/// Runs `command CONFIG --out DIR extra...`, requires a refusal before any work (exit 1, no
/// stage reported, no output directory) and returns stderr.
fn refused(command: &str, config: &Path, extra: &[&str]) -> String {
    let out = config.parent().unwrap().join("out");
    let mut args = vec![
        command,
        config.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = htfid(&args);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "htfid {}: {err}", args.join(" "));
    assert!(!err.contains("panicked"), "{err}");
    assert!(!out.exists(), "a refused run left {}", out.display());
    assert!(
        err.contains(config.to_str().unwrap()),
        "the message names the config: {err}"
    );
    err
}

fn assert_has(err: &str, parts: &[&str]) {
    for p in parts {
        assert!(err.contains(p), "expected {p:?} in: {err}");
    }
}

#[test]
fn a_gigahertz_sample_rate_is_refused_before_the_orbit() {
    let tmp = tempfile::tempdir().unwrap();
    let c = edited(
        tmp.path(),
        "paper.toml",
        &[("sample_rate = 100.0", "sample_rate = 1e9")],
    );
    for command in ["simulate", "run"] {
        let err = refused(command, &c, &[]);
        // 301 s at 1e9 Hz: 3.01e11 samples of 80 bytes.
        assert_has(
            &err,
            &[
                "simulation.sample_rate = 1e9",
                "24.1 TB for the time series",
                "3.01e11 samples",
                "limit 4 GB",
                "--max-memory",
            ],
        );
        // Refused before the limit cycle is searched.
        assert!(!err.contains("limit cycle ..."), "{err}");
    }
}

#[test]
fn a_megahertz_sample_rate_is_refused_and_the_flag_raises_the_limit() {
    let tmp = tempfile::tempdir().unwrap();
    let c = edited(
        tmp.path(),
        "paper.toml",
        &[("sample_rate = 100.0", "sample_rate = 1e6")],
    );
    let err = refused("simulate", &c, &[]);
    assert_has(
        &err,
        &["simulation.sample_rate = 1e6", "24.1 GB", "limit 4 GB"],
    );
    // A limit given on the command line is the one applied and reported.
    let err = refused("simulate", &c, &["--max-memory", "16GiB"]);
    assert_has(&err, &["limit 17.2 GB"]);
}

#[test]
fn a_chirp_of_a_billion_seconds_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let c = edited(
        tmp.path(),
        "paper.toml",
        &[(
            "waveform = \"paper\"",
            "waveform = \"linear\"\nf_start_hz = 0.1\nf_end_hz = 7.0\nduration = 1e9\namplitude = 0.004",
        )],
    );
    let err = refused("simulate", &c, &[]);
    assert_has(
        &err,
        &[
            "excitation.duration = 1e9",
            "72 TB for the time series",
            "limit 4 GB",
        ],
    );
    // With memory to spare, the step cap still refuses it up front.
    let err = refused("simulate", &c, &["--max-memory", "100T"]);
    assert_has(
        &err,
        &[
            "excitation.duration = 1e9",
            "needs at least 3.6e10 integration steps",
            "limit 10000000",
            "simulation.max_steps",
        ],
    );
}

#[test]
fn a_multisine_spacing_far_below_the_band_is_refused_and_its_search_is_bounded() {
    let tmp = tempfile::tempdir().unwrap();
    let c = edited(
        tmp.path(),
        "paper-improved.toml",
        &[
            ("spacing = 0.45", "spacing = 1e-4"),
            ("max_record = 600.0", "max_record = 1e9"),
        ],
    );
    let err = refused("simulate", &c, &[]);
    assert_has(
        &err,
        &[
            "excitation.spacing = 1e-4",
            "for the time series",
            "limit 4 GB",
        ],
    );
    // Past the memory check, the design search gives up with the key instead of hanging.
    let err = refused("run", &c, &["--max-memory", "1T"]);
    assert_has(
        &err,
        &[
            "excitation.spacing: no design found",
            "widen excitation.spacing",
        ],
    );
}

#[test]
fn the_step_cap_is_a_config_key() {
    let tmp = tempfile::tempdir().unwrap();
    // 301 s need at least 1204 steps: refused up front.
    let c = edited(
        tmp.path(),
        "paper.toml",
        &[("atol = 1e-12", "atol = 1e-12\nmax_steps = 1000")],
    );
    let err = refused("simulate", &c, &[]);
    assert_has(
        &err,
        &[
            "needs at least 1204 integration steps",
            "limit 1000",
            "raise simulation.max_steps",
        ],
    );
    // Above the lower bound but below what the run takes: the integrator stops at the cap and
    // the message says which key raises it.
    let c = edited(
        tmp.path(),
        "paper.toml",
        &[("atol = 1e-12", "atol = 1e-12\nmax_steps = 5000")],
    );
    let err = refused("simulate", &c, &[]);
    assert_has(
        &err,
        &[
            "simulation of the experiment failed: 5000 steps attempted",
            "simulation.max_steps = 5000; raise it",
        ],
    );
    // Raised above the default, the cap is accepted and the run succeeds.
    let c = edited(
        tmp.path(),
        "paper.toml",
        &[("atol = 1e-12", "atol = 1e-12\nmax_steps = 20000000")],
    );
    let out = tmp.path().join("raised");
    let o = htfid(&[
        "simulate",
        c.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let summary = fs::read_to_string(out.join("summary.json")).unwrap();
    assert!(summary.contains("\"steps\""), "{summary}");
    let c = edited(
        tmp.path(),
        "paper.toml",
        &[("atol = 1e-12", "atol = 1e-12\nmax_steps = 0")],
    );
    let err = refused("simulate", &c, &[]);
    assert_has(&err, &["simulation.max_steps: must be an integer in 1..="]);
}

#[test]
fn a_theory_grid_beyond_the_limit_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let c = edited(
        tmp.path(),
        "paper.toml",
        &[("points = 400", "points = 1000000")],
    );
    let err = refused("theory", &c, &["--max-memory", "10M"]);
    assert_has(
        &err,
        &["theory.points = 1000000", "for the HTF grid", "limit 10 MB"],
    );
}

#[test]
fn max_memory_is_global_and_checks_its_unit() {
    let o = htfid(&["--max-memory", "8X", "simulate", "configs/paper.toml"]);
    assert_eq!(o.status.code(), Some(2));
    assert_has(&stderr(&o), &["--max-memory", "unknown unit \"X\""]);
    // Accepted before or after the command.
    for args in [
        ["--max-memory", "1k", "simulate", "configs/two-dof.toml"],
        ["simulate", "configs/two-dof.toml", "--max-memory", "1k"],
    ] {
        let o = htfid(&args);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert_has(&stderr(&o), &["configs/two-dof.toml", "limit 1 kB"]);
    }
}

#[test]
fn a_data_file_beyond_the_limit_is_refused_before_it_is_read() {
    let tmp = tempfile::tempdir().unwrap();
    let data = root().join("data/hopper-protocol.csv");
    let c = edited(
        tmp.path(),
        "estimate-hopper.toml",
        &[(
            "file = \"../data/hopper-protocol.csv\"",
            &format!("file = \"{}\"", data.display()),
        )],
    );
    let err = refused("estimate", &c, &["--max-memory", "1M"]);
    assert_has(
        &err,
        &[
            "data.file = ",
            "hopper-protocol.csv",
            "to read",
            "limit 1 MB",
        ],
    );
}

/// `data/hopper-protocol.csv` with its time column in milliseconds.
fn milliseconds_record(dir: &Path) -> PathBuf {
    let text = fs::read_to_string(root().join("data/hopper-protocol.csv")).unwrap();
    let mut out = String::new();
    for line in text.lines() {
        match line.split_once(',') {
            Some((t, rest)) if t.parse::<f64>().is_ok() => {
                let ms = t.parse::<f64>().unwrap() * 1000.0;
                out.push_str(&format!("{ms},{rest}\n"));
            }
            _ => {
                out.push_str(line);
                out.push('\n');
            }
        }
    }
    let path = dir.join("ms.csv");
    fs::write(&path, out).unwrap();
    path
}

/// A record in milliseconds is refused by every command that reads measured data, with the key
/// to fix, before the diagnosis or the estimator runs.
#[test]
fn a_time_column_in_milliseconds_is_refused_up_front() {
    let tmp = tempfile::tempdir().unwrap();
    let data = milliseconds_record(tmp.path());
    let out = tmp.path().join("out");
    let given_period = edited(
        tmp.path(),
        "estimate-hopper.toml",
        &[
            ("value = \"estimate\"", "value = 1.0"),
            (
                "file = \"../data/hopper-protocol.csv\"",
                &format!("file = \"{}\"", data.display()),
            ),
        ],
    );
    let given = given_period.to_str().unwrap();
    let cases: Vec<(&str, &str, &[&str])> = vec![
        (
            "diagnose",
            "configs/diagnose-hopper.toml",
            &[
                "sampled every 1.000e1 s",
                "forcing period of model `hopper`",
            ],
        ),
        (
            "estimate",
            "configs/estimate-hopper.toml",
            &[
                "estimation.omega_max = 40",
                "Nyquist frequency 3.142e-1 rad/s",
            ],
        ),
        ("estimate", given, &["the period (period.value) (1.000 s)"]),
    ];
    for (command, config, parts) in cases {
        let o = htfid(&[
            command,
            config,
            "--data",
            data.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{command} {config}: {err}");
        assert!(!out.exists(), "{command} {config} left its output");
        assert!(!err.contains("diagnosing"), "the diagnosis started: {err}");
        assert_has(&err, &[config, "time column (data.time) is in seconds"]);
        assert_has(&err, parts);
    }
}

/// A multisine whose lines cannot be sampled is refused before the design samples its peak (a
/// spacing of 1e9 rad/s once asked for a 61 GB peak search).
#[test]
fn multisine_lines_beyond_the_nyquist_frequency_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let model = root().join("models/two-dof.toml");
    let c = edited(
        tmp.path(),
        "two-dof.toml",
        &[
            ("spacing = 0.5", "spacing = 1e9"),
            (
                "file = \"../models/two-dof.toml\"",
                &format!("file = \"{}\"", model.display()),
            ),
        ],
    );
    let err = refused("simulate", &c, &[]);
    assert_has(
        &err,
        &[
            "excitation.spacing = 1e9 puts input lines at 5e8 rad/s or above",
            "simulation.sample_rate = 200 Hz",
        ],
    );
    let c = edited(
        tmp.path(),
        "paper-improved.toml",
        &[("sample_rate = 100.0", "sample_rate = 10.0")],
    );
    let err = refused("run", &c, &[]);
    assert_has(&err, &["excitation.omega_max = 40 puts input lines"]);
}

/// A configured model off by orders of magnitude is refused before the fits (which would run
/// hundreds of simulations of it): the forcing amplitude of the diagnosis's model set to 1e9.
#[test]
fn a_model_off_by_orders_of_magnitude_is_refused_before_the_fit() {
    let tmp = tempfile::tempdir().unwrap();
    let data = root().join("data/hopper-protocol.csv");
    let model = root().join("models/hopper.toml");
    let c = edited(
        tmp.path(),
        "diagnose-hopper.toml",
        &[
            ("a = 0.0", "a = 1e9"),
            (
                "file = \"../data/hopper-protocol.csv\"",
                &format!("file = \"{}\"", data.display()),
            ),
            (
                "file = \"../models/hopper.toml\"",
                &format!("file = \"{}\"", model.display()),
            ),
        ],
    );
    let err = refused("diagnose", &c, &[]);
    assert_has(
        &err,
        &[
            "model.parameters",
            "output x misses the record by 1.000e9 times the record's spread",
        ],
    );
}
