use crate::HybridError;

/// The explicit Runge-Kutta pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Method {
    /// Dormand-Prince 5(4), 6 function evaluations per step (FSAL), 4th-order dense output.
    Dopri5,
    /// Hairer's DOP853: order 8 with the 5th- and 3rd-order error estimators combined,
    /// 12 evaluations per step (FSAL) plus 3 for the 7th-order dense output.
    #[default]
    Dop853,
}

impl Method {
    /// Order of the propagated solution.
    pub fn order(self) -> u32 {
        match self {
            Method::Dopri5 => 5,
            Method::Dop853 => 8,
        }
    }

    /// Order of the dense output (the interpolant's local error is `O(h^(order + 1))`).
    pub fn dense_order(self) -> u32 {
        match self {
            Method::Dopri5 => 4,
            Method::Dop853 => 7,
        }
    }
}

/// Integrator settings. Times are in seconds; tolerances apply per state component as
/// `atol + rtol * |x_i|`.
#[derive(Debug, Clone)]
pub struct Options {
    /// Runge-Kutta pair.
    pub method: Method,
    /// Relative tolerance, `> 0`. Default `1e-10`.
    pub rtol: f64,
    /// Absolute tolerance, `>= 0`. Default `1e-12`.
    pub atol: f64,
    /// First step; `None` picks it with Hairer's starting-step algorithm.
    pub h_init: Option<f64>,
    /// Largest step, `> 0` (may be infinite). Default infinite. Also bounds how far apart the
    /// guard samples are (`h_max / (guard_samples + 1)`).
    pub h_max: f64,
    /// Smallest step the controller may propose, `>= 0` (absolute, s). Default `1e-14`.
    /// A smaller proposal is [`HybridError::StepSizeTooSmall`]. Steps shortened to land on
    /// `t_stop` are exempt.
    pub h_min: f64,
    /// Cap on attempted (accepted plus rejected) steps. Default `10_000_000`.
    pub max_steps: u64,
    /// Accuracy of located event times, `> 0` (s). Default `1e-12`.
    pub event_tol: f64,
    /// Interior dense-output samples per step and guard, in addition to the step end.
    /// Default 4. More samples catch sign changes closer together.
    pub guard_samples: usize,
    /// A guard extremum whose value lies within `graze_tol` of zero without crossing it is
    /// reported as an [`EventKind::Grazing`](crate::EventKind::Grazing) event, `>= 0`, in guard
    /// units. Default `1e-8`. Zero reports only exact touches.
    pub graze_tol: f64,
    /// Window of the Zeno test, `> 0` (s). Default `1e-3`.
    pub zeno_window: f64,
    /// More transitions than this within any `zeno_window` is [`HybridError::Zeno`], `>= 1`.
    /// Default 100.
    pub zeno_max_events: usize,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            method: Method::default(),
            rtol: 1e-10,
            atol: 1e-12,
            h_init: None,
            h_max: f64::INFINITY,
            h_min: 1e-14,
            max_steps: 10_000_000,
            event_tol: 1e-12,
            guard_samples: 4,
            graze_tol: 1e-8,
            zeno_window: 1e-3,
            zeno_max_events: 100,
        }
    }
}

fn invalid(field: &'static str, reason: String) -> HybridError {
    HybridError::InvalidOptions { field, reason }
}

fn positive_finite(field: &'static str, value: f64) -> Result<(), HybridError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(invalid(
            field,
            format!("must be > 0 and finite (got {value})"),
        ))
    }
}

fn non_negative_finite(field: &'static str, value: f64) -> Result<(), HybridError> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(invalid(
            field,
            format!("must be >= 0 and finite (got {value})"),
        ))
    }
}

impl Options {
    /// Checks every field's range; the error names the field and the offending value.
    pub fn validate(&self) -> Result<(), HybridError> {
        positive_finite("rtol", self.rtol)?;
        non_negative_finite("atol", self.atol)?;
        if let Some(h) = self.h_init {
            positive_finite("h_init", h)?;
        }
        if self.h_max.is_nan() || self.h_max <= 0.0 {
            return Err(invalid(
                "h_max",
                format!("must be > 0 (got {})", self.h_max),
            ));
        }
        non_negative_finite("h_min", self.h_min)?;
        if self.h_min >= self.h_max {
            return Err(invalid(
                "h_min",
                format!(
                    "must be smaller than h_max = {} (got {})",
                    self.h_max, self.h_min
                ),
            ));
        }
        if self.max_steps == 0 {
            return Err(invalid("max_steps", "must be >= 1 (got 0)".to_string()));
        }
        positive_finite("event_tol", self.event_tol)?;
        non_negative_finite("graze_tol", self.graze_tol)?;
        positive_finite("zeno_window", self.zeno_window)?;
        if self.zeno_max_events == 0 {
            return Err(invalid(
                "zeno_max_events",
                "must be >= 1 (got 0)".to_string(),
            ));
        }
        Ok(())
    }
}
