//! The exclusive lock that makes one output directory belong to one run at a time.

use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use crate::error::DataError;

/// Name of the lock file inside an output directory. It exists while a run holds the directory.
pub(crate) const LOCK_NAME: &str = ".htfid-lock";

/// An advisory exclusive lock (`flock` on Unix, `LockFileEx` on Windows) on `DIR/.htfid-lock`,
/// held from [`acquire`](Self::acquire) until the value is dropped or the process ends (the
/// operating system releases it then, so a killed run never leaves the directory locked).
#[derive(Debug)]
pub(crate) struct DirLock {
    path: PathBuf,
    // Holding the open file is holding the lock.
    file: Option<File>,
}

impl DirLock {
    /// Takes the lock without waiting: a directory in use is an error naming the holder's pid.
    pub(crate) fn acquire(dir: &Path) -> Result<Self, DataError> {
        let path = dir.join(LOCK_NAME);
        let write_err = |source| DataError::Write {
            path: path.clone(),
            source,
        };
        // A few attempts: a holder that finishes removes the file, and a lock taken on the
        // removed file would protect nothing (see `same_file`).
        for _ in 0..20 {
            let file = OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .open(&path)
                .map_err(write_err)?;
            // Called through the trait: on Rust >= 1.89 `File` has an inherent `try_lock` with
            // another error type.
            match fs4::FileExt::try_lock(&file) {
                Ok(()) => {}
                Err(fs4::TryLockError::WouldBlock) => {
                    return Err(DataError::Locked {
                        dir: dir.to_path_buf(),
                        pid: read_pid(&path),
                    })
                }
                Err(fs4::TryLockError::Error(e)) => return Err(write_err(e)),
            }
            if !same_file(&file, &path) {
                continue;
            }
            // The holder's pid, for the message another run shows.
            let mut f = &file;
            f.set_len(0)
                .and_then(|()| f.write_all(format!("{}\n", std::process::id()).as_bytes()))
                .and_then(|()| f.flush())
                .map_err(write_err)?;
            return Ok(Self {
                path,
                file: Some(file),
            });
        }
        Err(write_err(io::Error::other(
            "the lock file kept being replaced by other runs",
        )))
    }

    /// The lock file's path.
    pub(crate) fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for DirLock {
    fn drop(&mut self) {
        // Removed while still held, so a finished directory holds only results; `acquire`
        // re-checks the file after locking, which makes the removal safe. Windows refuses to
        // open a file pending deletion, so there the file stays.
        if cfg!(unix) {
            let _ = fs::remove_file(&self.path);
        }
        self.file.take();
    }
}

/// Removes the lock file of a lock this process holds, without closing it (used on the way out
/// of a process that is being stopped).
pub(crate) fn remove_lock_file(path: &Path) {
    if cfg!(unix) {
        let _ = fs::remove_file(path);
    }
}

/// The pid written by the holder, when it can be read.
fn read_pid(path: &Path) -> Option<u32> {
    fs::read_to_string(path).ok()?.trim().parse().ok()
}

/// Whether `path` still names the locked file (another run may have removed it between our
/// open and our lock).
#[cfg(unix)]
fn same_file(file: &File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (file.metadata(), fs::metadata(path)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_file(_file: &File, path: &Path) -> bool {
    // The file is never removed off Unix.
    path.exists()
}
