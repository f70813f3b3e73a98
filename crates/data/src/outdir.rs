use std::fs;
use std::io;
use std::path::{Component, Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Mutex, MutexGuard};

use crate::error::DataError;
use crate::write::{sync_files, write_timeseries_csv, write_unsynced, CsvWriter};

mod lock;
mod manifest;

use lock::DirLock;
pub(crate) use manifest::MANIFEST_NAME;
use manifest::{Entry, Manifest};

/// Prefix of the hidden staging directory inside an output directory.
pub(crate) const STAGING_PREFIX: &str = ".htfid-staging-";
/// Prefix of the hidden directory holding the replaced files while a commit runs.
const BACKUP_PREFIX: &str = ".htfid-backup-";
/// Every name htfid keeps for itself inside an output directory starts with this.
const RESERVED_PREFIX: &str = ".htfid-";

static STAGING_COUNTER: AtomicU64 = AtomicU64::new(0);

/// The output directories of this process not yet committed or dropped, for
/// [`OutputDir::abandon_all`]. A commit holds this lock while it moves files, so a signal
/// handler's clean-up never runs in the middle of one.
static LIVE: Mutex<Vec<Live>> = Mutex::new(Vec::new());
/// Set once [`OutputDir::abandon_all`] has run: later commits refuse.
static ABANDONED: AtomicBool = AtomicBool::new(false);

#[derive(Debug)]
struct Live {
    id: u64,
    dir: PathBuf,
    staging: PathBuf,
    lock_file: PathBuf,
    created_dir: bool,
}

fn live() -> MutexGuard<'static, Vec<Live>> {
    // A panic elsewhere while holding the list leaves it usable: entries are plain paths.
    LIVE.lock().unwrap_or_else(|e| e.into_inner())
}

/// An output directory written all-or-nothing by one run at a time.
///
/// The project's rules: one run writes into a directory at a time; a run overwrites nothing the
/// user did not ask to overwrite; a rerun replaces the earlier run's results as a whole; a
/// failed run leaves no partial output. So:
///
/// - [`create`](Self::create) takes an exclusive lock on the directory (`DIR/.htfid-lock`, held
///   until the value is committed or dropped): a second run is refused with
///   [`DataError::Locked`], naming the holder's pid. With the lock held it removes what killed
///   runs left: staging directories, and the backups of an interrupted commit, whose files it
///   first puts back.
/// - Every file is written into a hidden staging directory `DIR/.htfid-staging-<pid>` and moved
///   into `DIR` only by [`commit`](Self::commit). Dropping an `OutputDir` without committing
///   deletes the staging directory (and `DIR` itself if `create` made it).
/// - A commit writes the manifest `DIR/.htfid-manifest.json`: every file of the run with its
///   size and modification time. A file listed in the previous manifest and unchanged since is
///   htfid's own: the next run replaces it, and removes it when that run does not write it, so
///   no stale result survives a rerun. Any other file the run would write over (written by
///   someone else, changed since, or with no manifest) is a clash: without `overwrite` an error
///   ([`DataError::WouldOverwrite`], listing every clash), checked early by
///   [`claim`](Self::claim), again whenever a file is staged, and finally in `commit` before
///   anything moves. With `overwrite`, clashing files are replaced and every file of the
///   previous manifest is replaced or removed, changed or not. Files that are neither written
///   by the run nor listed in the previous manifest are never touched.
///
/// `commit` first moves the files it replaces or removes into `DIR/.htfid-backup-<pid>`, then
/// the new files into place, the manifest last; each move is an atomic rename. If a move fails,
/// the new files are taken out again and the old ones put back, and the error
/// ([`DataError::Commit`]) says whether that restored the directory. A process killed midway
/// leaves the backup, and the next `create` in the directory finishes the restore. Replacing
/// the directory as a whole by renaming a sibling is not done: the lock and files of the user
/// live in it.
///
/// Output names are relative paths inside `DIR` (`"htf.csv"`, `"plots/htf.svg"`); subdirectories
/// are created as needed. Names starting with `.htfid-` are htfid's own and refused.
#[derive(Debug)]
pub struct OutputDir {
    id: u64,
    dir: PathBuf,
    staging: PathBuf,
    backup: PathBuf,
    overwrite: bool,
    created_dir: bool,
    staged: Vec<PathBuf>,
    /// Staged text files not yet synced to disk: [`commit`](Self::commit) syncs them together.
    unsynced: Vec<PathBuf>,
    committed: bool,
    /// Kept when a failed commit could not restore everything, for the next run to finish.
    keep_for_recovery: bool,
    previous: Option<Manifest>,
    manifest_problem: Option<String>,
    notes: Vec<String>,
    lock: Option<DirLock>,
}

impl OutputDir {
    /// Creates `dir` if missing (an existing directory is fine, whatever it holds), locks it for
    /// this run, cleans up after killed runs, and makes a fresh staging directory inside it.
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
        let give_up = |e: DataError, lock: Option<DirLock>| {
            drop(lock);
            if created_dir {
                let _ = fs::remove_dir(&dir);
            }
            e
        };
        let lock = match DirLock::acquire(&dir) {
            Ok(lock) => lock,
            Err(e) => return Err(give_up(e, None)),
        };
        // The lock proves no other run works here: what hidden directories remain are a
        // killed run's.
        let notes = match clean_after_killed_runs(&dir) {
            Ok(notes) => notes,
            Err(e) => return Err(give_up(e, Some(lock))),
        };
        let (previous, manifest_problem) = match Manifest::read(&dir.join(MANIFEST_NAME)) {
            Ok(m) => (m, None),
            Err(reason) => (None, Some(reason)),
        };

        let pid = std::process::id();
        let mut attempts = 0;
        let (staging, suffix) = loop {
            attempts += 1;
            // The plain `<pid>` name first; a counter only when this process stages twice.
            let n = STAGING_COUNTER.fetch_add(1, Ordering::Relaxed);
            let suffix = if n == 0 {
                pid.to_string()
            } else {
                format!("{pid}-{n}")
            };
            let staging = dir.join(format!("{STAGING_PREFIX}{suffix}"));
            match fs::create_dir(&staging) {
                Ok(()) => break (staging, suffix),
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists && attempts < 1000 => {}
                Err(e) => return Err(give_up(write_err(&staging, e), Some(lock))),
            }
        };
        let id = STAGING_COUNTER.fetch_add(1, Ordering::Relaxed);
        live().push(Live {
            id,
            dir: dir.clone(),
            staging: staging.clone(),
            lock_file: lock.path().to_path_buf(),
            created_dir,
        });
        Ok(Self {
            id,
            backup: dir.join(format!("{BACKUP_PREFIX}{suffix}")),
            dir,
            staging,
            overwrite,
            created_dir,
            staged: Vec::new(),
            unsynced: Vec::new(),
            committed: false,
            keep_for_recovery: false,
            previous,
            manifest_problem,
            notes,
            lock: Some(lock),
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

    /// Whether files that are not this directory's earlier results may be replaced.
    pub fn overwrite(&self) -> bool {
        self.overwrite
    }

    /// What [`create`](Self::create) cleaned up after killed runs, one sentence each.
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// Checks, before any work, that the named outputs may be written: valid names and, without
    /// `overwrite`, none clashing with a file that is not an earlier result of htfid's. The
    /// error lists every clash.
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
        // A missing staging directory means the run is being stopped: it is not made again.
        if ABANDONED.load(Ordering::SeqCst) || !self.staging.is_dir() {
            return Err(DataError::Abandoned {
                dir: self.dir.clone(),
            });
        }
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
        write_unsynced(&path, text)?;
        self.unsynced.push(path);
        Ok(())
    }

    /// The outputs registered so far, relative to the directory.
    pub fn staged(&self) -> &[PathBuf] {
        &self.staged
    }

    /// Moves every staged file into the directory, removes the earlier run's results this run
    /// did not write, writes the manifest and releases the lock. Returns the final paths in the
    /// order the outputs were registered.
    pub fn commit(mut self) -> Result<Vec<PathBuf>, DataError> {
        let result = {
            let mut live = live();
            let result = if ABANDONED.load(Ordering::SeqCst) {
                Err(DataError::Abandoned {
                    dir: self.dir.clone(),
                })
            } else {
                self.commit_locked()
            };
            live.retain(|l| l.id != self.id);
            result
        };
        // Dropping `self` now releases the lock (and cleans up after a failure).
        result
    }

    fn commit_locked(&mut self) -> Result<Vec<PathBuf>, DataError> {
        let write_err = |path: &Path, source| DataError::Write {
            path: path.to_path_buf(),
            source,
        };
        // Other processes that ignore the lock may have written into the directory meanwhile.
        self.check_clashes(self.staged.iter().map(PathBuf::as_path))?;
        let mut entries = Vec::with_capacity(self.staged.len());
        for relative in &self.staged {
            let staged = self.staging.join(relative);
            // Renames keep size and modification time, so the staged file describes the final one.
            entries.push(Entry::of_file(relative, &staged).map_err(|e| write_err(&staged, e))?);
        }
        let manifest = Manifest::new(entries);
        let manifest_path = self.staging.join(MANIFEST_NAME);
        write_unsynced(&manifest_path, &manifest.to_json())?;
        // Nothing leaves the staging directory before it is on disk, so a crash cannot leave
        // a moved but empty file: CSV files are synced as they are finished, figures as they
        // are saved (`htfid-plot`), the texts and the manifest here, together.
        self.unsynced.push(manifest_path);
        sync_files(&self.unsynced)?;
        self.unsynced.clear();

        // What leaves the directory: files replaced by this run, the earlier run's results it
        // does not write again (its own only, unless overwriting), and the old manifest.
        let mut out: Vec<PathBuf> = self
            .staged
            .iter()
            .filter(|r| fs::symlink_metadata(self.dir.join(r)).is_ok())
            .cloned()
            .collect();
        if let Some(previous) = &self.previous {
            for relative in previous.paths() {
                let owned = self.overwrite
                    || previous
                        .entry(&relative)
                        .is_some_and(|e| e.matches(&self.dir.join(&relative)));
                // A directory where a listed file was is someone else's since.
                let exists =
                    fs::symlink_metadata(self.dir.join(&relative)).is_ok_and(|m| !m.is_dir());
                if owned && exists && !out.contains(&relative) {
                    out.push(relative);
                }
            }
        }
        if fs::symlink_metadata(self.dir.join(MANIFEST_NAME)).is_ok() {
            out.push(PathBuf::from(MANIFEST_NAME));
        }
        let mut into: Vec<PathBuf> = self.staged.clone();
        into.push(PathBuf::from(MANIFEST_NAME));

        let mut moved_out = Vec::new();
        let mut moved_in = Vec::new();
        let failure = (|| -> Result<(), (PathBuf, io::Error)> {
            if !out.is_empty() {
                fs::create_dir(&self.backup).map_err(|e| (self.backup.clone(), e))?;
            }
            for relative in &out {
                move_file(&self.dir, &self.backup, relative)?;
                moved_out.push(relative.clone());
            }
            for relative in &into {
                move_file(&self.staging, &self.dir, relative)?;
                moved_in.push(relative.clone());
            }
            Ok(())
        })();
        if let Err((path, source)) = failure {
            let unrestored = restore(&self.dir, &self.backup, &moved_in, &moved_out);
            if unrestored.is_empty() {
                let _ = fs::remove_dir_all(&self.backup);
            } else {
                self.keep_for_recovery = true;
            }
            return Err(DataError::Commit {
                dir: self.dir.clone(),
                path,
                source,
                unrestored,
                backup: self.backup.clone(),
            });
        }
        self.committed = true;
        for relative in &out {
            if !self.staged.contains(relative) {
                remove_empty_parents(&self.dir, relative);
            }
        }
        // The results are in place; a leftover hidden directory is only untidy, and the next
        // run removes it.
        let _ = fs::remove_dir_all(&self.backup);
        let _ = fs::remove_dir_all(&self.staging);
        Ok(self.staged.iter().map(|r| self.dir.join(r)).collect())
    }

    /// Stops every uncommitted output directory of this process: deletes its staging directory
    /// (and the directory itself if the run created it and it is empty) and makes later
    /// commits fail with [`DataError::Abandoned`]. For a signal handler, just before the
    /// process exits: waits for a commit in progress, so the directory is left either as it
    /// was or with the whole run. Returns the output directories cleaned. The locks are
    /// released when the process exits.
    pub fn abandon_all() -> Vec<PathBuf> {
        let mut live = live();
        ABANDONED.store(true, Ordering::SeqCst);
        let mut cleaned = Vec::new();
        for l in live.drain(..) {
            // The run's threads may still create or rename a file in the staging directory
            // while it is removed, which makes one removal fail: a few tries.
            for _ in 0..5 {
                if remove_all(&l.staging).is_ok() {
                    break;
                }
                std::thread::sleep(std::time::Duration::from_millis(10));
            }
            lock::remove_lock_file(&l.lock_file);
            if l.created_dir {
                let _ = fs::remove_dir(&l.dir);
            }
            cleaned.push(l.dir);
        }
        cleaned
    }

    fn check_clashes<'a>(&self, relative: impl Iterator<Item = &'a Path>) -> Result<(), DataError> {
        if self.overwrite {
            return Ok(());
        }
        let files: Vec<String> = relative
            .filter(|r| {
                let path = self.dir.join(r);
                fs::symlink_metadata(&path).is_ok()
                    && !self
                        .previous
                        .as_ref()
                        .and_then(|m| m.entry(r))
                        .is_some_and(|e| e.matches(&path))
            })
            .map(|r| r.display().to_string())
            .collect();
        if files.is_empty() {
            Ok(())
        } else {
            Err(DataError::WouldOverwrite {
                dir: self.dir.clone(),
                files,
                manifest_problem: self.manifest_problem.clone(),
            })
        }
    }
}

impl Drop for OutputDir {
    fn drop(&mut self) {
        live().retain(|l| l.id != self.id);
        if !self.committed && !self.keep_for_recovery {
            // Best effort: a leftover staging directory is removed by the next run here.
            let _ = fs::remove_dir_all(&self.staging);
        }
        // Unlocks (and removes the lock file) before the directory can be removed.
        self.lock.take();
        if !self.committed && self.created_dir {
            // Fails, as it should, if anything else is in the directory.
            let _ = fs::remove_dir(&self.dir);
        }
    }
}

/// Renames `from/relative` to `to/relative`, making `to`'s subdirectories as needed.
fn move_file(from: &Path, to: &Path, relative: &Path) -> Result<(), (PathBuf, io::Error)> {
    let target = to.join(relative);
    if let Some(parent) = target.parent() {
        fs::create_dir_all(parent).map_err(|e| (parent.to_path_buf(), e))?;
    }
    fs::rename(from.join(relative), &target).map_err(|e| (target, e))
}

/// Undoes a partial commit: deletes the files moved in, moves the backed-up files back. Returns
/// the files it could not put back (they are still in `backup`).
fn restore(dir: &Path, backup: &Path, moved_in: &[PathBuf], moved_out: &[PathBuf]) -> Vec<String> {
    for relative in moved_in {
        let _ = fs::remove_file(dir.join(relative));
    }
    let mut unrestored = Vec::new();
    for relative in moved_out {
        if move_file(backup, dir, relative).is_err() {
            unrestored.push(relative.display().to_string());
        }
    }
    unrestored
}

/// Removes the now empty directories between `relative` (a removed file) and `dir`.
fn remove_empty_parents(dir: &Path, relative: &Path) {
    let mut parent = relative.parent();
    while let Some(p) = parent.filter(|p| !p.as_os_str().is_empty()) {
        if fs::remove_dir(dir.join(p)).is_err() {
            break;
        }
        parent = p.parent();
    }
}

/// Removes the hidden directories of runs that were killed (the caller holds the lock), after
/// putting back the files of a commit that was interrupted. Returns what it did, for the user.
fn clean_after_killed_runs(dir: &Path) -> Result<Vec<String>, DataError> {
    let read_err = |source| DataError::Read {
        path: dir.to_path_buf(),
        source,
    };
    let mut names: Vec<String> = Vec::new();
    for entry in fs::read_dir(dir).map_err(read_err)? {
        let name = entry.map_err(read_err)?.file_name();
        let name = name.to_string_lossy();
        if name.starts_with(STAGING_PREFIX) || name.starts_with(BACKUP_PREFIX) {
            names.push(name.into_owned());
        }
    }
    names.sort();
    let mut notes = Vec::new();
    // Backups first: their staging directory says how far the commit went.
    for name in names.iter().filter(|n| n.starts_with(BACKUP_PREFIX)) {
        let suffix = &name[BACKUP_PREFIX.len()..];
        let backup = dir.join(name);
        let staging = dir.join(format!("{STAGING_PREFIX}{suffix}"));
        // The manifest moves in last: while it is still staged, the commit did not finish.
        // Without it the commit finished and only the backup was left.
        if let Ok(Some(new)) = Manifest::read(&staging.join(MANIFEST_NAME)) {
            // A new file in the directory that is no longer staged was moved in by the
            // killed commit; old files were moved to the backup before any new one moved in.
            let moved_in: Vec<PathBuf> = new
                .paths()
                .filter(|r| !staging.join(r).exists() && dir.join(r).exists())
                .collect();
            let moved_out = files_under(&backup);
            let unrestored = restore(dir, &backup, &moved_in, &moved_out);
            if !unrestored.is_empty() {
                return Err(DataError::Commit {
                    dir: dir.to_path_buf(),
                    path: backup.clone(),
                    source: io::Error::other("files of an interrupted commit"),
                    unrestored,
                    backup,
                });
            }
            notes.push(format!(
                "put back the {} earlier result(s) of a run killed while it committed (pid {})",
                moved_out.len(),
                pid_of(suffix)
            ));
        }
        remove_all(&backup).map_err(|source| DataError::Write {
            path: backup.clone(),
            source,
        })?;
    }
    for name in names.iter().filter(|n| n.starts_with(STAGING_PREFIX)) {
        let path = dir.join(name);
        remove_all(&path).map_err(|source| DataError::Write {
            path: path.clone(),
            source,
        })?;
        notes.push(format!(
            "removed {name}, left by an htfid run that was killed (pid {})",
            pid_of(&name[STAGING_PREFIX.len()..])
        ));
    }
    Ok(notes)
}

fn pid_of(suffix: &str) -> &str {
    suffix.split('-').next().unwrap_or(suffix)
}

fn remove_all(path: &Path) -> io::Result<()> {
    match fs::symlink_metadata(path) {
        Ok(m) if m.is_dir() => fs::remove_dir_all(path),
        Ok(_) => fs::remove_file(path),
        Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(e),
    }
}

/// Every file below `root`, relative to it.
fn files_under(root: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![PathBuf::new()];
    while let Some(rel) = stack.pop() {
        let Ok(entries) = fs::read_dir(root.join(&rel)) else {
            continue;
        };
        for entry in entries.flatten() {
            let r = rel.join(entry.file_name());
            if entry.file_type().is_ok_and(|t| t.is_dir()) {
                stack.push(r);
            } else {
                out.push(r);
            }
        }
    }
    out.sort();
    out
}

/// A relative path of normal components, not reaching into htfid's own hidden files.
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
    let reserved = relative
        .components()
        .next()
        .and_then(|c| c.as_os_str().to_str())
        .is_some_and(|first| first.starts_with(RESERVED_PREFIX));
    if relative.as_os_str().is_empty() || reserved || name.ends_with(['/', '\\']) {
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
            ".htfid-manifest.json",
            ".htfid-lock",
        ] {
            assert!(
                matches!(validate_name(bad), Err(DataError::InvalidOutputName { .. })),
                "{bad:?} accepted"
            );
        }
    }
}
