//! Reading CSV files: accepted variations, and every error with its exact message.

use std::path::{Path, PathBuf};

use approx::assert_relative_eq;
use htfid_data::{read_csv, ColumnId, CsvSpec, DataError, Delimiter, Location};
use tempfile::TempDir;

fn file(dir: &TempDir, name: &str, content: &str) -> PathBuf {
    let path = dir.path().join(name);
    std::fs::write(&path, content).unwrap();
    path
}

/// The message of the error reading `content` with `spec`, with the temporary directory's path
/// replaced by `DIR` so the expected text can be written out in full.
fn message(content: &str, spec: &CsvSpec) -> String {
    let dir = TempDir::new().unwrap();
    let path = file(&dir, "m.csv", content);
    let err = read_csv(&path, spec).unwrap_err();
    err.to_string()
        .replace(&dir.path().display().to_string(), "DIR")
}

fn read(content: &str, spec: &CsvSpec) -> htfid_data::TimeSeries {
    let dir = TempDir::new().unwrap();
    let path = file(&dir, "ok.csv", content);
    read_csv(path, spec).unwrap()
}

// Values below are decimal literals that appear verbatim in the files, so the parser must return
// the correctly rounded f64 of each; the literal in the test is that same f64, and 1e-15 relative
// only guards against the comparison itself.

#[test]
fn project_format_with_extra_columns_and_free_order() {
    let s = read(
        "x,comment,t,f\n0.5,first,10.0,1\n0.25,second,10.5,2\n0.125,,11.0,4\n",
        &CsvSpec::default(),
    );
    assert_eq!(s.len(), 3);
    assert_relative_eq!(s.time()[0], 10.0, max_relative = 1e-15);
    assert_relative_eq!(s.dt(), 0.5, max_relative = 1e-15);
    assert_relative_eq!(s.input()[2], 4.0, max_relative = 1e-15);
    assert_relative_eq!(s.output()[1], 0.25, max_relative = 1e-15);
}

#[test]
fn crlf_comments_blank_lines_bom_and_quoted_header() {
    let content = "\u{feff}# recorded 2024\r\n\r\n\"t\" , \"f\",\"x\"\r\n  # mid comment\r\n0,1,2\r\n\r\n0.1,3,4\r\n0.2,5,6";
    let s = read(content, &CsvSpec::default());
    assert_eq!(s.len(), 3);
    assert_relative_eq!(s.input()[1], 3.0, max_relative = 1e-15);
    assert_relative_eq!(s.output()[2], 6.0, max_relative = 1e-15);
    // One rounding each in 0.1 and 0.2 and the difference; 1e-15 is a few ulps.
    assert_relative_eq!(s.dt(), 0.1, max_relative = 1e-15);
}

#[test]
fn trailing_empty_column_is_dropped() {
    let spec = CsvSpec::default()
        .with_columns("V1", "V2")
        .with_sample_rate(4.0, 1.0);
    let s = read("\"V1\",\"V2\",\n0.1,0.2,\n0.3,0.4,\n", &spec);
    assert_eq!(s.len(), 2);
    assert_relative_eq!(s.output()[1], 0.4, max_relative = 1e-15);
    // t_k = start + k / fs = 1 + k/4, exact in binary.
    assert_relative_eq!(s.time()[1], 1.25, max_relative = 1e-15);
}

#[test]
fn other_delimiters() {
    let semi = CsvSpec::default().with_delimiter(Delimiter::Semicolon);
    assert_eq!(read("t;f;x\n0;1;2\n1;3;4\n", &semi).len(), 2);
    let ws = CsvSpec::default().with_delimiter(Delimiter::Whitespace);
    let s = read("  t   f\tx\n 0  1.5 2\n1 3 4  \n", &ws);
    assert_relative_eq!(s.input()[0], 1.5, max_relative = 1e-15);
    let auto = CsvSpec::default().with_delimiter(Delimiter::Auto);
    assert_eq!(read("t\tf\tx\n0\t1\t2\n1\t3\t4\n", &auto).len(), 2);
    assert_eq!(read("t;f;x\n0;1;2\n1;3;4\n", &auto).len(), 2);
}

#[test]
fn comment_character_can_be_changed_or_disabled() {
    let pct = CsvSpec::default().with_comment(Some('%'));
    assert_eq!(read("% matlab style\nt,f,x\n0,1,2\n1,3,4\n", &pct).len(), 2);
    let none = CsvSpec::default().with_comment(None);
    assert_eq!(
        message("# t,f,x\n0,1,2\n1,3,4\n", &none),
        "DIR/m.csv:1: no column \"t\" in the header; available columns: \"# t\", \"f\", \"x\""
    );
}

#[test]
fn time_tolerance_is_configurable() {
    // Times printed with 4 digits: steps of 0.0016 and 0.0017 (true step 1/610.35 s).
    let content = "t,f,x\n0.0000,0,0\n0.0016,0,0\n0.0033,0,0\n0.0049,0,0\n";
    assert_eq!(
        message(content, &CsvSpec::default()),
        "DIR/m.csv:4: column \"t\": time step 0.0017 s differs from the expected 0.0016 s by more \
         than the relative tolerance 1e-6 (the data must be uniformly sampled; if the times are \
         printed with few digits, raise the time tolerance or give the sample rate instead)"
    );
    let s = read(content, &CsvSpec::default().with_time_tolerance(0.1));
    // dt = (0.0049 - 0) / 3, the end-to-end mean.
    assert_relative_eq!(s.dt(), 0.0049 / 3.0, max_relative = 1e-15);
}

#[test]
fn parse_error_names_line_column_and_text() {
    let spec = CsvSpec::default()
        .with_columns("V1", "V2")
        .with_sample_rate(610.3515625, 0.0);
    let mut content = String::from("\"V1\",\"V2\",\n");
    for _ in 0..15 {
        content.push_str("0.1,0.2,\n");
    }
    content.push_str("0.3, abc ,\n");
    let dir = TempDir::new().unwrap();
    let path = file(&dir, "SNLS80mV.csv", &content);
    let err = read_csv(&path, &spec).unwrap_err();
    assert_eq!(
        err.to_string(),
        format!(
            "{}:17: column \"V2\": cannot parse \"abc\" as a number",
            path.display()
        )
    );
    match err {
        DataError::Parse {
            path: p,
            line,
            column,
            value,
        } => {
            assert_eq!(p, path);
            assert_eq!(line, 17);
            assert_eq!(column, ColumnId::Name("V2".into()));
            assert_eq!(value, "abc");
        }
        other => panic!("expected a parse error, got {other:?}"),
    }
}

#[test]
fn empty_used_cell_and_decimal_comma_are_parse_errors() {
    assert_eq!(
        message("t,f,x\n0,1,2\n1,,4\n", &CsvSpec::default()),
        "DIR/m.csv:3: column \"f\": cannot parse \"\" as a number"
    );
    assert_eq!(
        message(
            "t;f;x\n0;1,5;2\n",
            &CsvSpec::default().with_delimiter(Delimiter::Semicolon)
        ),
        "DIR/m.csv:2: column \"f\": cannot parse \"1,5\" as a number"
    );
}

#[test]
fn unused_columns_are_not_parsed() {
    assert_eq!(
        read("t,f,x,note\n0,1,2,n/a\n1,3,4,NaN\n", &CsvSpec::default()).len(),
        2
    );
}

#[test]
fn non_finite_values_are_rejected() {
    for (text, line) in [("NaN", 3), ("inf", 3), ("-Infinity", 3), ("1e400", 3)] {
        let content = format!("t,f,x\n0,1,2\n1,3,{text}\n");
        assert_eq!(
            message(&content, &CsvSpec::default()),
            format!("DIR/m.csv:{line}: column \"x\": value \"{text}\" is not a finite number")
        );
    }
    let dir = TempDir::new().unwrap();
    let path = file(&dir, "n.csv", "t,f,x\n0,nan,2\n1,3,4\n");
    assert!(matches!(
        read_csv(&path, &CsvSpec::default()),
        Err(DataError::NonFinite {
            location: Location::Line(2),
            ..
        })
    ));
}

#[test]
fn wrong_number_of_cells() {
    assert_eq!(
        message("t,f,x\n0,1,2\n1,3\n", &CsvSpec::default()),
        "DIR/m.csv:3: expected 3 cells as in the header, found 2"
    );
    assert_eq!(
        message("t,f,x\n0,1,2\n1,3,4,5\n", &CsvSpec::default()),
        "DIR/m.csv:3: expected 3 cells as in the header, found 4"
    );
    // A trailing separator on a row is an empty extra cell, tolerated, but not a non-empty one.
    assert_eq!(read("t,f,x\n0,1,2,\n1,3,4\n", &CsvSpec::default()).len(), 2);
}

#[test]
fn non_monotonic_time() {
    assert_eq!(
        message("t,f,x\n# c\n0,1,2\n1,1,2\n1,1,2\n", &CsvSpec::default()),
        "DIR/m.csv:5: column \"t\": time 1 s is not after the previous time 1 s"
    );
    assert_eq!(
        message("t,f,x\n0,1,2\n1,1,2\n0.5,1,2\n", &CsvSpec::default()),
        "DIR/m.csv:4: column \"t\": time 0.5 s is not after the previous time 1 s"
    );
}

#[test]
fn non_uniform_time_reports_the_gap_line_and_both_steps() {
    // A missing sample at t = 3: the step into line 6 (t = 4) is 2 s, the median step 1 s.
    assert_eq!(
        message(
            "t,f,x\n0,0,0\n1,0,0\n2,0,0\n\n4,0,0\n5,0,0\n6,0,0\n",
            &CsvSpec::default()
        ),
        "DIR/m.csv:6: column \"t\": time step 2 s differs from the expected 1 s by more than the \
         relative tolerance 1e-6 (1 sample(s) missing before this one; the data must be \
         uniformly sampled, so fill the gap or cut the record there (a tolerance does not mend a \
         gap))"
    );
}

#[test]
fn missing_column_lists_the_available_ones() {
    assert_eq!(
        message("# header below\ntime,force,pos,\n0,1,2,\n", &CsvSpec::default()),
        "DIR/m.csv:2: no column \"t\" in the header; available columns: \"time\", \"force\", \"pos\""
    );
    assert_eq!(
        message("t,F,x\n0,1,2\n", &CsvSpec::default()),
        "DIR/m.csv:1: no column \"f\" in the header; available columns: \"t\", \"F\", \"x\""
    );
}

#[test]
fn duplicate_used_column_is_ambiguous() {
    assert_eq!(
        message("t,f,x,f\n0,1,2,3\n", &CsvSpec::default()),
        "DIR/m.csv:1: column \"f\" appears more than once in the header (cells 2 and 4)"
    );
}

#[test]
fn header_of_numbers_is_missing_header() {
    assert_eq!(
        message("# t,f,x\n0,1,2\n1,3,4\n", &CsvSpec::default()),
        "DIR/m.csv:2: expected a header row of column names, found only numbers or empty cells \
         (a header line that starts with the comment character is skipped as a comment)"
    );
    assert_eq!(
        message(",,\n0,1,2\n", &CsvSpec::default()),
        "DIR/m.csv:1: expected a header row of column names, found only numbers or empty cells \
         (a header line that starts with the comment character is skipped as a comment)"
    );
}

#[test]
fn too_little_data() {
    assert_eq!(
        message("t,f,x\n0,1,2\n", &CsvSpec::default()),
        "DIR/m.csv: 1 data rows, at least 2 needed"
    );
    assert_eq!(
        message("t,f,x\n# nothing yet\n", &CsvSpec::default()),
        "DIR/m.csv: 0 data rows, at least 2 needed"
    );
    assert_eq!(
        message(
            "t,f,x\n0,1,2\n1,1,2\n2,1,2\n",
            &CsvSpec::default().with_min_samples(1000)
        ),
        "DIR/m.csv: 3 data rows, at least 1000 needed"
    );
}

#[test]
fn empty_file() {
    for content in ["", "\n\n", "# only\r\n# comments\r\n   \r\n"] {
        assert_eq!(
            message(content, &CsvSpec::default()),
            "DIR/m.csv: the file holds no data (it is empty or has only blank and comment lines)"
        );
    }
}

#[test]
fn malformed_quote() {
    assert_eq!(
        message("t,f,x\n0,\"1,2\n", &CsvSpec::default()),
        "DIR/m.csv:2: malformed quoted cell (a quote is not closed, or text follows a closing quote)"
    );
}

#[test]
fn not_utf8_names_the_line() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("latin1.csv");
    std::fs::write(&path, b"t,f,x\n0,1,2\n1,3,\xb5\n").unwrap();
    assert_eq!(
        read_csv(&path, &CsvSpec::default())
            .unwrap_err()
            .to_string(),
        format!("{}:3: the file is not valid UTF-8 text", path.display())
    );
}

#[test]
fn missing_file_is_a_read_error() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("absent.csv");
    let err = read_csv(&path, &CsvSpec::default()).unwrap_err();
    assert!(matches!(err, DataError::Read { .. }));
    assert!(err
        .to_string()
        .starts_with(&format!("cannot read {}: ", path.display())));
}

#[test]
fn invalid_specs_are_rejected_before_reading() {
    let nowhere = Path::new("/nonexistent/never-read.csv");
    let cases: [(CsvSpec, &str); 5] = [
        (
            CsvSpec::default().with_sample_rate(-3.0, 0.0),
            "sample rate must be finite and > 0 (got -3 Hz)",
        ),
        (
            CsvSpec::default().with_sample_rate(100.0, f64::NAN),
            "start time must be finite (got NaN s)",
        ),
        (
            CsvSpec::default().with_time_tolerance(-1e-3),
            "relative time tolerance must be finite and >= 0 (got -0.001)",
        ),
        (
            CsvSpec::default().with_comment(Some(',')),
            "comment character ',' clashes with the delimiter, the quote or whitespace",
        ),
        (
            CsvSpec::default().with_comment(Some('"')),
            "comment character '\"' clashes with the delimiter, the quote or whitespace",
        ),
    ];
    for (spec, expected) in cases {
        assert_eq!(read_csv(nowhere, &spec).unwrap_err().to_string(), expected);
    }
}
