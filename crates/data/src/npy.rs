use std::fs;
use std::path::Path;

use crate::csv_read::TimeSource;
use crate::error::{ColumnId, DataError};
use crate::record::{assemble, Picked};
use crate::series::{check_rate, check_tolerance, TimeSeries, DEFAULT_TIME_TOLERANCE};

/// What to read from a `.npy` file: columns of a 2-D array by 0-based index.
/// [`NpySpec::default`] mirrors the CSV format: column 0 time (s), 1 input, 2 output.
#[derive(Debug, Clone, PartialEq)]
pub struct NpySpec {
    /// The time column, or a sample rate when the array has none.
    pub time: TimeSource<usize>,
    /// Column index of the input.
    pub input: usize,
    /// Column index of the output.
    pub output: usize,
    /// Fewer rows than this is an error. Values below 2 act as 2.
    pub min_samples: usize,
    /// Relative tolerance on each time step against the median step (default 1e-6).
    pub time_tolerance: f64,
}

impl Default for NpySpec {
    fn default() -> Self {
        Self {
            time: TimeSource::Column(0),
            input: 1,
            output: 2,
            min_samples: 2,
            time_tolerance: DEFAULT_TIME_TOLERANCE,
        }
    }
}

impl NpySpec {
    /// Times from column `time`, input and output from columns `input` and `output`.
    pub fn with_time_column(time: usize, input: usize, output: usize) -> Self {
        Self {
            time: TimeSource::Column(time),
            input,
            output,
            ..Self::default()
        }
    }

    /// No time column: uniform samples at `rate_hz` from `start` s; input and output by index.
    pub fn with_sample_rate(rate_hz: f64, start: f64, input: usize, output: usize) -> Self {
        Self {
            time: TimeSource::SampleRate { rate_hz, start },
            input,
            output,
            ..Self::default()
        }
    }

    /// The minimum number of rows.
    pub fn with_min_samples(mut self, min_samples: usize) -> Self {
        self.min_samples = min_samples;
        self
    }

    /// The relative tolerance on time steps.
    pub fn with_time_tolerance(mut self, tolerance: f64) -> Self {
        self.time_tolerance = tolerance;
        self
    }
}

const MAGIC: &[u8] = b"\x93NUMPY";

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Float {
    F8,
    F4,
}

impl Float {
    /// Machine epsilon of the stored values, which bounds the rounding of stored times.
    fn eps(self) -> f64 {
        match self {
            Float::F8 => f64::EPSILON,
            Float::F4 => f64::from(f32::EPSILON),
        }
    }

    fn size(self) -> usize {
        match self {
            Float::F8 => 8,
            Float::F4 => 4,
        }
    }
}

/// Reads a uniformly sampled input/output record from a NumPy `.npy` file.
///
/// Accepted: format versions 1.0, 2.0 and 3.0; dtype little-endian float64 (`<f8`) or float32
/// (`<f4`, widened exactly to `f64`); C order; a 2-D shape `(samples, columns)`. Anything else
/// is refused with a message saying how to convert it. Errors give 0-based rows.
pub fn read_npy(path: impl AsRef<Path>, spec: &NpySpec) -> Result<TimeSeries, DataError> {
    let path = path.as_ref();
    check_tolerance(spec.time_tolerance)?;
    if let TimeSource::SampleRate { rate_hz, start } = spec.time {
        check_rate(rate_hz, start)?;
    }
    let bytes = fs::read(path).map_err(|source| DataError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    let array = parse_npy(&bytes, path, false)?;
    let cols = array.columns.len();
    for index in [spec.input, spec.output]
        .into_iter()
        .chain(match spec.time {
            TimeSource::Column(index) => Some(index),
            TimeSource::SampleRate { .. } => None,
        })
    {
        if index >= cols {
            return Err(DataError::NpyColumn {
                path: path.to_path_buf(),
                index,
                columns: cols,
            });
        }
    }
    let column = |index: usize| Picked {
        id: ColumnId::Index(index),
        values: &array.columns[index],
        eps: array.eps,
    };
    assemble(
        path,
        match spec.time {
            TimeSource::Column(index) => TimeSource::Column(column(index)),
            TimeSource::SampleRate { rate_hz, start } => TimeSource::SampleRate { rate_hz, start },
        },
        column(spec.input),
        column(spec.output),
        array.eps,
        spec.min_samples,
        spec.time_tolerance,
    )
}

/// A numeric array decoded from a `.npy` stream: one `f64` vector per column (a 1-D array is
/// one column), and the machine epsilon of the stored values.
#[derive(Debug)]
pub(crate) struct NpyArray {
    pub rows: usize,
    pub columns: Vec<Vec<f64>>,
    pub eps: f64,
}

impl NpyArray {
    /// The array as a named variable (column-major).
    pub(crate) fn into_variable(self, name: String) -> crate::record::Variable {
        let cols = self.columns.len();
        crate::record::Variable {
            name,
            rows: self.rows,
            cols,
            data: self.columns.into_iter().flatten().collect(),
            eps: self.eps,
        }
    }
}

/// Decodes the `.npy` bytes of `path` (a file, or a member of an `.npz` named like a file).
/// `allow_1d` accepts a 1-D shape `(n,)` as one column, as `.npz` members of single signals are.
pub(crate) fn parse_npy(bytes: &[u8], path: &Path, allow_1d: bool) -> Result<NpyArray, DataError> {
    let format_err = |reason: String| DataError::NpyFormat {
        path: path.to_path_buf(),
        reason,
    };
    let unsupported = |what: String| DataError::NpyUnsupported {
        path: path.to_path_buf(),
        what,
    };

    if bytes.len() < 10 || &bytes[..6] != MAGIC {
        return Err(format_err(
            "it does not start with the magic bytes \\x93NUMPY".to_owned(),
        ));
    }
    let (major, minor) = (bytes[6], bytes[7]);
    let (header_len, header_start) = match major {
        1 => (usize::from(u16::from_le_bytes([bytes[8], bytes[9]])), 10),
        2 | 3 => {
            let Some(len) = bytes.get(8..12) else {
                return Err(format_err("the file ends inside the preamble".to_owned()));
            };
            let len = u32::from_le_bytes([len[0], len[1], len[2], len[3]]);
            (
                usize::try_from(len).map_err(|_| format_err("header too long".to_owned()))?,
                12,
            )
        }
        _ => {
            return Err(format_err(format!(
                "format version {major}.{minor} is unknown (1.0, 2.0 and 3.0 are read)"
            )))
        }
    };
    let data_start = header_start + header_len;
    let Some(header) = bytes.get(header_start..data_start) else {
        return Err(format_err(format!(
            "the header claims {header_len} bytes but the file ends before"
        )));
    };
    let header =
        std::str::from_utf8(header).map_err(|_| format_err("the header is not text".to_owned()))?;
    let dict = parse_header(header).map_err(|e| format_err(format!("header {header:?}: {e}")))?;

    let descr = match dict.get("descr") {
        Some(Value::Str(s)) => s.as_str(),
        Some(_) => {
            return Err(unsupported(
                "structured dtype; save a plain 2-D float array, one column per signal".to_owned(),
            ))
        }
        None => return Err(format_err("the header has no 'descr'".to_owned())),
    };
    let float = match descr {
        "<f8" => Float::F8,
        "<f4" => Float::F4,
        ">f8" | ">f4" => {
            return Err(unsupported(format!(
                "big-endian dtype '{descr}'; convert with arr.astype('<f8')"
            )))
        }
        other => {
            return Err(unsupported(format!(
                "dtype '{other}'; only little-endian float64 '<f8' and float32 '<f4' are read, \
                 convert with arr.astype('<f8')"
            )))
        }
    };
    match dict.get("fortran_order") {
        Some(Value::Bool(false)) => {}
        Some(Value::Bool(true)) => {
            return Err(unsupported(
                "Fortran (column-major) order; save np.ascontiguousarray(arr) instead".to_owned(),
            ))
        }
        _ => {
            return Err(format_err(
                "the header has no boolean 'fortran_order'".to_owned(),
            ))
        }
    }
    let (rows, cols) = match dict.get("shape") {
        Some(Value::Tuple(dims)) => {
            let dims: Option<Vec<u64>> = dims
                .iter()
                .map(|d| match d {
                    Value::Int(v) => Some(*v),
                    _ => None,
                })
                .collect();
            match dims.as_deref() {
                Some(&[r, c]) => (r, c),
                Some(&[n]) if allow_1d => (n, 1),
                Some(other) => {
                    return Err(unsupported(format!(
                        "{}-D shape {other:?}; need a 2-D array (samples, columns), e.g. \
                         np.column_stack((t, f, x))",
                        other.len()
                    )))
                }
                None => return Err(format_err("'shape' holds a non-integer".to_owned())),
            }
        }
        _ => return Err(format_err("the header has no tuple 'shape'".to_owned())),
    };

    let expected = rows
        .checked_mul(cols)
        .and_then(|n| n.checked_mul(float.size() as u64));
    let found = (bytes.len() - data_start) as u64;
    if expected != Some(found) {
        return Err(DataError::NpyDataLength {
            path: path.to_path_buf(),
            expected: expected.unwrap_or(u64::MAX),
            found,
        });
    }
    // The length check bounds rows * cols by the file size, so both fit in usize.
    let (rows, cols) = (rows as usize, cols as usize);
    let data = &bytes[data_start..];
    let columns = (0..cols)
        .map(|index| {
            (0..rows)
                .map(|row| {
                    let at = (row * cols + index) * float.size();
                    match float {
                        Float::F8 => {
                            let mut cell = [0; 8];
                            cell.copy_from_slice(&data[at..at + 8]);
                            f64::from_le_bytes(cell)
                        }
                        Float::F4 => {
                            let mut cell = [0; 4];
                            cell.copy_from_slice(&data[at..at + 4]);
                            f64::from(f32::from_le_bytes(cell))
                        }
                    }
                })
                .collect()
        })
        .collect();
    Ok(NpyArray {
        rows,
        columns,
        eps: float.eps(),
    })
}

/// The subset of Python literals a `.npy` header uses.
#[derive(Debug, Clone, PartialEq)]
enum Value {
    Str(String),
    Bool(bool),
    Int(u64),
    Tuple(Vec<Value>),
    List(Vec<Value>),
}

#[derive(Debug, Default)]
struct Dict(Vec<(String, Value)>);

impl Dict {
    fn get(&self, key: &str) -> Option<&Value> {
        self.0.iter().find(|(k, _)| k == key).map(|(_, v)| v)
    }
}

fn parse_header(text: &str) -> Result<Dict, String> {
    let mut p = Parser {
        s: text.as_bytes(),
        i: 0,
    };
    let dict = p.dict()?;
    p.blanks();
    if p.i != p.s.len() {
        return Err(format!("unexpected text at byte {}", p.i));
    }
    Ok(dict)
}

struct Parser<'a> {
    s: &'a [u8],
    i: usize,
}

impl Parser<'_> {
    fn blanks(&mut self) {
        while self.i < self.s.len() && self.s[self.i].is_ascii_whitespace() {
            self.i += 1;
        }
    }

    fn peek(&mut self) -> Option<u8> {
        self.blanks();
        self.s.get(self.i).copied()
    }

    fn expect(&mut self, c: u8) -> Result<(), String> {
        if self.peek() == Some(c) {
            self.i += 1;
            Ok(())
        } else {
            Err(format!("expected '{}' at byte {}", c as char, self.i))
        }
    }

    /// Items up to `close`, separated by commas, a trailing comma allowed.
    fn items<T>(
        &mut self,
        close: u8,
        mut item: impl FnMut(&mut Self) -> Result<T, String>,
    ) -> Result<Vec<T>, String> {
        let mut out = Vec::new();
        loop {
            if self.peek() == Some(close) {
                self.i += 1;
                return Ok(out);
            }
            out.push(item(self)?);
            match self.peek() {
                Some(b',') => self.i += 1,
                Some(c) if c == close => {}
                _ => {
                    return Err(format!(
                        "expected ',' or '{}' at byte {}",
                        close as char, self.i
                    ))
                }
            }
        }
    }

    fn dict(&mut self) -> Result<Dict, String> {
        self.expect(b'{')?;
        let entries = self.items(b'}', |p| {
            let Value::Str(key) = p.value()? else {
                return Err(format!("dictionary key is not a string at byte {}", p.i));
            };
            p.expect(b':')?;
            Ok((key, p.value()?))
        })?;
        Ok(Dict(entries))
    }

    fn value(&mut self) -> Result<Value, String> {
        match self.peek() {
            Some(q @ (b'\'' | b'"')) => {
                let start = self.i + 1;
                let len = self.s[start..]
                    .iter()
                    .position(|&c| c == q)
                    .ok_or_else(|| "unclosed string".to_owned())?;
                self.i = start + len + 1;
                Ok(Value::Str(
                    String::from_utf8_lossy(&self.s[start..start + len]).into_owned(),
                ))
            }
            Some(b'(') => {
                self.i += 1;
                Ok(Value::Tuple(self.items(b')', Self::value)?))
            }
            Some(b'[') => {
                self.i += 1;
                Ok(Value::List(self.items(b']', Self::value)?))
            }
            Some(c) if c.is_ascii_digit() => {
                let start = self.i;
                while self.i < self.s.len() && self.s[self.i].is_ascii_digit() {
                    self.i += 1;
                }
                let digits = std::str::from_utf8(&self.s[start..self.i]).unwrap_or_default();
                // Python 2 era writers appended `L` to long integers.
                if self.s.get(self.i) == Some(&b'L') {
                    self.i += 1;
                }
                digits
                    .parse()
                    .map(Value::Int)
                    .map_err(|_| format!("integer {digits} too large"))
            }
            _ => {
                for (word, v) in [("True", true), ("False", false)] {
                    if self.s[self.i..].starts_with(word.as_bytes()) {
                        self.i += word.len();
                        return Ok(Value::Bool(v));
                    }
                }
                Err(format!("unexpected value at byte {}", self.i))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_dict_parses_as_numpy_writes_it() {
        let d = parse_header("{'descr': '<f8', 'fortran_order': False, 'shape': (3, 2), }    \n")
            .unwrap();
        assert_eq!(d.get("descr"), Some(&Value::Str("<f8".into())));
        assert_eq!(d.get("fortran_order"), Some(&Value::Bool(false)));
        assert_eq!(
            d.get("shape"),
            Some(&Value::Tuple(vec![Value::Int(3), Value::Int(2)]))
        );
    }

    #[test]
    fn header_parses_one_tuples_lists_and_long_ints() {
        let d = parse_header("{'descr': [('a', '<f8')], 'fortran_order': True, 'shape': (5L,)}")
            .unwrap();
        assert_eq!(
            d.get("descr"),
            Some(&Value::List(vec![Value::Tuple(vec![
                Value::Str("a".into()),
                Value::Str("<f8".into())
            ])]))
        );
        assert_eq!(d.get("shape"), Some(&Value::Tuple(vec![Value::Int(5)])));
    }

    #[test]
    fn malformed_headers_are_errors() {
        assert!(parse_header("{'descr': '<f8'").is_err());
        assert!(parse_header("{'descr' '<f8'}").is_err());
        assert!(parse_header("{'shape': (3, 2)} x").is_err());
        assert!(parse_header("{'x': None}").is_err());
    }
}
