//! A Rust user's own model, written in code: a forced linear oscillator
//! `m x'' + c x' + k x = cos(2 pi t / PERIOD) + u`, measured at its position, with `k` and `c`
//! as named parameters. It implements every trait of the pipeline (`HybridSystem`,
//! `InputOutput`, `Parametric`, `Rhythmic`), and writes its equations in the model language for
//! the diagnosis when `written` (else it is a model of code alone). Shared by the tests of
//! `htfid-experiment` and `htfid-diagnose`.

use htfid_experiment::{ExperimentError, Input, Rhythmic};
use htfid_hybrid::{HybridSystem, Options};
use htfid_identify::Parametric;
use htfid_lang::Model;
use htfid_ltp::InputOutput;
use htfid_orbit::{find_limit_cycle, LimitCycle, ShootingOptions};

/// The forcing period, s.
pub const PERIOD: f64 = 2.0;

#[derive(Clone)]
pub struct Oscillator {
    pub m: f64,
    pub k: f64,
    pub c: f64,
    /// Whether [`Rhythmic::equations`] gives the model's equations.
    pub written: bool,
    /// The damping its equations say, where it differs from its code's `c`: a mistake in the
    /// equations, which the diagnosis must catch.
    pub miswritten_c: Option<f64>,
    pub input: Option<Input>,
}

impl Oscillator {
    /// The oscillator of mass `m`, stiffness `k` and damping `c`, undriven, of code alone.
    pub fn new(m: f64, k: f64, c: f64) -> Oscillator {
        Oscillator {
            m,
            k,
            c,
            written: false,
            miswritten_c: None,
            input: None,
        }
    }
}

impl std::fmt::Debug for Oscillator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Oscillator(m {}, k {}, c {})", self.m, self.k, self.c)
    }
}

impl HybridSystem for Oscillator {
    type Mode = ();
    fn dim(&self) -> usize {
        2
    }
    fn vector_field(&self, _: (), t: f64, x: &[f64], dxdt: &mut [f64]) {
        let u = self.input.as_ref().map_or(0.0, |u| u(t));
        let f = (2.0 * std::f64::consts::PI * t / PERIOD).cos() + u;
        dxdt[0] = x[1];
        dxdt[1] = (f - self.k * x[0] - self.c * x[1]) / self.m;
    }
}

impl InputOutput for Oscillator {
    fn input_gain(&self, _: (), _t: f64, _x: &[f64], b: &mut [f64]) {
        b[0] = 0.0;
        b[1] = 1.0 / self.m;
    }
    fn output_gain(&self, _: (), _t: f64, _x: &[f64], c: &mut [f64]) {
        c[0] = 1.0;
        c[1] = 0.0;
    }
    fn is_piecewise_constant(&self) -> bool {
        true
    }
}

impl Parametric for Oscillator {
    fn parameter(&self, name: &str) -> Option<(f64, (f64, f64))> {
        match name {
            "k" => Some((self.k, (1e-9, f64::INFINITY))),
            "c" => Some((self.c, (0.0, f64::INFINITY))),
            _ => None,
        }
    }
    fn unforced_with(&self, changes: &[(&str, f64)]) -> Result<Self, String> {
        let mut o = self.with_input(None);
        for &(name, v) in changes {
            match name {
                "k" => o.k = v,
                "c" => o.c = v,
                _ => return Err(format!("no parameter {name}")),
            }
        }
        Ok(o)
    }
    fn forcing_period(&self) -> Option<f64> {
        Some(PERIOD)
    }
}

impl Rhythmic for Oscillator {
    fn limit_cycle(
        &self,
        shooting: &ShootingOptions,
        integrator: &Options,
    ) -> Result<LimitCycle<()>, ExperimentError> {
        let free = self.with_input(None);
        Ok(find_limit_cycle(
            &free,
            (),
            0.0,
            &[0.0, 0.0],
            PERIOD,
            shooting,
            integrator,
        )?)
    }
    fn with_input(&self, input: Option<Input>) -> Self {
        Oscillator {
            input,
            ..self.clone()
        }
    }
    fn outputs(&self, _: (), _t: f64, x: &[f64], _u: f64, y: &mut [f64]) {
        y[0] = x[0];
    }
    /// The same equations as [`HybridSystem::vector_field`], in the model language, with this
    /// oscillator's values; `k` and `c` free.
    fn equations(&self) -> Option<Result<Model, ExperimentError>> {
        let (m, k, c) = (self.m, self.k, self.miswritten_c.unwrap_or(self.c));
        let text = format!(
            r#"
            name = "oscillator"
            states = ["x", "v"]
            [parameters]
            m = {{ value = {m:?}, min = 0.0 }}
            k = {{ value = {k:?}, min = 0.0, free = true }}
            c = {{ value = {c:?}, min = 0.0, free = true }}
            T = {PERIOD:?}
            [input]
            name = "u"
            [forcing]
            period = "T"
            signals = {{ f = "cos(2*pi*t/T)" }}
            [flow]
            x = "v"
            v = "(f + u - k*x - c*v) / m"
            [outputs]
            x = "x"
            [initial]
            x = 0.0
            v = 0.0
            "#
        );
        self.written
            .then(|| Model::parse(&text).map_err(ExperimentError::from))
    }
}
