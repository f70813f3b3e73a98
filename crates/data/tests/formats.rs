//! Every measurement format against the same record written as CSV, by NumPy and SciPy (see
//! `tests/fixtures/data/make_fixtures.py`): the numbers must be identical to the bit.

use std::path::{Path, PathBuf};

use htfid_data::{read_csv, read_record, CsvSpec, Delimiter, Format, RecordSpec, TimeSeries};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/fixtures/data")
        .join(name)
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

fn same_record(a: &TimeSeries, b: &TimeSeries) {
    assert_eq!(bits(a.time()), bits(b.time()));
    assert_eq!(bits(a.input()), bits(b.input()));
    assert_eq!(bits(a.output()), bits(b.output()));
    assert_eq!(a.dt().to_bits(), b.dt().to_bits());
}

fn txf() -> RecordSpec {
    RecordSpec::default().with_matrix_columns(vec!["t".into(), "f".into(), "x".into()])
}

fn message(name: &str, spec: &RecordSpec) -> String {
    read_record(fixture(name), spec)
        .unwrap_err()
        .to_string()
        .replace(&fixture("").display().to_string(), "")
}

#[test]
fn every_format_reads_the_numbers_of_the_csv_to_the_bit() {
    let csv = read_csv(fixture("record.csv"), &CsvSpec::default()).unwrap();
    assert_eq!(csv.len(), 192);
    for (file, format) in [
        ("record.csv", Format::Csv),
        ("record.npy", Format::Npy),
        ("record.npz", Format::Npz),
        ("record_matrix.npz", Format::Npz),
        ("record.mat", Format::Mat),
        ("record_matrix.mat", Format::Mat),
    ] {
        let bytes = std::fs::read(fixture(file)).unwrap();
        assert_eq!(Format::sniff(&bytes), format, "{file}");
        let series = read_record(fixture(file), &txf()).unwrap();
        same_record(&series, &csv);
    }
}

#[test]
fn matrix_columns_are_chosen_by_name_and_order() {
    // Naming the columns in another order swaps the signals: input "x" is then column 1.
    let spec = RecordSpec::default()
        .with_matrix("rec")
        .with_matrix_columns(vec!["t".into(), "x".into(), "f".into()]);
    let csv = read_csv(fixture("record.csv"), &CsvSpec::default()).unwrap();
    for file in ["record_matrix.npz", "record_matrix.mat"] {
        let s = read_record(fixture(file), &spec).unwrap();
        assert_eq!(bits(s.input()), bits(csv.output()), "{file}");
        assert_eq!(bits(s.output()), bits(csv.input()), "{file}");
    }
    // Unnamed columns answer to their 0-based indices.
    let spec = RecordSpec::default()
        .with_time_column("0")
        .with_columns("1", "2");
    let s = read_record(fixture("record.npy"), &spec).unwrap();
    same_record(&s, &csv);
}

#[test]
fn numeric_classes_convert_exactly() {
    let read = |file: &str, input: &str, output: &str| {
        read_record(
            fixture(file),
            &RecordSpec::default()
                .with_sample_rate(10.0, 0.0)
                .with_columns(input, output),
        )
        .unwrap()
    };
    let s = read("classes.mat", "single", "int16");
    let single: Vec<f64> = [0.1f32, 1.5, -2.25].into_iter().map(f64::from).collect();
    assert_eq!(bits(s.input()), bits(&single));
    assert_eq!(bits(s.output()), bits(&[-300.0, 0.0, 300.0]));
    let s = read("classes.mat", "uint8", "int64");
    assert_eq!(bits(s.input()), bits(&[0.0, 7.0, 255.0]));
    let big = 2f64.powi(53);
    assert_eq!(bits(s.output()), bits(&[-big, 1.0, big]));
    let s = read("classes.mat", "row", "row");
    assert_eq!(bits(s.input()), bits(&[0.0, 0.5, 1.0, 1.5, 2.0, 2.5]));
    let s = read("classes.npz", "f4", "one_d");
    assert_eq!(bits(s.input()), bits(&single));
    assert_eq!(bits(s.output()), bits(&[1.0, 2.0, 3.0]));
}

#[test]
fn missing_and_unreadable_names_are_explained() {
    let by_index = RecordSpec::default().with_sample_rate(10.0, 0.0);
    assert_eq!(
        message("record.npy", &by_index),
        "record.npy: no column \"f\" in the .npy; it holds \"0\", \"1\", \"2\" (the 3 columns \
         of the array are unnamed: name them in order with `columns`, or use their 0-based \
         indices)"
    );
    assert_eq!(
        message(
            "classes.mat",
            &by_index.clone().with_columns("cube", "single")
        ),
        "classes.mat: no column \"cube\" in the MAT-file; it holds \"row\", \"single\", \
         \"int16\", \"uint8\", \"int64\" (\"cube\" is not readable: has 3 dimensions [2, 2, 2]; \
         only vectors and 2-D matrices are read)"
    );
    assert_eq!(
        message(
            "record_matrix.mat",
            &by_index.clone().with_columns("meta", "t")
        ),
        "record_matrix.mat: no column \"meta\" in the MAT-file; it holds no named column \
         (\"rec\" is a 192x3 matrix (choose it with `matrix` and name its columns with \
         `columns`); \"meta\" is not readable: is a struct; \"note\" is not readable: is a char \
         array)"
    );
    assert_eq!(
        message(
            "record.npy",
            &txf().with_matrix_columns(vec!["t".into(), "f".into()])
        ),
        "record.npy: 2 column names given, but the .npy matrix is 192x3 (one sample per row, \
         one signal per column)"
    );
    assert_eq!(
        message("record_matrix.npz", &txf().with_matrix("data")),
        "record_matrix.npz: no readable matrix \"data\" in the .npz; it holds \"rec\""
    );
    assert_eq!(
        message("record.npz", &RecordSpec::default().with_columns("f", "y")),
        "record.npz: no column \"y\" in the .npz; it holds \"t\", \"f\", \"x\""
    );
}

fn temp_file(name: &str, bytes: &[u8]) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, bytes).unwrap();
    (dir, path)
}

#[test]
fn damaged_and_v73_files_are_refused_with_the_cause() {
    let mut bytes = std::fs::read(fixture("record_matrix.npz")).unwrap();
    // A byte inside the deflated data: either the inflater or the CRC-32 must object.
    bytes[200] ^= 0x55;
    let (_d, path) = temp_file("bad.npz", &bytes);
    let err = read_record(&path, &txf()).unwrap_err().to_string();
    assert!(
        err.contains("bad.npz: not a valid .npz (ZIP) file: member \"rec.npy\""),
        "{err}"
    );

    // A ZIP archive of other members (as a spreadsheet workbook is) is not taken for an .npz.
    let npz = std::fs::read(fixture("record.npz")).unwrap();
    let mut renamed = Vec::with_capacity(npz.len());
    let mut i = 0;
    while i < npz.len() {
        if npz[i..].starts_with(b".npy") {
            renamed.extend_from_slice(b".xml");
            i += 4;
        } else {
            renamed.push(npz[i]);
            i += 1;
        }
    }
    let (_d, path) = temp_file("book.xlsx", &renamed);
    assert_eq!(
        read_record(&path, &txf()).unwrap_err().to_string(),
        format!(
            "{}: unsupported .npz archive: a ZIP archive without .npy members is not an .npz (a \
             spreadsheet workbook? export the sheet as CSV)",
            path.display()
        )
    );

    // What MATLAB's save -v7.3 writes: a text header, then HDF5 from byte 512.
    let mut v73 =
        b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Tue Nov 24 2026 HDF5 schema 1.00 ."
            .to_vec();
    v73.resize(512, b' ');
    v73.extend_from_slice(b"\x89HDF\r\n\x1a\n");
    v73.resize(1024, 0);
    let (_d, path) = temp_file("r.mat", &v73);
    let err = read_record(&path, &txf()).unwrap_err().to_string();
    assert!(
        err.ends_with(
            "r.mat: unsupported MAT-file: MATLAB v7.3 MAT-files are HDF5 containers, and htfid \
         reads no HDF5 (no well-kept pure-Rust reader exists, and the build must need no system \
         libraries); save the variables with save(FILE, ..., '-v7'), which writes a level-5 \
         MAT-file htfid reads, or use scipy.io.savemat"
        ),
        "{err}"
    );
}

#[test]
fn cr_only_line_ends_are_lines() {
    let text = std::fs::read_to_string(fixture("record.csv")).unwrap();
    let (_d, path) = temp_file("mac.csv", text.replace('\n', "\r").as_bytes());
    let s = read_record(&path, &RecordSpec::default()).unwrap();
    same_record(
        &s,
        &read_csv(fixture("record.csv"), &CsvSpec::default()).unwrap(),
    );
}

#[test]
fn other_separators_are_named_with_the_setting_to_change() {
    let text = std::fs::read_to_string(fixture("record.csv")).unwrap();
    for (sep, looks, set) in [
        (";", "semicolon-separated", "\";\""),
        ("\t", "tab-separated", "\"tab\""),
    ] {
        let (_d, path) = temp_file("s.csv", text.replace(',', sep).as_bytes());
        let err = read_record(&path, &RecordSpec::default())
            .unwrap_err()
            .to_string();
        assert_eq!(
            err,
            format!(
                "{}:1: no column \"t\" in the header {:?}: it looks {looks} but cells are split \
                 at \",\"; set the delimiter to {set}",
                path.display(),
                format!("t{sep}f{sep}x")
            )
        );
        let delimiter = Delimiter::parse(if sep == ";" { ";" } else { "tab" }).unwrap();
        let s = read_record(&path, &RecordSpec::default().with_delimiter(delimiter)).unwrap();
        assert_eq!(s.len(), 192);
    }
}
