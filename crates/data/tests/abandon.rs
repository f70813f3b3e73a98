//! `OutputDir::abandon_all`, as a signal handler calls it. In its own test binary: it stops
//! every output directory of the process for good.

use std::fs;

use htfid_data::{DataError, OutputDir};
use tempfile::TempDir;

#[test]
fn abandon_all_removes_the_staging_and_refuses_the_commit() {
    let root = TempDir::new().unwrap();
    let fresh = root.path().join("fresh");
    let existing = root.path().join("existing");
    fs::create_dir(&existing).unwrap();
    fs::write(existing.join("notes.txt"), "the user's").unwrap();

    let mut a = OutputDir::create(&fresh, false).unwrap();
    a.write_text("a.csv", "half").unwrap();
    let mut b = OutputDir::create(&existing, false).unwrap();
    b.write_text("b.csv", "half").unwrap();
    let b_staging = b.staging_dir().to_path_buf();

    let mut cleaned = OutputDir::abandon_all();
    cleaned.sort();
    assert_eq!(cleaned, [existing.clone(), fresh.clone()]);
    assert!(!fresh.exists(), "the directory the run made is gone");
    assert!(!b_staging.exists());
    assert!(
        !existing.join(".htfid-lock").exists(),
        "no lock file is left behind"
    );

    // Work still under way cannot stage or commit any more.
    assert!(matches!(
        b.write_text("c.csv", "late"),
        Err(DataError::Abandoned { .. })
    ));
    assert!(matches!(a.commit(), Err(DataError::Abandoned { .. })));
    drop(b);
    let names: Vec<_> = fs::read_dir(&existing)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, ["notes.txt"]);
}
