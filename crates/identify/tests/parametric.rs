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
use htfid_orbit::{LimitCycle, ShootingOptions};
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

/// `G_-1, G_0, G_1` of `htf` on the hopper's grid, as an estimate with a uniform standard
/// error.
fn exact_estimate(htf: &dyn HarmonicTransferFunction) -> HtfEstimate {
    let omegas: Vec<f64> = (0..60).map(|i| 2.0 + 0.5 * f64::from(i)).collect();
    estimate_at(htf, &omegas)
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

/// Options tight enough that the orbits of the finite-difference reference are found to
/// `rtol = 1e-12`.
fn tight() -> Options {
    Options {
        rtol: 1e-12,
        atol: 1e-14,
        ..Options::default()
    }
}

/// The limit cycle of any of the models here.
trait Cycle: Parametric {
    fn cycle(&self, opts: &Options) -> LimitCycle<Self::Mode>;
}

impl Cycle for Hopper {
    fn cycle(&self, opts: &Options) -> LimitCycle<Self::Mode> {
        self.limit_cycle(&ShootingOptions::default(), opts)
            .unwrap()
            .cycle
    }
}

impl Cycle for Model {
    fn cycle(&self, opts: &Options) -> LimitCycle<Self::Mode> {
        self.limit_cycle(&ShootingOptions::default(), opts).unwrap()
    }
}

/// `G_-1, G_0, G_1` of `htf` at `omegas`, as an estimate with a uniform standard error.
fn estimate_at(htf: &dyn HarmonicTransferFunction, omegas: &[f64]) -> HtfEstimate {
    let harmonics = vec![-1, 0, 1];
    let values = harmonics
        .iter()
        .map(|&n| omegas.iter().map(|&w| htf.g(n, w)).collect())
        .collect();
    HtfEstimate::new(
        Method::Siddiqi,
        harmonics,
        vec![omegas.to_vec(); 3],
        values,
        vec![vec![1e-6; omegas.len()]; 3],
    )
    .expect("consistent arrays")
}

/// The fit's Jacobian at the first step against a second method, for the parameters `names`
/// of `model`: central differences of the exact HTF at steps `h` and `2h` (`h = step` of the
/// parameter, `1e-4` unless a test says why not), each model's orbit found afresh at
/// `rtol = 1e-12`, combined by Richardson extrapolation (truncation `O(h^4)`, about 1e-16;
/// the orbit's error over the step, `1e-12 / 1e-4 = 1e-8`). Returns per column the norm of the difference, the reference's
/// norm and the parameter's value. The fit starts at the truth, so the Jacobian it reports
/// is taken at `model`'s own values.
fn jacobian_against_differences<S: Cycle>(
    model: &S,
    names: &[&str],
    omegas: &[f64],
    step: f64,
) -> Vec<Column> {
    let start = model.cycle(&opts());
    let htf = LinearisedHtf::new(model, &start, &opts()).unwrap();
    let estimate = estimate_at(&htf.channel(0).unwrap(), omegas);
    let spec = HtfFitSpec::new(
        names.iter().map(|n| (*n).to_string()).collect(),
        vec![-1, 0, 1],
        (0.0, f64::INFINITY),
    );
    let fit = fit_to_htf(model, &start, &[(0, &estimate)], &spec, &opts()).unwrap();
    assert_eq!(fit.jacobian_method, "exact");
    let points: Vec<(i32, f64)> = fit.fitted.iter().map(|f| (f.n, f.omega)).collect();
    let g_at = |name: &str, value: f64| {
        let trial = model.unforced_with(&[(name, value)]).unwrap();
        let cycle = trial.cycle(&tight());
        let htf = LinearisedHtf::new(&trial, &cycle, &tight()).unwrap();
        htf.channel(0).unwrap().values(&points)
    };
    let mut out = Vec::new();
    for (j, name) in fit.parameters.iter().enumerate() {
        let p = fit.values[j];
        let h = step * p;
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
        let (diff, norm) = (diff.sqrt(), norm.sqrt());
        eprintln!(
            "d/d{name}: relative difference {:e} (column norm {norm:e}, times the value {:e})",
            diff / norm,
            norm * p.abs()
        );
        out.push(Column {
            name: name.clone(),
            diff,
            norm,
            value: p,
        });
    }
    out
}

/// One column of the comparison.
struct Column {
    name: String,
    /// The norm of the difference from the reference, and the reference's norm.
    diff: f64,
    norm: f64,
    /// The parameter's value.
    value: f64,
}

/// The relative step of the differences, unless a test says why not.
const STEP: f64 = 1e-4;

/// The tolerance of the comparisons below: ten times the reference's own error (1e-8, see
/// [`jacobian_against_differences`]).
const JACOBIAN_TOLERANCE: f64 = 1e-7;

/// Every column within [`JACOBIAN_TOLERANCE`] of its reference, relative to its norm. A
/// parameter that moves nothing (a rest length, which shifts the whole orbit and its guards
/// with it) has a column that is zero in exact arithmetic; the reference's is then its own
/// error. Compared on the scale of a relative change (the column times the parameter's
/// value), such a column must be zero to within the tolerance of the largest column.
fn assert_columns(columns: &[Column]) {
    let largest = columns
        .iter()
        .map(|c| c.norm * c.value.abs())
        .fold(0.0, f64::max);
    for c in columns {
        let name = &c.name;
        if c.norm * c.value.abs() >= 1e-6 * largest {
            let relative = c.diff / c.norm;
            assert!(
                relative < JACOBIAN_TOLERANCE,
                "d/d{name}: relative difference {relative:e}"
            );
        } else {
            let scaled = c.diff * c.value.abs() / largest;
            assert!(
                scaled < JACOBIAN_TOLERANCE,
                "d/d{name}: not zero, {scaled:e} of the largest"
            );
        }
    }
}

/// The built-in hopper (its tangents from its own orbit sensitivity and moved switches).
/// Measured: 1e-10 of the column's norm for `k`, `c` and `m` (the forward difference of step
/// `FD_STEP` that the fit took before was 1.2e-4 off for `k`). The forcing amplitude `a`
/// moves neither the switches nor any matrix of this piecewise-linear hopper, so its column
/// is zero and has no relative error to measure.
#[test]
fn the_fits_jacobian_matches_an_extrapolated_central_difference() {
    let hopper = Hopper::new(HopperParams::paper()).unwrap();
    let names = ["k", "c", "m"];
    let omegas: Vec<f64> = (0..60).map(|i| 2.0 + 0.5 * f64::from(i)).collect();
    assert_columns(&jacobian_against_differences(
        &hopper, &names, &omegas, STEP,
    ));
}

/// The hopper written in the model language (its tangents from symbolic second derivatives,
/// the orbit's periodic sensitivity and the moved switches, `Model::piecewise_tangents`),
/// with every parameter that shapes its linearisation, the mass and the rest length
/// included.
#[test]
fn the_model_files_jacobian_matches_an_extrapolated_central_difference() {
    let names = ["k", "c", "m", "x0", "a"];
    let omegas: Vec<f64> = (0..60).map(|i| 2.0 + 0.5 * f64::from(i)).collect();
    assert_columns(&jacobian_against_differences(
        &model_file(),
        &names,
        &omegas,
        STEP,
    ));
}

fn shipped(name: &str) -> Model {
    Model::from_file(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../models/{name}.toml")),
    )
    .expect("the shipped model reads")
}

/// The ball on the vibrating table: every switch is an impact whose saltation depends on the
/// restitution `e`, on gravity and on the table's motion, on a guard that moves in time. The
/// linearisation's matrices do not change at all; the whole derivative is the moved impact
/// and its changed jump (`dJ` from the saltation's symbolic derivatives).
#[test]
fn the_bouncing_balls_jacobian_matches_an_extrapolated_central_difference() {
    let names = ["e", "g", "A"];
    let wp = std::f64::consts::TAU / 0.25;
    let omegas: Vec<f64> = (0..40).map(|i| wp * (0.05 + 0.07 * f64::from(i))).collect();
    assert_columns(&jacobian_against_differences(
        &shipped("bouncing-ball"),
        &names,
        &omegas,
        STEP,
    ));
}

/// The hopper with a flight phase: touchdown on a fixed height, liftoff where the ground's
/// force (spring, damper and the thrust of time) vanishes; the stance matrices, both guards
/// and the touchdown's non-identity saltation all move.
#[test]
fn the_flight_hoppers_jacobian_matches_an_extrapolated_central_difference() {
    let names = ["k", "c", "m", "L0", "a"];
    let wp = std::f64::consts::TAU / 0.5;
    let omegas: Vec<f64> = (0..40).map(|i| wp * (0.05 + 0.07 * f64::from(i))).collect();
    assert_columns(&jacobian_against_differences(
        &shipped("flight-hopper"),
        &names,
        &omegas,
        STEP,
    ));
}

/// The two-degree-of-freedom oscillator: a cubic spring, so `A(t)` varies along the orbit and
/// its HTFs are taken along it (`OrbitHtf`); its Jacobian from the orbit's tangents
/// (`Model::orbit_tangents`: the orbit's sensitivity, the Hessian of the field, the moved
/// switches of the first damper and their saltation's change) through
/// `OrbitHtf::derivatives`.
#[test]
fn the_two_dofs_jacobian_along_the_orbit_matches_an_extrapolated_central_difference() {
    let names = ["k1", "k3", "c1", "c2", "m1"];
    let wp = std::f64::consts::TAU;
    let omegas: Vec<f64> = (0..12).map(|i| wp * (0.15 + 0.4 * f64::from(i))).collect();
    let model = shipped("two-dof");
    assert!(!htfid_ltp::InputOutput::is_piecewise_constant(&model));
    assert_columns(&jacobian_against_differences(&model, &names, &omegas, STEP));
}

/// The free mass under PD control with smooth friction (`tanh`): one mode, no switch, the
/// linearisation varying with the velocity along the orbit. Its friction law is stiff
/// (`vs = 0.01 m/s`), and the reference's own error grows as its step shrinks: for `vs` the
/// difference is 2.4e-8 at a step of 1e-3, 7.9e-8 at 3e-4, 1.7e-7 at 1e-4 (measured; the
/// Jacobian itself did not move when the fit's tolerance was tightened to the reference's).
/// The step is therefore 1e-3, whose truncation (`O(h^4)` along a law that changes by 3e-3
/// of its argument over the step) stays near 1e-10.
#[test]
fn the_closed_loops_jacobian_along_the_orbit_matches_an_extrapolated_central_difference() {
    let names = ["Fc", "b", "kp", "vs"];
    let wp = std::f64::consts::TAU;
    let omegas: Vec<f64> = (0..12).map(|i| wp * (0.15 + 0.4 * f64::from(i))).collect();
    assert_columns(&jacobian_against_differences(
        &shipped("closed-loop-friction"),
        &names,
        &omegas,
        1e-3,
    ));
}

/// A ball on a table whose height is the forcing plus the input: the guard reads the input,
/// so the input moves every impact and the state jumps by it there (`OrbitHtf`'s input
/// jump). Its Jacobian along the orbit includes the change of that jump
/// (`OrbitTangents::input_jump_change`).
#[test]
fn a_guard_that_reads_the_input_has_its_jacobian_along_the_orbit() {
    let model = Model::from_file(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../tests/fixtures/models/ball-moved-by-input.toml"),
    )
    .unwrap();
    let names = ["e", "g", "A"];
    let wp = std::f64::consts::TAU / 0.25;
    let omegas: Vec<f64> = (0..12).map(|i| wp * (0.15 + 0.4 * f64::from(i))).collect();
    assert_columns(&jacobian_against_differences(&model, &names, &omegas, STEP));
}
