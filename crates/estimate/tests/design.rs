//! An estimator prepared from the input alone (`Design`, `SiddiqiDesign`) gives what the
//! one-step estimators give on the same signal, bit for bit, and refuses another input.

mod common;

use common::{random_spectrum, synth_record, Grid, Rational, Truth};
use htfid_estimate::{
    estimate_experiment, siddiqi, Alpha, Design, Error, Estimator, HtfEstimate, Layout,
    MultiOptions, Request, Sampled, SiddiqiDesign, TimeSeries,
};
use num_complex::Complex64;

const PERIOD: f64 = 1.0;

/// A record of a random periodic input through a rational HTF with noise-like structure:
/// `p` periods at 25 Hz, starting at 12.34 s.
fn record(p: usize, seed: u64) -> TimeSeries {
    let truth = Rational::standard(2);
    let grid = Grid {
        n: p * 25,
        dt: 0.04,
        period: PERIOD,
    };
    let kmax = (8.0 / grid.dw()) as i64 + 1 + i64::from(truth.nmax()) * grid.p();
    synth_record(grid, &random_spectrum(kmax, seed), 0.0, 12.34, &truth)
}

fn bits(e: &HtfEstimate) -> Vec<(i32, u64, u64, u64, u64)> {
    e.rows()
        .map(|r| {
            (
                r.n,
                r.omega.to_bits(),
                r.value.re.to_bits(),
                r.value.im.to_bits(),
                r.stderr.to_bits(),
            )
        })
        .collect()
}

fn bias_bits(e: &HtfEstimate) -> Vec<(u64, u64)> {
    e.bias()
        .map(|(_, b)| {
            b.iter()
                .flatten()
                .map(|c: &Complex64| (c.re.to_bits(), c.im.to_bits()))
                .collect()
        })
        .unwrap_or_default()
}

#[test]
fn a_prepared_siddiqi_estimate_equals_the_one_step_estimate() {
    let rec = record(40, 7);
    let harmonics = [-2, -1, 0, 1, 2];
    for alpha in [1e-3, 1.0, 300.0] {
        let one =
            siddiqi(&rec, PERIOD, &harmonics, (0.5, 8.0), Alpha::Fixed(alpha)).expect("estimates");
        let design =
            SiddiqiDesign::new(&rec, PERIOD, &harmonics, (0.5, 8.0), alpha).expect("prepares");
        let two = design.estimate(&rec).expect("estimates");
        assert_eq!(bits(&one), bits(&two), "alpha {alpha}");
        assert_eq!(bias_bits(&one), bias_bits(&two), "alpha {alpha}");
        assert_eq!(one.alpha(), two.alpha());
        assert_eq!(one.alpha_effective(), two.alpha_effective());
    }
}

#[test]
fn a_design_estimates_as_estimate_experiment_does_for_every_estimator() {
    // Nine copies of a 4 s record one after the other, each shifted by a ninth of the period,
    // after 3 s of settling: the layout of a chirp train.
    let rec = record(40, 11);
    let (u, y, dt, t0) = (rec.input(), rec.output(), rec.dt(), rec.time()[0]);
    let copies: Vec<f64> = (0..9).map(|k| t0 + 3.0 + 4.0 * f64::from(k)).collect();
    let layout = Layout {
        excited_from: t0 + 3.0,
        copies: Some((copies, 4.0)),
        lines: None,
    };
    let harmonics = [-1, 0, 1];
    let request = Request {
        period: PERIOD,
        harmonics: &harmonics,
        band: (1.0, 8.0),
    };
    let signal = Sampled {
        u,
        y,
        dt,
        t_start: t0,
    };
    for estimator in [
        Estimator::Siddiqi(Alpha::Fixed(1.0)),
        Estimator::Siddiqi(Alpha::Gcv),
        Estimator::Multi(MultiOptions::default()),
    ] {
        let one = estimate_experiment(&signal, &layout, &request, &estimator).expect("estimates");
        let design = Design::new((u, dt, t0), &layout, &request, &estimator).expect("prepares");
        let two = design.estimate(y).expect("estimates");
        assert_eq!(bits(&one), bits(&two), "{}", estimator.name());
        assert_eq!(bias_bits(&one), bias_bits(&two), "{}", estimator.name());
        // The same design serves any number of outputs.
        let halved: Vec<f64> = y.iter().map(|v| 0.5 * v).collect();
        let three = design.estimate(&halved).expect("estimates");
        let four = estimate_experiment(
            &Sampled {
                y: &halved,
                ..signal
            },
            &layout,
            &request,
            &estimator,
        )
        .expect("estimates");
        assert_eq!(bits(&three), bits(&four), "{}", estimator.name());
    }
}

#[test]
fn a_prepared_estimator_refuses_a_record_with_another_input() {
    let rec = record(40, 3);
    let harmonics = [-1, 0, 1];
    let design = SiddiqiDesign::new(&rec, PERIOD, &harmonics, (0.5, 8.0), 1.0).expect("prepares");
    let mut u = rec.input().to_vec();
    u[17] += 1e-9;
    let other = htfid_estimate::deviation_record(u, rec.output().to_vec(), rec.dt(), rec.time()[0])
        .expect("record");
    assert!(matches!(
        design.estimate(&other),
        Err(Error::InputDiffers { index: 17 })
    ));
    let shorter = htfid_estimate::deviation_record(
        rec.input()[..500].to_vec(),
        rec.output()[..500].to_vec(),
        rec.dt(),
        rec.time()[0],
    )
    .expect("record");
    let err = design.estimate(&shorter).unwrap_err();
    assert!(matches!(err, Error::InputDiffers { .. }), "{err}");
    assert!(err.to_string().contains("prepare it again"), "{err}");
}
