use std::sync::Arc;

use serde::{Deserialize, Serialize};

/// How the sampled force is read between samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Interpolation {
    /// Straight lines between samples (continuous, kinks at the samples).
    Linear,
    /// The cubic spline through the samples with not-a-knot ends (twice continuously
    /// differentiable, so a delayed input `f(t - delay)` is smooth in `delay`).
    #[default]
    CubicSpline,
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
            Interpolation::CubicSpline => spline_curvature(values),
        };
        SampledSignal {
            t0,
            inv_dt: 1.0 / dt,
            values: values.to_vec(),
            curvature,
        }
    }

    /// The interval `i` and fraction `a` in `[0, 1)` of time `t`; `None` outside the samples.
    #[inline]
    fn locate(&self, t: f64) -> Option<(usize, f64)> {
        let n = self.values.len();
        let s = (t - self.t0) * self.inv_dt;
        if s.is_nan() || s <= 0.0 || s >= (n - 1) as f64 {
            return None;
        }
        // `s` lies in (0, n - 1), so the cast is in range.
        let i = (s as usize).min(n - 2);
        Some((i, s - i as f64))
    }

    /// The interpolant and its first three derivatives with respect to the fraction `a` on
    /// interval `i` (the k-th times `1/dt^k` is the time derivative).
    #[inline]
    fn piece(&self, i: usize, a: f64) -> [f64; 4] {
        let b = 1.0 - a;
        let (y0, y1) = (self.values[i], self.values[i + 1]);
        let (c0, c1) = if self.curvature.is_empty() {
            (0.0, 0.0)
        } else {
            (self.curvature[i], self.curvature[i + 1])
        };
        [
            b * y0 + a * y1 + (b * b * b - b) * c0 + (a * a * a - a) * c1,
            y1 - y0 + (1.0 - 3.0 * b * b) * c0 + (3.0 * a * a - 1.0) * c1,
            6.0 * (b * c0 + a * c1),
            6.0 * (c1 - c0),
        ]
    }

    /// The interpolant's time derivative at `t` (0 outside the samples, where it is held).
    #[inline]
    pub(crate) fn rate(&self, t: f64) -> f64 {
        match self.locate(t) {
            Some((i, a)) => self.piece(i, a)[1] * self.inv_dt,
            None => 0.0,
        }
    }

    #[inline(always)]
    pub(crate) fn eval(&self, t: f64) -> f64 {
        match self.locate(t) {
            Some((i, a)) => {
                let b = 1.0 - a;
                let lin = b * self.values[i] + a * self.values[i + 1];
                if self.curvature.is_empty() {
                    lin
                } else {
                    lin + (b * b * b - b) * self.curvature[i]
                        + (a * a * a - a) * self.curvature[i + 1]
                }
            }
            None if t > self.t0 => self.values[self.values.len() - 1],
            None => self.values[0],
        }
    }
}

/// The sampled signal passed through the first-order lag `tau F' = f - F`, with `F = f` at the
/// first sample, evaluated exactly for the interpolant (one cubic or linear piece per
/// interval): on a piece `S` the particular solution is `S - tau S' + tau^2 S'' - tau^3 S^(3)`
/// and the homogeneous part decays as `exp(-(t - t_i) / tau)`. Exact and stable for every
/// `tau > 0`, also far below the sample step.
#[derive(Debug, Clone)]
pub(crate) struct LaggedSignal {
    base: Arc<SampledSignal>,
    /// `tau / dt`.
    r: f64,
    /// Homogeneous amplitude `F(t_i) - F_p(t_i)` per interval.
    offset: Vec<f64>,
    /// Its derivative by `r`.
    offset_r: Vec<f64>,
    first: f64,
    last: f64,
    /// The derivative of `last` by `r`.
    last_r: f64,
}

impl LaggedSignal {
    pub(crate) fn new(base: Arc<SampledSignal>, tau: f64) -> Self {
        let n = base.values.len();
        let r = tau * base.inv_dt;
        let decay = (-1.0 / r).exp();
        let particular = |p: [f64; 4]| p[0] - r * p[1] + r * r * p[2] - r * r * r * p[3];
        // The same recursion differentiated by `r`: the particular solution's
        // `-p1 + 2 r p2 - 3 r^2 p3`, the decay's `exp(-1 / r) / r^2`.
        let particular_r = |p: [f64; 4]| -p[1] + 2.0 * r * p[2] - 3.0 * r * r * p[3];
        let decay_r = decay / (r * r);
        let mut offset = Vec::with_capacity(n.saturating_sub(1));
        let mut offset_r = Vec::with_capacity(n.saturating_sub(1));
        let (mut state, mut state_r) = (base.values[0], 0.0);
        for i in 0..n - 1 {
            let (start, end) = (base.piece(i, 0.0), base.piece(i, 1.0));
            let d = state - particular(start);
            let d_r = state_r - particular_r(start);
            offset.push(d);
            offset_r.push(d_r);
            state = particular(end) + d * decay;
            state_r = particular_r(end) + d_r * decay + d * decay_r;
        }
        LaggedSignal {
            first: base.values[0],
            last: state,
            last_r: state_r,
            base,
            r,
            offset,
            offset_r,
        }
    }

    /// The lagged signal's time derivative at `t`: `(f - F) / tau` exactly, `f` the
    /// interpolant it follows (0 outside the samples, where it is held).
    #[inline]
    pub(crate) fn rate(&self, t: f64) -> f64 {
        if self.base.locate(t).is_none() {
            return 0.0;
        }
        (self.base.eval(t) - self.eval(t)) * self.base.inv_dt / self.r
    }

    /// The derivative of the lagged signal at `t` by its time constant `tau` (its
    /// recursion differentiated, exact to rounding).
    #[inline]
    pub(crate) fn tau_derivative(&self, t: f64) -> f64 {
        let dt = 1.0 / self.base.inv_dt;
        match self.base.locate(t) {
            Some((i, a)) => {
                let p = self.base.piece(i, a);
                let r = self.r;
                let e = (-a / r).exp();
                let d_r = -p[1] + 2.0 * r * p[2] - 3.0 * r * r * p[3]
                    + self.offset_r[i] * e
                    + self.offset[i] * e * a / (r * r);
                d_r / dt
            }
            None if t > self.base.t0 => self.last_r / dt,
            None => 0.0,
        }
    }

    #[inline]
    pub(crate) fn eval(&self, t: f64) -> f64 {
        match self.base.locate(t) {
            Some((i, a)) => {
                let p = self.base.piece(i, a);
                let r = self.r;
                p[0] - r * p[1] + r * r * p[2] - r * r * r * p[3] + self.offset[i] * (-a / r).exp()
            }
            None if t > self.base.t0 => self.last,
            None => self.first,
        }
    }
}

/// Second derivatives, times `1/6`, of the not-a-knot cubic spline through `y` on a unit grid
/// (so that the spline reads `b y_i + a y_{i+1} + (b^3 - b) c_i + (a^3 - a) c_{i+1}`).
///
/// Interior rows `c_{i-1} + 4 c_i + c_{i+1} = y_{i+1} - 2 y_i + y_{i-1}`; at each end the third
/// derivative is continuous across the second knot (`c_0 = 2 c_1 - c_2`), which turns the first
/// row into `6 c_1 = y_2 - 2 y_1 + y_0` and likewise the last. Unlike the natural spline
/// (`c_0 = 0`), this does not force zero curvature on a signal that has some at the record's
/// start, which would kick a simulation started there. Fewer than 4 samples: linear.
fn spline_curvature(y: &[f64]) -> Vec<f64> {
    let n = y.len();
    let mut c = vec![0.0; n];
    if n < 4 {
        return c;
    }
    // Unknowns c_1 .. c_{n-2}: m of them, tridiagonal with unit off-diagonals except the first
    // row's upper and the last row's lower entries, which vanish.
    let m = n - 2;
    let mut diag = vec![4.0; m];
    let mut upper = vec![1.0; m];
    let lower_last = 0.0;
    diag[0] = 6.0;
    upper[0] = 0.0;
    diag[m - 1] = 6.0;
    let mut rhs: Vec<f64> = (1..n - 1)
        .map(|i| y[i + 1] - 2.0 * y[i] + y[i - 1])
        .collect();
    for i in 1..m {
        let lower = if i == m - 1 { lower_last } else { 1.0 };
        let w = lower / diag[i - 1];
        diag[i] -= w * upper[i - 1];
        rhs[i] -= w * rhs[i - 1];
    }
    c[m] = rhs[m - 1] / diag[m - 1];
    for i in (0..m - 1).rev() {
        c[i + 1] = (rhs[i] - upper[i] * c[i + 2]) / diag[i];
    }
    c[0] = 2.0 * c[1] - c[2];
    c[n - 1] = 2.0 * c[n - 2] - c[n - 3];
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
        // Ramp f = t from F(0) = 0: F = t - tau (1 - e^{-t/tau}). Both interpolants reproduce a
        // ramp (the natural spline of a line has zero curvature), so only rounding remains.
        let (dt, t0) = (0.01, 0.0);
        let ramp: Vec<f64> = (0..500).map(|k| k as f64 * dt).collect();
        for kind in [Interpolation::Linear, Interpolation::CubicSpline] {
            for tau in [0.002, 0.037, 1.3] {
                let base = Arc::new(SampledSignal::new(t0, dt, &ramp, kind));
                let lag = LaggedSignal::new(base, tau);
                for j in 0..997 {
                    let t = j as f64 * 0.005 + 0.0013;
                    let exact = t - tau * (1.0 - (-t / tau).exp());
                    assert_abs_diff_eq!(lag.eval(t), exact, epsilon = 1e-11);
                }
            }
        }
        // Steady sine sin(w t): F = sin(w t - atan(w tau)) / sqrt(1 + (w tau)^2) after 20 tau.
        // The lag of the spline differs from the lag of the sine by at most the spline's
        // interpolation error (2e-7 at 1 Hz and 100 Hz, see the next test); 5e-7 allows it,
        // for a lag five times shorter than the sample step as well as for a long one.
        let w = 2.0 * std::f64::consts::PI;
        let sine: Vec<f64> = (0..1000).map(|k| (w * k as f64 * dt).sin()).collect();
        let base = Arc::new(SampledSignal::new(
            t0,
            dt,
            &sine,
            Interpolation::CubicSpline,
        ));
        for tau in [0.002, 0.05] {
            let lag = LaggedSignal::new(Arc::clone(&base), tau);
            for j in 0..600 {
                let t = 1.0 + j as f64 * 0.01337;
                let exact = (w * t - (w * tau).atan()).sin() / (1.0 + (w * tau).powi(2)).sqrt();
                assert_abs_diff_eq!(lag.eval(t), exact, epsilon = 5e-7);
            }
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

    #[test]
    fn spline_reproduces_cubics_up_to_the_ends() {
        // Not-a-knot ends reproduce any cubic exactly, including its curvature at the first
        // and last sample (a natural spline would force zero curvature there and miss the
        // value between the first samples by about h^2 |y''| / 8 = 1e-5 here).
        let dt = 0.01;
        let cubic = |t: f64| 0.3 - 2.0 * t + 5.0 * t * t - 7.0 * t * t * t;
        let y: Vec<f64> = (0..50).map(|k| cubic(k as f64 * dt)).collect();
        let s = SampledSignal::new(0.0, dt, &y, Interpolation::CubicSpline);
        for j in 0..490 {
            let t = j as f64 * 0.001 + 0.0003;
            assert_abs_diff_eq!(s.eval(t), cubic(t), epsilon = 1e-12);
        }
    }

    /// The rates and the lag's derivative by its time constant against differences of the
    /// signals themselves (extrapolated central differences, `O(h^4)`): the spline's rate
    /// with `h = 1e-4 dt` in time; the lag's rate the same way; `dF/dtau` with `h = 1e-3
    /// tau` in the time constant, two lags built per difference. The values are of order 1
    /// with rounding near `1e-15`, so the differences carry `~1e-15 / h` (`1e-9` at worst);
    /// checked to `1e-7`. Both lags, shorter and longer than the step; times past the end
    /// (held) included. The rates are checked to `1e-7` of their bound `3 + 0.4 * 17 < 10`.
    #[test]
    fn rates_and_the_lags_derivative_are_the_derivatives_of_the_signals() {
        let dt = 0.01;
        let y: Vec<f64> = (0..400)
            .map(|k| {
                let t = k as f64 * dt;
                (3.0 * t).sin() + 0.4 * (17.0 * t + 0.5).cos()
            })
            .collect();
        let base = Arc::new(SampledSignal::new(0.0, dt, &y, Interpolation::CubicSpline));
        let extrapolated = |f: &dyn Fn(f64) -> f64, h: f64| {
            let wide = (f(h) - f(-h)) / (2.0 * h);
            let narrow = (f(h / 2.0) - f(-h / 2.0)) / h;
            (4.0 * narrow - wide) / 3.0
        };
        let times: Vec<f64> = (0..390).map(|j| 0.0123 + j as f64 * 0.0101).collect();
        for &t in &times {
            let fd = extrapolated(&|h| base.eval(t + h), 1e-4 * dt);
            assert!(
                (base.rate(t) - fd).abs() < 1e-7 * 10.0,
                "spline rate at {t}"
            );
        }
        for tau in [0.003, 0.08] {
            let lag = LaggedSignal::new(Arc::clone(&base), tau);
            for &t in times.iter().chain(&[5.0]) {
                if t < 3.99 {
                    let fd = extrapolated(&|h| lag.eval(t + h), 1e-4 * dt);
                    assert!((lag.rate(t) - fd).abs() < 1e-7 * 10.0, "lag rate at {t}");
                }
                let fd = extrapolated(
                    &|h| LaggedSignal::new(Arc::clone(&base), tau + h).eval(t),
                    1e-3 * tau,
                );
                let exact = lag.tau_derivative(t);
                assert!(
                    (exact - fd).abs() < 1e-7 * (1.0 + fd.abs()),
                    "tau {tau}, t {t}: {exact} against {fd}"
                );
            }
        }
    }
}
