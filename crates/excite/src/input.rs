//! The designed record as a signal of absolute time.

use crate::{Block, Multisine, Polarity, Signal};

/// The designed record as a [`Signal`] of absolute time.
///
/// In block k, `u(t) = s_k m(t - measure_start_k)` on `[start_k, end_k)` with
/// `m` the multisine and `s_k` the block's sign; the settling segment is the
/// periodic continuation of the same window. Zero outside every block.
///
/// The input never jumps: over the first half of each settling segment the
/// previous block's signal (zero before the first block) is cross-faded into
/// this block's with a raised-cosine weight `w = (1 - cos(pi s)) / 2`,
/// `s = (t - start) / (settle / 2)`. A jump in the input would start a
/// transient at the system's natural frequency that decays only as fast as
/// its Floquet multipliers allow; with the fade the second half of the
/// settling segment (and the measured window) is in periodic steady state up
/// to the decay of a much smaller, slowly varying disturbance.
#[derive(Debug, Clone)]
pub struct DesignInput {
    multisine: Multisine,
    blocks: Vec<Block>,
}

impl DesignInput {
    pub(crate) fn new(multisine: Multisine, blocks: Vec<Block>) -> Self {
        Self { multisine, blocks }
    }

    /// The blocks this input plays.
    pub fn blocks(&self) -> &[Block] {
        &self.blocks
    }
}

impl DesignInput {
    /// Block `k`'s own signal at `t` (no fade).
    fn block_value(&self, k: usize, t: f64) -> f64 {
        let b = &self.blocks[k];
        b.polarity.sign() * self.multisine.value(t - b.measure_start)
    }

    /// The cross-fade weight of block `k` at `t`, or `None` past the fade.
    fn fade_weight(&self, k: usize, t: f64) -> Option<f64> {
        let b = &self.blocks[k];
        let half = 0.5 * (b.measure_start - b.start);
        if half <= 0.0 || t >= b.start + half {
            return None;
        }
        let s = (t - b.start) / half;
        Some(0.5 * (1.0 - (std::f64::consts::PI * s).cos()))
    }
}

impl Signal for DesignInput {
    fn value(&self, t: f64) -> f64 {
        let Some(k) = self
            .blocks
            .iter()
            .position(|b| (b.start..b.end).contains(&t))
        else {
            return 0.0;
        };
        let own = self.block_value(k, t);
        match self.fade_weight(k, t) {
            None => own,
            Some(w) => {
                let previous =
                    if k > 0 && (self.blocks[k - 1].end - self.blocks[k].start).abs() < 1e-9 {
                        self.block_value(k - 1, t)
                    } else {
                        0.0
                    };
                w * own + (1.0 - w) * previous
            }
        }
    }

    fn fill_uniform(&self, t0: f64, dt: f64, out: &mut [f64]) {
        if dt.is_nan() || dt <= 0.0 {
            for (i, o) in out.iter_mut().enumerate() {
                *o = self.value(t0 + i as f64 * dt);
            }
            return;
        }
        out.fill(0.0);
        let n = out.len();
        for b in &self.blocks {
            let i0 = first_index_at_or_after(t0, dt, b.start, n);
            let i1 = first_index_at_or_after(t0, dt, b.end, n);
            if i0 >= i1 {
                continue;
            }
            let seg = &mut out[i0..i1];
            self.multisine
                .fill_uniform(t0 + i0 as f64 * dt - b.measure_start, dt, seg);
            if b.polarity == Polarity::Negative {
                for v in seg.iter_mut() {
                    *v = -*v;
                }
            }
            // The cross-fade at the start of the settling segment, point by point.
            let half = 0.5 * (b.measure_start - b.start);
            let i_fade = first_index_at_or_after(t0, dt, b.start + half, n).min(i1);
            for (i, o) in out.iter_mut().enumerate().take(i_fade).skip(i0) {
                *o = self.value(t0 + i as f64 * dt);
            }
        }
    }
}

/// Smallest i in `0..=n` with `t0 + i dt >= x` (dt > 0), using the same time
/// expression as the samples so block edges are assigned consistently.
fn first_index_at_or_after(t0: f64, dt: f64, x: f64, n: usize) -> usize {
    let mut i = ((x - t0) / dt).ceil().clamp(0.0, n as f64) as usize;
    while i > 0 && t0 + (i - 1) as f64 * dt >= x {
        i -= 1;
    }
    while i < n && t0 + i as f64 * dt < x {
        i += 1;
    }
    i
}
