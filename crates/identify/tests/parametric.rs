//! One fit for every model: the built-in hopper fitted to HTFs of the hopper written in the
//! model language (`models/hopper.toml`, checked against its closed-form oracle in
//! `htfid-lang`), and the other way round. The two are separate implementations of the same
//! equations, so each recovers the other's parameters.

use std::path::Path;

use htfid_estimate::{HtfEstimate, Method};
use htfid_hybrid::Options;
use htfid_identify::{fit_to_htf, HtfFitSpec, Parametric};
use htfid_lang::Model;
use htfid_model::{Hopper, HopperParams};
use htfid_orbit::ShootingOptions;
use htfid_theory::{HarmonicTransferFunction, LinearisedHtf};

fn opts() -> Options {
    Options {
        rtol: 1e-10,
        atol: 1e-12,
        ..Options::default()
    }
}

fn model_file() -> Model {
    Model::from_file(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/hopper.toml"))
        .expect("the shipped hopper model reads")
}

/// `G_-1, G_0, G_1` of `htf` on a grid, as an estimate with a uniform standard error.
fn exact_estimate(htf: &dyn HarmonicTransferFunction) -> HtfEstimate {
    let harmonics = vec![-1, 0, 1];
    let omegas: Vec<f64> = (0..60).map(|i| 2.0 + 0.5 * f64::from(i)).collect();
    let values = harmonics
        .iter()
        .map(|&n| omegas.iter().map(|&w| htf.g(n, w)).collect())
        .collect();
    HtfEstimate::new(
        Method::Siddiqi,
        harmonics,
        vec![omegas.clone(); 3],
        values,
        vec![vec![1e-6; omegas.len()]; 3],
    )
    .expect("consistent arrays")
}

fn spec() -> HtfFitSpec {
    HtfFitSpec::new(vec!["k".into(), "c".into()], vec![-1, 0, 1], (1.0, 40.0))
}

/// Both fits converge to within 1e-6 of the truth: the HTFs of the two implementations agree
/// to the integrator's tolerance (1e-10), far inside this.
const TOLERANCE: f64 = 1e-6;

#[test]
fn the_hopper_recovers_the_model_files_parameters() {
    let truth = model_file()
        .with_parameters(&[("k", 210.0), ("c", 2.5)])
        .unwrap();
    let cycle = truth
        .limit_cycle(&ShootingOptions::default(), &opts())
        .unwrap();
    let htf = LinearisedHtf::new(&truth, &cycle, &opts()).unwrap();
    let estimate = exact_estimate(&htf.channel(0).unwrap());

    let hopper = Hopper::new(HopperParams::paper()).unwrap();
    assert!(htfid_ltp::InputOutput::is_piecewise_constant(&hopper));
    let start = hopper
        .limit_cycle(&ShootingOptions::default(), &opts())
        .unwrap();
    let fit = fit_to_htf(&hopper, &start.cycle, &[(0, &estimate)], &spec(), &opts()).unwrap();
    assert!((fit.values[0] / 210.0 - 1.0).abs() < TOLERANCE, "{fit:?}");
    assert!((fit.values[1] / 2.5 - 1.0).abs() < TOLERANCE, "{fit:?}");
    assert_eq!(fit.fitted.len(), fit.points);
    assert_eq!(fit.residuals.len(), 2 * fit.points);
}

#[test]
fn the_model_file_recovers_the_hoppers_parameters() {
    let params = HopperParams {
        k: 190.0,
        c: 1.5,
        ..HopperParams::paper()
    };
    let truth = Hopper::new(params).unwrap();
    let cycle = truth
        .limit_cycle(&ShootingOptions::default(), &opts())
        .unwrap();
    let htf = LinearisedHtf::new(&truth, &cycle.cycle, &opts()).unwrap();
    let estimate = exact_estimate(&htf.channel(0).unwrap());

    let model = model_file();
    let start = model
        .limit_cycle(&ShootingOptions::default(), &opts())
        .unwrap();
    let fit = fit_to_htf(&model, &start, &[(0, &estimate)], &spec(), &opts()).unwrap();
    assert!((fit.values[0] / 190.0 - 1.0).abs() < TOLERANCE, "{fit:?}");
    assert!((fit.values[1] / 1.5 - 1.0).abs() < TOLERANCE, "{fit:?}");
}

#[test]
fn the_hopper_names_its_parameters_and_refuses_others() {
    let hopper = Hopper::new(HopperParams::paper()).unwrap();
    assert_eq!(hopper.parameter("k"), Some((200.0, (1e-12, f64::INFINITY))));
    assert_eq!(hopper.parameter("c").map(|p| p.1 .0), Some(0.0));
    assert!(hopper.parameter("q").is_none());
    let err = hopper.unforced_with(&[("q", 1.0)]).unwrap_err();
    assert!(
        err.contains("no parameter q") && err.contains("m, k, c"),
        "{err}"
    );
    let err = hopper.unforced_with(&[("m", -1.0)]).unwrap_err();
    assert!(err.contains('m'), "{err}");
    let changed = hopper.unforced_with(&[("k", 150.0), ("a", 2.0)]).unwrap();
    assert!((changed.params().k - 150.0).abs() < 1e-12);
    assert!((changed.params().forcing_amplitude - 2.0).abs() < 1e-12);
}
