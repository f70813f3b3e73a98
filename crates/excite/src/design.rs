//! Multisine experiment design for harmonic transfer function estimation.

use std::collections::HashMap;
use std::f64::consts::TAU;

use serde::{Deserialize, Serialize};

use crate::error::{finite, non_negative, positive, ExciteError};
use crate::multisine::phase_values;
use crate::report::HarmonicCoverage;
use crate::{Amplitude, DesignInput, DesignReport, Line, Multisine, PhaseRule};

/// How even-order nonlinear distortion is kept off the estimation bins.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EvenOrder {
    /// Two blocks, `+u` then `-u`; estimate from `(y(+u) - y(-u)) / 2`, which
    /// cancels every even-order term (and the periodic orbit). Doubles the record.
    SignReversal,
    /// One block; lines restricted so that no second-order product lands on
    /// an estimation bin. About three times the multisine period; fourth and
    /// higher even orders are not protected.
    QuadraticGuard,
    /// One block, no protection; the report lists the exposed lines.
    Unprotected,
}

impl EvenOrder {
    fn blocks(self) -> usize {
        match self {
            Self::SignReversal => 2,
            Self::QuadraticGuard | Self::Unprotected => 1,
        }
    }
}

/// What an HTF experiment must resolve, and within which budget.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DesignSpec {
    /// Forcing (limit-cycle) period T, s; pumping frequency `wp = 2 pi / T`.
    pub period: f64,
    /// H: the harmonics to estimate are `n = -H..=H`.
    pub max_harmonic: u32,
    /// Lower edge of the output band, rad/s (>= 0).
    pub omega_lo: f64,
    /// Upper edge of the output band, rad/s (> `omega_lo`).
    pub omega_hi: f64,
    /// Largest allowed distance between neighbouring estimate frequencies of
    /// one harmonic, rad/s.
    pub spacing: f64,
    /// Input level, peak or RMS of the multisine.
    pub amplitude: Amplitude,
    /// Phase rule of the lines (Schroeder keeps the crest factor low; random
    /// phases carry their seed).
    pub phases: PhaseRule,
    /// Protection against even-order distortion.
    pub even_order: EvenOrder,
    /// Periodic pre-roll before each measured window, s (>= 0); rounded up to
    /// whole forcing periods.
    pub settle: f64,
    /// Absolute start of the record, s; a whole number of forcing periods.
    pub start: f64,
    /// Longest acceptable record (all blocks with their settling), s.
    pub max_record: f64,
}

/// Sign of the multisine in one block.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Polarity {
    /// `+u`.
    Positive,
    /// `-u`.
    Negative,
}

impl Polarity {
    /// `+1.0` or `-1.0`.
    pub fn sign(self) -> f64 {
        match self {
            Self::Positive => 1.0,
            Self::Negative => -1.0,
        }
    }
}

/// One block of the record: settling on `[start, measure_start)`, the
/// measured window (one multisine period) on `[measure_start, end)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Block {
    /// Block index in time order.
    pub index: usize,
    /// Sign of the multisine in this block.
    pub polarity: Polarity,
    /// Absolute start of the settling segment, s.
    pub start: f64,
    /// Absolute start of the measured window, s; a multiple of T.
    pub measure_start: f64,
    /// Absolute end of the measured window, s (`measure_start + Tm`).
    pub end: f64,
}

/// One designed input line.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DesignLine {
    /// DFT bin b of a measured window (frequency `b dw`, `dw = 2 pi / Tm`).
    pub bin: u64,
    /// Angular frequency, rad/s.
    pub omega: f64,
    /// Cosine amplitude.
    pub amplitude: f64,
    /// Cosine phase at the start of each measured window, rad.
    pub phase: f64,
    /// `bin mod P`; the output bins of this line all have residue `r` (direct)
    /// or `P - r` (mirror).
    pub residue: u64,
    /// Whether some second-order product `+-b_i +- b_j` shares this line's
    /// residues (always false for the guarded design; irrelevant with sign
    /// reversal, where even orders cancel).
    pub second_order_exposed: bool,
}

/// Which image of an input line an output bin comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Branch {
    /// From the line at `+b`: output bin `b + nP`, `G_n = Y / U[b]`.
    Direct,
    /// From the image at `-b`: output bin `-b + nP`, `G_n = Y / conj(U[b])`.
    Mirror,
}

/// A frequency at which one harmonic transfer function is observed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HtfPoint {
    /// Harmonic index n.
    pub harmonic: i32,
    /// Output angular frequency `output_bin * dw`, rad/s (may be negative).
    pub omega: f64,
    /// Signed output DFT bin c. For `c < 0` read `Y[c] = conj(Y[-c])`.
    pub output_bin: i64,
    /// Index of the input line into [`Design::lines`].
    pub line: usize,
    /// Direct or mirror image of the line.
    pub branch: Branch,
}

/// What occupies an output bin.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BinOwner {
    /// The response of line `line` through harmonic `harmonic`.
    Line {
        /// Index into [`Design::lines`].
        line: usize,
        /// Harmonic n.
        harmonic: i64,
        /// Direct or mirror image.
        branch: Branch,
    },
    /// A multiple of P: the periodic orbit and DC of even-order products.
    Periodic {
        /// `c / P`.
        harmonic: i64,
    },
    /// A residue no line uses (a place to look for distortion and noise).
    Unused,
}

/// A finished design: multisine, lines, record layout.
///
/// Build it with [`design_htf_multisine`]. The derivation and its guarantees
/// are documented there.
#[derive(Debug, Clone)]
pub struct Design {
    spec: DesignSpec,
    p: u64,
    h: u64,
    top_odd: u64,
    settle: f64,
    multisine: Multisine,
    lines: Vec<DesignLine>,
    blocks: Vec<Block>,
    owner: HashMap<u64, (usize, Branch)>,
}

/// The period, band and spacing of `spec`, checked (with the harmonic count): the
/// part of the spec that both the design and its size estimate need.
fn checked_band(spec: &DesignSpec) -> Result<(f64, f64, f64, f64), ExciteError> {
    let t = positive("period", spec.period)?;
    let lo = non_negative("omega_lo", spec.omega_lo)?;
    let hi = positive("omega_hi", spec.omega_hi)?;
    if hi <= lo {
        return Err(ExciteError::InvalidParameter {
            name: "omega_hi",
            requirement: "> omega_lo",
            value: hi,
        });
    }
    let spacing = positive("spacing", spec.spacing)?;
    // The search visits every harmonic for every line; beyond a few hundred
    // harmonics an HTF model is meaningless anyway.
    if spec.max_harmonic > MAX_HARMONIC {
        return Err(ExciteError::InvalidParameter {
            name: "max_harmonic",
            requirement: "<= 1000",
            value: f64::from(spec.max_harmonic),
        });
    }
    Ok((t, lo, hi, spacing))
}

/// Designs a multisine experiment that observes every harmonic transfer
/// function `G_n`, `|n| <= H`, over `[omega_lo, omega_hi]` at spacing
/// `<= spacing`, without any aliasing between harmonics.
///
/// # Derivation
///
/// HTF convention (the paper's): `Y(jw) = sum_n G_n(jw) U(jw - j n wp)`,
/// `wp = 2 pi / T`; `G_n` maps input at `w - n wp` to output at `w`.
///
/// 1. **Grid.** Take a multisine of period `Tm = P T`, P an integer. A window
///    of length Tm has DFT bins `c dw`, `dw = 2 pi / Tm = wp / P`, so a shift
///    by `n wp` is exactly `n P` bins. In periodic steady state input and
///    output are Tm-periodic and, for a window starting at a multiple of T,
///    `Y[c] = sum_n G_n(j c dw) U[c - n P]` bin by bin.
/// 2. **Unique bins.** A real line at bin `b > 0` also occupies `-b`. Line b
///    through harmonic n lands on `b + nP` (direct) and `-b + nP` (mirror).
///    All direct bins of a line share the residue `r = b mod P`, all mirror
///    bins `P - r`. If the numbers `{r_l} u {P - r_l}` are non-zero and
///    pairwise distinct, the residue of an output bin c names its line and
///    branch, and `n = (c -+ b) / P`: no two (line, harmonic) pairs share a
///    bin, **for every n**, not only `|n| <= H`. Hence
///    `G_n(j (b + nP) dw) = Y[b + nP] / U[b]` and
///    `G_n(j (nP - b) dw) = Y[nP - b] / conj(U[b])`.
///    Residue 0 (bins `nP`) holds the periodic orbit itself and is never used.
/// 3. **Residues from an odd grid.** With P odd and `gcd(h, P) = 1`, take
///    lines `b_j = j h` for odd `j <= J`. Multiplication by `h^-1 mod P` is a
///    bijection that preserves sums, so the residues behave like the odd
///    integers j and their negatives: `j - j'` is even with `0 < |j - j'| < P`,
///    `j + j'` is even (P is odd) and below `2P`, so `J <= P - 2` makes all
///    residues distinct: up to `(P - 1) / 2` lines, every non-zero residue used.
/// 4. **Spacing.** Harmonic n is observed at bins `nP +- j h`, j odd: one
///    uniform grid `nP + (odd) h` of step `2h`, i.e. spacing
///    `D = 2 h wp / P` rad/s for every n, with no wider gap around `n wp`
///    (the grid is offset by half a step). Requirement: `D <= spacing`.
/// 5. **Coverage.** Coverage means every `w` in the band is bracketed by
///    estimate points `p <= w <= q` with `q - p <= spacing`. The grid of
///    harmonic n spans `n wp +- J h dw`, so it brackets the band iff
///    `J h dw >= max(omega_hi - n wp, n wp - omega_lo)`; the worst case is
///    `n = -H`: the input lines must run from `D / 2` up to at least
///    `omega_hi + H wp`. More precisely only the input frequencies
///    `|w - n wp|`, `w` in the band, `|n| <= H`, are needed (plus one grid
///    step around them); lines elsewhere are dropped, which matters for
///    narrow bands.
/// 6. **Choosing P.** For a wide band every line up to `omega_hi + H wp` is
///    kept, and `h <= spacing P / (2 wp)`, `J >= (omega_hi + H wp) P / (h wp)`,
///    `J <= P - 2` give `P >= 2 (omega_hi + H wp) / spacing + 2`. In general
///    odd P are tried upwards from a lower bound set by the number of lines
///    needed (step 5), each with h running down from the largest value the
///    spacing allows (coprime to P), and a grid is accepted only after its
///    kept residues are checked to be non-zero and distinct (step 2; with
///    dropped lines, residues of j beyond `P - 2` may still be distinct).
///    The result is the smallest P this search finds, not a proven optimum
///    over all residue sets: for narrow bands far from DC, sums of kept bins
///    must avoid multiples of P (aliasing through large |n| is excluded
///    too), which can push P well above the line count.
///    The record is `blocks * (settle + P T)`.
/// 7. **Even orders.** Around a stable orbit the response is a Volterra
///    series with T-periodic kernels; the order-k term is homogeneous,
///    `V_k[-u] = (-1)^k V_k[u]`. Second-order products of lines i, j fall on
///    residues `+-r_i +- r_j`, which (all residues being used) are estimation
///    bins. [`EvenOrder::SignReversal`] measures `+u` and `-u` and uses
///    `(y(+u) - y(-u)) / 2`, cancelling every even order and the orbit.
///    [`EvenOrder::QuadraticGuard`] additionally requires, checked on the kept
///    residues, that no `+-r_i +- r_j` equals any `+-r_k`; such grids exist
///    once `3 J < P`, because a collision `+-j_i +- j_k +- j_l = 0 (mod P)`
///    would need an odd integer of size at most `3J < P` to vanish. The guarded
///    residue set is sum-free, so it holds at most P/5 lines (P odd): about
///    three times the unguarded P in practice. [`EvenOrder::Unprotected`] only
///    reports the exposed lines. Odd orders (third, ...) fall on residues
///    `+-r_i +- r_j +- r_k`, which can be estimation bins in any design: they
///    are not separated from `G_n` and bias it in proportion to amplitude^2.
///
/// Windows: the DFT above is of one measured window `[measure_start, end)`
/// of a block; every `measure_start` is a multiple of T, and the multisine is
/// evaluated in window-local time, so `U[b] = N A e^{j phi} / 2` for an
/// N-sample DFT of the window.
///
/// # Errors
///
/// Invalid parameters; a start that is not a multiple of T;
/// [`ExciteError::RecordTooLong`] when the smallest admissible P does not fit
/// `max_record`.
pub fn design_htf_multisine(spec: DesignSpec) -> Result<Design, ExciteError> {
    let (t, lo, hi, spacing) = checked_band(&spec)?;
    let settle_req = non_negative("settle", spec.settle)?;
    let max_record = positive("max_record", spec.max_record)?;
    let start = finite("start", spec.start)?;
    match spec.amplitude {
        Amplitude::Peak(a) => positive("peak amplitude", a)?,
        Amplitude::Rms(a) => positive("rms amplitude", a)?,
    };
    let start_periods = (start / t).round();
    if (start - start_periods * t).abs() > 1e-9 * t.max(start.abs()) {
        return Err(ExciteError::StartOffPeriod { start, period: t });
    }
    let start = start_periods * t;

    let wp = TAU / t;
    let targets = Targets {
        lo: lo / wp,
        hi: hi / wp,
        spacing: spacing / wp,
        max_harmonic: spec.max_harmonic,
        guard: spec.even_order == EvenOrder::QuadraticGuard,
    };
    let settle = (settle_req / t - 1e-9).ceil().max(0.0) * t;
    let n_blocks = spec.even_order.blocks() as f64;
    let too_long = |p: u64| {
        let tm = p as f64 * t;
        let record = n_blocks * (settle + tm);
        (record > max_record).then_some(ExciteError::RecordTooLong {
            needed_p: p,
            multisine_period: tm,
            record,
            max_record,
        })
    };
    // Over budget, a large lower bound is reported as is rather than
    // searched up to the exact P, which could take long for absurd targets.
    let bound = p_lower_bound(&targets);
    if bound > 1 << 20 {
        if let Some(err) = too_long(bound) {
            return Err(err);
        }
    }
    let Grid {
        p,
        h,
        top_odd,
        bins,
    } = find_grid(&targets, bound)?;
    if let Some(err) = too_long(p) {
        return Err(err);
    }
    let tm = p as f64 * t;

    let dw = wp / p as f64;
    let phases = phase_values(spec.phases, &vec![1.0; bins.len()]);
    let unit = Multisine::new(
        tm,
        bins.iter()
            .zip(&phases)
            .map(|(&bin, &phase)| Line {
                bin,
                amplitude: 1.0,
                phase,
            })
            .collect(),
    )?;
    let multisine = unit.scaled_to(spec.amplitude)?;

    let mut owner = HashMap::with_capacity(2 * bins.len());
    for (i, &b) in bins.iter().enumerate() {
        owner.insert(b % p, (i, Branch::Direct));
        owner.insert(p - b % p, (i, Branch::Mirror));
    }
    let exposed = second_order_exposure(&bins, p, &owner);
    let lines = multisine
        .lines()
        .iter()
        .zip(&exposed)
        .map(|(l, &e)| DesignLine {
            bin: l.bin,
            omega: l.bin as f64 * dw,
            amplitude: l.amplitude,
            phase: l.phase,
            residue: l.bin % p,
            second_order_exposed: e,
        })
        .collect();
    let polarities: &[Polarity] = match spec.even_order {
        EvenOrder::SignReversal => &[Polarity::Positive, Polarity::Negative],
        EvenOrder::QuadraticGuard | EvenOrder::Unprotected => &[Polarity::Positive],
    };
    let blocks = polarities
        .iter()
        .enumerate()
        .map(|(k, &polarity)| {
            let s = start + k as f64 * (settle + tm);
            Block {
                index: k,
                polarity,
                start: s,
                measure_start: s + settle,
                end: s + settle + tm,
            }
        })
        .collect();

    let design = Design {
        spec,
        p,
        h,
        top_odd,
        settle,
        multisine,
        lines,
        blocks,
        owner,
    };
    for n in -(spec_h(&design))..=spec_h(&design) {
        let cov = design.coverage(n);
        if cov.max_gap > spacing * (1.0 + 1e-9) {
            return Err(ExciteError::CoverageNotMet {
                harmonic: n,
                max_gap: cov.max_gap,
                target: spacing,
            });
        }
    }
    Ok(design)
}

const MAX_HARMONIC: u32 = 1000;

fn spec_h(d: &Design) -> i32 {
    i32::try_from(d.spec.max_harmonic).unwrap_or(i32::MAX)
}

/// Design targets in units of wp (so one unit is P bins).
#[derive(Debug, Clone, Copy)]
struct Targets {
    lo: f64,
    hi: f64,
    spacing: f64,
    max_harmonic: u32,
    guard: bool,
}

#[derive(Debug, Clone)]
struct Grid {
    p: u64,
    h: u64,
    top_odd: u64,
    bins: Vec<u64>,
}

/// Smallest odd P (with its h, top odd index J and kept bins) for which an
/// odd grid meets spacing and coverage with valid residues.
///
/// P starts at a lower bound from the number of lines any grid of step
/// `<= spacing` needs (half the residues are usable; with the guard at most
/// P/5 lines, the largest sum-free symmetric set in Z_P for odd P). For each
/// P, h runs down from the largest value the spacing allows, skipping h not
/// coprime to P, until the kept lines exceed that capacity.
///
/// The search is bounded twice: P runs at most `max(start, 100000)` past its
/// start, and the candidate bins examined in all (`SEARCH_WORK`) are capped,
/// so fine targets over a wide band end in [`ExciteError::NoDesign`] within
/// seconds instead of searching for hours.
fn find_grid(t: &Targets, bound: u64) -> Result<Grid, ExciteError> {
    const MAX_START: u64 = 1 << 32;
    let start = bound.max(3) | 1;
    if start > MAX_START {
        return Err(ExciteError::NoDesign {
            searched_up_to: start,
        });
    }
    let limit = start + start.max(100_000);
    let mut work: u64 = 0;
    let mut p = start;
    while p <= limit {
        let capacity = if t.guard { p / 5 } else { (p - 1) / 2 };
        let h_max = (t.spacing * p as f64 / 2.0 + 1e-9).floor() as u64;
        for h in (1..=h_max).rev() {
            if gcd(h, p) != 1 {
                continue;
            }
            let reach = (t.hi + f64::from(t.max_harmonic)) * p as f64 / h as f64;
            let mut top_odd = (reach - 1e-9).ceil().max(1.0) as u64;
            if top_odd % 2 == 0 {
                top_odd += 1;
            }
            // Each candidate bin is checked against every harmonic.
            work = work.saturating_add((top_odd / 2 + 1) * (2 * u64::from(t.max_harmonic) + 1));
            if work > SEARCH_WORK {
                return Err(ExciteError::NoDesign { searched_up_to: p });
            }
            // Smaller h needs more lines against the same capacity.
            let Some(bins) = kept_bins(t, p, h, top_odd, capacity) else {
                break;
            };
            if residues_valid(&bins, p, t.guard) {
                return Ok(Grid {
                    p,
                    h,
                    top_odd,
                    bins,
                });
            }
        }
        p += 2;
    }
    Err(ExciteError::NoDesign {
        searched_up_to: limit,
    })
}

/// Candidate bin checks [`find_grid`] may make in all: a fraction of a second
/// of optimised work, far beyond what any design under a realistic record needs.
const SEARCH_WORK: u64 = 100_000_000;

/// What any design for a spec needs at least, known without searching: see
/// [`design_size`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DesignSize {
    /// Lower bound on P, the forcing periods per multisine period.
    pub min_p: u64,
    /// Lower bound on the number of input lines.
    pub min_lines: u64,
    /// Lower bound on the record (all blocks with their settling), s.
    pub min_record: f64,
    /// Lower bound on the highest input line, rad/s: the band's top reached through
    /// harmonic `-H` (less one grid step), and never below the first line at `spacing / 2`.
    /// A record must be sampled faster than twice this.
    pub min_top_line: f64,
    /// Lower bound on the samples [`Multisine::peak`] takes to find the peak (32 per cycle of
    /// the highest line over one multisine period).
    pub min_peak_samples: f64,
}

/// Lower bounds on the size of the design [`design_htf_multisine`] would
/// search for, in O(H log H) time: the line count any grid of step
/// `<= spacing` needs over the band's input images, the P that holds that
/// many distinct residues (step 6 of the derivation), and the record that P
/// implies. A caller can refuse absurd targets (a tiny spacing, a huge band)
/// before the search or the record's simulation start. The actual design is
/// at least this large; `min_record > max_record` means
/// [`design_htf_multisine`] fails with [`ExciteError::RecordTooLong`].
///
/// # Errors
///
/// The invalid parameters that [`design_htf_multisine`] rejects in period,
/// band, spacing, harmonic count and settling.
pub fn design_size(spec: &DesignSpec) -> Result<DesignSize, ExciteError> {
    let (t, lo, hi, spacing) = checked_band(spec)?;
    let settle = (non_negative("settle", spec.settle)? / t - 1e-9)
        .ceil()
        .max(0.0)
        * t;
    let wp = TAU / t;
    let targets = Targets {
        lo: lo / wp,
        hi: hi / wp,
        spacing: spacing / wp,
        max_harmonic: spec.max_harmonic,
        guard: spec.even_order == EvenOrder::QuadraticGuard,
    };
    let min_p = p_lower_bound(&targets);
    let min_top_line = (spacing / 2.0).max(hi + f64::from(spec.max_harmonic) * wp - spacing);
    // The highest line sits at bin `top / dw`, `dw = wp / P`.
    let min_peak_samples = (32.0 * min_top_line / wp * min_p as f64).max(64.0);
    Ok(DesignSize {
        min_p,
        min_lines: min_line_count(&targets),
        min_record: spec.even_order.blocks() as f64 * (settle + min_p as f64 * t),
        min_top_line,
        min_peak_samples,
    })
}

/// Odd lower bound on P from the line count (see [`find_grid`]).
fn p_lower_bound(t: &Targets) -> u64 {
    let min_lines = min_line_count(t);
    let bound = if t.guard {
        min_lines.saturating_mul(5)
    } else {
        min_lines.saturating_mul(2).saturating_add(1)
    };
    bound.max(3) | 1
}

/// Lower bound on the number of lines: for every harmonic the band maps to
/// input frequencies `|w - n wp|`; on the union of those intervals a grid of
/// step `<= spacing` has at least `floor(length / spacing)` lines.
fn min_line_count(t: &Targets) -> u64 {
    let hh = f64::from(t.max_harmonic);
    let mut iv: Vec<(f64, f64)> = (0..=2 * t.max_harmonic)
        .map(|k| {
            let n = f64::from(k) - hh;
            let (a, b) = (t.lo - n, t.hi - n);
            if a <= 0.0 && b >= 0.0 {
                (0.0, b.max(-a))
            } else {
                (a.abs().min(b.abs()), a.abs().max(b.abs()))
            }
        })
        .collect();
    iv.sort_by(|x, y| x.0.total_cmp(&y.0));
    let mut merged: Vec<(f64, f64)> = Vec::new();
    for (a, b) in iv {
        match merged.last_mut() {
            Some(last) if a <= last.1 => last.1 = last.1.max(b),
            _ => merged.push((a, b)),
        }
    }
    merged
        .iter()
        .map(|(a, b)| ((b - a) / t.spacing - 1e-9).floor().max(0.0) as u64)
        .sum()
}

/// Bins `j h`, odd `j <= top_odd`, whose image through some `|n| <= H` lies
/// within one grid step of the band; `None` once more than `capacity` are kept.
fn kept_bins(t: &Targets, p: u64, h: u64, top_odd: u64, capacity: u64) -> Option<Vec<u64>> {
    let pf = p as f64;
    let step = 2.0 * h as f64;
    let (lo, hi) = (t.lo * pf - step, t.hi * pf + step);
    let hmax = i64::from(t.max_harmonic);
    let mut bins = Vec::new();
    for j in (1..=top_odd).step_by(2) {
        let b = (j * h) as f64;
        let needed = (-hmax..=hmax).any(|n| {
            let c = n as f64 * pf;
            (lo..=hi).contains(&(c + b)) || (lo..=hi).contains(&(c - b))
        });
        if needed {
            if bins.len() as u64 == capacity {
                return None;
            }
            bins.push(j * h);
        }
    }
    Some(bins)
}

/// Residues `b mod P` and `P - b mod P` of all bins non-zero and pairwise
/// distinct; with `guard`, additionally no `+-r_i +- r_j` equal to any of them.
fn residues_valid(bins: &[u64], p: u64, guard: bool) -> bool {
    let mut used = std::collections::HashSet::with_capacity(2 * bins.len());
    for &b in bins {
        let r = b % p;
        if r == 0 || !used.insert(r) || !used.insert(p - r) {
            return false;
        }
    }
    if guard {
        // `used` is symmetric under negation, so one sign of each product suffices.
        for (i, &bi) in bins.iter().enumerate() {
            for &bj in &bins[i..] {
                let (ri, rj) = (bi % p, bj % p);
                if used.contains(&((ri + rj) % p)) || used.contains(&((ri + p - rj) % p)) {
                    return false;
                }
            }
        }
    }
    true
}

fn gcd(mut a: u64, mut b: u64) -> u64 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

/// For each line, whether a second-order product `+-b_i +- b_j (mod P)`
/// falls on one of its two residues. The owner table holds both `r` and
/// `P - r` of every line, so checking one sign of each product suffices.
fn second_order_exposure(bins: &[u64], p: u64, owner: &HashMap<u64, (usize, Branch)>) -> Vec<bool> {
    let mut exposed = vec![false; bins.len()];
    for (i, &bi) in bins.iter().enumerate() {
        for &bj in &bins[i..] {
            let (ri, rj) = (bi % p, bj % p);
            for r in [(ri + rj) % p, (ri + p - rj) % p] {
                if let Some(&(k, _)) = owner.get(&r) {
                    exposed[k] = true;
                }
            }
        }
    }
    exposed
}

impl Design {
    /// The specification this design answers.
    pub fn spec(&self) -> &DesignSpec {
        &self.spec
    }

    /// P: forcing periods per multisine period.
    pub fn periods_per_multisine(&self) -> u64 {
        self.p
    }

    /// Multisine period `Tm = P T`, s (the length of one measured window).
    pub fn multisine_period(&self) -> f64 {
        self.p as f64 * self.spec.period
    }

    /// DFT bin width of a measured window, `dw = 2 pi / Tm`, rad/s.
    pub fn bin_width(&self) -> f64 {
        TAU / self.multisine_period()
    }

    /// Distance between neighbouring lines in bins (`2h`); the estimate grid
    /// of every harmonic has this step too.
    pub fn line_step_bins(&self) -> u64 {
        2 * self.h
    }

    /// Spacing of the estimate grid of every harmonic, rad/s.
    pub fn achieved_spacing(&self) -> f64 {
        self.line_step_bins() as f64 * self.bin_width()
    }

    /// Settling before each window, s (the requested value rounded up to whole periods).
    pub fn settle(&self) -> f64 {
        self.settle
    }

    /// The input lines, ascending in frequency.
    pub fn lines(&self) -> &[DesignLine] {
        &self.lines
    }

    /// The multisine in window-local time (positive polarity).
    pub fn multisine(&self) -> &Multisine {
        &self.multisine
    }

    /// The blocks of the record in time order.
    pub fn blocks(&self) -> &[Block] {
        &self.blocks
    }

    /// Record length from the first block's start to the last block's end, s.
    pub fn total_duration(&self) -> f64 {
        self.blocks.len() as f64 * (self.settle + self.multisine_period())
    }

    /// Absolute end of the record, s.
    pub fn record_end(&self) -> f64 {
        self.blocks.last().map_or(self.spec.start, |b| b.end)
    }

    /// The whole input as a signal of absolute time (zero outside the record).
    pub fn input(&self) -> DesignInput {
        DesignInput::new(self.multisine.clone(), self.blocks.clone())
    }

    /// Every observation of `G_n`: two per line (direct and mirror), sorted
    /// by output frequency, including those outside the band and at negative
    /// frequencies (`G_n(-jw) = conj(G_{-n}(jw))` for a real system).
    pub fn htf_points(&self, n: i32) -> Vec<HtfPoint> {
        let np = i64::from(n) * self.p as i64;
        let dw = self.bin_width();
        let mut pts: Vec<HtfPoint> = self
            .lines
            .iter()
            .enumerate()
            .flat_map(|(i, l)| {
                let b = l.bin as i64;
                [(np + b, Branch::Direct), (np - b, Branch::Mirror)].map(|(c, branch)| HtfPoint {
                    harmonic: n,
                    omega: c as f64 * dw,
                    output_bin: c,
                    line: i,
                    branch,
                })
            })
            .collect();
        pts.sort_by_key(|q| q.output_bin);
        pts
    }

    /// What occupies output bin `c` of a measured window's DFT.
    pub fn bin_owner(&self, c: i64) -> BinOwner {
        let p = self.p as i64;
        let r = c.rem_euclid(p) as u64;
        if r == 0 {
            return BinOwner::Periodic { harmonic: c / p };
        }
        match self.owner.get(&r) {
            Some(&(line, branch)) => {
                let b = self.lines[line].bin as i64;
                let base = match branch {
                    Branch::Direct => c - b,
                    Branch::Mirror => c + b,
                };
                BinOwner::Line {
                    line,
                    harmonic: base / p,
                    branch,
                }
            }
            None => BinOwner::Unused,
        }
    }

    fn coverage(&self, n: i32) -> HarmonicCoverage {
        let (lo, hi) = (self.spec.omega_lo, self.spec.omega_hi);
        let tol = 1e-9 * self.bin_width();
        let pts: Vec<f64> = self.htf_points(n).iter().map(|q| q.omega).collect();
        let below = pts.iter().rposition(|&w| w <= lo + tol);
        let above = pts.iter().position(|&w| w >= hi - tol);
        let in_band: Vec<f64> = pts
            .iter()
            .copied()
            .filter(|&w| w >= lo - tol && w <= hi + tol)
            .collect();
        let max_gap = match (below, above) {
            (Some(a), Some(b)) if a < b => pts[a..=b]
                .windows(2)
                .map(|w| w[1] - w[0])
                .fold(0.0, f64::max),
            _ => f64::INFINITY,
        };
        HarmonicCoverage {
            harmonic: n,
            points_in_band: in_band.len(),
            first_omega: in_band.first().copied().unwrap_or(f64::NAN),
            last_omega: in_band.last().copied().unwrap_or(f64::NAN),
            max_gap,
            meets_target: max_gap <= self.spec.spacing * (1.0 + 1e-9),
        }
    }

    /// What the design resolves and what it cannot, as data (serde
    /// `Serialize`) that also prints as a readable summary (`Display`).
    pub fn report(&self) -> DesignReport {
        let h = spec_h(self);
        let harmonics = (-h..=h).map(|n| self.coverage(n)).collect();
        let used_pairs = self.lines.len() as u64;
        let free_residue_pairs = (self.p - 1) / 2 - used_pairs;
        let exposed = self.lines.iter().filter(|l| l.second_order_exposed).count();
        let peak = self.multisine.peak();
        let rms = self.multisine.rms();
        let mut limitations = Vec::new();
        match self.spec.even_order {
            EvenOrder::SignReversal => limitations.push(
                "even-order distortion cancels only in (y(+u) - y(-u))/2, and only if both \
                 blocks reach the same periodic steady state (settling long enough)"
                    .to_string(),
            ),
            EvenOrder::QuadraticGuard => limitations.push(
                "second-order products miss every estimation bin; fourth and higher even \
                 orders are not protected"
                    .to_string(),
            ),
            EvenOrder::Unprotected => limitations.push(format!(
                "{exposed} of {} lines share residues with second-order products: \
                 G_n at their frequencies is biased by even-order distortion",
                self.lines.len()
            )),
        }
        limitations.push(
            "odd-order distortion (third, fifth, ...) lands on estimation bins and is not \
             separated from G_n; its bias grows with amplitude^2"
                .to_string(),
        );
        limitations.push(format!(
            "harmonics |n| > {h} are not estimated; they never alias onto estimated bins \
             (they have their own bins), so their energy can be checked"
        ));
        limitations.push(
            "bins that are multiples of P carry the periodic orbit and DC of even-order \
             products; they are not used"
                .to_string(),
        );
        limitations.push(format!(
            "G_n is observed on a grid of step {:.4} rad/s; values between points need \
             interpolation, and the lowest input line is {:.4} rad/s",
            self.achieved_spacing(),
            self.lines.first().map_or(f64::NAN, |l| l.omega)
        ));
        if !self.lines.is_empty() && self.lines.len() as u64 * 2 < self.top_odd + 1 {
            limitations.push(
                "lines not needed for the band were dropped: the estimate grids have holes \
                 outside the band"
                    .to_string(),
            );
        }
        DesignReport {
            period: self.spec.period,
            omega_p: TAU / self.spec.period,
            periods_per_multisine: self.p,
            multisine_period: self.multisine_period(),
            bin_width: self.bin_width(),
            line_count: self.lines.len(),
            line_step_bins: self.line_step_bins(),
            first_line_bin: self.lines.first().map_or(0, |l| l.bin),
            last_line_bin: self.lines.last().map_or(0, |l| l.bin),
            lowest_line_omega: self.lines.first().map_or(f64::NAN, |l| l.omega),
            highest_line_omega: self.lines.last().map_or(f64::NAN, |l| l.omega),
            achieved_spacing: self.achieved_spacing(),
            target_spacing: self.spec.spacing,
            band: [self.spec.omega_lo, self.spec.omega_hi],
            line_amplitude: self.lines.first().map_or(0.0, |l| l.amplitude),
            rms,
            peak,
            crest_factor: peak / rms,
            harmonics,
            even_order: self.spec.even_order,
            second_order_exposed_lines: exposed,
            free_residue_pairs,
            blocks: self.blocks.clone(),
            settle: self.settle,
            total_duration: self.total_duration(),
            max_record: self.spec.max_record,
            limitations,
        }
    }
}
