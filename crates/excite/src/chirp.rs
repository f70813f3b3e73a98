//! Swept sines: linear, exponential, and the paper's printed chirp.

use std::f64::consts::{PI, TAU};

use crate::error::{finite, non_negative, positive, ExciteError};
use crate::Signal;

/// Linear sweep from `f_start_hz` to `f_end_hz` over `duration` seconds.
///
/// ```text
/// u(t) = a sin(2 pi (f0 t + (f1 - f0) t^2 / (2 D)))   for 0 <= t < D,
/// u(t) = 0                                           otherwise,
/// ```
///
/// with instantaneous frequency `f0 + (f1 - f0) t / D` Hz. Down-sweeps
/// (`f1 < f0`) are allowed. `t` is absolute time: to start the sweep later,
/// place it in a [`PhaseShiftedTrain`](crate::PhaseShiftedTrain).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearChirp {
    f_start_hz: f64,
    f_end_hz: f64,
    duration: f64,
    amplitude: f64,
}

impl LinearChirp {
    /// A linear sweep; frequencies in Hz (>= 0), duration in s (> 0),
    /// amplitude finite (a negative amplitude is a sign-reversed sweep).
    pub fn new(
        f_start_hz: f64,
        f_end_hz: f64,
        duration: f64,
        amplitude: f64,
    ) -> Result<Self, ExciteError> {
        Ok(Self {
            f_start_hz: non_negative("f_start_hz", f_start_hz)?,
            f_end_hz: non_negative("f_end_hz", f_end_hz)?,
            duration: positive("duration", duration)?,
            amplitude: finite("amplitude", amplitude)?,
        })
    }

    /// Start frequency, Hz.
    pub fn f_start_hz(&self) -> f64 {
        self.f_start_hz
    }

    /// End frequency (reached at `t = D`), Hz.
    pub fn f_end_hz(&self) -> f64 {
        self.f_end_hz
    }

    /// Sweep duration D, s.
    pub fn duration(&self) -> f64 {
        self.duration
    }

    /// Peak amplitude a.
    pub fn amplitude(&self) -> f64 {
        self.amplitude
    }

    /// Phase of the sine, radians: `2 pi f0 t + pi (f1 - f0) t^2 / D`.
    ///
    /// Defined for every `t`; the signal itself is gated to `[0, D)`.
    pub fn phase(&self, t: f64) -> f64 {
        // Written so that f0 = 0 reproduces the paper's `14 pi t^2 / 30`
        // operation for operation (see `PaperChirp`).
        TAU * self.f_start_hz * t + (self.f_end_hz - self.f_start_hz) * PI * t * t / self.duration
    }

    /// Instantaneous frequency, Hz: `f0 + (f1 - f0) t / D`.
    pub fn instantaneous_frequency_hz(&self, t: f64) -> f64 {
        self.f_start_hz + (self.f_end_hz - self.f_start_hz) * t / self.duration
    }
}

impl Signal for LinearChirp {
    fn value(&self, t: f64) -> f64 {
        if (0.0..self.duration).contains(&t) {
            self.amplitude * self.phase(t).sin()
        } else {
            0.0
        }
    }
}

/// Exponential (logarithmic) sweep from `f_start_hz` to `f_end_hz`, both > 0.
///
/// ```text
/// k = ln(f1 / f0)
/// u(t) = a sin(2 pi f0 D / k (exp(k t / D) - 1))   for 0 <= t < D, else 0,
/// ```
///
/// with instantaneous frequency `f0 (f1 / f0)^(t / D)` Hz, so every octave
/// gets the same time. When `f1 = f0` the phase tends to `2 pi f0 t`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LogChirp {
    f_start_hz: f64,
    f_end_hz: f64,
    duration: f64,
    amplitude: f64,
    rate: f64,
}

impl LogChirp {
    /// An exponential sweep; frequencies in Hz (> 0), duration in s (> 0).
    pub fn new(
        f_start_hz: f64,
        f_end_hz: f64,
        duration: f64,
        amplitude: f64,
    ) -> Result<Self, ExciteError> {
        let f_start_hz = positive("f_start_hz", f_start_hz)?;
        let f_end_hz = positive("f_end_hz", f_end_hz)?;
        Ok(Self {
            f_start_hz,
            f_end_hz,
            duration: positive("duration", duration)?,
            amplitude: finite("amplitude", amplitude)?,
            rate: (f_end_hz / f_start_hz).ln(),
        })
    }

    /// Start frequency, Hz.
    pub fn f_start_hz(&self) -> f64 {
        self.f_start_hz
    }

    /// End frequency, Hz.
    pub fn f_end_hz(&self) -> f64 {
        self.f_end_hz
    }

    /// Sweep duration D, s.
    pub fn duration(&self) -> f64 {
        self.duration
    }

    /// Peak amplitude a.
    pub fn amplitude(&self) -> f64 {
        self.amplitude
    }

    /// Phase of the sine, radians; defined for every `t`.
    pub fn phase(&self, t: f64) -> f64 {
        let k = self.rate;
        // expm1 keeps full precision for small k t / D, and the k -> 0 limit
        // is the constant-frequency phase.
        if k.abs() < 1e-12 {
            TAU * self.f_start_hz * t
        } else {
            TAU * self.f_start_hz * self.duration / k * (k * t / self.duration).exp_m1()
        }
    }

    /// Instantaneous frequency, Hz: `f0 (f1 / f0)^(t / D)`.
    pub fn instantaneous_frequency_hz(&self, t: f64) -> f64 {
        self.f_start_hz * (self.rate * t / self.duration).exp()
    }
}

impl Signal for LogChirp {
    fn value(&self, t: f64) -> f64 {
        if (0.0..self.duration).contains(&t) {
            self.amplitude * self.phase(t).sin()
        } else {
            0.0
        }
    }
}

/// The chirp exactly as printed in the reference paper:
/// `u(t) = 0.004 sin(14 pi t^2 / 30)` for `0 <= t < 30`, zero elsewhere.
///
/// Its instantaneous frequency is `14 t / 30` Hz, rising from 0 to **14 Hz**,
/// although the paper's text says the sweep covers (0, 7] Hz. The printed
/// formula is kept verbatim; it equals
/// `LinearChirp::new(0.0, 14.0, 30.0, 0.004)` (see [`PaperChirp::as_linear`]).
/// A sweep matching the text would be `LinearChirp::new(0.0, 7.0, 30.0, 0.004)`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PaperChirp;

impl PaperChirp {
    /// Amplitude printed in the paper.
    pub const AMPLITUDE: f64 = 0.004;
    /// Duration printed in the paper, s.
    pub const DURATION: f64 = 30.0;
    /// Frequency reached at `t = 30 s` by the printed formula, Hz.
    pub const F_END_HZ: f64 = 14.0;

    /// The same signal as a [`LinearChirp`] from 0 Hz to 14 Hz over 30 s.
    pub fn as_linear(&self) -> LinearChirp {
        LinearChirp {
            f_start_hz: 0.0,
            f_end_hz: Self::F_END_HZ,
            duration: Self::DURATION,
            amplitude: Self::AMPLITUDE,
        }
    }

    /// Sweep duration, s.
    pub fn duration(&self) -> f64 {
        Self::DURATION
    }
}

impl Signal for PaperChirp {
    fn value(&self, t: f64) -> f64 {
        if (0.0..Self::DURATION).contains(&t) {
            0.004 * htfid_trig::sin(14.0 * PI * t * t / 30.0)
        } else {
            0.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    #[test]
    fn paper_chirp_equals_linear_chirp_0_to_14_hz() {
        let linear = LinearChirp::new(0.0, 14.0, 30.0, 0.004).unwrap();
        // Step not commensurate with the duration so samples land everywhere in [0, 30).
        for i in 0..30_011 {
            let t = -0.5 + i as f64 * 1.0e-3;
            // The brief's tolerance; amplitude 0.004 times a few ulp of the
            // largest phase (1319 rad) would be ~1e-15, and both forms
            // evaluate the same operations, so the difference is far below.
            assert_abs_diff_eq!(PaperChirp.value(t), linear.value(t), epsilon = 1e-15);
        }
        assert_eq!(PaperChirp.as_linear(), linear);
    }

    #[test]
    fn paper_chirp_reaches_14_hz_not_7() {
        let c = PaperChirp.as_linear();
        assert_abs_diff_eq!(c.instantaneous_frequency_hz(30.0), 14.0, epsilon = 1e-12);
        assert_abs_diff_eq!(c.instantaneous_frequency_hz(15.0), 7.0, epsilon = 1e-12);
    }

    #[test]
    fn linear_instantaneous_frequency_matches_phase_derivative() {
        let c = LinearChirp::new(0.3, 9.0, 20.0, 1.5).unwrap();
        let h = 1e-4;
        for i in 0..200 {
            let t = 0.05 + i as f64 * 0.0995;
            let fd = (c.phase(t + h) - c.phase(t - h)) / (2.0 * h) / TAU;
            let exact = 0.3 + (9.0 - 0.3) * t / 20.0;
            // Central difference is exact for a quadratic phase; what remains
            // is rounding, |phase| eps / h ~ 600 * 2.2e-16 / 1e-4 ~ 1.3e-9.
            assert_abs_diff_eq!(fd, exact, epsilon = 1e-8);
            assert_abs_diff_eq!(c.instantaneous_frequency_hz(t), exact, epsilon = 1e-12);
        }
    }

    #[test]
    fn linear_chirp_zero_crossings_give_the_frequency() {
        // Independent of `phase()`: consecutive zero crossings of the sampled
        // signal are half a cycle apart; for a quadratic phase the mean
        // frequency over the interval equals the frequency at its midpoint.
        let c = LinearChirp::new(1.0, 6.0, 10.0, 2.0).unwrap();
        let crossings = zero_crossings(&c, 0.01, 9.99, 1e-4);
        assert!(crossings.len() > 50);
        for w in crossings.windows(2) {
            let mid = 0.5 * (w[0] + w[1]);
            let f_est = 0.5 / (w[1] - w[0]);
            let exact = 1.0 + 5.0 * mid / 10.0;
            // Crossings located to 1e-13 s by bisection; intervals >= 0.08 s,
            // so the relative error of 1/(2 dt) is below 1e-11.
            assert_abs_diff_eq!(f_est, exact, epsilon = 1e-9);
        }
    }

    #[test]
    fn log_chirp_instantaneous_frequency_matches_phase_derivative() {
        let c = LogChirp::new(0.1, 10.0, 30.0, 1.0).unwrap();
        let h = 1e-4;
        for i in 0..300 {
            let t = 0.01 + i as f64 * 0.0999;
            let fd = (c.phase(t + h) - c.phase(t - h)) / (2.0 * h) / TAU;
            let exact = 0.1 * 100.0_f64.powf(t / 30.0);
            // Truncation h^2 phi'''/6 <= 1e-8 * 0.24 / 6 rad/s, rounding
            // |phase| eps / h <= 400 * 2.2e-16 / 1e-4 ~ 1e-9.
            assert_abs_diff_eq!(fd, exact, epsilon = 1e-8);
        }
    }

    #[test]
    fn log_chirp_with_equal_ends_is_a_sine() {
        let c = LogChirp::new(2.0, 2.0, 5.0, 1.0).unwrap();
        for i in 0..100 {
            let t = i as f64 * 0.049;
            assert_abs_diff_eq!(c.value(t), (TAU * 2.0 * t).sin(), epsilon = 1e-12);
        }
    }

    #[test]
    fn chirps_vanish_outside_their_duration() {
        let c = LinearChirp::new(1.0, 2.0, 3.0, 1.0).unwrap();
        for t in [-1.0, -1e-12, 3.0, 3.5, 100.0] {
            assert_abs_diff_eq!(c.value(t), 0.0);
        }
        let l = LogChirp::new(1.0, 2.0, 3.0, 1.0).unwrap();
        for t in [-1.0, 3.0, 7.0] {
            assert_abs_diff_eq!(l.value(t), 0.0);
        }
    }

    #[test]
    fn constructors_reject_bad_parameters() {
        assert!(matches!(
            LinearChirp::new(-1.0, 2.0, 3.0, 1.0),
            Err(ExciteError::InvalidParameter {
                name: "f_start_hz",
                ..
            })
        ));
        assert!(matches!(
            LinearChirp::new(1.0, 2.0, 0.0, 1.0),
            Err(ExciteError::InvalidParameter {
                name: "duration",
                ..
            })
        ));
        assert!(matches!(
            LinearChirp::new(1.0, f64::NAN, 1.0, 1.0),
            Err(ExciteError::InvalidParameter {
                name: "f_end_hz",
                ..
            })
        ));
        assert!(matches!(
            LogChirp::new(0.0, 2.0, 3.0, 1.0),
            Err(ExciteError::InvalidParameter {
                name: "f_start_hz",
                ..
            })
        ));
        let msg = LinearChirp::new(1.0, 2.0, -3.0, 1.0)
            .unwrap_err()
            .to_string();
        assert_eq!(msg, "duration must be finite and > 0 (got -3)");
    }

    fn zero_crossings(s: &dyn Signal, t0: f64, t1: f64, step: f64) -> Vec<f64> {
        let mut out = Vec::new();
        let n = ((t1 - t0) / step) as usize;
        let mut a = t0;
        let mut ua = s.value(a);
        for i in 1..=n {
            let b = t0 + i as f64 * step;
            let ub = s.value(b);
            if ua * ub < 0.0 {
                let (mut lo, mut hi, mut ulo) = (a, b, ua);
                while hi - lo > 1e-13 {
                    let m = 0.5 * (lo + hi);
                    let um = s.value(m);
                    if um * ulo < 0.0 {
                        hi = m;
                    } else {
                        lo = m;
                        ulo = um;
                    }
                }
                out.push(0.5 * (lo + hi));
            }
            a = b;
            ua = ub;
        }
        out
    }
}
