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

/// The fit's Jacobian (exact: the hopper's linearisation tangents, its orbit's sensitivity
/// and moved switches, through `ExactHtf::derivatives`) against a second method: central
/// differences of the exact HTF at steps `h` and `2h` (`h = 1e-4` of the parameter), each
/// model's orbit found afresh at `rtol = 1e-12`, combined by Richardson extrapolation
/// (truncation `O(h^4)`, about 1e-16; the orbit's error over the step, `1e-12 / 1e-4 =
/// 1e-8`). Measured: 1e-10 of the column's norm for `k`, `c` and `m` (the forward difference
/// of step `FD_STEP` that the fit took before was 1.2e-4 off for `k`); the tolerance, 1e-7,
/// is ten times the reference's own error. The forcing amplitude `a` moves neither the
/// switches nor any matrix of this piecewise-linear hopper, so its column is zero and has no
/// relative error to measure.
#[test]
fn the_fits_jacobian_matches_an_extrapolated_central_difference() {
    let hopper = Hopper::new(HopperParams::paper()).unwrap();
    let start = hopper
        .limit_cycle(&ShootingOptions::default(), &opts())
        .unwrap();
    let htf = LinearisedHtf::new(&hopper, &start.cycle, &opts()).unwrap();
    let estimate = exact_estimate(&htf.channel(0).unwrap());
    let spec = HtfFitSpec::new(
        vec!["k".into(), "c".into(), "m".into()],
        vec![-1, 0, 1],
        (1.0, 40.0),
    );
    let fit = fit_to_htf(&hopper, &start.cycle, &[(0, &estimate)], &spec, &opts()).unwrap();
    assert_eq!(fit.jacobian_method, "exact");

    let tight = Options {
        rtol: 1e-12,
        atol: 1e-14,
        ..Options::default()
    };
    let points: Vec<(i32, f64)> = fit.fitted.iter().map(|f| (f.n, f.omega)).collect();
    let g_at = |name: &str, value: f64| {
        let trial = hopper.unforced_with(&[(name, value)]).unwrap();
        let cycle = trial
            .limit_cycle(&ShootingOptions::default(), &tight)
            .unwrap();
        let htf = LinearisedHtf::new(&trial, &cycle.cycle, &tight).unwrap();
        htf.channel(0).unwrap().values(&points)
    };
    for (j, name) in fit.parameters.iter().enumerate() {
        let p = fit.values[j];
        let h = 1e-4 * p;
        let (plus, minus) = (g_at(name, p + h), g_at(name, p - h));
        let (plus2, minus2) = (g_at(name, p + 2.0 * h), g_at(name, p - 2.0 * h));
        let mut diff = 0.0;
        let mut norm = 0.0;
        for (i, point) in fit.fitted.iter().enumerate() {
            let d1 = (plus[i] - minus[i]) / (2.0 * h);
            let d2 = (plus2[i] - minus2[i]) / (4.0 * h);
            // The residual is (estimate - G) * weight.
            let d = -(d1 * 4.0 - d2) / 3.0 * point.weight;
            for (fitted, reference) in [
                (fit.jacobian[2 * i][j], d.re),
                (fit.jacobian[2 * i + 1][j], d.im),
            ] {
                diff += (fitted - reference).powi(2);
                norm += reference.powi(2);
            }
        }
        let relative = (diff / norm).sqrt();
        eprintln!("d/d{name}: relative difference {relative:e}");
        assert!(
            relative < 1e-7,
            "d/d{name}: relative difference {relative:e}"
        );
    }
}
