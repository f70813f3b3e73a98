//! Building series from vectors: the invariants every reader also guarantees.

use approx::assert_relative_eq;
use htfid_data::{DataError, Location, TimeSeries};

#[test]
fn new_accepts_uniform_times_and_keeps_them_absolute() {
    let t: Vec<f64> = (0..50).map(|k| 100.0 + k as f64 * 0.02).collect();
    let s = TimeSeries::new(t.clone(), vec![1.0; 50], vec![2.0; 50], "sim").unwrap();
    assert_relative_eq!(s.time()[0], 100.0, max_relative = 1e-15);
    // (t_49 - t_0) / 49 with t near 100: rounding of the ends (1.4e-14 each) over a 0.98 s span
    // is ~3e-14 relative; 1e-13 covers it.
    assert_relative_eq!(s.dt(), 0.02, max_relative = 1e-13);
    assert_relative_eq!(s.sample_rate(), 50.0, max_relative = 1e-13);
    assert_eq!(s.source(), std::path::Path::new("sim"));
    assert!(!s.is_empty());
}

#[test]
fn new_reports_problems_by_zero_based_row() {
    let err =
        TimeSeries::new(vec![0.0, 1.0, 2.0, 3.5], vec![0.0; 4], vec![0.0; 4], "sim").unwrap_err();
    assert!(
        matches!(
            err,
            DataError::NonUniformTime {
                location: Location::Row(3),
                ..
            }
        ),
        "{err}"
    );
    let err =
        TimeSeries::new(vec![0.0, 1.0], vec![0.0, f64::NAN], vec![0.0; 2], "sim").unwrap_err();
    assert_eq!(
        err.to_string(),
        "sim: row 1: column \"input\": value \"NaN\" is not a finite number"
    );
    let err = TimeSeries::new(vec![0.0, 1.0], vec![0.0; 2], vec![0.0; 3], "sim").unwrap_err();
    assert_eq!(
        err.to_string(),
        "sim: column \"output\" has 3 values, the time vector has 2"
    );
    let err = TimeSeries::new(vec![0.0], vec![0.0], vec![0.0], "sim").unwrap_err();
    assert_eq!(err.to_string(), "sim: 1 data rows, at least 2 needed");
}

#[test]
fn from_sample_rate_multiplies_rather_than_accumulates() {
    let n = 1_000_000;
    let s =
        TimeSeries::from_sample_rate(610.3515625, 2.0, vec![0.0; n], vec![0.0; n], "x").unwrap();
    // Exact reference: 1/fs = 2^14 / 10^7 s, so t_k = 2 + k * 0.0016384; the computed value has
    // at most a couple of roundings (1/fs, the product, the sum), i.e. ~1e-15 relative.
    let k = n - 1;
    assert_relative_eq!(
        s.time()[k],
        2.0 + k as f64 * 0.0016384,
        max_relative = 1e-15
    );
    assert!(matches!(
        TimeSeries::from_sample_rate(0.0, 0.0, vec![0.0; 2], vec![0.0; 2], "x"),
        Err(DataError::InvalidSampleRate { .. })
    ));
}

#[test]
fn slice_keeps_absolute_time_and_step() {
    let s = TimeSeries::from_sample_rate(
        4.0,
        0.0,
        (0..10).map(f64::from).collect(),
        vec![0.0; 10],
        "x",
    )
    .unwrap();
    let part = s.slice(3..7).unwrap();
    assert_eq!(part.len(), 4);
    // k / 4 is exact in binary.
    assert_relative_eq!(part.time()[0], 0.75, max_relative = 1e-15);
    assert_relative_eq!(part.input()[3], 6.0, max_relative = 1e-15);
    assert_relative_eq!(part.dt(), 0.25, max_relative = 1e-15);
    #[allow(clippy::reversed_empty_ranges)] // a reversed range is one of the bad inputs
    for bad in [3..4, 8..11, 5..3] {
        assert_eq!(
            s.slice(bad.clone()).unwrap_err().to_string(),
            format!(
                "sample range {}..{} is not a range of at least 2 samples within 0..10",
                bad.start, bad.end
            )
        );
    }
}

/// A step of two or three typical ones is a gap of lost samples: the message counts them and
/// says a tolerance does not mend it; a step off by a fraction may be printing, and the message
/// says so.
#[test]
fn a_gap_of_lost_samples_is_named_as_one() {
    let mut t: Vec<f64> = (0..20).map(|k| k as f64 * 0.01).collect();
    t.drain(10..12); // samples 10 and 11 lost: the step from 0.09 to 0.12 is three steps
    let n = t.len();
    let err = TimeSeries::new(t, vec![0.0; n], vec![0.0; n], "sim").unwrap_err();
    let text = err.to_string();
    assert!(text.contains("2 sample(s) missing"), "{text}");
    assert!(!text.contains("raise the time tolerance"), "{text}");
    let err =
        TimeSeries::new(vec![0.0, 1.0, 2.0, 3.5], vec![0.0; 4], vec![0.0; 4], "sim").unwrap_err();
    assert!(
        err.to_string().contains("raise the time tolerance"),
        "{err}"
    );
    assert_eq!(htfid_data::missing_samples(0.02, 0.01), Some(1));
    assert_eq!(htfid_data::missing_samples(0.015, 0.01), None);
    assert_eq!(htfid_data::missing_samples(0.0102, 0.01), None);
}
