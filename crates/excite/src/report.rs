//! The design report: what a design resolves and what it does not.

use std::fmt;

use serde::Serialize;

use crate::{Block, EvenOrder};

/// How well one harmonic is observed over the band.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct HarmonicCoverage {
    /// Harmonic n.
    pub harmonic: i32,
    /// Estimate points inside `[omega_lo, omega_hi]`.
    pub points_in_band: usize,
    /// Lowest in-band estimate frequency, rad/s.
    pub first_omega: f64,
    /// Highest in-band estimate frequency, rad/s.
    pub last_omega: f64,
    /// Largest gap between consecutive points bracketing the band, rad/s
    /// (infinite if the band is not bracketed).
    pub max_gap: f64,
    /// `max_gap <= spacing`.
    pub meets_target: bool,
}

/// Machine-readable summary of a [`Design`](crate::Design); `Display` prints it for people.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DesignReport {
    /// Forcing period T, s.
    pub period: f64,
    /// Pumping frequency `2 pi / T`, rad/s.
    pub omega_p: f64,
    /// P.
    pub periods_per_multisine: u64,
    /// Tm = P T, s.
    pub multisine_period: f64,
    /// dw = 2 pi / Tm, rad/s.
    pub bin_width: f64,
    /// Number of input lines.
    pub line_count: usize,
    /// Line step in bins (2h).
    pub line_step_bins: u64,
    /// Lowest line bin.
    pub first_line_bin: u64,
    /// Highest line bin.
    pub last_line_bin: u64,
    /// Lowest line frequency, rad/s.
    pub lowest_line_omega: f64,
    /// Highest line frequency, rad/s.
    pub highest_line_omega: f64,
    /// Estimate-grid spacing of every harmonic, rad/s.
    pub achieved_spacing: f64,
    /// Requested spacing, rad/s.
    pub target_spacing: f64,
    /// Output band `[omega_lo, omega_hi]`, rad/s.
    pub band: [f64; 2],
    /// Amplitude of each line.
    pub line_amplitude: f64,
    /// RMS of the multisine.
    pub rms: f64,
    /// Peak of the multisine.
    pub peak: f64,
    /// Peak / RMS.
    pub crest_factor: f64,
    /// Coverage of each estimated harmonic.
    pub harmonics: Vec<HarmonicCoverage>,
    /// Even-order handling.
    pub even_order: EvenOrder,
    /// Lines whose bins receive second-order products.
    pub second_order_exposed_lines: usize,
    /// Residue pairs `{r, P - r}` without a line.
    pub free_residue_pairs: u64,
    /// Record layout.
    pub blocks: Vec<Block>,
    /// Settling per block, s.
    pub settle: f64,
    /// Record length, s.
    pub total_duration: f64,
    /// Allowed record length, s.
    pub max_record: f64,
    /// What the design does not resolve, in words.
    pub limitations: Vec<String>,
}

impl fmt::Display for DesignReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "HTF multisine design")?;
        writeln!(
            f,
            "  forcing: T = {} s, wp = {:.4} rad/s",
            self.period, self.omega_p
        )?;
        writeln!(
            f,
            "  multisine: P = {}, Tm = {} s, dw = {:.6} rad/s",
            self.periods_per_multisine, self.multisine_period, self.bin_width
        )?;
        writeln!(
            f,
            "  lines: {} (bins {}..={} step {}), {:.4}..{:.4} rad/s, amplitude {:.3e} each",
            self.line_count,
            self.first_line_bin,
            self.last_line_bin,
            self.line_step_bins,
            self.lowest_line_omega,
            self.highest_line_omega,
            self.line_amplitude
        )?;
        writeln!(
            f,
            "  level: peak {:.4e}, rms {:.4e}, crest factor {:.3}",
            self.peak, self.rms, self.crest_factor
        )?;
        writeln!(
            f,
            "  resolves: G_n for n = {}..={} over {}..{} rad/s at spacing {:.4} rad/s (target {})",
            self.harmonics.first().map_or(0, |c| c.harmonic),
            self.harmonics.last().map_or(0, |c| c.harmonic),
            self.band[0],
            self.band[1],
            self.achieved_spacing,
            self.target_spacing
        )?;
        for c in &self.harmonics {
            writeln!(
                f,
                "    n = {:>3}: {:>4} points in band, {:.4}..{:.4} rad/s, max gap {:.4}{}",
                c.harmonic,
                c.points_in_band,
                c.first_omega,
                c.last_omega,
                c.max_gap,
                if c.meets_target {
                    ""
                } else {
                    "  MISSES TARGET"
                }
            )?;
        }
        writeln!(
            f,
            "  aliasing: none between any (line, harmonic) pairs, for every n"
        )?;
        let even = match self.even_order {
            EvenOrder::SignReversal => "sign reversal: all even orders cancel in (y(+u) - y(-u))/2",
            EvenOrder::QuadraticGuard => "quadratic guard: second-order products miss every line",
            EvenOrder::Unprotected => "unprotected",
        };
        writeln!(f, "  even orders: {even}")?;
        writeln!(
            f,
            "    lines sharing residues with second-order products: {} of {}; free residue pairs: {}",
            self.second_order_exposed_lines, self.line_count, self.free_residue_pairs
        )?;
        writeln!(
            f,
            "  record: {} block(s), settle {} s each, total {} s (max {} s)",
            self.blocks.len(),
            self.settle,
            self.total_duration,
            self.max_record
        )?;
        for b in &self.blocks {
            writeln!(
                f,
                "    block {} {:?}: settle {}..{} s, measure {}..{} s",
                b.index, b.polarity, b.start, b.measure_start, b.measure_start, b.end
            )?;
        }
        writeln!(f, "  does not resolve:")?;
        for l in &self.limitations {
            writeln!(f, "    - {l}")?;
        }
        Ok(())
    }
}
