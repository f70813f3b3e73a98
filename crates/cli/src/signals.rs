//! Builds the configured excitation as a signal of absolute time.

use std::sync::Arc;

use anyhow::{Context, Result};
use htfid_excite::{
    design_htf_multisine, Amplitude, Design, DesignSpec, EvenOrder, ExciteError, LinearChirp,
    LogChirp, PaperChirp, PhaseRule, PhaseShiftedTrain, Segment, Signal, TrainLayout,
};
use htfid_model::InputFn;

use crate::settings::{EvenOrderSetting, Excitation, PhaseSetting, Settings, Waveform};

/// The excitation of an experiment: the input signal and where its parts lie in time.
pub struct Built {
    pub signal: Option<Arc<dyn Signal>>,
    /// Phase-shifted segments (chirp trains), absolute times.
    pub segments: Vec<Segment>,
    /// End of the excitation (absolute time, s).
    pub end: f64,
    /// The multisine design, when the excitation is one.
    pub design: Option<Design>,
}

impl Built {
    /// The input as a model input function.
    pub fn input_fn(&self) -> Option<InputFn> {
        self.signal.clone().map(|s| {
            let f: InputFn = Arc::new(move |t| s.value(t));
            f
        })
    }
}

pub fn build(settings: &Settings) -> Result<Built> {
    let start = settings.settle_time();
    match &settings.excitation {
        Excitation::None => Ok(Built {
            signal: None,
            segments: Vec::new(),
            end: start,
            design: None,
        }),
        Excitation::MultisineDesign { .. } => {
            let spec = design_spec(settings).context("a multisine excitation has a design spec")?;
            let design = design_htf_multisine(spec).map_err(|e| design_error(settings, e))?;
            Ok(Built {
                signal: Some(Arc::new(design.input())),
                segments: Vec::new(),
                end: design.record_end(),
                design: Some(design),
            })
        }
        Excitation::ChirpTrain {
            waveform,
            f_start_hz,
            f_end_hz,
            duration,
            amplitude,
            copies,
        } => {
            let base: Box<dyn Signal> = match waveform {
                Waveform::Paper => Box::new(PaperChirp),
                Waveform::Linear => Box::new(
                    LinearChirp::new(*f_start_hz, *f_end_hz, *duration, *amplitude)
                        .context("excitation: invalid linear chirp")?,
                ),
                Waveform::Log => Box::new(
                    LogChirp::new(*f_start_hz, *f_end_hz, *duration, *amplitude)
                        .context("excitation: invalid log chirp")?,
                ),
            };
            let train = PhaseShiftedTrain::new(
                base,
                TrainLayout {
                    duration: *duration,
                    copies: *copies,
                    period: settings.period,
                    start,
                    min_gap: 0.0,
                },
            )
            .context("excitation: invalid chirp train")?;
            let segments = train.segments();
            let end = train.end();
            Ok(Built {
                signal: Some(Arc::new(train)),
                segments,
                end,
                design: None,
            })
        }
    }
}

/// The design spec of a multisine excitation, `None` for other excitations.
pub fn design_spec(settings: &Settings) -> Option<DesignSpec> {
    let Excitation::MultisineDesign {
        max_harmonic,
        omega_min,
        omega_max,
        spacing,
        amplitude,
        even_order,
        phases,
        settle,
        max_record,
    } = &settings.excitation
    else {
        return None;
    };
    Some(DesignSpec {
        period: settings.period,
        max_harmonic: *max_harmonic,
        omega_lo: *omega_min,
        omega_hi: *omega_max,
        spacing: *spacing,
        amplitude: Amplitude::Peak(*amplitude),
        phases: match phases {
            PhaseSetting::Schroeder => PhaseRule::Schroeder,
            PhaseSetting::Random(seed) => PhaseRule::Random { seed: *seed },
        },
        even_order: match even_order {
            EvenOrderSetting::SignReversal => EvenOrder::SignReversal,
            EvenOrderSetting::QuadraticGuard => EvenOrder::QuadraticGuard,
            EvenOrderSetting::Unprotected => EvenOrder::Unprotected,
        },
        settle: *settle,
        start: settings.settle_time(),
        max_record: *max_record,
    })
}

/// A design failure located at the key that decides it: the record budget, or the spacing
/// that the search could not meet.
fn design_error(settings: &Settings, e: ExciteError) -> anyhow::Error {
    let path = settings.path.display();
    match &e {
        ExciteError::RecordTooLong { .. } => anyhow::anyhow!(
            "{path}: excitation.max_record: {e}; raise excitation.max_record, or widen \
             excitation.spacing or narrow the band"
        ),
        ExciteError::NoDesign { .. } => anyhow::anyhow!(
            "{path}: excitation.spacing: {e}; widen excitation.spacing, or narrow the band \
             (excitation.omega_min, omega_max) or lower excitation.max_harmonic"
        ),
        _ => anyhow::anyhow!("{path}: [excitation] multisine design: {e}"),
    }
}
