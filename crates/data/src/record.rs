//! One reader for every measurement format: the format is told from the file's first bytes, the
//! columns are found by name, and every format ends in the same checks ([`assemble`]).

use std::fmt;
use std::fs;
use std::path::{Path, PathBuf};

use crate::csv_read::{read_csv_bytes, CsvSpec, Delimiter, TimeSource};
use crate::error::{ColumnId, DataError, Location};
use crate::series::{
    check_count, check_rate, check_tolerance, check_uniform, uniform_times, TimeSeries,
    DEFAULT_TIME_TOLERANCE,
};
use crate::{mat, npy, zip};

/// The file formats [`read_record`] reads. The format is told from the content, never from the
/// file name, so a `.txt` CSV or a `.dat` NPY file reads the same.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Format {
    /// Delimited text with a header of column names.
    Csv,
    /// A NumPy `.npy` array: columns by 0-based index, or named by [`RecordSpec::columns`].
    Npy,
    /// A NumPy `.npz` archive (`numpy.savez`, `savez_compressed`): members by name.
    Npz,
    /// A MATLAB level-5 MAT-file (`save -v7`, `-v6`; `scipy.io.savemat`): variables by name.
    Mat,
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Format::Csv => "CSV",
            Format::Npy => ".npy",
            Format::Npz => ".npz",
            Format::Mat => "MAT-file",
        })
    }
}

impl Format {
    /// The format of a file that starts with `bytes` (its first 8 bytes suffice).
    pub fn sniff(bytes: &[u8]) -> Format {
        if bytes.starts_with(b"\x93NUMPY") {
            Format::Npy
        } else if bytes.starts_with(b"PK\x03\x04") || bytes.starts_with(b"PK\x05\x06") {
            Format::Npz
        } else if mat::looks_like_mat(bytes) || bytes.starts_with(b"\x89HDF") {
            Format::Mat
        } else {
            Format::Csv
        }
    }
}

/// What to read from a measurement file of any [`Format`]: the time, input and output columns
/// by name, and the options of the formats that need them.
///
/// Names are CSV header names, `.npz` member names (without `.npy`), or MAT variable names; a
/// vector (`(n,)`, `(n, 1)` or `(1, n)`) is one column. The columns of a 2-D array (the array
/// of a `.npy` file, or the `.npz` member or MAT variable named by [`RecordSpec::matrix`]) are
/// named in order by [`RecordSpec::columns`], or by their 0-based indices `"0"`, `"1"`, ...
#[derive(Debug, Clone, PartialEq)]
pub struct RecordSpec {
    /// The time column, or a sample rate when the file has none.
    pub time: TimeSource<String>,
    /// Name of the input column.
    pub input: String,
    /// Name of the output column.
    pub output: String,
    /// Fewer samples than this is an error. Values below 2 act as 2.
    pub min_samples: usize,
    /// Relative tolerance on each time step against the median step (default 1e-6).
    pub time_tolerance: f64,
    /// CSV only: the cell separator ([`Delimiter::Comma`] by default).
    pub delimiter: Delimiter,
    /// CSV only: the comment character (`#` by default).
    pub comment: Option<char>,
    /// `.npz` and MAT only: the member or variable that holds a matrix of signals, one per
    /// column. Without it, the one matrix in the file is used when `columns` is given.
    pub matrix: Option<String>,
    /// Binary formats: names of the matrix's columns, in order.
    pub columns: Option<Vec<String>>,
}

impl Default for RecordSpec {
    fn default() -> Self {
        Self {
            time: TimeSource::Column("t".to_owned()),
            input: "f".to_owned(),
            output: "x".to_owned(),
            min_samples: 2,
            time_tolerance: DEFAULT_TIME_TOLERANCE,
            delimiter: Delimiter::Comma,
            comment: Some('#'),
            matrix: None,
            columns: None,
        }
    }
}

impl RecordSpec {
    /// The input and output columns by name.
    pub fn with_columns(mut self, input: impl Into<String>, output: impl Into<String>) -> Self {
        self.input = input.into();
        self.output = output.into();
        self
    }

    /// Times from the named column.
    pub fn with_time_column(mut self, name: impl Into<String>) -> Self {
        self.time = TimeSource::Column(name.into());
        self
    }

    /// No time column: uniform samples at `rate_hz`, the first at `start` s.
    pub fn with_sample_rate(mut self, rate_hz: f64, start: f64) -> Self {
        self.time = TimeSource::SampleRate { rate_hz, start };
        self
    }

    /// The CSV cell separator.
    pub fn with_delimiter(mut self, delimiter: Delimiter) -> Self {
        self.delimiter = delimiter;
        self
    }

    /// The member or variable holding a matrix of signals.
    pub fn with_matrix(mut self, name: impl Into<String>) -> Self {
        self.matrix = Some(name.into());
        self
    }

    /// Names of the matrix's columns, in order.
    pub fn with_matrix_columns(mut self, names: Vec<String>) -> Self {
        self.columns = Some(names);
        self
    }

    /// The minimum number of samples.
    pub fn with_min_samples(mut self, min_samples: usize) -> Self {
        self.min_samples = min_samples;
        self
    }

    /// The relative tolerance on time steps.
    pub fn with_time_tolerance(mut self, tolerance: f64) -> Self {
        self.time_tolerance = tolerance;
        self
    }

    fn csv(&self) -> CsvSpec {
        CsvSpec {
            time: self.time.clone(),
            input: self.input.clone(),
            output: self.output.clone(),
            comment: self.comment,
            delimiter: self.delimiter,
            min_samples: self.min_samples,
            time_tolerance: self.time_tolerance,
        }
    }
}

/// Reads a uniformly sampled input/output record from a file of any [`Format`], told from its
/// first bytes. CSV files are read as [`read_csv`](crate::read_csv) reads them; binary files
/// give 0-based rows in messages. Every format passes the same checks: finite values, equal
/// lengths, strictly increasing and uniform times, at least `min_samples` samples.
pub fn read_record(path: impl AsRef<Path>, spec: &RecordSpec) -> Result<TimeSeries, DataError> {
    let path = path.as_ref();
    check_tolerance(spec.time_tolerance)?;
    if let TimeSource::SampleRate { rate_hz, start } = spec.time {
        check_rate(rate_hz, start)?;
    }
    let bytes = fs::read(path).map_err(|source| DataError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    let format = Format::sniff(&bytes);
    let (vars, unreadable): (Vec<Variable>, Vec<(String, String)>) = match format {
        Format::Csv => return read_csv_bytes(&bytes, path, &spec.csv()),
        Format::Npy => {
            let array = npy::parse_npy(&bytes, path, false)?;
            (vec![array.into_variable(String::new())], Vec::new())
        }
        Format::Npz => {
            let mut vars = Vec::new();
            let mut unreadable = Vec::new();
            let members = zip::read_members(&bytes, path)?;
            // Spreadsheet workbooks (.xlsx, .ods) are ZIP archives too.
            if !members.iter().any(|m| m.name.ends_with(".npy")) {
                return Err(DataError::ZipUnsupported {
                    path: path.to_path_buf(),
                    what: "a ZIP archive without .npy members is not an .npz (a spreadsheet \
                           workbook? export the sheet as CSV)"
                        .to_owned(),
                });
            }
            for member in members {
                let name = member
                    .name
                    .strip_suffix(".npy")
                    .unwrap_or(&member.name)
                    .to_owned();
                let member_path = PathBuf::from(format!("{}[{}]", path.display(), member.name));
                match npy::parse_npy(&member.data, &member_path, true) {
                    Ok(array) => vars.push(array.into_variable(name)),
                    // An unreadable member matters only when it is asked for.
                    Err(e) => unreadable.push((name, e.to_string())),
                }
            }
            (vars, unreadable)
        }
        Format::Mat => {
            let (vars, skipped) = mat::parse_mat(&bytes, path)?;
            let unreadable = skipped.into_iter().map(|s| (s.name, s.why)).collect();
            (vars, unreadable)
        }
    };
    let table = name_columns(path, format, &vars, &unreadable, spec)?;
    let find = |name: &str| -> Result<Picked<'_>, DataError> {
        let c = table.find(name).ok_or_else(|| DataError::NoSuchColumn {
            path: path.to_path_buf(),
            format,
            column: name.to_owned(),
            available: table.columns.iter().map(|c| c.name.clone()).collect(),
            hint: table.hint.clone(),
        })?;
        Ok(Picked {
            id: ColumnId::Name(c.name.clone()),
            values: c.values,
            eps: c.eps,
        })
    };
    let (time, eps) = match &spec.time {
        TimeSource::Column(name) => {
            let c = find(name)?;
            let eps = c.eps;
            (TimeSource::Column(c), eps)
        }
        &TimeSource::SampleRate { rate_hz, start } => {
            (TimeSource::SampleRate { rate_hz, start }, f64::EPSILON)
        }
    };
    let input = find(&spec.input)?;
    let output = find(&spec.output)?;
    assemble(
        path,
        time,
        input,
        output,
        eps,
        spec.min_samples,
        spec.time_tolerance,
    )
}

/// A numeric array of a binary file: a `.npz` member, a MAT variable, or the array of a `.npy`
/// file. `data` is column-major: column `j` is `data[j * rows..(j + 1) * rows]`.
#[derive(Debug)]
pub(crate) struct Variable {
    pub name: String,
    pub rows: usize,
    pub cols: usize,
    pub data: Vec<f64>,
    /// Machine epsilon of the stored values (bounds the rounding of stored times).
    pub eps: f64,
}

impl Variable {
    fn is_vector(&self) -> bool {
        self.rows == 1 || self.cols == 1
    }

    fn column(&self, j: usize) -> &[f64] {
        &self.data[j * self.rows..(j + 1) * self.rows]
    }
}

/// One named column of a binary file.
#[derive(Debug)]
struct Named<'a> {
    name: String,
    values: &'a [f64],
    eps: f64,
}

/// The named columns of a binary file, and what to say when a name is not among them.
#[derive(Debug)]
struct Table<'a> {
    columns: Vec<Named<'a>>,
    hint: String,
}

impl<'a> Table<'a> {
    fn find(&self, name: &str) -> Option<&Named<'a>> {
        self.columns.iter().find(|c| c.name == name)
    }
}

fn name_columns<'a>(
    path: &Path,
    format: Format,
    vars: &'a [Variable],
    unreadable: &[(String, String)],
    spec: &RecordSpec,
) -> Result<Table<'a>, DataError> {
    let mut columns = Vec::new();
    let mut hints = Vec::new();
    let matrix: Option<&Variable> = match (format, &spec.matrix, &spec.columns) {
        (Format::Npy, _, _) => vars.first(),
        (_, Some(name), _) => match vars.iter().find(|v| &v.name == name) {
            Some(v) => Some(v),
            None => {
                let why = unreadable.iter().find(|(n, _)| n == name);
                return Err(DataError::NoSuchMatrix {
                    path: path.to_path_buf(),
                    format,
                    matrix: name.clone(),
                    available: vars.iter().map(|v| v.name.clone()).collect(),
                    why: why.map(|(_, w)| w.clone()),
                });
            }
        },
        (_, None, Some(_)) => {
            let matrices: Vec<&Variable> = vars.iter().filter(|v| !v.is_vector()).collect();
            match matrices.as_slice() {
                // A file of vectors names its columns itself; the names serve the one config
                // that reads a record saved in several formats.
                [] => None,
                [one] => Some(*one),
                _ => {
                    return Err(DataError::WhichMatrix {
                        path: path.to_path_buf(),
                        format,
                        matrices: matrices.iter().map(|v| v.name.clone()).collect(),
                    })
                }
            }
        }
        (_, None, None) => None,
    };
    for v in vars {
        let chosen = matrix.is_some_and(|m| std::ptr::eq(m, v));
        if !chosen && v.is_vector() {
            columns.push(Named {
                name: v.name.clone(),
                values: &v.data,
                eps: v.eps,
            });
        } else if !chosen {
            hints.push(format!(
                "\"{}\" is a {}x{} matrix (choose it with `matrix` and name its columns with \
                 `columns`)",
                v.name, v.rows, v.cols
            ));
        }
    }
    if let Some(m) = matrix {
        match &spec.columns {
            Some(names) if names.len() != m.cols => {
                return Err(DataError::ColumnNames {
                    path: path.to_path_buf(),
                    format,
                    matrix: m.name.clone(),
                    named: names.len(),
                    rows: m.rows,
                    cols: m.cols,
                })
            }
            Some(names) => {
                for (j, name) in names.iter().enumerate() {
                    columns.push(Named {
                        name: name.clone(),
                        values: m.column(j),
                        eps: m.eps,
                    });
                }
            }
            None => {
                for j in 0..m.cols {
                    columns.push(Named {
                        name: j.to_string(),
                        values: m.column(j),
                        eps: m.eps,
                    });
                }
                hints.push(format!(
                    "the {} columns of the {} are unnamed: name them in order with `columns`, or \
                     use their 0-based indices",
                    m.cols,
                    if format == Format::Npy {
                        "array".to_owned()
                    } else {
                        format!("matrix \"{}\"", m.name)
                    }
                ));
            }
        }
    }
    for (name, why) in unreadable {
        hints.push(format!("\"{name}\" is not readable: {why}"));
    }
    // Two columns of one name make every choice ambiguous; refuse whether or not it is used.
    for (i, c) in columns.iter().enumerate() {
        if columns[..i].iter().any(|d| d.name == c.name) {
            return Err(DataError::AmbiguousColumn {
                path: path.to_path_buf(),
                column: c.name.clone(),
            });
        }
    }
    Ok(Table {
        columns,
        hint: hints.join("; "),
    })
}

/// A column chosen for the record, as the messages name it.
#[derive(Debug)]
pub(crate) struct Picked<'a> {
    pub id: ColumnId,
    pub values: &'a [f64],
    /// Machine epsilon of the stored values.
    pub eps: f64,
}

/// The checks every binary format shares: equal lengths, enough samples, finite values (0-based
/// rows in messages), strictly increasing uniform times; `eps` is the rounding of stored times.
pub(crate) fn assemble(
    path: &Path,
    time: TimeSource<Picked<'_>>,
    input: Picked<'_>,
    output: Picked<'_>,
    eps: f64,
    min_samples: usize,
    tolerance: f64,
) -> Result<TimeSeries, DataError> {
    let rows = input.values.len();
    let time_col = match &time {
        TimeSource::Column(c) => Some(c),
        TimeSource::SampleRate { .. } => None,
    };
    for c in std::iter::once(&output).chain(time_col) {
        if c.values.len() != rows {
            return Err(DataError::ColumnLengths {
                path: path.to_path_buf(),
                first: input.id.clone(),
                first_len: rows,
                second: c.id.clone(),
                second_len: c.values.len(),
            });
        }
    }
    check_count(path, rows, min_samples.max(2))?;
    for c in [&input, &output].into_iter().chain(time_col) {
        if let Some(row) = c.values.iter().position(|v| !v.is_finite()) {
            return Err(DataError::NonFinite {
                path: path.to_path_buf(),
                location: Location::Row(row),
                column: c.id.clone(),
                value: c.values[row].to_string(),
            });
        }
    }
    let (times, dt) = match time {
        TimeSource::Column(c) => {
            let dt = check_uniform(c.values, tolerance, eps)
                .map_err(|fault| fault.into_error(path, c.id.clone(), Location::Row))?;
            (c.values.to_vec(), dt)
        }
        TimeSource::SampleRate { rate_hz, start } => {
            let dt = check_rate(rate_hz, start)?;
            (uniform_times(start, dt, rows), dt)
        }
    };
    Ok(TimeSeries::from_checked(
        times,
        input.values.to_vec(),
        vec![output.values.to_vec()],
        dt,
        path.to_path_buf(),
    ))
}
