//! The measurement chain between the model's position and the recorded output.

use serde::{Deserialize, Serialize};

/// What the position sensor does to the position `x` before it is recorded: a first-order
/// low-pass `tau_s s' = x - s` (absent when `tau_s = 0`), then an offset and a gain,
/// `y = b + g s`. The default is the ideal sensor (`tau_s = 0`, `b = 0`, `g = 1`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Sensor {
    /// Time constant of the sensor's low-pass (s), `>= 0`.
    pub tau_s: f64,
    /// Offset of the reading (output units).
    pub b: f64,
    /// Gain of the reading (output units per m).
    pub g: f64,
}

impl Default for Sensor {
    fn default() -> Self {
        Sensor {
            tau_s: 0.0,
            b: 0.0,
            g: 1.0,
        }
    }
}

impl Sensor {
    /// Whether the reading is the position itself.
    // Exact: the ideal sensor is the default's exact values, and anything else is applied.
    #[allow(clippy::float_cmp)]
    pub fn is_ideal(&self) -> bool {
        self.tau_s == 0.0 && self.b == 0.0 && self.g == 1.0
    }

    /// Turns simulated positions sampled `dt` apart into readings, in place.
    ///
    /// The low-pass is solved exactly for the cubic Hermite interpolant of the samples, whose
    /// slopes come from fourth-order central differences (third-order one-sided ones at the
    /// ends): on a cubic `x`, the particular solution is `x - T x' + T^2 x'' - T^3 x'''`, and
    /// the homogeneous part decays by `exp(-dt / T)` per sample. With `T <= dt` the filter
    /// starts on that particular solution, that is without a transient of its own; a slower
    /// sensor starts at the first position (the series above no longer describes its steady
    /// state), and its transient dies out within a few `T`, which the burn-in of a diagnosis
    /// covers. The error is that of the interpolant, `O(dt^4)` in the position's fourth
    /// derivative.
    // Exact comparisons: the identity map is skipped only when it is exactly the identity.
    #[allow(clippy::float_cmp)]
    pub fn apply(&self, dt: f64, x: &mut [f64]) {
        if self.tau_s > 0.0 && x.len() >= 5 {
            low_pass(self.tau_s, dt, x);
        }
        if self.b != 0.0 || self.g != 1.0 {
            for v in x.iter_mut() {
                *v = self.b + self.g * *v;
            }
        }
    }

    /// The derivative of the readings of positions `x` (sampled `dt` apart) with respect to
    /// the time constant `tau_s`: `g dL/dtau_s (x)`, `L` the low-pass of
    /// [`Sensor::apply`], differentiated step by step (exact to rounding; fits take it
    /// instead of a difference). At `tau_s = 0` it is the derivative from above, `-g x'`,
    /// with the low-pass's own slopes.
    pub fn tau_derivative(&self, dt: f64, x: &[f64]) -> Vec<f64> {
        if x.len() < 5 {
            return vec![0.0; x.len()];
        }
        let mut d = low_pass_tau_derivative(self.tau_s.max(0.0), dt, x);
        for v in &mut d {
            *v *= self.g;
        }
        d
    }
}

/// Slopes of the samples by finite differences of fourth order inside and third order at the
/// two samples of each end.
fn slopes(x: &[f64], dt: f64) -> Vec<f64> {
    let n = x.len();
    let mut v = vec![0.0; n];
    for i in 2..n - 2 {
        v[i] = (x[i - 2] - 8.0 * x[i - 1] + 8.0 * x[i + 1] - x[i + 2]) / (12.0 * dt);
    }
    // Third-order one-sided and off-centre stencils.
    v[0] = (-11.0 * x[0] + 18.0 * x[1] - 9.0 * x[2] + 2.0 * x[3]) / (6.0 * dt);
    v[1] = (-2.0 * x[0] - 3.0 * x[1] + 6.0 * x[2] - x[3]) / (6.0 * dt);
    v[n - 2] = (x[n - 4] - 6.0 * x[n - 3] + 3.0 * x[n - 2] + 2.0 * x[n - 1]) / (6.0 * dt);
    v[n - 1] = (-2.0 * x[n - 4] + 9.0 * x[n - 3] - 18.0 * x[n - 2] + 11.0 * x[n - 1]) / (6.0 * dt);
    v
}

/// The cubic Hermite piece from `(x0, v0)` to `(x1, v1)` over `h`: its second derivative
/// halved at the start and at the end, and its third derivative over six.
#[inline]
fn hermite_terms(x0: f64, x1: f64, v0: f64, v1: f64, h: f64) -> (f64, f64, f64) {
    let d = (x1 - x0) / h;
    (
        (6.0 * d - 4.0 * v0 - 2.0 * v1) / h,
        (-6.0 * d + 2.0 * v0 + 4.0 * v1) / h,
        (-12.0 * d + 6.0 * (v0 + v1)) / (h * h),
    )
}

fn low_pass(tau: f64, h: f64, x: &mut [f64]) {
    let v = slopes(x, h);
    let decay = (-h / tau).exp();
    let (t2, t3) = (tau * tau, tau * tau * tau);
    let mut s = 0.0;
    let mut prev = x[0];
    for i in 0..x.len() - 1 {
        let (x0, x1, v0, v1) = (prev, x[i + 1], v[i], v[i + 1]);
        let (a2_start, a2_end, a3) = hermite_terms(x0, x1, v0, v1, h);
        let p_start = x0 - tau * v0 + t2 * a2_start - t3 * a3;
        let p_end = x1 - tau * v1 + t2 * a2_end - t3 * a3;
        if i == 0 {
            s = if tau <= h { p_start } else { x0 };
            x[0] = s;
        }
        s = p_end + (s - p_start) * decay;
        prev = x1;
        x[i + 1] = s;
    }
}

/// `d/dtau` of [`low_pass`]`(tau, h, x)`, by differentiating its recursion: the particular
/// solutions' ends `p = x - tau v + tau^2 a2 - tau^3 a3` give `-v + 2 tau a2 - 3 tau^2 a3`, the
/// decay `exp(-h / tau)` gives `h / tau^2` times itself (0 at `tau = 0`).
fn low_pass_tau_derivative(tau: f64, h: f64, x: &[f64]) -> Vec<f64> {
    let v = slopes(x, h);
    let (decay, d_decay) = if tau > 0.0 {
        let e = (-h / tau).exp();
        (e, h / (tau * tau) * e)
    } else {
        (0.0, 0.0)
    };
    let (t2, t3) = (tau * tau, tau * tau * tau);
    let mut out = vec![0.0; x.len()];
    let (mut s, mut ds) = (0.0, 0.0);
    for i in 0..x.len() - 1 {
        let (x0, x1, v0, v1) = (x[i], x[i + 1], v[i], v[i + 1]);
        let (a2_start, a2_end, a3) = hermite_terms(x0, x1, v0, v1, h);
        let p_start = x0 - tau * v0 + t2 * a2_start - t3 * a3;
        let p_end = x1 - tau * v1 + t2 * a2_end - t3 * a3;
        let dp_start = -v0 + 2.0 * tau * a2_start - 3.0 * t2 * a3;
        let dp_end = -v1 + 2.0 * tau * a2_end - 3.0 * t2 * a3;
        if i == 0 {
            (s, ds) = if tau <= h {
                (p_start, dp_start)
            } else {
                (x0, 0.0)
            };
            out[0] = ds;
        }
        ds = dp_end + (ds - dp_start) * decay + (s - p_start) * d_decay;
        s = p_end + (s - p_start) * decay;
        out[i + 1] = ds;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On `x = sin(w t)` the low-pass's steady state is known in closed form:
    /// `(sin(w t) - w T cos(w t)) / (1 + (w T)^2)`, compared after 15 time constants (the
    /// start's transient is then below 1e-6 of the amplitude). Tolerance: the
    /// Hermite interpolant's error with slopes of fourth order, `~ (w dt)^4 / 100` relative
    /// (w dt = 0.1 here gives ~1e-6), times 10 for margin.
    #[test]
    fn low_pass_of_a_sine_matches_the_closed_form() {
        for (tau, dt) in [(0.01, 0.01), (0.001, 0.01), (0.5, 0.01), (0.02, 0.001)] {
            let w = 0.1 / dt;
            let mut x: Vec<f64> = (0..2000).map(|i| (w * i as f64 * dt).sin()).collect();
            Sensor {
                tau_s: tau,
                ..Sensor::default()
            }
            .apply(dt, &mut x);
            let wt: f64 = w * tau;
            let worst = x
                .iter()
                .enumerate()
                .skip((15.0 * tau / dt) as usize)
                .map(|(i, y)| {
                    let t = i as f64 * dt;
                    let truth = ((w * t).sin() - wt * (w * t).cos()) / (1.0 + wt * wt);
                    (y - truth).abs()
                })
                .fold(0.0, f64::max);
            assert!(worst < 1e-5, "tau {tau}, dt {dt}: worst error {worst:e}");
        }
    }

    /// The derivative by `tau_s` against differences of the readings themselves, on both
    /// sides of `tau = dt` where the start changes. The readings carry rounding of about
    /// `1e-13` (the recursion's terms reach tens), so the differences take wide steps and
    /// Richardson's extrapolation: central differences at `h = 1e-3 tau` and `h / 2` leave
    /// `O(h^4)` and a rounding of `1e-13 / h` (at most `3e-8`), checked to `1e-6` of the largest
    /// derivative. At `tau = 0`, one-sided differences at `1e-4` and `5e-5` extrapolated leave
    /// `O(h^2)`, about `1e-5` of it here; checked to `1e-4`.
    #[test]
    fn tau_derivative_is_the_derivative_of_the_readings() {
        let dt = 0.01;
        let x: Vec<f64> = (0..400)
            .map(|i| {
                let t = i as f64 * dt;
                (7.0 * t).sin() + 0.3 * (23.0 * t).cos() + 0.1 * t
            })
            .collect();
        let sensor = |tau: f64| Sensor {
            tau_s: tau,
            b: 0.2,
            g: 1.7,
        };
        let read = |tau: f64| {
            let mut y = x.clone();
            sensor(tau).apply(dt, &mut y);
            y
        };
        let largest = |d: &[f64]| d.iter().map(|v| v.abs()).fold(0.0, f64::max);
        for tau in [0.004, 0.02, 0.3] {
            let exact = sensor(tau).tau_derivative(dt, &x);
            let central = |h: f64| -> Vec<f64> {
                let (up, down) = (read(tau + h), read(tau - h));
                up.iter()
                    .zip(&down)
                    .map(|(a, b)| (a - b) / (2.0 * h))
                    .collect()
            };
            let h = 1e-3 * tau;
            let (wide, narrow) = (central(h), central(h / 2.0));
            let scale = largest(&exact);
            for (i, e) in exact.iter().enumerate() {
                let fd = (4.0 * narrow[i] - wide[i]) / 3.0;
                assert!(
                    (e - fd).abs() <= 1e-6 * scale,
                    "tau {tau}, sample {i}: {e} against {fd}"
                );
            }
        }
        let exact = sensor(0.0).tau_derivative(dt, &x);
        let at = read(0.0);
        let forward =
            |h: f64| -> Vec<f64> { read(h).iter().zip(&at).map(|(a, b)| (a - b) / h).collect() };
        let (wide, narrow) = (forward(1e-4), forward(5e-5));
        let scale = largest(&exact);
        for (i, e) in exact.iter().enumerate() {
            let fd = 2.0 * narrow[i] - wide[i];
            assert!(
                (e - fd).abs() <= 1e-4 * scale,
                "tau 0, sample {i}: {e} against {fd}"
            );
        }
    }

    #[test]
    fn offset_and_gain_apply_after_the_filter_and_the_ideal_sensor_changes_nothing() {
        let mut x = vec![1.0, 2.0, 3.0];
        Sensor::default().apply(0.1, &mut x);
        assert_eq!(x, vec![1.0, 2.0, 3.0]);
        Sensor {
            tau_s: 0.0,
            b: 0.5,
            g: 2.0,
        }
        .apply(0.1, &mut x);
        assert_eq!(x, vec![2.5, 4.5, 6.5]);
    }
}
