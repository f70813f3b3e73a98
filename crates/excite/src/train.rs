//! Phase-shifted copies of one waveform, and the harmonic aliasing they leave.

use serde::Serialize;

use crate::error::{non_negative, positive, ExciteError};
use crate::{PaperChirp, Signal};

/// Where the copies of a [`PhaseShiftedTrain`] go in time.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TrainLayout {
    /// Duration D of the base waveform, s; the base is evaluated on `[0, D)`
    /// of its own local time.
    pub duration: f64,
    /// Number of copies K (>= 1).
    pub copies: usize,
    /// Forcing period T, s.
    pub period: f64,
    /// Absolute start t0 of copy 0, s. Put it on forcing phase 0 (a multiple
    /// of T) for copy k to start at phase `k T / K`.
    pub start: f64,
    /// Smallest silent gap between the end of one copy and the start of the
    /// next, s (>= 0).
    pub min_gap: f64,
}

impl TrainLayout {
    /// Absolute end of the train this layout describes, s, without building
    /// it: callers size the record (and refuse absurd ones) before any
    /// signal exists. Not meaningful for a layout [`PhaseShiftedTrain::new`]
    /// rejects.
    pub fn end(&self) -> f64 {
        let stride = self.stride_of(self.duration, self.period, self.min_gap);
        self.start + self.copies.saturating_sub(1) as f64 * stride + self.duration
    }

    fn stride_of(&self, d: f64, t: f64, gap: f64) -> f64 {
        let shift = t / self.copies.max(1) as f64;
        // The 1e-9 keeps "D exactly a multiple of T" from rounding up a whole
        // extra period.
        let m = ((d + gap - shift) / t - 1e-9).ceil().max(0.0);
        shift + m * t
    }
}

/// One copy inside a train: absolute start and end, and its forcing phase.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Segment {
    /// Copy index k, `0..K`.
    pub index: usize,
    /// Absolute start time, s.
    pub start: f64,
    /// Absolute end time (`start + D`), s; the copy occupies `[start, end)`.
    pub end: f64,
    /// Forcing phase at which the copy starts, as a time in `[0, T)`:
    /// `start mod T`. Equals `k T / K` when `t0` is a multiple of T.
    pub delay: f64,
}

/// K copies of a finite waveform, copy k delayed by `k T / K` against the
/// forcing.
///
/// Layout (one choice, fixed here): every copy starts a fixed stride S after
/// the previous one, and S is the shortest length of at least `D + min_gap`
/// that is congruent to `T / K` modulo T:
///
/// ```text
///  t0               t0 + S             t0 + 2S
///  |<---- D ---->|g |<---- D ---->|g |<---- D ---->|
///  [   copy 0    ]  [   copy 1    ]  [   copy 2    ]  ...   [ copy K-1 ]
///
///  S = T/K + m T,   m = smallest integer >= 0 with S >= D + min_gap
///  g = S - D        (silence, u = 0)
///  start_k = t0 + k S,   (start_k - t0) mod T = k T / K
///  total duration = (K - 1) S + D
/// ```
///
/// With D a multiple of T and `min_gap = 0` this gives `g = T / K`, i.e.
/// copy k starts at `t0 + k (D + T/K)`. The base is evaluated in its own
/// local time, `u(t) = base(t - start_k)` on `[start_k, start_k + D)`.
pub struct PhaseShiftedTrain {
    base: Box<dyn Signal>,
    layout: TrainLayout,
    stride: f64,
}

impl std::fmt::Debug for PhaseShiftedTrain {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PhaseShiftedTrain")
            .field("layout", &self.layout)
            .field("stride", &self.stride)
            .finish_non_exhaustive()
    }
}

impl PhaseShiftedTrain {
    /// A train of `layout.copies` copies of `base`.
    pub fn new(base: Box<dyn Signal>, layout: TrainLayout) -> Result<Self, ExciteError> {
        let d = positive("duration", layout.duration)?;
        let t = positive("period", layout.period)?;
        crate::error::finite("start", layout.start)?;
        let gap = non_negative("min_gap", layout.min_gap)?;
        if layout.copies == 0 {
            return Err(ExciteError::InvalidParameter {
                name: "copies",
                requirement: ">= 1",
                value: 0.0,
            });
        }
        let stride = layout.stride_of(d, t, gap);
        Ok(Self {
            base,
            layout,
            stride,
        })
    }

    /// The paper's experiment: nine copies of [`PaperChirp`] (30 s each),
    /// T = 1 s, no extra gap, starting at `start`.
    pub fn paper(start: f64) -> Result<Self, ExciteError> {
        Self::new(
            Box::new(PaperChirp),
            TrainLayout {
                duration: PaperChirp::DURATION,
                copies: 9,
                period: 1.0,
                start,
                min_gap: 0.0,
            },
        )
    }

    /// The layout this train was built from.
    pub fn layout(&self) -> &TrainLayout {
        &self.layout
    }

    /// Start-to-start distance S between consecutive copies, s.
    pub fn stride(&self) -> f64 {
        self.stride
    }

    /// Silence between consecutive copies, `S - D`, s.
    pub fn gap(&self) -> f64 {
        self.stride - self.layout.duration
    }

    /// From the start of copy 0 to the end of copy K-1, s.
    pub fn total_duration(&self) -> f64 {
        (self.layout.copies - 1) as f64 * self.stride + self.layout.duration
    }

    /// Absolute end of the train, s.
    pub fn end(&self) -> f64 {
        self.layout.start + self.total_duration()
    }

    /// Every copy's absolute interval and forcing phase, in order.
    pub fn segments(&self) -> Vec<Segment> {
        let TrainLayout {
            duration,
            copies,
            period,
            start,
            ..
        } = self.layout;
        (0..copies)
            .map(|k| {
                let s = start + k as f64 * self.stride;
                let mut delay = (start.rem_euclid(period) + k as f64 * period / copies as f64)
                    .rem_euclid(period);
                // A phase a rounding error below T is phase 0.
                if period - delay < 1e-9 * period {
                    delay = 0.0;
                }
                Segment {
                    index: k,
                    start: s,
                    end: s + duration,
                    delay,
                }
            })
            .collect()
    }

    /// Aliasing left by this train's K copies; see [`alias_map`].
    pub fn alias_map(&self, harmonics: &[i32], n_max: i32) -> Result<Vec<AliasEntry>, ExciteError> {
        alias_map(self.layout.copies, harmonics, n_max)
    }
}

impl Signal for PhaseShiftedTrain {
    fn value(&self, t: f64) -> f64 {
        let tau = t - self.layout.start;
        if tau < 0.0 {
            return 0.0;
        }
        let k = (tau / self.stride).floor();
        if k >= self.layout.copies as f64 {
            return 0.0;
        }
        let local = tau - k * self.stride;
        if local < self.layout.duration {
            self.base.value(local)
        } else {
            0.0
        }
    }
}

/// For one estimated harmonic, the other harmonics that alias onto it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct AliasEntry {
    /// The estimated harmonic n.
    pub harmonic: i32,
    /// Every m != n with |m| <= n_max and m = n (mod K), ascending.
    pub aliases: Vec<i32>,
}

/// Which harmonics K phase-shifted copies cannot separate.
///
/// Copy k is delayed by `s_k = k T / K (mod T)`. Re-aligning the output of
/// copy k to its own start multiplies the contribution of harmonic n by
/// `exp(j n wp s_k) = exp(j 2 pi n k / K)`, which depends on n only through
/// `n mod K`. The K copies therefore give K independent equations per
/// frequency, and harmonics n and n + m K enter them identically: whatever
/// `G_{n + mK}` contributes is attributed to `G_n`.
///
/// Returns, for each harmonic in `harmonics`, the harmonics within
/// `|m| <= n_max` that alias onto it. Fails if two requested harmonics are
/// congruent modulo K (the system of equations is then singular).
pub fn alias_map(
    copies: usize,
    harmonics: &[i32],
    n_max: i32,
) -> Result<Vec<AliasEntry>, ExciteError> {
    if copies == 0 {
        return Err(ExciteError::InvalidParameter {
            name: "copies",
            requirement: ">= 1",
            value: 0.0,
        });
    }
    if n_max < 0 {
        return Err(ExciteError::InvalidParameter {
            name: "n_max",
            requirement: ">= 0",
            value: f64::from(n_max),
        });
    }
    let k = copies as i64;
    for (i, &a) in harmonics.iter().enumerate() {
        for &b in &harmonics[i + 1..] {
            if (i64::from(a) - i64::from(b)).rem_euclid(k) == 0 {
                return Err(ExciteError::HarmonicsAlias {
                    first: a,
                    second: b,
                    copies,
                });
            }
        }
    }
    Ok(harmonics
        .iter()
        .map(|&n| AliasEntry {
            harmonic: n,
            aliases: (-n_max..=n_max)
                .filter(|&m| m != n && (i64::from(m) - i64::from(n)).rem_euclid(k) == 0)
                .collect(),
        })
        .collect())
}

/// How strongly the harmonics that alias onto each estimated one stand against it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AliasSizes {
    /// Copies of the train.
    pub copies: usize,
    /// Largest `|m|` considered.
    pub n_max: i32,
    /// Per estimated harmonic, in the order asked.
    pub by_harmonic: Vec<AliasedHarmonic>,
}

/// One estimated harmonic and the harmonics that alias onto it, with their sizes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AliasedHarmonic {
    /// The estimated harmonic `n`.
    pub harmonic: i32,
    /// Its size (the largest `|G_n|` over the band, for an HTF).
    pub max_abs_g: f64,
    /// Every `m != n`, `|m| <= n_max`, `m = n (mod K)`, ascending.
    pub aliases: Vec<AliasSize>,
}

/// A harmonic that aliases onto an estimated one.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AliasSize {
    /// The harmonic `m`.
    pub harmonic: i32,
    /// Its size.
    pub max_abs_g: f64,
    /// Its size over the estimated harmonic's: the share of the estimate it takes over.
    pub relative_to_estimated: f64,
}

/// [`alias_map`] with sizes: `sizes` gives the size of each harmonic of a list (every
/// estimated harmonic and every alias, ascending, each once), for example the largest `|G_m|`
/// of a model's HTF over the band, so that a reader sees which aliases matter.
///
/// # Errors
/// As [`alias_map`].
pub fn alias_sizes(
    copies: usize,
    harmonics: &[i32],
    n_max: i32,
    sizes: impl FnOnce(&[i32]) -> Vec<f64>,
) -> Result<AliasSizes, ExciteError> {
    let map = alias_map(copies, harmonics, n_max)?;
    let mut all: Vec<i32> = map
        .iter()
        .flat_map(|e| std::iter::once(e.harmonic).chain(e.aliases.iter().copied()))
        .collect();
    all.sort_unstable();
    all.dedup();
    let measured = sizes(&all);
    let size = |n: i32| {
        all.iter()
            .position(|&m| m == n)
            .and_then(|i| measured.get(i).copied())
            .unwrap_or(0.0)
    };
    Ok(AliasSizes {
        copies,
        n_max,
        by_harmonic: map
            .into_iter()
            .map(|entry| {
                let own = size(entry.harmonic);
                AliasedHarmonic {
                    harmonic: entry.harmonic,
                    max_abs_g: own,
                    aliases: entry
                        .aliases
                        .iter()
                        .map(|&m| AliasSize {
                            harmonic: m,
                            max_abs_g: size(m),
                            relative_to_estimated: size(m) / own,
                        })
                        .collect(),
                }
            })
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::LinearChirp;
    use approx::assert_abs_diff_eq;

    /// Nine copies: `G_2` is aliased by `G_-7` and `G_11` (within 12), sized by the closure
    /// (here `1 / (1 + |m|)`), each alias against the estimated harmonic's size.
    #[test]
    fn alias_sizes_name_each_alias_with_its_share() {
        let sized = alias_sizes(9, &[0, 2], 12, |hs| {
            hs.iter()
                .map(|&m| 1.0 / (1.0 + f64::from(m.abs())))
                .collect()
        })
        .unwrap();
        let two = &sized.by_harmonic[1];
        assert_eq!(two.harmonic, 2);
        assert_abs_diff_eq!(two.max_abs_g, 1.0 / 3.0);
        let found: Vec<(i32, f64)> = two
            .aliases
            .iter()
            .map(|a| (a.harmonic, a.relative_to_estimated))
            .collect();
        assert_eq!(found.len(), 2);
        assert_eq!((found[0].0, found[1].0), (-7, 11));
        assert_abs_diff_eq!(found[0].1, 3.0 / 8.0, epsilon = 1e-15);
        assert_abs_diff_eq!(found[1].1, 3.0 / 12.0, epsilon = 1e-15);
        assert_eq!(
            sized.by_harmonic[0]
                .aliases
                .iter()
                .map(|a| a.harmonic)
                .collect::<Vec<_>>(),
            vec![-9, 9]
        );
    }

    #[test]
    fn paper_train_layout() {
        let tr = PhaseShiftedTrain::paper(30.0).unwrap();
        // D = 30 s is a multiple of T = 1 s, so the gap is T/K = 1/9 s.
        assert_abs_diff_eq!(tr.gap(), 1.0 / 9.0, epsilon = 1e-12);
        assert_abs_diff_eq!(tr.stride(), 30.0 + 1.0 / 9.0, epsilon = 1e-12);
        assert_abs_diff_eq!(
            tr.total_duration(),
            8.0 * (30.0 + 1.0 / 9.0) + 30.0,
            epsilon = 1e-9
        );
        let segs = tr.segments();
        assert_eq!(segs.len(), 9);
        for s in &segs {
            let k = s.index as f64;
            // Expected start written from the brief's rule t0 + k (D + T/K).
            assert_abs_diff_eq!(s.start, 30.0 + k * (30.0 + 1.0 / 9.0), epsilon = 1e-9);
            assert_abs_diff_eq!(s.end - s.start, 30.0, epsilon = 1e-9);
            assert_abs_diff_eq!(s.delay, k / 9.0, epsilon = 1e-9);
            // Independent check of the delay from the absolute start.
            assert_abs_diff_eq!((s.start - 30.0).rem_euclid(1.0), k / 9.0, epsilon = 1e-9);
        }
    }

    #[test]
    fn layout_end_matches_the_built_train() {
        let paper = PhaseShiftedTrain::paper(30.0).unwrap();
        assert_abs_diff_eq!(paper.layout().end(), paper.end(), epsilon = 1e-12);
        let layout = TrainLayout {
            duration: 2.3,
            copies: 4,
            period: 0.7,
            start: 1.4,
            min_gap: 0.25,
        };
        let tr = PhaseShiftedTrain::new(
            Box::new(LinearChirp::new(0.5, 3.0, 2.3, 1.0).unwrap()),
            layout,
        )
        .unwrap();
        assert_abs_diff_eq!(layout.end(), tr.end(), epsilon = 1e-12);
        // Written from the layout rule: S = T/K + m T >= D + gap, end = t0 + (K - 1) S + D.
        assert_abs_diff_eq!(
            layout.end(),
            1.4 + 3.0 * (0.175 + 4.0 * 0.7) + 2.3,
            epsilon = 1e-9
        );
    }

    #[test]
    fn train_plays_the_base_in_local_time_and_is_silent_between_copies() {
        let chirp = LinearChirp::new(0.5, 3.0, 2.3, 1.0).unwrap();
        let layout = TrainLayout {
            duration: 2.3,
            copies: 4,
            period: 0.8,
            start: 1.6,
            min_gap: 0.1,
        };
        let tr = PhaseShiftedTrain::new(Box::new(chirp), layout).unwrap();
        // Shortest S >= 2.4 with S = 0.2 (mod 0.8) is 2.6.
        assert_abs_diff_eq!(tr.stride(), 2.6, epsilon = 1e-12);
        let segs = tr.segments();
        for s in &segs {
            assert_abs_diff_eq!(
                (s.start - layout.start).rem_euclid(0.8),
                s.index as f64 * 0.2,
                epsilon = 1e-9
            );
            for j in 0..50 {
                let local = j as f64 * 0.046;
                assert_abs_diff_eq!(
                    tr.value(s.start + local),
                    chirp.value(local),
                    epsilon = 1e-9
                );
            }
        }
        for w in segs.windows(2) {
            assert!(w[1].start - w[0].end >= layout.min_gap - 1e-12);
            for j in 0..20 {
                let t = w[0].end + (w[1].start - w[0].end) * (j as f64 + 0.5) / 20.0;
                assert_abs_diff_eq!(tr.value(t), 0.0);
            }
        }
        assert_abs_diff_eq!(tr.value(layout.start - 1e-6), 0.0);
        assert_abs_diff_eq!(tr.value(tr.end() + 1e-6), 0.0);
        assert_abs_diff_eq!(tr.end(), segs[3].end, epsilon = 1e-12);
    }

    #[test]
    fn train_rejects_zero_copies() {
        let layout = TrainLayout {
            duration: 1.0,
            copies: 0,
            period: 1.0,
            start: 0.0,
            min_gap: 0.0,
        };
        let err = PhaseShiftedTrain::new(Box::new(PaperChirp), layout).unwrap_err();
        assert_eq!(err.to_string(), "copies must be >= 1 (got 0)");
    }

    #[test]
    fn alias_map_lists_congruent_harmonics() {
        let map = alias_map(3, &[-1, 0, 1], 7).unwrap();
        assert_eq!(map[0].aliases, vec![-7, -4, 2, 5]);
        assert_eq!(map[1].aliases, vec![-6, -3, 3, 6]);
        assert_eq!(map[2].aliases, vec![-5, -2, 4, 7]);
        // With the paper's nine copies and |n| <= 3, nothing within |n| <= 5 aliases.
        let tr = PhaseShiftedTrain::paper(0.0).unwrap();
        for e in tr.alias_map(&[-3, -2, -1, 0, 1, 2, 3], 5).unwrap() {
            assert!(e.aliases.is_empty(), "{e:?}");
        }
        assert_eq!(
            alias_map(2, &[-1, 0, 1], 3).unwrap_err(),
            ExciteError::HarmonicsAlias {
                first: -1,
                second: 1,
                copies: 2
            }
        );
    }
}
