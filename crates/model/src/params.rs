use serde::{Deserialize, Serialize};

use crate::ModelError;

/// Physical parameters of the hopper and its periodic forcing (SI units).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HopperParams {
    /// Mass (kg), > 0.
    pub m: f64,
    /// Spring stiffness (N/m), > 0.
    pub k: f64,
    /// Damping coefficient while the damper is on (N s/m), >= 0.
    pub c: f64,
    /// Gravitational acceleration (m/s^2), finite (0 removes gravity).
    pub g: f64,
    /// Spring rest length (m).
    pub x0: f64,
    /// Amplitude `A` of the forcing `A cos(2 pi t / T)` (N).
    pub forcing_amplitude: f64,
    /// Forcing period `T` (s), > 0.
    pub period: f64,
}

impl HopperParams {
    /// The paper's parameters: g = 9.81, k = 200, c = 2, m = 1, x0 = 0.2, f0 = cos(2 pi t).
    pub fn paper() -> Self {
        HopperParams {
            m: 1.0,
            k: 200.0,
            c: 2.0,
            g: 9.81,
            x0: 0.2,
            forcing_amplitude: 1.0,
            period: 1.0,
        }
    }

    /// Checks every range; the error names the parameter, what was expected and the value.
    pub fn validate(&self) -> Result<(), ModelError> {
        positive("m", self.m)?;
        // k = 0 is a free mass (an integrating plant, e.g. a positioning stage).
        non_negative("k", self.k)?;
        non_negative("c", self.c)?;
        finite("g", self.g)?;
        finite("x0", self.x0)?;
        finite("forcing_amplitude", self.forcing_amplitude)?;
        positive("period", self.period)?;
        Ok(())
    }

    /// The static equilibrium `x0 - m g / k`; `x0` for a free mass (`k = 0`), which has
    /// none.
    pub fn equilibrium(&self) -> f64 {
        if self.k > 0.0 {
            self.x0 - self.m * self.g / self.k
        } else {
            self.x0
        }
    }

    /// The rate (rad/s) that sets the model's time scale: the undamped natural frequency
    /// `sqrt(k / m)`, or for a free mass (`k = 0`) the velocity's decay rate `c / m` (zero
    /// for a free mass without damping, which has no time scale of its own).
    pub fn natural_rate(&self) -> f64 {
        if self.k > 0.0 {
            (self.k / self.m).sqrt()
        } else {
            self.c / self.m
        }
    }

    /// Pumping (forcing) angular frequency `2 pi / T` (rad/s).
    pub fn pump_frequency(&self) -> f64 {
        2.0 * std::f64::consts::PI / self.period
    }
}

pub(crate) fn finite(name: &'static str, value: f64) -> Result<(), ModelError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(ModelError::InvalidParameter {
            name,
            expected: "a finite number",
            value,
        })
    }
}

pub(crate) fn positive(name: &'static str, value: f64) -> Result<(), ModelError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(ModelError::InvalidParameter {
            name,
            expected: "> 0 and finite",
            value,
        })
    }
}

pub(crate) fn non_negative(name: &'static str, value: f64) -> Result<(), ModelError> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(ModelError::InvalidParameter {
            name,
            expected: ">= 0 and finite",
            value,
        })
    }
}

/// A one-sided contact spring below `x_stop`: extra force `-k_stop (x - x_stop)` while
/// `x < x_stop`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HardStop {
    /// Contact position (m).
    pub x_stop: f64,
    /// Contact stiffness (N/m), >= 0.
    pub k_stop: f64,
}

/// Optional physical terms beyond the nominal hopper. All default to "absent"; each is one of
/// the candidate effects the diagnosis can name.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Effects {
    /// Cubic stiffness: extra force `-k3 (x - x0)^3` (N/m^3).
    pub k3: f64,
    /// Coulomb friction: `-mu sign(x')` (N).
    pub mu: f64,
    /// Flight damping: `-c_f x'` while the damper is off (N s/m).
    pub c_f: f64,
    /// Quadratic drag: `-c2 x' |x'|` (N s^2/m^2).
    pub c2: f64,
    /// Actuator lag: the applied force follows the commanded one through `tau F' = f - F` (s);
    /// adds a third state.
    pub tau: f64,
    /// Input delay: the applied force is `f(t - delay)` (s), >= 0.
    pub delay: f64,
    /// Switch threshold: the damper is on while `x' > v_th` (m/s).
    pub v_th: f64,
    /// One-sided contact spring.
    pub hard_stop: Option<HardStop>,
    /// Constant added to the applied force (N); models an input offset.
    pub input_offset: f64,
}

impl Effects {
    /// Checks every range.
    pub fn validate(&self) -> Result<(), ModelError> {
        finite("k3", self.k3)?;
        finite("mu", self.mu)?;
        finite("c_f", self.c_f)?;
        finite("c2", self.c2)?;
        non_negative("tau", self.tau)?;
        non_negative("delay", self.delay)?;
        finite("v_th", self.v_th)?;
        finite("input_offset", self.input_offset)?;
        if let Some(stop) = self.hard_stop {
            finite("x_stop", stop.x_stop)?;
            non_negative("k_stop", stop.k_stop)?;
        }
        Ok(())
    }

    /// Whether the actuator-lag state is present.
    #[inline]
    pub fn has_lag(&self) -> bool {
        self.tau > 0.0
    }
}
