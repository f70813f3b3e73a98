//! Reading `.npy` files, written byte by byte here so the tests need no NumPy.

use std::path::PathBuf;

use approx::assert_relative_eq;
use htfid_data::{read_npy, DataError, NpySpec};
use tempfile::TempDir;

/// An `.npy` file as NumPy's `format.write_array` lays it out: magic, version, little-endian
/// header length (u16 for 1.0, u32 for 2.0/3.0), the dict padded with spaces and a newline so
/// the data start is a multiple of 64, then the raw data.
fn npy_bytes(major: u8, header_dict: &str, data: &[u8]) -> Vec<u8> {
    let preamble = if major == 1 { 10 } else { 12 };
    let mut header = header_dict.to_owned();
    let unpadded = preamble + header.len() + 1;
    header.push_str(&" ".repeat((64 - unpadded % 64) % 64));
    header.push('\n');
    let mut out = b"\x93NUMPY".to_vec();
    out.extend([major, 0]);
    if major == 1 {
        out.extend(u16::try_from(header.len()).unwrap().to_le_bytes());
    } else {
        out.extend(u32::try_from(header.len()).unwrap().to_le_bytes());
    }
    out.extend(header.as_bytes());
    assert_eq!(out.len() % 64, 0);
    out.extend(data);
    out
}

fn dict(descr: &str, fortran: bool, shape: &str) -> String {
    let order = if fortran { "True" } else { "False" };
    format!("{{'descr': '{descr}', 'fortran_order': {order}, 'shape': {shape}, }}")
}

fn f8(values: &[f64]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

fn write(dir: &TempDir, bytes: &[u8]) -> PathBuf {
    let path = dir.path().join("a.npy");
    std::fs::write(&path, bytes).unwrap();
    path
}

/// Rows (t, f, x) with t = 5 + 0.25 k, all exactly representable.
fn txf_rows(n: usize) -> Vec<f64> {
    (0..n)
        .flat_map(|k| {
            let k = k as f64;
            [5.0 + 0.25 * k, k * 0.5, -k * 0.125]
        })
        .collect()
}

fn message(bytes: &[u8], spec: &NpySpec) -> String {
    let dir = TempDir::new().unwrap();
    let path = write(&dir, bytes);
    read_npy(&path, spec)
        .unwrap_err()
        .to_string()
        .replace(&dir.path().display().to_string(), "DIR")
}

#[test]
fn float64_c_order_in_all_versions() {
    let data = f8(&txf_rows(6));
    for major in [1, 2, 3] {
        let dir = TempDir::new().unwrap();
        let path = write(
            &dir,
            &npy_bytes(major, &dict("<f8", false, "(6, 3)"), &data),
        );
        let s = read_npy(&path, &NpySpec::default()).unwrap();
        assert_eq!(s.len(), 6);
        // All values are small dyadic rationals, exact in binary; the tolerance only guards
        // the comparison.
        assert_relative_eq!(s.time()[5], 6.25, max_relative = 1e-15);
        assert_relative_eq!(s.input()[3], 1.5, max_relative = 1e-15);
        assert_relative_eq!(s.output()[4], -0.5, max_relative = 1e-15);
        assert_relative_eq!(s.dt(), 0.25, max_relative = 1e-15);
    }
}

#[test]
fn float32_is_widened_exactly() {
    let values: [f32; 6] = [0.0, 0.1, 1.0, 0.2, 2.0, 0.3];
    let data: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    let dir = TempDir::new().unwrap();
    let path = write(&dir, &npy_bytes(1, &dict("<f4", false, "(3, 2)"), &data));
    let s = read_npy(&path, &NpySpec::with_sample_rate(100.0, 0.0, 0, 1)).unwrap();
    // Widening f32 -> f64 is exact, so the f64 of each f32 is expected to the bit.
    assert_eq!(s.input()[1].to_bits(), f64::from(1.0f32).to_bits());
    assert_eq!(s.output()[2].to_bits(), f64::from(0.3f32).to_bits());
    assert_relative_eq!(s.time()[2], 0.02, max_relative = 1e-15);
}

#[test]
fn float32_times_pass_at_their_own_rounding_floor() {
    // As `(np.arange(1000) * 1e-3 + 2.0).astype('<f4')`: near t = 3 s adjacent f32 values are
    // 2.4e-7 s apart, so 1 ms steps vary by ~2e-4 relative, far beyond the 1e-6 tolerance,
    // yet the data are as uniform as float32 can store them.
    let data: Vec<u8> = (0..1000)
        .flat_map(|k| {
            let t = (2.0 + f64::from(k) * 1e-3) as f32;
            [t, 0.0, 1.0]
        })
        .flat_map(f32::to_le_bytes)
        .collect();
    let dir = TempDir::new().unwrap();
    let path = write(&dir, &npy_bytes(1, &dict("<f4", false, "(1000, 3)"), &data));
    let s = read_npy(&path, &NpySpec::default()).unwrap();
    // dt = (t_999 - t_0) / 999: t_0 = 2 is exact, t_999 ~ 3 is off by at most half an f32 ulp
    // (1.2e-7 s), which over the 0.999 s span is 1.2e-7 relative; 1e-6 bounds it.
    assert_relative_eq!(s.dt(), 1e-3, max_relative = 1e-6);
}

#[test]
fn columns_by_index_and_python2_long_shape() {
    let header = "{'descr': '<f8', 'fortran_order': False, 'shape': (4L, 3L), }";
    let dir = TempDir::new().unwrap();
    let path = write(&dir, &npy_bytes(1, header, &f8(&txf_rows(4))));
    let s = read_npy(&path, &NpySpec::with_time_column(0, 2, 1)).unwrap();
    assert_relative_eq!(s.input()[2], -0.25, max_relative = 1e-15);
    assert_relative_eq!(s.output()[2], 1.0, max_relative = 1e-15);
}

#[test]
fn unsupported_arrays_say_how_to_convert() {
    let data = f8(&txf_rows(2));
    let cases = [
        (
            dict("<i8", false, "(2, 3)"),
            "DIR/a.npy: unsupported .npy array: dtype '<i8'; only little-endian float64 '<f8' \
             and float32 '<f4' are read, convert with arr.astype('<f8')",
        ),
        (
            dict(">f8", false, "(2, 3)"),
            "DIR/a.npy: unsupported .npy array: big-endian dtype '>f8'; convert with arr.astype('<f8')",
        ),
        (
            dict("<f8", true, "(2, 3)"),
            "DIR/a.npy: unsupported .npy array: Fortran (column-major) order; save \
             np.ascontiguousarray(arr) instead",
        ),
        (
            dict("<f8", false, "(6,)"),
            "DIR/a.npy: unsupported .npy array: 1-D shape [6]; need a 2-D array (samples, \
             columns), e.g. np.column_stack((t, f, x))",
        ),
        (
            dict("<f8", false, "(1, 2, 3)"),
            "DIR/a.npy: unsupported .npy array: 3-D shape [1, 2, 3]; need a 2-D array (samples, \
             columns), e.g. np.column_stack((t, f, x))",
        ),
        (
            "{'descr': [('t', '<f8'), ('f', '<f8'), ('x', '<f8')], 'fortran_order': False, 'shape': (2,), }"
                .to_owned(),
            "DIR/a.npy: unsupported .npy array: structured dtype; save a plain 2-D float array, \
             one column per signal",
        ),
    ];
    for (header, expected) in cases {
        assert_eq!(
            message(&npy_bytes(1, &header, &data), &NpySpec::default()),
            expected
        );
    }
}

#[test]
fn malformed_files() {
    assert_eq!(
        message(b"t,f,x\n0,1,2\n", &NpySpec::default()),
        "DIR/a.npy: not a valid .npy file: it does not start with the magic bytes \\x93NUMPY"
    );
    let mut v4 = npy_bytes(2, &dict("<f8", false, "(2, 3)"), &f8(&txf_rows(2)));
    v4[6] = 4;
    assert_eq!(
        message(&v4, &NpySpec::default()),
        "DIR/a.npy: not a valid .npy file: format version 4.0 is unknown (1.0, 2.0 and 3.0 are read)"
    );
    let full = npy_bytes(1, &dict("<f8", false, "(2, 3)"), &f8(&txf_rows(2)));
    assert_eq!(
        message(&full[..40], &NpySpec::default()),
        "DIR/a.npy: not a valid .npy file: the header claims 118 bytes but the file ends before"
    );
    assert_eq!(
        message(&full[..full.len() - 8], &NpySpec::default()),
        "DIR/a.npy: the .npy header promises 48 data bytes, the file holds 40"
    );
    assert_eq!(
        message(
            &npy_bytes(1, "{'descr': '<f8', 'shape': (2, 3)}", &f8(&txf_rows(2))),
            &NpySpec::default()
        ),
        "DIR/a.npy: not a valid .npy file: the header has no boolean 'fortran_order'"
    );
}

#[test]
fn column_out_of_range() {
    let bytes = npy_bytes(1, &dict("<f8", false, "(2, 3)"), &f8(&txf_rows(2)));
    assert_eq!(
        message(&bytes, &NpySpec::with_time_column(0, 1, 3)),
        "DIR/a.npy: column index 3 out of range: the array has 3 columns (indices are 0-based)"
    );
}

#[test]
fn value_errors_give_zero_based_rows() {
    let mut rows = txf_rows(5);
    rows[3 * 3 + 2] = f64::NAN;
    let bytes = npy_bytes(1, &dict("<f8", false, "(5, 3)"), &f8(&rows));
    assert_eq!(
        message(&bytes, &NpySpec::default()),
        "DIR/a.npy: row 3: column 2: value \"NaN\" is not a finite number"
    );

    let mut rows = txf_rows(5);
    rows[3 * 3] = 6.5; // t = 5, 5.25, 5.5, 6.5, 6.0
    let bytes = npy_bytes(1, &dict("<f8", false, "(5, 3)"), &f8(&rows));
    assert_eq!(
        message(&bytes, &NpySpec::default()),
        "DIR/a.npy: row 4: column 0: time 6 s is not after the previous time 6.5 s"
    );

    let mut rows = txf_rows(5);
    rows[3 * 3] = 5.8;
    rows[4 * 3] = 6.05;
    let bytes = npy_bytes(1, &dict("<f8", false, "(5, 3)"), &f8(&rows));
    let dir = TempDir::new().unwrap();
    let path = write(&dir, &bytes);
    match read_npy(&path, &NpySpec::default()) {
        Err(DataError::NonUniformTime {
            location,
            found_dt,
            expected_dt,
            ..
        }) => {
            assert_eq!(location, htfid_data::Location::Row(3));
            // 5.8 - 5.5 and the median step 0.25 (exact); 1e-14 covers the rounding of 5.8.
            assert_relative_eq!(found_dt, 0.3, max_relative = 1e-14);
            assert_relative_eq!(expected_dt, 0.25, max_relative = 1e-15);
        }
        other => panic!("expected a non-uniform time error, got {other:?}"),
    }
}

#[test]
fn too_few_rows() {
    let bytes = npy_bytes(1, &dict("<f8", false, "(1, 3)"), &f8(&txf_rows(1)));
    assert_eq!(
        message(&bytes, &NpySpec::default()),
        "DIR/a.npy: 1 data rows, at least 2 needed"
    );
    let bytes = npy_bytes(1, &dict("<f8", false, "(4, 3)"), &f8(&txf_rows(4)));
    assert_eq!(
        message(&bytes, &NpySpec::default().with_min_samples(10)),
        "DIR/a.npy: 4 data rows, at least 10 needed"
    );
}

/// A seeded fault sweep: a valid file mutated 400 ways (truncated, bytes overwritten, huge or
/// negative shapes, wrong dtypes, NaN data). Every result is an `Ok` or an error naming the
/// file; none panics, and none allocates by the header's word (a shape of 1e18 rows in a small
/// file is refused, not reserved).
#[test]
fn mutated_files_never_panic_and_errors_name_the_file() {
    // A 64-bit LCG (Knuth's MMIX constants): a fixed seed, no dependency.
    let mut state: u64 = 20261124;
    let mut next = move |n: usize| {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 33) as usize) % n.max(1)
    };
    let rows = 100;
    let good = npy_bytes(
        1,
        &dict("<f8", false, &format!("({rows}, 3)")),
        &f8(&txf_rows(rows)),
    );
    let shapes = [
        "(1000000000000000000, 3)",
        "(18446744073709551615, 3)",
        "(-1, 3)",
        "(100, 100000000000)",
        "(100,)",
        "(100, 3, 2)",
        "()",
        "(0, 3)",
        "(100, 0)",
        "(nan, 3)",
    ];
    let descrs = ["<f8", "<f4", "<i8", ">f8", "|b1", "<c16", "", "<f8<f8"];
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("a.npy");
    let mut errors = 0;
    for case in 0..400 {
        let bytes = match next(6) {
            0 => good[..next(good.len())].to_vec(),
            1 => {
                let mut b = good.clone();
                for _ in 0..1 + next(8) {
                    let i = next(b.len());
                    b[i] = next(256) as u8;
                }
                b
            }
            2 => {
                let shape = shapes[next(shapes.len())];
                npy_bytes(1, &dict("<f8", false, shape), &f8(&txf_rows(rows)))
            }
            3 => {
                let descr = descrs[next(descrs.len())];
                npy_bytes(
                    1 + 2 * (next(2) as u8),
                    &dict(descr, next(2) == 1, "(100, 3)"),
                    &f8(&txf_rows(rows)),
                )
            }
            4 => {
                let mut values = txf_rows(rows);
                let i = next(values.len());
                values[i] = [f64::NAN, f64::INFINITY, -f64::INFINITY, 1e308][next(4)];
                npy_bytes(1, &dict("<f8", false, "(100, 3)"), &f8(&values))
            }
            _ => {
                // A header length pointing anywhere.
                let mut b = good.clone();
                let len = next(70000) as u16;
                b[8..10].copy_from_slice(&len.to_le_bytes());
                b
            }
        };
        std::fs::write(&path, &bytes).unwrap();
        let spec = if next(2) == 0 {
            NpySpec::default()
        } else {
            NpySpec::with_sample_rate(100.0, 0.0, 1, 2)
        };
        if let Err(e) = read_npy(&path, &spec) {
            errors += 1;
            let text = e.to_string();
            assert!(text.contains("a.npy"), "case {case}: {text}");
        }
    }
    // The sweep exercises the error paths, not only files that happen to stay valid.
    assert!(errors > 200, "only {errors} of 400 mutations were refused");
}
