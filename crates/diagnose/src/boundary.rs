//! Effects on the boundary of any model: on its input (an offset, a delay, a first-order lag
//! of the actuator) and on its measured outputs (an offset and a gain, a first-order lag of
//! the sensor). They need nothing of the model's equations, so they apply to every model
//! written in the model language.

use std::sync::Arc;

use htfid_lang::InputFn;
use serde::{Deserialize, Serialize};

use crate::interp::{LaggedSignal, SampledSignal};
use crate::sensor::Sensor;

/// A candidate effect on a model's input or outputs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BoundaryEffect {
    /// The applied input is the recorded one plus a constant `input_offset`.
    InputOffset,
    /// The applied input is the recorded one `delay` seconds earlier.
    InputDelay,
    /// The applied input is the recorded one through a first-order lag `tau a' = u - a`.
    ActuatorLag,
    /// Each recorded output is `b + g y` of the model's output `y` (one `b_<output>` and one
    /// `g_<output>` per output).
    SensorOffsetGain,
    /// Each recorded output is the model's output through a first-order lag
    /// `tau_s s' = y - s` (one time constant for all outputs).
    SensorLag,
}

impl BoundaryEffect {
    /// Every boundary effect, in the order they are tried.
    pub const ALL: [BoundaryEffect; 5] = [
        BoundaryEffect::InputOffset,
        BoundaryEffect::InputDelay,
        BoundaryEffect::ActuatorLag,
        BoundaryEffect::SensorOffsetGain,
        BoundaryEffect::SensorLag,
    ];

    /// The name used in results and configs.
    pub fn name(self) -> &'static str {
        match self {
            BoundaryEffect::InputOffset => "input_offset",
            BoundaryEffect::InputDelay => "input_delay",
            BoundaryEffect::ActuatorLag => "actuator_lag",
            BoundaryEffect::SensorOffsetGain => "sensor_offset_gain",
            BoundaryEffect::SensorLag => "sensor_lag",
        }
    }

    /// The effect of this name, if any.
    pub fn from_name(name: &str) -> Option<BoundaryEffect> {
        BoundaryEffect::ALL.into_iter().find(|e| e.name() == name)
    }

    /// Names of the effect's parameters for a model with these outputs.
    pub fn parameter_names(self, outputs: &[String]) -> Vec<String> {
        match self {
            BoundaryEffect::InputOffset => vec!["input_offset".into()],
            BoundaryEffect::InputDelay => vec!["delay".into()],
            BoundaryEffect::ActuatorLag => vec!["tau".into()],
            BoundaryEffect::SensorLag => vec!["tau_s".into()],
            BoundaryEffect::SensorOffsetGain => outputs
                .iter()
                .flat_map(|o| [format!("b_{o}"), format!("g_{o}")])
                .collect(),
        }
    }

    /// How many parameters the effect has for a model with `outputs` outputs.
    pub(crate) fn parameter_count(self, outputs: usize) -> usize {
        match self {
            BoundaryEffect::SensorOffsetGain => 2 * outputs,
            _ => 1,
        }
    }

    /// Whether the parameters are time constants or delays (`>= 0`, searched across decades).
    pub(crate) fn is_lag(self) -> bool {
        matches!(
            self,
            BoundaryEffect::InputDelay | BoundaryEffect::ActuatorLag | BoundaryEffect::SensorLag
        )
    }

    /// The values that leave the model unchanged (the start of an offset and gain; a lag's
    /// start is searched).
    pub(crate) fn neutral(self, outputs: usize) -> Vec<f64> {
        match self {
            BoundaryEffect::SensorOffsetGain => (0..outputs).flat_map(|_| [0.0, 1.0]).collect(),
            _ => vec![0.0],
        }
    }
}

/// The experiment that would tell rival boundary effects (by name) apart.
pub fn separating_experiment(rivals: &[String]) -> String {
    let has = |n: &str| rivals.iter().any(|r| r == n);
    let input_side = has("input_delay") || has("actuator_lag") || has("input_offset");
    let output_side = has("sensor_lag") || has("sensor_offset_gain");
    let mut ways = Vec::new();
    if input_side && output_side {
        ways.push(
            "measuring the applied input itself (the actuator's output) or the output with a \
             second sensor separates the input side from the output side",
        );
    }
    if has("input_delay") && (has("actuator_lag") || has("sensor_lag")) {
        ways.push(
            "an input with power over a wider band separates a delay from a lag: a lag's phase \
             saturates at 90 degrees while a delay's grows with frequency",
        );
    }
    if ways.is_empty() {
        ways.push("a larger or broader excitation, so that their responses differ above the noise");
    }
    ways.join("; ")
}

/// The boundary of a model: what happens between the recorded input and the model's input,
/// and between the model's outputs and the recorded ones. The default changes nothing.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Boundary {
    pub offset: f64,
    pub delay: f64,
    pub tau: f64,
    /// One per output; empty for ideal sensors.
    pub sensors: Vec<Sensor>,
}

impl Boundary {
    /// The boundary with `effect`'s parameters `p` (in [`BoundaryEffect::parameter_names`]
    /// order) for a model with `outputs` outputs.
    pub(crate) fn with(effect: BoundaryEffect, p: &[f64], outputs: usize) -> Boundary {
        let mut b = Boundary::default();
        match effect {
            BoundaryEffect::InputOffset => b.offset = p[0],
            BoundaryEffect::InputDelay => b.delay = p[0],
            BoundaryEffect::ActuatorLag => b.tau = p[0],
            BoundaryEffect::SensorLag => {
                b.sensors = vec![
                    Sensor {
                        tau_s: p[0],
                        ..Sensor::default()
                    };
                    outputs
                ];
            }
            BoundaryEffect::SensorOffsetGain => {
                b.sensors = p
                    .chunks(2)
                    .take(outputs)
                    .map(|bg| Sensor {
                        tau_s: 0.0,
                        b: bg[0],
                        g: bg[1],
                    })
                    .collect();
            }
        }
        b
    }

    /// The boundary with several effects at once, their parameters one after another in
    /// `effects`' order (each in [`BoundaryEffect::parameter_names`] order). A sensor's lag
    /// and its offset and gain combine in one [`Sensor`] per output.
    pub(crate) fn with_all(effects: &[BoundaryEffect], p: &[f64], outputs: usize) -> Boundary {
        let mut b = Boundary::default();
        let mut at = 0;
        for &effect in effects {
            let n = effect.parameter_count(outputs);
            let one = Boundary::with(effect, &p[at..at + n], outputs);
            at += n;
            match effect {
                BoundaryEffect::InputOffset => b.offset = one.offset,
                BoundaryEffect::InputDelay => b.delay = one.delay,
                BoundaryEffect::ActuatorLag => b.tau = one.tau,
                BoundaryEffect::SensorLag | BoundaryEffect::SensorOffsetGain => {
                    b.sensors.resize(outputs, Sensor::default());
                    for (mine, theirs) in b.sensors.iter_mut().zip(&one.sensors) {
                        if effect == BoundaryEffect::SensorLag {
                            mine.tau_s = theirs.tau_s;
                        } else {
                            mine.b = theirs.b;
                            mine.g = theirs.g;
                        }
                    }
                }
            }
        }
        b
    }

    /// The applied input: the recorded one read by `signal`, lagged, delayed and offset.
    pub(crate) fn input(&self, signal: &Arc<SampledSignal>) -> InputFn {
        let (offset, delay) = (self.offset, self.delay);
        if self.tau > 0.0 {
            let lagged = LaggedSignal::new(Arc::clone(signal), self.tau);
            Arc::new(move |t| lagged.eval(t - delay) + offset)
        } else {
            let signal = Arc::clone(signal);
            Arc::new(move |t| signal.eval(t - delay) + offset)
        }
    }

    /// The derivative of the applied input ([`Boundary::input`]) by the input side's
    /// parameter `effect` (an offset, a delay or a lag), as a function of time: 1 for the
    /// offset, `-F'(t - delay)` for the delay and `dF/dtau (t - delay)` for the lag, `F` the
    /// recorded input read between samples and lagged (`-f'` at `tau = 0`, the derivative
    /// from above); `None` for the sensors' effects.
    pub(crate) fn input_direction(
        &self,
        effect: BoundaryEffect,
        signal: &Arc<SampledSignal>,
    ) -> Option<InputFn> {
        let delay = self.delay;
        let lagged =
            (self.tau > 0.0).then(|| Arc::new(LaggedSignal::new(Arc::clone(signal), self.tau)));
        let signal = Arc::clone(signal);
        Some(match effect {
            BoundaryEffect::InputOffset => Arc::new(|_| 1.0),
            BoundaryEffect::InputDelay => match lagged {
                Some(l) => Arc::new(move |t| -l.rate(t - delay)),
                None => Arc::new(move |t| -signal.rate(t - delay)),
            },
            BoundaryEffect::ActuatorLag => match lagged {
                Some(l) => Arc::new(move |t| l.tau_derivative(t - delay)),
                None => Arc::new(move |t| -signal.rate(t - delay)),
            },
            BoundaryEffect::SensorOffsetGain | BoundaryEffect::SensorLag => return None,
        })
    }

    /// Turns the model's outputs (sampled `dt` apart) into the recorded ones, in place.
    pub(crate) fn outputs(&self, dt: f64, y: &mut [Vec<f64>]) {
        for (column, sensor) in y.iter_mut().zip(&self.sensors) {
            sensor.apply(dt, column);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::interp::Interpolation;

    #[test]
    fn rivals_get_the_experiment_that_separates_them() {
        let names = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        let both = separating_experiment(&names(&["sensor_lag", "actuator_lag"]));
        assert!(
            both.contains("second sensor") && !both.contains("delay"),
            "{both}"
        );
        let three = separating_experiment(&names(&["sensor_lag", "actuator_lag", "input_delay"]));
        assert!(
            three.contains("second sensor") && three.contains("saturates"),
            "{three}"
        );
        let inputs = separating_experiment(&names(&["actuator_lag", "input_delay"]));
        assert!(
            !inputs.contains("second sensor") && inputs.contains("saturates"),
            "{inputs}"
        );
    }

    #[test]
    fn names_round_trip_and_parameters_follow_the_outputs() {
        for e in BoundaryEffect::ALL {
            assert_eq!(BoundaryEffect::from_name(e.name()), Some(e));
        }
        let outputs = ["x1".to_string(), "x2".to_string()];
        assert_eq!(
            BoundaryEffect::SensorOffsetGain.parameter_names(&outputs),
            ["b_x1", "g_x1", "b_x2", "g_x2"]
        );
        assert_eq!(
            BoundaryEffect::SensorOffsetGain.neutral(2),
            [0.0, 1.0, 0.0, 1.0]
        );
    }

    #[test]
    fn the_input_is_offset_and_delayed_as_written() {
        // A ramp u = t sampled at 10 Hz: the spline reproduces it exactly, so the applied
        // input is t - delay + offset to rounding.
        let values: Vec<f64> = (0..100).map(|i| 0.1 * f64::from(i)).collect();
        let signal = Arc::new(SampledSignal::new(
            0.0,
            0.1,
            &values,
            Interpolation::CubicSpline,
        ));
        let b = Boundary::with(BoundaryEffect::InputDelay, &[0.25], 1);
        let u = b.input(&signal);
        assert!((u(5.0) - 4.75).abs() < 1e-12, "{}", u(5.0));
        let b = Boundary::with(BoundaryEffect::InputOffset, &[-2.0], 1);
        let u = b.input(&signal);
        assert!((u(5.0) - 3.0).abs() < 1e-12, "{}", u(5.0));
    }

    #[test]
    fn a_lagged_ramp_trails_by_the_time_constant() {
        // tau a' = t - a from a(0) = 0: a = t - tau (1 - exp(-t / tau)); after 20 tau the ramp
        // is followed at a distance tau to 2e-9 relative.
        let values: Vec<f64> = (0..200).map(|i| 0.01 * f64::from(i)).collect();
        let signal = Arc::new(SampledSignal::new(
            0.0,
            0.01,
            &values,
            Interpolation::CubicSpline,
        ));
        let tau = 0.05;
        let u = Boundary::with(BoundaryEffect::ActuatorLag, &[tau], 1).input(&signal);
        for t in [0.3, 1.0, 1.9] {
            let exact = t - tau * (1.0 - (-t / tau).exp());
            assert!((u(t) - exact).abs() < 1e-9, "t = {t}: {} vs {exact}", u(t));
        }
    }
}
