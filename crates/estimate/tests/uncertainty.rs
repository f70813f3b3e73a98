//! The uncertainty budget of a fit against straight-line regressions whose answers are known in
//! closed form.

use htfid_estimate::{
    contiguous_clusters, uncertainty_budget, BiasSource, ErrorSource, FitBias, FitBudgetInput,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Least-squares straight line `y = a + b x` with unit weights: the parameters, the Jacobian
/// of the residuals `y - a - b x` and the residuals.
fn line_fit(x: &[f64], y: &[f64]) -> ([f64; 2], Vec<Vec<f64>>, Vec<f64>) {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let sxx: f64 = x.iter().map(|v| (v - mx) * (v - mx)).sum();
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let b = sxy / sxx;
    let a = my - b * mx;
    let jac = x.iter().map(|&v| vec![-1.0, -v]).collect();
    let r = x.iter().zip(y).map(|(&v, &w)| w - a - b * v).collect();
    ([a, b], jac, r)
}

fn grid() -> Vec<f64> {
    (0..200).map(|i| f64::from(i) / 20.0).collect()
}

#[test]
fn noise_alone_gives_the_textbook_standard_error_and_covers() {
    // Slope standard error of a straight line: sigma / sqrt(sum (x - mean)^2), a closed form
    // the budget does not use. With noise alone the total must cover the truth at 95 %: over
    // 1000 seeded fits the count of misses is binomial (mean 50, sd 6.9); the structure term
    // only widens the interval, so the bound is one-sided: at most 50 + 3 sd = 71 misses.
    // Noise-only intervals are checked to miss about 5 % too (between 29 and 71), so a budget
    // that simply inflated everything would not pass unnoticed either.
    let x = grid();
    let sigma = 0.3;
    let (a0, b0) = (1.0, -0.5);
    let n = x.len() as f64;
    let mx = x.iter().sum::<f64>() / n;
    let sxx: f64 = x.iter().map(|v| (v - mx) * (v - mx)).sum();
    let textbook = sigma / sxx.sqrt();
    let clusters = contiguous_clusters(&vec![0; x.len()], 10);
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let normal = Normal::new(0.0, sigma).unwrap();
    let (mut misses, mut noise_misses) = (0, 0);
    for _ in 0..1000 {
        let y: Vec<f64> = x
            .iter()
            .map(|&v| a0 + b0 * v + normal.sample(&mut rng))
            .collect();
        let (p, jac, r) = line_fit(&x, &y);
        let b = uncertainty_budget(&FitBudgetInput {
            jacobian: &jac,
            residuals: &r,
            noise_variance: sigma * sigma,
            clusters: &clusters,
            bias: None,
            level: 0.95,
        })
        .unwrap();
        let slope = &b.parameters[1];
        assert!((slope.noise - textbook).abs() <= 1e-12 * textbook);
        assert!(slope.coverage_factor >= 1.959_964 - 1e-5);
        misses += usize::from((p[1] - b0).abs() > slope.half_width);
        noise_misses += usize::from((p[1] - b0).abs() > 1.959_964 * slope.noise);
    }
    assert!(misses <= 71, "{misses} of 1000 missed");
    assert!((29..=71).contains(&noise_misses), "{noise_misses}");
}

#[test]
fn errors_shared_within_clusters_are_structure_and_are_covered() {
    // A model that lacks an effect: every run of 10 neighbouring points shares an offset
    // (sd 0.3, as large as the noise), so residuals correlate within runs and the noise-only
    // standard error is too small. The truth (a, b) is set here, not by the budget. The total
    // must cover it at 95 %: over 400 fits the misses are binomial (mean 20, sd 4.4), at most
    // 20 + 3 sd = 34 (measured 24; with 10 clusters of 20 points it was 41, the sandwich of
    // few clusters being itself uncertain). The noise-only interval must miss far more often
    // (measured 216; at least 100), or this test could not fail.
    let x = grid();
    let sigma = 0.3;
    let (a0, b0) = (1.0, -0.5);
    let clusters = contiguous_clusters(&vec![0; x.len()], 10);
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let normal = Normal::new(0.0, 1.0).unwrap();
    let (mut misses, mut noise_misses) = (0, 0);
    let mut dominated = 0;
    for _ in 0..400 {
        let offsets: Vec<f64> = (0..20).map(|_| 0.3 * normal.sample(&mut rng)).collect();
        let y: Vec<f64> = x
            .iter()
            .zip(&clusters)
            .map(|(&v, &c)| a0 + b0 * v + offsets[c] + sigma * normal.sample(&mut rng))
            .collect();
        let (p, jac, r) = line_fit(&x, &y);
        let b = uncertainty_budget(&FitBudgetInput {
            jacobian: &jac,
            residuals: &r,
            noise_variance: sigma * sigma,
            clusters: &clusters,
            bias: None,
            level: 0.95,
        })
        .unwrap();
        let slope = &b.parameters[1];
        misses += usize::from((p[1] - b0).abs() > slope.half_width);
        noise_misses += usize::from((p[1] - b0).abs() > 1.959_964 * slope.noise);
        dominated += usize::from(slope.dominant == ErrorSource::Structure);
    }
    assert!(misses <= 34, "{misses} of 400 missed");
    assert!(
        noise_misses >= 100,
        "{noise_misses} of 400 missed by noise alone"
    );
    assert!(dominated >= 300, "structure dominated {dominated} of 400");
}

#[test]
fn a_known_bias_is_propagated_and_removed_from_the_residuals() {
    // Data biased by d * x: the least-squares slope is off by exactly d (a closed form), which
    // the first-order propagation must reproduce; with the bias taken out of the residuals
    // nothing is left for the structure term, and chi-square per degree of freedom returns to
    // 1 (noise variance 1e-4, 200 points: its sd is 0.1, bound 0.7..1.3).
    let x = grid();
    let d = 0.02;
    let sigma = 0.01;
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    let normal = Normal::new(0.0, sigma).unwrap();
    let y: Vec<f64> = x
        .iter()
        .map(|&v| 1.0 - 0.5 * v + d * v + normal.sample(&mut rng))
        .collect();
    let (p, jac, r) = line_fit(&x, &y);
    let bias: Vec<f64> = x.iter().map(|&v| d * v).collect();
    let clusters = contiguous_clusters(&vec![0; x.len()], 10);
    let b = uncertainty_budget(&FitBudgetInput {
        jacobian: &jac,
        residuals: &r,
        noise_variance: sigma * sigma,
        clusters: &clusters,
        bias: Some(FitBias {
            source: BiasSource::Smoothing,
            residual_bias: &bias,
            parameter_bias: None,
        }),
        level: 0.95,
    })
    .unwrap();
    let slope = &b.parameters[1];
    assert!(
        (slope.htf_bias_estimate - d).abs() < 1e-12,
        "{}",
        slope.htf_bias_estimate
    );
    assert!(b.parameters[0].htf_bias_estimate.abs() < 1e-12);
    assert_eq!(slope.dominant, ErrorSource::HtfBias(BiasSource::Smoothing));
    assert!((p[1] - (-0.5)).abs() <= slope.half_width);
    assert!(
        (0.7..=1.3).contains(&b.chi2_per_dof_corrected),
        "{}",
        b.chi2_per_dof_corrected
    );
    // Without the correction the bias (which the slope absorbs) leaves nothing in the
    // residuals either: a straight-line bias is invisible to the residuals of a straight line.
    assert!((0.7..=1.3).contains(&b.chi2_per_dof), "{}", b.chi2_per_dof);
}

#[test]
fn inconsistent_inputs_are_rejected() {
    let jac = vec![vec![1.0], vec![2.0]];
    let base = FitBudgetInput {
        jacobian: &jac,
        residuals: &[0.1, 0.2],
        noise_variance: 1.0,
        clusters: &[0, 1],
        bias: None,
        level: 0.95,
    };
    assert!(uncertainty_budget(&base).is_ok());
    for bad in [
        FitBudgetInput {
            level: 1.0,
            ..base.clone()
        },
        FitBudgetInput {
            clusters: &[0],
            ..base.clone()
        },
        FitBudgetInput {
            noise_variance: 0.0,
            ..base.clone()
        },
    ] {
        assert!(uncertainty_budget(&bad).is_err());
    }
    let singular = vec![vec![0.0], vec![0.0]];
    let e = uncertainty_budget(&FitBudgetInput {
        jacobian: &singular,
        ..base
    })
    .unwrap_err();
    assert_eq!(
        e.to_string(),
        "the fit's Jacobian is rank deficient (1 parameters): no covariance exists"
    );
}
