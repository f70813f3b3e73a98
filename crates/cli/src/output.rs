//! Where a command writes, and the `summary.json` it leaves.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use htfid_data::{DataError, OutputDir};

/// The output directory of a run: `--out DIR`, or `out/<config name>/`.
pub fn resolve_dir(out: Option<PathBuf>, name: &str) -> PathBuf {
    out.unwrap_or_else(|| Path::new("out").join(name))
}

/// Opens the output directory after checking that none of `names` would be overwritten
/// (unless `force`), so a clash is reported before any work is done.
/// The directory is locked for this run until the returned value is committed or dropped.
pub fn open(dir: &Path, force: bool, names: &[&str]) -> Result<OutputDir> {
    let out = match OutputDir::create(dir, force) {
        Ok(out) => out,
        // The message names the directory and the other run already.
        Err(e @ DataError::Locked { .. }) => {
            return Err(anyhow::anyhow!("{e}\n(pass --out DIR to write elsewhere)"))
        }
        Err(e) => {
            return Err(e).with_context(|| format!("cannot use output directory {}", dir.display()))
        }
    };
    for note in out.notes() {
        crate::progress::line(&format!("{}: {note}", dir.display()));
    }
    out.claim(names).map_err(|e| {
        anyhow::anyhow!("{e}\n(pass --force to replace them, or --out DIR to write elsewhere)")
    })?;
    Ok(out)
}

/// Pretty JSON with a trailing newline.
pub fn json_text(value: &serde_json::Value) -> String {
    let mut s = serde_json::to_string_pretty(value).expect("a JSON value always serialises");
    s.push('\n');
    s
}
