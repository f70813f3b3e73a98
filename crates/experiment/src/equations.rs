//! The built-in hopper's equations in the model language: what the diagnosis reads of a model
//! (it adds each candidate effect as a term to a named equation), written from the hopper's
//! parameters, damper law and extra terms.

use std::fmt::Write;

use htfid_lang::Model;
use htfid_model::{DamperLaw, Hopper, HopperMode};

use crate::ExperimentError;

/// The hopper `h` as a model-language model, input off, or `None` when one of its terms has no
/// equation in the language: an input delay (the language has no delayed arguments).
///
/// The text is `models/hopper.toml` with `h`'s values, and each extra term that is present
/// written into the equations with its own parameter (fixed): `k3` (a cubic spring about `x0`),
/// `mu` (Coulomb friction, its sign the chart's on the switching hopper and `sign(v)` on the
/// damper that is always on), `c_f` (damping in the free mode), `c2` (quadratic drag),
/// `k_stop` and `x_stop` (a contact spring below `x_stop`), `u0` (an input offset), `v_th` (the
/// damper's switch at `v = v_th`) and `tau` (an actuator lag, with its applied force as a third
/// state `F`). `k` and `c` are free, as in the shipped file.
pub(crate) fn hopper_equations(h: &Hopper) -> Option<Result<Model, ExperimentError>> {
    let p = h.params();
    let e = h.effects();
    if e.delay != 0.0 {
        return None;
    }
    let switching = h.damper() == DamperLaw::Switching;
    let lag = e.has_lag();
    let mut text = String::from(
        "name = \"hopper\"\n\
         description = \"the built-in hopper's equations\"\n",
    );
    let states = if lag {
        "[{ name = \"x\", unit = \"m\" }, { name = \"v\", unit = \"m/s\" }, { name = \"F\", unit = \"N\" }]"
    } else {
        "[{ name = \"x\", unit = \"m\" }, { name = \"v\", unit = \"m/s\" }]"
    };
    let _ = writeln!(text, "states = {states}\n\n[parameters]");
    let mut parameter = |name: &str, value: f64, unit: &str, extra: &str| {
        let _ = writeln!(
            text,
            "{name} = {{ value = {value:?}, unit = \"{unit}\"{extra} }}"
        );
    };
    parameter("m", p.m, "kg", ", min = 0.0");
    parameter("k", p.k, "N/m", ", min = 0.0, free = true");
    parameter("c", p.c, "N s/m", ", min = 0.0, free = true");
    parameter("g", p.g, "m/s^2", "");
    parameter("x0", p.x0, "m", "");
    parameter("a", p.forcing_amplitude, "N", "");
    parameter("T", p.period, "s", ", min = 0.0");
    // The extra terms, each present only when it acts.
    let mut force = String::from("-m*g - k*(x - x0)");
    if e.k3 != 0.0 {
        parameter("k3", e.k3, "N/m^3", "");
        force.push_str(" - k3*(x - x0)^3");
    }
    if e.c2 != 0.0 {
        parameter("c2", e.c2, "N s^2/m^2", "");
        force.push_str(" - c2*v*abs(v)");
    }
    if let Some(stop) = e.hard_stop {
        parameter("k_stop", stop.k_stop, "N/m", "");
        parameter("x_stop", stop.x_stop, "m", "");
        force.push_str(" + k_stop*max(0, x_stop - x)");
    }
    if e.mu != 0.0 {
        parameter("mu", e.mu, "N", "");
    }
    if e.c_f != 0.0 {
        parameter("c_f", e.c_f, "N s/m", "");
    }
    if e.v_th != 0.0 {
        parameter("v_th", e.v_th, "m/s", "");
    }
    if lag {
        parameter("tau", e.tau, "s", ", min = 0.0");
    }
    let commanded = if e.input_offset != 0.0 {
        parameter("u0", e.input_offset, "N", "");
        "f0 + u + u0"
    } else {
        "f0 + u"
    };
    let applied = if lag { "F" } else { commanded };
    text.push_str(
        "\n[input]\nname = \"u\"\nunit = \"N\"\n\n\
         [forcing]\nperiod = \"T\"\nsignals = { f0 = \"a * cos(2*pi*t/T)\" }\n\n\
         [flow]\nx = \"v\"\n",
    );
    if lag {
        let _ = writeln!(text, "F = \"({commanded} - F) / tau\"");
    }
    // The acceleration in each chart: `damped` with the damper on (s = 1), `free` without.
    let mode = |name: &str, on: bool| {
        let mut sum = force.clone();
        if on {
            sum.push_str(" - c*v");
        } else if e.c_f != 0.0 {
            sum.push_str(" - c_f*v");
        }
        if e.mu != 0.0 {
            sum.push_str(match (switching, on) {
                (false, _) => " - mu*sign(v)",
                (true, true) => " - mu",
                (true, false) => " + mu",
            });
        }
        format!("\n[modes.{name}]\nv = \"({sum} + {applied}) / m\"\n")
    };
    if switching {
        text.push_str(&mode("free", false));
        text.push_str(&mode("damped", true));
        let when = if e.v_th != 0.0 { "v - v_th" } else { "v" };
        for (from, to, direction) in [("free", "damped", "rising"), ("damped", "free", "falling")] {
            let _ = write!(
                text,
                "\n[[guards]]\nfrom = \"{from}\"\nto = \"{to}\"\nwhen = \"{when}\"\ndirection = \"{direction}\"\n"
            );
        }
    } else {
        text.push_str(&mode("damped", true));
    }
    text.push_str("\n[outputs]\nx = { expr = \"x\", unit = \"m\" }\n");
    let start = h.initial_guess();
    let name = match h.mode_of(start[1]) {
        HopperMode::Damped => "damped",
        HopperMode::Free => "free",
    };
    let _ = write!(
        text,
        "\n[initial]\nmode = \"{name}\"\nx = {:?}\nv = {:?}\n",
        start[0], start[1]
    );
    if lag {
        let _ = writeln!(text, "F = {:?}", start[2]);
    }
    Some(Model::parse(&text).map_err(ExperimentError::from))
}
