//! The binary, driven as a user would.

use std::path::PathBuf;
use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_htfid-truth"))
}

fn temp_dir(tag: &str) -> PathBuf {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    std::env::temp_dir().join(format!("htfid-truth-{tag}-{}-{nanos}", std::process::id()))
}

#[test]
fn writes_records_and_manifest() {
    let dir = temp_dir("run");
    // The first three core cells: a single effect, a compound pair, an out-of-library effect.
    let out = bin()
        .args(["--out", dir.to_str().unwrap(), "--seed", "1", "--n", "3"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("manifest.json")).unwrap()).unwrap();
    let records = manifest["records"].as_array().unwrap();
    assert_eq!(records.len(), 3);
    for (i, r) in records.iter().enumerate() {
        let file = format!("record-{i:03}.csv");
        assert_eq!(r["file"], file.as_str());
        let text = std::fs::read_to_string(dir.join(&file)).unwrap();
        let mut lines = text.lines();
        assert_eq!(lines.next(), Some("t,f,x"));
        let rows: Vec<Vec<f64>> = lines
            .map(|l| l.split(',').map(|c| c.parse().unwrap()).collect())
            .collect();
        assert_eq!(rows.len() as u64, r["samples"].as_u64().unwrap());
        assert!((rows[0][0] - 30.0).abs() < 1e-12);
        assert!(rows.iter().all(|row| row.len() == 3));
        assert!(r["effect_rms_m"].as_f64().unwrap() > 0.0);
        assert!(!r["label"]["effects"].as_array().unwrap().is_empty());
        assert_eq!(r["scenario"]["seed"], r["scenario"]["seed"]);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_arguments_exit_2_with_a_message() {
    let out = bin().args(["--n", "x"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--n must be an unsigned integer (got x)"),
        "{err}"
    );
    let out = bin().args(["--seed", "1"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--out is required"));
}
