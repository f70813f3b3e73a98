//! One entry point from a system and its limit cycle to its HTFs, choosing the method.

use htfid_hybrid::Options;
use htfid_ltp::{linearise, InputOutput, Linearisation};
use htfid_orbit::LimitCycle;
use num_complex::Complex64;

use crate::{ExactHtf, HarmonicTransferFunction, HtfGrid, OrbitHtf, TheoryError};

/// Samples of `A(t)` kept by the linearisation for inspection only: the piecewise model uses
/// Gauss-Legendre quadrature per chart, and fits build this object many times.
const LINEAR_SAMPLES: usize = 8;

/// How [`LinearisedHtf`] computes the HTFs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HtfMethod {
    /// `A, B, C, D` are constant within each mode: the closed-form exact HTF of the
    /// piecewise-LTI linearisation ([`ExactHtf`]), saltation jumps included.
    ExactPiecewise,
    /// The general case: the periodic response of the linearisation along the orbit, per
    /// input frequency ([`OrbitHtf`]), exact to the integrator's tolerance.
    PeriodicResponse,
}

impl HtfMethod {
    /// A stable name for result files.
    pub fn name(self) -> &'static str {
        match self {
            HtfMethod::ExactPiecewise => "exact_piecewise",
            HtfMethod::PeriodicResponse => "periodic_response",
        }
    }
}

#[derive(Debug)]
enum Inner<'a, S: InputOutput> {
    Exact {
        linearisation: Box<Linearisation<S::Mode>>,
        channels: Vec<ExactHtf>,
    },
    Orbit(OrbitHtf<'a, S>),
}

/// The HTFs of a system linearised about its limit cycle, every output, by the exact method
/// that applies: [`HtfMethod::ExactPiecewise`] when the system says its linearisation is
/// constant within each mode ([`InputOutput::is_piecewise_constant`]), otherwise
/// [`HtfMethod::PeriodicResponse`]. Both are exact up to the integrator's error.
#[derive(Debug)]
pub struct LinearisedHtf<'a, S: InputOutput> {
    inner: Inner<'a, S>,
    multipliers: Vec<Complex64>,
}

impl<'a, S: InputOutput> LinearisedHtf<'a, S> {
    /// Linearises `system` about `cycle` (computed with the input off) and prepares its HTFs.
    ///
    /// # Errors
    /// Linearisation and HTF construction errors ([`TheoryError`]).
    pub fn new(
        system: &'a S,
        cycle: &LimitCycle<S::Mode>,
        opts: &Options,
    ) -> Result<Self, TheoryError> {
        if system.is_piecewise_constant() {
            let linearisation = linearise(system, cycle, LINEAR_SAMPLES, opts)?;
            let lti = &linearisation.piecewise;
            let channels = (0..lti.n_outputs())
                .map(|o| ExactHtf::new(&lti.channel(o, 0)?))
                .collect::<Result<Vec<_>, TheoryError>>()?;
            let multipliers = channels
                .first()
                .map(|c| c.floquet_multipliers().to_vec())
                .unwrap_or_default();
            Ok(Self {
                inner: Inner::Exact {
                    linearisation: Box::new(linearisation),
                    channels,
                },
                multipliers,
            })
        } else {
            let orbit = OrbitHtf::new(system, cycle, opts)?;
            let multipliers = orbit.floquet_multipliers().to_vec();
            Ok(Self {
                inner: Inner::Orbit(orbit),
                multipliers,
            })
        }
    }

    /// The method in use.
    pub fn method(&self) -> HtfMethod {
        match self.inner {
            Inner::Exact { .. } => HtfMethod::ExactPiecewise,
            Inner::Orbit(_) => HtfMethod::PeriodicResponse,
        }
    }

    /// The piecewise-LTI linearisation, when that method is in use.
    pub fn linearisation(&self) -> Option<&Linearisation<S::Mode>> {
        match &self.inner {
            Inner::Exact { linearisation, .. } => Some(linearisation),
            Inner::Orbit(_) => None,
        }
    }

    /// The periodic-response HTFs (every output), when that method is in use.
    pub fn orbit(&self) -> Option<&OrbitHtf<'a, S>> {
        match &self.inner {
            Inner::Exact { .. } => None,
            Inner::Orbit(orbit) => Some(orbit),
        }
    }

    /// Number of outputs.
    pub fn n_outputs(&self) -> usize {
        match &self.inner {
            Inner::Exact { channels, .. } => channels.len(),
            Inner::Orbit(o) => o.n_outputs(),
        }
    }

    /// Floquet multipliers of the linearisation, largest modulus first.
    pub fn floquet_multipliers(&self) -> &[Complex64] {
        &self.multipliers
    }

    /// `G_n(jw)` on `omegas x harmonics`, one grid per output.
    ///
    /// # Errors
    /// [`TheoryError::Integration`] when the periodic-response integration fails.
    pub fn grids(&self, harmonics: &[i32], omegas: &[f64]) -> Result<Vec<HtfGrid>, TheoryError> {
        match &self.inner {
            Inner::Exact { channels, .. } => {
                Ok(channels.iter().map(|c| c.grid(harmonics, omegas)).collect())
            }
            Inner::Orbit(o) => o.grids(harmonics, omegas),
        }
    }
}

impl<'a, S: InputOutput> LinearisedHtf<'a, S> {
    /// Output `output` as a [`HarmonicTransferFunction`] (for point evaluations and grids).
    ///
    /// # Errors
    /// [`TheoryError::OutputOutOfRange`].
    pub fn channel(&self, output: usize) -> Result<HtfChannel<'_, 'a, S>, TheoryError> {
        let n_outputs = self.n_outputs();
        if output >= n_outputs {
            return Err(TheoryError::OutputOutOfRange { output, n_outputs });
        }
        Ok(match &self.inner {
            Inner::Exact { channels, .. } => HtfChannel::Exact(&channels[output]),
            Inner::Orbit(o) => HtfChannel::Orbit(Box::new(o.channel(output)?)),
        })
    }
}

/// One output of a [`LinearisedHtf`].
#[derive(Debug)]
pub enum HtfChannel<'h, 'a, S: InputOutput> {
    /// The closed-form exact HTF of one output.
    Exact(&'h ExactHtf),
    /// The periodic-response HTF with this output selected.
    Orbit(Box<OrbitHtf<'a, S>>),
}

impl<S: InputOutput> HarmonicTransferFunction for HtfChannel<'_, '_, S> {
    fn pumping_frequency(&self) -> f64 {
        match self {
            HtfChannel::Exact(e) => e.pumping_frequency(),
            HtfChannel::Orbit(o) => o.pumping_frequency(),
        }
    }

    fn g(&self, n: i32, w: f64) -> Complex64 {
        match self {
            HtfChannel::Exact(e) => e.g(n, w),
            HtfChannel::Orbit(o) => o.g(n, w),
        }
    }

    fn values(&self, points: &[(i32, f64)]) -> Vec<Complex64> {
        match self {
            HtfChannel::Exact(e) => e.values(points),
            HtfChannel::Orbit(o) => o.values(points),
        }
    }

    fn grid(&self, harmonics: &[i32], omegas: &[f64]) -> HtfGrid {
        match self {
            HtfChannel::Exact(e) => e.grid(harmonics, omegas),
            HtfChannel::Orbit(o) => o.grid(harmonics, omegas),
        }
    }
}
