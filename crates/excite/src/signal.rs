//! The signal capability: a real function of absolute time.

use std::sync::Arc;

/// A real-valued excitation as a function of absolute time `t` (seconds).
///
/// Time zero is forcing phase 0 of the system being excited. Only [`value`]
/// is required; the sampling helpers have defaults that call it point by
/// point, and fast signals (e.g. [`Multisine`](crate::Multisine)) override
/// [`fill_uniform`].
///
/// [`value`]: Signal::value
/// [`fill_uniform`]: Signal::fill_uniform
pub trait Signal: Send + Sync {
    /// The signal at absolute time `t`, seconds.
    fn value(&self, t: f64) -> f64;

    /// The signal at each of `times`.
    fn sample(&self, times: &[f64]) -> Vec<f64> {
        times.iter().map(|&t| self.value(t)).collect()
    }

    /// Writes the signal at `t0 + i * dt` into `out[i]`.
    ///
    /// Times are computed as `t0 + (i as f64) * dt`, never accumulated, so a
    /// long record does not drift.
    fn fill_uniform(&self, t0: f64, dt: f64, out: &mut [f64]) {
        for (i, o) in out.iter_mut().enumerate() {
            *o = self.value(t0 + i as f64 * dt);
        }
    }

    /// `n` samples at `t0 + i * dt`, `i = 0..n`.
    fn sample_uniform(&self, t0: f64, dt: f64, n: usize) -> Vec<f64> {
        let mut out = vec![0.0; n];
        self.fill_uniform(t0, dt, &mut out);
        out
    }
}

// Forward every method, not only `value`, so a boxed multisine keeps its fast path.
macro_rules! forward_signal {
    ($ptr:ty) => {
        impl<S: Signal + ?Sized> Signal for $ptr {
            fn value(&self, t: f64) -> f64 {
                (**self).value(t)
            }
            fn sample(&self, times: &[f64]) -> Vec<f64> {
                (**self).sample(times)
            }
            fn fill_uniform(&self, t0: f64, dt: f64, out: &mut [f64]) {
                (**self).fill_uniform(t0, dt, out)
            }
            fn sample_uniform(&self, t0: f64, dt: f64, n: usize) -> Vec<f64> {
                (**self).sample_uniform(t0, dt, n)
            }
        }
    };
}

forward_signal!(Box<S>);
forward_signal!(Arc<S>);
forward_signal!(&S);
