//! HTFs from a record alone (`PeriodicRecord`): against a system whose HTF is known in closed
//! form, and every refusal.

use std::f64::consts::PI;

use htfid_estimate::{Alpha, DataSpec, FromDataError, PeriodChoice, PeriodicRecord};
use num_complex::Complex64;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

const DT: f64 = 0.01;
const PERIOD: f64 = 1.0;

/// A linear time-invariant system `y[k] = 2 u[k] + 0.5 u[k-1]` (so `G_0(jw) = 2 + 0.5
/// exp(-j w dt)` exactly, every other harmonic zero) driven by white noise, with a periodic
/// orbit added to both input and output (what the period average must remove), and a little
/// output noise.
fn record(samples: usize) -> (Vec<f64>, Vec<f64>) {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let white = Normal::new(0.0, 1.0).unwrap();
    let noise = Normal::new(0.0, 1e-3).unwrap();
    let wp = 2.0 * PI / PERIOD;
    let excitation: Vec<f64> = (0..samples).map(|_| white.sample(&mut rng)).collect();
    let mut u = Vec::with_capacity(samples);
    let mut y = Vec::with_capacity(samples);
    for k in 0..samples {
        let t = k as f64 * DT;
        let previous = if k > 0 { excitation[k - 1] } else { 0.0 };
        u.push(excitation[k] + 0.3 * (wp * t).sin());
        y.push(
            2.0 * excitation[k]
                + 0.5 * previous
                + 5.0 * (wp * t).sin()
                + 1.5 * (2.0 * wp * t + 0.4).cos()
                + noise.sample(&mut rng),
        );
    }
    (u, y)
}

fn spec() -> DataSpec {
    DataSpec::new(vec![-1, 0, 1], (1.0, 40.0), Alpha::Fixed(1e-3))
}

/// The period found in the data, `G_0` against its closed form to 1 % (Siddiqi's smoothing
/// bias on a function this smooth and noise of 1e-3 against a response of order 1 leave far
/// less), `G_+-1` below 2 % of `|G_0|` (they are zero), and the orbits taken out.
#[test]
fn an_lti_system_has_its_closed_form_htf() {
    let (u, y) = record(60_000);
    let spec = spec();
    let plan = PeriodicRecord::plan(&y, DT, PeriodChoice::Estimate, &spec).unwrap();
    assert!((plan.period - PERIOD).abs() < 1e-9, "{}", plan.period);
    assert_eq!(plan.periods, 600);
    assert_eq!(plan.samples, 60_000);
    let found = plan.estimate(0.0, &u, &[&y], &spec).unwrap();
    let e = &found.outputs[0].estimate;
    let exact = |w: f64| Complex64::new(2.0, 0.0) + 0.5 * Complex64::from_polar(1.0, -w * DT);
    let mut worst = 0.0f64;
    let mut rows = 0;
    for r in e.rows() {
        let truth = if r.n == 0 {
            exact(r.omega)
        } else {
            Complex64::new(0.0, 0.0)
        };
        let err = (r.value - truth).norm() / 2.5;
        if r.n == 0 {
            worst = worst.max(err);
        } else {
            assert!(err < 0.02, "G_{} at {}: {}", r.n, r.omega, r.value);
        }
        rows += 1;
    }
    assert!(rows > 100);
    assert!(worst < 0.01, "G_0 relative error {worst}");
    // The output's orbit: 5 sin(wp t) is c_1 = -2.5 j, 1.5 cos(2 wp t + 0.4) is
    // c_2 = 0.75 exp(0.4 j). The response to the white excitation falls on these frequencies
    // too: its variance 4.25 gives each coefficient's real and imaginary part a standard
    // deviation of sqrt(4.25 / (2 * 60000)) = 0.006; 0.05 is eight of them.
    let orbit = &found.outputs[0].orbit;
    assert!(
        (orbit[1] - Complex64::new(0.0, -2.5)).norm() < 0.05,
        "{}",
        orbit[1]
    );
    assert!(
        (orbit[2] - 0.75 * Complex64::from_polar(1.0, 0.4)).norm() < 0.05,
        "{}",
        orbit[2]
    );
    // White noise excites the whole band; no harmonic reads past Nyquist (314 rad/s).
    let (lo, hi) = found.excited_band.unwrap();
    assert!(lo < 1.0 && hi > 40.0, "{lo} {hi}");
    assert!(found.unexcited.is_empty() && found.aliased.is_empty());
}

/// Each refusal is its own error, with the numbers a message needs.
#[test]
fn what_the_record_cannot_give_is_refused() {
    let (u, y) = record(3000);
    let spec = spec();
    // 76.54 samples per period.
    match PeriodicRecord::plan(&y, DT, PeriodChoice::Given(0.7654), &spec) {
        Err(FromDataError::PeriodNotWhole { per_period, .. }) => {
            assert!((per_period - 76.54).abs() < 1e-9)
        }
        other => panic!("{other:?}"),
    }
    // One and a half periods of 20 s.
    match PeriodicRecord::plan(&y, DT, PeriodChoice::Given(20.0), &spec) {
        Err(FromDataError::TooFewPeriods { periods: 1, .. }) => {}
        other => panic!("{other:?}"),
    }
    // G_1 at 40 rad/s reads input at 40 - 2 pi; at a step of 0.1 s Nyquist is 31.4 rad/s.
    let coarse: Vec<f64> = y.iter().step_by(10).copied().collect();
    match PeriodicRecord::plan(&coarse, 0.1, PeriodChoice::Given(PERIOD), &spec) {
        Err(FromDataError::BeyondNyquist {
            needed, nyquist, ..
        }) => {
            assert!((needed - (40.0 + 2.0 * PI)).abs() < 1e-9 && (nyquist - 10.0 * PI).abs() < 1e-9)
        }
        other => panic!("{other:?}"),
    }
    assert!(matches!(
        PeriodicRecord::plan(&y[..50], DT, PeriodChoice::Estimate, &spec),
        Err(FromDataError::TooShort { samples: 50 })
    ));
    // A period the data contradict: 1.01 s against the data's 1 s drifts by 0.3 periods over
    // the record, and its period average leaves most of the orbit in.
    let plan = PeriodicRecord::plan(&y, DT, PeriodChoice::Given(1.01), &spec);
    let plan = match plan {
        Ok(plan) => plan,
        Err(e) => panic!("{e}"),
    };
    // An output shorter than the periods the plan reads.
    match plan.estimate(0.0, &u, &[&y, &y[..100]], &spec) {
        Err(FromDataError::Length {
            samples: 100,
            needed,
            ..
        }) => assert_eq!(needed, plan.samples),
        other => panic!("{other:?}"),
    }
    match plan.estimate(0.0, &u, &[&y], &spec) {
        Err(FromDataError::PeriodContradicted { own, .. }) => {
            assert!((own.period - PERIOD).abs() < 1e-3, "{}", own.period)
        }
        other => panic!("{other:?}"),
    }
}
