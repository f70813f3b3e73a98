//! How a measured output follows a simulated one, and the plain mismatches (a flipped sign, a
//! unit slip) that no parameter can mend.

/// How a measured output follows a simulated one: the regression gain of the measured on the
/// simulated (about 1 when they agree, negative when one moves against the other), the ratio
/// of their spreads, and their correlation.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Agreement {
    pub gain: f64,
    pub scale: f64,
    pub correlation: f64,
}

impl Agreement {
    /// The agreement of paired samples; `None` with fewer than two. Non-finite where the
    /// simulated output does not vary.
    pub(crate) fn of(measured: &[f64], simulated: &[f64]) -> Option<Agreement> {
        let n = measured.len().min(simulated.len());
        if n < 2 {
            return None;
        }
        let (measured, simulated) = (&measured[..n], &simulated[..n]);
        let mean = |v: &[f64]| v.iter().sum::<f64>() / n as f64;
        let (my, ms) = (mean(measured), mean(simulated));
        let cov: f64 = measured
            .iter()
            .zip(simulated)
            .map(|(a, b)| (a - my) * (b - ms))
            .sum::<f64>();
        let var_s: f64 = simulated.iter().map(|b| (b - ms).powi(2)).sum::<f64>();
        let var_y: f64 = measured.iter().map(|a| (a - my).powi(2)).sum::<f64>();
        Some(Agreement {
            gain: cov / var_s,
            scale: (var_y / var_s).sqrt(),
            correlation: cov / (var_s * var_y).sqrt(),
        })
    }

    /// What plainly keeps the simulated output from describing the measured one, whatever
    /// the parameters: the measured moves against it (regression gain below -0.2 at a
    /// correlation below -0.5: a flipped sign), or follows its shape (correlation above 0.5 in
    /// size) at a spread more than [`MAX_SCALE_RATIO`] times larger or smaller (a unit slip).
    /// Both leave the shape plain, so a configured parameter that is merely off (a refit's
    /// business) rarely trips them.
    pub(crate) fn plain(&self) -> Option<Plain> {
        if self.gain < -0.2 && self.correlation < -0.5 {
            Some(Plain::Sign)
        } else if !(1.0 / MAX_SCALE_RATIO..=MAX_SCALE_RATIO).contains(&self.scale)
            && self.correlation.abs() > 0.5
        {
            Some(Plain::Units)
        } else {
            None
        }
    }
}

/// Largest ratio of the measured output's spread to the configured model's (either way) that
/// [`Agreement::plain`] leaves to the refit. Unit slips are factors of 100 and more (cm, mm,
/// um against m); a configured hopper's stiffness a quarter of the truth's already gives 13.
pub(crate) const MAX_SCALE_RATIO: f64 = 30.0;

/// A plain mismatch of a simulated output with the measured one ([`Agreement::plain`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Plain {
    Sign,
    Units,
}
