use serde::{Deserialize, Serialize};

/// How the sampled force is read between samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Interpolation {
    /// Straight lines between samples (continuous, kinks at the samples).
    Linear,
    /// The natural cubic spline through the samples (twice continuously differentiable, so a
    /// delayed input `f(t - delay)` is smooth in `delay`).
    #[default]
    CubicSpline,
}

/// `tau F' = f - F` applied to the samples `f` (step `dt`), `F_0 = f_0`: the exact solution for
/// an input linear between samples (first-order hold), stable for every `tau > 0`.
pub(crate) fn first_order_lag(f: &[f64], dt: f64, tau: f64) -> Vec<f64> {
    let mut out = Vec::with_capacity(f.len());
    let Some(&first) = f.first() else {
        return out;
    };
    if !(tau > 0.0) {
        return f.to_vec();
    }
    let a = (-dt / tau).exp();
    let mut state = first;
    out.push(state);
    for w in f.windows(2) {
        let slope_tau = (w[1] - w[0]) * tau / dt;
        // Particular solution of a ramp input is the ramp delayed by tau; the homogeneous part
        // decays by `a` over the step.
        state = w[1] - slope_tau + (state - w[0] + slope_tau) * a;
        out.push(state);
    }
    out
}

/// A uniformly sampled signal read at any time. Before the first sample it holds the first
/// value, after the last the last value.
#[derive(Debug, Clone)]
pub(crate) struct SampledSignal {
    t0: f64,
    inv_dt: f64,
    values: Vec<f64>,
    /// Spline second derivatives times `dt^2 / 6`; empty for linear interpolation.
    curvature: Vec<f64>,
}

impl SampledSignal {
    pub(crate) fn new(t0: f64, dt: f64, values: &[f64], kind: Interpolation) -> Self {
        let curvature = match kind {
            Interpolation::Linear => Vec::new(),
            Interpolation::CubicSpline => natural_spline_curvature(values),
        };
        SampledSignal {
            t0,
            inv_dt: 1.0 / dt,
            values: values.to_vec(),
            curvature,
        }
    }

    #[inline]
    pub(crate) fn eval(&self, t: f64) -> f64 {
        let n = self.values.len();
        let s = (t - self.t0) * self.inv_dt;
        if !(s > 0.0) {
            return self.values[0];
        }
        let last = (n - 1) as f64;
        if s >= last {
            return self.values[n - 1];
        }
        // `s` lies in (0, n - 1), so the cast is in range.
        let i = (s as usize).min(n - 2);
        let a = s - i as f64;
        let b = 1.0 - a;
        let lin = b * self.values[i] + a * self.values[i + 1];
        if self.curvature.is_empty() {
            lin
        } else {
            lin + (b * b * b - b) * self.curvature[i] + (a * a * a - a) * self.curvature[i + 1]
        }
    }
}

/// Second derivatives of the natural cubic spline through `y` on a unit grid, times `1/6`
/// (so that the spline reads `b y_i + a y_{i+1} + (b^3 - b) c_i + (a^3 - a) c_{i+1}`).
/// Thomas algorithm on `c_{i-1} + 4 c_i + c_{i+1} = y_{i+1} - 2 y_i + y_{i-1}`, `c_0 = c_{n-1} = 0`.
fn natural_spline_curvature(y: &[f64]) -> Vec<f64> {
    let n = y.len();
    let mut c = vec![0.0; n];
    if n < 3 {
        return c;
    }
    let m = n - 2;
    let mut diag = vec![4.0; m];
    let mut rhs: Vec<f64> = (1..n - 1)
        .map(|i| y[i + 1] - 2.0 * y[i] + y[i - 1])
        .collect();
    for i in 1..m {
        let w = 1.0 / diag[i - 1];
        diag[i] -= w;
        rhs[i] -= w * rhs[i - 1];
    }
    c[m] = rhs[m - 1] / diag[m - 1];
    for i in (0..m - 1).rev() {
        c[i + 1] = (rhs[i] - c[i + 2]) / diag[i];
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    #[test]
    fn linear_interpolation_is_exact_for_lines_and_holds_the_ends() {
        let y: Vec<f64> = (0..10).map(|k| 2.0 + 0.5 * k as f64).collect();
        let s = SampledSignal::new(1.0, 0.1, &y, Interpolation::Linear);
        // A line is reproduced to rounding.
        assert_abs_diff_eq!(s.eval(1.234), 2.0 + 0.5 * 2.34, epsilon = 1e-12);
        assert_abs_diff_eq!(s.eval(0.5), 2.0, epsilon = 0.0);
        assert_abs_diff_eq!(s.eval(5.0), 6.5, epsilon = 0.0);
    }

    #[test]
    fn lag_matches_the_closed_form_response_to_a_ramp_and_a_sine() {
        // Ramp f = t from F_0 = 0: F = t - tau (1 - e^{-t/tau}); exact for a ramp, so only
        // rounding remains (1e-12).
        let (dt, tau) = (0.01, 0.037);
        let ramp: Vec<f64> = (0..500).map(|k| k as f64 * dt).collect();
        let lagged = first_order_lag(&ramp, dt, tau);
        for (k, &v) in lagged.iter().enumerate() {
            let t = k as f64 * dt;
            assert_abs_diff_eq!(v, t - tau * (1.0 - (-t / tau).exp()), epsilon = 1e-12);
        }
        // Steady sine sin(w t): F = sin(w t - atan(w tau)) / sqrt(1 + (w tau)^2) after the
        // transient (20 tau). First-order hold of a sine errs by about (w dt)^2 / 12 times
        // w tau relative: 3e-4 * 0.23 = 8e-5 for w = 2 pi; 2e-4 allows it.
        let w = 2.0 * std::f64::consts::PI;
        let sine: Vec<f64> = (0..500).map(|k| (w * k as f64 * dt).sin()).collect();
        let lagged = first_order_lag(&sine, dt, tau);
        for (k, &v) in lagged.iter().enumerate().skip(100) {
            let t = k as f64 * dt;
            let exact = (w * t - (w * tau).atan()).sin() / (1.0 + (w * tau).powi(2)).sqrt();
            assert_abs_diff_eq!(v, exact, epsilon = 2e-4);
        }
    }

    #[test]
    fn spline_matches_a_smooth_signal_to_fourth_order() {
        // sin(2 pi 1 Hz t) at 100 Hz: the interior error of a cubic spline is about
        // (5/384) h^4 max|y''''| = 0.013 * 1e-8 * (2 pi)^4 = 2e-7; 1e-6 leaves margin, and
        // linear interpolation (error h^2/8 max|y''| = 5e-4) would fail it.
        let dt = 0.01;
        let y: Vec<f64> = (0..300)
            .map(|k| (2.0 * std::f64::consts::PI * k as f64 * dt).sin())
            .collect();
        let s = SampledSignal::new(0.0, dt, &y, Interpolation::CubicSpline);
        for j in 0..1000 {
            let t = 0.5 + j as f64 * 0.00197;
            let exact = (2.0 * std::f64::consts::PI * t).sin();
            assert_abs_diff_eq!(s.eval(t), exact, epsilon = 1e-6);
        }
        // It interpolates: samples are reproduced.
        assert_abs_diff_eq!(s.eval(1.0), y[100], epsilon = 1e-12);
    }
}
