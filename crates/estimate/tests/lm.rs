//! Levenberg-Marquardt against problems with known answers.

use htfid_estimate::{
    levenberg_marquardt, levenberg_marquardt_batch, levenberg_marquardt_parallel, Error, FdScheme,
    LmOptions, LmStop,
};
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

type Never = std::convert::Infallible;
type Problem<'a> = dyn Fn(&[f64], &mut [f64]) -> Result<(), Never> + 'a;
/// A named problem, its start, its residual count and its known minimum.
type Case<'a> = (&'a str, &'a Problem<'a>, Vec<f64>, usize, Vec<f64>);

#[test]
fn rosenbrock_reaches_its_minimum() {
    // r = (10 (y - x^2), 1 - x): cost (1 - x)^2 + 100 (y - x^2)^2, minimum 0 at (1, 1).
    let f = |p: &[f64], r: &mut [f64]| -> Result<(), Never> {
        r[0] = 10.0 * (p[1] - p[0] * p[0]);
        r[1] = 1.0 - p[0];
        Ok(())
    };
    let fit = levenberg_marquardt(f, &[-1.2, 1.0], 2, &LmOptions::default()).unwrap();
    // The residuals vanish at the minimum, so the finite-difference error (~1e-10 in J) does
    // not bias the solution; 1e-8 is rounding plus the stopping tolerance.
    assert!((fit.params[0] - 1.0).abs() < 1e-8 && (fit.params[1] - 1.0).abs() < 1e-8);
    assert!(fit.cost < 1e-16, "cost {}", fit.cost);
    assert!(
        fit.covariance.is_none(),
        "m = p leaves no degrees of freedom"
    );
    assert!(fit.iterations < 100, "{} iterations", fit.iterations);
    // One iteration is not enough from the classic start.
    let short = LmOptions {
        max_iter: 1,
        ..LmOptions::default()
    };
    let fit = levenberg_marquardt(f, &[-1.2, 1.0], 2, &short).unwrap();
    assert_eq!(fit.stop, LmStop::MaxIterations);
}

#[test]
fn linear_least_squares_matches_the_closed_form() {
    // Quadratic model, residuals linear in the parameters: LM must land on the normal-equation
    // solution, and its covariance must be s^2 (X^T X)^{-1}.
    let xs: Vec<f64> = (0..30).map(|i| -1.0 + i as f64 / 14.5).collect();
    let ys: Vec<f64> = xs
        .iter()
        .enumerate()
        .map(|(i, &x)| 0.5 - 1.5 * x + 2.0 * x * x + 0.1 * ((i * 37 % 11) as f64 / 11.0 - 0.5))
        .collect();
    let f = |p: &[f64], r: &mut [f64]| -> Result<(), Never> {
        for i in 0..xs.len() {
            r[i] = p[0] + p[1] * xs[i] + p[2] * xs[i] * xs[i] - ys[i];
        }
        Ok(())
    };
    let fit = levenberg_marquardt(f, &[0.0, 0.0, 0.0], xs.len(), &LmOptions::default()).unwrap();
    let x = DMatrix::from_fn(xs.len(), 3, |i, j| xs[i].powi(j as i32));
    let y = DVector::from_column_slice(&ys);
    let xtx_inv = (x.transpose() * &x).try_inverse().unwrap();
    let beta = &xtx_inv * x.transpose() * &y;
    let res = &y - &x * &beta;
    let s2 = res.norm_squared() / (xs.len() - 3) as f64;
    let cov = fit.covariance.as_ref().unwrap();
    for j in 0..3 {
        // Central differences of a linear function are exact up to rounding (eps / h ~ 1e-11).
        assert!((fit.params[j] - beta[j]).abs() < 1e-9, "p{j}");
        for k in 0..3 {
            let want = s2 * xtx_inv[(j, k)];
            assert!(
                (cov[j][k] - want).abs() < 1e-6 * s2 * xtx_inv[(j, j)].abs(),
                "cov {j}{k}"
            );
        }
    }
    assert!((fit.cost - res.norm_squared()).abs() < 1e-12);
}

fn decay_data(rng: &mut ChaCha8Rng, sigma: f64) -> (Vec<f64>, Vec<f64>) {
    let normal = Normal::new(0.0, sigma).unwrap();
    let t: Vec<f64> = (0..50).map(|i| i as f64 * 0.1).collect();
    let y = t
        .iter()
        .map(|&t| 2.0 * (-0.7 * t).exp() + normal.sample(rng))
        .collect();
    (t, y)
}

fn fit_decay(t: &[f64], y: &[f64], scheme: FdScheme) -> htfid_estimate::LmFit {
    let f = |p: &[f64], r: &mut [f64]| -> Result<(), Never> {
        for i in 0..t.len() {
            r[i] = p[0] * (-p[1] * t[i]).exp() - y[i];
        }
        Ok(())
    };
    let opts = LmOptions {
        fd_scheme: scheme,
        ..LmOptions::default()
    };
    levenberg_marquardt(f, &[1.0, 0.2], t.len(), &opts).unwrap()
}

#[test]
fn exponential_decay_standard_errors_match_monte_carlo_scatter() {
    let mut rng = ChaCha8Rng::seed_from_u64(2024);
    let trials = 200;
    let mut est = vec![Vec::new(); 2];
    let mut rep2 = [0.0; 2];
    for _ in 0..trials {
        let (t, y) = decay_data(&mut rng, 0.02);
        let fit = fit_decay(&t, &y, FdScheme::Central);
        let se = fit.stderr.unwrap();
        for j in 0..2 {
            est[j].push(fit.params[j]);
            rep2[j] += se[j] * se[j] / trials as f64;
        }
    }
    // The sample standard deviation of 200 estimates has a relative spread of
    // 1/sqrt(2 * 199) = 5%, the mean reported variance far less, and at 1% noise the
    // nonlinearity bias is second order: 0.8..1.25 is a > 4 sigma band.
    for j in 0..2 {
        let mean = est[j].iter().sum::<f64>() / trials as f64;
        let var = est[j].iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (trials - 1) as f64;
        let ratio = (var / rep2[j]).sqrt();
        assert!((0.8..1.25).contains(&ratio), "parameter {j}: ratio {ratio}");
        // And the estimates are unbiased to within their scatter.
        let truth = [2.0, 0.7][j];
        assert!((mean - truth).abs() < 4.0 * var.sqrt() / (trials as f64).sqrt());
    }
}

#[test]
fn forward_differences_reach_the_same_minimum() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let (t, y) = decay_data(&mut rng, 0.02);
    let c = fit_decay(&t, &y, FdScheme::Central);
    let f = fit_decay(&t, &y, FdScheme::Forward);
    // Forward differences carry O(sqrt(eps)) ~ 1e-8 relative Jacobian error; the minimum itself
    // does not depend on J, only the path and the covariance do.
    for j in 0..2 {
        assert!((c.params[j] - f.params[j]).abs() < 1e-7 * c.params[j].abs());
        let (sc, sf) = (c.stderr.as_ref().unwrap()[j], f.stderr.as_ref().unwrap()[j]);
        assert!((sc - sf).abs() < 1e-5 * sc);
    }
}

#[test]
fn failures_at_the_start_are_errors_and_later_failures_are_avoided() {
    let fails = |_: &[f64], _: &mut [f64]| -> Result<(), String> { Err("model blew up".into()) };
    let e = levenberg_marquardt(fails, &[1.0], 3, &LmOptions::default()).unwrap_err();
    assert_eq!(
        e.to_string(),
        "residual function failed at the start point: model blew up"
    );
    let nan = |_: &[f64], r: &mut [f64]| -> Result<(), Never> {
        r[0] = 1.0;
        r[1] = f64::NAN;
        Ok(())
    };
    let e = levenberg_marquardt(nan, &[1.0], 2, &LmOptions::default()).unwrap_err();
    assert!(matches!(e, Error::NonFiniteResidual { index: 1, .. }));
    // r = sqrt(p) - 0.5 is undefined for p < 0; the first full step from p = 4 overshoots into
    // p < 0 and must be rejected, not crash. Minimum at p = 0.25.
    let sqrt = |p: &[f64], r: &mut [f64]| -> Result<(), String> {
        if p[0] < 0.0 {
            return Err(format!("negative p = {}", p[0]));
        }
        r[0] = p[0].sqrt() - 0.5;
        r[1] = 0.0;
        Ok(())
    };
    let fit = levenberg_marquardt(sqrt, &[4.0], 2, &LmOptions::default()).unwrap();
    assert!((fit.params[0] - 0.25).abs() < 1e-8, "{:?}", fit.params);
}

#[test]
fn bounds_hold_and_invalid_options_are_rejected() {
    let f = |p: &[f64], r: &mut [f64]| -> Result<(), Never> {
        r[0] = p[0] - 5.0;
        r[1] = 0.1 * (p[0] - 5.0);
        Ok(())
    };
    let opts = LmOptions {
        bounds: Some(vec![(0.0, 2.0)]),
        ..LmOptions::default()
    };
    let fit = levenberg_marquardt(f, &[1.0], 2, &opts).unwrap();
    assert!((fit.params[0] - 2.0).abs() < 1e-12, "{:?}", fit.params);
    let e = levenberg_marquardt(f, &[3.0], 2, &opts).unwrap_err();
    assert!(matches!(e, Error::InvalidStart { index: 0, .. }));
    let bad = LmOptions {
        bounds: Some(vec![(1.0, 0.0)]),
        ..LmOptions::default()
    };
    assert!(matches!(
        levenberg_marquardt(f, &[0.5], 2, &bad),
        Err(Error::InvalidBounds { index: 0, .. })
    ));
    assert!(matches!(
        levenberg_marquardt(f, &[], 2, &LmOptions::default()),
        Err(Error::LmDimensions { .. })
    ));
    let bad = LmOptions {
        scales: Some(vec![1.0, 2.0]),
        ..LmOptions::default()
    };
    assert!(matches!(
        levenberg_marquardt(f, &[0.5], 2, &bad),
        Err(Error::WrongLength { what: "scales", .. })
    ));
}

/// A minimum on the box's edge: `(p0 + 1)^2 + (p1 - 2)^2 + (p0 + 1)(p1 - 2)` with `p0 >= 0`
/// has its constrained minimum where `d/dp1 = 0` at `p0 = 0`: `p1 = 2 - 1/2`. The parameter
/// held by its bound leaves the step and the gradient test, so the fit lands on the exact
/// constrained minimum (a Newton step of the remaining quadratic) and stops within a few
/// Jacobians, where clipping every step would crawl.
#[test]
fn a_minimum_on_a_bound_converges_on_the_projected_gradient() {
    let f = |p: &[f64], r: &mut [f64]| -> Result<(), Never> {
        // r^T r = (p0 + 1)^2 + (p1 - 2)^2 + (p0 + 1)(p1 - 2), written as a sum of squares.
        let (a, b) = (p[0] + 1.0, p[1] - 2.0);
        r[0] = a + 0.5 * b;
        r[1] = 0.75f64.sqrt() * b;
        Ok(())
    };
    let opts = LmOptions {
        bounds: Some(vec![(0.0, 10.0), (-10.0, 10.0)]),
        ..LmOptions::default()
    };
    let fit = levenberg_marquardt(f, &[3.0, 0.0], 2, &opts).unwrap();
    assert!(fit.params[0].abs() < 1e-12, "{:?}", fit.params);
    assert!((fit.params[1] - 1.5).abs() < 1e-9, "{:?}", fit.params);
    assert!(
        matches!(fit.stop, LmStop::GradientTolerance | LmStop::CostTolerance),
        "{fit:?}"
    );
    assert!(fit.iterations <= 8, "{} Jacobians", fit.iterations);
}

#[test]
fn parallel_jacobians_give_the_same_iterates() {
    // Both schemes, a bound the fit runs into, and a residual that fails at some trial points:
    // the parallel variant must reproduce the serial one exactly.
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let (t, y) = decay_data(&mut rng, 0.05);
    let f = |p: &[f64], r: &mut [f64]| -> Result<(), String> {
        if p[1] > 5.0 {
            return Err("too fast".into());
        }
        for i in 0..t.len() {
            r[i] = p[0] * (-p[1] * t[i]).exp() + p[2] - y[i];
        }
        Ok(())
    };
    for scheme in [FdScheme::Forward, FdScheme::Central] {
        let opts = LmOptions {
            fd_scheme: scheme,
            bounds: Some(vec![(0.0, 10.0), (0.0, 10.0), (0.05, 1.0)]),
            ..LmOptions::default()
        };
        let serial = levenberg_marquardt(f, &[1.0, 0.2, 0.3], t.len(), &opts).unwrap();
        let parallel = levenberg_marquardt_parallel(f, &[1.0, 0.2, 0.3], t.len(), &opts).unwrap();
        assert_eq!(serial.params, parallel.params, "{scheme:?}");
        assert_eq!(serial.cost.to_bits(), parallel.cost.to_bits());
        assert_eq!(serial.jacobian, parallel.jacobian);
        assert_eq!(serial.iterations, parallel.iterations);
        assert_eq!(serial.evaluations, parallel.evaluations);
        assert_eq!(serial.stop, parallel.stop);
        // The batch variant, its points evaluated together in reverse order (a batch function
        // is free to order its work): the same iterates again.
        let batch = |points: &[&[f64]], outs: &mut [&mut [f64]]| {
            let mut results: Vec<Result<(), String>> = Vec::with_capacity(points.len());
            for (p, r) in points.iter().zip(outs.iter_mut()).rev() {
                results.push(f(p, r));
            }
            results.reverse();
            results
        };
        let batched = levenberg_marquardt_batch(batch, &[1.0, 0.2, 0.3], t.len(), &opts).unwrap();
        assert_eq!(serial.params, batched.params, "{scheme:?}");
        assert_eq!(serial.cost.to_bits(), batched.cost.to_bits());
        assert_eq!(serial.jacobian, batched.jacobian);
        assert_eq!(serial.iterations, batched.iterations);
        assert_eq!(serial.evaluations, batched.evaluations);
        assert_eq!(serial.stop, batched.stop);
    }
}

#[test]
fn a_batch_that_fails_a_column_names_the_first_such_column() {
    // Every point off the start fails: the first column's difference fails on both sides, and
    // the error names it, as the serial iteration does.
    let f = |points: &[&[f64]], outs: &mut [&mut [f64]]| -> Vec<Result<(), String>> {
        points
            .iter()
            .zip(outs.iter_mut())
            .map(|(p, r)| {
                if p[0].to_bits() != 1.0f64.to_bits() || p[1].to_bits() != 2.0f64.to_bits() {
                    return Err("off the start".to_string());
                }
                r[0] = p[0] - 3.0;
                r[1] = p[1] - 1.0;
                r[2] = p[0] * p[1];
                Ok(())
            })
            .collect()
    };
    let err = levenberg_marquardt_batch(f, &[1.0, 2.0], 3, &LmOptions::default()).unwrap_err();
    assert!(
        matches!(err, Error::JacobianFailed { index: 0, value } if value.to_bits() == 1.0f64.to_bits()),
        "{err:?}"
    );
}

/// Extending accepted steps (`extend_steps`) reaches the minimum plain steps reach, and where
/// Gauss-Newton steps keep falling short along their direction, with far fewer evaluations.
/// The short steps: fitting `sin(a t) + b` to data it cannot follow (a decaying exponential
/// beside an offset and an oscillation of another frequency), a large-residual problem whose
/// residuals curve against their sign, so the Gauss-Newton model overstates the curvature.
/// Elsewhere (Rosenbrock's valley, a two-exponential fit) an extension is rarely tried and
/// costs at most one evaluation when it fails: at most 10 % more evaluations is allowed.
#[test]
fn extended_steps_reach_the_same_minimum_and_save_evaluations_on_short_steps() {
    let ts: Vec<f64> = (0..40).map(|i| 0.1 * i as f64).collect();
    let ys: Vec<f64> = ts
        .iter()
        .map(|t| 2.0 * (-1.3 * t).exp() + 3.0 + 0.5 * (3.0 * t).sin())
        .collect();
    let sine = |p: &[f64], r: &mut [f64]| -> Result<(), Never> {
        for ((ri, t), y) in r.iter_mut().zip(&ts).zip(&ys) {
            *ri = (p[0] * t).sin() + p[1] - y;
        }
        Ok(())
    };
    let two_exp = |p: &[f64], r: &mut [f64]| -> Result<(), Never> {
        for (ri, t) in r.iter_mut().zip(&ts) {
            let y = 2.0 * (-1.3 * t).exp() + 0.5 * (-0.2 * t).exp();
            *ri = p[0] * (-p[1] * t).exp() + p[2] * (-p[3] * t).exp() - y;
        }
        Ok(())
    };
    let rosenbrock = |p: &[f64], r: &mut [f64]| -> Result<(), Never> {
        r[0] = 10.0 * (p[1] - p[0] * p[0]);
        r[1] = 1.0 - p[0];
        Ok(())
    };
    let plain = LmOptions {
        ftol: 1e-15,
        xtol: 1e-15,
        gtol: 1e-12,
        ..LmOptions::default()
    };
    let extended = LmOptions {
        extend_steps: true,
        ..plain.clone()
    };
    let compare = |name: &str, a: &htfid_estimate::LmFit, b: &htfid_estimate::LmFit| {
        // Both stop at the tolerances above: the same minimum to 1e-6 of each parameter's
        // size (the stopping rule leaves up to ~1e-8; the rest is margin).
        for (pa, pb) in a.params.iter().zip(&b.params) {
            assert!(
                (pa - pb).abs() <= 1e-6 * pa.abs().max(1.0),
                "{name}: {:?} plain, {:?} extended",
                a.params,
                b.params
            );
        }
        assert!(
            (a.cost - b.cost).abs() <= 1e-9 * a.cost.max(1e-30),
            "{name}: cost {} plain, {} extended",
            a.cost,
            b.cost
        );
    };
    let (a, b) = (
        levenberg_marquardt(sine, &[1.0, 2.0], ts.len(), &plain).unwrap(),
        levenberg_marquardt(sine, &[1.0, 2.0], ts.len(), &extended).unwrap(),
    );
    compare("sine", &a, &b);
    // The sine fit's minimum is not known in closed form: its cost's gradient, by central
    // differences of the residuals here (not the fit's Jacobian), must vanish there, to 1e-6 of
    // the cost per unit of the parameter (the differences' error is about 1e-9).
    let cost = |p: &[f64]| {
        let mut r = vec![0.0; ts.len()];
        sine(p, &mut r).unwrap();
        r.iter().map(|v| v * v).sum::<f64>()
    };
    for j in 0..2 {
        let h = 1e-6 * b.params[j].abs().max(1.0);
        let (mut up, mut down) = (b.params.clone(), b.params.clone());
        up[j] += h;
        down[j] -= h;
        let g = (cost(&up) - cost(&down)) / (2.0 * h);
        assert!(
            g.abs() * b.params[j].abs().max(1.0) <= 1e-6 * b.cost,
            "sine: gradient {g} in parameter {j} at {:?}",
            b.params
        );
    }
    // Measured: 155 plain, 49 extended.
    assert!(
        2 * b.evaluations < a.evaluations,
        "sine: {} evaluations extended, {} plain",
        b.evaluations,
        a.evaluations
    );
    // Their minima are known: the data of the two exponentials are the model at (2, 1.3, 0.5,
    // 0.2) exactly, Rosenbrock's minimum is (1, 1); both with zero cost.
    let problems: [Case<'_>; 3] = [
        (
            "two exponentials",
            &two_exp,
            vec![1.0, 3.0, 1.0, 0.5],
            ts.len(),
            vec![2.0, 1.3, 0.5, 0.2],
        ),
        (
            "Rosenbrock",
            &rosenbrock,
            vec![-1.2, 1.0],
            2,
            vec![1.0, 1.0],
        ),
        (
            "Rosenbrock",
            &rosenbrock,
            vec![3.0, -2.0],
            2,
            vec![1.0, 1.0],
        ),
    ];
    for (name, f, start, m, truth) in problems {
        let a = levenberg_marquardt(f, &start, m, &plain).unwrap();
        let b = levenberg_marquardt(f, &start, m, &extended).unwrap();
        compare(name, &a, &b);
        // 1e-6: the zero-residual minimum to the stopping tolerances and the central
        // differences' error, with margin.
        for (got, want) in b.params.iter().zip(&truth) {
            assert!((got - want).abs() <= 1e-6, "{name}: {:?}", b.params);
        }
        assert!(
            10 * b.evaluations <= 11 * a.evaluations,
            "{name}: {} evaluations extended, {} plain",
            b.evaluations,
            a.evaluations
        );
    }
}

#[test]
fn a_callers_exact_jacobian_reaches_the_known_minimum_in_fewer_evaluations() {
    // Rosenbrock with its analytic Jacobian (column-major): the same minimum (1, 1), one
    // evaluation per Jacobian instead of two per parameter.
    let f = |p: &[f64], r: &mut [f64]| -> Result<(), Never> {
        r[0] = 10.0 * (p[1] - p[0] * p[0]);
        r[1] = 1.0 - p[0];
        Ok(())
    };
    let jac = |p: &[f64], _r: &[f64], j: &mut [f64]| -> Result<(), Never> {
        // Column 0: d r / d x; column 1: d r / d y.
        j.copy_from_slice(&[-20.0 * p[0], -1.0, 10.0, 0.0]);
        Ok(())
    };
    let exact = htfid_estimate::levenberg_marquardt_with_jacobian(
        f,
        jac,
        &[-1.2, 1.0],
        2,
        &LmOptions::default(),
    )
    .unwrap();
    assert!((exact.params[0] - 1.0).abs() < 1e-8 && (exact.params[1] - 1.0).abs() < 1e-8);
    let differences = levenberg_marquardt(f, &[-1.2, 1.0], 2, &LmOptions::default()).unwrap();
    assert!(
        exact.evaluations < differences.evaluations,
        "{} evaluations with the exact Jacobian, {} with differences",
        exact.evaluations,
        differences.evaluations
    );
    // A Jacobian that fails, or that is not finite, stops the fit with its reason.
    let failing = |_: &[f64], _: &[f64], _: &mut [f64]| -> Result<(), String> {
        Err("no sensitivities here".to_string())
    };
    let g = |p: &[f64], r: &mut [f64]| -> Result<(), String> {
        r[0] = p[0] - 1.0;
        r[1] = p[0] + 1.0;
        Ok(())
    };
    let err = htfid_estimate::levenberg_marquardt_with_jacobian(
        g,
        failing,
        &[0.5],
        2,
        &LmOptions::default(),
    )
    .unwrap_err();
    assert!(
        matches!(&err, Error::JacobianFunction { message } if message == "no sensitivities here"),
        "{err:?}"
    );
    let nan = |_: &[f64], _: &[f64], j: &mut [f64]| -> Result<(), String> {
        j.copy_from_slice(&[1.0, f64::NAN]);
        Ok(())
    };
    let err =
        htfid_estimate::levenberg_marquardt_with_jacobian(g, nan, &[0.5], 2, &LmOptions::default())
            .unwrap_err();
    assert!(
        matches!(&err, Error::JacobianFunction { message } if message.contains("(1, 0)")),
        "{err:?}"
    );
}

#[test]
fn an_undetermined_parameter_leaves_the_others_standard_errors() {
    // A line a + b t through noisy points, with a third parameter that changes nothing (as an
    // initial state whose effect has died out before the scored samples): its standard error
    // is NaN, and a and b keep those of the fit without it.
    let t: Vec<f64> = (0..50).map(|i| i as f64 / 49.0).collect();
    let y: Vec<f64> = t
        .iter()
        .enumerate()
        .map(|(i, &t)| 1.0 + 2.0 * t + 0.01 * (((i * 37) % 11) as f64 / 11.0 - 0.5))
        .collect();
    let line = |p: &[f64], r: &mut [f64]| -> Result<(), Never> {
        for i in 0..t.len() {
            r[i] = p[0] + p[1] * t[i] - y[i];
        }
        Ok(())
    };
    let with_idle = |p: &[f64], r: &mut [f64]| -> Result<(), Never> { line(&p[..2], r) };
    let opts = LmOptions::default();
    let two = levenberg_marquardt(line, &[0.0, 0.0], t.len(), &opts).unwrap();
    let three = levenberg_marquardt(with_idle, &[0.0, 0.0, 0.5], t.len(), &opts).unwrap();
    let (s2, s3) = (two.stderr.unwrap(), three.stderr.unwrap());
    assert!(s3[2].is_nan(), "{s3:?}");
    // The residual degrees of freedom differ by one (48 against 47): sqrt(48/47) = 1.0106.
    for j in 0..2 {
        let ratio = s3[j] / s2[j];
        assert!(
            (ratio - (48.0_f64 / 47.0).sqrt()).abs() < 1e-6,
            "{j}: {ratio}"
        );
    }
    // Columns of very different sizes (a slope in units a million times smaller) are still
    // determined: the standard error scales with the unit.
    let scaled = |p: &[f64], r: &mut [f64]| -> Result<(), Never> {
        for i in 0..t.len() {
            r[i] = p[0] + 1e-6 * p[1] * t[i] - y[i];
        }
        Ok(())
    };
    let fit = levenberg_marquardt(scaled, &[0.0, 1e6], t.len(), &opts).unwrap();
    let s = fit.stderr.unwrap();
    assert!(
        (s[1] * 1e-6 / s2[1] - 1.0).abs() < 1e-6,
        "{s:?} against {s2:?}"
    );
}
