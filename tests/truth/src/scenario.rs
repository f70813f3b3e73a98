//! What a record contains: the [`Scenario`] (serde) and its parts.

use serde::{Deserialize, Serialize};

use crate::error::Error;
use crate::label::{EffectLabel, Label, LabelClass};

/// Nominal mass, kg.
pub const M: f64 = 1.0;
/// Nominal spring stiffness, N/m.
pub const K: f64 = 200.0;
/// Nominal damper coefficient, N s/m.
pub const C: f64 = 2.0;
/// Nominal gravity, m/s^2.
pub const G: f64 = 9.81;
/// Nominal spring rest length, m.
pub const X0: f64 = 0.2;
/// Forcing amplitude, N.
pub const FORCING_AMPLITUDE: f64 = 1.0;
/// Forcing period, s.
pub const FORCING_PERIOD: f64 = 1.0;

/// One record to generate: the true system's deviations from the nominal hopper, the input,
/// the sampling and the noise.
///
/// Every field has a default, so `{}` is the clean paper protocol at 100 Hz without noise.
/// Unknown keys are rejected.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Free-form identifier, copied to the manifest.
    #[serde(default)]
    pub name: String,
    /// Effects present in the true system (each kind at most once).
    #[serde(default)]
    pub effects: Vec<Effect>,
    /// Fractional errors of the physical parameters.
    #[serde(default)]
    pub parameter_errors: ParameterErrors,
    /// Measurement noise.
    #[serde(default)]
    pub noise: Noise,
    /// Sample rate of the record.
    #[serde(default)]
    pub sample_rate: SampleRate,
    /// The excitation `u(t)` added to the periodic forcing.
    #[serde(default)]
    pub excitation: Excitation,
    /// Seed of the measurement noise.
    #[serde(default)]
    pub seed: u64,
    /// Settling time simulated from `t = 0` before the record starts, s (default 30).
    #[serde(default = "default_settle_s")]
    pub settle_s: f64,
    /// Length of the record, s (default 270: nine 30 s chirps).
    #[serde(default = "default_record_s")]
    pub record_s: f64,
}

fn default_settle_s() -> f64 {
    30.0
}

fn default_record_s() -> f64 {
    270.0
}

impl Default for Scenario {
    fn default() -> Self {
        Scenario {
            name: String::new(),
            effects: Vec::new(),
            parameter_errors: ParameterErrors::default(),
            noise: Noise::default(),
            sample_rate: SampleRate::default(),
            excitation: Excitation::default(),
            seed: 0,
            settle_s: default_settle_s(),
            record_s: default_record_s(),
        }
    }
}

/// One deviation of the true system from the nominal hopper. See the crate docs for the exact
/// equations. In JSON: `{"effect": "cubic_stiffness", "k3": 2000.0}`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "effect", rename_all = "snake_case", deny_unknown_fields)]
pub enum Effect {
    /// Extra spring force `-k3 (x - x0)^3`; `k3` in N/m^3.
    CubicStiffness {
        /// N/m^3.
        k3: f64,
    },
    /// Coulomb friction `-mu sign(v)` with sticking; `mu` in N.
    CoulombFriction {
        /// N, >= 0.
        mu: f64,
    },
    /// Friction `-mu_pos` while `v > 0`, `+mu_neg` while `v < 0`, with sticking; N.
    AsymmetricFriction {
        /// N, >= 0.
        mu_pos: f64,
        /// N, >= 0.
        mu_neg: f64,
    },
    /// Damping `-c_f (1 - s) v` while the damper is off; N s/m.
    FlightDamping {
        /// N s/m.
        c_f: f64,
    },
    /// Drag `-c2 v |v|`; N s^2/m^2.
    QuadraticDrag {
        /// N s^2/m^2.
        c2: f64,
    },
    /// First-order actuator: `tau F' = f_cmd - F`; s.
    ActuatorLag {
        /// s, > 0.
        tau: f64,
    },
    /// Applied force `f_cmd(t - delay)`; s.
    InputDelay {
        /// s, >= 0.
        delay: f64,
    },
    /// Applied force `f_cmd + offset`; N.
    InputOffset {
        /// N.
        offset: f64,
    },
    /// The damper is on while `v > v_th`; m/s.
    SwitchThreshold {
        /// m/s.
        v_th: f64,
    },
    /// One-sided contact `-k_stop (x - x_stop)` while `x < x_stop`.
    HardStop {
        /// N/m, > 0.
        k_stop: f64,
        /// m.
        x_stop: f64,
    },
    /// Measured position is a first-order low-pass of `x`: `tau_s x_m' = x - x_m`; s.
    SensorLag {
        /// s, > 0.
        tau_s: f64,
    },
    /// Measured position `gain * x + b`.
    SensorOffsetGain {
        /// m.
        b: f64,
        /// Dimensionless, > 0.
        gain: f64,
    },
    /// Out of library. Force backlash (play operator) of total width `gap` between the
    /// commanded and the applied force; N.
    Backlash {
        /// N, > 0.
        gap: f64,
    },
    /// Out of library. Part `m2` of the mass hangs on a spring `k2` and damper `c2`.
    SecondMode {
        /// kg, 0 < m2 < m.
        m2: f64,
        /// N/m, > 0.
        k2: f64,
        /// N s/m, >= 0.
        c2: f64,
    },
    /// Out of library. Force `-a (x - x_eq) v`; N s/m^2.
    PosVelForce {
        /// N s/m^2.
        a: f64,
    },
    /// Out of library, unmeasured. True forcing amplitude `A (1 + depth sin(2 pi t / period))`.
    SlowForcingAmplitude {
        /// Dimensionless, |depth| < 1.
        depth: f64,
        /// s, > 0.
        period: f64,
    },
}

impl Effect {
    /// The effect's name as written in JSON and in labels.
    pub fn name(&self) -> &'static str {
        match self {
            Effect::CubicStiffness { .. } => "cubic_stiffness",
            Effect::CoulombFriction { .. } => "coulomb_friction",
            Effect::AsymmetricFriction { .. } => "asymmetric_friction",
            Effect::FlightDamping { .. } => "flight_damping",
            Effect::QuadraticDrag { .. } => "quadratic_drag",
            Effect::ActuatorLag { .. } => "actuator_lag",
            Effect::InputDelay { .. } => "input_delay",
            Effect::InputOffset { .. } => "input_offset",
            Effect::SwitchThreshold { .. } => "switch_threshold",
            Effect::HardStop { .. } => "hard_stop",
            Effect::SensorLag { .. } => "sensor_lag",
            Effect::SensorOffsetGain { .. } => "sensor_offset_gain",
            Effect::Backlash { .. } => "backlash",
            Effect::SecondMode { .. } => "second_mode",
            Effect::PosVelForce { .. } => "pos_vel_force",
            Effect::SlowForcingAmplitude { .. } => "slow_forcing_amplitude",
        }
    }

    /// Whether the diagnosis's library contains this effect (it is expected to name it).
    pub fn in_library(&self) -> bool {
        !matches!(
            self,
            Effect::Backlash { .. }
                | Effect::SecondMode { .. }
                | Effect::PosVelForce { .. }
                | Effect::SlowForcingAmplitude { .. }
        )
    }

    /// Whether the effect acts on the measurement rather than on the dynamics.
    pub fn is_sensor_side(&self) -> bool {
        matches!(
            self,
            Effect::SensorLag { .. } | Effect::SensorOffsetGain { .. }
        )
    }

    /// Parameter names and values, in declaration order.
    pub fn params(&self) -> Vec<(&'static str, f64)> {
        match *self {
            Effect::CubicStiffness { k3 } => vec![("k3", k3)],
            Effect::CoulombFriction { mu } => vec![("mu", mu)],
            Effect::AsymmetricFriction { mu_pos, mu_neg } => {
                vec![("mu_pos", mu_pos), ("mu_neg", mu_neg)]
            }
            Effect::FlightDamping { c_f } => vec![("c_f", c_f)],
            Effect::QuadraticDrag { c2 } => vec![("c2", c2)],
            Effect::ActuatorLag { tau } => vec![("tau", tau)],
            Effect::InputDelay { delay } => vec![("delay", delay)],
            Effect::InputOffset { offset } => vec![("offset", offset)],
            Effect::SwitchThreshold { v_th } => vec![("v_th", v_th)],
            Effect::HardStop { k_stop, x_stop } => vec![("k_stop", k_stop), ("x_stop", x_stop)],
            Effect::SensorLag { tau_s } => vec![("tau_s", tau_s)],
            Effect::SensorOffsetGain { b, gain } => vec![("b", b), ("gain", gain)],
            Effect::Backlash { gap } => vec![("gap", gap)],
            Effect::SecondMode { m2, k2, c2 } => vec![("m2", m2), ("k2", k2), ("c2", c2)],
            Effect::PosVelForce { a } => vec![("a", a)],
            Effect::SlowForcingAmplitude { depth, period } => {
                vec![("depth", depth), ("period", period)]
            }
        }
    }

    /// Range checks; `index` names the effect in messages.
    fn validate(&self, index: usize) -> Result<(), Error> {
        let name = |p: &str| format!("effects[{index}].{p}");
        let check = |p: &str, v: f64, ok: bool, requirement: &'static str| {
            if ok && v.is_finite() {
                Ok(())
            } else {
                Err(Error::InvalidParameter {
                    name: name(p),
                    requirement,
                    value: v,
                })
            }
        };
        match *self {
            Effect::CoulombFriction { mu } => check("mu", mu, mu >= 0.0, ">= 0"),
            Effect::AsymmetricFriction { mu_pos, mu_neg } => {
                check("mu_pos", mu_pos, mu_pos >= 0.0, ">= 0")?;
                check("mu_neg", mu_neg, mu_neg >= 0.0, ">= 0")
            }
            Effect::FlightDamping { c_f } => check("c_f", c_f, c_f >= 0.0, ">= 0"),
            Effect::QuadraticDrag { c2 } => check("c2", c2, c2 >= 0.0, ">= 0"),
            Effect::ActuatorLag { tau } => check("tau", tau, tau > 0.0, "> 0"),
            Effect::InputDelay { delay } => check("delay", delay, delay >= 0.0, ">= 0"),
            Effect::HardStop { k_stop, x_stop } => {
                check("k_stop", k_stop, k_stop > 0.0, "> 0")?;
                check("x_stop", x_stop, true, "finite")
            }
            Effect::SensorLag { tau_s } => check("tau_s", tau_s, tau_s > 0.0, "> 0"),
            Effect::SensorOffsetGain { b, gain } => {
                check("b", b, true, "finite")?;
                check("gain", gain, gain > 0.0, "> 0")
            }
            Effect::Backlash { gap } => check("gap", gap, gap > 0.0, "> 0"),
            Effect::SecondMode { m2, k2, c2 } => {
                // The bound on m2 against the true mass is checked by the plant.
                check("m2", m2, m2 > 0.0, "> 0")?;
                check("k2", k2, k2 > 0.0, "> 0")?;
                check("c2", c2, c2 >= 0.0, ">= 0")
            }
            Effect::SlowForcingAmplitude { depth, period } => {
                check("depth", depth, depth.abs() < 1.0, "in (-1, 1)")?;
                check("period", period, period > 0.0, "> 0")
            }
            Effect::CubicStiffness { k3 } => check("k3", k3, true, "finite"),
            Effect::InputOffset { offset } => check("offset", offset, true, "finite"),
            Effect::SwitchThreshold { v_th } => check("v_th", v_th, true, "finite"),
            Effect::PosVelForce { a } => check("a", a, true, "finite"),
        }
    }
}

/// Fractional errors of the true physical parameters: true value = nominal * (1 + error).
/// All zero by default.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ParameterErrors {
    /// Mass.
    pub m: f64,
    /// Spring stiffness.
    pub k: f64,
    /// Damper coefficient.
    pub c: f64,
    /// Gravity.
    pub g: f64,
    /// Spring rest length.
    pub x0: f64,
}

impl ParameterErrors {
    /// `(name, fraction, nominal)` for each parameter, in the order m, k, c, g, x0.
    pub fn entries(&self) -> [(&'static str, f64, f64); 5] {
        [
            ("m", self.m, M),
            ("k", self.k, K),
            ("c", self.c, C),
            ("g", self.g, G),
            ("x0", self.x0, X0),
        ]
    }

    /// Whether any parameter differs from nominal.
    pub fn any(&self) -> bool {
        self.entries().iter().any(|e| e.1 != 0.0)
    }

    fn validate(&self) -> Result<(), Error> {
        for (name, frac, _) in self.entries() {
            if !(frac.is_finite() && frac > -0.5 && frac < 0.5) {
                return Err(Error::InvalidParameter {
                    name: format!("parameter_errors.{name}"),
                    requirement: "in (-0.5, 0.5)",
                    value: frac,
                });
            }
        }
        Ok(())
    }
}

/// Additive white Gaussian measurement noise (standard deviations). Zero by default.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Noise {
    /// On the measured position, m.
    pub sigma_x: f64,
    /// On the recorded commanded force, N (the applied force is not affected).
    pub sigma_f: f64,
}

/// Sample rate of a record. In JSON a plain number of Hz: `100`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "u32", into = "u32")]
pub enum SampleRate {
    /// 50 Hz.
    Hz50,
    /// 100 Hz (default).
    #[default]
    Hz100,
    /// 200 Hz.
    Hz200,
    /// 1000 Hz.
    Hz1000,
}

impl SampleRate {
    /// All supported rates.
    pub const ALL: [SampleRate; 4] = [
        SampleRate::Hz50,
        SampleRate::Hz100,
        SampleRate::Hz200,
        SampleRate::Hz1000,
    ];

    /// The rate in Hz.
    pub fn hz(self) -> u32 {
        match self {
            SampleRate::Hz50 => 50,
            SampleRate::Hz100 => 100,
            SampleRate::Hz200 => 200,
            SampleRate::Hz1000 => 1000,
        }
    }
}

impl TryFrom<u32> for SampleRate {
    type Error = Error;
    fn try_from(hz: u32) -> Result<Self, Error> {
        SampleRate::ALL
            .into_iter()
            .find(|r| r.hz() == hz)
            .ok_or(Error::UnsupportedSampleRate { hz })
    }
}

impl From<SampleRate> for u32 {
    fn from(r: SampleRate) -> u32 {
        r.hz()
    }
}

/// The excitation `u(t)`, added to the periodic forcing from `settle_s` on (zero before).
/// In JSON: `{"kind": "paper_chirps"}`, `{"kind": "multisine", "phase_seed": 7}`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Excitation {
    /// Back-to-back 30 s chirps `0.004 sin(14 pi tau^2 / 30 + 2 pi i / 9)`, `i` = chirp index
    /// mod 9, `tau` the time since the chirp started (0 to 14 Hz).
    #[default]
    PaperChirps,
    /// Random-phase multisine, 68 equal-amplitude lines at 0.25, 0.35, ..., 6.95 Hz, with the
    /// RMS of the chirp (0.004 / sqrt 2 N).
    Multisine {
        /// Seed of the phases.
        phase_seed: u64,
    },
    /// No excitation: the periodic forcing alone.
    ForcingOnly,
}

impl Scenario {
    /// Range checks of every field. Conflicts between effects and bounds that need the true
    /// parameters are checked when the plant is built ([`crate::Plant::new`]).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the field, [`Error::ConflictingEffects`].
    pub fn validate(&self) -> Result<(), Error> {
        for (i, e) in self.effects.iter().enumerate() {
            e.validate(i)?;
            for other in &self.effects[..i] {
                if other.name() == e.name() {
                    return Err(Error::ConflictingEffects {
                        first: e.name(),
                        second: e.name(),
                    });
                }
                let frictions = ["coulomb_friction", "asymmetric_friction"];
                if frictions.contains(&other.name()) && frictions.contains(&e.name()) {
                    return Err(Error::ConflictingEffects {
                        first: other.name(),
                        second: e.name(),
                    });
                }
            }
        }
        self.parameter_errors.validate()?;
        let nonneg = |name: &str, v: f64| {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err(Error::InvalidParameter {
                    name: name.to_string(),
                    requirement: ">= 0",
                    value: v,
                })
            }
        };
        nonneg("noise.sigma_x", self.noise.sigma_x)?;
        nonneg("noise.sigma_f", self.noise.sigma_f)?;
        nonneg("settle_s", self.settle_s)?;
        if !(self.record_s.is_finite() && self.record_s > 0.0) {
            return Err(Error::InvalidParameter {
                name: "record_s".to_string(),
                requirement: "> 0",
                value: self.record_s,
            });
        }
        Ok(())
    }

    /// The expected answer: every effect with its parameters, the parameter errors, the noise.
    pub fn label(&self) -> Label {
        let mut effects: Vec<EffectLabel> = self
            .effects
            .iter()
            .map(|e| EffectLabel {
                name: e.name().to_string(),
                in_library: e.in_library(),
                params: e
                    .params()
                    .into_iter()
                    .map(|(k, v)| (k.to_string(), v))
                    .collect(),
            })
            .collect();
        if self.parameter_errors.any() {
            effects.push(EffectLabel {
                name: "parameter_error".to_string(),
                in_library: true,
                params: self
                    .parameter_errors
                    .entries()
                    .into_iter()
                    .filter(|e| e.1 != 0.0)
                    .map(|(k, v, _)| (k.to_string(), v))
                    .collect(),
            });
        }
        let inside = effects.iter().filter(|e| e.in_library).count();
        let class = match (inside, effects.len() - inside) {
            (0, 0) => LabelClass::Clean,
            (_, 0) => LabelClass::InLibrary,
            (0, _) => LabelClass::OutOfLibrary,
            _ => LabelClass::Mixed,
        };
        Label {
            class,
            effects,
            noise_sigma_x: self.noise.sigma_x,
            noise_sigma_f: self.noise.sigma_f,
        }
    }

    /// The same scenario without effects, parameter errors or noise: the nominal twin, used to
    /// measure how much the effects change the output.
    pub fn nominal_twin(&self) -> Scenario {
        Scenario {
            name: format!("{}-nominal", self.name),
            effects: Vec::new(),
            parameter_errors: ParameterErrors::default(),
            noise: Noise::default(),
            ..self.clone()
        }
    }
}
