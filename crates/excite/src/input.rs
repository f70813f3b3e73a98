//! The designed record as a signal of absolute time.

use crate::{Block, Multisine, Polarity, Signal};

/// The designed record as a [`Signal`] of absolute time.
///
/// In block k, `u(t) = s_k m(t - measure_start_k)` on `[start_k, end_k)` with
/// `m` the multisine and `s_k` the block's sign; the settling segment is the
/// periodic continuation of the same window. Zero outside every block.
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

impl Signal for DesignInput {
    fn value(&self, t: f64) -> f64 {
        self.blocks
            .iter()
            .find(|b| (b.start..b.end).contains(&t))
            .map_or(0.0, |b| {
                b.polarity.sign() * self.multisine.value(t - b.measure_start)
            })
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
