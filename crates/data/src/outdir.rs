use std::fs;
use std::io;
use std::path::{Component, Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::DataError;
use crate::write::{write_json_atomic, write_timeseries_csv, CsvWriter};

/// Prefix of the hidden staging directory inside an output directory.
pub(crate) const STAGING_PREFIX: &str = ".htfid-staging-";

static STAGING_COUNTER: AtomicU64 = AtomicU64::new(0);

/// An output directory written all-or-nothing.
///
/// The project's rule is that a run overwrites nothing the user did not ask to overwrite, and
/// that a failed run leaves no partial output. So every file is first written into a hidden
/// staging directory `DIR/.htfid-staging-<pid>` and moved into `DIR` only by
/// [`commit`](Self::commit). Dropping an `OutputDir` without committing deletes the staging
/// directory (and `DIR` itself if [`create`](Self::create) made it and it is still empty).
///
/// Without `overwrite`, a file of the run that already exists in `DIR` is an error
/// ([`DataError::WouldOverwrite`], listing every clash): checked early by [`claim`](Self::claim),
/// again whenever a file is staged, and finally in `commit` before anything moves. With
/// `overwrite`, only the run's own files are replaced; other files in `DIR` are never touched.
///
/// Output names are relative paths inside `DIR` (`"htf.csv"`, `"plots/htf.svg"`); subdirectories
/// are created as needed. `commit` moves files one by one with atomic renames: each file is
/// either old or new, but an I/O failure midway through `commit` can leave the earlier files
/// moved.
#[derive(Debug)]
pub struct OutputDir {
    dir: PathBuf,
    staging: PathBuf,
    overwrite: bool,
    created_dir: bool,
    staged: Vec<PathBuf>,
    committed: bool,
}

impl OutputDir {
    /// Creates `dir` if missing (an existing directory is fine, whatever it holds) and a fresh
    /// staging directory inside it.
    pub fn create(dir: impl AsRef<Path>, overwrite: bool) -> Result<Self, DataError> {
        let dir = dir.as_ref().to_path_buf();
        let write_err = |path: &Path, source| DataError::Write {
            path: path.to_path_buf(),
            source,
        };
        let created_dir = match fs::metadata(&dir) {
            Ok(meta) if meta.is_dir() => false,
            Ok(_) => return Err(DataError::NotADirectory { path: dir }),
            Err(e) if e.kind() == io::ErrorKind::NotFound => {
                fs::create_dir_all(&dir).map_err(|e| write_err(&dir, e))?;
                true
            }
            Err(source) => return Err(DataError::Read { path: dir, source }),
        };
        let pid = std::process::id();
        let mut attempts = 0;
        let staging = loop {
            attempts += 1;
            // The plain `<pid>` name first; a counter only when this process stages twice or a
            // stale directory of a crashed run holds the name.
            let n = STAGING_COUNTER.fetch_add(1, Ordering::Relaxed);
            let name = if n == 0 {
                format!("{STAGING_PREFIX}{pid}")
            } else {
                format!("{STAGING_PREFIX}{pid}-{n}")
            };
            let staging = dir.join(name);
            match fs::create_dir(&staging) {
                Ok(()) => break staging,
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists && attempts < 1000 => {}
                Err(e) => {
                    if created_dir {
                        let _ = fs::remove_dir(&dir);
                    }
                    return Err(write_err(&staging, e));
                }
            }
        };
        Ok(Self {
            dir,
            staging,
            overwrite,
            created_dir,
            staged: Vec::new(),
            committed: false,
        })
    }

    /// The final output directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The hidden staging directory files are written to before [`commit`](Self::commit).
    pub fn staging_dir(&self) -> &Path {
        &self.staging
    }

    /// Whether existing files of the run may be replaced.
    pub fn overwrite(&self) -> bool {
        self.overwrite
    }

    /// Checks, before any work, that the named outputs may be written: valid names and, without
    /// `overwrite`, none present in the directory yet. The error lists every clash.
    pub fn claim(&self, names: &[&str]) -> Result<(), DataError> {
        let mut relative = Vec::with_capacity(names.len());
        for name in names {
            relative.push(validate_name(name)?);
        }
        self.check_clashes(relative.iter().map(PathBuf::as_path))
    }

    /// Registers output `name` and returns the path to write it to, inside the staging
    /// directory (its parent directories exist). For files written by other code, such as plots.
    pub fn path_for(&mut self, name: &str) -> Result<PathBuf, DataError> {
        let relative = validate_name(name)?;
        if self.staged.contains(&relative) {
            return Err(DataError::DuplicateOutput {
                name: name.to_owned(),
            });
        }
        self.check_clashes(std::iter::once(relative.as_path()))?;
        let staged = self.staging.join(&relative);
        if let Some(parent) = staged.parent() {
            fs::create_dir_all(parent).map_err(|source| DataError::Write {
                path: parent.to_path_buf(),
                source,
            })?;
        }
        self.staged.push(relative);
        Ok(staged)
    }

    /// Starts a CSV output (see [`CsvWriter`]); it must be finished before [`commit`](Self::commit).
    pub fn csv(&mut self, name: &str, header: &[&str]) -> Result<CsvWriter, DataError> {
        let path = self.path_for(name)?;
        CsvWriter::create(path, header)
    }

    /// Stages a time-series CSV (see [`write_timeseries_csv`]).
    pub fn write_timeseries_csv(
        &mut self,
        name: &str,
        t: &[f64],
        columns: &[(&str, &[f64])],
    ) -> Result<(), DataError> {
        let path = self.path_for(name)?;
        write_timeseries_csv(path, t, columns)
    }

    /// Stages a text file (JSON, TOML, a report).
    pub fn write_text(&mut self, name: &str, text: &str) -> Result<(), DataError> {
        let path = self.path_for(name)?;
        write_json_atomic(path, text)
    }

    /// The outputs registered so far, relative to the directory.
    pub fn staged(&self) -> &[PathBuf] {
        &self.staged
    }

    /// Moves every staged file into the directory and removes the staging directory. Returns the
    /// final paths in the order the outputs were registered.
    pub fn commit(mut self) -> Result<Vec<PathBuf>, DataError> {
        // Other processes may have written into the directory while this run worked.
        self.check_clashes(self.staged.iter().map(PathBuf::as_path))?;
        let mut finals = Vec::with_capacity(self.staged.len());
        for relative in &self.staged {
            let target = self.dir.join(relative);
            if let Some(parent) = target.parent() {
                fs::create_dir_all(parent).map_err(|source| DataError::Write {
                    path: parent.to_path_buf(),
                    source,
                })?;
            }
            fs::rename(self.staging.join(relative), &target).map_err(|source| {
                DataError::Write {
                    path: target.clone(),
                    source,
                }
            })?;
            finals.push(target);
        }
        self.committed = true;
        fs::remove_dir_all(&self.staging).map_err(|source| DataError::Write {
            path: self.staging.clone(),
            source,
        })?;
        Ok(finals)
    }

    fn check_clashes<'a>(&self, relative: impl Iterator<Item = &'a Path>) -> Result<(), DataError> {
        if self.overwrite {
            return Ok(());
        }
        let files: Vec<String> = relative
            .filter(|r| fs::symlink_metadata(self.dir.join(r)).is_ok())
            .map(|r| r.display().to_string())
            .collect();
        if files.is_empty() {
            Ok(())
        } else {
            Err(DataError::WouldOverwrite {
                dir: self.dir.clone(),
                files,
            })
        }
    }
}

impl Drop for OutputDir {
    fn drop(&mut self) {
        if !self.committed {
            // Best effort: a leftover hidden staging directory is harmless and recognisable.
            let _ = fs::remove_dir_all(&self.staging);
            if self.created_dir {
                // Fails, as it should, if anything else is in the directory.
                let _ = fs::remove_dir(&self.dir);
            }
        }
    }
}

/// A relative path of normal components, not reaching into a staging directory.
fn validate_name(name: &str) -> Result<PathBuf, DataError> {
    let invalid = || DataError::InvalidOutputName {
        name: name.to_owned(),
    };
    let path = Path::new(name);
    let mut relative = PathBuf::new();
    for component in path.components() {
        match component {
            Component::Normal(part) => relative.push(part),
            _ => return Err(invalid()),
        }
    }
    let staging = relative
        .components()
        .next()
        .and_then(|c| c.as_os_str().to_str())
        .is_some_and(|first| first.starts_with(STAGING_PREFIX));
    if relative.as_os_str().is_empty() || staging || name.ends_with(['/', '\\']) {
        return Err(invalid());
    }
    Ok(relative)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_must_stay_inside_the_directory() {
        assert_eq!(validate_name("a.csv").unwrap(), PathBuf::from("a.csv"));
        assert_eq!(
            validate_name("plots/htf.svg").unwrap(),
            PathBuf::from("plots").join("htf.svg")
        );
        for bad in [
            "",
            "/abs.csv",
            "../up.csv",
            "a/../b.csv",
            "./a.csv",
            "dir/",
            ".htfid-staging-1/x",
        ] {
            assert!(
                matches!(validate_name(bad), Err(DataError::InvalidOutputName { .. })),
                "{bad:?} accepted"
            );
        }
    }
}
