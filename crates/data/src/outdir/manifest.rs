//! `DIR/.htfid-manifest.json`: the files the last run wrote, so the next run knows which files
//! in the directory are htfid's to replace and which are not.

use std::fs;
use std::io;
use std::path::{Component, Path, PathBuf};
use std::time::UNIX_EPOCH;

use serde::{Deserialize, Serialize};

/// Name of the manifest inside an output directory.
pub(crate) const MANIFEST_NAME: &str = ".htfid-manifest.json";

/// Version of the manifest format written here.
const FORMAT: u32 = 1;

/// The manifest's contents.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct Manifest {
    /// Format version (1).
    pub format: u32,
    /// The version of htfid-data that wrote it.
    pub written_by: String,
    /// Every file the run wrote, in the order it registered them.
    pub files: Vec<Entry>,
}

/// One written file. Size and modification time tell whether the file is still as htfid left it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub(crate) struct Entry {
    /// Relative path with `/` separators.
    pub path: String,
    /// Size in bytes.
    pub bytes: u64,
    /// Modification time in ns since the Unix epoch, when the file system reports one.
    pub modified_ns: Option<u64>,
}

impl Manifest {
    pub(crate) fn new(files: Vec<Entry>) -> Self {
        Manifest {
            format: FORMAT,
            written_by: format!("htfid-data {}", env!("CARGO_PKG_VERSION")),
            files,
        }
    }

    /// Reads `path`: `Ok(None)` when there is none, `Err(reason)` when it cannot be trusted.
    pub(crate) fn read(path: &Path) -> Result<Option<Self>, String> {
        let text = match fs::read_to_string(path) {
            Ok(t) => t,
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(e.to_string()),
        };
        let m: Manifest = serde_json::from_str(&text).map_err(|e| e.to_string())?;
        if m.format != FORMAT {
            return Err(format!("unknown format {}", m.format));
        }
        if m.files.iter().any(|e| relative_path(&e.path).is_none()) {
            return Err("a listed path leaves the directory".into());
        }
        Ok(Some(m))
    }

    pub(crate) fn to_json(&self) -> String {
        let mut s = serde_json::to_string_pretty(self).expect("a manifest always serialises");
        s.push('\n');
        s
    }

    /// The entry of `relative`, if listed.
    pub(crate) fn entry(&self, relative: &Path) -> Option<&Entry> {
        let key = slash_path(relative);
        self.files.iter().find(|e| e.path == key)
    }

    /// Listed paths, as relative paths of this platform.
    pub(crate) fn paths(&self) -> impl Iterator<Item = PathBuf> + '_ {
        self.files.iter().filter_map(|e| relative_path(&e.path))
    }
}

impl Entry {
    /// The entry describing the file at `path` now, listed as `relative`.
    pub(crate) fn of_file(relative: &Path, path: &Path) -> io::Result<Self> {
        let meta = fs::metadata(path)?;
        Ok(Entry {
            path: slash_path(relative),
            bytes: meta.len(),
            modified_ns: modified_ns(&meta),
        })
    }

    /// Whether the file at `path` is still the one this entry describes.
    pub(crate) fn matches(&self, path: &Path) -> bool {
        match fs::symlink_metadata(path) {
            Ok(meta) if meta.is_file() => {
                meta.len() == self.bytes
                    && (self.modified_ns.is_none() || modified_ns(&meta) == self.modified_ns)
            }
            _ => false,
        }
    }
}

fn modified_ns(meta: &fs::Metadata) -> Option<u64> {
    let d = meta.modified().ok()?.duration_since(UNIX_EPOCH).ok()?;
    u64::try_from(d.as_nanos()).ok()
}

/// `a/b.svg` on every platform, so a manifest reads the same everywhere.
pub(crate) fn slash_path(relative: &Path) -> String {
    relative
        .components()
        .map(|c| c.as_os_str().to_string_lossy())
        .collect::<Vec<_>>()
        .join("/")
}

/// A listed path back to a relative path, refusing anything that would leave the directory
/// (a manifest is a file anyone can edit).
fn relative_path(listed: &str) -> Option<PathBuf> {
    let mut out = PathBuf::new();
    for part in listed.split('/') {
        let p = Path::new(part);
        match p.components().next() {
            Some(Component::Normal(_)) if p.components().count() == 1 => out.push(part),
            _ => return None,
        }
    }
    (!out.as_os_str().is_empty()).then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn listed_paths_stay_inside_the_directory() {
        assert_eq!(
            relative_path("plots/a.svg"),
            Some(Path::new("plots").join("a.svg"))
        );
        for bad in ["", "../x", "/abs", "a//b", "a/./b", "a/../b"] {
            assert_eq!(relative_path(bad), None, "{bad:?}");
        }
        assert_eq!(slash_path(&Path::new("plots").join("a.svg")), "plots/a.svg");
    }
}
