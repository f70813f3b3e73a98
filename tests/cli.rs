//! End-to-end tests: drive the `htfid` binary the way a user does.

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

/// Runs `htfid` and requires success, showing its stderr otherwise.
fn htfid_ok(args: &[&str]) {
    let o = htfid(args);
    assert!(
        o.status.success(),
        "htfid {}: {}",
        args.join(" "),
        stderr(&o)
    );
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Writes the paper config with `edit` applied (a textual replacement) into `dir`.
fn edited_config(dir: &Path, from: &str, to: &str) -> PathBuf {
    let text = fs::read_to_string(root().join("configs/paper.toml")).unwrap();
    assert!(text.contains(from), "the paper config contains {from:?}");
    let path = dir.join("edited.toml");
    fs::write(&path, text.replacen(from, to, 1)).unwrap();
    path
}

fn line_of(path: &Path, needle: &str) -> usize {
    let text = fs::read_to_string(path).unwrap();
    text.lines().position(|l| l.contains(needle)).unwrap() + 1
}

#[test]
fn simulate_writes_the_contracted_files() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("sim");
    htfid_ok(&[
        "simulate",
        "configs/paper.toml",
        "--out",
        out.to_str().unwrap(),
    ]);
    let ts = fs::read_to_string(out.join("timeseries.csv")).unwrap();
    assert!(
        ts.starts_with("t,f,x"),
        "timeseries header: {}",
        ts.lines().next().unwrap()
    );
    // 30 s settling + 9 chirps of 30 s spaced by 30 + 1/9 s (ending at 300.9 s), rounded up to
    // whole periods, at 100 Hz.
    let rows = ts.lines().count() - 1;
    assert_eq!(rows, 301 * 100 + 1);
    let lc = fs::read_to_string(out.join("limit_cycle.csv")).unwrap();
    assert_eq!(lc.lines().next().unwrap(), "phase,x,xd,s,stick");
    let summary: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let lc = &summary["limit_cycle"];
    for key in [
        "period",
        "t_on",
        "t_off",
        "duty",
        "state_phase0",
        "floquet_multipliers",
        "periodicity_residual",
    ] {
        assert!(!lc[key].is_null(), "summary.limit_cycle.{key} missing");
    }
    // Against the independent closed-form oracle (tests/oracle): t_on = 0.49805894329238 s.
    assert!((lc["t_on"].as_f64().unwrap() - 0.4980589432923819).abs() < 1e-7);
    assert!((lc["t_off"].as_f64().unwrap() - 0.010561677927640789).abs() < 1e-7);
    assert!(summary["timings_ms"]["total"].as_f64().unwrap() > 0.0);
    // The switches in the record: two per period over ~301 periods.
    let switches = summary["simulation"]["switches"].as_u64().unwrap();
    assert!((598..=604).contains(&switches), "{switches} switches");
}

#[test]
fn existing_outputs_are_not_overwritten_unless_forced() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("sim");
    let out_s = out.to_str().unwrap();
    assert!(htfid(&["simulate", "configs/paper.toml", "--out", out_s])
        .status
        .success());
    fs::write(out.join("summary.json"), "keep me").unwrap();
    let o = htfid(&["simulate", "configs/paper.toml", "--out", out_s]);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(
        err.contains("summary.json") && err.contains("--force"),
        "{err}"
    );
    assert_eq!(
        fs::read_to_string(out.join("summary.json")).unwrap(),
        "keep me"
    );
    htfid_ok(&["simulate", "configs/paper.toml", "--out", out_s, "--force"]);
    assert_ne!(
        fs::read_to_string(out.join("summary.json")).unwrap(),
        "keep me"
    );
}

/// Each broken config fails with a message naming the file, the line and the key, and leaves
/// no output behind.
#[test]
fn broken_configs_give_clear_errors_and_no_output() {
    let cases: &[(&str, &str, &str, &[&str])] = &[
        (
            "k = 200.0",
            "k = -3.0",
            "k = -3.0",
            &["model.k: must be > 0 (got -3)"],
        ),
        (
            "k = 200.0",
            "kk = 200.0",
            "kk = 200.0",
            &["unknown field `kk`"],
        ),
        (
            "k = 200.0",
            "k = \"stiff\"",
            "k = \"stiff\"",
            &["invalid type"],
        ),
        (
            "copies = 9",
            "copies = 0",
            "copies = 0",
            &["excitation.copies", "1..=1000", "got 0"],
        ),
        (
            "kind = \"chirp_train\"",
            "kind = \"chirp\"",
            "kind = \"chirp\"",
            &["excitation.kind", "\"chirp_train\""],
        ),
        (
            "period = 1.0",
            "period = 0.0",
            "period = 0.0",
            &["forcing.period: must be > 0 (got 0)"],
        ),
        (
            "rtol = 1e-10",
            "rtol = 2.0",
            "rtol = 2.0",
            &["simulation.rtol"],
        ),
        (
            "damper = \"switching\"",
            "damper = \"sometimes\"",
            "damper = \"sometimes\"",
            &["model.damper", "\"always_on\""],
        ),
    ];
    for (from, to, needle, expected) in cases {
        let tmp = tempfile::tempdir().unwrap();
        let cfg = edited_config(tmp.path(), from, to);
        let out = tmp.path().join("out");
        let o = htfid(&[
            "simulate",
            cfg.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(!o.status.success(), "{to} was accepted");
        let err = stderr(&o);
        let line = line_of(&cfg, needle);
        assert!(
            err.contains(&format!("edited.toml:{line}")),
            "{to}: message does not name edited.toml:{line}: {err}"
        );
        for e in *expected {
            assert!(err.contains(e), "{to}: message lacks {e:?}: {err}");
        }
        assert!(!out.exists(), "{to}: output directory created");
    }
}

#[test]
fn no_limit_cycle_is_a_clear_error() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = edited_config(tmp.path(), "c = 2.0", "c = 0.0");
    let out = tmp.path().join("out");
    let o = htfid(&[
        "simulate",
        cfg.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(err.contains("no stable period-1 orbit"), "{err}");
    assert!(!out.exists());
}

#[test]
fn missing_config_file_is_named() {
    let o = htfid(&["simulate", "configs/does-not-exist.toml"]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("configs/does-not-exist.toml: file: cannot read"),
        "{}",
        stderr(&o)
    );
}

fn summary(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap()
}

fn max_error(s: &serde_json::Value, estimator: &str, n: i32) -> f64 {
    s["errors"][estimator][n.to_string()]["max"]
        .as_f64()
        .unwrap()
}

/// `htfid theory --omega` at the frequencies of the independent brute-force reference
/// (tests/oracle/hopper_reference.json, computed in Python by direct integration).
#[test]
fn theory_csv_matches_the_independent_reference() {
    let tmp = tempfile::tempdir().unwrap();
    let reference: serde_json::Value = serde_json::from_str(
        &fs::read_to_string(root().join("tests/oracle/hopper_reference.json")).unwrap(),
    )
    .unwrap();
    let rows = reference["htf"].as_array().unwrap();
    let mut omegas: Vec<f64> = rows.iter().map(|r| r["omega"].as_f64().unwrap()).collect();
    omegas.dedup();
    let list = omegas
        .iter()
        .map(|w| format!("{w}"))
        .collect::<Vec<_>>()
        .join(",");
    let out = tmp.path().join("th");
    htfid_ok(&[
        "theory",
        "configs/paper.toml",
        "--omega",
        &list,
        "--out",
        out.to_str().unwrap(),
        "--no-plots",
    ]);
    let csv = fs::read_to_string(out.join("theory.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next().unwrap(), "omega,n,re,im");
    let ours: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    let max_g = rows
        .iter()
        .map(|r| r["re"].as_f64().unwrap().hypot(r["im"].as_f64().unwrap()))
        .fold(0.0, f64::max);
    for r in rows {
        let (w, n) = (r["omega"].as_f64().unwrap(), r["n"].as_f64().unwrap());
        let row = ours
            .iter()
            .find(|o| (o[0] - w).abs() < 1e-12 && (o[1] - n).abs() < 0.5)
            .unwrap_or_else(|| panic!("theory.csv lacks omega {w}, n {n}"));
        let err = (row[2] - r["re"].as_f64().unwrap()).hypot(row[3] - r["im"].as_f64().unwrap());
        // Issue: within 1e-7 of max|G| of an independent computation.
        assert!(err < 1e-7 * max_g, "G_{n}({w}) off by {err}");
    }
    let s = summary(&out);
    let sf = s["ltp"]["s_fourier"].as_array().unwrap();
    assert_eq!(sf.len(), 11);
    // s_0 is the duty cycle.
    assert!(
        (sf[0][0].as_f64().unwrap() - s["limit_cycle"]["duty"].as_f64().unwrap()).abs() < 1e-12
    );
}

/// `--omega` takes negative frequencies as values, not as options, and the HTF of a real
/// system there is the conjugate of the mirrored one: `G_n(-jw) = conj(G_{-n}(jw))`, to
/// rounding (1e-12 of max |G|, each value computed on its own).
#[test]
fn theory_takes_negative_frequencies_and_they_mirror_the_positive_ones() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("th");
    htfid_ok(&[
        "theory",
        "configs/paper.toml",
        "--omega",
        "-7.5,7.5",
        "--out",
        out.to_str().unwrap(),
        "--no-plots",
    ]);
    let csv = fs::read_to_string(out.join("theory.csv")).unwrap();
    let rows: Vec<Vec<f64>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    let at = |w: f64, n: f64| {
        rows.iter()
            .find(|r| r[0].to_bits() == w.to_bits() && r[1].to_bits() == n.to_bits())
            .unwrap_or_else(|| panic!("theory.csv lacks omega {w}, n {n}"))
    };
    let max_g = rows.iter().map(|r| r[2].hypot(r[3])).fold(0.0, f64::max);
    let mut compared = 0;
    for r in rows.iter().filter(|r| r[0] < 0.0) {
        // `+ 0.0` makes the mirror of n = 0 the +0 the file holds.
        let mirror = at(-r[0], -r[1] + 0.0);
        let err = (r[2] - mirror[2]).hypot(r[3] + mirror[3]);
        assert!(err <= 1e-12 * max_g, "G_{}({}) off by {err}", r[1], r[0]);
        compared += 1;
    }
    assert!(compared >= 3, "{compared} negative-frequency rows");
}

/// The paper's experiment reproduces the paper's failure: `G_-2` and `G_2` are wrong near
/// 12-15 rad/s while `G_0` is right; k and c come back close to the truth.
#[test]
fn run_paper_reproduces_the_papers_failure() {
    papers_failure("configs/paper.toml");
}

/// The paper's reproduction keeps its checks with the hopper written in the model language.
#[test]
fn run_paper_model_reproduces_the_papers_failure() {
    papers_failure("configs/paper-model.toml");
}

fn papers_failure(config: &str) {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("paper");
    htfid_ok(&["run", config, "--out", out.to_str().unwrap()]);
    for f in [
        "timeseries.csv",
        "theory.csv",
        "estimate_siddiqi.csv",
        "estimate_multi.csv",
        "htf_g0.png",
        "htf_harmonics.svg",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    let est = fs::read_to_string(out.join("estimate_multi.csv")).unwrap();
    assert_eq!(est.lines().next().unwrap(), "omega,n,re,im,stderr");
    let s = summary(&out);
    for est in ["siddiqi", "multi"] {
        // G_0 is estimated well (a few per cent at worst, at the resonance peak) ...
        assert!(
            max_error(&s, est, 0) < 0.1,
            "{est}: G_0 max error {}",
            max_error(&s, est, 0)
        );
        // ... G_+-2 are not: errors of the order of the harmonic itself.
        assert!(
            max_error(&s, est, 2) > 0.5 && max_error(&s, est, -2) > 0.5,
            "{est}: G_2 not failing"
        );
        let fit = &s["fit"][est];
        assert!((fit["k"].as_f64().unwrap() - 200.0).abs() < 1.0);
        assert!((fit["c"].as_f64().unwrap() - 2.0).abs() < 0.1);
        assert!(fit["k_stderr"].as_f64().unwrap() > 0.0);
    }
    // With 9 phase shifts, G_-3 shares its bins with G_6 (and G_3 with G_-6).
    let aliases = s["aliasing"]["by_harmonic"]["-3"]["aliases"]
        .as_array()
        .unwrap();
    assert!(aliases.iter().any(|a| a["harmonic"] == 6));
}

/// The designed experiment removes the failure: every |n| <= 3 within 0.5 % of max|G_n| over
/// 1-40 rad/s at a spacing of 0.45 rad/s or finer, and k, c recovered to 0.01 and 1e-3.
#[test]
fn run_paper_improved_meets_its_targets() {
    improved_targets("configs/paper-improved.toml");
}

/// The designed experiment's targets hold with the hopper written in the model language.
#[test]
fn run_paper_improved_model_meets_its_targets() {
    improved_targets("configs/paper-improved-model.toml");
}

fn improved_targets(config: &str) {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("improved");
    htfid_ok(&["run", config, "--out", out.to_str().unwrap(), "--no-plots"]);
    let s = summary(&out);
    assert!(s["simulation"]["t_end"].as_f64().unwrap() - 30.0 <= 600.0 + 1e-9);
    for n in -3..=3 {
        let e = max_error(&s, "lines", n);
        assert!(e <= 0.005, "G_{n}: max error {e}");
    }
    // Spacing, from the estimate file itself.
    let est = fs::read_to_string(out.join("estimate_lines.csv")).unwrap();
    for n in -3..=3 {
        let mut w: Vec<f64> = est
            .lines()
            .skip(1)
            .map(|l| {
                l.split(',')
                    .map(|v| v.parse::<f64>().unwrap())
                    .collect::<Vec<_>>()
            })
            .filter(|r| (r[1] - f64::from(n)).abs() < 0.5)
            .map(|r| r[0])
            .collect();
        w.sort_by(f64::total_cmp);
        assert!(
            w[0] <= 1.45 && *w.last().unwrap() >= 39.55,
            "G_{n} covers {}..{}",
            w[0],
            w.last().unwrap()
        );
        assert!(
            w.windows(2).all(|p| p[1] - p[0] <= 0.45 + 1e-9),
            "G_{n} spacing"
        );
    }
    let fit = &s["fit"]["lines"];
    assert!(
        (fit["c"].as_f64().unwrap() - 2.0).abs() <= 1e-3,
        "c_hat {}",
        fit["c"]
    );
    assert!(
        (fit["k"].as_f64().unwrap() - 200.0).abs() <= 0.01,
        "k_hat {}",
        fit["k"]
    );
}

/// The configured truth of `configs/paper-improved.toml` (`[model] k`, `c`), which the fit
/// does not see.
const IMPROVED_TRUTH: [(&str, f64); 2] = [("k", 200.0), ("c", 2.0)];

/// `htfid run configs/paper-improved.toml` with white output noise of `std` m and `seed`,
/// into `dir/<seed>`: the fit and its uncertainty.
fn improved_with_noise(dir: &Path, std: f64, seed: u64) -> serde_json::Value {
    let text = fs::read_to_string(root().join("configs/paper-improved.toml")).unwrap();
    let cfg = dir.join(format!("noise-{seed}.toml"));
    fs::write(
        &cfg,
        format!("{text}\n[noise]\noutput_std = {std:e}\nseed = {seed}\n"),
    )
    .unwrap();
    let out = dir.join(seed.to_string());
    htfid_ok(&[
        "run",
        cfg.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--no-plots",
        "-q",
    ]);
    summary(&out)["fit"]["lines"].clone()
}

/// Misses of the stated total interval and of the noise-only interval (same level), summed
/// over k and c and the given seeds.
fn improved_coverage(std: f64, seeds: std::ops::Range<u64>) -> (usize, usize, usize) {
    let tmp = tempfile::tempdir().unwrap();
    let (mut total, mut noise_only, mut checks) = (0, 0, 0);
    for seed in seeds {
        let fit = improved_with_noise(tmp.path(), std, seed);
        for (name, truth) in IMPROVED_TRUTH {
            let p = &fit["uncertainty"]["parameters"][name];
            let error = (fit[name].as_f64().unwrap() - truth).abs();
            let k = p["coverage_factor"].as_f64().unwrap();
            total += usize::from(error > p["half_width"].as_f64().unwrap());
            noise_only += usize::from(error > k * p["noise"].as_f64().unwrap());
            checks += 1;
        }
    }
    (total, noise_only, checks)
}

#[test]
fn paper_improved_states_why_c_is_off_and_covers_it() {
    states_why_c_is_off("configs/paper-improved.toml");
}

/// The bootstrap budget of the designed experiment, with the hopper written in the model
/// language.
#[test]
fn paper_improved_model_states_why_c_is_off_and_covers_it() {
    states_why_c_is_off("configs/paper-improved-model.toml");
}

fn states_why_c_is_off(config: &str) {
    // Noise free, the fitted c is off by the odd-order distortion that the sign reversal
    // leaves (it scales with the square of the amplitude: -4.6e-6, -2.5e-5, -9.8e-5, -3.4e-4
    // at amplitudes 0.001, 0.002, 0.004, 0.008), about 100 times the noise-only standard
    // error. The summary must name it as dominant, estimate it (the estimate comes from a
    // re-run on the fitted model, the truth is the config's c; they agreed to 0.05 %, bound
    // 5 %: the re-run is at parameters 5e-5 off the truth) and state an interval holding the
    // truth, which the noise-only one does not.
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("improved");
    let o = htfid(&[
        "run",
        config,
        "--out",
        out.to_str().unwrap(),
        "--no-plots",
        "-q",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let fit = &summary(&out)["fit"]["lines"];
    let u = &fit["uncertainty"];
    assert_eq!(u["htf_bias_source"], "pairing_distortion");
    assert_eq!(u["htf_bias_method"], "bootstrap");
    for (name, truth) in IMPROVED_TRUTH {
        let p = &u["parameters"][name];
        let error = fit[name].as_f64().unwrap() - truth;
        let get = |k: &str| p[k].as_f64().unwrap();
        assert_eq!(p["dominant"], "pairing_distortion", "{name}: {p}");
        assert!(error.abs() <= get("half_width"), "{name}: {error:e} {p}");
        assert!(error.abs() > 1.96 * get("noise"), "{name}: {error:e} {p}");
        let estimate = get("htf_bias_estimate");
        assert!(
            (estimate - error).abs() <= 0.05 * error.abs(),
            "{name}: bias estimate {estimate:e}, error {error:e}"
        );
        for key in ["htf_bias", "structure", "total", "coverage_factor"] {
            assert!(get(key).is_finite(), "{name}.{key}");
        }
    }
    let text = stdout(&o);
    assert!(
        text.contains("uncertainty (lines)") && text.contains("pairing distortion dominates"),
        "{text}"
    );
}

#[test]
fn paper_improved_uncertainty_covers_the_truth_quick() {
    // Output noise of 1e-7 m makes noise and pairing distortion comparable for c (noise-only
    // standard error 4.2e-5 against a distortion of 9.8e-5), so an interval that ignored the
    // distortion would miss often: the noise-only intervals must miss at least 4 of the 16
    // checks (k and c over 8 seeds; measured 5), or this test could not fail. The stated
    // intervals claim 95 %: with 16 checks, 3 or more misses has probability 4 % if the claim
    // holds (measured 1 miss); at most 2 are allowed. The long version is
    // `paper_improved_uncertainty_covers_the_truth_long`.
    let (total, noise_only, checks) = improved_coverage(1e-7, 1..9);
    assert_eq!(checks, 16);
    assert!(total <= 2, "{total} of {checks} missed");
    assert!(
        noise_only >= 4,
        "noise-only intervals missed only {noise_only}"
    );
}

#[test]
#[ignore = "Monte Carlo over 200 seeds, 4 to 10 minutes"]
fn paper_improved_uncertainty_covers_the_truth_long() {
    // As the quick version over 200 seeds (400 checks): at a true 95 % the misses are
    // binomial, mean 20, sd 4.4; at most 20 + 3 sd = 33 are allowed. Measured (2026-11-24):
    // 11 misses, 163 by the noise-only intervals; 582 s on 2 cores shared with a build.
    let (total, noise_only, checks) = improved_coverage(1e-7, 1..201);
    println!("{total} of {checks} missed ({noise_only} by noise-only intervals)");
    assert!(total <= 33, "{total} of {checks} missed");
    assert!(
        noise_only >= 100,
        "noise-only intervals missed only {noise_only}"
    );
}

#[test]
fn too_few_phase_shifts_for_the_harmonics_is_explained() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = edited_config(tmp.path(), "copies = 9", "copies = 5");
    let o = htfid(&[
        "run",
        cfg.to_str().unwrap(),
        "--out",
        tmp.path().join("o").to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(
        err.contains("7 harmonics cannot be separated with 5 phase shifts"),
        "{err}"
    );
}

#[test]
fn edited_chirp_band_runs() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = edited_config(
        tmp.path(),
        "waveform = \"paper\"    # u = 0.004 sin(14 pi t^2 / 30), exactly as printed",
        "waveform = \"linear\"\nf_start_hz = 0.1\nf_end_hz = 7.0\nduration = 30.0\namplitude = 0.004",
    );
    let out = tmp.path().join("o");
    htfid_ok(&[
        "run",
        cfg.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--no-plots",
    ]);
    assert!(summary(&out)["fit"]["multi"]["k"].as_f64().unwrap() > 0.0);
}

fn diagnosis(dir: &Path) -> serde_json::Value {
    read_json(&dir.join("diagnosis.json"))
}

fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&fs::read_to_string(path).unwrap()).unwrap()
}

/// `htfid diagnose CONFIG --out OUT --quiet`, which must succeed, and its `diagnosis.json`.
fn diagnose_quietly(config: &Path, out: &Path) -> serde_json::Value {
    htfid_ok(&[
        "diagnose",
        config.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    diagnosis(out)
}

/// The effects of a diagnosis's `causes`, strongest first.
fn cause_names(d: &serde_json::Value) -> Vec<&str> {
    d["causes"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|c| c["effect"].as_str())
        .collect()
}

/// Writes `config` as `dir/NAME.toml`, diagnoses it into `dir/NAME` and reads its
/// `diagnosis.json`.
fn diagnose_text(dir: &Path, name: &str, config: &str) -> serde_json::Value {
    let path = dir.join(format!("{name}.toml"));
    fs::write(&path, config).unwrap();
    let out = dir.join(name);
    htfid_ok(&[
        "diagnose",
        path.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    diagnosis(&out)
}

/// The hopper record (made by `htfid simulate configs/hopper-truth.toml`, whose truth has flight
/// damping c_f = 0.2 N s/m that `models/hopper.toml` lacks) is diagnosed through the shipped
/// config as damping of `v` in mode `free`, its coefficient within 5 % of 0.2 (per unit mass,
/// m = 1 kg: the record's noise, 2e-5 m, leaves it a few percent), with the contract's keys,
/// every figure in the report, the evidence, and the validation of the refitted and the final
/// model.
#[test]
fn diagnose_hopper_names_the_hidden_flight_damping() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("dh");
    htfid_ok(&[
        "diagnose",
        "configs/diagnose-hopper.toml",
        "--out",
        out.to_str().unwrap(),
    ]);
    let d = diagnosis(&out);
    // A cubic and quadratic spring comes within 2 % of it held out (both near the noise
    // floor), but the fit data separate them by a likelihood ratio of about 600 at one
    // parameter fewer: the damping is named alone (`bic_margin`).
    assert_eq!(d["cause"], "mode_damping(v, free)", "{}", d["alternatives"]);
    assert_eq!(d["options"]["bic_margin"], 10.0);
    let best = &d["candidates"][0];
    assert_eq!(
        best["effect"], "mode_damping(v, free)",
        "{}",
        d["candidates"]
    );
    assert_eq!(
        best["term"],
        "`-damping_v_free*v` added to dv/dt in mode free"
    );
    let c_f = d["parameters"]["damping_v_free"].as_f64().unwrap();
    assert!((c_f / 0.2 - 1.0).abs() < 0.05, "damping_v_free = {c_f}");
    assert!(d["gain"].as_f64().unwrap() > 0.2);
    for key in [
        "parameters",
        "stderr",
        "nominal",
        "extended",
        "gain",
        "candidates",
        "causes",
    ] {
        assert!(!d[key].is_null(), "diagnosis.json lacks {key}");
    }
    assert!(d["nominal"]["nrmse"].as_f64().unwrap() > d["extended"]["nrmse"].as_f64().unwrap());
    let report = fs::read_to_string(out.join("report.md")).unwrap();
    assert!(report.contains("`mode_damping(v, free)`"), "{report}");
    assert!(
        report.contains("## Error on held-out data") && report.contains("NRMSE"),
        "{report}"
    );
    // Paths relative to the working directory, without detours through configs/...
    assert!(
        report.contains("data: `data/hopper-protocol.csv`"),
        "{report}"
    );
    for f in [
        "residual_time.png",
        "residual_spectrum.png",
        "orbit.png",
        "htf_data.png",
        "compare.png",
        "resid.png",
        "residual_bins.png",
        "error_waterfall.png",
        "htf_difference.png",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
        assert!(report.contains(f), "report.md does not show {f}");
    }
    // The evidence: the refitted model's residual acceleration stands out against velocity
    // (the missing damping acts on one side of zero velocity; measured 63 standard errors),
    // the final model's does not (measured 2.9); the waterfall runs from the configured model
    // to the final one; the report has no NaN cells.
    let bins = &d["residual_bins"];
    let max_z = |model: &str| {
        bins[model]["by_velocity"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|b| Some((b["mean"].as_f64()? / b["stderr"].as_f64()?).abs()))
            .fold(0.0, f64::max)
    };
    assert!(max_z("nominal") > 10.0, "{bins}");
    assert!(max_z("extended") < 6.0, "{bins}");
    let steps: Vec<&str> = d["error_waterfall"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["step"].as_str().unwrap())
        .collect();
    assert_eq!(
        steps,
        ["configured", "refitted", "mode_damping(v, free)", "final"]
    );
    assert_eq!(d["htf_difference"].as_array().unwrap().len(), 5);
    assert!(!report.contains("NaN"), "{report}");
    // Validation as compare/resid give it. The hopper file lacks the record's flight damping:
    // the refitted model's residual keeps structure, which the whiteness test must see (p far
    // below 1 %). The final model's residual is white and independent of the force at the
    // 1 % level (the record's noise is white and the final model holds the true effect), with
    // N, the bounds and the degrees of freedom as stated.
    let v = &d["validation"];
    assert_eq!(v["whiteness"]["passed"], false, "{v}");
    assert!(v["whiteness"]["p_value"].as_f64().unwrap() < 1e-6, "{v}");
    assert!(v["fit_percent"]["refitted model"].as_f64().unwrap() > 90.0);
    assert!(!v["by_output"]["x"].is_null());
    assert!(report.contains("**not white**"), "{report}");
    let f = &d["validation_final"];
    let fit = |k: &str| f["fit_percent"][k].as_f64().unwrap();
    assert!(
        fit("with mode_damping(v, free)") > fit("refitted model"),
        "{f}"
    );
    for test in ["whiteness", "independence"] {
        let t = &f[test];
        assert_eq!(t["passed"], true, "{test}: {t}");
        let n = t["samples"].as_f64().unwrap();
        assert!((t["bound"].as_f64().unwrap() - 2.5758293035489 / n.sqrt()).abs() < 1e-12);
    }
    assert_eq!(f["whiteness"]["dof"], 25);
    assert_eq!(f["independence"]["dof"], 26);
    assert!(report.contains("## Validation"));
}

/// The truth config regenerates the committed record exactly (so the data are reproducible).
#[test]
fn hopper_truth_config_reproduces_the_committed_record() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("truth");
    htfid_ok(&[
        "simulate",
        "configs/hopper-truth.toml",
        "--out",
        out.to_str().unwrap(),
    ]);
    let made: Vec<String> = fs::read_to_string(out.join("timeseries.csv"))
        .unwrap()
        .lines()
        .map(|l| l.split(',').take(3).collect::<Vec<_>>().join(","))
        .collect();
    let committed: Vec<String> = fs::read_to_string(root().join("data/hopper-protocol.csv"))
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(str::to_string)
        .collect();
    assert_eq!(made.len(), committed.len());
    // Same integrator, same seed: identical up to the last printed digit on this platform;
    // compare numerically with a tolerance far below the noise (2e-5 m) to allow other
    // platforms' libm.
    for (a, b) in made.iter().zip(&committed).skip(1) {
        for (x, y) in a.split(',').zip(b.split(',')) {
            let (x, y): (f64, f64) = (x.parse().unwrap(), y.parse().unwrap());
            assert!((x - y).abs() <= 1e-9 * (1.0 + y.abs()), "{a} vs {b}");
        }
    }
}

/// A short experiment (a 10 s linear chirp after two settling periods) at `rate` Hz, with
/// `effects` appended, simulated into `dir/name`; its `t`, `x`, `xd` columns.
fn short_record(dir: &Path, name: &str, rate: f64, effects: &str) -> Vec<[f64; 3]> {
    let config = dir.join(format!("{name}.toml"));
    fs::write(
        &config,
        format!(
            "name = \"{name}\"\n\
             [model]\nm = 1.0\nk = 200.0\nc = 2.0\ng = 9.81\nx0 = 0.2\n\
             [forcing]\namplitude = 1.0\nperiod = 1.0\n\
             [simulation]\nsettle_periods = 2\nsample_rate = {rate}\nrtol = 1e-10\natol = 1e-12\n\
             [excitation]\nkind = \"chirp_train\"\nwaveform = \"linear\"\nf_start_hz = 0.5\n\
             f_end_hz = 5.0\nduration = 10.0\namplitude = 0.5\n{effects}"
        ),
    )
    .unwrap();
    let out = dir.join(name);
    htfid_ok(&[
        "simulate",
        config.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "-q",
    ]);
    let text = fs::read_to_string(out.join("timeseries.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |n: &str| header.iter().position(|h| *h == n).unwrap();
    let (t, x, xd) = (col("t"), col("x"), col("xd"));
    lines
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|c| c.parse().unwrap()).collect();
            [v[t], v[x], v[xd]]
        })
        .collect()
}

/// `[effects] tau_s`, `b`, `g` put the diagnosis's position sensor into a simulated record:
/// the recorded `x` is `b + g s` with `tau_s s' = x - s`, the velocity `xd` untouched.
///
/// Offset and gain: exactly `b + g x` of the record without them (to rounding, 1e-15 m).
/// The lag against a filter written here from its definition: the same experiment sampled at
/// 2 kHz, filtered exactly for a position linear between those samples (from `s = x` at the
/// first sample, as a sensor slower than the sampling starts), read every 20th sample. Its own
/// error is `h^2 |x''| / 8`, about 1e-9 m. The record's filter reads the 100 Hz samples through
/// a cubic interpolant, whose error near the damper's 42 switches (where `x''` jumps) is
/// 6.6e-8 m, 1.5e-6 of the 0.045 m peak to peak, measured; 5e-6 of it is allowed.
#[test]
fn a_simulated_sensor_lags_offsets_and_scales_the_recorded_position() {
    let tmp = tempfile::tempdir().unwrap();
    let ideal = short_record(tmp.path(), "ideal", 100.0, "");
    let scaled = short_record(
        tmp.path(),
        "scaled",
        100.0,
        "[effects]\nb = 0.01\ng = 1.1\n",
    );
    assert_eq!(ideal.len(), scaled.len());
    for (a, b) in ideal.iter().zip(&scaled) {
        assert!((b[1] - (0.01 + 1.1 * a[1])).abs() <= 1e-15, "{a:?} {b:?}");
        assert_eq!(
            a[2].to_bits(),
            b[2].to_bits(),
            "the velocity is not measured"
        );
    }

    let (tau, h, stride): (f64, f64, usize) = (0.05, 1.0 / 2000.0, 20);
    let fine = short_record(tmp.path(), "fine", 2000.0, "");
    let lagged = short_record(
        tmp.path(),
        "lagged",
        100.0,
        "[effects]\ntau_s = 0.05\nb = 0.01\ng = 1.1\n",
    );
    // tau s' = x - s for x linear from x0 to x1 over h: s1 = e s0 + (1 - e) x0 + w (x1 - x0).
    let a = h / tau;
    let e = (-a).exp();
    let w = (1.0 - e) - (1.0 - e * (1.0 + a)) / a;
    let mut s = fine[0][1];
    let mut filtered = vec![s];
    for pair in fine.windows(2) {
        let (x0, x1) = (pair[0][1], pair[1][1]);
        s = e * s + (1.0 - e) * x0 + w * (x1 - x0);
        filtered.push(s);
    }
    let (lo, hi) = ideal
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| {
            (lo.min(r[1]), hi.max(r[1]))
        });
    let worst = lagged
        .iter()
        .enumerate()
        .map(|(i, r)| {
            assert!((r[0] - fine[i * stride][0]).abs() < 1e-12, "the same times");
            (r[1] - (0.01 + 1.1 * filtered[i * stride])).abs()
        })
        .fold(0.0, f64::max);
    assert!(worst <= 5e-6 * (hi - lo), "worst {worst} of {}", hi - lo);

    // A gain of 0 records nothing and a negative lag is no lag: both named.
    for (effects, key) in [
        ("[effects]\ng = 0.0\n", "effects.g"),
        ("[effects]\ntau_s = -1.0\n", "effects.tau_s"),
    ] {
        simulate_refuses(tmp.path(), "ideal", effects, key);
    }
}

/// `simulate` of the short experiment `name` (written by [`short_record`] into `dir`) with
/// `effects` in place of its own fails, names `key` and writes nothing.
fn simulate_refuses(dir: &Path, name: &str, effects: &str, key: &str) {
    let config = dir.join("bad.toml");
    let good = fs::read_to_string(dir.join(format!("{name}.toml"))).unwrap();
    let good = good.split("[effects]").next().unwrap().to_string();
    fs::write(&config, format!("{good}{effects}")).unwrap();
    let out = dir.join("bad");
    let o = htfid(&[
        "simulate",
        config.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success(), "{effects}");
    assert!(stderr(&o).contains(key), "{effects}: {}", stderr(&o));
    assert!(!out.exists(), "no output for a refused config");
}

/// `[effects] mu_pos`, `mu_neg` (the diagnosis's asymmetric friction): friction `mu_pos`
/// against upward motion and `mu_neg` against downward motion. Worked by hand for 0.3 N and
/// 0.1 N: up, `-0.3 = -0.2 - 0.1`; down, `+0.1 = +0.2 - 0.1`: symmetric friction `mu = 0.2`
/// and a constant force of -0.1 N, so the two records are the same, sample for sample. One
/// level alone, or beside `mu`, is named.
#[test]
fn asymmetric_friction_is_simulated_as_its_mean_and_a_constant_force() {
    let tmp = tempfile::tempdir().unwrap();
    let asymmetric = short_record(
        tmp.path(),
        "asym",
        100.0,
        "[effects]\nmu_pos = 0.3\nmu_neg = 0.1\n",
    );
    let split = short_record(
        tmp.path(),
        "split",
        100.0,
        "[effects]\nmu = 0.2\ninput_offset = -0.1\n",
    );
    let symmetric = short_record(tmp.path(), "sym", 100.0, "[effects]\nmu = 0.2\n");
    assert_eq!(asymmetric.len(), split.len());
    // The same up to one rounding of the constant (`0.5 (0.1 - 0.3)` is -0.09999999999999999),
    // which the integrator (rtol 1e-10) may turn into a different step: 1e-9 m and m/s allowed.
    for (a, b) in asymmetric.iter().zip(&split) {
        assert_eq!(a[0].to_bits(), b[0].to_bits());
        assert!(
            (a[1] - b[1]).abs() < 1e-9 && (a[2] - b[2]).abs() < 1e-9,
            "{a:?} {b:?}"
        );
    }
    // The constant force moves the record: the asymmetry is not lost.
    let moved = asymmetric
        .iter()
        .zip(&symmetric)
        .map(|(a, b)| (a[1] - b[1]).abs())
        .fold(0.0, f64::max);
    assert!(moved > 1e-4, "{moved}");
    for (effects, key) in [
        ("[effects]\nmu_pos = 0.3\n", "effects.mu_pos"),
        ("[effects]\nmu_neg = 0.3\n", "effects.mu_neg"),
        (
            "[effects]\nmu = 0.2\nmu_pos = 0.3\nmu_neg = 0.1\n",
            "effects.mu",
        ),
        ("[effects]\nmu_pos = -0.3\nmu_neg = 0.1\n", "effects.mu_pos"),
        // Beyond the scale limit the level is named, not the `mu` it sets.
        (
            "[effects]\nmu_pos = 1e12\nmu_neg = 0.1\n",
            "effects.mu_pos: the friction",
        ),
    ] {
        simulate_refuses(tmp.path(), "sym", effects, key);
    }
}

/// The Silverbox record in ../shared; a missing file fails the test that asks for it.
fn silverbox_data() -> PathBuf {
    let data = root().join("../shared/data/silverbox/SNLS80mV.csv");
    assert!(
        data.exists(),
        "Silverbox data missing at {}",
        data.display()
    );
    data
}

#[test]
fn broken_data_files_are_named_with_line_and_column() {
    let tmp = tempfile::tempdir().unwrap();
    let csv = tmp.path().join("bad.csv");
    fs::write(&csv, "t,f,x\n0,1,0.15\n0.01,1,abc\n0.02,1,0.15\n").unwrap();
    let o = htfid(&[
        "diagnose",
        "configs/diagnose-hopper.toml",
        "--data",
        csv.to_str().unwrap(),
        "--out",
        tmp.path().join("o").to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(
        err.contains("bad.csv:3") && err.contains("\"abc\""),
        "{err}"
    );
    fs::write(&csv, "t,force,x\n0,1,0.15\n").unwrap();
    let o = htfid(&[
        "diagnose",
        "configs/diagnose-hopper.toml",
        "--data",
        csv.to_str().unwrap(),
        "--out",
        tmp.path().join("o").to_str().unwrap(),
    ]);
    let err = stderr(&o);
    assert!(
        err.contains("no column \"f\"") && err.contains("\"force\""),
        "{err}"
    );
    assert!(!tmp.path().join("o").exists());
}

/// Every shipped config is exercised by a test in this file, so none can rot unnoticed.
#[test]
fn every_shipped_config_is_run_by_a_test() {
    let covered = [
        "paper.toml",
        "paper-improved.toml",
        "hopper-truth.toml",
        "diagnose-hopper.toml",
        "silverbox.toml",
        "bouncing-ball.toml",
        "flight-hopper.toml",
        "two-dof.toml",
        "closed-loop-friction.toml",
        "paper-model.toml",
        "paper-improved-model.toml",
        "estimate-hopper.toml",
    ];
    let this = fs::read_to_string(root().join("tests/cli.rs")).unwrap();
    for entry in fs::read_dir(root().join("configs")).unwrap() {
        let name = entry.unwrap().file_name().to_string_lossy().into_owned();
        if name.ends_with(".toml") {
            assert!(
                covered.contains(&name.as_str()),
                "configs/{name} is not run by any test"
            );
            assert!(
                this.contains(&format!("\"configs/{name}\"")),
                "configs/{name} is listed but not run"
            );
        }
    }
}

/// Reads `estimate_<name>.csv` into rows `[omega, n, re, im, stderr]`.
fn estimate_rows(dir: &Path, name: &str) -> Vec<Vec<f64>> {
    fs::read_to_string(dir.join(format!("estimate_{name}.csv")))
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect()
}

/// Monte Carlo through the whole pipeline: with seeded measurement noise, the standard errors
/// `htfid run` reports match the scatter of its estimates over noise realisations.
fn stderr_matches_scatter(config: &str, estimator: &str, noise: f64) {
    let tmp = tempfile::tempdir().unwrap();
    let text = fs::read_to_string(root().join(config)).unwrap();
    let seeds = 16;
    let mut runs = Vec::new();
    for seed in 0..seeds {
        let cfg = tmp.path().join(format!("mc{seed}.toml"));
        fs::write(
            &cfg,
            format!("{text}\n[noise]\noutput_std = {noise}\nseed = {seed}\n"),
        )
        .unwrap();
        let out = tmp.path().join(format!("mc{seed}"));
        htfid_ok(&[
            "run",
            cfg.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--no-plots",
        ]);
        runs.push(estimate_rows(&out, estimator));
    }
    let rows = runs[0].len();
    let mut ratios = Vec::new();
    for i in 0..rows {
        let n = seeds as f64;
        let (mut sre, mut sim) = (0.0, 0.0);
        for r in &runs {
            sre += r[i][2];
            sim += r[i][3];
        }
        let (mre, mim) = (sre / n, sim / n);
        // Complex standard deviation: sqrt(E|G - mean|^2), with n - 1 degrees of freedom.
        let var: f64 = runs
            .iter()
            .map(|r| (r[i][2] - mre).powi(2) + (r[i][3] - mim).powi(2))
            .sum::<f64>()
            / (n - 1.0);
        let reported = (runs.iter().map(|r| r[i][4].powi(2)).sum::<f64>() / n).sqrt();
        if reported.is_finite() && reported > 0.0 {
            ratios.push(var.sqrt() / reported);
        }
    }
    ratios.sort_by(f64::total_cmp);
    let median = ratios[ratios.len() / 2];
    // 16 realisations give each bin's scatter a ~18 % relative spread; the median over hundreds
    // of bins is far tighter, so 0.8..1.25 leaves room only for a real miscalibration.
    assert!(
        (0.8..1.25).contains(&median),
        "{config} {estimator}: median scatter / stderr = {median}"
    );
}

#[test]
fn reported_standard_errors_match_monte_carlo_scatter_multi() {
    stderr_matches_scatter("configs/paper.toml", "multi", 1e-6);
}

#[test]
fn reported_standard_errors_match_monte_carlo_scatter_lines() {
    stderr_matches_scatter("configs/paper-improved.toml", "lines", 1e-6);
}

#[test]
fn a_config_of_the_other_kind_is_explained() {
    let o = htfid(&[
        "diagnose",
        "configs/paper.toml",
        "--out",
        "/nonexistent/never",
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("this is an experiment config"),
        "{}",
        stderr(&o)
    );
    let o = htfid(&[
        "run",
        "configs/silverbox.toml",
        "--out",
        "/nonexistent/never",
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("run it with `htfid diagnose`"),
        "{}",
        stderr(&o)
    );
}

/// A diagnosis config whose `[model]` holds inline keys (the form `simulate` and `run` read
/// for the built-in hopper) names no model file: it is refused at the line of `[model]`, with
/// the keys it found and the shipped model files that take them, and nothing is written.
/// The same for an effect named as in that form.
#[test]
fn a_diagnosis_without_a_model_file_is_refused_with_the_way_to_write_it() {
    let tmp = tempfile::tempdir().unwrap();
    let config = tmp.path().join("inline.toml");
    fs::write(
        &config,
        "name = \"inline\"\n\n[data]\nfile = \"r.csv\"\ntime = \"t\"\ninput = \"f\"\n\
         outputs = [\"x\"]\n\n[model]\nm = 1.0\nk = 200.0\ndamper = \"switching\"\n",
    )
    .unwrap();
    assert_refused(
        "diagnose",
        &config,
        &tmp.path().join("out"),
        &[
            "inline.toml:9:1: model.file: is missing",
            "damper, k, m",
            "models/hopper.toml",
            "models/spring-mass-damper.toml",
            "[model.parameters]",
            "docs/config.md",
        ],
        "inline [model]",
    );
    // An effect by the name of its earlier form is refused with its name now.
    fs::write(
        &config,
        diagnose_hopper_config().replacen(
            "min_gain = 0.05",
            "min_gain = 0.05\neffects = [\"cubic_stiffness\"]",
            1,
        ),
    )
    .unwrap();
    assert_refused(
        "diagnose",
        &config,
        &tmp.path().join("out"),
        &[
            "diagnose.effects: unknown effect \"cubic_stiffness\" (\"cubic_stiffness\" is now \
             nonlinear_stiffness)",
        ],
        "an effect's earlier name",
    );
}

/// `--truncate N` gives Wereley's truncated HTF, close to the exact one and closer as N grows.
#[test]
fn theory_truncate_converges_to_exact() {
    let tmp = tempfile::tempdir().unwrap();
    let read = |args: &[&str], name: &str| -> Vec<Vec<f64>> {
        let out = tmp.path().join(name);
        let mut all = vec![
            "theory",
            "configs/paper.toml",
            "--omega",
            "3,9,13.5,20",
            "--no-plots",
            "--out",
            out.to_str().unwrap(),
        ];
        all.extend_from_slice(args);
        let o = htfid(&all);
        assert!(o.status.success(), "{}", stderr(&o));
        fs::read_to_string(out.join("theory.csv"))
            .unwrap()
            .lines()
            .skip(1)
            .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
            .collect()
    };
    let exact = read(&[], "exact");
    let max_g = exact.iter().map(|r| r[2].hypot(r[3])).fold(0.0, f64::max);
    let err = |rows: &[Vec<f64>]| {
        rows.iter()
            .zip(&exact)
            .map(|(a, b)| (a[2] - b[2]).hypot(a[3] - b[3]))
            .fold(0.0, f64::max)
            / max_g
    };
    let (e10, e40) = (
        err(&read(&["--truncate", "10"], "t10")),
        err(&read(&["--truncate", "40"], "t40")),
    );
    assert!(e10 < 1e-4, "N = 10: {e10}");
    assert!(e40 < e10 / 10.0, "N = 40: {e40} vs N = 10: {e10}");
    let s = summary(&tmp.path().join("t10"));
    assert_eq!(s["htf"]["method"], "truncated");
    assert_eq!(s["htf"]["truncation"], 10);
}

/// `--truncate` takes any model whose linearisation is constant within each mode: the hopper
/// written as a model file gives the built-in hopper's truncated HTF (the same harmonic state
/// space from two implementations of its equations, so the same numbers to round-off: 1e-12
/// of the largest `|G_n|`). A model whose linearisation varies along the orbit (the two-dof
/// system) has no harmonic state space to truncate: a clear error, and nothing written.
#[test]
fn theory_truncates_model_files_with_piecewise_linearisations() {
    let tmp = tempfile::tempdir().unwrap();
    let read = |config: &str, name: &str| -> Vec<Vec<f64>> {
        let out = tmp.path().join(name);
        let o = htfid(&[
            "theory",
            config,
            "--omega",
            "3,9,13.5,20",
            "--no-plots",
            "--truncate",
            "10",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        fs::read_to_string(out.join("theory.csv"))
            .unwrap()
            .lines()
            .skip(1)
            .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
            .collect()
    };
    let built_in = read("configs/paper.toml", "built-in");
    let file = read("configs/paper-model.toml", "file");
    assert_eq!(built_in.len(), file.len());
    let max_g = built_in
        .iter()
        .map(|r| r[2].hypot(r[3]))
        .fold(0.0, f64::max);
    for (a, b) in built_in.iter().zip(&file) {
        assert_eq!((a[0], a[1]), (b[0], b[1]));
        let d = (a[2] - b[2]).hypot(a[3] - b[3]);
        assert!(d <= 1e-12 * max_g, "{a:?} against {b:?}");
    }
    assert_eq!(
        summary(&tmp.path().join("file"))["htf"]["method"],
        "truncated"
    );

    let out = tmp.path().join("two-dof");
    let o = htfid(&[
        "theory",
        "configs/two-dof.toml",
        "--truncate",
        "10",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("--truncate") && e.contains("not constant within each mode"),
        "{e}"
    );
    assert!(!out.join("theory.csv").exists() && !out.join("summary.json").exists());
}

/// Reads a theory CSV (`omega,n,re,im`) into `(omega, n) -> G`.
fn theory_rows(path: &Path) -> Vec<(f64, i32, f64, f64)> {
    let text = fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("omega,n,re,im"));
    lines
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            (v[0], v[1] as i32, v[2], v[3])
        })
        .collect()
}

/// Every model-language config simulates and gives its HTFs; the HTFs of every output agree
/// with the independent oracle of `tests/oracle/models` (numpy/scipy, written from the
/// equations alone) at its frequencies, to 1e-7 of max |G| (both are exact up to integrator
/// error; the oracle's own methods agree to about 1e-10).
#[test]
fn model_configs_simulate_and_match_the_oracle_htfs() {
    let tmp = tempfile::tempdir().unwrap();
    for (config, oracle, outputs) in [
        (
            "configs/bouncing-ball.toml",
            "bouncing_ball.json",
            &["y"][..],
        ),
        (
            "configs/flight-hopper.toml",
            "flight_hopper.json",
            &["y"][..],
        ),
        ("configs/two-dof.toml", "two_dof.json", &["x1", "x2"][..]),
        (
            "configs/closed-loop-friction.toml",
            "closed_loop_friction.json",
            &["x"][..],
        ),
    ] {
        let sim = tmp.path().join("sim");
        htfid_ok(&[
            "simulate",
            config,
            "--out",
            sim.to_str().unwrap(),
            "--force",
        ]);
        let s = summary(&sim);
        assert!(
            s["simulation"]["samples"].as_u64().unwrap() > 10_000,
            "{config}"
        );
        let header = fs::read_to_string(sim.join("timeseries.csv")).unwrap();
        let header = header.lines().next().unwrap().to_string();
        for o in outputs {
            assert!(header.split(',').any(|c| c == *o), "{config}: {header}");
        }

        let reference: serde_json::Value = serde_json::from_str(
            &fs::read_to_string(root().join("tests/oracle/models").join(oracle)).unwrap(),
        )
        .unwrap();
        let rows = reference["htf"].as_array().unwrap();
        let mut omegas: Vec<f64> = rows.iter().map(|r| r["omega"].as_f64().unwrap()).collect();
        omegas.sort_by(f64::total_cmp);
        omegas.dedup();
        let list: Vec<String> = omegas.iter().map(|w| format!("{w:.17e}")).collect();
        let th = tmp.path().join("theory");
        htfid_ok(&[
            "theory",
            config,
            "--omega",
            &list.join(","),
            "--out",
            th.to_str().unwrap(),
            "--force",
            "--no-plots",
        ]);
        for (k, name) in outputs.iter().enumerate() {
            let file = if outputs.len() > 1 {
                th.join(format!("theory_{name}.csv"))
            } else {
                th.join("theory.csv")
            };
            let ours = theory_rows(&file);
            let want: Vec<&serde_json::Value> = rows
                .iter()
                .filter(|r| r["output"].as_u64() == Some(k as u64))
                .collect();
            let scale = want
                .iter()
                .map(|r| r["re"].as_f64().unwrap().hypot(r["im"].as_f64().unwrap()))
                .fold(0.0, f64::max);
            for r in want {
                let (w, n) = (
                    r["omega"].as_f64().unwrap(),
                    r["n"].as_i64().unwrap() as i32,
                );
                let row = ours
                    .iter()
                    .find(|x| x.1 == n && (x.0 - w).abs() < 1e-12 * w)
                    .unwrap_or_else(|| panic!("{config}: no row for w {w}, n {n}"));
                let err =
                    (row.2 - r["re"].as_f64().unwrap()).hypot(row.3 - r["im"].as_f64().unwrap());
                assert!(
                    err < 1e-7 * scale,
                    "{config} {name} w {w} n {n}: {err:e} of {scale:e}"
                );
            }
        }
    }
}

/// Mistakes in a config that names a model file are located; nothing is written.
#[test]
fn model_config_errors_are_located() {
    let tmp = tempfile::tempdir().unwrap();
    let base = fs::read_to_string(root().join("configs/two-dof.toml")).unwrap();
    let models = root().join("models");
    let base = base.replace(
        "file = \"../models/two-dof.toml\"",
        &format!("file = {:?}", models.join("two-dof.toml").to_str().unwrap()),
    );
    let cases: &[(&str, &str, &[&str])] = &[
        (
            "[simulation]",
            "[model.parameters]\nk99 = 1.0\n\n[simulation]",
            &["model.parameters.k99:", "no such parameter"],
        ),
        (
            "[simulation]",
            "[model.parameters]\nc1 = -2.0\n\n[simulation]",
            &["model.parameters.c1:", "outside its bounds"],
        ),
        (
            "# [model.parameters]",
            "k = 3.0\n# [model.parameters]",
            &["model.k", "is not used with a model-language model"],
        ),
        (
            "[simulation]",
            "[forcing]\namplitude = 1.0\nperiod = 1.0\n\n[simulation]",
            &["forcing", "part of the model"],
        ),
    ];
    for (from, to, needles) in cases {
        let path = tmp.path().join("edited.toml");
        fs::write(&path, base.replacen(from, to, 1)).unwrap();
        assert_refused("simulate", &path, &tmp.path().join("out"), needles, to);
    }
    // An override naming no parameter is reported at its own line.
    let path = tmp.path().join("edited.toml");
    fs::write(
        &path,
        base.replacen(
            "[simulation]",
            "[model.parameters]\nk2 = 90.0\nk99 = 1.0\n\n[simulation]",
            1,
        ),
    )
    .unwrap();
    let o = htfid(&[
        "simulate",
        path.to_str().unwrap(),
        "--out",
        tmp.path().join("o9").to_str().unwrap(),
    ]);
    let line = line_of(&path, "k99 = 1.0");
    assert!(
        stderr(&o).contains(&format!("edited.toml:{line}:1: model.parameters")),
        "{}",
        stderr(&o)
    );
    // A mistake inside the model file is reported at its line and column there.
    let model = fs::read_to_string(models.join("two-dof.toml"))
        .unwrap()
        .replace("- c1 * v1 + f0", "- c1 * vv1 + f0");
    let model_path = tmp.path().join("broken-model.toml");
    fs::write(&model_path, &model).unwrap();
    let path = tmp.path().join("edited.toml");
    fs::write(
        &path,
        base.replace(
            &format!("{:?}", models.join("two-dof.toml").to_str().unwrap()),
            &format!("{:?}", model_path.to_str().unwrap()),
        ),
    )
    .unwrap();
    let o = htfid(&[
        "simulate",
        path.to_str().unwrap(),
        "--out",
        tmp.path().join("o2").to_str().unwrap(),
    ]);
    let err = stderr(&o);
    let line = line_of(&model_path, "vv1");
    assert!(
        err.contains(&format!("broken-model.toml:{line}:")) && err.contains("unknown name `vv1`"),
        "{err}"
    );
}

/// `htfid run` on every model-language config: the designed multisine's line estimates agree
/// with the exact theory of the same model, and the fit returns the model's own parameter
/// values. The record is noise-free, so what remains is the excitation's odd-order distortion
/// (sign reversal cancels the even orders): the tolerances are the measured errors with a
/// margin of about two.
#[test]
fn run_model_configs_recover_their_parameters() {
    let tmp = tempfile::tempdir().unwrap();
    // (parameter, true value, relative tolerance)
    type Truth<'a> = &'a [(&'a str, f64, f64)];
    let cases: &[(&str, Truth, f64)] = &[
        ("configs/bouncing-ball.toml", &[("e", 0.8, 1e-3)], 0.06),
        (
            "configs/flight-hopper.toml",
            &[("k", 1000.0, 1e-3), ("c", 10.0, 1e-3)],
            0.005,
        ),
        (
            "configs/two-dof.toml",
            &[("k1", 200.0, 1e-4), ("c1", 2.0, 1e-4)],
            0.05,
        ),
        (
            "configs/closed-loop-friction.toml",
            &[("Fc", 2.0, 1e-3), ("b", 1.0, 2e-3)],
            0.002,
        ),
    ];
    for (config, params, max_error) in cases {
        let out = tmp.path().join("run");
        htfid_ok(&[
            "run",
            config,
            "--out",
            out.to_str().unwrap(),
            "--force",
            "--no-plots",
        ]);
        let s = summary(&out);
        let fit = &s["fit"]["lines"];
        for (name, truth, rel) in *params {
            let v = fit[*name].as_f64().unwrap();
            assert!(
                (v / truth - 1.0).abs() < *rel,
                "{config}: {name} = {v}, truth {truth}"
            );
        }
        for (key, per) in s["errors"].as_object().unwrap() {
            for (n, e) in per.as_object().unwrap() {
                let max = e["max"].as_f64().unwrap();
                assert!(max < *max_error, "{config} {key} G_{n}: max error {max}");
            }
        }
    }
}

/// The paper's experiment with the hopper as a model file gives the built-in hopper's results:
/// the same fits (the two simulations differ by integrator round-off, about 1e-12 m, against a
/// response of 1e-5 m) and the same error table.
#[test]
fn paper_with_the_hopper_as_a_model_file_matches_the_built_in() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (tmp.path().join("model"), tmp.path().join("built-in"));
    htfid_ok(&[
        "run",
        "configs/paper-model.toml",
        "--out",
        a.to_str().unwrap(),
        "--no-plots",
    ]);
    htfid_ok(&[
        "run",
        "configs/paper.toml",
        "--out",
        b.to_str().unwrap(),
        "--no-plots",
    ]);
    let (sa, sb) = (summary(&a), summary(&b));
    for est in ["siddiqi", "multi"] {
        for p in ["k", "c"] {
            let (x, y) = (
                sa["fit"][est][p].as_f64().unwrap(),
                sb["fit"][est][p].as_f64().unwrap(),
            );
            assert!((x / y - 1.0).abs() < 1e-7, "{est} {p}: {x} vs {y}");
        }
        for n in -3..=3 {
            let key = n.to_string();
            let (x, y) = (
                sa["errors"][est][&key]["max"].as_f64().unwrap(),
                sb["errors"][est][&key]["max"].as_f64().unwrap(),
            );
            assert!((x / y - 1.0).abs() < 1e-4, "{est} G_{n}: {x} vs {y}");
        }
    }
    let (x, y) = (
        &sa["limit_cycle"]["state_phase0"],
        &sb["limit_cycle"]["state_phase0"],
    );
    for i in 0..2 {
        assert!((x[i].as_f64().unwrap() - y[i].as_f64().unwrap()).abs() < 1e-10);
    }
}

/// A record of an outside tester's own simulator (`tests/oracle/outsider_records`: written
/// from the docs alone): a sensor's offset of 2 mm and gain of 1.05 beside quadratic drag
/// (`tests/fixtures/outsider/p3-sensor-gain-drag/diagnose.toml`: `models/hopper.toml`, `k`
/// and `c` refitted). Both effects are named, each parameter within 10 % of the truth in its
/// `truth.json` (offset 0.002 m, gain 1.05, drag 10), and `k` and `c` come back to the
/// generator's 200 and 2 within 1 %.
#[test]
fn an_outsiders_drag_beside_a_sensor_gain_error_is_named() {
    let dir = root().join("tests/fixtures/outsider/p3-sensor-gain-drag");
    let truth = read_json(&dir.join("truth.json"));
    let tmp = tempfile::tempdir().unwrap();
    let d = diagnose_quietly(&dir.join("diagnose.toml"), &tmp.path().join("d"));
    let mut named = cause_names(&d);
    named.sort_unstable();
    assert_eq!(
        named,
        ["quadratic_drag(v)", "sensor_offset_gain"],
        "{}",
        d["causes"]
    );
    let within = |key: &str, want: f64, tol: f64| {
        let got = d["parameters"][key].as_f64().unwrap();
        assert!((got / want - 1.0).abs() < tol, "{key} {got} against {want}");
    };
    let effects = &truth["effects"];
    within("b_x", effects["sensor_offset"].as_f64().unwrap(), 0.1);
    let gain = effects["sensor_gain"].as_f64().unwrap();
    let g = d["parameters"]["g_x"].as_f64().unwrap();
    assert!(
        ((g - 1.0) / (gain - 1.0) - 1.0).abs() < 0.1,
        "g_x {g} against {gain}"
    );
    // The generator's drag `c2 |v| v` over the mass (1 kg): the model file's `drag_v`.
    within("drag_v", effects["c2"].as_f64().unwrap(), 0.1);
    within("k", truth["nominal_truth"]["k"].as_f64().unwrap(), 0.01);
    within("c", truth["nominal_truth"]["c"].as_f64().unwrap(), 0.01);
}

/// An outside tester's forced oscillator with a one-sided soft stop (a model file of theirs),
/// recorded by their own simulator with the stop's stiffness 1.5 times the model's, which is
/// not refitted (`tests/fixtures/outsider/p4-contact-stiffness`: `kc` 1500 N/m against the
/// model's 1000, the stop at `x = -d = -0.02` m, `m` = 1 kg). The library's hard stop below `x`
/// is exactly the missing stiffness: a second contact spring at the same place. It is named,
/// with its position within 0.1 mm of the model's contact (5 % of `d`, the depth scale of the
/// contact) and its stiffness within 10 % of the missing `(1500 - 1000) / m` = 500 (the
/// promise for a single effect), and `k` and `c` stay within 1 % of the model's values, which
/// the record shares.
#[test]
fn an_outsiders_stiffer_stop_is_named_as_the_missing_contact_stiffness() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("d");
    htfid_ok(&[
        "diagnose",
        "tests/fixtures/outsider/p4-contact-stiffness/diagnose.toml",
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    let d = diagnosis(&out);
    assert_eq!(d["cause"], "hard_stop(x, below)", "{}", d["candidates"]);
    let fitted = &d["extended"]["parameters"];
    let value = |name: &str| fitted[name].as_f64().unwrap();
    assert!((value("floor_x") + 0.02).abs() < 1e-4, "{fitted}");
    assert!((value("k_floor_x") / 500.0 - 1.0).abs() < 0.1, "{fitted}");
    assert!((value("k") / 100.0 - 1.0).abs() < 0.01, "{fitted}");
    assert!((value("c") / 2.0 - 1.0).abs() < 0.01, "{fitted}");
}

/// A record of the independent truth generator (90 s of the paper's protocol, 2e-6 m of noise)
/// whose damper is 11.5 % stronger than configured and whose switch sits at -0.0346 m/s, through
/// `htfid diagnose` with the hopper's model file: the moved switch and, beside it, the
/// parameter error are named in `causes`, with `c` as fitted beside the switch within 1 % of
/// the truth's 2.2305 in `parameters_beside`, and the terminal and the report say so.
#[test]
fn a_parameter_error_beside_an_effect_is_named_with_it_through_the_command() {
    use htfid_truth::{generate, Effect, Noise, ParameterErrors, Scenario};
    let tmp = tempfile::tempdir().unwrap();
    let scenario = Scenario {
        effects: vec![Effect::SwitchThreshold { v_th: -0.03457 }],
        parameter_errors: ParameterErrors {
            c: 0.11524,
            ..ParameterErrors::default()
        },
        noise: Noise {
            sigma_x: 2e-6,
            sigma_f: 0.0,
        },
        record_s: 90.0,
        ..Scenario::default()
    };
    let r = generate(&scenario).unwrap();
    let mut csv = String::from("t,f,x\n");
    for ((t, f), x) in r.t.iter().zip(&r.f).zip(&r.x) {
        csv.push_str(&format!("{t},{f},{x}\n"));
    }
    fs::write(tmp.path().join("record.csv"), csv).unwrap();
    let config = fs::read_to_string(root().join("configs/diagnose-hopper.toml"))
        .unwrap()
        .replace("../data/hopper-protocol.csv", "record.csv")
        .replace(
            "../models/hopper.toml",
            &root().join("models/hopper.toml").display().to_string(),
        );
    assert!(config.contains("file = \"record.csv\""), "{config}");
    fs::write(tmp.path().join("diagnose.toml"), config).unwrap();
    let out = tmp.path().join("d");
    let o = htfid(&[
        "diagnose",
        tmp.path().join("diagnose.toml").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let d = diagnosis(&out);
    let mut named: Vec<&str> = d["causes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["effect"].as_str().unwrap())
        .collect();
    named.sort_unstable();
    assert_eq!(
        named,
        ["guard_shift(v)", "parameter_error"],
        "{}",
        d["candidates"]
    );
    let beside = &d["parameters_beside"];
    assert_eq!(beside["named"], true, "{beside}");
    let c = beside["moved"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["name"] == "c")
        .unwrap_or_else(|| panic!("c not moved: {beside}"));
    let c = c["fitted"].as_f64().unwrap();
    assert!((c / 2.23048 - 1.0).abs() < 0.01, "c = {c}");
    let terminal = String::from_utf8_lossy(&o.stdout);
    assert!(
        terminal.contains("parameter error") && terminal.contains("beside the effects"),
        "{terminal}"
    );
    let report = fs::read_to_string(out.join("report.md")).unwrap();
    assert!(
        report.contains("**The configured parameters are off as well** (`parameter_error`)"),
        "{report}"
    );
}

/// The same record with the hard stop left out of the library (`[diagnose] effects`): no
/// library effect is then that stop, so none may be named; the term search outside the
/// library proposes terms up to its cap of three and says so (it said "stopped because ."
/// once), and the advice names the parameters held at their configured values, `kc` among
/// them.
#[test]
fn an_outsiders_stiffer_stop_outside_the_library_is_not_claimed_and_the_term_search_says_why_it_stopped(
) {
    let tmp = tempfile::tempdir().unwrap();
    let fixture = root().join("tests/fixtures/outsider/p4-contact-stiffness");
    for file in ["contact.toml", "record.csv"] {
        fs::copy(fixture.join(file), tmp.path().join(file)).unwrap();
    }
    let config = fs::read_to_string(fixture.join("diagnose.toml")).unwrap();
    let config = config.replace(
        "[diagnose]\n",
        "[diagnose]\neffects = [\"input_offset\", \"input_delay\", \"actuator_lag\", \
         \"sensor_offset_gain\", \"sensor_lag\", \"quadratic_drag\", \"nonlinear_stiffness\", \
         \"mode_damping\", \"guard_shift\", \"coulomb_friction\"]\n",
    );
    assert!(config.contains("effects = ["), "{config}");
    fs::write(tmp.path().join("diagnose.toml"), config).unwrap();
    let out = tmp.path().join("d");
    htfid_ok(&[
        "diagnose",
        tmp.path().join("diagnose.toml").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    let d = diagnosis(&out);
    let cause = d["cause"].as_str().unwrap();
    assert!(
        ["unexplained", "ambiguous"].contains(&cause),
        "a library effect claimed: {cause}"
    );
    let stopped = d["discovered"]["stopped"]
        .as_str()
        .unwrap_or_else(|| panic!("no terms proposed: {}", d["term_search"]));
    assert!(stopped.contains("cap of 3 terms"), "stopped: {stopped:?}");
    let report = fs::read_to_string(out.join("report.md")).unwrap();
    assert!(!report.contains("because ."), "{report}");
    // The stiffness that is off is held at its configured value: the advice names it.
    if cause == "unexplained" {
        assert!(
            report.contains("free more of the model's parameters") && report.contains("`kc`"),
            "{report}"
        );
    }
}

/// The same outsider's record with its output's sign flipped, and in centimetres against the
/// model's metres: refused at once (it ran for over ten minutes with the flipped sign), naming
/// the check, exit 1, nothing written.
#[test]
fn a_flipped_or_rescaled_output_against_a_model_file_is_refused_at_once() {
    let tmp = tempfile::tempdir().unwrap();
    let fixture = root().join("tests/fixtures/outsider/p4-contact-stiffness");
    fs::copy(
        fixture.join("contact.toml"),
        tmp.path().join("contact.toml"),
    )
    .unwrap();
    let config = fs::read_to_string(fixture.join("diagnose.toml")).unwrap();
    fs::write(tmp.path().join("diagnose.toml"), config).unwrap();
    let text = fs::read_to_string(fixture.join("record.csv")).unwrap();
    for (factor, check) in [(-1.0, "sign:"), (100.0, "units:")] {
        let mut lines = text.lines();
        let mut edited = vec![lines.next().unwrap().to_string()];
        for line in lines {
            let mut v: Vec<f64> = line.split(',').map(|c| c.parse().unwrap()).collect();
            v[2] *= factor;
            edited.push(format!("{},{},{}", v[0], v[1], v[2]));
        }
        fs::write(tmp.path().join("record.csv"), edited.join("\n")).unwrap();
        let out = tmp.path().join("d");
        let o = htfid(&[
            "diagnose",
            tmp.path().join("diagnose.toml").to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--quiet",
        ]);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert!(stderr(&o).contains(check), "{}", stderr(&o));
        assert!(stderr(&o).contains("data.outputs"), "{}", stderr(&o));
        assert!(!out.exists(), "nothing written");
    }
}

/// A column the config names but the file lacks is reported at the config line that names it,
/// as every other config error is, with the columns the file has.
#[test]
fn a_missing_column_is_named_at_its_config_line() {
    let tmp = tempfile::tempdir().unwrap();
    let fixture = root().join("tests/fixtures/outsider/p4-contact-stiffness");
    for f in ["contact.toml", "record.csv"] {
        fs::copy(fixture.join(f), tmp.path().join(f)).unwrap();
    }
    let config = fs::read_to_string(fixture.join("diagnose.toml")).unwrap();
    for (from, to, key) in [
        ("input = \"u\"", "input = \"force\"", "data.input"),
        ("outputs = [\"x\"]", "outputs = [\"y\"]", "data.output"),
    ] {
        let path = tmp.path().join("diagnose.toml");
        fs::write(&path, config.replace(from, to)).unwrap();
        let line = line_of(&path, to);
        let o = htfid(&[
            "diagnose",
            path.to_str().unwrap(),
            "--out",
            tmp.path().join("d").to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(1));
        let e = stderr(&o);
        assert!(e.contains(&format!("diagnose.toml:{line}:1: {key}")), "{e}");
        assert!(e.contains("available columns: \"t\", \"u\", \"x\""), "{e}");
    }
}

/// A `[forcing]` table beside a model file is refused with the reason (the forcing is part of
/// the model), at its line, not as an unknown field.
#[test]
fn a_forcing_table_beside_a_model_file_is_refused_with_the_reason() {
    let tmp = tempfile::tempdir().unwrap();
    let fixture = root().join("tests/fixtures/outsider/p4-contact-stiffness");
    let config = fs::read_to_string(fixture.join("diagnose.toml")).unwrap();
    let path = tmp.path().join("diagnose.toml");
    fs::write(&path, format!("{config}\n[forcing]\nperiod = 1.0\n")).unwrap();
    let line = line_of(&path, "[forcing]");
    let out = tmp.path().join("d");
    let o = htfid(&[
        "diagnose",
        path.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(e.contains(&format!("diagnose.toml:{line}:")), "{e}");
    assert!(e.contains("forcing: is not used with a model file"), "{e}");
    assert!(!out.exists());
}

/// The paper's experiment simulated by `htfid simulate configs/paper.toml` into `DIR/sim`
/// (`timeseries.csv` there), for the estimate tests to read.
fn paper_record(dir: &Path) -> PathBuf {
    let sim = dir.join("sim");
    htfid_ok(&[
        "simulate",
        "configs/paper.toml",
        "--out",
        sim.to_str().unwrap(),
        "--quiet",
    ]);
    sim
}

/// Writes `toml` as `DIR/estimate.toml` and runs `htfid estimate` on it into `DIR/est`.
fn estimate_with(dir: &Path, toml: &str) -> (PathBuf, Output) {
    let config = dir.join("estimate.toml");
    fs::write(&config, toml).unwrap();
    let out = dir.join("est");
    let o = htfid(&[
        "estimate",
        config.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    (out, o)
}

/// The improved design's multisine excites the input frequencies that `G_-3 .. G_3` need over
/// 1-40 rad/s, up to about 40 + 3 wp = 59 rad/s. Estimated over 1-100 rad/s, `G_-3` at an
/// output frequency `w` reads the input at `w + 3 wp`, unexcited above `b - 3 wp` (`b` the
/// excited band's top): the summary names that range, from within three frequency bins of
/// where it must start (the check's margin of one bin, a grid step, rounding) up to the band's
/// top, and a note says the estimates there rest on regularisation; every range listed, of any
/// harmonic, reads input frequencies outside the excited band.
#[test]
fn estimate_names_where_a_harmonic_reads_unexcited_input_frequencies() {
    let tmp = tempfile::tempdir().unwrap();
    let sim = tmp.path().join("sim");
    htfid_ok(&[
        "simulate",
        "configs/paper-improved.toml",
        "--out",
        sim.to_str().unwrap(),
    ]);
    let (out, o) = estimate_with(
        tmp.path(),
        "[data]\nfile = \"sim/timeseries.csv\"\ntime = \"t\"\ninput = \"f\"\noutputs = [\"x\"]\n\
         start = 30.0\n\n[period]\nvalue = 1.0\n\n[estimation]\nomega_min = 1.0\nomega_max = 100.0\n",
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let s = summary(&out);
    let band = s["checks"]["excited_band"].as_array().unwrap();
    let (a, b) = (band[0].as_f64().unwrap(), band[1].as_f64().unwrap());
    assert!((55.0..65.0).contains(&b), "excited band {a}-{b}");
    let wp = 2.0 * std::f64::consts::PI;
    let bin = s["record"]["frequency_resolution"].as_f64().unwrap();
    let unexcited = s["checks"]["unexcited"].as_array().unwrap();
    let minus3 = unexcited
        .iter()
        .find(|u| u["n"].as_i64() == Some(-3))
        .unwrap_or_else(|| panic!("G_-3 not named: {unexcited:?}"));
    let range = minus3["omega"][0].as_array().unwrap();
    let (from, to) = (range[0].as_f64().unwrap(), range[1].as_f64().unwrap());
    assert!(
        (from - (b - 3.0 * wp)).abs() <= 3.0 * bin,
        "G_-3 from {from}, b {b}"
    );
    assert!(to >= 100.0 - 2.0 * bin, "G_-3 to {to}");
    for u in unexcited {
        let n = u["n"].as_f64().unwrap();
        for r in u["omega"].as_array().unwrap() {
            for w in [r[0].as_f64().unwrap(), r[1].as_f64().unwrap()] {
                let input = (w - n * wp).abs();
                assert!(
                    input < a - bin || input > b + bin,
                    "G_{n} at {w}: input {input}"
                );
            }
        }
    }
    let notes = s["checks"]["notes"].as_array().unwrap();
    assert!(
        notes.iter().any(|n| {
            let t = n.as_str().unwrap();
            t.contains("G_-3 at") && t.contains("outside the excited band")
        }),
        "{notes:?}"
    );
}

/// `htfid estimate` on a record of the paper's experiment made by `htfid simulate`: the period
/// is recovered from the position alone, and the model-free estimate of `G_0` agrees with the
/// exact theory of the hopper (computed by `htfid theory`, the closed-form piecewise HTF) in the
/// band the chirps excite well, to the accuracy the paper run reports for the same estimator
/// with the simulated orbit subtracted (0.7 % of max |G_0|; 2 % allowed).
#[test]
fn estimate_from_data_alone_matches_the_theory() {
    let tmp = tempfile::tempdir().unwrap();
    paper_record(tmp.path());
    let (out, o) = estimate_with(
        tmp.path(),
        "[data]\nfile = \"sim/timeseries.csv\"\ntime = \"t\"\ninput = \"f\"\noutputs = [\"x\", \"xd\"]\n\
         start = 30.0\n\n[period]\nvalue = \"estimate\"\n\n[estimation]\nomega_min = 1.0\nomega_max = 40.0\n",
    );
    assert!(o.status.success(), "{}", stderr(&o));
    // On the terminal: the period and where it came from, and a table per output.
    let text = stdout(&o);
    assert!(
        text.lines().any(|l| l.trim_start().starts_with("period")
            && l.trim_end()
                .ends_with("1.000 s (estimated), periodic share of the output 100 %")),
        "{text}"
    );
    assert!(
        text.contains("HTF of x ") && text.contains("HTF of xd "),
        "{text}"
    );
    let s = summary(&out);
    let period = s["period"]["estimated"].as_f64().unwrap();
    assert!((period - 1.0).abs() < 1e-5, "{period}");
    assert_eq!(s["period"]["value"].as_f64(), Some(1.0));
    assert_eq!(s["record"]["periods"].as_u64(), Some(271));
    assert!(out.join("estimate_siddiqi_xd.csv").exists());

    let rows: Vec<Vec<f64>> = fs::read_to_string(out.join("estimate_siddiqi.csv"))
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .filter(|r: &Vec<f64>| r[1] == 0.0 && r[0] >= 5.0 && r[0] <= 30.0)
        .collect();
    let omegas: Vec<String> = rows
        .iter()
        .step_by(25)
        .map(|r| format!("{:.17e}", r[0]))
        .collect();
    let th = tmp.path().join("theory");
    htfid_ok(&[
        "theory",
        "configs/paper.toml",
        "--omega",
        &omegas.join(","),
        "--out",
        th.to_str().unwrap(),
        "--no-plots",
    ]);
    let theory = theory_rows(&th.join("theory.csv"));
    let g0: Vec<&(f64, i32, f64, f64)> = theory.iter().filter(|r| r.1 == 0).collect();
    let scale = g0.iter().map(|r| r.2.hypot(r.3)).fold(0.0, f64::max);
    for (r, t) in rows.iter().step_by(25).zip(&g0) {
        assert!((r[0] - t.0).abs() < 1e-9 * t.0);
        let err = (r[2] - t.2).hypot(r[3] - t.3);
        assert!(err < 0.02 * scale, "w {}: {err:e} of {scale:e}", r[0]);
    }
}

/// `configs/diagnose-hopper.toml` with its data and model paths absolute, for a copy written
/// elsewhere.
fn diagnose_hopper_config() -> String {
    fs::read_to_string(root().join("configs/diagnose-hopper.toml"))
        .unwrap()
        .replace(
            "\"../data/",
            &format!("\"{}/", root().join("data").display()),
        )
        .replace(
            "\"../models/",
            &format!("\"{}/", root().join("models").display()),
        )
}

/// A user's own candidate, `[[diagnose.terms]]`: a term on a named state equation in a named
/// mode, with its parameter's start. Alone (`effects = []`), the flight damping written by
/// hand is found with the same coefficient; a mistake in a term names its line and key.
#[test]
fn a_users_own_term_is_a_candidate() {
    let tmp = tempfile::tempdir().unwrap();
    let config = diagnose_hopper_config();
    let with_term = |term: &str| {
        format!(
            "{config}\neffects = []\n\n[[diagnose.terms]]\nname = \"air_in_flight\"\nstate = \"v\"\n\
             mode = \"free\"\nterm = \"{term}\"\nparameters = {{ cf = 0.0 }}\n"
        )
    };
    let d = diagnose_text(tmp.path(), "terms", &with_term("-cf*v"));
    let path = tmp.path().join("terms.toml");
    assert_eq!(d["cause"], "air_in_flight", "{}", d["candidates"]);
    let cf = d["extended"]["parameters"]["cf"].as_f64().unwrap();
    assert!((cf / 0.2 - 1.0).abs() < 0.05, "{cf}");

    let text = with_term("-cf*w");
    let line = text
        .lines()
        .position(|l| l.starts_with("term = \"-cf*w\""))
        .unwrap()
        + 1;
    fs::write(&path, text).unwrap();
    let o = htfid(&[
        "diagnose",
        path.to_str().unwrap(),
        "--out",
        tmp.path().join("bad").to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(
        err.contains(&format!("terms.toml:{line}:"))
            && err.contains("diagnose.terms[0].term")
            && err.contains("unknown name `w`"),
        "{err}"
    );
    // A state, mode or guard the model lacks, or a parameter name it already has, is named at
    // its own key.
    for (from, to, needle) in [
        (
            "state = \"v\"",
            "state = \"w\"",
            "diagnose.terms[0].state: `w` is not a state",
        ),
        (
            "mode = \"free\"",
            "mode = \"flight\"",
            "diagnose.terms[0].mode: no mode `flight`",
        ),
        (
            "parameters = { cf = 0.0 }",
            "parameters = { k = 0.0 }",
            "diagnose.terms[0].parameters: `k` is already a name of the model",
        ),
    ] {
        // In the appended term, not in the config's commented example.
        let mut text = with_term("-cf*v");
        let at = text.rfind(from).unwrap();
        text.replace_range(at..at + from.len(), to);
        fs::write(&path, text).unwrap();
        let o = htfid(&[
            "diagnose",
            path.to_str().unwrap(),
            "--out",
            tmp.path().join("bad").to_str().unwrap(),
        ]);
        assert!(!o.status.success());
        assert!(stderr(&o).contains(needle), "{}", stderr(&o));
    }
}

/// The diagnosis on the terminal: cause, gain, refitted parameters with standard errors and
/// units, and where the files are, as in diagnosis.json.
#[test]
fn diagnose_prints_the_cause_and_the_gain() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("d");
    let o = htfid(&[
        "diagnose",
        "configs/diagnose-hopper.toml",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    let d: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(out.join("diagnosis.json")).unwrap()).unwrap();
    let cause = d["cause"].as_str().unwrap();
    assert!(
        text.lines()
            .any(|l| l.trim_start().starts_with("cause") && l.trim_end().ends_with(cause)),
        "{text}"
    );
    // The gain line shows the percentage to 3 significant digits: within half a unit of the
    // last digit of the JSON value.
    let gain = 100.0 * d["gain"].as_f64().unwrap();
    let shown: f64 = text
        .lines()
        .find_map(|l| l.trim_start().strip_prefix("gain"))
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no gain line: {text}"));
    let half_digit = 0.5 * 10f64.powf(gain.abs().log10().floor() - 2.0);
    assert!((shown - gain).abs() <= half_digit * 1.001, "{gain}: {text}");
    for p in d["refit_parameters"].as_array().unwrap() {
        let name = p["name"].as_str().unwrap();
        assert!(
            text.lines()
                .any(|l| l.contains(&format!("{name} = ")) && l.contains(" ± ")),
            "{name}: {text}"
        );
    }
    assert!(text.contains(" N/m "), "k in N/m: {text}");
    assert!(
        text.contains(&format!(
            "{}/ ({} files)",
            out.display(),
            result_files(&out).len()
        )),
        "{text}"
    );
}

/// Estimate configs are checked like the others, and a config of another kind is explained.
#[test]
fn estimate_config_errors_are_clear() {
    let tmp = tempfile::tempdir().unwrap();
    // The shipped config runs, and its record's period is found.
    let good = tmp.path().join("good");
    htfid_ok(&[
        "estimate",
        "configs/estimate-hopper.toml",
        "--out",
        good.to_str().unwrap(),
    ]);
    let period = summary(&good)["period"]["estimated"].as_f64().unwrap();
    assert!((period - 1.0).abs() < 1e-5, "{period}");
    let base = fs::read_to_string(root().join("configs/estimate-hopper.toml")).unwrap();
    let base = base.replace(
        "file = \"../data/hopper-protocol.csv\"",
        &format!(
            "file = {:?}",
            root().join("data/hopper-protocol.csv").to_str().unwrap()
        ),
    );
    for (from, to, needle) in [
        (
            "outputs = [\"x\"]",
            "outputs = [\"f\"]",
            "data.outputs: \"f\" is also the input column",
        ),
        (
            "outputs = [\"x\"]",
            "outputs = []",
            "data.outputs: must name at least one output",
        ),
        (
            "value = \"estimate\"",
            "value = -1.0",
            "period.value: must be a period > 0",
        ),
        ("outputs = [\"x\"]", "outputs = [\"y\"]", "y"),
        (
            "time = \"t\"",
            "time = \"t\"\nsample_rate = 100.0",
            "exactly one of `time`",
        ),
    ] {
        let path = tmp.path().join("e.toml");
        fs::write(&path, base.replacen(from, to, 1)).unwrap();
        let out = tmp.path().join("out");
        let o = htfid(&[
            "estimate",
            path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(!o.status.success(), "{to}");
        assert!(stderr(&o).contains(needle), "{to}: {}", stderr(&o));
        assert!(!out.exists() || fs::read_dir(&out).unwrap().next().is_none());
    }
    let o = htfid(&["estimate", "configs/paper.toml"]);
    assert!(stderr(&o).contains("`htfid estimate` needs a config with [data] and [period]"));
    let o = htfid(&["run", "configs/estimate-hopper.toml"]);
    assert!(
        stderr(&o).contains("run it with `htfid estimate`"),
        "{}",
        stderr(&o)
    );
}

/// Times printed with few digits (as float32 timestamps are) break the default 1e-6 step
/// tolerance: the message names the key that allows them, and with that key the record is read
/// and diagnosed.
#[test]
fn coarse_timestamps_are_allowed_by_data_time_tolerance() {
    let tmp = tempfile::tempdir().unwrap();
    let text = fs::read_to_string(root().join("data/hopper-protocol.csv")).unwrap();
    let mut out = String::new();
    for line in text.lines() {
        match line.split_once(',') {
            Some((t, rest)) if t.parse::<f64>().is_ok() => {
                let t: f64 = t.parse().unwrap();
                out.push_str(&format!("{:.8e},{rest}\n", t as f32));
            }
            _ => {
                out.push_str(line);
                out.push('\n');
            }
        }
    }
    let data = tmp.path().join("coarse.csv");
    fs::write(&data, out).unwrap();
    let config = tmp.path().join("d.toml");
    let base = diagnose_hopper_config();
    fs::write(&config, &base).unwrap();
    let o = htfid(&[
        "diagnose",
        config.to_str().unwrap(),
        "--data",
        data.to_str().unwrap(),
        "--out",
        tmp.path().join("o1").to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("data.time_tolerance"), "{}", stderr(&o));
    fs::write(
        &config,
        base.replacen(
            "outputs = [\"x\"]",
            "outputs = [\"x\"]\ntime_tolerance = 1e-2",
            1,
        ),
    )
    .unwrap();
    htfid_ok(&[
        "diagnose",
        config.to_str().unwrap(),
        "--data",
        data.to_str().unwrap(),
        "--out",
        tmp.path().join("o2").to_str().unwrap(),
    ]);
}

/// `htfid diagnose` on every shipped model: a record simulated with one parameter 3 % off
/// (and measurement noise) is diagnosed against the model as shipped; the configured
/// simulation is the baseline and the shifted parameter is named and recovered.
#[test]
fn diagnose_names_a_shifted_parameter_of_every_model() {
    let tmp = tempfile::tempdir().unwrap();
    let models = root().join("models");
    // (model, parameter, shipped value, sample rate, chirp end Hz, amplitude, noise, outputs)
    type Case<'a> = (&'a str, &'a str, f64, f64, f64, f64, f64, &'a [&'a str]);
    let cases: &[Case] = &[
        ("bouncing-ball", "e", 0.8, 400.0, 10.0, 0.3, 1e-6, &["y"]),
        ("flight-hopper", "c", 10.0, 400.0, 8.0, 2.0, 1e-6, &["y"]),
        ("two-dof", "k1", 200.0, 200.0, 6.0, 0.5, 1e-6, &["x1", "x2"]),
        (
            "closed-loop-friction",
            "Fc",
            2.0,
            200.0,
            8.0,
            0.002,
            1e-7,
            &["x"],
        ),
    ];
    for &(model, param, value, rate, f_end, amplitude, noise, outputs) in cases {
        let file = models.join(format!("{model}.toml"));
        let truth = value * 1.03;
        let experiment = tmp.path().join("experiment.toml");
        fs::write(
            &experiment,
            format!(
                "[model]\nfile = {file:?}\n\n[model.parameters]\n{param} = {truth}\n\n\
                 [simulation]\nsettle_periods = 10\nsample_rate = {rate}\n\n\
                 [excitation]\nkind = \"chirp_train\"\nwaveform = \"linear\"\nf_start_hz = 0.2\n\
                 f_end_hz = {f_end}\nduration = 20.0\namplitude = {amplitude}\ncopies = 1\n\n\
                 [noise]\noutput_std = {noise}\nseed = 3\n"
            ),
        )
        .unwrap();
        let sim = tmp.path().join(format!("sim-{model}"));
        htfid_ok(&[
            "simulate",
            experiment.to_str().unwrap(),
            "--out",
            sim.to_str().unwrap(),
        ]);
        let diagnosis = tmp.path().join("diagnose.toml");
        let list: Vec<String> = outputs.iter().map(|o| format!("{o:?}")).collect();
        fs::write(
            &diagnosis,
            format!(
                "[data]\nfile = {:?}\ntime = \"t\"\ninput = \"u\"\noutputs = [{}]\n\n\
                 [model]\nfile = {file:?}\nfree = [\"{param}\"]\n",
                sim.join("timeseries.csv"),
                list.join(", ")
            ),
        )
        .unwrap();
        let out = tmp.path().join(format!("diag-{model}"));
        htfid_ok(&[
            "diagnose",
            diagnosis.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        let d: serde_json::Value =
            serde_json::from_str(&fs::read_to_string(out.join("diagnosis.json")).unwrap()).unwrap();
        assert_eq!(d["cause"], "parameter_error", "{model}: {d}");
        let fitted = d["refit_parameters"][0]["fitted"].as_f64().unwrap();
        assert!(
            (fitted / truth - 1.0).abs() < 2e-3,
            "{model}: {param} = {fitted}, truth {truth}"
        );
        // The evidence figures (every shipped model has a forcing period: the orbit too),
        // and the held-out error step by step: configured, the refit, the final level, each
        // the held-out score reported beside it (mean over the outputs).
        for figure in [
            "residual_time",
            "residual_spectrum",
            "orbit",
            "error_waterfall",
        ] {
            for ext in ["svg", "png"] {
                assert!(
                    out.join(format!("{figure}.{ext}")).is_file(),
                    "{model}: {figure}.{ext}"
                );
            }
        }
        // The binned residual acceleration: for every output that reads a position state,
        // which every shipped model's outputs do (a position whose derivative is a velocity
        // state), and drawn.
        let mut binned: Vec<&str> = d["residual_bins"]["by_output"]
            .as_object()
            .map(|m| m.keys().map(String::as_str).collect())
            .unwrap_or_default();
        binned.sort_unstable();
        let mut positions = outputs.to_vec();
        positions.sort_unstable();
        assert_eq!(binned, positions, "{model}");
        assert!(out.join("residual_bins.png").is_file(), "{model}");
        let mean = |v: &serde_json::Value| {
            let a = v.as_array().unwrap();
            a.iter().map(|x| x.as_f64().unwrap()).sum::<f64>() / a.len() as f64
        };
        let steps = d["error_waterfall"].as_array().unwrap();
        let names: Vec<&str> = steps.iter().map(|s| s["step"].as_str().unwrap()).collect();
        assert_eq!(names, ["configured", "refitted", "final"], "{model}");
        let configured = mean(&d["configured"]["nrmse_validation"]);
        let refitted = mean(&d["refitted"]["nrmse_validation"]);
        // Equal up to the rounding of the means (1e-12 relative; one unit in the last place).
        let same = |step: usize, key: &str, v: f64| {
            let w = steps[step][key].as_f64().unwrap();
            assert!(
                (w / v - 1.0).abs() < 1e-12,
                "{model}: step {step} {key} {w} against {v}"
            );
        };
        same(0, "after", configured);
        same(1, "before", configured);
        same(1, "after", refitted);
        same(2, "after", refitted);
        assert!(
            refitted < configured,
            "{model}: {refitted} against {configured}"
        );
    }
}

/// Values that parse but mean nothing are refused with the key named: a plotted harmonic that
/// is not computed, the output column equal to the input column, a test range inside the fit
/// range.
#[test]
fn meaningless_values_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let paper = fs::read_to_string(root().join("configs/paper.toml")).unwrap();
    let path = tmp.path().join("p.toml");
    fs::write(
        &path,
        paper.replacen("points = 400", "points = 400\nplot_harmonics = [9]", 1),
    )
    .unwrap();
    let o = htfid(&[
        "theory",
        path.to_str().unwrap(),
        "--out",
        tmp.path().join("o").to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("theory.plot_harmonics: harmonic 9 is not among theory.harmonics"),
        "{}",
        stderr(&o)
    );
    // An estimation band whose harmonics reach past Nyquist is refused before simulating,
    // at its line: 300 rad/s + 3 * 2 pi rad/s = 318.8 rad/s > pi * 100 Hz = 314.2 rad/s.
    let edited = paper.replacen("omega_max = 40.0", "omega_max = 300.0", 1);
    let line = edited
        .lines()
        .position(|l| l.starts_with("omega_max = 300.0"))
        .unwrap()
        + 1;
    fs::write(&path, edited).unwrap();
    let out = tmp.path().join("nyquist");
    let o = htfid(&[
        "run",
        path.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(
        err.contains(&format!("p.toml:{line}:"))
            && err.contains("estimation.omega_max")
            && err.contains("Nyquist frequency 314.2 rad/s"),
        "{err}"
    );
    assert!(
        !err.contains("[htfid] simulate"),
        "refused before simulating: {err}"
    );
    assert!(!out.exists());
    // A smoothness weight so large that the penalty drowns the data is refused at its line, for
    // both the simulated and the measured pipeline (the data path is absolute for the copy).
    let estimate_config = fs::read_to_string(root().join("configs/estimate-hopper.toml"))
        .unwrap()
        .replace(
            "\"../data/",
            &format!("\"{}/", root().join("data").display()),
        );
    for (config, command) in [(&paper, "run"), (&estimate_config, "estimate")] {
        let edited = config.replacen("alpha = 1.0", "alpha = 9223372036854775807", 1);
        let line = edited
            .lines()
            .position(|l| l.starts_with("alpha = 9223372036854775807"))
            .unwrap()
            + 1;
        fs::write(&path, edited).unwrap();
        let out = tmp.path().join(format!("alpha-{command}"));
        let o = htfid(&[
            command,
            path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(!o.status.success());
        let err = stderr(&o);
        assert!(
            err.contains(&format!("p.toml:{line}:"))
                && err.contains("estimation.alpha")
                && err.contains("must be a number in [0, 1e6]"),
            "{command}: {err}"
        );
        assert!(!out.exists());
    }
    // An output that is the input column is refused at its key.
    let diag = diagnose_hopper_config();
    fs::write(
        &path,
        diag.replacen("outputs = [\"x\"]", "outputs = [\"f\"]", 1),
    )
    .unwrap();
    let o = htfid(&[
        "diagnose",
        path.to_str().unwrap(),
        "--out",
        tmp.path().join("o").to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("data.outputs: \"f\" is also the input column"),
        "{}",
        stderr(&o)
    );
}

/// Separate estimation and validation files: the validation record (another experiment on the
/// same system) is held out whole, and the shifted parameter is still found.
#[test]
fn diagnose_with_a_separate_validation_file() {
    let tmp = tempfile::tempdir().unwrap();
    let file = root().join("models/two-dof.toml");
    let mut records = Vec::new();
    for (i, (f_end, seed)) in [(6.0, 3), (4.0, 4)].into_iter().enumerate() {
        let experiment = tmp.path().join(format!("e{i}.toml"));
        fs::write(
            &experiment,
            format!(
                "[model]\nfile = {file:?}\n\n[model.parameters]\nk1 = 206.0\n\n\
                 [simulation]\nsettle_periods = 10\nsample_rate = 200.0\n\n\
                 [excitation]\nkind = \"chirp_train\"\nwaveform = \"linear\"\nf_start_hz = 0.2\n\
                 f_end_hz = {f_end}\nduration = 20.0\namplitude = 0.5\ncopies = 1\n\n\
                 [noise]\noutput_std = 1e-6\nseed = {seed}\n"
            ),
        )
        .unwrap();
        let sim = tmp.path().join(format!("sim{i}"));
        htfid_ok(&[
            "simulate",
            experiment.to_str().unwrap(),
            "--out",
            sim.to_str().unwrap(),
        ]);
        records.push(sim.join("timeseries.csv"));
    }
    let diagnosis = tmp.path().join("d.toml");
    fs::write(
        &diagnosis,
        format!(
            "[data]\nfile = {:?}\nvalidation = {:?}\ntime = \"t\"\ninput = \"u\"\n\
             outputs = [\"x1\", \"x2\"]\n\n[model]\nfile = {file:?}\nfree = [\"k1\", \"c1\"]\n",
            records[0], records[1]
        ),
    )
    .unwrap();
    let out = tmp.path().join("d");
    htfid_ok(&[
        "diagnose",
        diagnosis.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let d: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(out.join("diagnosis.json")).unwrap()).unwrap();
    assert_eq!(d["cause"], "parameter_error", "{d}");
    let k1 = d["refit_parameters"][0]["fitted"].as_f64().unwrap();
    assert!((k1 / 206.0 - 1.0).abs() < 2e-3, "{k1}");
    assert!(d["validation_data"]
        .as_str()
        .unwrap()
        .ends_with("timeseries.csv"));
    let report = fs::read_to_string(out.join("report.md")).unwrap();
    assert!(report.contains("the separate record"), "{report}");
}

/// A sample rate in the wrong unit (1e300 Hz) made the diagnosis panic in a linear solve; now
/// the record's time scale is checked against the model's forcing period first, with a located
/// hint.
#[test]
fn a_record_on_the_wrong_time_scale_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let config = tmp.path().join("d.toml");
    let text = diagnose_hopper_config().replacen("time = \"t\"", "sample_rate = 1e300", 1);
    fs::write(&config, text).unwrap();
    let out = tmp.path().join("o");
    let o = htfid(&[
        "diagnose",
        config.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("shorter than the forcing period of model `hopper`"),
        "{}",
        stderr(&o)
    );
    assert!(stderr(&o).contains("data.sample_rate"), "{}", stderr(&o));
    assert!(!out.exists());
}

/// Every threshold of the diagnosis is a config key: a value out of range is refused at its
/// line with the key named, and a value in range reaches the decision (a `resolution` above
/// the refit's error claims no effect) and is echoed under `options` in `diagnosis.json`.
#[test]
fn every_decision_threshold_is_a_config_key() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("d.toml");
    let base = diagnose_hopper_config();
    let refused: &[(&str, &str)] = &[
        (
            "noise_band = [0.9, 0.5]",
            "diagnose.noise_band: must be two fractions",
        ),
        (
            "noise_band = [0.6]",
            "diagnose.noise_band: must be two fractions",
        ),
        (
            "noise_band = [0.5, 1.5]",
            "diagnose.noise_band: must be two fractions",
        ),
        ("resolution = -1", "diagnose.resolution: must be >= 0"),
        (
            "input_noise_flatness = 0.5",
            "diagnose.input_noise_flatness: must be >= 1",
        ),
        (
            "second_effect_floor_ratio = 0.5",
            "diagnose.second_effect_floor_ratio: must be >= 1",
        ),
        ("rtol = 0.1", "diagnose.rtol: must be in [1e-14, 1e-3]"),
        ("fit_tolerance = 0", "diagnose.fit_tolerance: must be > 0"),
        (
            "max_iterations = 0",
            "diagnose.max_iterations: must be a whole number",
        ),
        (
            "max_iterations = 2.5",
            "diagnose.max_iterations: must be a whole number",
        ),
        (
            "candidate_max_iterations = 1.5",
            "diagnose.candidate_max_iterations: must be a whole number",
        ),
    ];
    for (line, needle) in refused {
        let text = base.replacen("min_gain = 0.05", &format!("min_gain = 0.05\n{line}"), 1);
        let at = text.lines().position(|l| l == *line).unwrap() + 1;
        fs::write(&path, text).unwrap();
        let out = tmp.path().join("refused");
        let o = htfid(&[
            "diagnose",
            path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(1), "{line}: {}", stderr(&o));
        let err = stderr(&o);
        assert!(
            err.contains(&format!("d.toml:{at}:")) && err.contains(needle),
            "{line}: {err}"
        );
        assert!(!out.exists(), "{line}");
    }
    // In range: read, used and echoed.
    let run = |lines: &str, name: &str| -> serde_json::Value {
        let text = base.replacen("min_gain = 0.05", &format!("min_gain = 0.05\n{lines}"), 1);
        fs::write(&path, text).unwrap();
        let out = tmp.path().join(name);
        htfid_ok(&[
            "diagnose",
            path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--quiet",
        ]);
        diagnosis(&out)
    };
    let plain = run("", "plain");
    let set = run(
        "noise_band = [0.5, 0.9]\ninput_noise_flatness = 2.0\nsecond_effect_floor_ratio = 1.5\n\
         resolution = 0.05\nmax_iterations = 60",
        "set",
    );
    let o = &set["options"];
    assert_eq!(o["noise_band"], serde_json::json!([0.5, 0.9]));
    assert_eq!(o["input_noise_flatness"], 2.0);
    assert_eq!(o["second_effect_floor_ratio"], 1.5);
    assert_eq!(o["resolution"], 0.05);
    assert_eq!(o["max_iterations"], 60);
    assert_eq!(plain["options"]["resolution"], 1e-4);
    // The resolution reaches the decision: at 5 %, above the refitted model's held-out NRMSE
    // (0.9 %), no effect is claimed and the refit's moved parameters are the answer; at the
    // default the record's flight damping is named.
    assert_eq!(plain["cause"], "mode_damping(v, free)");
    assert_eq!(set["cause"], "parameter_error");
}

// ---- One run per output directory, results on the terminal ----

/// Every file below `dir` but htfid's own hidden ones (manifest, lock, staging), relative, with
/// `/` separators, sorted.
fn result_files(dir: &Path) -> Vec<String> {
    let mut out = Vec::new();
    let mut stack = vec![PathBuf::new()];
    while let Some(rel) = stack.pop() {
        for e in fs::read_dir(dir.join(&rel)).unwrap() {
            let e = e.unwrap();
            let r = rel.join(e.file_name());
            if r.to_string_lossy().starts_with(".htfid-") {
                continue;
            }
            if e.file_type().unwrap().is_dir() {
                stack.push(r);
            } else {
                out.push(r.to_string_lossy().replace('\\', "/"));
            }
        }
    }
    out.sort();
    out
}

/// The manifest's files (path, bytes), sorted.
fn manifest(dir: &Path) -> Vec<(String, u64)> {
    let m: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(dir.join(".htfid-manifest.json")).unwrap())
            .unwrap();
    let mut files: Vec<(String, u64)> = m["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| {
            (
                f["path"].as_str().unwrap().to_owned(),
                f["bytes"].as_u64().unwrap(),
            )
        })
        .collect();
    files.sort();
    files
}

/// The manifest lists exactly the directory's files (but `others`), with their sizes.
fn assert_manifest_matches(dir: &Path, others: &[&str]) {
    let listed = manifest(dir);
    let present: Vec<String> = result_files(dir)
        .into_iter()
        .filter(|f| !others.contains(&f.as_str()))
        .collect();
    let names: Vec<String> = listed.iter().map(|(p, _)| p.clone()).collect();
    assert_eq!(names, present, "manifest against the directory");
    for (path, bytes) in listed {
        assert_eq!(
            fs::metadata(dir.join(&path)).unwrap().len(),
            bytes,
            "{path}: size in the manifest"
        );
    }
}

fn spawn(args: &[&str]) -> std::process::Child {
    Command::new(env!("CARGO_BIN_EXE_htfid"))
        .args(args)
        .current_dir(root())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("the htfid binary starts")
}

/// Waits until the run has staged a file in `dir`, and returns its staging directory.
fn wait_for_staged_file(dir: &Path, child: &mut std::process::Child) -> PathBuf {
    let start = std::time::Instant::now();
    loop {
        if let Ok(entries) = fs::read_dir(dir) {
            for e in entries.flatten() {
                let name = e.file_name().to_string_lossy().into_owned();
                if name.starts_with(".htfid-staging-")
                    && fs::read_dir(e.path()).is_ok_and(|mut s| s.next().is_some())
                {
                    return e.path();
                }
            }
        }
        if let Some(status) = child.try_wait().unwrap() {
            panic!("the run ended ({status}) before it staged a file");
        }
        assert!(
            start.elapsed().as_secs() < 120,
            "no staged file after 2 minutes"
        );
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
}

/// A run slow enough to be caught while it works: the two-dof fit takes seconds, and its
/// time series is staged before the fit starts.
const SLOW_RUN: [&str; 3] = ["run", "configs/two-dof.toml", "--no-plots"];

/// A second run into a directory in use fails at once, naming the directory and the run that
/// holds it; SIGTERM then stops the first run, which removes everything it had staged.
#[cfg(unix)]
#[test]
fn a_busy_directory_is_refused_and_sigterm_leaves_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("busy");
    let out_s = out.to_str().unwrap();
    let mut first = spawn(&[SLOW_RUN[0], SLOW_RUN[1], SLOW_RUN[2], "--out", out_s]);
    let staging = wait_for_staged_file(&out, &mut first);

    let started = std::time::Instant::now();
    let o = htfid(&["simulate", "configs/paper.toml", "--out", out_s]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains(&format!(
            "output directory {out_s} is in use by another htfid run (pid {})",
            first.id()
        )),
        "{}",
        stderr(&o)
    );
    assert!(
        started.elapsed().as_secs_f64() < 5.0,
        "refused without waiting: {:?}",
        started.elapsed()
    );
    assert!(staging.is_dir(), "the refused run left the first one alone");

    let kill = Command::new("kill")
        .args(["-TERM", &first.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let status = first.wait().unwrap();
    assert_eq!(status.code(), Some(130), "{status}");
    assert!(
        !out.exists(),
        "the stopped run made the directory and leaves nothing in it: {:?}",
        fs::read_dir(&out).map(|d| d.flatten().map(|e| e.file_name()).collect::<Vec<_>>())
    );
}

/// Ctrl-C (SIGINT) in a directory holding earlier results: they stay exactly as they were.
#[cfg(unix)]
#[test]
fn sigint_keeps_the_earlier_results() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("earlier");
    let out_s = out.to_str().unwrap();
    htfid_ok(&["simulate", "configs/paper.toml", "--out", out_s]);
    let before = fs::read_to_string(out.join(".htfid-manifest.json")).unwrap();
    let mut run = spawn(&[SLOW_RUN[0], SLOW_RUN[1], SLOW_RUN[2], "--out", out_s]);
    wait_for_staged_file(&out, &mut run);
    let kill = Command::new("kill")
        .args(["-INT", &run.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    assert_eq!(run.wait().unwrap().code(), Some(130));
    let mut names: Vec<String> = fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        [
            ".htfid-manifest.json",
            "limit_cycle.csv",
            "summary.json",
            "timeseries.csv"
        ],
        "no staging, no lock, nothing of the stopped run"
    );
    assert_eq!(
        fs::read_to_string(out.join(".htfid-manifest.json")).unwrap(),
        before
    );
    assert_manifest_matches(&out, &[]);
}

/// SIGKILL cannot be handled: the staging directory stays, and the next run there removes it.
#[cfg(unix)]
#[test]
fn the_next_run_removes_what_a_killed_run_left() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("killed");
    let out_s = out.to_str().unwrap();
    // Earlier results in the directory, which the killed run must not disturb.
    htfid_ok(&["simulate", "configs/paper.toml", "--out", out_s]);
    let before = fs::read_to_string(out.join("summary.json")).unwrap();
    let mut first = spawn(&[SLOW_RUN[0], SLOW_RUN[1], SLOW_RUN[2], "--out", out_s]);
    let staging = wait_for_staged_file(&out, &mut first);
    first.kill().unwrap();
    first.wait().unwrap();
    assert!(staging.is_dir(), "a killed run cannot clean up");
    assert_eq!(
        fs::read_to_string(out.join("summary.json")).unwrap(),
        before,
        "nothing of the killed run was committed"
    );
    assert_manifest_matches(&out, &[]);

    let o = htfid(&["simulate", "configs/paper.toml", "--out", out_s]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("left by an htfid run that was killed"),
        "{}",
        stderr(&o)
    );
    assert!(!staging.exists());
    let mut names: Vec<String> = fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        [
            ".htfid-manifest.json",
            "limit_cycle.csv",
            "summary.json",
            "timeseries.csv"
        ]
    );
    assert_manifest_matches(&out, &[]);
}

/// Two runs of different configs started together into one directory: one may be refused as
/// busy, or both succeed one after the other; the directory always holds one run's files,
/// exactly as its manifest lists them.
#[test]
fn two_runs_into_one_directory_never_mix() {
    let tmp = tempfile::tempdir().unwrap();
    let other = edited_config(tmp.path(), "sample_rate = 100.0", "sample_rate = 50.0");
    let configs = [
        root().join("configs/paper.toml"),
        other.canonicalize().unwrap(),
    ];
    for round in 0..3 {
        let out = tmp.path().join(format!("shared-{round}"));
        let out_s = out.to_str().unwrap();
        let children: Vec<_> = configs
            .iter()
            .map(|c| {
                Command::new(env!("CARGO_BIN_EXE_htfid"))
                    .args(["simulate", c.to_str().unwrap(), "--out", out_s])
                    .current_dir(root())
                    .stdout(std::process::Stdio::piped())
                    .stderr(std::process::Stdio::piped())
                    .spawn()
                    .unwrap()
            })
            .collect();
        let outputs: Vec<Output> = children
            .into_iter()
            .map(|c| c.wait_with_output().unwrap())
            .collect();
        for o in &outputs {
            assert!(
                o.status.success() || stderr(o).contains("is in use by another htfid run (pid "),
                "{}",
                stderr(o)
            );
        }
        assert!(outputs.iter().any(|o| o.status.success()));
        assert_manifest_matches(&out, &[]);
        assert_eq!(
            result_files(&out),
            ["limit_cycle.csv", "summary.json", "timeseries.csv"]
        );
        // The time series and the summary are of the same run.
        let s = summary(&out);
        let rows = fs::read_to_string(out.join("timeseries.csv"))
            .unwrap()
            .lines()
            .count()
            - 1;
        assert_eq!(rows as u64, s["simulation"]["samples"].as_u64().unwrap());
        let rate = s["simulation"]["sample_rate"].as_f64().unwrap();
        let expected = if s["config"].as_str().unwrap().ends_with("edited.toml") {
            50.0
        } else {
            100.0
        };
        assert!(
            (rate - expected).abs() < 1e-9,
            "{rate} from {}",
            s["config"]
        );
    }
}

/// A rerun replaces htfid's earlier results without --force, stale ones included; a file
/// htfid did not write (or that was edited since) blocks the run unless --force, which then
/// replaces the previous run's files as a whole. Files no run writes are never touched.
#[test]
fn reruns_replace_their_own_results_and_protect_others() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("rerun");
    let out_s = out.to_str().unwrap();
    htfid_ok(&["simulate", "configs/paper.toml", "--out", out_s]);
    fs::write(out.join("notes.txt"), "the user's").unwrap();
    htfid_ok(&["simulate", "configs/paper.toml", "--out", out_s]);
    assert_manifest_matches(&out, &["notes.txt"]);

    // Other outputs: the simulation's files are stale and go.
    htfid_ok(&["theory", "configs/paper.toml", "--no-plots", "--out", out_s]);
    assert_eq!(
        result_files(&out),
        ["notes.txt", "summary.json", "theory.csv"]
    );
    assert_manifest_matches(&out, &["notes.txt"]);

    // A result edited by hand is the user's: no silent replacement.
    fs::write(out.join("summary.json"), "edited").unwrap();
    let o = htfid(&["simulate", "configs/paper.toml", "--out", out_s]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("\"summary.json\"") && stderr(&o).contains("--force"),
        "{}",
        stderr(&o)
    );
    assert_eq!(
        result_files(&out),
        ["notes.txt", "summary.json", "theory.csv"]
    );
    assert_eq!(
        fs::read_to_string(out.join("summary.json")).unwrap(),
        "edited"
    );

    htfid_ok(&["simulate", "configs/paper.toml", "--out", out_s, "--force"]);
    assert_eq!(
        result_files(&out),
        [
            "limit_cycle.csv",
            "notes.txt",
            "summary.json",
            "timeseries.csv"
        ]
    );
    assert_manifest_matches(&out, &["notes.txt"]);
    assert_eq!(
        fs::read_to_string(out.join("notes.txt")).unwrap(),
        "the user's"
    );
}

/// `run` ends with its results on stdout: the fitted k and c with standard errors and units,
/// the HTF errors, the output directory; progress goes to stderr, and --quiet silences it.
#[test]
fn run_prints_its_results_and_quiet_silences_progress() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("run");
    let out_s = out.to_str().unwrap();
    let o = htfid(&["run", "configs/paper.toml", "--no-plots", "--out", out_s]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("[htfid] simulate ... "),
        "plain progress lines when stderr is not a terminal: {}",
        stderr(&o)
    );
    let text = stdout(&o);
    let s = summary(&out);
    for estimator in ["siddiqi", "multi"] {
        assert!(text.contains(&format!("fit ({estimator})")), "{text}");
    }
    // k and c as in summary.json, to the precision of their standard errors, with their units.
    let shown = |name: &str| -> (f64, f64) {
        let line = text
            .lines()
            .find(|l| l.contains(&format!("{name} = ")))
            .unwrap_or_else(|| panic!("no {name}: {text}"));
        let rest = line.split(&format!("{name} = ")).nth(1).unwrap();
        let mut parts = rest.split(" ± ");
        let value = parts.next().unwrap().parse().unwrap();
        let stderr = parts
            .next()
            .unwrap()
            .split(' ')
            .next()
            .unwrap()
            .parse()
            .unwrap();
        (value, stderr)
    };
    for name in ["k", "c"] {
        let fit = &s["fit"]["siddiqi"];
        let (value, stderr) = shown(name);
        let (v, se) = (
            fit[name].as_f64().unwrap(),
            fit[format!("{name}_stderr")].as_f64().unwrap(),
        );
        // The standard error to one or two digits, the value to the same place.
        assert!(
            (stderr - se).abs() <= 0.5 * se,
            "{name}: {se} shown as {stderr}"
        );
        assert!(
            (value - v).abs() <= 0.5 * stderr,
            "{name}: {v} shown as {value}"
        );
    }
    let k_shown = text
        .lines()
        .find_map(|l| l.split_once("k = ").map(|(_, rest)| rest.to_string()))
        .unwrap();
    assert!(text
        .lines()
        .any(|l| l.contains("k = ") && l.ends_with(" N/m")));
    assert!(text
        .lines()
        .any(|l| l.contains("c = ") && l.ends_with(" N s/m")));
    assert!(text.contains("HTF error"), "{text}");
    assert!(text.contains(&format!("{out_s}/ (7 files)")), "{text}");
    // report.md: the decision first (the paper's G_+-2 failure and why), the config by a
    // clean path, the fit with its unit; no NaN and no e-notation anywhere.
    let report = fs::read_to_string(out.join("report.md")).unwrap();
    let decision = report.split("\n\n").nth(1).unwrap();
    assert!(
        decision.contains("G_-2 and G_2 are not resolved") && decision.contains("G_7"),
        "{report}"
    );
    assert!(decision.contains(&format!("`k` = {k_shown}")), "{report}");
    assert!(report.contains("Config: `configs/paper.toml`"), "{report}");
    let e_notation = report
        .as_bytes()
        .windows(3)
        .any(|w| w[0].is_ascii_digit() && w[1] == b'e' && (w[2] == b'-' || w[2].is_ascii_digit()));
    assert!(!report.contains("NaN") && !e_notation, "{report}");

    // --quiet anywhere on the line: the same results, nothing on stderr.
    let o = htfid(&[
        "-q",
        "run",
        "configs/paper.toml",
        "--no-plots",
        "--out",
        out_s,
    ]);
    assert!(o.status.success());
    assert_eq!(stderr(&o), "");
    let quiet_text = stdout(&o);
    assert!(
        quiet_text.contains(&format!("k = {k_shown}")),
        "{k_shown}: {quiet_text}"
    );
    let o = htfid(&["simulate", "configs/paper.toml", "--out", out_s, "--quiet"]);
    assert!(o.status.success());
    assert_eq!(stderr(&o), "");
    assert!(
        stdout(&o).contains("limit cycle  period 1.000 s"),
        "{}",
        stdout(&o)
    );
}

/// The paper config with Coulomb friction `mu` (N) added, in `dir`.
fn friction_config(dir: &Path, mu: f64) -> PathBuf {
    let text = fs::read_to_string(root().join("configs/paper.toml")).unwrap();
    let path = dir.join(format!("friction-{mu}.toml"));
    fs::write(&path, format!("{text}\n[effects]\nmu = {mu}\n")).unwrap();
    path
}

/// Rows of a CSV file as numbers, by column name.
fn csv_columns(path: &Path) -> std::collections::HashMap<String, Vec<f64>> {
    let text = fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let names: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); names.len()];
    for line in lines {
        for (c, v) in cols.iter_mut().zip(line.split(',')) {
            c.push(v.parse().unwrap());
        }
    }
    names.into_iter().zip(cols).collect()
}

/// Checks the friction hopper's outputs: the damper chart agrees with the sign of the velocity
/// wherever the mass does not stick, the stick rows sit at rest inside the reported stick
/// intervals, and the energy over the record does not grow. Returns the stick fraction.
fn check_friction_run(out: &Path, mu: f64) -> f64 {
    let summary = summary(out);
    let lc = &summary["limit_cycle"];
    let intervals = lc["stick_intervals"].as_array().unwrap();
    assert!(
        !intervals.is_empty(),
        "mu = {mu}: the mass sticks on the orbit"
    );
    let inside = |phase: f64| {
        intervals.iter().any(|i| {
            let (a, b) = (i["start"].as_f64().unwrap(), i["end"].as_f64().unwrap());
            phase >= a && phase < b
        })
    };
    let cols = csv_columns(&out.join("limit_cycle.csv"));
    let (phase, xd, s, stick) = (&cols["phase"], &cols["xd"], &cols["s"], &cols["stick"]);
    let mut stuck = 0;
    for i in 0..phase.len() {
        if stick[i] > 0.5 {
            stuck += 1;
            assert!(
                inside(phase[i]),
                "mu = {mu}: phase {} flagged stuck",
                phase[i]
            );
            // The mass is held on x' = 0 (to rounding: the state is projected onto it).
            assert!(
                xd[i].abs() < 1e-12,
                "mu = {mu}: stuck at phase {} with xd = {}",
                phase[i],
                xd[i]
            );
        } else {
            assert!(
                !inside(phase[i]),
                "mu = {mu}: phase {} in a stick interval",
                phase[i]
            );
            // Off the stick intervals the chart is the sign of the velocity: damper on while
            // moving up. A sample within 1e-9 m/s of zero sits at a located switch.
            if xd[i].abs() > 1e-9 {
                let expected = if xd[i] > 0.0 { 1.0 } else { 0.0 };
                assert!(
                    (s[i] - expected).abs() < 0.5,
                    "mu = {mu}: phase {}: xd = {:e} but s = {}",
                    phase[i],
                    xd[i],
                    s[i]
                );
            }
        }
    }
    let fraction = lc["stick_fraction"].as_f64().unwrap();
    // The flagged samples cover the reported fraction of the period (1000 samples).
    assert!(
        (stuck as f64 / 1000.0 - fraction).abs() < 0.01,
        "{stuck} vs {fraction}"
    );
    let sim = &summary["simulation"];
    assert!(sim["stick_intervals"].as_u64().unwrap() > 0);
    assert!(sim["stick_time"].as_f64().unwrap() > 0.0);

    // Energy about the static equilibrium x_eq = x0 - m g / k (m = 1, k = 200, g = 9.81,
    // x0 = 0.2): kinetic plus spring, about 3e-3 J on this orbit. The defect this guards
    // against was a mass gaining speed without bound (14 m/s, 98 J, under a 1 N forcing). The
    // 4 mN excitation moves the orbit's energy: measured +2 % at mu = 0.5 and +21 % at
    // mu = 0.95, whose orbit holds only 4e-5 J. So the largest energy of the last 30 s of the
    // record may exceed that of the first 30 s by at most 50 %, and the speed stays below
    // that of the frictionless orbit (about 0.12 m/s; friction only removes energy).
    let ts = csv_columns(&out.join("timeseries.csv"));
    let x_eq = 0.2 - 9.81 / 200.0;
    let energy: Vec<f64> = ts["x"]
        .iter()
        .zip(&ts["xd"])
        .map(|(x, v)| 0.5 * v * v + 100.0 * (x - x_eq) * (x - x_eq))
        .collect();
    let n = energy.len();
    let window = 3000.min(n / 2);
    let first = energy[..window].iter().cloned().fold(f64::MIN, f64::max);
    let last = energy[n - window..]
        .iter()
        .cloned()
        .fold(f64::MIN, f64::max);
    eprintln!("mu = {mu}: largest energy {first:e} J (first 30 s), {last:e} J (last 30 s)");
    assert!(
        last <= 1.5 * first,
        "mu = {mu}: energy grew from {first} to {last} J"
    );
    let vmax = ts["xd"].iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    assert!(vmax < 0.2, "mu = {mu}: speed reached {vmax} m/s");
    fraction
}

#[test]
fn simulate_with_coulomb_friction_sticks_instead_of_chattering() {
    let tmp = tempfile::tempdir().unwrap();
    let mut fractions = Vec::new();
    for mu in [0.5, 0.95] {
        let cfg = friction_config(tmp.path(), mu);
        let out = tmp.path().join(format!("out-{mu}"));
        htfid_ok(&[
            "simulate",
            cfg.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        fractions.push(check_friction_run(&out, mu));
    }
    // A larger friction bound holds the mass longer: 27 % of the period at 0.5 N, 61 % at
    // 0.95 N (stuck most of the time).
    assert!(fractions[0] > 0.2 && fractions[1] > 0.5, "{fractions:?}");
}

#[test]
fn a_mass_stuck_for_good_is_a_clear_error_and_theory_refuses_sticking_orbits() {
    let tmp = tempfile::tempdir().unwrap();
    // mu = 2 N exceeds the 1 N forcing around the rest position: the mass sticks for good,
    // every nearby rest position is periodic too, and there is no isolated orbit to report.
    let cfg = friction_config(tmp.path(), 2.0);
    let out = tmp.path().join("stuck");
    let o = htfid(&[
        "simulate",
        cfg.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(
        err.contains("slides along guard 0 through the whole period"),
        "{err}"
    );
    assert!(!out.exists());
    // The linearisation through sticking is not implemented: theory refuses the orbit.
    let cfg = friction_config(tmp.path(), 0.5);
    let out = tmp.path().join("theory");
    let o = htfid(&[
        "theory",
        cfg.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(
        err.contains("linearisation through sliding is not implemented"),
        "{err}"
    );
    assert!(!out.exists());
}

fn fixture(name: &str) -> PathBuf {
    root().join("tests/fixtures/data").join(name)
}

/// An estimate config of the fixture record (see `tests/fixtures/data/make_fixtures.py`),
/// with `extra` lines added to its `[data]` table.
fn fixture_estimate_config(dir: &Path, file: &str, extra: &str) -> PathBuf {
    let config = dir.join("formats.toml");
    fs::write(
        &config,
        format!(
            "name = \"formats\"\n\n[data]\nfile = {:?}\ntime = \"t\"\ninput = \"f\"\n\
             outputs = [\"x\"]\n{extra}\n\n[period]\nvalue = 0.16\n\n[estimation]\n\
             harmonics = [-1, 0, 1]\nomega_min = 5.0\nomega_max = 60.0\n",
            fixture(file)
        ),
    )
    .unwrap();
    config
}

/// `htfid estimate --data` of the one record written by NumPy and SciPy in every format gives
/// byte-identical estimates and orbit to the CSV, and carries `data.units` to summary.json.
#[test]
fn estimate_reads_every_data_format_identically() {
    let tmp = tempfile::tempdir().unwrap();
    let config = fixture_estimate_config(
        tmp.path(),
        "record.csv",
        "columns = [\"t\", \"f\", \"x\"]   # names the matrix columns of binary files\n\
         units = { t = \"s\", f = \"N\", x = \"m\" }",
    );
    let run = |file: &str| {
        let out = tmp.path().join(file);
        htfid_ok(&[
            "estimate",
            config.to_str().unwrap(),
            "--data",
            fixture(file).to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        out
    };
    let csv = run("record.csv");
    let read = |dir: &Path, name: &str| fs::read_to_string(dir.join(name)).unwrap();
    for file in [
        "record.npy",
        "record.npz",
        "record_matrix.npz",
        "record.mat",
        "record_matrix.mat",
    ] {
        let out = run(file);
        for name in ["estimate_siddiqi.csv", "orbit.csv"] {
            assert_eq!(read(&out, name), read(&csv, name), "{file}: {name}");
        }
        let s = summary(&out);
        assert_eq!(s["data"], fixture(file).display().to_string());
        assert_eq!(
            s["units"],
            serde_json::json!({"t": "s", "f": "N", "x": "m"}),
            "{file}"
        );
    }
}

/// The `[data]` table chooses a MAT-file's matrix by name and names its columns; a semicolon
/// file, an unknown delimiter, a unit of an unread column, a missing matrix and a v7.3 file are
/// each explained with the key to change.
#[test]
fn data_format_keys_and_their_messages() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("o");
    let run = |config: &Path, data: Option<&Path>| {
        let mut args = vec![
            "estimate".to_owned(),
            config.display().to_string(),
            "--out".to_owned(),
            out.display().to_string(),
            "--force".to_owned(),
        ];
        if let Some(d) = data {
            args.extend(["--data".to_owned(), d.display().to_string()]);
        }
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        htfid(&args)
    };
    let config = fixture_estimate_config(
        tmp.path(),
        "record_matrix.mat",
        "matrix = \"rec\"\ncolumns = [\"t\", \"f\", \"x\"]",
    );
    let o = run(&config, None);
    assert!(o.status.success(), "{}", stderr(&o));

    let semicolons = tmp.path().join("semi.csv");
    fs::write(
        &semicolons,
        fs::read_to_string(fixture("record.csv"))
            .unwrap()
            .replace(',', ";"),
    )
    .unwrap();
    let config = fixture_estimate_config(tmp.path(), "record.csv", "");
    // The error line, after the progress lines.
    let error = |o: &Output| {
        stderr(o)
            .lines()
            .find(|l| l.starts_with("error: "))
            .unwrap_or_default()
            .to_owned()
    };
    let o = run(&config, Some(&semicolons));
    assert_eq!(
        error(&o),
        format!(
            "error: {}: [data] file (set data.delimiter = \";\" in the config): {}:1: no column \
             \"t\" in the header \"t;f;x\": it looks semicolon-separated but cells are split at \
             \",\"; set the delimiter to \";\"",
            config.display(),
            semicolons.display()
        )
    );
    let config = fixture_estimate_config(tmp.path(), "record.csv", "delimiter = \";\"");
    let o = run(&config, Some(&semicolons));
    assert!(o.status.success(), "{}", stderr(&o));

    for (extra, message) in [
        (
            "delimiter = \"|\"",
            "8:13: data.delimiter: must be one of \",\", \";\", \"tab\", \"whitespace\", \"auto\" \
             (got \"|\")",
        ),
        (
            "units = { t = \"s\", y = \"m\" }",
            "8:9: data.units: \"y\" is not a column this config reads (\"f\", \"x\", \"t\"): \
             if it was renamed in data.input, data.output(s) or data.time, rename it here too, \
             else remove it",
        ),
        (
            "columns = [\"t\", \"t\"]",
            "8:11: data.columns: \"t\" is listed twice",
        ),
    ] {
        let config = fixture_estimate_config(tmp.path(), "record.csv", extra);
        let o = run(&config, None);
        assert_eq!(error(&o), format!("error: {}:{message}", config.display()),);
    }

    let config = fixture_estimate_config(tmp.path(), "record_matrix.mat", "matrix = \"data\"");
    let o = run(&config, None);
    assert!(
        stderr(&o).ends_with(&format!(
            "(data.matrix and data.columns name a matrix and its columns): {}: no readable \
             matrix \"data\" in the MAT-file; it holds \"rec\"\n",
            fixture("record_matrix.mat").display()
        )),
        "{}",
        stderr(&o)
    );

    let v73 = tmp.path().join("v73.mat");
    let mut bytes = b"MATLAB 7.3 MAT-file, Platform: GLNXA64".to_vec();
    bytes.resize(512, b' ');
    bytes.extend_from_slice(b"\x89HDF\r\n\x1a\n");
    fs::write(&v73, bytes).unwrap();
    let o = run(&config, Some(&v73));
    assert!(
        stderr(&o).contains("save the variables with save(FILE, ..., '-v7')"),
        "{}",
        stderr(&o)
    );
    assert_eq!(o.status.code(), Some(1));
}

/// `htfid diagnose --data` reads a `.npy` copy of the shipped CSV
/// record (written here as NumPy lays it out) to the same diagnosis.
#[test]
fn diagnose_reads_a_npy_record_like_its_csv() {
    let tmp = tempfile::tempdir().unwrap();
    let csv = root().join("data/hopper-protocol.csv");
    let rows: Vec<[f64; 3]> = fs::read_to_string(&csv)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#'))
        .skip(1)
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|c| c.parse().unwrap()).collect();
            [v[0], v[1], v[2]]
        })
        .collect();
    // NPY 1.0: magic, version, header length, a dict padded with spaces to a 64-byte boundary
    // ending in a newline, then the little-endian doubles in C order.
    let mut header = format!(
        "{{'descr': '<f8', 'fortran_order': False, 'shape': ({}, 3), }}",
        rows.len()
    );
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    for v in rows.iter().flatten() {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    let npy = tmp.path().join("rec.npy");
    fs::write(&npy, bytes).unwrap();
    let config = tmp.path().join("d.toml");
    fs::write(
        &config,
        diagnose_hopper_config().replacen(
            "outputs = [\"x\"]",
            "outputs = [\"x\"]\ncolumns = [\"t\", \"f\", \"x\"]\nunits = { x = \"m\" }",
            1,
        ),
    )
    .unwrap();
    let diagnose = |data: &Path, out: &Path| {
        htfid_ok(&[
            "diagnose",
            config.to_str().unwrap(),
            "--data",
            data.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        let json: serde_json::Value =
            serde_json::from_str(&fs::read_to_string(out.join("diagnosis.json")).unwrap()).unwrap();
        json
    };
    let a = diagnose(&csv, &tmp.path().join("csv"));
    let b = diagnose(&npy, &tmp.path().join("npy"));
    for key in [
        "cause",
        "gain",
        "parameters",
        "refit_parameters",
        "refitted",
    ] {
        assert_eq!(a[key], b[key], "{key}");
    }
    assert_eq!(b["units"], serde_json::json!({"x": "m"}));
}

/// `configs/NAME` with one textual replacement, written as `edited.toml` in `dir`; returns the
/// path and the line and column where the replacement starts.
fn edited(dir: &Path, name: &str, from: &str, to: &str) -> (PathBuf, usize, usize) {
    let text = fs::read_to_string(root().join("configs").join(name)).unwrap();
    let at = text
        .find(from)
        .unwrap_or_else(|| panic!("{name} contains {from:?}"));
    let line = text[..at].matches('\n').count() + 1;
    let column = at - text[..at].rfind('\n').map_or(0, |i| i + 1) + 1;
    let path = dir.join("edited.toml");
    fs::write(&path, text.replacen(from, to, 1)).unwrap();
    (path, line, column)
}

/// The error line `htfid COMMAND CONFIG` prints, with the config's folder removed.
fn error_of(command: &str, config: &Path) -> String {
    let out = config.with_file_name("out");
    let o = htfid(&[
        command,
        config.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(!out.exists(), "an output directory was left behind");
    stderr(&o)
        .lines()
        .find(|l| l.starts_with("error: "))
        .unwrap_or_default()
        .replace(&format!("{}/", config.parent().unwrap().display()), "")
}

/// Type errors name the key path, the line and the column in every kind of config, in words
/// a reader knows ("an integer", "a list"), not Rust type names.
#[test]
fn type_errors_name_the_key_in_every_config_kind() {
    let cases: &[(&str, &str, &str, &str, &str, usize, &str)] = &[
        // (config, command, from, to, text at the error's column, its offset in `to`, message)
        (
            "paper.toml",
            "simulate",
            "copies = 9",
            "copies = \"nine\"",
            "\"nine\"",
            9,
            "excitation.copies: invalid type: string \"nine\", expected an integer",
        ),
        (
            "paper.toml",
            "theory",
            "points = 400",
            "points = 4.5",
            "4.5",
            9,
            "theory.points: invalid type: floating point `4.5`, expected an integer",
        ),
        (
            "paper.toml",
            "run",
            "harmonics = [-3, -2, -1, 0, 1, 2, 3]",
            "harmonics = [-3, \"two\"]",
            "\"two\"",
            17,
            "estimation.harmonics[1]: invalid type: string \"two\", expected an integer",
        ),
        (
            "paper.toml",
            "run",
            "rtol = 1e-10",
            "rtol = true",
            "true",
            7,
            "simulation.rtol: invalid type: boolean `true`, expected a number",
        ),
        (
            "paper-model.toml",
            "run",
            "settle_periods = 30",
            "settle_periods = [30]",
            "[30]",
            17,
            "simulation.settle_periods: invalid type: sequence, expected an integer",
        ),
        (
            "estimate-hopper.toml",
            "estimate",
            "omega_min = 1.0",
            "omega_min = \"low\"",
            "\"low\"",
            12,
            "estimation.omega_min: invalid type: string \"low\", expected a number",
        ),
        (
            "estimate-hopper.toml",
            "estimate",
            "outputs = [\"x\"]",
            "outputs = \"x\"",
            "\"x\"",
            10,
            "data.outputs: invalid type: string \"x\", expected a list",
        ),
        (
            "diagnose-hopper.toml",
            "diagnose",
            "significance_sigma = 5.0",
            "significance_sigma = \"five\"",
            "\"five\"",
            21,
            "diagnose.significance_sigma: invalid type: string \"five\", expected a number",
        ),
        (
            "diagnose-hopper.toml",
            "diagnose",
            "free = [\"k\", \"c\"]",
            "free = [\"k\", 3]",
            "3",
            13,
            "model.free[1]: invalid type: integer `3`, expected a string",
        ),
        (
            "diagnose-hopper.toml",
            "diagnose",
            "fit_fraction = 0.7",
            "fit_fraction = \"most\"",
            "\"most\"",
            15,
            "diagnose.fit_fraction: invalid type: string \"most\", expected a number",
        ),
    ];
    for &(name, command, from, to, at, offset, message) in cases {
        assert_eq!(&to[offset..offset + at.len()], at, "{to}");
        let tmp = tempfile::tempdir().unwrap();
        let (config, line, column) = edited(tmp.path(), name, from, to);
        // A replacement that starts with new lines moves the error to its last line.
        let (line, column) = match to[..offset].rfind('\n') {
            Some(nl) => (line + to[..offset].matches('\n').count(), offset - nl),
            None => (line, column + offset),
        };
        assert_eq!(
            error_of(command, &config),
            format!("error: edited.toml:{line}:{column}: {message}"),
            "{name}: {to}"
        );
    }
}

/// Finite values that leave no meaningful simulation are refused at their key, with the
/// quantity that is out of range, instead of ending in an optimiser or integrator error.
#[test]
fn values_that_overflow_or_stall_the_simulation_are_refused_at_their_key() {
    let cases: &[(&str, &str, &str, &str, &str)] = &[
        (
            "paper.toml",
            "g = 9.81",
            "g = 1e308",
            "run",
            "11:5: model.g: the spring's static sag m g / k = 5e305 m must be within +-1e6 m, \
             or the simulation overflows (got g = 1e308)",
        ),
        (
            "paper.toml",
            "atol = 1e-12",
            "atol = 1e-300",
            "run",
            "23:8: simulation.atol: must be in [1e-20, 0.1] (below 1e-20 the target is finer \
             than the rounding of a state near zero, and the step size collapses) (got 1e-300)",
        ),
        (
            "paper.toml",
            "rtol = 1e-10",
            "rtol = 1e-300",
            "simulate",
            "22:8: simulation.rtol: must be in [1e-14, 0.1] (below 1e-14 the target is finer \
             than double-precision rounding) (got 1e-300)",
        ),
        (
            "paper.toml",
            "fit = [\"k\", \"c\"]",
            "fit = []",
            "run",
            "36:7: estimation.fit: must name at least one parameter, among \"k\", \"c\", \"m\"",
        ),
        (
            "paper.toml",
            "k = 200.0",
            "k = 1e300",
            "simulate",
            "9:5: model.k: the natural period 2 pi sqrt(m / k) = 6.283185307179586e-150 s must \
             be within 1e4 times the forcing period 1 s either way, or one simulation cannot \
             resolve both (got m = 1, k = 1e300)",
        ),
        (
            "paper.toml",
            "m = 1.0",
            "m = 1e-300",
            "simulate",
            "8:5: model.m: the natural period 2 pi sqrt(m / k) = 4.442882938158366e-151 s must \
             be within 1e4 times the forcing period 1 s either way, or one simulation cannot \
             resolve both (got m = 1e-300, k = 200)",
        ),
        (
            "paper.toml",
            "c = 2.0",
            "c = 1e300",
            "simulate",
            "10:5: model.c: the damping ratio c / (2 sqrt(k m)) = 3.5355339059327375e298 must \
             be <= 1e4: beyond it the damper locks the mass and the equations are too stiff to \
             integrate (got c = 1e300)",
        ),
        (
            "paper.toml",
            "amplitude = 1.0",
            "amplitude = -1e308",
            "simulate",
            "16:13: forcing.amplitude: the static deflection amplitude / k = -5e305 m must be \
             within +-1e6 m, or the simulation overflows (got amplitude = -1e308)",
        ),
        (
            "hopper-truth.toml",
            "c_f = 0.2",
            "k3 = 1e308",
            "simulate",
            "40:6: effects.k3: the cubic force's share k3 L^2 / k at the hopper's length L = \
             0.2 m = 2.000e304 must be <= 1e6, or the simulation overflows or stalls (got k3 = \
             1e308)",
        ),
        (
            "hopper-truth.toml",
            "c_f = 0.2",
            "tau = 1e308",
            "simulate",
            "40:7: effects.tau: the lag in forcing periods, tau / T = 1.000e308 must be <= 1e4, \
             or the simulation overflows or stalls (got tau = 1e308)",
        ),
        (
            "hopper-truth.toml",
            "output_std = 2e-5",
            "output_std = 1e308",
            "simulate",
            "43:14: noise.output_std: must be in [0, 1e6] (in the outputs' units) (got 1e308)",
        ),
    ];
    for &(name, from, to, command, message) in cases {
        let tmp = tempfile::tempdir().unwrap();
        let (config, _, _) = edited(tmp.path(), name, from, to);
        let err = error_of(command, &config);
        assert_eq!(err, format!("error: edited.toml:{message}"), "{name}: {to}");
    }
}

/// A model file's parameter override that loses the limit cycle (g = 1e308 overflows the
/// simulation) is named at its line, with the file's own value that has one.
#[test]
fn an_override_that_loses_the_limit_cycle_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    let text = fs::read_to_string(root().join("configs/paper-model.toml"))
        .unwrap()
        .replace("\"../models/", &format!("\"{}/models/", root().display()))
        .replacen(
            "[simulation]",
            "[model.parameters]\ng = 1e308\n\n[simulation]",
            1,
        );
    let config = tmp.path().join("edited.toml");
    fs::write(&config, &text).unwrap();
    let line = line_of(&config, "g = 1e308");
    assert_eq!(
        error_of("simulate", &config),
        format!(
            "error: edited.toml:{line}:1: model.parameters.g: with g = 1e308 the model `hopper` \
             has no stable limit cycle from its [initial] state (with the model file's value \
             9.81 it has one): integration failed: step size 0e0 s fell below the minimum at \
             t = 0 s"
        )
    );
}

/// A record whose output never changes says nothing about the dynamics: both diagnoses refuse
/// it, naming the config, the data file and the output key, and write nothing.
#[test]
fn a_record_without_motion_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let text = fs::read_to_string(root().join("data/hopper-protocol.csv")).unwrap();
    let mut header: Option<usize> = None;
    let mut out = String::new();
    for line in text.lines() {
        if line.starts_with('#') || line.trim().is_empty() {
            out.push_str(line);
        } else if let Some(xi) = header {
            let mut cells: Vec<&str> = line.split(',').collect();
            cells[xi] = "0.15";
            out.push_str(&cells.join(","));
        } else {
            header = line.split(',').position(|c| c.trim() == "x");
            out.push_str(line);
        }
        out.push('\n');
    }
    let data = tmp.path().join("still.csv");
    fs::write(&data, out).unwrap();
    let config = "configs/diagnose-hopper.toml";
    let dir = tmp.path().join("d");
    let o = htfid(&[
        "diagnose",
        config,
        "--data",
        data.to_str().unwrap(),
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(
        err.contains(config)
            && err.contains("still.csv")
            && err.contains("data.outputs")
            && err.contains("the measured output is constant (0.15)"),
        "{err}"
    );
    assert!(!dir.exists());
}

/// The parameters of an effect on a model file's boundary carry their units on the terminal
/// and in report.md: a delay in s (the record: a delayed input from the independent two-dof
/// generator, only the delay tried).
#[test]
fn boundary_parameters_carry_their_units() {
    let tmp = tempfile::tempdir().unwrap();
    let config = format!(
        "name = \"delay-units\"\n\n[data]\nfile = {:?}\ntime = \"t\"\ninput = \"u\"\n\
         outputs = [\"x1\", \"x2\"]\n\n[model]\nfile = {:?}\nfree = [\"k2\"]\n\n[diagnose]\n\
         effects = [\"input_delay\"]\n",
        root()
            .join("tests/fixtures/two-dof-effects/input-delay.csv")
            .to_str()
            .unwrap(),
        root().join("models/two-dof.toml").to_str().unwrap(),
    );
    let path = tmp.path().join("delay.toml");
    fs::write(&path, config).unwrap();
    let out = tmp.path().join("d");
    let o = htfid(&[
        "diagnose",
        path.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let d = diagnosis(&out);
    assert_eq!(d["cause"], "input_delay", "{}", d["candidates"]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    let line = stdout
        .lines()
        .find(|l| {
            l.trim_start()
                .trim_start_matches("fitted")
                .trim_start()
                .starts_with("delay = ")
        })
        .unwrap_or_else(|| panic!("no fitted delay on the terminal:\n{stdout}"));
    assert!(line.trim_end().ends_with(" s"), "{line}");
    let report = fs::read_to_string(out.join("report.md")).unwrap();
    let shown: Vec<&str> = report
        .match_indices("delay = ")
        .map(|(at, _)| {
            let rest = &report[at..];
            rest[..rest.find([',', ')', '|']).unwrap()].trim_end()
        })
        .collect();
    // The decision in words and the table of effects tried.
    assert!(shown.len() >= 2, "{report}");
    for d in shown {
        assert!(d.ends_with(" s"), "{d}");
    }
}

/// The friction-dominated positioning stage under closed-loop control from a generator that
/// shares no code with htfid (`tests/oracle/real_like`, Python with SciPy's DOP853, written
/// from the equations alone; truth in its `truth.json`: motor force held per sample, position
/// quantised to 1 um), diagnosed through `tests/fixtures/real-like/friction.toml` against a
/// free mass with viscous damping (`free-mass.toml`, `k = 0`, the mass held at 1 kg):
/// Coulomb friction is named, and the friction level, the offset force and the viscous
/// damping come within 10 % of the truth (measured 20.42 N, 3.100 N and 200.6 N s/m against
/// 20.4, 3.1 and 213). Friction is a force over the mass in the library's term; the mass is
/// held at 1 kg against the truth's 0.95, which a sensor gain of about 0.94 beside it absorbs.
#[test]
fn an_independent_friction_stage_is_diagnosed_as_coulomb_friction() {
    let dir = root().join("tests/fixtures/real-like");
    let truth = read_json(&dir.join("truth.json"));
    let tmp = tempfile::tempdir().unwrap();
    let d = diagnose_quietly(&dir.join("friction.toml"), &tmp.path().join("friction"));
    assert!(
        cause_names(&d).contains(&"coulomb_friction(v)"),
        "{}",
        d["causes"]
    );
    let p = &truth["friction_stage.csv"]["parameters"];
    let within = |key: &str, want: f64| {
        let got = d["parameters"][key].as_f64().unwrap();
        assert!(
            (got / want - 1.0).abs() <= 0.1,
            "{key}: {got} against the truth {want}"
        );
    };
    within("friction_v", p["Fc_N"].as_f64().unwrap());
    // The offset force F0 enters as -F0 (truth.json's note): an input offset of -F0.
    within("u0", -p["F0_N"].as_f64().unwrap());
    within("c", p["Fv_Ns_per_m"].as_f64().unwrap());
}

/// A hysteretic (Bouc-Wen) oscillator from the same independent generator, against a linear
/// spring-mass-damper (`tests/fixtures/real-like/bouc-wen.toml`,
/// `models/spring-mass-damper.toml`, every parameter free): hysteresis is outside the
/// library, so no library effect may be claimed with confidence (`unexplained`, or
/// `ambiguous`).
#[test]
fn an_independent_hysteretic_record_is_not_claimed() {
    let dir = root().join("tests/fixtures/real-like");
    let tmp = tempfile::tempdir().unwrap();
    let d = diagnose_quietly(&dir.join("bouc-wen.toml"), &tmp.path().join("bouc-wen"));
    let cause = d["cause"].as_str().unwrap();
    assert!(
        cause == "unexplained" || cause == "ambiguous",
        "{cause}: {}",
        d["causes"]
    );
}

/// A record whose force column carries white noise (0.007 N, from a fixed generator): the
/// diagnosis reads the noise from the force's spectrum (`input_noise` in `diagnosis.json`,
/// within 10 % of the level added: the band's median scatters by a few percent), count the
/// model's response to it in the noise floor, and say so in `report.md`.
#[test]
fn a_noisy_force_column_is_read_into_the_noise_floor() {
    let tmp = tempfile::tempdir().unwrap();
    let text = fs::read_to_string(root().join("data/hopper-protocol.csv")).unwrap();
    // xorshift64* and Box-Muller: white Gaussian noise with a fixed seed.
    let mut state: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut uniform = move || {
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        ((state.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    let sigma = 0.007;
    let mut out = String::new();
    for line in text.lines() {
        let fields: Vec<&str> = line.split(',').collect();
        match fields.as_slice() {
            [t, f, x] if f.parse::<f64>().is_ok() => {
                let (u1, u2) = (uniform(), uniform());
                let n = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
                let f: f64 = f.parse().unwrap();
                out.push_str(&format!("{t},{:e},{x}\n", f + sigma * n));
            }
            _ => {
                out.push_str(line);
                out.push('\n');
            }
        }
    }
    let data = tmp.path().join("noisy.csv");
    fs::write(&data, out).unwrap();
    let dir = tmp.path().join("d");
    htfid_ok(&[
        "diagnose",
        "configs/diagnose-hopper.toml",
        "--data",
        data.to_str().unwrap(),
        "--out",
        dir.to_str().unwrap(),
        "--quiet",
    ]);
    let json = diagnosis(&dir);
    let read = json["input_noise"]["sigma"].as_f64().unwrap();
    assert!((read / sigma - 1.0).abs() < 0.1, "{read}");
    let floor = json["noise_floor"].as_f64().unwrap();
    let propagated = json["input_noise"]["propagated"].as_f64().unwrap();
    assert!(floor >= propagated && propagated > 0.0, "{json}");
    let report = fs::read_to_string(dir.join("report.md")).unwrap();
    assert!(report.contains("carries noise"), "{report}");
}

/// The third round of models written from `docs/models.md` by someone who never saw the code
/// (`tests/oracle/hidden_models_3`), diagnosed against the records that person simulated with
/// their own integrator, with parameters planted off the model files' values
/// (`<name>-truth.json`): the refit names every planted error and leaves the rest alone.
fn outsiders_diagnosis(name: &str) -> serde_json::Value {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("d");
    let config = format!("tests/oracle/hidden_models_3/diagnose-{name}.toml");
    htfid_ok(&[
        "diagnose",
        &config,
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    let d = diagnosis(&out);
    let truth: serde_json::Value = serde_json::from_str(
        &fs::read_to_string(root().join(format!("tests/oracle/hidden_models_3/{name}-truth.json")))
            .unwrap(),
    )
    .unwrap();
    assert_eq!(d["cause"], "parameter_error", "{name}: {}", d["cause"]);
    for p in d["refit_parameters"].as_array().unwrap() {
        let key = p["name"].as_str().unwrap();
        let fitted = p["fitted"].as_f64().unwrap();
        let configured = p["configured"].as_f64().unwrap();
        let stderr = p["stderr"].as_f64().unwrap();
        let true_value = truth["true_parameters"][key].as_f64().unwrap();
        let planted = (true_value - configured).abs() > 1e-9 * configured.abs();
        // Planted: found within 5 standard errors (the records' noise and the integrators'
        // difference, about 1e-8 of the outputs, are both below that). Not planted: not moved
        // by the 5 standard errors that count as a finding.
        if planted {
            assert!(
                (fitted - true_value).abs() < 5.0 * stderr,
                "{name}: {key} = {fitted} +- {stderr}, truth {true_value}"
            );
        } else {
            assert!(
                p["z"].as_f64().unwrap().abs() < 5.0,
                "{name}: {key} moved: {p}"
            );
        }
    }
    assert_ne!(
        d["stop"], "MaxIterations",
        "{name}: the refit did not converge"
    );
    d
}

/// A Hertz contact (`kc pos(d)^1.5`, with damping) between two masses: its limit cycle at the
/// diagnosis's rtol 1e-8 stalls at a periodicity residual of 1.9e-9 (the adaptive steps change
/// with the start), which Newton shooting once refused.
#[test]
fn an_outsiders_hertz_contact_model_is_diagnosed_from_their_record() {
    outsiders_diagnosis("contact_pair");
}

/// A relay under hysteresis driven by a band-limited multisine: the exact model's residual is
/// independent of that input, which the cross-correlation test once denied (it summed the
/// lags' squares as if a coloured input left them independent).
#[test]
fn an_outsiders_relay_model_is_diagnosed_and_its_residual_is_independent_of_the_input() {
    let d = outsiders_diagnosis("relay_oscillator");
    let independence = &d["validation"]["independence"];
    assert_eq!(independence["passed"], true, "{independence}");
    assert_eq!(d["validation"]["whiteness"]["passed"], true);
}

/// Cross-validation on one record with five harmonics per bin keeps lowering its score down to
/// the smallest weight, where the estimate interpolates the data (7 residual degrees of freedom
/// of 1401) and its standard errors came out a thousand times below its real error: refused,
/// naming the key, with nothing written.
#[test]
fn cross_validation_that_would_interpolate_the_data_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("e");
    let o = htfid(&[
        "estimate",
        "tests/oracle/hidden_models_3/estimate-relay_oscillator-gcv.toml",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("estimation.alpha = \"gcv\"") && err.contains("interpolates the data"),
        "{err}"
    );
    assert!(!out.exists());
}

/// The relay's response carries harmonics up to at least 8 (its switching is sharp): an
/// estimate of `-2..2` says which ones outside its set carry it. The paper's hopper, whose
/// harmonics fall off fast, gets no such note.
#[test]
fn the_estimate_names_harmonics_outside_its_set_that_the_response_carries() {
    let tmp = tempfile::tempdir().unwrap();
    let relay = tmp.path().join("relay");
    htfid_ok(&[
        "estimate",
        "tests/oracle/hidden_models_3/estimate-relay_oscillator.toml",
        "--out",
        relay.to_str().unwrap(),
        "--quiet",
    ]);
    let s = summary(&relay);
    let notes = s["checks"]["notes"].to_string();
    assert!(notes.contains("G_4 at"), "{notes}");
    let g4 = s["checks"]["outer_harmonics"][0]["harmonics"]
        .as_array()
        .unwrap()
        .iter()
        .find(|h| h["n"] == 4)
        .unwrap()["significant_share"]
        .as_f64()
        .unwrap();
    assert!(g4 > 0.3, "G_4 significant at {g4}");
    let hopper = tmp.path().join("hopper");
    htfid_ok(&[
        "estimate",
        "configs/estimate-hopper.toml",
        "--out",
        hopper.to_str().unwrap(),
        "--quiet",
    ]);
    let s = summary(&hopper);
    for h in s["checks"]["outer_harmonics"][0]["harmonics"]
        .as_array()
        .unwrap()
    {
        assert!(h["significant_share"].as_f64().unwrap() < 0.05, "{h}");
    }
    assert!(!s["checks"]["notes"].to_string().contains("carries"));
}

/// A relay whose hysteresis is wider than the motion: a valid orbit without its switches,
/// which the summary points out (the outsider of round three found it passed in silence).
#[test]
fn a_guard_that_never_fires_on_the_orbit_is_pointed_out() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = root().join("tests/oracle/hidden_models_3");
    let model = fs::read_to_string(dir.join("relay_oscillator.toml")).unwrap();
    let wide = "delta = { value = 0.5,";
    let model = model.replacen("delta = { value = 0.05,", wide, 1);
    assert!(model.contains(wide));
    fs::write(tmp.path().join("relay.toml"), model).unwrap();
    let config = fs::read_to_string(dir.join("theory-relay_oscillator.toml")).unwrap();
    fs::write(
        tmp.path().join("theory.toml"),
        config.replacen("\"relay_oscillator.toml\"", "\"relay.toml\"", 1),
    )
    .unwrap();
    let out = tmp.path().join("t");
    let o = htfid(&[
        "theory",
        tmp.path().join("theory.toml").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("guards `upper`, `lower` never fire on the orbit"),
        "{}",
        stdout(&o)
    );
    let s = summary(&out);
    assert_eq!(
        s["limit_cycle"]["guards_not_firing"],
        serde_json::json!(["upper", "lower"])
    );
    // The model as written switches twice a period: nothing to point out.
    let out = tmp.path().join("t2");
    htfid_ok(&[
        "theory",
        "tests/oracle/hidden_models_3/theory-relay_oscillator.toml",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(
        summary(&out)["limit_cycle"]["guards_not_firing"],
        serde_json::json!([])
    );
}

/// A given period must be a whole number of samples and agree with the data's own. On the
/// paper's experiment (`htfid simulate`, 100 Hz, `T = 1 s`):
/// - `period.value = 1.01` is refused, naming the key and the data's own period (over the 270
///   periods after 30 s the two part by 2.7 periods);
/// - `period.value = 1 / 1.3` (76.92 samples) is refused with two sample rates to resample to;
/// - 19 periods (from 282 s) are too few to check the harmonics beyond the set: the notes say
///   so rather than name any;
/// - the same record with its times printed as float32 (`data.time_tolerance` raised) gives the
///   same estimate as with exact times: the step is taken as `T / 100`, which the float32 times
///   approach to a few parts in 1e8. Tolerance 1e-9 of `max |G_0|`: the two runs differ only in
///   the step, by rounding.
#[test]
fn a_given_period_is_checked_against_the_samples_and_the_data() {
    let tmp = tempfile::tempdir().unwrap();
    let sim = paper_record(tmp.path());
    let config = |file: &str, value: &str, extra: &str| {
        format!(
            "[data]\nfile = \"{file}\"\ntime = \"t\"\ninput = \"f\"\noutputs = [\"x\"]\n\
             start = 30.0\n{extra}\n[period]\nvalue = {value}\n\n[estimation]\nomega_min = 1.0\n\
             omega_max = 40.0\nalpha = 1.0\n"
        )
    };
    // 19 periods from 282 s: too few for the check of the harmonics beyond the set, which
    // says so instead of naming harmonics from standard errors of few degrees of freedom.
    let short = config("sim/timeseries.csv", "1.0", "").replace("start = 30.0", "start = 282.0");
    let (out, o) = estimate_with(tmp.path(), &short);
    assert!(o.status.success(), "{}", stderr(&o));
    let notes = summary(&out)["checks"]["notes"].to_string();
    assert!(
        notes.contains("with only 19 periods (fewer than 20) the harmonics outside")
            && !notes.contains("the response carries harmonics"),
        "{notes}"
    );
    let (_, o) = estimate_with(tmp.path(), &config("sim/timeseries.csv", "1.01", ""));
    assert!(!o.status.success());
    let e = stderr(&o);
    let own: f64 = e
        .split("own period is ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no own period in: {e}"));
    assert!(
        e.contains("period.value = 1.01 s")
            && (own - 1.0).abs() < 1e-5
            && e.contains("\"estimate\""),
        "{e}"
    );
    let (_, o) = estimate_with(
        tmp.path(),
        &config("sim/timeseries.csv", "0.7692307692307693", ""),
    );
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("76.9231 samples")
            && e.contains("98.8 Hz (76 samples")
            && e.contains("100.1 Hz (77)"),
        "{e}"
    );

    let exact = {
        let (out, o) = estimate_with(tmp.path(), &config("sim/timeseries.csv", "1.0", ""));
        assert!(o.status.success(), "{}", stderr(&o));
        estimate_rows(&out, "siddiqi")
    };
    // The times as float32 prints them (nine significant digits), the rest as it is.
    let text = fs::read_to_string(sim.join("timeseries.csv")).unwrap();
    let mut f32_text = String::new();
    for (i, line) in text.lines().enumerate() {
        if i == 0 {
            f32_text.push_str(line);
        } else {
            let (t, rest) = line.split_once(',').unwrap();
            let t32 = t.parse::<f64>().unwrap() as f32;
            f32_text.push_str(&format!("{t32:.9e},{rest}"));
        }
        f32_text.push('\n');
    }
    fs::write(tmp.path().join("f32.csv"), f32_text).unwrap();
    let (out, o) = estimate_with(
        tmp.path(),
        &config("f32.csv", "1.0", "time_tolerance = 0.01\n"),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let rounded = estimate_rows(&out, "siddiqi");
    assert_eq!(rounded.len(), exact.len());
    let scale = exact.iter().map(|r| r[2].hypot(r[3])).fold(0.0, f64::max);
    for (a, b) in exact.iter().zip(&rounded) {
        assert!(
            (a[0] - b[0]).abs() <= 1e-12 * a[0] && a[1].to_bits() == b[1].to_bits(),
            "rows differ in omega or n: {a:?} against {b:?}"
        );
        for k in 2..4 {
            assert!((a[k] - b[k]).abs() <= 1e-9 * scale, "{a:?} against {b:?}");
        }
    }
}

/// `diagnose.parameter_error` names the model's own parameters held at their configured
/// values: an unknown name, a free parameter (already refitted with every candidate) and a
/// name given twice are each refused at the key's line, before any output is written.
#[test]
fn a_wrong_parameter_error_list_is_refused_at_its_line() {
    let model = root().join("models/hopper.toml");
    let cases: &[(&str, &str)] = &[
        (
            "[\"m\", \"spring\"]",
            "the model has no parameter \"spring\"; it has",
        ),
        (
            "[\"m\", \"k\"]",
            "\"k\" is in model.free, refitted with every candidate already",
        ),
        ("[\"m\", \"m\"]", "\"m\" is listed twice"),
    ];
    for &(list, message) in cases {
        let tmp = tempfile::tempdir().unwrap();
        let (config, line, column) = edited(
            tmp.path(),
            "diagnose-hopper.toml",
            "min_gain = 0.05",
            &format!("min_gain = 0.05\nparameter_error = {list}"),
        );
        // The model file and the record, from the shipped config's folder.
        let text = fs::read_to_string(&config).unwrap();
        let text = text
            .replace("../models/hopper.toml", model.to_str().unwrap())
            .replace(
                "../data/hopper-protocol.csv",
                root().join("data/hopper-protocol.csv").to_str().unwrap(),
            );
        fs::write(&config, text).unwrap();
        let error = error_of("diagnose", &config);
        let at = format!(
            "error: edited.toml:{}:{}: diagnose.parameter_error: ",
            line + 1,
            column + "parameter_error = ".len()
        );
        assert!(
            error.starts_with(&at) && error.contains(message),
            "{list}: {error}"
        );
    }
}

/// `configs/silverbox.toml` fitted on three of its eight multisine periods (rows 40650 to
/// 65226) and judged on the rows `held_out` of the same file, its paths absolute.
fn silverbox_config(held_out: [usize; 2]) -> String {
    let data = silverbox_data();
    let shipped = fs::read_to_string(root().join("configs/silverbox.toml")).unwrap();
    let config = shipped
        .replace("rows = [40650, 105712]", "rows = [40650, 65226]")
        .replace(
            "validation_rows = [105712, 127400]",
            &format!("validation_rows = [{}, {}]", held_out[0], held_out[1]),
        )
        .replace(
            "\"../../shared/data/silverbox/SNLS80mV.csv\"",
            &format!("{:?}", data.to_str().unwrap()),
        )
        .replace(
            "\"../models/silverbox.toml\"",
            &format!(
                "{:?}",
                root().join("models/silverbox.toml").to_str().unwrap()
            ),
        );
    let validation = format!("validation_rows = [{}, {}]", held_out[0], held_out[1]);
    for changed in ["rows = [40650, 65226]", validation.as_str()] {
        assert!(
            config.contains(changed),
            "the shipped config changed: {changed} not set"
        );
    }
    assert!(!config.contains("\"../"), "a relative path left: {config}");
    config
}

/// Silverbox judged on the "arrow" (rows 100 to 32100: filtered noise of rising amplitude,
/// beyond the multisines' amplitude at its end), the benchmark's test of extrapolation in
/// amplitude, fitted on three multisine periods: the stiffness law is named and extrapolates.
/// Held-out RMSE against the published figures on the arrow (an estimate, not an exact
/// truth): the linear model's between 5 and 10 mV (measured 6.7 mV), the final model's under
/// 1.5 mV, the published grey-box Duffing model's 1 mV with half again for a fit on three
/// periods (measured 0.24 mV).
#[test]
fn silverbox_extrapolates_in_amplitude_on_the_arrow() {
    let tmp = tempfile::tempdir().unwrap();
    let d = diagnose_text(tmp.path(), "arrow", &silverbox_config([100, 32100]));
    assert_eq!(d["validation_rows"], serde_json::json!([100, 32100]));
    assert!(
        cause_names(&d).contains(&"nonlinear_stiffness(y)"),
        "{}",
        d["causes"]
    );
    let linear = d["refitted"]["rmse_validation"][0].as_f64().unwrap();
    assert!((0.005..0.01).contains(&linear), "linear {linear}");
    let final_rmse = d["extended"]["nrmse"].as_f64().unwrap() * linear
        / d["refitted"]["nrmse"].as_f64().unwrap();
    assert!(final_rmse < 1.5e-3, "final {final_rmse}");
}

/// Real measured data: Silverbox against a linear
/// spring-mass-damper written in the model language (`configs/silverbox.toml`, the fitted
/// and held-out sections as rows of the one published file). The cubic spring must be named,
/// its coefficient near the published Duffing fit's, the held-out error near the published
/// grey-box figure. Before the fits of a term started from the equation error, this answer was
/// `unexplained`: on thousands of lightly damped cycles the fit of a stiffness law from zero
/// stayed in the refit's basin. The shipped config as it is, on three of the eight multisine
/// periods it fits and one of its held-out section's (2 min against 9 on 2 cores; the answer and
/// `k3_y` are the whole sections', `docs/diagnosis.md`).
#[test]
fn silverbox_is_diagnosed_as_a_stiffness_law() {
    let tmp = tempfile::tempdir().unwrap();
    let config = silverbox_config([105712, 113904]);
    let d = diagnose_text(tmp.path(), "silverbox", &config);
    assert_eq!(d["rows"], serde_json::json!([40650, 65226]));
    assert_eq!(d["validation_rows"], serde_json::json!([105712, 113904]));
    let causes = cause_names(&d);
    assert!(
        causes.contains(&"nonlinear_stiffness(y)"),
        "causes {causes:?}, cause {}",
        d["cause"]
    );
    // The configured m, k, c and u0 are rough starts, so a parameter error is named too; the
    // waterfall goes from the configured model to the refit to each effect, the last ending at
    // the final fit, each step starting where the one before it ended: the parameters' move
    // is the refit's step, not a step that sets them back (60 % held-out error, above the
    // refit's 12 %).
    assert!(causes.contains(&"parameter_error"), "causes {causes:?}");
    let steps = d["error_waterfall"].as_array().unwrap();
    let names: Vec<&str> = steps.iter().map(|s| s["step"].as_str().unwrap()).collect();
    assert_eq!(names[..2], ["configured", "refitted"], "{names:?}");
    assert_eq!(names.last(), Some(&"final"), "{names:?}");
    assert!(!names.contains(&"parameter_error"), "{names:?}");
    for pair in steps.windows(2) {
        assert_eq!(pair[0]["after"], pair[1]["before"], "{names:?}");
    }
    assert_eq!(steps[steps.len() - 2]["after"], d["extended"]["nrmse"]);
    // Every final parameter without a standard error is named in the report's note on what
    // the record cannot tell apart, and the note is there only then.
    let report = fs::read_to_string(tmp.path().join("silverbox/report.md")).unwrap();
    let note = report
        .split("\n\n")
        .find(|p| p.starts_with("**The record cannot tell some"));
    let unresolved: Vec<&String> = d["stderr"]
        .as_object()
        .unwrap()
        .iter()
        .filter(|(_, e)| e.is_null())
        .map(|(n, _)| n)
        .collect();
    match note {
        Some(note) => {
            assert!(!unresolved.is_empty(), "{note}");
            for n in &unresolved {
                assert!(note.contains(&format!("`{n}`")), "{n} not in {note}");
            }
        }
        None => assert!(unresolved.is_empty(), "{unresolved:?} not named"),
    }
    // The published Duffing fit's cubic coefficient over the mass, 7.47e5 V^-2 s^-2, from a
    // fit by another method (an estimate, not an exact truth): within 10 %.
    let k3 = d["parameters"]["k3_y"].as_f64().unwrap();
    assert!((k3 / 7.47e5 - 1.0).abs() < 0.10, "k3_y = {k3:e}");
    // Held-out RMSE (output RMS about 54 mV): the published linear model about 7 mV, the
    // Duffing model about 1 mV.
    let rmse = |m: &str| d[m]["rmse_validation"][0].as_f64().unwrap();
    assert!(
        (0.005..0.01).contains(&rmse("refitted")),
        "linear {}",
        rmse("refitted")
    );
    let final_nrmse = d["extended"]["nrmse"].as_f64().unwrap();
    let refitted_nrmse = d["refitted"]["nrmse"].as_f64().unwrap();
    assert!(
        final_nrmse * rmse("refitted") / refitted_nrmse < 1.5e-3,
        "final held-out NRMSE {final_nrmse}"
    );
}

/// `data.rows` and `data.validation_rows`: a range past the record's
/// end, a held-out range that meets the fitted one in the same file and a range that is not
/// `[start, end)` are refused with the key, nothing written.
#[test]
fn model_diagnosis_rows_are_checked() {
    let tmp = tempfile::tempdir().unwrap();
    let base = diagnose_hopper_config();
    let cases: &[(&str, &[&str])] = &[
        (
            "rows = [0, 99999999]",
            &["data.rows", "reaches past the end", "hopper-protocol.csv"],
        ),
        (
            "rows = [0, 2000]\nvalidation_rows = [1500, 3000]",
            &["data.validation_rows", "meet the fitted rows [0, 2000)"],
        ),
        (
            "validation_rows = [1500, 3000]",
            &["data.validation_rows", "all of the file"],
        ),
        ("rows = [2000, 1000]", &["data.rows", "0 <= start < end"]),
        ("rows = [5]", &["data.rows", "two sample indices"]),
    ];
    for (i, (rows, expect)) in cases.iter().enumerate() {
        let text = base.replace("outputs = [\"x\"]", &format!("outputs = [\"x\"]\n{rows}"));
        assert_ne!(text, base);
        let config = tmp.path().join(format!("c{i}.toml"));
        fs::write(&config, text).unwrap();
        assert_refused(
            "diagnose",
            &config,
            &tmp.path().join(format!("o{i}")),
            expect,
            rows,
        );
    }
}

/// Runs `htfid COMMAND CONFIG --out OUT`, which must fail with each of `needles` in its error
/// and leave `out` absent or empty; `what` names the case in a failure.
fn assert_refused(command: &str, config: &Path, out: &Path, needles: &[&str], what: &str) {
    let o = htfid(&[
        command,
        config.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success(), "{what}: accepted");
    let err = stderr(&o);
    for n in needles {
        assert!(err.contains(n), "{what}: {n:?} not in {err}");
    }
    assert!(!out.exists() || fs::read_dir(out).unwrap().next().is_none());
}

/// The independent generator's hardening Duffing record (`tests/oracle/real_like`) through the
/// diagnosis (`tests/fixtures/real-like/duffing.toml`: `models/spring-mass-damper.toml`,
/// every parameter free): the stiffness law is named and its coefficient, over the mass,
/// matches the generator's `k3 / m` to 1 %; the damping the model file configures (1.0 N s/m)
/// is named as off, at the generator's 0.8.
#[test]
fn an_independent_duffing_record_is_diagnosed_as_a_stiffness_law() {
    let dir = root().join("tests/fixtures/real-like");
    let truth = read_json(&dir.join("truth.json"));
    let p = &truth["duffing_hardening.csv"]["parameters"];
    let tmp = tempfile::tempdir().unwrap();
    let d = diagnose_quietly(&dir.join("duffing.toml"), &tmp.path().join("duffing"));
    assert_eq!(d["cause"], "nonlinear_stiffness(x)", "{}", d["causes"]);
    let k3_over_m = p["k3_N_per_m3"].as_f64().unwrap() / p["m_kg"].as_f64().unwrap();
    let k3 = d["parameters"]["k3_x"].as_f64().unwrap();
    assert!(
        (k3 / k3_over_m - 1.0).abs() < 0.01,
        "k3_x {k3} against {k3_over_m}"
    );
    let c = d["parameters"]["c"].as_f64().unwrap();
    let c_true = p["c_Ns_per_m"].as_f64().unwrap();
    assert!((c / c_true - 1.0).abs() < 0.01, "c {c} against {c_true}");
    assert_eq!(
        cause_names(&d),
        ["nonlinear_stiffness(x)", "parameter_error"]
    );
}
