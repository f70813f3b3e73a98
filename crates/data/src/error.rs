use std::fmt;
use std::io;
use std::path::PathBuf;

/// Where in an input an error sits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Location {
    /// A 1-based line number of a text file, counting every line (header, comments and blank
    /// lines included), as an editor shows it. Displayed as `:17` right after the path.
    Line(usize),
    /// A 0-based sample (row) index, as NumPy indexes arrays. Displayed as `: row 17`.
    Row(usize),
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Line(line) => write!(f, ":{line}"),
            Location::Row(row) => write!(f, ": row {row}"),
        }
    }
}

/// A column named in an error: by header name (CSV) or by 0-based index (NPY).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ColumnId {
    /// A header name, displayed in double quotes.
    Name(String),
    /// A 0-based column index, displayed bare.
    Index(usize),
}

impl fmt::Display for ColumnId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ColumnId::Name(name) => write!(f, "\"{name}\""),
            ColumnId::Index(index) => write!(f, "{index}"),
        }
    }
}

fn quoted_list(items: &[String]) -> String {
    if items.is_empty() {
        return "(none)".to_owned();
    }
    let quoted: Vec<String> = items.iter().map(|s| format!("\"{s}\"")).collect();
    quoted.join(", ")
}

/// Everything that can go wrong reading measured data or writing results.
///
/// Messages start with the file (and line) they concern, compiler style:
/// `SNLS80mV.csv:17: column "V2": cannot parse "abc" as a number`.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DataError {
    /// The file could not be opened or read.
    #[error("cannot read {}: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The operating system's reason.
        source: io::Error,
    },
    /// A file or directory could not be created, written, synced or renamed.
    #[error("cannot write {}: {source}", path.display())]
    Write {
        /// The file or directory.
        path: PathBuf,
        /// The operating system's reason.
        source: io::Error,
    },
    /// The text file is not UTF-8 (or ASCII).
    #[error("{}:{line}: the file is not valid UTF-8 text", path.display())]
    NotUtf8 {
        /// The file.
        path: PathBuf,
        /// 1-based line of the first invalid byte.
        line: usize,
    },
    /// The file holds nothing but blank and comment lines.
    #[error("{}: the file holds no data (it is empty or has only blank and comment lines)", path.display())]
    EmptyFile {
        /// The file.
        path: PathBuf,
    },
    /// The first non-comment line consists of numbers only, so there is no header.
    #[error(
        "{}:{line}: expected a header row of column names, found only numbers or empty cells \
         (a header line that starts with the comment character is skipped as a comment)",
        path.display()
    )]
    MissingHeader {
        /// The file.
        path: PathBuf,
        /// 1-based line of the would-be header.
        line: usize,
    },
    /// A requested column is not in the header.
    #[error(
        "{}:{line}: no column \"{column}\" in the header; available columns: {}",
        path.display(),
        quoted_list(available)
    )]
    MissingColumn {
        /// The file.
        path: PathBuf,
        /// 1-based line of the header.
        line: usize,
        /// The requested name.
        column: String,
        /// The non-empty names the header does have, in order.
        available: Vec<String>,
    },
    /// A requested column name occurs twice in the header, so the choice is ambiguous.
    #[error(
        "{}:{line}: column \"{column}\" appears more than once in the header (cells {first} and {second})",
        path.display()
    )]
    DuplicateColumn {
        /// The file.
        path: PathBuf,
        /// 1-based line of the header.
        line: usize,
        /// The ambiguous name.
        column: String,
        /// 1-based position of its first occurrence.
        first: usize,
        /// 1-based position of its second occurrence.
        second: usize,
    },
    /// A data row has a different number of cells than the header.
    #[error("{}:{line}: expected {expected} cells as in the header, found {found}", path.display())]
    CellCount {
        /// The file.
        path: PathBuf,
        /// 1-based line of the row.
        line: usize,
        /// Number of header columns.
        expected: usize,
        /// Number of cells in the row.
        found: usize,
    },
    /// A quoted cell is not closed, or text follows its closing quote.
    #[error(
        "{}:{line}: malformed quoted cell (a quote is not closed, or text follows a closing quote)",
        path.display()
    )]
    BadQuote {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
    },
    /// A cell of a used column is not a number.
    #[error("{}:{line}: column {column}: cannot parse \"{value}\" as a number", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// The column.
        column: ColumnId,
        /// The cell's text (trimmed, without quotes).
        value: String,
    },
    /// A value of a used column is NaN or infinite (or overflows `f64`, like `1e400`).
    #[error("{}{location}: column {column}: value \"{value}\" is not a finite number", path.display())]
    NonFinite {
        /// The file.
        path: PathBuf,
        /// Line (text) or row (binary) of the value.
        location: Location,
        /// The column.
        column: ColumnId,
        /// The value as written in the file, or as formatted from the binary value.
        value: String,
    },
    /// A time is not strictly after the one before it.
    #[error(
        "{}{location}: column {column}: time {found} s is not after the previous time {previous} s",
        path.display()
    )]
    NonMonotonicTime {
        /// The file.
        path: PathBuf,
        /// Line (text) or row (binary) of the offending time.
        location: Location,
        /// The time column.
        column: ColumnId,
        /// The time before it, in s.
        previous: f64,
        /// The offending time, in s.
        found: f64,
    },
    /// A time step differs from the typical (median) step by more than the tolerance.
    #[error(
        "{}{location}: column {column}: time step {found_dt} s differs from the expected {expected_dt} s \
         by more than the relative tolerance {tolerance:e} ({})",
        path.display(),
        step_advice(*found_dt, *expected_dt)
    )]
    NonUniformTime {
        /// The file.
        path: PathBuf,
        /// Line (text) or row (binary) of the time that ends the offending step.
        location: Location,
        /// The time column.
        column: ColumnId,
        /// The step found there, in s.
        found_dt: f64,
        /// The median step of the whole record, in s.
        expected_dt: f64,
        /// The relative tolerance in force.
        tolerance: f64,
    },
    /// Fewer samples than the spec's minimum (never fewer than 2, which a sample step needs).
    #[error("{}: {found} data rows, at least {min} needed", path.display())]
    TooFewSamples {
        /// The file.
        path: PathBuf,
        /// Data rows found.
        found: usize,
        /// Minimum required.
        min: usize,
    },
    /// The sample rate is zero, negative, NaN or infinite.
    #[error("sample rate must be finite and > 0 (got {rate_hz} Hz)")]
    InvalidSampleRate {
        /// The rate given, in Hz.
        rate_hz: f64,
    },
    /// The sample step is zero, negative, NaN or infinite.
    #[error("sample step must be finite and > 0 (got {dt} s)")]
    InvalidStep {
        /// The step given, in s.
        dt: f64,
    },
    /// A series was given no output.
    #[error("{}: a record needs at least one output", path.display())]
    NoOutputs {
        /// Where the data came from.
        path: PathBuf,
    },
    /// Series joined into one record have different times or inputs.
    #[error(
        "{}: output {} was read with other times or another input than the outputs before it",
        path.display(),
        output + 1
    )]
    OutputsDisagree {
        /// Where the disagreeing series came from.
        path: PathBuf,
        /// 0-based index the output would have had.
        output: usize,
    },
    /// The start time is NaN or infinite.
    #[error("start time must be finite (got {start} s)")]
    InvalidStartTime {
        /// The start time given, in s.
        start: f64,
    },
    /// The relative time tolerance is negative, NaN or infinite.
    #[error("relative time tolerance must be finite and >= 0 (got {tolerance})")]
    InvalidTolerance {
        /// The tolerance given.
        tolerance: f64,
    },
    /// The comment character would make data lines or quoted cells ambiguous.
    #[error("comment character {comment:?} clashes with the delimiter, the quote or whitespace")]
    InvalidComment {
        /// The character given.
        comment: char,
    },
    /// The `.npy` file is malformed (magic, version, header).
    #[error("{}: not a valid .npy file: {reason}", path.display())]
    NpyFormat {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// The `.npy` file is valid but holds an array this crate does not read.
    #[error("{}: unsupported .npy array: {what}", path.display())]
    NpyUnsupported {
        /// The file.
        path: PathBuf,
        /// What is unsupported and how to convert it.
        what: String,
    },
    /// A column index beyond the array's columns.
    #[error(
        "{}: column index {index} out of range: the array has {columns} columns (indices are 0-based)",
        path.display()
    )]
    NpyColumn {
        /// The file.
        path: PathBuf,
        /// The index requested.
        index: usize,
        /// Columns in the array.
        columns: usize,
    },
    /// The data section is shorter or longer than the header's shape and dtype imply.
    #[error("{}: the .npy header promises {expected} data bytes, the file holds {found}", path.display())]
    NpyDataLength {
        /// The file.
        path: PathBuf,
        /// Bytes implied by shape and dtype.
        expected: u64,
        /// Bytes present after the header.
        found: u64,
    },
    /// The `.npz` file is not a ZIP archive numpy could have written, or is damaged.
    #[error("{}: not a valid .npz (ZIP) file: {reason}", path.display())]
    ZipFormat {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// The `.npz` archive uses a ZIP feature this crate does not read.
    #[error("{}: unsupported .npz archive: {what}", path.display())]
    ZipUnsupported {
        /// The file.
        path: PathBuf,
        /// What is unsupported.
        what: String,
    },
    /// The MAT-file is malformed.
    #[error("{}: not a valid MAT-file: {reason}", path.display())]
    MatFormat {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// The MAT-file is of a version this crate does not read (v4, v7.3).
    #[error("{}: unsupported MAT-file: {what}", path.display())]
    MatUnsupported {
        /// The file.
        path: PathBuf,
        /// What is unsupported and how to save the file instead.
        what: String,
    },
    /// A column name that a binary file (`.npy`, `.npz`, MAT) does not hold.
    #[error(
        "{}: no column \"{column}\" in the {format}; it holds {}{}",
        path.display(),
        if available.is_empty() { "no named column".to_owned() } else { quoted_list(available) },
        if hint.is_empty() { String::new() } else { format!(" ({hint})") }
    )]
    NoSuchColumn {
        /// The file.
        path: PathBuf,
        /// The file's format.
        format: crate::Format,
        /// The requested name.
        column: String,
        /// The columns the file does hold.
        available: Vec<String>,
        /// Matrices not chosen, unnamed columns, unreadable variables.
        hint: String,
    },
    /// The matrix named by the spec is not in the file (or cannot be read).
    #[error(
        "{}: no readable matrix \"{matrix}\" in the {format}{}; it holds {}",
        path.display(),
        why.as_ref().map(|w| format!(" (it {w})")).unwrap_or_default(),
        quoted_list(available)
    )]
    NoSuchMatrix {
        /// The file.
        path: PathBuf,
        /// The file's format.
        format: crate::Format,
        /// The requested member or variable.
        matrix: String,
        /// The readable members or variables.
        available: Vec<String>,
        /// Why a variable of that name cannot be read, when it exists.
        why: Option<String>,
    },
    /// Column names were given but the file has no single matrix to give them to.
    #[error(
        "{}: column names are given for a matrix, but the {format} holds several: {}; name \
         the matrix to use",
        path.display(),
        quoted_list(matrices)
    )]
    WhichMatrix {
        /// The file.
        path: PathBuf,
        /// The file's format.
        format: crate::Format,
        /// The matrices the file holds.
        matrices: Vec<String>,
    },
    /// The number of column names differs from the matrix's columns.
    #[error(
        "{}: {named} column names given, but the {format} matrix{} is {rows}x{cols} \
         (one sample per row, one signal per column{})",
        path.display(),
        if matrix.is_empty() { String::new() } else { format!(" \"{matrix}\"") },
        if *rows == *named && *rows != *cols { "; it looks transposed: save its transpose" } else { "" }
    )]
    ColumnNames {
        /// The file.
        path: PathBuf,
        /// The file's format.
        format: crate::Format,
        /// The matrix's member or variable name (empty for a `.npy` file).
        matrix: String,
        /// Names given.
        named: usize,
        /// Rows of the matrix.
        rows: usize,
        /// Columns of the matrix.
        cols: usize,
    },
    /// Two columns of a binary file share a name (a vector and a named matrix column).
    #[error("{}: two columns are named \"{column}\"; rename one", path.display())]
    AmbiguousColumn {
        /// The file.
        path: PathBuf,
        /// The shared name.
        column: String,
    },
    /// Two used columns of a binary file differ in length.
    #[error(
        "{}: column {first} has {first_len} values but column {second} has {second_len} \
         (every signal needs one value per sample)",
        path.display()
    )]
    ColumnLengths {
        /// The file.
        path: PathBuf,
        /// The input column.
        first: ColumnId,
        /// Its length.
        first_len: usize,
        /// The column of another length.
        second: ColumnId,
        /// Its length.
        second_len: usize,
    },
    /// A requested column is not in the header, and the header looks separated by another
    /// character than the delimiter in use.
    #[error(
        "{}:{line}: no column \"{column}\" in the header {header:?}: it looks {} but cells are \
         split at {}; set the delimiter to {}",
        path.display(),
        match found { ';' => "semicolon-separated", '\t' => "tab-separated", _ => "comma-separated" },
        used.describe(),
        crate::Delimiter::for_char(*found).map(|d| d.describe()).unwrap_or_default()
    )]
    LooksDelimited {
        /// The file.
        path: PathBuf,
        /// 1-based line of the header.
        line: usize,
        /// The requested name.
        column: String,
        /// The header line as read.
        header: String,
        /// The separator the header seems to use.
        found: char,
        /// The delimiter in use.
        used: crate::Delimiter,
    },
    /// Two vectors that must have one value per sample differ in length.
    #[error("{}: column \"{column}\" has {found} values, the time vector has {expected}", path.display())]
    LengthMismatch {
        /// The source or target file.
        path: PathBuf,
        /// The column.
        column: String,
        /// Length of the time vector.
        expected: usize,
        /// Length of the column.
        found: usize,
    },
    /// A row handed to a CSV writer has the wrong number of values.
    #[error("{}: row {row} has {found} values, the header has {expected} columns", path.display())]
    RowLength {
        /// The target file.
        path: PathBuf,
        /// 0-based data row.
        row: usize,
        /// Header columns.
        expected: usize,
        /// Values given.
        found: usize,
    },
    /// A CSV writer was given no columns.
    #[error("{}: a CSV file needs at least one column", path.display())]
    EmptyHeader {
        /// The target file.
        path: PathBuf,
    },
    /// A sample range outside the series or shorter than two samples.
    #[error("sample range {start}..{end} is not a range of at least 2 samples within 0..{len}")]
    InvalidRange {
        /// First sample (inclusive).
        start: usize,
        /// Last sample (exclusive).
        end: usize,
        /// Samples in the series.
        len: usize,
    },
    /// The output path exists but is not a directory.
    #[error("output path {} exists and is not a directory", path.display())]
    NotADirectory {
        /// The path.
        path: PathBuf,
    },
    /// The output directory holds files the run would write that are not earlier results of
    /// htfid's (not in its manifest, or changed since), and overwriting was not asked for.
    #[error(
        "output directory {} already holds files this run would write that htfid did not write \
         or that changed since: {}{}; allow overwriting or choose another directory",
        dir.display(),
        quoted_list(files),
        manifest_problem.as_ref().map_or(String::new(), |p| format!(
            " (its manifest .htfid-manifest.json cannot be read: {p})"
        ))
    )]
    WouldOverwrite {
        /// The output directory.
        dir: PathBuf,
        /// The clashing files, relative to the directory.
        files: Vec<String>,
        /// Why the directory's manifest could not be used, when it could not.
        manifest_problem: Option<String>,
    },
    /// Another run holds the output directory's lock.
    #[error(
        "output directory {} is in use by another htfid run ({}); wait for it to finish or \
         choose another directory",
        dir.display(),
        pid.map_or("pid unknown".to_string(), |p| format!("pid {p}"))
    )]
    Locked {
        /// The output directory.
        dir: PathBuf,
        /// The process holding the lock, when it could be read.
        pid: Option<u32>,
    },
    /// The run was stopped (by a signal) before it committed its files.
    #[error("the run writing into {} was stopped; nothing was committed", dir.display())]
    Abandoned {
        /// The output directory.
        dir: PathBuf,
    },
    /// Moving the run's files into place failed; the message says what state is left.
    #[error(
        "could not move the results into {}: {}: {source}; {}",
        dir.display(),
        path.display(),
        commit_state(dir, unrestored, backup)
    )]
    Commit {
        /// The output directory.
        dir: PathBuf,
        /// The file or directory whose move failed.
        path: PathBuf,
        /// The operating system's reason.
        source: io::Error,
        /// Earlier files that could not be put back (relative to `dir`); empty when the
        /// directory was restored.
        unrestored: Vec<String>,
        /// Where the files that could not be put back are.
        backup: PathBuf,
    },
    /// An output name that is empty, absolute, or leaves the output directory.
    #[error("output name \"{name}\" must be a relative file path inside the output directory")]
    InvalidOutputName {
        /// The name given.
        name: String,
    },
    /// The same output file is written twice in one run.
    #[error("output \"{name}\" is written twice in one run")]
    DuplicateOutput {
        /// The name given.
        name: String,
    },
}

fn commit_state(dir: &std::path::Path, unrestored: &[String], backup: &std::path::Path) -> String {
    if unrestored.is_empty() {
        format!(
            "{} was restored: it holds its earlier files and nothing of this run",
            dir.display()
        )
    } else {
        format!(
            "nothing of this run is in {}, but earlier files could not be put back: {} \
             (they are in {}; the next htfid run in this directory puts them back)",
            dir.display(),
            quoted_list(unrestored),
            backup.display()
        )
    }
}

/// The samples missing where a time step `found` stands for a whole multiple (2 or more, within
/// 5 % of a step) of the `expected` one: a gap, which no tolerance mends. `None` otherwise.
pub fn missing_samples(found: f64, expected: f64) -> Option<u64> {
    let ratio = found / expected;
    let whole = ratio.round();
    ((2.0..1e15).contains(&whole) && (ratio - whole).abs() < 0.05).then(|| whole as u64 - 1)
}

/// What to do about a time step `found` where `expected` was due.
fn step_advice(found: f64, expected: f64) -> String {
    match missing_samples(found, expected) {
        Some(missing) => format!(
            "{missing} sample(s) missing before this one; the data must be uniformly sampled, so \
             fill the gap or cut the record there (a tolerance does not mend a gap)"
        ),
        None => "the data must be uniformly sampled; if the times are printed with few digits, \
                 raise the time tolerance or give the sample rate instead"
            .to_string(),
    }
}
