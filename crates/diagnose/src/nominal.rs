use htfid_model::{DamperLaw, Effects, Hopper, HopperParams};
use serde::{Deserialize, Serialize};

use crate::effect::Slot;
use crate::{DiagnoseError, NominalParam, Sensor};

/// The model the data are compared with: the hopper's parameters, damper law and any effects
/// already believed present, plus the parameters refitted in every fit (`free`).
///
/// The nominal fit refits `free` only; every candidate refits `free` too, so a candidate's
/// gain is never just the gain of refitting nominal parameters. The forcing amplitude is
/// ignored: the measured force is the total applied force.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NominalModel {
    /// Physical parameters (the starting point of every fit).
    pub params: HopperParams,
    /// When the damper acts.
    pub damper: DamperLaw,
    /// Extra terms already part of the nominal model (normally all absent).
    pub effects: Effects,
    /// The measurement chain believed present (normally the ideal sensor).
    #[serde(default)]
    pub sensor: Sensor,
    /// Parameters refitted alongside every candidate.
    pub free: Vec<NominalParam>,
}

impl NominalModel {
    /// A nominal model; checks the parameters, the effects and that `free` has no repeats.
    pub fn new(
        params: HopperParams,
        damper: DamperLaw,
        effects: Effects,
        free: Vec<NominalParam>,
    ) -> Result<Self, DiagnoseError> {
        let model = NominalModel {
            params,
            damper,
            effects,
            sensor: Sensor::default(),
            free,
        };
        model.validate()?;
        Ok(model)
    }

    /// The switching hopper with the given parameters and `k`, `c` refitted.
    pub fn hopper(params: HopperParams) -> Result<Self, DiagnoseError> {
        NominalModel::new(
            params,
            DamperLaw::Switching,
            Effects::default(),
            vec![NominalParam::K, NominalParam::C],
        )
    }

    /// A plain linear spring-mass-damper `m x'' + c x' + k x = f + input_offset` (damper always
    /// on, no gravity, rest length 0) with `m`, `c`, `k` and the input offset refitted.
    pub fn linear_spring_mass_damper(m: f64, k: f64, c: f64) -> Result<Self, DiagnoseError> {
        let params = HopperParams {
            m,
            k,
            c,
            g: 0.0,
            x0: 0.0,
            forcing_amplitude: 0.0,
            period: 1.0,
        };
        NominalModel::new(
            params,
            DamperLaw::AlwaysOn,
            Effects::default(),
            vec![
                NominalParam::M,
                NominalParam::C,
                NominalParam::K,
                NominalParam::InputOffset,
            ],
        )
    }

    /// Checks the parameters, the effects and that `free` has no repeats.
    pub fn validate(&self) -> Result<(), DiagnoseError> {
        Hopper::with_effects(self.params, self.damper, self.effects)?;
        for (i, p) in self.free.iter().enumerate() {
            if self.free[..i].contains(p) {
                return Err(DiagnoseError::DuplicateFree { name: p.name() });
            }
        }
        Ok(())
    }

    pub(crate) fn free_slots(&self) -> Vec<Slot> {
        self.free.iter().map(|p| p.slot()).collect()
    }

    /// Parameters as simulated on measured data: the forcing is in the measured force.
    pub(crate) fn measured_params(&self) -> HopperParams {
        HopperParams {
            forcing_amplitude: 0.0,
            ..self.params
        }
    }
}
