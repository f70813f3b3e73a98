use std::fs;
use std::path::Path;

use crate::error::{ColumnId, DataError, Location};
use crate::series::{
    check_count, check_rate, check_tolerance, check_uniform, uniform_times, TimeSeries,
    DEFAULT_TIME_TOLERANCE,
};

/// Where sample times come from. `C` names a column: a header name (`String`) for CSV, a
/// 0-based index (`usize`) for NPY.
#[derive(Debug, Clone, PartialEq)]
pub enum TimeSource<C> {
    /// A column of absolute times in s, checked to be strictly increasing and uniform.
    Column(C),
    /// No time column: samples are `1 / rate_hz` apart, the first at `start` s.
    SampleRate {
        /// Sample rate in Hz, finite and > 0.
        rate_hz: f64,
        /// Time of the first sample in s.
        start: f64,
    },
}

/// How cells of a CSV line are separated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Delimiter {
    /// Chosen from the header line: `,` if it has one, else `;`, else tab, else whitespace.
    Auto,
    /// `,` (the project's format).
    #[default]
    Comma,
    /// `;` (common where `,` is the decimal mark; the numbers must still use `.`).
    Semicolon,
    /// A tab character.
    Tab,
    /// Any run of spaces and tabs; leading and trailing blanks are ignored.
    Whitespace,
}

impl Delimiter {
    /// The delimiter a config spells `","`, `";"`, `"tab"`, `"whitespace"` or `"auto"` (a tab
    /// character itself also reads as `"tab"`).
    pub fn parse(text: &str) -> Option<Delimiter> {
        Some(match text {
            "," => Delimiter::Comma,
            ";" => Delimiter::Semicolon,
            "tab" | "\t" => Delimiter::Tab,
            "whitespace" => Delimiter::Whitespace,
            "auto" => Delimiter::Auto,
            _ => return None,
        })
    }

    /// The spelling [`Delimiter::parse`] reads, quoted: `","`, `"tab"`, ...
    pub fn describe(self) -> &'static str {
        match self {
            Delimiter::Comma => "\",\"",
            Delimiter::Semicolon => "\";\"",
            Delimiter::Tab => "\"tab\"",
            Delimiter::Whitespace => "\"whitespace\"",
            Delimiter::Auto => "\"auto\"",
        }
    }

    /// The single-character delimiter `c`, if it is one.
    pub fn for_char(c: char) -> Option<Delimiter> {
        match c {
            ',' => Some(Delimiter::Comma),
            ';' => Some(Delimiter::Semicolon),
            '\t' => Some(Delimiter::Tab),
            _ => None,
        }
    }
}

/// What to read from a CSV file. [`CsvSpec::default`] is the project's format: columns `t`
/// (time, s), `f` (input force, N) and `x` (output position, m), comma-separated, `#` comments.
#[derive(Debug, Clone, PartialEq)]
pub struct CsvSpec {
    /// The time column, or a sample rate when the file has none.
    pub time: TimeSource<String>,
    /// Header name of the input column.
    pub input: String,
    /// Header name of the output column.
    pub output: String,
    /// Lines whose first non-blank character is this are skipped; `None` disables comments.
    pub comment: Option<char>,
    /// Cell separator.
    pub delimiter: Delimiter,
    /// Fewer data rows than this is an error. Values below 2 act as 2, the fewest that define a step.
    pub min_samples: usize,
    /// Relative tolerance on each time step against the median step (default 1e-6). Only used
    /// with a time column.
    pub time_tolerance: f64,
}

impl Default for CsvSpec {
    fn default() -> Self {
        Self {
            time: TimeSource::Column("t".to_owned()),
            input: "f".to_owned(),
            output: "x".to_owned(),
            comment: Some('#'),
            delimiter: Delimiter::Comma,
            min_samples: 2,
            time_tolerance: DEFAULT_TIME_TOLERANCE,
        }
    }
}

impl CsvSpec {
    /// The input and output columns by header name.
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

    /// The cell separator.
    pub fn with_delimiter(mut self, delimiter: Delimiter) -> Self {
        self.delimiter = delimiter;
        self
    }

    /// The comment character, or `None` for no comments.
    pub fn with_comment(mut self, comment: Option<char>) -> Self {
        self.comment = comment;
        self
    }

    /// The minimum number of data rows.
    pub fn with_min_samples(mut self, min_samples: usize) -> Self {
        self.min_samples = min_samples;
        self
    }

    /// The relative tolerance on time steps.
    pub fn with_time_tolerance(mut self, tolerance: f64) -> Self {
        self.time_tolerance = tolerance;
        self
    }

    fn validate(&self) -> Result<(), DataError> {
        check_tolerance(self.time_tolerance)?;
        if let TimeSource::SampleRate { rate_hz, start } = self.time {
            check_rate(rate_hz, start)?;
        }
        if let Some(c) = self.comment {
            let clashes = c == '"'
                || c.is_whitespace()
                || match self.delimiter {
                    Delimiter::Auto => matches!(c, ',' | ';'),
                    Delimiter::Comma => c == ',',
                    Delimiter::Semicolon => c == ';',
                    Delimiter::Tab | Delimiter::Whitespace => false,
                };
            if clashes {
                return Err(DataError::InvalidComment { comment: c });
            }
        }
        Ok(())
    }
}

/// Reads a uniformly sampled input/output record from a CSV file.
///
/// See the crate documentation for the accepted format. Only the used columns (time, input,
/// output) are parsed, so other columns may hold anything; every row must still have as many
/// cells as the header. Errors name the file, the 1-based line and the column.
pub fn read_csv(path: impl AsRef<Path>, spec: &CsvSpec) -> Result<TimeSeries, DataError> {
    let path = path.as_ref();
    spec.validate()?;
    let bytes = fs::read(path).map_err(|source| DataError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    read_csv_bytes(&bytes, path, spec)
}

/// [`read_csv`] of the bytes of the file `path`.
pub(crate) fn read_csv_bytes(
    bytes: &[u8],
    path: &Path,
    spec: &CsvSpec,
) -> Result<TimeSeries, DataError> {
    spec.validate()?;
    let text = match std::str::from_utf8(bytes) {
        Ok(text) => text,
        Err(e) => {
            // The valid prefix ends inside the line of the first invalid byte.
            let line = split_lines(&String::from_utf8_lossy(&bytes[..e.valid_up_to()])).count();
            return Err(DataError::NotUtf8 {
                path: path.to_path_buf(),
                line,
            });
        }
    };
    // Spreadsheet programs often prefix a byte-order mark; it would otherwise glue onto the
    // first column name.
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    parse_csv(text, path, spec)
}

/// The lines of `text`, ended by `\n`, `\r\n` or a lone `\r` (classic Mac OS and some
/// instrument software end lines with CR alone; reading those as one line would hide the data).
fn split_lines(text: &str) -> impl Iterator<Item = &str> {
    let mut rest = Some(text);
    std::iter::from_fn(move || {
        let s = rest?;
        match s.find(['\n', '\r']) {
            None => {
                rest = None;
                Some(s)
            }
            Some(i) => {
                let end = if s[i..].starts_with("\r\n") { 2 } else { 1 };
                rest = Some(&s[i + end..]);
                Some(&s[..i])
            }
        }
    })
}

fn parse_csv(text: &str, path: &Path, spec: &CsvSpec) -> Result<TimeSeries, DataError> {
    let skipped = |line: &str| {
        let t = line.trim();
        t.is_empty() || spec.comment.is_some_and(|c| t.starts_with(c))
    };
    let mut lines = split_lines(text)
        .enumerate()
        .map(|(i, l)| (i + 1, l))
        .filter(|&(_, l)| !skipped(l));

    let Some((header_line, header)) = lines.next() else {
        return Err(DataError::EmptyFile {
            path: path.to_path_buf(),
        });
    };
    let sep = Sep::resolve(spec.delimiter, header);
    let bad_quote = |line| DataError::BadQuote {
        path: path.to_path_buf(),
        line,
    };

    let mut cells: Vec<Cell<'_>> = Vec::new();
    split(header, sep, &mut cells).map_err(|()| bad_quote(header_line))?;
    let mut names: Vec<String> = cells
        .iter()
        .map(|c| {
            if c.quoted {
                c.text.replace("\"\"", "\"")
            } else {
                c.text.to_owned()
            }
        })
        .collect();
    // A trailing delimiter (as in `"V1","V2",`) makes an unnamed last column; it is not data.
    while names.last().is_some_and(|n| n.is_empty()) {
        names.pop();
    }
    if names.iter().all(|n| n.parse::<f64>().is_ok()) {
        return Err(DataError::MissingHeader {
            path: path.to_path_buf(),
            line: header_line,
        });
    }
    let find = |name: &str| {
        find_column(&names, name, path, header_line).map_err(|e| match e {
            DataError::MissingColumn { .. } if names.len() == 1 => {
                looks_delimited(header, spec.delimiter)
                    .map(|found| DataError::LooksDelimited {
                        path: path.to_path_buf(),
                        line: header_line,
                        column: name.to_owned(),
                        header: header.to_owned(),
                        found,
                        used: spec.delimiter,
                    })
                    .unwrap_or(e)
            }
            e => e,
        })
    };

    let time_col = match &spec.time {
        TimeSource::Column(name) => Some(find(name)?),
        TimeSource::SampleRate { .. } => None,
    };
    let input_col = find(&spec.input)?;
    let output_col = find(&spec.output)?;
    let n_cols = names.len();

    let mut time = Vec::new();
    let mut input = Vec::new();
    let mut output = Vec::new();
    let mut line_of_row = Vec::new();
    for (line_no, line) in lines {
        split(line, sep, &mut cells).map_err(|()| bad_quote(line_no))?;
        if cells.len() != n_cols {
            let extra_empty =
                cells.len() > n_cols && cells[n_cols..].iter().all(|c| c.text.is_empty());
            if !extra_empty {
                return Err(DataError::CellCount {
                    path: path.to_path_buf(),
                    line: line_no,
                    expected: n_cols,
                    found: cells.len(),
                });
            }
        }
        let value = |col: usize| parse_cell(cells[col].text, path, line_no, &names[col]);
        if let Some(col) = time_col {
            time.push(value(col)?);
        }
        input.push(value(input_col)?);
        output.push(value(output_col)?);
        line_of_row.push(line_no);
    }

    check_count(path, input.len(), spec.min_samples.max(2))?;
    let (time, dt) = match &spec.time {
        TimeSource::Column(name) => {
            let dt = check_uniform(&time, spec.time_tolerance, f64::EPSILON).map_err(|fault| {
                fault.into_error(path, ColumnId::Name(name.clone()), |row| {
                    Location::Line(line_of_row[row])
                })
            })?;
            (time, dt)
        }
        &TimeSource::SampleRate { rate_hz, start } => {
            let dt = check_rate(rate_hz, start)?;
            (uniform_times(start, dt, input.len()), dt)
        }
    };
    Ok(TimeSeries::from_checked(
        time,
        input,
        vec![output],
        dt,
        path.to_path_buf(),
    ))
}

/// The separator a one-cell header seems to use instead of `used`: the first of `;`, tab and
/// `,` that it contains.
fn looks_delimited(header: &str, used: Delimiter) -> Option<char> {
    [';', '\t', ',']
        .into_iter()
        .find(|&c| header.contains(c) && Delimiter::for_char(c) != Some(used))
}

fn find_column(names: &[String], name: &str, path: &Path, line: usize) -> Result<usize, DataError> {
    let mut hits = names.iter().enumerate().filter(|(_, n)| *n == name);
    match (hits.next(), hits.next()) {
        (Some((i, _)), None) => Ok(i),
        (Some((first, _)), Some((second, _))) => Err(DataError::DuplicateColumn {
            path: path.to_path_buf(),
            line,
            column: name.to_owned(),
            first: first + 1,
            second: second + 1,
        }),
        (None, _) => Err(DataError::MissingColumn {
            path: path.to_path_buf(),
            line,
            column: name.to_owned(),
            available: names.iter().filter(|n| !n.is_empty()).cloned().collect(),
        }),
    }
}

fn parse_cell(text: &str, path: &Path, line: usize, column: &str) -> Result<f64, DataError> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(DataError::NonFinite {
            path: path.to_path_buf(),
            location: Location::Line(line),
            column: ColumnId::Name(column.to_owned()),
            value: text.to_owned(),
        }),
        Err(_) => Err(DataError::Parse {
            path: path.to_path_buf(),
            line,
            column: ColumnId::Name(column.to_owned()),
            value: text.to_owned(),
        }),
    }
}

/// A resolved separator: one ASCII byte, or runs of blanks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Sep {
    Byte(u8),
    Blanks,
}

impl Sep {
    fn resolve(delimiter: Delimiter, header: &str) -> Self {
        match delimiter {
            Delimiter::Comma => Sep::Byte(b','),
            Delimiter::Semicolon => Sep::Byte(b';'),
            Delimiter::Tab => Sep::Byte(b'\t'),
            Delimiter::Whitespace => Sep::Blanks,
            Delimiter::Auto => {
                if header.contains(',') {
                    Sep::Byte(b',')
                } else if header.contains(';') {
                    Sep::Byte(b';')
                } else if header.contains('\t') {
                    Sep::Byte(b'\t')
                } else {
                    Sep::Blanks
                }
            }
        }
    }
}

/// One cell: its text without surrounding blanks or quotes. Doubled quotes inside a quoted cell
/// are left doubled; only header names need unescaping, and a number never contains a quote.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Cell<'a> {
    text: &'a str,
    quoted: bool,
}

fn is_blank(b: u8, sep: Sep) -> bool {
    b == b' ' || (b == b'\t' && sep != Sep::Byte(b'\t'))
}

/// Splits one line into cells, reusing `out`. Errors on an unclosed quote or text after a
/// closing quote. Delimiters and quotes are ASCII, so byte positions are char boundaries.
fn split<'a>(line: &'a str, sep: Sep, out: &mut Vec<Cell<'a>>) -> Result<(), ()> {
    out.clear();
    let b = line.as_bytes();
    let n = b.len();
    let is_sep = |c: u8| match sep {
        Sep::Byte(d) => c == d,
        Sep::Blanks => c == b' ' || c == b'\t',
    };
    let mut i = 0;
    loop {
        while i < n && is_blank(b[i], sep) {
            i += 1;
        }
        if sep == Sep::Blanks && i == n {
            return Ok(());
        }
        if i < n && b[i] == b'"' {
            let start = i + 1;
            let mut j = start;
            let end = loop {
                match b[j..].iter().position(|&c| c == b'"') {
                    None => return Err(()),
                    Some(q) if j + q + 1 < n && b[j + q + 1] == b'"' => j += q + 2,
                    Some(q) => break j + q,
                }
            };
            out.push(Cell {
                text: &line[start..end],
                quoted: true,
            });
            i = end + 1;
            if sep != Sep::Blanks {
                while i < n && is_blank(b[i], sep) {
                    i += 1;
                }
            }
            if i == n {
                return Ok(());
            }
            if !is_sep(b[i]) {
                return Err(());
            }
        } else {
            let start = i;
            while i < n && !is_sep(b[i]) {
                i += 1;
            }
            out.push(Cell {
                text: line[start..i].trim_end_matches([' ', '\t']),
                quoted: false,
            });
            if i == n {
                return Ok(());
            }
        }
        // Step over the separator; with a single-byte separator a line ending in one yields a
        // final empty cell on the next pass.
        i += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn texts(line: &str, sep: Sep) -> Result<Vec<(String, bool)>, ()> {
        let mut out = Vec::new();
        split(line, sep, &mut out)?;
        Ok(out.iter().map(|c| (c.text.to_owned(), c.quoted)).collect())
    }

    fn plain(items: &[&str]) -> Vec<(String, bool)> {
        items.iter().map(|s| ((*s).to_owned(), false)).collect()
    }

    #[test]
    fn comma_split_trims_and_keeps_empty_cells() {
        assert_eq!(
            texts(" a , b,,c,", Sep::Byte(b',')).unwrap(),
            plain(&["a", "b", "", "c", ""])
        );
        assert_eq!(texts("", Sep::Byte(b',')).unwrap(), plain(&[""]));
    }

    #[test]
    fn quoted_cells_may_hold_separators_and_doubled_quotes() {
        assert_eq!(
            texts(r#""a,b", "say ""hi""" ,c"#, Sep::Byte(b',')).unwrap(),
            vec![
                ("a,b".to_owned(), true),
                (r#"say ""hi"""#.to_owned(), true),
                ("c".to_owned(), false)
            ]
        );
        assert!(texts(r#""open,b"#, Sep::Byte(b',')).is_err());
        assert!(texts(r#""a"x,b"#, Sep::Byte(b',')).is_err());
    }

    #[test]
    fn whitespace_split_merges_runs() {
        assert_eq!(
            texts("  1.5\t 2  3 ", Sep::Blanks).unwrap(),
            plain(&["1.5", "2", "3"])
        );
        assert_eq!(
            texts(r#""t s" x"#, Sep::Blanks).unwrap(),
            vec![("t s".to_owned(), true), ("x".to_owned(), false)]
        );
    }

    #[test]
    fn tab_split_keeps_spaces_inside_cells() {
        assert_eq!(
            texts("a b\tc", Sep::Byte(b'\t')).unwrap(),
            plain(&["a b", "c"])
        );
    }

    #[test]
    fn auto_delimiter_prefers_comma_then_semicolon_then_tab() {
        assert_eq!(Sep::resolve(Delimiter::Auto, "t,f;x"), Sep::Byte(b','));
        assert_eq!(Sep::resolve(Delimiter::Auto, "t;f;x"), Sep::Byte(b';'));
        assert_eq!(Sep::resolve(Delimiter::Auto, "t\tf x"), Sep::Byte(b'\t'));
        assert_eq!(Sep::resolve(Delimiter::Auto, "t f x"), Sep::Blanks);
    }
}
