use std::fmt::Write as _;
use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::DataError;

/// Distinguishes temporary files of one process; the process id distinguishes processes.
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// A file written under a temporary name beside its target and renamed onto the target on
/// [`commit`](Self::commit). Dropped uncommitted, it deletes the temporary file, so the target
/// is either untouched or complete.
#[derive(Debug)]
pub(crate) struct AtomicFile {
    target: PathBuf,
    temp: PathBuf,
    file: Option<BufWriter<File>>,
    /// Bytes handed to the writer so far.
    written: u64,
    /// Bytes whose write-back to the disk has been started (see [`WRITEBACK_CHUNK`]).
    started: u64,
}

/// Buffer of each file's writer.
const BUFFER_BYTES: usize = 64 * 1024;

/// Every this many bytes a file's write-back to the disk is started in the background
/// (see [`start_writeback`]), so that the sync on
/// [`AtomicFile::commit`] waits only for the last chunk instead of the whole file: a 2.7 MB
/// time series otherwise waits milliseconds for its sync after its last byte.
const WRITEBACK_CHUNK: u64 = 512 * 1024;

impl AtomicFile {
    pub(crate) fn create(target: &Path) -> Result<Self, DataError> {
        let write_err = |source| DataError::Write {
            path: target.to_path_buf(),
            source,
        };
        let Some(name) = target.file_name() else {
            return Err(write_err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "the path does not name a file",
            )));
        };
        // Same directory as the target: a rename is atomic only within one file system.
        let dir = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let pid = std::process::id();
        let mut attempts = 0;
        loop {
            attempts += 1;
            let n = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
            let mut temp_name = std::ffi::OsString::from(".");
            temp_name.push(name);
            temp_name.push(format!(".{pid}-{n}.tmp"));
            let temp = dir.join(temp_name);
            match OpenOptions::new().write(true).create_new(true).open(&temp) {
                Ok(file) => {
                    return Ok(Self {
                        target: target.to_path_buf(),
                        temp,
                        file: Some(BufWriter::with_capacity(BUFFER_BYTES, file)),
                        written: 0,
                        started: 0,
                    })
                }
                // A stale file of an earlier process with the same id: take the next number.
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists && attempts < 1000 => continue,
                Err(e) => return Err(write_err(e)),
            }
        }
    }

    pub(crate) fn target(&self) -> &Path {
        &self.target
    }

    pub(crate) fn write_all(&mut self, bytes: &[u8]) -> Result<(), DataError> {
        let result = match self.file.as_mut() {
            Some(f) => f.write_all(bytes).and_then(|()| {
                self.written += bytes.len() as u64;
                if self.written - self.started >= WRITEBACK_CHUNK {
                    f.flush()?;
                    start_writeback(f.get_ref(), self.started, self.written - self.started);
                    self.started = self.written;
                }
                Ok(())
            }),
            None => Err(io::Error::other("file already finished")),
        };
        result.map_err(|source| DataError::Write {
            path: self.target.clone(),
            source,
        })
    }

    /// Flushes, syncs to disk (so a crash cannot leave a renamed but empty file) and renames.
    pub(crate) fn commit(self) -> Result<(), DataError> {
        self.finish(true)
    }

    /// Flushes and renames without the sync: for a file in the staging directory whose sync
    /// [`sync_files`] does later, before anything moves it out of staging.
    pub(crate) fn commit_unsynced(self) -> Result<(), DataError> {
        self.finish(false)
    }

    fn finish(mut self, sync: bool) -> Result<(), DataError> {
        let result = (|| {
            let file = self
                .file
                .take()
                .ok_or_else(|| io::Error::other("file already finished"))?;
            let file = file.into_inner().map_err(|e| e.into_error())?;
            if sync {
                file.sync_all()?;
            }
            drop(file);
            fs::rename(&self.temp, &self.target)
        })();
        result.map_err(|source| DataError::Write {
            path: self.target.clone(),
            source,
        })?;
        self.temp = PathBuf::new();
        Ok(())
    }
}

/// Starts writing `len` bytes of `file` from `offset` back to the disk without waiting for
/// them. Linux starts the write-back of a range's dirty pages when told they will not be
/// needed (`posix_fadvise` with `POSIX_FADV_DONTNEED`; pages under write-back stay cached).
/// Only a hint: the sync on commit is what makes the data durable, so a failure here is
/// ignored (the sync reports any real error).
#[cfg(target_os = "linux")]
fn start_writeback(file: &File, offset: u64, len: u64) {
    let _ = rustix::fs::fadvise(
        file,
        offset,
        std::num::NonZeroU64::new(len),
        rustix::fs::Advice::DontNeed,
    );
}

/// Elsewhere the sync on commit writes the whole file.
#[cfg(not(target_os = "linux"))]
fn start_writeback(_file: &File, _offset: u64, _len: u64) {}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        self.file.take();
        if !self.temp.as_os_str().is_empty() {
            // Nothing useful can be done if this fails; the name marks it as a temporary.
            let _ = fs::remove_file(&self.temp);
        }
    }
}

/// Appends `x` in the shortest form that parses back to the identical `f64`.
///
/// The text is that of Rust's `Display` (plain notation) for ordinary magnitudes and of its
/// `LowerExp` (`1e-300`, not 300 zeros) for tiny and huge ones; both print the shortest
/// round-trip digits. The text comes from `zmij` (several times faster than `Display`, which
/// dominated the time to write a result file), adjusted to read as `Display` and `LowerExp`
/// write (checked against both in this module's tests; where the value lies
/// exactly halfway between two shortest texts, the last digit is the even one, as in Python's
/// `repr`; `Display` may take the other, which reads back to the same `f64`). Non-finite values
/// print as `NaN`, `inf`, `-inf`, which Python and NumPy parse too.
pub(crate) fn push_f64(buf: &mut String, x: f64) {
    let a = x.abs();
    if a == 0.0 || !a.is_finite() {
        // Writing to a String cannot fail.
        let _ = write!(buf, "{x}");
        return;
    }
    let mut text = zmij::Buffer::new();
    let t = text.format_finite(x);
    if (1e-5..1e16).contains(&a) {
        // In this range the formatter writes plain notation, as `Display` does, apart from a
        // `.0` after whole numbers.
        buf.push_str(t.strip_suffix(".0").unwrap_or(t));
    } else if let Some((mantissa, exponent)) = t.split_once("e+") {
        // Outside it, exponent notation as `LowerExp` writes it, apart from the `+`.
        buf.push_str(mantissa);
        buf.push('e');
        buf.push_str(exponent);
    } else {
        buf.push_str(t);
    }
}

/// Appends a header name, quoting it (with doubled inner quotes) when it would otherwise not
/// read back as the same single cell.
fn push_name(buf: &mut String, name: &str) {
    let needs_quotes = name.contains([',', '"', '\n', '\r', ';', '\t'])
        || name.starts_with([' ', '#'])
        || name.ends_with(' ');
    if needs_quotes {
        buf.push('"');
        buf.push_str(&name.replace('"', "\"\""));
        buf.push('"');
    } else {
        buf.push_str(name);
    }
}

/// Writes a comma-separated file of numbers atomically: rows go to a temporary file beside the
/// target, which replaces the target only on [`finish`](Self::finish). Dropping the writer
/// unfinished (an error, a panic) leaves the target as it was.
///
/// Values are written with full round-trip precision: reading them back gives the identical
/// `f64` bits. This writer replaces an existing target; the policy of what may be overwritten
/// belongs to [`OutputDir`](crate::OutputDir).
#[derive(Debug)]
pub struct CsvWriter {
    file: AtomicFile,
    columns: usize,
    rows: usize,
    line: String,
}

impl CsvWriter {
    /// Starts a file at `path` with the given header. Names that contain separators, quotes or
    /// leading `#` are quoted.
    pub fn create(path: impl AsRef<Path>, header: &[&str]) -> Result<Self, DataError> {
        let path = path.as_ref();
        if header.is_empty() {
            return Err(DataError::EmptyHeader {
                path: path.to_path_buf(),
            });
        }
        let mut file = AtomicFile::create(path)?;
        let mut line = String::new();
        for (i, name) in header.iter().enumerate() {
            if i > 0 {
                line.push(',');
            }
            push_name(&mut line, name);
        }
        line.push('\n');
        file.write_all(line.as_bytes())?;
        Ok(Self {
            file,
            columns: header.len(),
            rows: 0,
            line,
        })
    }

    /// Appends one row; it must have one value per header column.
    pub fn write_row(&mut self, values: &[f64]) -> Result<(), DataError> {
        if values.len() != self.columns {
            return Err(DataError::RowLength {
                path: self.file.target().to_path_buf(),
                row: self.rows,
                expected: self.columns,
                found: values.len(),
            });
        }
        self.line.clear();
        for (i, &v) in values.iter().enumerate() {
            if i > 0 {
                self.line.push(',');
            }
            push_f64(&mut self.line, v);
        }
        self.line.push('\n');
        self.file.write_all(self.line.as_bytes())?;
        self.rows += 1;
        Ok(())
    }

    /// Data rows written so far.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// The file this writer will create.
    pub fn path(&self) -> &Path {
        self.file.target()
    }

    /// Completes the file and moves it into place.
    pub fn finish(self) -> Result<(), DataError> {
        self.file.commit()
    }
}

/// Writes a time series as CSV with header `t,<name>,...`: one row per sample, time first.
/// Every column must have one value per time. Atomic like [`CsvWriter`].
pub fn write_timeseries_csv(
    path: impl AsRef<Path>,
    t: &[f64],
    columns: &[(&str, &[f64])],
) -> Result<(), DataError> {
    let path = path.as_ref();
    for &(name, values) in columns {
        if values.len() != t.len() {
            return Err(DataError::LengthMismatch {
                path: path.to_path_buf(),
                column: name.to_owned(),
                expected: t.len(),
                found: values.len(),
            });
        }
    }
    let header: Vec<&str> = std::iter::once("t")
        .chain(columns.iter().map(|&(name, _)| name))
        .collect();
    let mut writer = CsvWriter::create(path, &header)?;
    let mut row = vec![0.0; header.len()];
    for (k, &tk) in t.iter().enumerate() {
        row[0] = tk;
        for (slot, &(_, values)) in row[1..].iter_mut().zip(columns) {
            *slot = values[k];
        }
        writer.write_row(&row)?;
    }
    writer.finish()
}

/// Writes `json` (any text) to `path` atomically: complete or not at all.
pub fn write_json_atomic(path: impl AsRef<Path>, json: &str) -> Result<(), DataError> {
    let mut file = AtomicFile::create(path.as_ref())?;
    file.write_all(json.as_bytes())?;
    file.commit()
}

/// Writes `text` to `path` through a temporary file and a rename, without syncing it: the
/// caller syncs it with [`sync_files`] before relying on it.
pub(crate) fn write_unsynced(path: &Path, text: &str) -> Result<(), DataError> {
    let mut file = AtomicFile::create(path)?;
    file.write_all(text.as_bytes())?;
    file.commit_unsynced()
}

/// Syncs every file of `paths` to disk, all at once: each sync waits for the disk's
/// acknowledgement (about a millisecond here even for a small file), and waits started
/// together overlap instead of adding up.
pub(crate) fn sync_files(paths: &[PathBuf]) -> Result<(), DataError> {
    // Opened for writing: Windows syncs only a handle that may write.
    let sync = |path: &PathBuf| {
        OpenOptions::new()
            .write(true)
            .open(path)
            .and_then(|f| f.sync_all())
            .map_err(|source| DataError::Write {
                path: path.clone(),
                source,
            })
    };
    match paths {
        [] => Ok(()),
        [one] => sync(one),
        [first, rest @ ..] => std::thread::scope(|scope| {
            let others: Vec<_> = rest.iter().map(|p| scope.spawn(move || sync(p))).collect();
            let mut result = sync(first);
            for handle in others {
                let r = handle.join().expect("a file sync does not panic");
                result = result.and(r);
            }
            result
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fmt(x: f64) -> String {
        let mut s = String::new();
        push_f64(&mut s, x);
        s
    }

    #[test]
    fn numbers_use_plain_notation_for_ordinary_magnitudes() {
        assert_eq!(fmt(0.0057756), "0.0057756");
        assert_eq!(fmt(-0.0), "-0");
        assert_eq!(fmt(1e-300), "1e-300");
        assert_eq!(fmt(1e16), "1e16");
        assert_eq!(fmt(123456.0), "123456");
        assert_eq!(fmt(f64::NAN), "NaN");
        assert_eq!(fmt(f64::NEG_INFINITY), "-inf");
    }

    /// The text `Display` or `LowerExp` would write, by the rule `push_f64` documents.
    fn std_text(x: f64) -> String {
        let a = x.abs();
        if a == 0.0 || !a.is_finite() || (1e-5..1e16).contains(&a) {
            format!("{x}")
        } else {
            format!("{x:e}")
        }
    }

    /// The digits come from another formatter than the standard library's: every class of
    /// value gives the standard library's text, character for character (a wrong digit, point
    /// or exponent fails), and parses back to the same bits.
    #[test]
    fn numbers_are_written_as_the_standard_library_writes_them() {
        let mut values = vec![
            1e-5,
            9.999_999_999_999_999e-6,
            1e16,
            9_999_999_999_999_998.0,
            0.1,
            0.2 + 0.1,
            1.0,
            10.0,
            100.5,
            123_456_789_012_345.6,
            f64::MIN_POSITIVE,
            5e-324,
            f64::MAX,
            f64::EPSILON,
            std::f64::consts::PI * 1e-7,
            2.5e15,
            0.000_012_3,
        ];
        for e in -320..=308 {
            values.push(10f64.powi(e));
            values.push(1.5 * 10f64.powi(e));
        }
        // A fixed-seed xorshift over all bit patterns and over ordinary magnitudes.
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for _ in 0..200_000 {
            values.push(f64::from_bits(next()));
            let mantissa = (next() >> 11) as f64 / (1u64 << 53) as f64;
            let exponent = (next() % 40) as i32 - 20;
            values.push(mantissa * 10f64.powi(exponent));
            // Short decimals, as measured data often are.
            values.push((next() % 100_000) as f64 / 1000.0);
        }
        for &v in &values {
            for x in [v, -v] {
                let (ours, std) = (fmt(x), std_text(x));
                if x.is_finite() {
                    assert_eq!(ours.parse::<f64>().map(f64::to_bits), Ok(x.to_bits()));
                }
                if ours != std {
                    // An exact tie between two shortest texts (such as 96385028347924.625):
                    // the same length and layout, one digit apart, both reading back to the
                    // same number; ours ends in the even digit, as Python's `repr` does.
                    let differ: Vec<_> = ours
                        .bytes()
                        .zip(std.bytes())
                        .filter(|(a, b)| a != b)
                        .collect();
                    assert!(
                        ours.len() == std.len()
                            && differ.len() == 1
                            && differ[0].0 % 2 == 0
                            && std.parse::<f64>().map(f64::to_bits) == Ok(x.to_bits()),
                        "{:#x}: {ours} against {std}",
                        x.to_bits()
                    );
                }
            }
        }
    }

    #[test]
    fn awkward_names_are_quoted() {
        let mut s = String::new();
        for n in ["t", "a,b", "say \"x\"", "# n", "plain name"] {
            push_name(&mut s, n);
            s.push('|');
        }
        assert_eq!(s, "t|\"a,b\"|\"say \"\"x\"\"\"|\"# n\"|plain name|");
    }

    /// A file several write-back chunks long (the background write-back is started between
    /// them) reads back byte for byte as written, every number to the same bits.
    #[test]
    fn a_file_longer_than_many_write_back_chunks_reads_back_exactly() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("long.csv");
        let mut writer = CsvWriter::create(&path, &["t", "x"]).unwrap();
        let rows = 100_000;
        let value = |i: usize| ((i as f64) * 0.731).sin() / 3.0;
        let mut expected = String::from("t,x\n");
        for i in 0..rows {
            let row = [i as f64 * 0.01, value(i)];
            writer.write_row(&row).unwrap();
            push_f64(&mut expected, row[0]);
            expected.push(',');
            push_f64(&mut expected, row[1]);
            expected.push('\n');
        }
        writer.finish().unwrap();
        assert!(expected.len() as u64 > 4 * WRITEBACK_CHUNK);
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text == expected, "the file differs from what was written");
        for (i, line) in text.lines().skip(1).enumerate() {
            let x: f64 = line.split(',').nth(1).unwrap().parse().unwrap();
            assert_eq!(x.to_bits(), value(i).to_bits(), "row {i}");
        }
    }
}
