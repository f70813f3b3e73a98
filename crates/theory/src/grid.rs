//! The HTF trait and its tabulated values.

use std::collections::HashMap;

use num_complex::Complex64;

/// A harmonic transfer function in the estimation convention:
/// `G_n(jw)` maps input at frequency `w - n wp` to output at frequency `w`.
pub trait HarmonicTransferFunction {
    /// Pumping frequency `wp = 2 pi / T` (rad per time unit).
    fn pumping_frequency(&self) -> f64;

    /// `G_n(jw)` at output frequency `w` (rad per time unit).
    fn g(&self, n: i32, w: f64) -> Complex64;

    /// `G_n(j w)` at each `(n, w)` of `points`, in their order: the values of
    /// [`g`](Self::g), with the work shared between points of one harmonic or one frequency
    /// where an implementation can (a fit's residuals, an estimate's errors).
    fn values(&self, points: &[(i32, f64)]) -> Vec<Complex64> {
        points.iter().map(|&(n, w)| self.g(n, w)).collect()
    }

    /// `G_n(j w)` for every `w` in `omegas` and `n` in `harmonics`.
    fn grid(&self, harmonics: &[i32], omegas: &[f64]) -> HtfGrid {
        let mut values = Vec::with_capacity(harmonics.len() * omegas.len());
        for &w in omegas {
            for &n in harmonics {
                values.push(self.g(n, w));
            }
        }
        HtfGrid {
            omegas: omegas.to_vec(),
            harmonics: harmonics.to_vec(),
            values,
        }
    }
}

/// An HTF with its values at some points computed ahead of time (on another core while an
/// experiment runs, say). [`values`](HarmonicTransferFunction::values) and
/// [`g`](HarmonicTransferFunction::g) return those it holds and ask `inner` for the rest, so
/// every value is `inner`'s: bit for bit where `inner` computes a point's value the same in
/// any batch, as [`ExactHtf`](crate::ExactHtf) does.
pub struct Tabulated<'a> {
    inner: &'a (dyn HarmonicTransferFunction + Sync),
    points: Vec<(i32, f64)>,
    values: Vec<Complex64>,
    /// Where each point's value is in `values`.
    index: HashMap<(i32, u64), usize>,
}

impl<'a> Tabulated<'a> {
    /// `inner` with its values at `points` computed now.
    pub fn new(inner: &'a (dyn HarmonicTransferFunction + Sync), points: &[(i32, f64)]) -> Self {
        let index = points
            .iter()
            .enumerate()
            .map(|(i, &(n, w))| ((n, w.to_bits()), i))
            .collect();
        Tabulated {
            inner,
            points: points.to_vec(),
            values: inner.values(points),
            index,
        }
    }

    /// Points held.
    pub fn len(&self) -> usize {
        self.index.len()
    }

    /// Whether it holds no point.
    pub fn is_empty(&self) -> bool {
        self.index.is_empty()
    }

    /// The value held at `(n, w)`, if any.
    fn held(&self, n: i32, w: f64) -> Option<Complex64> {
        self.index.get(&(n, w.to_bits())).map(|&i| self.values[i])
    }
}

impl std::fmt::Debug for Tabulated<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Tabulated")
            .field("points", &self.index.len())
            .finish_non_exhaustive()
    }
}

impl HarmonicTransferFunction for Tabulated<'_> {
    fn pumping_frequency(&self) -> f64 {
        self.inner.pumping_frequency()
    }

    fn g(&self, n: i32, w: f64) -> Complex64 {
        self.held(n, w).unwrap_or_else(|| self.inner.g(n, w))
    }

    fn values(&self, points: &[(i32, f64)]) -> Vec<Complex64> {
        // The points it was made for, in their order: no lookups.
        let same = points.len() == self.points.len()
            && points
                .iter()
                .zip(&self.points)
                .all(|(a, b)| a.0 == b.0 && a.1.to_bits() == b.1.to_bits());
        if same {
            return self.values.clone();
        }
        let held: Vec<Option<Complex64>> = points.iter().map(|&(n, w)| self.held(n, w)).collect();
        let missing: Vec<(i32, f64)> = points
            .iter()
            .zip(&held)
            .filter(|(_, g)| g.is_none())
            .map(|(&p, _)| p)
            .collect();
        let mut computed = self.inner.values(&missing).into_iter();
        held.into_iter()
            .map(|g| {
                g.unwrap_or_else(|| {
                    computed
                        .next()
                        .expect("one computed value per missing point")
                })
            })
            .collect()
    }
}

/// `G_n(jw)` tabulated on frequencies x harmonics, stored row-major by
/// frequency: `values[iw * harmonics.len() + ih] = G_{harmonics[ih]}(j omegas[iw])`.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct HtfGrid {
    /// Output frequencies `w` (rad per time unit).
    pub omegas: Vec<f64>,
    /// Harmonic indices `n`.
    pub harmonics: Vec<i32>,
    /// Row-major `[w][n]` values.
    pub values: Vec<Complex64>,
}

impl HtfGrid {
    /// Bytes of a grid of `omegas` frequencies and `harmonics` harmonics (values and axes), so
    /// a caller can refuse a grid that cannot fit before computing it. Saturates.
    pub fn bytes_for(omegas: usize, harmonics: usize) -> u64 {
        let (w, h) = (omegas as u64, harmonics as u64);
        w.saturating_mul(h)
            .saturating_mul(16)
            .saturating_add(w.saturating_mul(8))
            .saturating_add(h.saturating_mul(4))
    }

    /// `G_{harmonics[ih]}(j omegas[iw])`, or `None` out of range.
    pub fn get(&self, iw: usize, ih: usize) -> Option<Complex64> {
        if iw < self.omegas.len() && ih < self.harmonics.len() {
            self.values.get(iw * self.harmonics.len() + ih).copied()
        } else {
            None
        }
    }

    /// All values of harmonic `n` along the frequency axis, or `None` when
    /// `n` is not in the grid.
    pub fn harmonic(&self, n: i32) -> Option<Vec<Complex64>> {
        let ih = self.harmonics.iter().position(|&h| h == n)?;
        let nh = self.harmonics.len();
        Some(self.values.iter().skip(ih).step_by(nh).copied().collect())
    }

    /// Largest `|G_n|` along the frequency axis (0 when `n` is not in the grid; NaN entries
    /// ignored).
    pub fn peak(&self, n: i32) -> f64 {
        self.harmonic(n)
            .map_or(0.0, |g| g.iter().map(|v| v.norm()).fold(0.0, f64::max))
    }

    /// Largest `|G|` in the grid (0 for an empty grid; NaN entries ignored).
    pub fn max_abs(&self) -> f64 {
        self.values.iter().map(|v| v.norm()).fold(0.0, f64::max)
    }
}
