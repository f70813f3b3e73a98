//! The published Silverbox measurement parses as its README describes.

use approx::assert_relative_eq;
use htfid_data::{read_csv, CsvSpec};

/// The shared data folder sits beside the project root (`../shared`); the test fails, not
/// skips, when the file is missing.
const SILVERBOX: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../../shared/data/silverbox/SNLS80mV.csv"
);
/// fs = 10^7 / 2^14 Hz, from the data set's README.
const FS: f64 = 610.3515625;

fn spec() -> CsvSpec {
    CsvSpec::default()
        .with_columns("V1", "V2")
        .with_sample_rate(FS, 0.0)
}

#[test]
fn silverbox_parses_with_its_documented_shape() {
    let s = read_csv(SILVERBOX, &spec()).unwrap();
    // 131072 = 2^17 samples, per the README; `wc -l` gives 131074 lines = header + rows + the
    // final empty line.
    assert_eq!(s.len(), 131_072);
    // Values as printed in the file (first line after the header, the start of the multisine
    // section at 0-based index 40650, i.e. line 40652, and the last line), read with `sed`.
    // One ulp of tolerance would be too strict for nothing: parsing is correctly rounded, so the
    // nearest f64 to each decimal is expected, i.e. relative error below 1.2e-16.
    let cases = [
        (0, 0.0057756, 0.0093978),
        (40_650, -0.014504, 0.036451),
        (131_071, 0.0096732, -0.0072247),
    ];
    for (k, u, y) in cases {
        assert_relative_eq!(s.input()[k], u, max_relative = 1.2e-16);
        assert_relative_eq!(s.output()[k], y, max_relative = 1.2e-16);
    }
    // 2^14 / 10^7 s exactly in decimal; 1/FS is one correctly rounded division.
    assert_relative_eq!(s.dt(), 0.0016384, max_relative = 1.2e-16);
    assert_relative_eq!(
        s.time()[131_071],
        131_071.0 * 0.0016384,
        max_relative = 1e-15
    );
}

#[test]
fn silverbox_sums_match_an_independent_reader() {
    // Reference sums from awk (`awk -F, 'NR>1 && NF>1 {s1+=$1; s2+=$2}'`), printed with 10
    // significant digits; summing 131072 values of ~1e-2 in a different order or with awk's
    // parser differs far below that, so 1e-9 relative covers the printing alone.
    let s = read_csv(SILVERBOX, &spec()).unwrap();
    let su: f64 = s.input().iter().sum();
    let sy: f64 = s.output().iter().sum();
    assert_relative_eq!(su, 810.2485416, max_relative = 1e-9);
    assert_relative_eq!(sy, 106.9545696, max_relative = 1e-9);
}

#[test]
fn silverbox_header_names_are_listed_when_a_column_is_missing() {
    let err = read_csv(SILVERBOX, &CsvSpec::default().with_sample_rate(FS, 0.0)).unwrap_err();
    assert_eq!(
        err.to_string(),
        format!("{SILVERBOX}:1: no column \"f\" in the header; available columns: \"V1\", \"V2\"")
    );
}
