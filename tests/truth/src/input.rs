//! The commanded force `f(t) = A cos(2 pi t / T) + u(t)` and its true counterpart.
//!
//! The excitation is piecewise smooth: it may jump where one chirp ends and the next starts.
//! Time is cut into segments at those breakpoints, and every evaluation names its segment, so a
//! step that ends exactly on a breakpoint still sees the left-hand formula (the integrator's
//! last stages must not see the next chirp).

use std::f64::consts::PI;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::scenario::Excitation;

/// Amplitude of each paper chirp, N.
pub const CHIRP_AMPLITUDE: f64 = 0.004;
/// Length of each chirp, s.
pub const CHIRP_LENGTH: f64 = 30.0;
/// Final instantaneous frequency of each chirp, Hz.
pub const CHIRP_END_HZ: f64 = 14.0;
/// Number of distinct chirp phases: chirp `i` has phase `2 pi (i mod 9) / 9`.
pub const CHIRP_PHASES: usize = 9;
/// Multisine line spacing, Hz; lines sit at odd multiples of half of it.
pub const MULTISINE_SPACING_HZ: f64 = 0.1;
/// Multisine band, Hz.
pub const MULTISINE_BAND_HZ: (f64, f64) = (0.2, 7.0);

/// The excitation signal `u`, as segments between breakpoints.
#[derive(Clone, Debug)]
enum Shape {
    None,
    Chirps {
        start: f64,
    },
    /// Lines at odd multiples `n w0` of `w0 = 2 pi 0.05 Hz`, from `first_odd` on, stored as
    /// `(a cos p, a sin p)` so that a line is `a sin(n w0 tau + p)`.
    Multisine {
        start: f64,
        first_odd: u32,
        lines: Vec<(f64, f64)>,
    },
}

/// The command side: nominal forcing plus excitation, and the true (possibly modulated)
/// forcing that the actuator receives.
#[derive(Clone, Debug)]
pub(crate) struct Drive {
    amplitude: f64,
    period: f64,
    /// Unmeasured amplitude modulation `(depth, period)` of the true forcing.
    slow: Option<(f64, f64)>,
    shape: Shape,
    /// Excitation breakpoints in command time, sorted.
    breaks: Vec<f64>,
}

impl Drive {
    pub(crate) fn new(
        excitation: &Excitation,
        amplitude: f64,
        period: f64,
        slow: Option<(f64, f64)>,
        start: f64,
        length: f64,
    ) -> Drive {
        let end = start + length;
        let (shape, breaks) = match *excitation {
            Excitation::ForcingOnly => (Shape::None, Vec::new()),
            Excitation::PaperChirps => {
                let mut b = Vec::new();
                let mut i = 0.0;
                while start + i * CHIRP_LENGTH < end {
                    b.push(start + i * CHIRP_LENGTH);
                    i += 1.0;
                }
                b.push(end);
                (Shape::Chirps { start }, b)
            }
            Excitation::Multisine { phase_seed } => {
                let mut rng = ChaCha8Rng::seed_from_u64(phase_seed);
                let freqs = multisine_frequencies();
                let a = multisine_line_amplitude();
                let lines = freqs
                    .iter()
                    .map(|_| {
                        let p = rng.gen::<f64>() * 2.0 * PI;
                        (a * p.cos(), a * p.sin())
                    })
                    .collect();
                let first_odd = (freqs[0] / (MULTISINE_SPACING_HZ / 2.0)).round() as u32;
                (
                    Shape::Multisine {
                        start,
                        first_odd,
                        lines,
                    },
                    vec![start, end],
                )
            }
        };
        Drive {
            amplitude,
            period,
            slow,
            shape,
            breaks,
        }
    }

    /// Breakpoints of the excitation, command time, s.
    pub(crate) fn breaks(&self) -> &[f64] {
        &self.breaks
    }

    /// The segment containing command time `t` (half-open on the right of each breakpoint).
    pub(crate) fn segment(&self, t: f64) -> usize {
        self.breaks.partition_point(|&b| b <= t)
    }

    /// Excitation and its time derivative at command time `t`, using segment `seg`'s formula.
    fn excitation(&self, t: f64, seg: usize) -> (f64, f64) {
        // Segment 0 is before the first breakpoint, the last segment after the end.
        if seg == 0 || seg >= self.breaks.len() {
            return (0.0, 0.0);
        }
        match &self.shape {
            Shape::None => (0.0, 0.0),
            Shape::Chirps { start } => {
                let i = seg - 1;
                let t0 = start + i as f64 * CHIRP_LENGTH;
                let tau = t - t0;
                let phi = 2.0 * PI * (i % CHIRP_PHASES) as f64 / CHIRP_PHASES as f64;
                let rate = PI * CHIRP_END_HZ / CHIRP_LENGTH;
                let arg = rate * tau * tau + phi;
                (
                    CHIRP_AMPLITUDE * arg.sin(),
                    CHIRP_AMPLITUDE * arg.cos() * 2.0 * rate * tau,
                )
            }
            Shape::Multisine {
                start,
                first_odd,
                lines,
            } => {
                // e^{i n w0 tau} by complex rotation: one sin_cos per call instead of 68.
                // The rounding grows like n * eps, far below the 1e-15 N that matters.
                let w0 = PI * MULTISINE_SPACING_HZ;
                let tau = t - start;
                let (s2, c2) = (2.0 * w0 * tau).sin_cos();
                let (mut s, mut c) = (f64::from(*first_odd) * w0 * tau).sin_cos();
                let mut n = f64::from(*first_odd);
                let (mut u, mut du) = (0.0, 0.0);
                for &(ac, as_) in lines {
                    // a sin(x + p) = a cos p sin x + a sin p cos x.
                    u += ac * s + as_ * c;
                    du += n * w0 * (ac * c - as_ * s);
                    (s, c) = (s * c2 + c * s2, c * c2 - s * s2);
                    n += 2.0;
                }
                (u, du)
            }
        }
    }

    /// The commanded force as recorded: nominal forcing plus excitation.
    pub(crate) fn commanded(&self, t: f64) -> f64 {
        let w = 2.0 * PI / self.period;
        self.amplitude * (w * t).cos() + self.excitation(t, self.segment(t)).0
    }

    /// The force command the actuator really receives, and its time derivative, at command
    /// time `t` in segment `seg`: as [`Drive::commanded`] but with the unmeasured amplitude
    /// modulation.
    pub(crate) fn true_command(&self, t: f64, seg: usize) -> (f64, f64) {
        let w = 2.0 * PI / self.period;
        let (amp, damp) = match self.slow {
            None => (self.amplitude, 0.0),
            Some((depth, p)) => {
                let ws = 2.0 * PI / p;
                (
                    self.amplitude * (1.0 + depth * (ws * t).sin()),
                    self.amplitude * depth * ws * (ws * t).cos(),
                )
            }
        };
        let (s, c) = (w * t).sin_cos();
        let (u, du) = self.excitation(t, seg);
        (amp * c + u, damp * c - amp * w * s + du)
    }
}

/// The multisine's line frequencies, Hz: odd multiples of 0.05 Hz inside the band.
pub(crate) fn multisine_frequencies() -> Vec<f64> {
    let half = MULTISINE_SPACING_HZ / 2.0;
    (0..)
        .map(|k| (2 * k + 1) as f64 * half)
        .skip_while(|&f| f < MULTISINE_BAND_HZ.0)
        .take_while(|&f| f <= MULTISINE_BAND_HZ.1)
        .collect()
}

/// Amplitude of each multisine line: the total RMS equals the chirp's, `0.004 / sqrt 2`.
pub(crate) fn multisine_line_amplitude() -> f64 {
    let n = multisine_frequencies().len() as f64;
    CHIRP_AMPLITUDE / n.sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn multisine_has_68_lines_with_chirp_rms() {
        let f = multisine_frequencies();
        assert_eq!(f.len(), 68);
        assert!((f[0] - 0.25).abs() < 1e-12 && (f[67] - 6.95).abs() < 1e-12);
        let d = Drive::new(
            &Excitation::Multisine { phase_seed: 3 },
            0.0,
            1.0,
            None,
            0.0,
            20.0,
        );
        // The lines are periodic with 20 s, so a 20 s mean is exact.
        let n = 200_000;
        let ms: f64 = (0..n)
            .map(|i| d.commanded(i as f64 * 20.0 / n as f64).powi(2))
            .sum::<f64>()
            / n as f64;
        assert!((ms.sqrt() - CHIRP_AMPLITUDE / 2f64.sqrt()).abs() < 1e-9);
    }

    /// The rotation recurrence against one `sin_cos` per line.
    #[test]
    fn multisine_recurrence_matches_direct_sum() {
        let d = Drive::new(
            &Excitation::Multisine { phase_seed: 9 },
            0.0,
            1.0,
            None,
            30.0,
            270.0,
        );
        let Shape::Multisine {
            start,
            first_odd,
            lines,
        } = &d.shape
        else {
            panic!("not a multisine")
        };
        for &t in &[30.0, 31.234, 123.456, 299.999] {
            let tau = t - start;
            let direct: f64 = lines
                .iter()
                .enumerate()
                .map(|(i, &(ac, as_))| {
                    let x = f64::from(first_odd + 2 * i as u32) * PI * MULTISINE_SPACING_HZ * tau;
                    ac * x.sin() + as_ * x.cos()
                })
                .sum();
            // Both round the phase of the highest line (~2000 rad) at ~1e-13 rad.
            let diff = (direct - d.commanded(t)).abs();
            assert!(diff < 1e-14, "{t}: {diff:e}");
        }
    }

    #[test]
    fn derivatives_match_finite_differences() {
        for exc in [
            Excitation::PaperChirps,
            Excitation::Multisine { phase_seed: 1 },
        ] {
            let d = Drive::new(&exc, 1.0, 1.0, Some((0.1, 100.0)), 30.0, 270.0);
            for &t in &[31.3, 77.7, 250.05] {
                let seg = d.segment(t);
                let h = 1e-6;
                let fd = (d.true_command(t + h, seg).0 - d.true_command(t - h, seg).0) / (2.0 * h);
                assert!((fd - d.true_command(t, seg).1).abs() < 1e-6);
            }
        }
    }

    #[test]
    fn chirp_segments_use_their_own_phase() {
        let d = Drive::new(&Excitation::PaperChirps, 0.0, 1.0, None, 30.0, 270.0);
        assert_eq!(d.breaks().len(), 10);
        // Left limit at the end of chirp 0 is sin(14 pi 30) = 0; chirp 1 starts at sin(2 pi/9).
        let end0 = d.excitation(60.0, 1).0;
        let start1 = d.commanded(60.0);
        assert!(end0.abs() < 1e-12);
        assert!((start1 - CHIRP_AMPLITUDE * (2.0 * PI / 9.0).sin()).abs() < 1e-15);
        assert!(d.commanded(300.0).abs() < 1e-15 && d.commanded(29.99).abs() < 1e-15);
    }
}
