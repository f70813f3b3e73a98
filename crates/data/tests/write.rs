//! Writing results: full-precision round trips, atomicity, and the output-directory policy.

use std::fs;
use std::path::Path;

use approx::assert_relative_eq;
use htfid_data::{
    read_csv, write_json_atomic, write_timeseries_csv, CsvSpec, CsvWriter, DataError, OutputDir,
};
use tempfile::TempDir;

/// SplitMix64: a tiny, seeded generator, enough to spread bit patterns over all of `f64`.
struct SplitMix(u64);

impl SplitMix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A finite f64 from uniformly random bits: every exponent, subnormals and signs included.
    fn finite(&mut self) -> f64 {
        loop {
            let v = f64::from_bits(self.next());
            if v.is_finite() {
                return v;
            }
        }
    }
}

fn entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn csv_round_trip_is_bit_exact() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("rt.csv");
    let mut rng = SplitMix(0x5EED_2024);
    let n = 20_000;
    let t: Vec<f64> = (0..n).map(|k| -3.0 + k as f64 / 7.0).collect();
    let mut f: Vec<f64> = (0..n).map(|_| rng.finite()).collect();
    let mut x: Vec<f64> = (0..n).map(|_| rng.finite()).collect();
    // Awkward values the random bits rarely hit.
    let special = [
        0.0,
        -0.0,
        f64::MIN_POSITIVE,
        5e-324,
        f64::MAX,
        -f64::MAX,
        0.1,
        1.0 / 3.0,
        1e-5,
        9.999_999_999_999_999e-6,
        1e16,
        9_999_999_999_999_998.0,
    ];
    f[..special.len()].copy_from_slice(&special);
    x[n - special.len()..].copy_from_slice(&special);
    write_timeseries_csv(&path, &t, &[("f", &f), ("x", &x)]).unwrap();

    let back = read_csv(&path, &CsvSpec::default().with_time_tolerance(1e-9)).unwrap();
    // Bit equality, not a tolerance: the format promises the identical f64 (this also keeps the
    // sign of -0.0).
    for (name, written, read) in [
        ("t", &t, back.time()),
        ("f", &f, back.input()),
        ("x", &x, back.output()),
    ] {
        for (k, (a, b)) in written.iter().zip(read).enumerate() {
            assert_eq!(
                a.to_bits(),
                b.to_bits(),
                "{name}[{k}]: wrote {a:e}, read {b:e}"
            );
        }
    }
    assert_eq!(entries(dir.path()), ["rt.csv"], "no temporary file left");
    let text = fs::read_to_string(&path).unwrap();
    assert!(text.starts_with("t,f,x\n-3,0,"), "{}", &text[..40]);
}

#[test]
fn csv_writer_writes_nothing_until_finished() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("out.csv");
    let mut w = CsvWriter::create(&path, &["a", "b"]).unwrap();
    w.write_row(&[1.0, 2.0]).unwrap();
    assert!(!path.exists(), "target must not exist before finish");
    drop(w); // as on an error path
    assert!(entries(dir.path()).is_empty(), "temporary file removed");

    let mut w = CsvWriter::create(&path, &["a", "b"]).unwrap();
    w.write_row(&[1.0, 2.5]).unwrap();
    w.write_row(&[f64::NAN, f64::INFINITY]).unwrap();
    assert_eq!(w.rows(), 2);
    w.finish().unwrap();
    assert_eq!(fs::read_to_string(&path).unwrap(), "a,b\n1,2.5\nNaN,inf\n");
}

#[test]
fn failed_rewrite_keeps_the_old_file() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("keep.csv");
    fs::write(&path, "old\n").unwrap();
    let mut w = CsvWriter::create(&path, &["a"]).unwrap();
    let err = w.write_row(&[1.0, 2.0]).unwrap_err();
    assert_eq!(
        err.to_string(),
        format!(
            "{}: row 0 has 2 values, the header has 1 columns",
            path.display()
        )
    );
    drop(w);
    assert_eq!(fs::read_to_string(&path).unwrap(), "old\n");
    assert_eq!(entries(dir.path()), ["keep.csv"]);
}

#[test]
fn header_names_round_trip_through_quoting() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("q.csv");
    let t = [0.0, 0.5];
    let f = [1.0, 2.0];
    let x = [3.0, 4.0];
    write_timeseries_csv(&path, &t, &[("force, N", &f), ("x \"pos\"", &x)]).unwrap();
    let s = read_csv(
        &path,
        &CsvSpec::default().with_columns("force, N", "x \"pos\""),
    )
    .unwrap();
    // Small integers and halves are exact.
    assert_relative_eq!(s.input()[1], 2.0, max_relative = 1e-15);
    assert_relative_eq!(s.output()[0], 3.0, max_relative = 1e-15);
}

#[test]
fn writer_argument_errors() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("bad.csv");
    let err = write_timeseries_csv(&path, &[0.0, 1.0], &[("f", &[1.0])]).unwrap_err();
    assert_eq!(
        err.to_string(),
        format!(
            "{}: column \"f\" has 1 values, the time vector has 2",
            path.display()
        )
    );
    let err = CsvWriter::create(&path, &[]).unwrap_err();
    assert_eq!(
        err.to_string(),
        format!("{}: a CSV file needs at least one column", path.display())
    );
    let missing = dir.path().join("no-such-dir").join("x.csv");
    assert!(matches!(
        CsvWriter::create(&missing, &["a"]),
        Err(DataError::Write { .. })
    ));
    assert!(entries(dir.path()).is_empty());
}

#[test]
fn json_is_written_atomically() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("summary.json");
    write_json_atomic(&path, "{\"a\": 1}\n").unwrap();
    write_json_atomic(&path, "{\"a\": 2}\n").unwrap();
    assert_eq!(fs::read_to_string(&path).unwrap(), "{\"a\": 2}\n");
    assert_eq!(entries(dir.path()), ["summary.json"]);
}

#[test]
fn output_dir_commits_all_files_at_once() {
    let root = TempDir::new().unwrap();
    let dir = root.path().join("run");
    let mut out = OutputDir::create(&dir, false).unwrap();
    assert!(out.staging_dir().starts_with(&dir));
    let staging_name = out
        .staging_dir()
        .file_name()
        .unwrap()
        .to_string_lossy()
        .into_owned();
    assert!(
        staging_name.starts_with(&format!(".htfid-staging-{}", std::process::id())),
        "{staging_name}"
    );
    out.claim(&["series.csv", "summary.json", "plots/htf.svg"])
        .unwrap();
    out.write_timeseries_csv("series.csv", &[0.0, 1.0], &[("x", &[2.0, 3.0])])
        .unwrap();
    out.write_text("summary.json", "{}\n").unwrap();
    let svg = out.path_for("plots/htf.svg").unwrap();
    fs::write(&svg, "<svg/>").unwrap();
    let mut w = out.csv("table.csv", &["k", "v"]).unwrap();
    w.write_row(&[1.0, 0.25]).unwrap();
    w.finish().unwrap();

    // Before commit the directory shows only the lock and the hidden staging directory.
    assert_eq!(entries(&dir), [".htfid-lock".to_string(), staging_name]);
    let finals = out.commit().unwrap();
    assert_eq!(
        finals,
        [
            dir.join("series.csv"),
            dir.join("summary.json"),
            dir.join("plots").join("htf.svg"),
            dir.join("table.csv")
        ]
    );
    assert_eq!(
        entries(&dir),
        [
            ".htfid-manifest.json",
            "plots",
            "series.csv",
            "summary.json",
            "table.csv"
        ]
    );
    assert_eq!(
        fs::read_to_string(dir.join("series.csv")).unwrap(),
        "t,x\n0,2\n1,3\n"
    );
    assert_eq!(
        fs::read_to_string(dir.join("plots/htf.svg")).unwrap(),
        "<svg/>"
    );
}

#[test]
fn output_dir_dropped_without_commit_leaves_nothing() {
    let root = TempDir::new().unwrap();
    let dir = root.path().join("fresh");
    {
        let mut out = OutputDir::create(&dir, false).unwrap();
        out.write_text("a.txt", "partial").unwrap();
        assert!(dir.exists());
        // The run fails here: `out` is dropped.
    }
    assert!(
        !dir.exists(),
        "a directory made by the failed run is removed"
    );

    let existing = root.path().join("existing");
    fs::create_dir(&existing).unwrap();
    fs::write(existing.join("notes.txt"), "user's").unwrap();
    {
        let mut out = OutputDir::create(&existing, true).unwrap();
        out.write_text("notes.txt", "replacement").unwrap();
    }
    assert_eq!(entries(&existing), ["notes.txt"]);
    assert_eq!(
        fs::read_to_string(existing.join("notes.txt")).unwrap(),
        "user's"
    );
}

#[test]
fn output_dir_refuses_to_overwrite_unless_asked() {
    let root = TempDir::new().unwrap();
    let dir = root.path().join("out");
    fs::create_dir(&dir).unwrap();
    fs::write(dir.join("a.csv"), "old a").unwrap();
    fs::write(dir.join("c.json"), "old c").unwrap();
    fs::write(dir.join("unrelated.txt"), "keep").unwrap();

    let mut out = OutputDir::create(&dir, false).unwrap();
    let err = out.claim(&["a.csv", "b.csv", "c.json"]).unwrap_err();
    assert_eq!(
        err.to_string(),
        format!(
            "output directory {} already holds files this run would write that htfid did not \
             write or that changed since: \"a.csv\", \"c.json\"; allow overwriting or choose \
             another directory",
            dir.display()
        )
    );
    assert!(matches!(
        out.write_text("a.csv", "new"),
        Err(DataError::WouldOverwrite { .. })
    ));
    out.write_text("b.csv", "new b").unwrap();
    // A clash that appears while the run works is caught by commit, before anything moves.
    fs::write(dir.join("b.csv"), "written meanwhile").unwrap();
    assert!(
        matches!(out.commit(), Err(DataError::WouldOverwrite { files, .. }) if files == ["b.csv"])
    );
    assert_eq!(entries(&dir), ["a.csv", "b.csv", "c.json", "unrelated.txt"]);
    assert_eq!(
        fs::read_to_string(dir.join("b.csv")).unwrap(),
        "written meanwhile"
    );

    let mut out = OutputDir::create(&dir, true).unwrap();
    out.claim(&["a.csv", "c.json"]).unwrap();
    out.write_text("a.csv", "new a").unwrap();
    out.commit().unwrap();
    assert_eq!(fs::read_to_string(dir.join("a.csv")).unwrap(), "new a");
    assert_eq!(fs::read_to_string(dir.join("c.json")).unwrap(), "old c");
    assert_eq!(
        fs::read_to_string(dir.join("unrelated.txt")).unwrap(),
        "keep"
    );
}

#[test]
fn output_dir_argument_errors() {
    let root = TempDir::new().unwrap();
    let file = root.path().join("plain");
    fs::write(&file, "").unwrap();
    assert_eq!(
        OutputDir::create(&file, true).unwrap_err().to_string(),
        format!(
            "output path {} exists and is not a directory",
            file.display()
        )
    );

    let mut out = OutputDir::create(root.path().join("o"), false).unwrap();
    assert_eq!(
        out.path_for("../escape.csv").unwrap_err().to_string(),
        "output name \"../escape.csv\" must be a relative file path inside the output directory"
    );
    assert!(matches!(
        out.claim(&["ok.csv", "/abs.csv"]),
        Err(DataError::InvalidOutputName { name }) if name == "/abs.csv"
    ));
    out.path_for("a.csv").unwrap();
    assert_eq!(
        out.path_for("a.csv").unwrap_err().to_string(),
        "output \"a.csv\" is written twice in one run"
    );
}

#[test]
fn two_output_dirs_in_one_process_stage_separately() {
    let root = TempDir::new().unwrap();
    let a = OutputDir::create(root.path().join("a"), false).unwrap();
    let b = OutputDir::create(root.path().join("b"), false).unwrap();
    assert_ne!(a.staging_dir(), b.staging_dir());
    drop((a, b));
    assert!(entries(root.path()).is_empty());
}
