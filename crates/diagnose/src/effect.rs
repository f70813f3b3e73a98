use std::fmt;
use std::str::FromStr;

use htfid_model::{DamperLaw, Effects, HardStop};

use crate::fit::ModelPoint;
use serde::{Deserialize, Serialize};

/// A candidate physical effect. Its [`name`](Effect::name) and
/// [`parameter_names`](Effect::parameter_names) are the keys of the JSON results.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Effect {
    /// `k3`: extra spring force `-k3 (x - x0)^3` (N/m^3).
    CubicStiffness,
    /// `mu`: Coulomb friction `-mu sign(x')` (N).
    CoulombFriction,
    /// `c_f`: damping `-c_f x'` while the damper is off (N s/m).
    FlightDamping,
    /// `c2`: quadratic drag `-c2 x' |x'|` (N s^2/m^2).
    QuadraticDrag,
    /// `tau`: the applied force lags the measured one, `tau F' = f - F` (s).
    ActuatorLag,
    /// `delay`: the applied force is `f(t - delay)` (s).
    InputDelay,
    /// `v_th`: the damper is on while `x' > v_th` (m/s).
    SwitchThreshold,
    /// `x_stop`, `k_stop`: one-sided contact spring `-k_stop (x - x_stop)` below `x_stop`
    /// (m, N/m).
    HardStop,
    /// `m`, `k`, `c`: the nominal structure with its mass, stiffness and damping refitted.
    ParameterError,
    /// `input_offset`: a constant added to the applied force (N).
    InputOffset,
    /// `mu_pos`, `mu_neg`: Coulomb friction of size `mu_pos` while `x' > 0` and `mu_neg` while
    /// `x' < 0` (N). Fitted as symmetric friction `mu = (mu_pos + mu_neg) / 2` plus a constant
    /// force `(mu_neg - mu_pos) / 2`, which is the same force law, sticking included.
    AsymmetricFriction,
    /// `tau_s`: the recorded output is the position through a first-order low-pass (s).
    SensorLag,
    /// `b`, `g`: the recorded output is `b + g x` (output units, output units per m).
    SensorOffsetGain,
}

impl Effect {
    /// Every effect of the library, in a fixed order.
    pub const ALL: [Effect; 13] = [
        Effect::CubicStiffness,
        Effect::CoulombFriction,
        Effect::FlightDamping,
        Effect::QuadraticDrag,
        Effect::ActuatorLag,
        Effect::InputDelay,
        Effect::SwitchThreshold,
        Effect::HardStop,
        Effect::ParameterError,
        Effect::InputOffset,
        Effect::AsymmetricFriction,
        Effect::SensorLag,
        Effect::SensorOffsetGain,
    ];

    /// The contract name used in results (`cubic_stiffness`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Effect::CubicStiffness => "cubic_stiffness",
            Effect::CoulombFriction => "coulomb_friction",
            Effect::FlightDamping => "flight_damping",
            Effect::QuadraticDrag => "quadratic_drag",
            Effect::ActuatorLag => "actuator_lag",
            Effect::InputDelay => "input_delay",
            Effect::SwitchThreshold => "switch_threshold",
            Effect::HardStop => "hard_stop",
            Effect::ParameterError => "parameter_error",
            Effect::InputOffset => "input_offset",
            Effect::AsymmetricFriction => "asymmetric_friction",
            Effect::SensorLag => "sensor_lag",
            Effect::SensorOffsetGain => "sensor_offset_gain",
        }
    }

    /// Names of the effect's parameters, as in results.
    pub fn parameter_names(self) -> &'static [&'static str] {
        match self {
            Effect::CubicStiffness => &["k3"],
            Effect::CoulombFriction => &["mu"],
            Effect::FlightDamping => &["c_f"],
            Effect::QuadraticDrag => &["c2"],
            Effect::ActuatorLag => &["tau"],
            Effect::InputDelay => &["delay"],
            Effect::SwitchThreshold => &["v_th"],
            Effect::HardStop => &["x_stop", "k_stop"],
            Effect::ParameterError => &["m", "k", "c"],
            Effect::InputOffset => &["input_offset"],
            Effect::AsymmetricFriction => &["mu_pos", "mu_neg"],
            Effect::SensorLag => &["tau_s"],
            Effect::SensorOffsetGain => &["b", "g"],
        }
    }

    /// The slots the effect adds to the fit (for `parameter_error`, those of `m`, `k`, `c` not
    /// already free).
    pub(crate) fn slots(self, free: &[Slot]) -> Vec<Slot> {
        match self {
            Effect::CubicStiffness => vec![Slot::K3],
            Effect::CoulombFriction => vec![Slot::Mu],
            Effect::FlightDamping => vec![Slot::CF],
            Effect::QuadraticDrag => vec![Slot::C2],
            Effect::ActuatorLag => vec![Slot::Tau],
            Effect::InputDelay => vec![Slot::Delay],
            Effect::SwitchThreshold => vec![Slot::VTh],
            Effect::HardStop => vec![Slot::XStop, Slot::KStop],
            Effect::ParameterError => [Slot::M, Slot::K, Slot::C]
                .into_iter()
                .filter(|s| !free.contains(s))
                .collect(),
            Effect::InputOffset => vec![Slot::InputOffset],
            Effect::AsymmetricFriction => [Slot::Mu, Slot::InputOffset]
                .into_iter()
                .filter(|s| !free.contains(s))
                .collect(),
            Effect::SensorLag => vec![Slot::TauS],
            Effect::SensorOffsetGain => vec![Slot::SensorB, Slot::SensorG],
        }
    }

    /// Why the effect cannot be tried on this nominal structure, if it cannot.
    pub(crate) fn skip_reason(self, damper: DamperLaw, free: &[Slot]) -> Option<&'static str> {
        match (self, damper) {
            (Effect::FlightDamping, DamperLaw::AlwaysOn) => {
                Some("skipped: the damper is always on, so there is no flight phase to damp")
            }
            (Effect::SwitchThreshold, DamperLaw::AlwaysOn) => {
                Some("skipped: the damper is always on, so it has no switching threshold")
            }
            (Effect::ParameterError, _) if self.slots(free).is_empty() => Some(
                "skipped: m, k and c are all refitted in the nominal fit already, so this \
                 candidate equals the nominal",
            ),
            (Effect::InputOffset, _) if free.contains(&Slot::InputOffset) => Some(
                "skipped: the input offset is refitted in the nominal fit already, so this \
                 candidate equals the nominal",
            ),
            (Effect::AsymmetricFriction, _) if free.contains(&Slot::InputOffset) => Some(
                "skipped: with the input offset refitted in the nominal fit, asymmetric \
                 friction equals Coulomb friction",
            ),
            _ => None,
        }
    }
}

impl fmt::Display for Effect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The name is not one of [`Effect::ALL`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown effect {0:?}; expected one of cubic_stiffness, coulomb_friction, flight_damping, quadratic_drag, actuator_lag, input_delay, switch_threshold, hard_stop, parameter_error, input_offset, asymmetric_friction, sensor_lag, sensor_offset_gain")]
pub struct UnknownEffect(pub String);

impl FromStr for Effect {
    type Err = UnknownEffect;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Effect::ALL
            .into_iter()
            .find(|e| e.name() == s)
            .ok_or_else(|| UnknownEffect(s.to_string()))
    }
}

/// A parameter of the nominal model that is refitted alongside every candidate (and in the
/// nominal fit itself).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NominalParam {
    /// Mass `m` (kg).
    M,
    /// Stiffness `k` (N/m).
    K,
    /// Damping `c` (N s/m).
    C,
    /// Spring rest length `x0` (m).
    X0,
    /// Constant added to the force, `input_offset` (N).
    InputOffset,
}

impl NominalParam {
    /// The name used in results (`m`, `k`, `c`, `x0`, `input_offset`).
    pub fn name(self) -> &'static str {
        self.slot().name()
    }

    pub(crate) fn slot(self) -> Slot {
        match self {
            NominalParam::M => Slot::M,
            NominalParam::K => Slot::K,
            NominalParam::C => Slot::C,
            NominalParam::X0 => Slot::X0,
            NominalParam::InputOffset => Slot::InputOffset,
        }
    }
}

/// One scalar of the model that a fit may move.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub(crate) enum Slot {
    M,
    K,
    C,
    X0,
    InputOffset,
    K3,
    Mu,
    CF,
    C2,
    Tau,
    Delay,
    VTh,
    XStop,
    KStop,
    TauS,
    SensorB,
    SensorG,
}

fn stop(e: &mut Effects) -> &mut HardStop {
    e.hard_stop.get_or_insert(HardStop {
        x_stop: 0.0,
        k_stop: 0.0,
    })
}

impl Slot {
    pub(crate) fn name(self) -> &'static str {
        match self {
            Slot::M => "m",
            Slot::K => "k",
            Slot::C => "c",
            Slot::X0 => "x0",
            Slot::InputOffset => "input_offset",
            Slot::K3 => "k3",
            Slot::Mu => "mu",
            Slot::CF => "c_f",
            Slot::C2 => "c2",
            Slot::Tau => "tau",
            Slot::Delay => "delay",
            Slot::VTh => "v_th",
            Slot::XStop => "x_stop",
            Slot::KStop => "k_stop",
            Slot::TauS => "tau_s",
            Slot::SensorB => "b",
            Slot::SensorG => "g",
        }
    }

    pub(crate) fn get(self, point: &ModelPoint) -> f64 {
        let (p, e) = (&point.params, &point.effects);
        match self {
            Slot::TauS => point.sensor.tau_s,
            Slot::SensorB => point.sensor.b,
            Slot::SensorG => point.sensor.g,
            Slot::M => p.m,
            Slot::K => p.k,
            Slot::C => p.c,
            Slot::X0 => p.x0,
            Slot::InputOffset => e.input_offset,
            Slot::K3 => e.k3,
            Slot::Mu => e.mu,
            Slot::CF => e.c_f,
            Slot::C2 => e.c2,
            Slot::Tau => e.tau,
            Slot::Delay => e.delay,
            Slot::VTh => e.v_th,
            Slot::XStop => e.hard_stop.map_or(0.0, |h| h.x_stop),
            Slot::KStop => e.hard_stop.map_or(0.0, |h| h.k_stop),
        }
    }

    pub(crate) fn set(self, point: &mut ModelPoint, value: f64) {
        let (p, e) = (&mut point.params, &mut point.effects);
        match self {
            Slot::TauS => point.sensor.tau_s = value,
            Slot::SensorB => point.sensor.b = value,
            Slot::SensorG => point.sensor.g = value,
            Slot::M => p.m = value,
            Slot::K => p.k = value,
            Slot::C => p.c = value,
            Slot::X0 => p.x0 = value,
            Slot::InputOffset => e.input_offset = value,
            Slot::K3 => e.k3 = value,
            Slot::Mu => e.mu = value,
            Slot::CF => e.c_f = value,
            Slot::C2 => e.c2 = value,
            Slot::Tau => e.tau = value,
            Slot::Delay => e.delay = value,
            Slot::VTh => e.v_th = value,
            Slot::XStop => stop(e).x_stop = value,
            Slot::KStop => stop(e).k_stop = value,
        }
    }

    /// Positive scale parameters are fitted as logarithms (a mass of 5e-6 and a stiffness of
    /// 200 then have steps of the same relative size).
    pub(crate) fn log_scaled(self) -> bool {
        matches!(self, Slot::M | Slot::K | Slot::C)
    }

    /// Lower bound of the physical range (friction, damping, lag, delay and contact stiffness
    /// cannot be negative).
    pub(crate) fn lower_bound(self) -> f64 {
        match self {
            Slot::Mu
            | Slot::CF
            | Slot::C2
            | Slot::Tau
            | Slot::Delay
            | Slot::KStop
            | Slot::TauS
            | Slot::SensorG => 0.0,
            _ => f64::NEG_INFINITY,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Sensor;
    use htfid_model::HopperParams;

    #[test]
    fn names_round_trip_and_unknown_names_fail() {
        for e in Effect::ALL {
            assert_eq!(e.name().parse::<Effect>(), Ok(e));
            let json = serde_json::to_string(&e).unwrap();
            assert_eq!(json, format!("\"{}\"", e.name()));
        }
        let err = "cubic".parse::<Effect>().unwrap_err();
        assert!(err.to_string().starts_with("unknown effect \"cubic\""));
    }

    #[test]
    fn slots_set_what_they_get() {
        let mut point = ModelPoint {
            params: HopperParams::paper(),
            effects: Effects::default(),
            sensor: Sensor::default(),
        };
        let all = [
            Slot::M,
            Slot::K,
            Slot::C,
            Slot::X0,
            Slot::InputOffset,
            Slot::K3,
            Slot::Mu,
            Slot::CF,
            Slot::C2,
            Slot::Tau,
            Slot::Delay,
            Slot::VTh,
            Slot::XStop,
            Slot::KStop,
            Slot::TauS,
            Slot::SensorB,
            Slot::SensorG,
        ];
        for (i, s) in all.into_iter().enumerate() {
            let v = 0.5 + i as f64;
            s.set(&mut point, v);
            assert!((s.get(&point) - v).abs() < 1e-15, "{}", s.name());
        }
        let parameter_error = Effect::ParameterError.slots(&[Slot::K, Slot::C]);
        assert_eq!(parameter_error, vec![Slot::M]);
    }
}
