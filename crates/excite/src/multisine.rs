//! Periodic sums of sinusoids on an integer bin grid.

use std::f64::consts::{PI, TAU};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::error::{finite, positive, ExciteError};
use crate::Signal;

/// One sinusoid of a [`Multisine`]: `amplitude * cos(2 pi bin t / Tm + phase)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Line {
    /// Integer bin b >= 1: frequency `b / Tm` Hz, `2 pi b / Tm` rad/s.
    pub bin: u64,
    /// Amplitude (peak of this one cosine).
    pub amplitude: f64,
    /// Phase, radians.
    pub phase: f64,
}

/// How to size a signal.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Amplitude {
    /// Largest |u(t)| over a period.
    Peak(f64),
    /// Root mean square over a period.
    Rms(f64),
}

/// How to choose line phases.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PhaseRule {
    /// Schroeder's low-crest-factor phases, taken over the lines in bin
    /// order as if they were equally spaced:
    /// `phi_k = -2 pi sum_{l<k} (k - l) p_l`, `p_l` the power share of line l
    /// (for equal amplitudes, `phi_k = -pi k (k - 1) / L`). Exact for equally
    /// spaced grids, including odd grids; still low-crest on irregular ones.
    Schroeder,
    /// Independent phases, uniform on `[-pi, pi)`, from ChaCha8 seeded with
    /// `seed` (reproducible across platforms).
    Random {
        /// RNG seed.
        seed: u64,
    },
    /// All phases zero (worst-case crest factor; for tests and references).
    Zero,
}

/// Which bins a band selection keeps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Parity {
    /// Every bin in the band.
    All,
    /// Odd bins only (even-order distortion then falls on even bins).
    OddOnly,
}

/// Which bins carry lines.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BinSelection {
    /// These bins, in any order (each >= 1, no repeats).
    Explicit(Vec<u64>),
    /// Every bin b >= 1 with `lo_hz <= b / Tm <= hi_hz` (Hz), optionally odd only.
    Band {
        /// Lower edge, Hz.
        lo_hz: f64,
        /// Upper edge, Hz.
        hi_hz: f64,
        /// All bins or odd bins.
        parity: Parity,
    },
}

/// A periodic multisine `u(t) = sum_l A_l cos(2 pi b_l t / Tm + phi_l)`.
///
/// Period `Tm` seconds; bins are integers, so the sampled DFT of exactly one
/// period with N > 2 max(b) points has `X[b_l] = N A_l exp(j phi_l) / 2` and
/// zero elsewhere on `0..N/2`. `t` is absolute time, reduced modulo `Tm`
/// before evaluation so late samples keep their accuracy.
///
/// [`value`](Signal::value) costs one cosine per line;
/// [`fill_uniform`](Signal::fill_uniform) uses per-line recursive
/// oscillators (one complex multiply per line and sample) re-anchored to the
/// exact phase every 256 samples, so rounding cannot accumulate.
#[derive(Debug, Clone, PartialEq)]
pub struct Multisine {
    period: f64,
    lines: Vec<Line>,
    /// `amplitude * (cos phase, sin phase)` per line, for [`Signal::value`].
    phasors: Vec<(f64, f64)>,
}

/// Samples between exact re-anchoring of the recursive oscillators: the
/// rotation error grows by about 2 eps per step, so 256 steps keep it near 1e-13.
const ANCHOR: usize = 256;

impl Multisine {
    /// A multisine from explicit lines; sorted by bin.
    pub fn new(period: f64, mut lines: Vec<Line>) -> Result<Self, ExciteError> {
        let period = positive("period", period)?;
        if lines.is_empty() {
            return Err(ExciteError::NoLines);
        }
        for l in &lines {
            if l.bin == 0 {
                return Err(ExciteError::ZeroBin);
            }
            finite("amplitude", l.amplitude)?;
            finite("phase", l.phase)?;
        }
        lines.sort_by_key(|l| l.bin);
        if let Some(w) = lines.windows(2).find(|w| w[0].bin == w[1].bin) {
            return Err(ExciteError::DuplicateBin { bin: w[0].bin });
        }
        Ok(Self::with_lines(period, lines))
    }

    /// Builds the struct with its phasor cache (lines already validated and sorted).
    fn with_lines(period: f64, lines: Vec<Line>) -> Self {
        let phasors = lines
            .iter()
            .map(|l| {
                let (s, c) = l.phase.sin_cos();
                (l.amplitude * c, l.amplitude * s)
            })
            .collect();
        Self {
            period,
            lines,
            phasors,
        }
    }

    /// Equal-amplitude lines on `bins`, phases by `phases`, scaled to `level`.
    pub fn flat(
        period: f64,
        bins: &BinSelection,
        phases: PhaseRule,
        level: Amplitude,
    ) -> Result<Self, ExciteError> {
        let period = positive("period", period)?;
        let mut bins = match bins {
            BinSelection::Explicit(b) => b.clone(),
            BinSelection::Band {
                lo_hz,
                hi_hz,
                parity,
            } => band_bins(period, *lo_hz, *hi_hz, *parity)?,
        };
        bins.sort_unstable();
        let amplitudes = vec![1.0; bins.len()];
        let phases = phase_values(phases, &amplitudes);
        let lines = bins
            .iter()
            .zip(&phases)
            .map(|(&bin, &phase)| Line {
                bin,
                amplitude: 1.0,
                phase,
            })
            .collect();
        Self::new(period, lines)?.scaled_to(level)
    }

    /// Period Tm, s.
    pub fn period(&self) -> f64 {
        self.period
    }

    /// The lines, ascending in bin.
    pub fn lines(&self) -> &[Line] {
        &self.lines
    }

    /// Angular frequency of bin `bin`, rad/s.
    pub fn bin_omega(&self, bin: u64) -> f64 {
        TAU * bin as f64 / self.period
    }

    /// Root mean square over a period: `sqrt(sum A^2 / 2)` (exact, lines are orthogonal).
    pub fn rms(&self) -> f64 {
        (self
            .lines
            .iter()
            .map(|l| l.amplitude * l.amplitude)
            .sum::<f64>()
            / 2.0)
            .sqrt()
    }

    /// Largest |u(t)| over one period.
    ///
    /// Found on a grid of 32 samples per cycle of the fastest line (worst
    /// relative miss `1 - cos(pi/32)`, 0.5 %), then the best local maxima are
    /// polished by Newton steps on `u'(t) = 0`, which leaves an error near rounding.
    pub fn peak(&self) -> f64 {
        let max_bin = self.lines.last().map_or(1, |l| l.bin);
        let n = (32 * max_bin as usize).max(64);
        let dt = self.period / n as f64;
        let mut samples = vec![0.0; n];
        self.fill_uniform(0.0, dt, &mut samples);
        let mut candidates: Vec<(f64, usize)> = (0..n)
            .filter(|&i| {
                let a = samples[i].abs();
                a >= samples[(i + n - 1) % n].abs() && a >= samples[(i + 1) % n].abs()
            })
            .map(|i| (samples[i].abs(), i))
            .collect();
        candidates.sort_by(|a, b| b.0.total_cmp(&a.0));
        let mut best = candidates.first().map_or(0.0, |c| c.0);
        for &(_, i) in candidates.iter().take(16) {
            let t0 = i as f64 * dt;
            let mut t = t0;
            for _ in 0..12 {
                let (_, d1, d2) = self.derivatives(t);
                if d2 == 0.0 || !d2.is_finite() {
                    break;
                }
                let step = (d1 / d2).clamp(-dt, dt);
                t -= step;
                if (t - t0).abs() > 2.0 * dt || step.abs() < 1e-15 * self.period {
                    break;
                }
            }
            if (t - t0).abs() <= 2.0 * dt {
                best = best.max(self.value(t).abs());
            }
        }
        best
    }

    /// `peak() / rms()`.
    pub fn crest_factor(&self) -> f64 {
        self.peak() / self.rms()
    }

    /// The same lines with every amplitude scaled so that the signal has the
    /// requested peak or RMS.
    pub fn scaled_to(&self, level: Amplitude) -> Result<Self, ExciteError> {
        let (target, current) = match level {
            Amplitude::Peak(p) => (positive("peak amplitude", p)?, self.peak()),
            Amplitude::Rms(r) => (positive("rms amplitude", r)?, self.rms()),
        };
        if current <= 0.0 {
            return Err(ExciteError::InvalidParameter {
                name: "multisine level before scaling",
                requirement: "> 0 (some line needs a non-zero amplitude)",
                value: current,
            });
        }
        let k = target / current;
        let mut lines = self.lines.clone();
        for l in &mut lines {
            l.amplitude *= k;
        }
        Ok(Self::with_lines(self.period, lines))
    }

    /// The sign-reversed signal `-u(t)`: every phase advanced by pi.
    pub fn negated(&self) -> Self {
        let mut lines = self.lines.clone();
        for l in &mut lines {
            l.phase = wrap_phase(l.phase + PI);
        }
        Self::with_lines(self.period, lines)
    }

    /// `(u, u', u'')` at `t`.
    fn derivatives(&self, t: f64) -> (f64, f64, f64) {
        let x = t.rem_euclid(self.period) / self.period;
        let (mut u, mut d1, mut d2) = (0.0, 0.0, 0.0);
        for l in &self.lines {
            let w = TAU * l.bin as f64 / self.period;
            let (s, c) = (TAU * (l.bin as f64 * x).fract() + l.phase).sin_cos();
            u += l.amplitude * c;
            d1 -= l.amplitude * w * s;
            d2 -= l.amplitude * w * w * c;
        }
        (u, d1, d2)
    }
}

impl Signal for Multisine {
    fn value(&self, t: f64) -> f64 {
        // Reduce to one period first, then to a fraction of a cycle per line:
        // the integer bins make the fractional part exact. The lines are sorted
        // by bin, so `exp(j 2 pi b x)` advances from line to line by one complex
        // multiply with `exp(j 2 pi (b' - b) x)`, recomputed only when the gap
        // changes (a designed grid has one gap). The chain is re-anchored to the
        // exact phase every ANCHOR_LINES lines, keeping the rounding near 1e-14.
        const ANCHOR_LINES: usize = 64;
        let x = t.rem_euclid(self.period) / self.period;
        let cis = |bins: u64| {
            let (s, c) = (TAU * (bins as f64 * x).fract()).sin_cos();
            (c, s)
        };
        let mut sum = 0.0;
        let (mut zr, mut zi) = (1.0, 0.0);
        let (mut step_r, mut step_i) = (1.0, 0.0);
        let mut last_gap = 0u64;
        let mut prev_bin = 0u64;
        for (j, l) in self.lines.iter().enumerate() {
            if j % ANCHOR_LINES == 0 {
                (zr, zi) = cis(l.bin);
            } else {
                let gap = l.bin - prev_bin;
                if gap != last_gap {
                    (step_r, step_i) = cis(gap);
                    last_gap = gap;
                }
                (zr, zi) = (zr * step_r - zi * step_i, zr * step_i + zi * step_r);
            }
            prev_bin = l.bin;
            let (pr, pi) = self.phasors[j];
            sum += zr * pr - zi * pi;
        }
        sum
    }

    fn fill_uniform(&self, t0: f64, dt: f64, out: &mut [f64]) {
        if out.is_empty() {
            return;
        }
        // Structure of arrays, padded to a multiple of 4 with silent lines so
        // the inner loop has no remainder and four independent accumulators.
        let n_lines = self.lines.len().div_ceil(4) * 4;
        let mut zr = vec![0.0; n_lines];
        let mut zi = vec![0.0; n_lines];
        let mut cr = vec![1.0; n_lines];
        let mut ci = vec![0.0; n_lines];
        let step = dt / self.period;
        for (j, l) in self.lines.iter().enumerate() {
            let (s, c) = (TAU * (l.bin as f64 * step).fract()).sin_cos();
            cr[j] = c;
            ci[j] = s;
        }
        let mut start = 0;
        while start < out.len() {
            let end = (start + ANCHOR).min(out.len());
            let x = (t0 + start as f64 * dt).rem_euclid(self.period) / self.period;
            for (j, l) in self.lines.iter().enumerate() {
                let (s, c) = (TAU * (l.bin as f64 * x).fract() + l.phase).sin_cos();
                zr[j] = l.amplitude * c;
                zi[j] = l.amplitude * s;
            }
            for o in &mut out[start..end] {
                let mut acc = [0.0; 4];
                for (((zr4, zi4), cr4), ci4) in zr
                    .chunks_exact_mut(4)
                    .zip(zi.chunks_exact_mut(4))
                    .zip(cr.chunks_exact(4))
                    .zip(ci.chunks_exact(4))
                {
                    for q in 0..4 {
                        acc[q] += zr4[q];
                        let r = zr4[q] * cr4[q] - zi4[q] * ci4[q];
                        zi4[q] = zr4[q] * ci4[q] + zi4[q] * cr4[q];
                        zr4[q] = r;
                    }
                }
                *o = (acc[0] + acc[1]) + (acc[2] + acc[3]);
            }
            start = end;
        }
    }
}

fn band_bins(period: f64, lo_hz: f64, hi_hz: f64, parity: Parity) -> Result<Vec<u64>, ExciteError> {
    let lo_hz = crate::error::non_negative("lo_hz", lo_hz)?;
    let hi_hz = positive("hi_hz", hi_hz)?;
    if hi_hz < lo_hz {
        return Err(ExciteError::InvalidParameter {
            name: "hi_hz",
            requirement: ">= lo_hz",
            value: hi_hz,
        });
    }
    // A tolerance of 1e-9 bins keeps band edges that sit exactly on a bin.
    let first = ((lo_hz * period - 1e-9).ceil() as u64).max(1);
    let last = (hi_hz * period + 1e-9).floor() as u64;
    let bins: Vec<u64> = (first..=last)
        .filter(|b| parity == Parity::All || b % 2 == 1)
        .collect();
    if bins.is_empty() {
        return Err(ExciteError::EmptyBand {
            lo_hz,
            hi_hz,
            period,
        });
    }
    Ok(bins)
}

/// Phases for lines in ascending bin order with the given amplitudes.
pub(crate) fn phase_values(rule: PhaseRule, amplitudes: &[f64]) -> Vec<f64> {
    match rule {
        PhaseRule::Zero => vec![0.0; amplitudes.len()],
        PhaseRule::Random { seed } => {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            amplitudes.iter().map(|_| rng.gen_range(-PI..PI)).collect()
        }
        PhaseRule::Schroeder => {
            let total: f64 = amplitudes.iter().map(|a| a * a).sum();
            let share: Vec<f64> = if total > 0.0 {
                amplitudes.iter().map(|a| a * a / total).collect()
            } else {
                vec![1.0 / amplitudes.len().max(1) as f64; amplitudes.len()]
            };
            // phi_k = -2 pi sum_{l<k} (k - l) p_l, built with running sums
            // (sum p_l and sum l p_l) so it is linear in the line count; the
            // phase is wrapped in cycles before scaling to keep it exact.
            let (mut s0, mut s1) = (0.0, 0.0);
            let mut out = Vec::with_capacity(amplitudes.len());
            for (k, p) in share.iter().enumerate() {
                let kf = k as f64;
                let cycles = kf * s0 - s1;
                out.push(wrap_phase(-TAU * cycles.fract()));
                s0 += p;
                s1 += kf * p;
            }
            out
        }
    }
}

/// Phase in `[-pi, pi)`.
pub(crate) fn wrap_phase(p: f64) -> f64 {
    (p + PI).rem_euclid(TAU) - PI
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    #[test]
    fn schroeder_equal_amplitudes_matches_closed_form() {
        let l = 37;
        let got = phase_values(PhaseRule::Schroeder, &vec![1.0; l]);
        for (i, &g) in got.iter().enumerate() {
            // 1-based k: phi_k = -pi k (k - 1) / L.
            let k = (i + 1) as f64;
            let expect = -PI * k * (k - 1.0) / l as f64;
            let d = wrap_phase(g - expect);
            assert_abs_diff_eq!(d, 0.0, epsilon = 1e-9);
        }
    }

    #[test]
    fn fast_sampling_agrees_with_pointwise_value() {
        let m = Multisine::flat(
            7.0,
            &BinSelection::Band {
                lo_hz: 0.1,
                hi_hz: 9.0,
                parity: Parity::All,
            },
            PhaseRule::Random { seed: 3 },
            Amplitude::Rms(1.0),
        )
        .unwrap();
        let (t0, dt) = (123.456, 0.0013);
        let fast = m.sample_uniform(t0, dt, 3000);
        for (i, f) in fast.iter().enumerate() {
            let slow = m.value(t0 + i as f64 * dt);
            // Both are exact up to rounding of ~60 lines of unit-RMS scale;
            // the oscillator drifts at most ~256 * 2 eps between anchors.
            assert_abs_diff_eq!(*f, slow, epsilon = 1e-11);
        }
    }

    #[test]
    fn negated_is_minus_u() {
        let m = Multisine::flat(
            3.0,
            &BinSelection::Explicit(vec![1, 4, 9, 10]),
            PhaseRule::Random { seed: 11 },
            Amplitude::Peak(2.0),
        )
        .unwrap();
        let n = m.negated();
        for i in 0..500 {
            let t = i as f64 * 0.0123;
            // Sum of |A| is below 4 * 2; cos(x + pi) = -cos(x) to a few ulp.
            assert_abs_diff_eq!(n.value(t), -m.value(t), epsilon = 1e-14);
        }
    }

    #[test]
    fn band_selection_respects_edges_and_parity() {
        let bins = band_bins(10.0, 0.3, 1.2, Parity::All).unwrap();
        assert_eq!(bins, (3..=12).collect::<Vec<_>>());
        let odd = band_bins(10.0, 0.3, 1.2, Parity::OddOnly).unwrap();
        assert_eq!(odd, vec![3, 5, 7, 9, 11]);
        assert!(matches!(
            band_bins(10.0, 0.01, 0.05, Parity::All),
            Err(ExciteError::EmptyBand { .. })
        ));
    }

    #[test]
    fn constructor_validates_lines() {
        let line = |bin| Line {
            bin,
            amplitude: 1.0,
            phase: 0.0,
        };
        assert_eq!(Multisine::new(1.0, vec![]), Err(ExciteError::NoLines));
        assert_eq!(
            Multisine::new(1.0, vec![line(0)]),
            Err(ExciteError::ZeroBin)
        );
        assert_eq!(
            Multisine::new(1.0, vec![line(3), line(2), line(3)]),
            Err(ExciteError::DuplicateBin { bin: 3 })
        );
        assert!(Multisine::new(-1.0, vec![line(1)]).is_err());
    }
}
