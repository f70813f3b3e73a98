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

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
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
    let o = htfid(&[
        "simulate",
        "configs/paper.toml",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
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
    assert_eq!(lc.lines().next().unwrap(), "phase,x,xd,s");
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
    let o = htfid(&["simulate", "configs/paper.toml", "--out", out_s, "--force"]);
    assert!(o.status.success(), "{}", stderr(&o));
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
