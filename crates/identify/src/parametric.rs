//! What a parametric fit needs of a model: its named parameters, and the same model with other
//! values and its input off, whose limit cycle the fit finds again at every trial.

use htfid_hybrid::Options;
use htfid_lang::Model;
use htfid_ltp::{InputOutput, Linearisation, PiecewiseTangent};
use htfid_model::{Hopper, HopperParams};
use htfid_orbit::LimitCycle;
use htfid_theory::OrbitHtf;
use num_complex::Complex64;

/// A rhythmic model with named parameters: every model-language [`Model`] and the built-in
/// [`Hopper`]. Rust users implement it (with [`InputOutput`]) to fit their own models with
/// [`fit_to_htf`](crate::fit_to_htf).
pub trait Parametric: InputOutput + Sized {
    /// The value of parameter `name` and its bounds `(min, max)`, or `None` when the model has
    /// no such parameter.
    fn parameter(&self, name: &str) -> Option<(f64, (f64, f64))>;

    /// The same model with the named parameters changed and its input off; an error names the
    /// parameter or the value it refuses.
    fn unforced_with(&self, changes: &[(&str, f64)]) -> Result<Self, String>;

    /// The period of its forcing, s.
    fn forcing_period(&self) -> Option<f64>;

    /// How the piecewise linearisation `lin` about `cycle` (of this model, input off) changes
    /// per unit change of each of `names`, exactly: every piece's matrices and jumps and the
    /// motion of every switch ([`PiecewiseTangent`]). With them [`fit_to_htf`](crate::fit_to_htf)
    /// takes its Jacobian from [`htfid_theory::ExactHtf::derivatives`] instead of differences.
    /// `None` (the default) when the model does not give them; an error when it should and
    /// cannot (the fit then stops with it).
    fn linearisation_tangents(
        &self,
        _names: &[&str],
        _cycle: &LimitCycle<Self::Mode>,
        _lin: &Linearisation<Self::Mode>,
        _opts: &Options,
    ) -> Option<Result<Vec<PiecewiseTangent>, String>> {
        None
    }

    /// The derivatives of the HTFs along the orbit (`htf`: this model about `cycle`, its input
    /// off, by the periodic-response method) along each of `names`, at `points[o]` of every
    /// output `o`: entry `[o][j][i]`, exact up to the integrator's tolerance (through
    /// [`OrbitHtf::derivatives`]). `None` (the default) when the model does not give them.
    fn orbit_derivatives(
        &self,
        _names: &[&str],
        _cycle: &LimitCycle<Self::Mode>,
        _htf: &OrbitHtf<'_, Self>,
        _points: &[Vec<(i32, f64)>],
        _opts: &Options,
    ) -> Option<Result<Vec<Vec<Vec<Complex64>>>, String>> {
        None
    }
}

impl Parametric for Model {
    fn parameter(&self, name: &str) -> Option<(f64, (f64, f64))> {
        let i = self.parameter_index(name)?;
        let p = &self.parameters()[i];
        Some((self.values()[i], (p.min, p.max)))
    }

    fn unforced_with(&self, changes: &[(&str, f64)]) -> Result<Self, String> {
        self.with_parameters(changes)
            .map(|m| m.with_input(None))
            .map_err(|e| e.to_string())
    }

    fn forcing_period(&self) -> Option<f64> {
        self.period()
    }

    /// Exact wherever the model's linearisation is constant within each mode for every value
    /// of `names` ([`Model::piecewise_tangents`]).
    fn linearisation_tangents(
        &self,
        names: &[&str],
        cycle: &LimitCycle<Self::Mode>,
        lin: &Linearisation<Self::Mode>,
        opts: &Options,
    ) -> Option<Result<Vec<PiecewiseTangent>, String>> {
        self.piecewise_tangents(names, cycle, lin, opts)
            .map_err(|e| e.to_string())
            .transpose()
    }

    /// Exact unless one of `names` sets the forcing's period ([`Model::orbit_tangents`]).
    fn orbit_derivatives(
        &self,
        names: &[&str],
        cycle: &LimitCycle<Self::Mode>,
        htf: &OrbitHtf<'_, Self>,
        points: &[Vec<(i32, f64)>],
        opts: &Options,
    ) -> Option<Result<Vec<Vec<Vec<Complex64>>>, String>> {
        let tangents = match self.orbit_tangents(names, cycle, opts) {
            Ok(Some(tangents)) => tangents,
            Ok(None) => return None,
            Err(e) => return Some(Err(e.to_string())),
        };
        // One integration for every output: the outputs' points merged.
        let mut all: Vec<(i32, f64)> = points.iter().flatten().copied().collect();
        all.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
        all.dedup();
        let derivatives = match htf.derivatives(&tangents, &all) {
            Ok(d) => d,
            Err(e) => return Some(Err(e.to_string())),
        };
        let at = |point: &(i32, f64)| {
            all.binary_search_by(|a| a.0.cmp(&point.0).then(a.1.total_cmp(&point.1)))
                .unwrap_or_default()
        };
        Some(Ok(points
            .iter()
            .zip(&derivatives)
            .map(|(of_output, by_direction)| {
                by_direction
                    .iter()
                    .map(|column| of_output.iter().map(|pt| column[at(pt)]).collect())
                    .collect()
            })
            .collect()))
    }
}

/// The smallest mass and stiffness a fit may try: both must stay positive.
const POSITIVE: f64 = 1e-12;

/// The hopper's parameters by name: `m`, `k`, `c`, `g`, `x0`, `a` (forcing amplitude).
fn hopper_slot<'a>(p: &'a mut HopperParams, name: &str) -> Option<(&'a mut f64, (f64, f64))> {
    let inf = f64::INFINITY;
    Some(match name {
        "m" => (&mut p.m, (POSITIVE, inf)),
        "k" => (&mut p.k, (POSITIVE, inf)),
        "c" => (&mut p.c, (0.0, inf)),
        "g" => (&mut p.g, (-inf, inf)),
        "x0" => (&mut p.x0, (-inf, inf)),
        "a" => (&mut p.forcing_amplitude, (-inf, inf)),
        _ => return None,
    })
}

impl Parametric for Hopper {
    fn parameter(&self, name: &str) -> Option<(f64, (f64, f64))> {
        let mut p = *self.params();
        hopper_slot(&mut p, name).map(|(v, b)| (*v, b))
    }

    fn unforced_with(&self, changes: &[(&str, f64)]) -> Result<Self, String> {
        let mut p = *self.params();
        for &(name, v) in changes {
            let (slot, _) = hopper_slot(&mut p, name).ok_or_else(|| {
                format!("the hopper has no parameter {name}; parameters: m, k, c, g, x0, a")
            })?;
            *slot = v;
        }
        Hopper::with_effects(p, self.damper(), *self.effects()).map_err(|e| e.to_string())
    }

    fn forcing_period(&self) -> Option<f64> {
        Some(self.params().period)
    }

    /// Exact for the hopper without effects (`crate::hopper_tangent`): `m, k, c, g, x0, a`.
    fn linearisation_tangents(
        &self,
        names: &[&str],
        cycle: &LimitCycle<Self::Mode>,
        lin: &Linearisation<Self::Mode>,
        opts: &Options,
    ) -> Option<Result<Vec<PiecewiseTangent>, String>> {
        crate::hopper_tangent::tangents(self, names, cycle, lin, opts)
    }
}
