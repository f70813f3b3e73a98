use crate::DiagnoseError;

/// Smallest record the diagnosis accepts.
pub(crate) const MIN_SAMPLES: usize = 32;

/// [`DiagnoseError::TooShort`] for a record of fewer than [`MIN_SAMPLES`] samples; a
/// [`TimeSeries`](htfid_data::TimeSeries) is otherwise valid by construction.
pub(crate) fn check_length(samples: usize) -> Result<(), DiagnoseError> {
    if samples < MIN_SAMPLES {
        return Err(DiagnoseError::TooShort {
            min: MIN_SAMPLES,
            found: samples,
        });
    }
    Ok(())
}

/// [`DiagnoseError::ConstantOutput`] when `y` holds one value throughout all of `ranges`.
pub(crate) fn check_varies(
    y: &[f64],
    ranges: &[std::ops::Range<usize>],
    which: &str,
) -> Result<(), DiagnoseError> {
    let mut values = ranges.iter().flat_map(|r| y[r.clone()].iter().copied());
    let Some(first) = values.next() else {
        return Ok(());
    };
    // Exactly one value: a sensor that never changes, not a small motion.
    if values.all(|v| v.to_bits() == first.to_bits()) {
        let start = ranges.iter().map(|r| r.start).min().unwrap_or(0);
        let end = ranges.iter().map(|r| r.end).max().unwrap_or(0);
        return Err(DiagnoseError::ConstantOutput {
            which: which.to_string(),
            start,
            end,
            value: first,
        });
    }
    Ok(())
}
