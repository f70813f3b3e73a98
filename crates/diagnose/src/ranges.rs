//! Which samples are fitted and which held out, the burn-in, and the segments fitted.

use std::ops::Range;

use htfid_model::DamperLaw;

use crate::deriv::local_fit;
use crate::fit::Segment;
use crate::options::DiagnoseOptions;
use crate::{DiagnoseError, NominalModel, TimeSeries};

/// Fewest scored samples a range must keep after the burn-in.
const MIN_SCORED: usize = 16;

/// Sample-index ranges.
pub(crate) type Ranges = Vec<Range<usize>>;

/// The fit and validation ranges of `opts` for a record of `n` samples (the first 70 % and the
/// rest when none are given): each inside the record, no fit range overlapping a held-out one.
pub(crate) fn resolve_ranges(
    opts: &DiagnoseOptions,
    n: usize,
) -> Result<(Ranges, Ranges), DiagnoseError> {
    let split = (n as f64 * 0.7).floor() as usize;
    let fit = if opts.fit.is_empty() {
        std::iter::once(0..split).collect()
    } else {
        opts.fit.clone()
    };
    let val = if opts.validation.is_empty() {
        std::iter::once(split..n).collect()
    } else {
        opts.validation.clone()
    };
    for (which, ranges) in [("fit", &fit), ("validation", &val)] {
        for r in ranges.iter() {
            if r.start >= r.end || r.end > n {
                return Err(DiagnoseError::InvalidRange {
                    which,
                    start: r.start,
                    end: r.end,
                    len: n,
                });
            }
        }
    }
    for f in &fit {
        for v in &val {
            if f.start < v.end && v.start < f.end {
                return Err(DiagnoseError::OverlappingRanges {
                    fit_start: f.start,
                    fit_end: f.end,
                    val_start: v.start,
                    val_end: v.end,
                });
            }
        }
    }
    Ok((fit, val))
}

pub(crate) fn auto_burn_in(
    nominal: &NominalModel,
    fit: &[Range<usize>],
    val: &[Range<usize>],
    dt: f64,
) -> f64 {
    let p = &nominal.params;
    let c_eff = match nominal.damper {
        DamperLaw::AlwaysOn => p.c,
        DamperLaw::Switching => 0.5 * p.c,
    };
    let shortest = fit.iter().chain(val).map(|r| r.len()).min().unwrap_or(0) as f64 * dt;
    let decay_time = if c_eff > 0.0 {
        2.0 * p.m / c_eff
    } else {
        f64::INFINITY
    };
    (4.0 * decay_time).min(0.25 * shortest)
}

pub(crate) fn segments(
    record: &TimeSeries,
    ranges: &[Range<usize>],
    skip: usize,
    half: usize,
    which: &'static str,
    burn_in_s: f64,
) -> Result<Vec<Segment>, DiagnoseError> {
    let x = record.output();
    ranges
        .iter()
        .map(|r| {
            let kept = r.len().saturating_sub(skip);
            if kept < MIN_SCORED {
                return Err(DiagnoseError::RangeTooShort {
                    which,
                    start: r.start,
                    end: r.end,
                    kept,
                    burn_in_s,
                    min: MIN_SCORED,
                });
            }
            let init = data_state(record, r.start, half).unwrap_or([x[r.start], 0.0]);
            Ok(Segment {
                range: r.clone(),
                skip,
                init,
            })
        })
        .collect()
}

/// Consecutive windows of `len` samples over the scored samples of `segs`, each simulated from
/// the state of a local cubic through the samples around its start (as [`segments`] starts a
/// segment), nothing skipped: short simulations whose errors do not compound over the record.
pub(crate) fn windows(
    record: &TimeSeries,
    segs: &[Segment],
    len: usize,
    half: usize,
) -> Vec<Segment> {
    let len = len.max(1);
    let mut out = Vec::new();
    for seg in segs {
        let scored = seg.scored();
        let mut start = scored.start;
        while start + len <= scored.end {
            if let Some(init) = data_state(record, start, half) {
                out.push(Segment {
                    range: start..start + len,
                    skip: 0,
                    init,
                });
            }
            start += len;
        }
    }
    out
}

/// Position and velocity at sample `at` of a local cubic through the measured samples within
/// `half` of it (those before a segment's start are measured data too; only the state is taken
/// from them). `None` where the window has too few samples.
fn data_state(record: &TimeSeries, at: usize, half: usize) -> Option<[f64; 2]> {
    let x = record.output();
    let lo = at.saturating_sub(half);
    let hi = (at + half + 1).min(x.len());
    local_fit(x, lo, hi, at, record.dt(), 3).map(|k| [k.x, k.v])
}
