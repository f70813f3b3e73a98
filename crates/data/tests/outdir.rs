//! One run per output directory: the lock, the manifest, reruns, clean-up after killed runs and
//! a commit that fails halfway.

use std::fs;
use std::path::Path;

use htfid_data::{DataError, OutputDir};
use tempfile::TempDir;

/// Every entry of `dir`, hidden ones included, sorted.
fn entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// The paths listed in the directory's manifest, sorted.
fn manifest_files(dir: &Path) -> Vec<String> {
    let m: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(dir.join(".htfid-manifest.json")).unwrap())
            .unwrap();
    let mut files: Vec<String> = m["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["path"].as_str().unwrap().to_owned())
        .collect();
    files.sort();
    files
}

/// One run writing `files` (name, contents).
fn run(dir: &Path, overwrite: bool, files: &[(&str, &str)]) -> Result<(), DataError> {
    let mut out = OutputDir::create(dir, overwrite)?;
    let names: Vec<&str> = files.iter().map(|(n, _)| *n).collect();
    out.claim(&names)?;
    for (name, text) in files {
        out.write_text(name, text)?;
    }
    out.commit().map(|_| ())
}

#[test]
fn a_rerun_replaces_the_earlier_results_and_removes_stale_ones() {
    let root = TempDir::new().unwrap();
    let dir = root.path().join("run");
    run(
        &dir,
        false,
        &[("a.csv", "a1"), ("fig.svg", "f1"), ("plots/x.svg", "x1")],
    )
    .unwrap();
    assert_eq!(manifest_files(&dir), ["a.csv", "fig.svg", "plots/x.svg"]);
    fs::write(dir.join("notes.txt"), "the user's").unwrap();

    // Same directory, no overwrite asked: the earlier results are htfid's own.
    run(&dir, false, &[("a.csv", "a2"), ("b.csv", "b2")]).unwrap();
    assert_eq!(
        entries(&dir),
        [".htfid-manifest.json", "a.csv", "b.csv", "notes.txt"],
        "the stale figure and its emptied folder are gone, the user's file stays"
    );
    assert_eq!(fs::read_to_string(dir.join("a.csv")).unwrap(), "a2");
    assert_eq!(
        fs::read_to_string(dir.join("notes.txt")).unwrap(),
        "the user's"
    );
    assert_eq!(manifest_files(&dir), ["a.csv", "b.csv"]);
}

#[test]
fn a_result_changed_by_the_user_is_theirs() {
    let root = TempDir::new().unwrap();
    let dir = root.path().join("run");
    run(&dir, false, &[("a.csv", "a1"), ("b.csv", "b1")]).unwrap();
    fs::write(dir.join("a.csv"), "edited by hand").unwrap();
    fs::write(dir.join("b.csv"), "also edited").unwrap();

    // Rewriting an edited file needs overwrite; an edited file the run does not write is kept.
    let err = run(&dir, false, &[("a.csv", "a2")]).unwrap_err();
    assert!(
        matches!(&err, DataError::WouldOverwrite { files, .. } if files == &["a.csv"]),
        "{err}"
    );
    assert_eq!(entries(&dir), [".htfid-manifest.json", "a.csv", "b.csv"]);
    run(&dir, false, &[("c.csv", "c2")]).unwrap();
    assert_eq!(
        fs::read_to_string(dir.join("b.csv")).unwrap(),
        "also edited"
    );

    // With overwrite, the previous run's files go as a whole, edited or not.
    run(&dir, false, &[("d.csv", "d3")]).unwrap();
    fs::write(dir.join("d.csv"), "edited again").unwrap();
    run(&dir, true, &[("a.csv", "a4")]).unwrap();
    assert_eq!(
        entries(&dir),
        [".htfid-manifest.json", "a.csv", "b.csv"],
        "d.csv (listed, edited) is replaced as part of the previous run; b.csv was never listed \
         again after its edit and stays"
    );
    assert_eq!(fs::read_to_string(dir.join("a.csv")).unwrap(), "a4");
}

#[test]
fn an_unreadable_manifest_protects_everything_and_says_so() {
    let root = TempDir::new().unwrap();
    let dir = root.path().join("run");
    run(&dir, false, &[("a.csv", "a1")]).unwrap();
    fs::write(dir.join(".htfid-manifest.json"), "{ not json").unwrap();
    let err = run(&dir, false, &[("a.csv", "a2")])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("\"a.csv\"") && err.contains("manifest .htfid-manifest.json cannot be read"),
        "{err}"
    );
    assert_eq!(fs::read_to_string(dir.join("a.csv")).unwrap(), "a1");
}

#[test]
fn a_second_run_into_a_locked_directory_is_refused() {
    let root = TempDir::new().unwrap();
    let dir = root.path().join("run");
    let first = OutputDir::create(&dir, false).unwrap();
    let err = OutputDir::create(&dir, true).unwrap_err();
    assert!(
        matches!(err, DataError::Locked { pid: Some(pid), .. } if pid == std::process::id()),
        "{err:?}"
    );
    assert_eq!(
        err.to_string(),
        format!(
            "output directory {} is in use by another htfid run (pid {}); wait for it to finish \
             or choose another directory",
            dir.display(),
            std::process::id()
        )
    );
    // The refused run touched nothing of the first one's.
    assert!(first.staging_dir().is_dir());
    drop(first);
    assert!(
        !dir.exists(),
        "the first run made the directory and left it empty"
    );
    run(&dir, false, &[("a.csv", "a")]).unwrap();
    assert!(
        !dir.join(".htfid-lock").exists(),
        "the lock file goes with the lock"
    );
}

#[test]
fn what_a_killed_run_left_is_removed_by_the_next() {
    let root = TempDir::new().unwrap();
    let dir = root.path().join("run");
    fs::create_dir_all(dir.join(".htfid-staging-999999-3/plots")).unwrap();
    fs::write(dir.join(".htfid-staging-999999-3/plots/half.svg"), "<sv").unwrap();
    let out = OutputDir::create(&dir, false).unwrap();
    assert_eq!(
        out.notes(),
        ["removed .htfid-staging-999999-3, left by an htfid run that was killed (pid 999999)"]
    );
    assert!(!dir.join(".htfid-staging-999999-3").exists());
    drop(out);
    assert!(entries(&dir).is_empty());
}

#[test]
fn a_commit_killed_halfway_is_undone_by_the_next_run() {
    let root = TempDir::new().unwrap();
    let dir = root.path().join("run");
    run(&dir, false, &[("a.csv", "old a"), ("b.csv", "old b")]).unwrap();
    let old_manifest = fs::read_to_string(dir.join(".htfid-manifest.json")).unwrap();

    // The state a commit of a.csv and c.csv leaves when killed after moving the old files out
    // and the new a.csv in: c.csv and the new manifest are still staged.
    let staging = dir.join(".htfid-staging-4242");
    let backup = dir.join(".htfid-backup-4242");
    fs::create_dir(&staging).unwrap();
    fs::create_dir(&backup).unwrap();
    fs::write(staging.join("c.csv"), "new c").unwrap();
    fs::write(
        staging.join(".htfid-manifest.json"),
        r#"{"format": 1, "written_by": "test", "files": [
            {"path": "a.csv", "bytes": 5, "modified_ns": null},
            {"path": "c.csv", "bytes": 5, "modified_ns": null}]}"#,
    )
    .unwrap();
    for name in ["a.csv", "b.csv", ".htfid-manifest.json"] {
        fs::rename(dir.join(name), backup.join(name)).unwrap();
    }
    fs::write(dir.join("a.csv"), "new a").unwrap();

    let out = OutputDir::create(&dir, false).unwrap();
    assert_eq!(out.notes().len(), 2, "{:?}", out.notes());
    drop(out);
    assert_eq!(entries(&dir), [".htfid-manifest.json", "a.csv", "b.csv"]);
    assert_eq!(fs::read_to_string(dir.join("a.csv")).unwrap(), "old a");
    assert_eq!(fs::read_to_string(dir.join("b.csv")).unwrap(), "old b");
    assert_eq!(
        fs::read_to_string(dir.join(".htfid-manifest.json")).unwrap(),
        old_manifest
    );
    // And the restored results are still htfid's own: a rerun replaces them.
    run(&dir, false, &[("a.csv", "a2")]).unwrap();
    assert_eq!(entries(&dir), [".htfid-manifest.json", "a.csv"]);
}

#[test]
fn a_commit_that_fails_halfway_restores_the_earlier_results() {
    let root = TempDir::new().unwrap();
    let dir = root.path().join("run");
    run(&dir, false, &[("a.csv", "old a"), ("b.csv", "old b")]).unwrap();
    let old_manifest = fs::read_to_string(dir.join(".htfid-manifest.json")).unwrap();
    // A plain file where the run needs a folder: the move of sub/x.csv fails after a.csv moved.
    fs::write(dir.join("sub"), "the user's").unwrap();

    let mut out = OutputDir::create(&dir, false).unwrap();
    out.write_text("a.csv", "new a").unwrap();
    out.write_text("sub/x.csv", "new x").unwrap();
    let err = out.commit().unwrap_err();
    let DataError::Commit { unrestored, .. } = &err else {
        panic!("{err:?}");
    };
    assert!(unrestored.is_empty());
    assert!(
        err.to_string().contains(&format!(
            "{} was restored: it holds its earlier files and nothing of this run",
            dir.display()
        )),
        "{err}"
    );
    assert_eq!(
        entries(&dir),
        [".htfid-manifest.json", "a.csv", "b.csv", "sub"]
    );
    assert_eq!(fs::read_to_string(dir.join("a.csv")).unwrap(), "old a");
    assert_eq!(fs::read_to_string(dir.join("b.csv")).unwrap(), "old b");
    assert_eq!(
        fs::read_to_string(dir.join(".htfid-manifest.json")).unwrap(),
        old_manifest
    );
}
