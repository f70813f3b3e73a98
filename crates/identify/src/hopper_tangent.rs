//! The built-in hopper's linearisation differentiated by its parameters, exactly.
//!
//! Without effects the hopper is `x' = v`, `m v' = F = -m g - c s v - k (x - x0) + a cos(wp t)`
//! (`s = 1` while the damper is on), linear within each chart, so `A_i`, `B`, `C`, `D` depend
//! on the parameters alone. Its switch `v = 0` has an identity saltation for every parameter
//! value (the damper's force `c v` vanishes there, so the field is continuous), so the jumps do
//! not change. What remains is how the switches move: a switch at `t_k` where `v(t_k) = 0`
//! moves by `dt_k = -v_p(t_k) / v'(t_k)`, with `(x_p, v_p)` the orbit's own sensitivity to the
//! parameter, the periodic solution of
//!
//! ```text
//! x_p' = v_p,   v_p' = -(k / m) x_p - (c s / m) v_p + dF/dp / m - F dm/dp / m^2,
//! ```
//!
//! continuous across the switch (identity saltation and a continuous field), found from one
//! period from zero and the monodromy: `(I - M) z(t0) = z_particular(t0 + T)`.

use htfid_hybrid::{simulate, Crossing, HybridSystem, Options};
use htfid_ltp::{Linearisation, PiecewiseTangent};
use htfid_model::{Effects, Hopper, HopperMode};
use htfid_orbit::LimitCycle;
use nalgebra::{DMatrix, DVector};

/// The hopper's parameters whose tangents are known, in the order of their columns.
const NAMES: [&str; 6] = ["m", "k", "c", "g", "x0", "a"];

/// The orbit of `hopper` with the sensitivities `(x_p, v_p)` of every parameter of `which`
/// beside it: state `[x, v, x_p0, v_p0, x_p1, v_p1, ...]`.
struct Sensitive<'a> {
    hopper: &'a Hopper,
    which: &'a [usize],
}

impl Sensitive<'_> {
    /// `(dF/dp) / m - F (dm/dp) / m^2` at `(t, x, v)` in chart `mode`, for parameter `p`
    /// (an index into [`NAMES`]): the forcing of the sensitivity equation.
    fn forcing(&self, p: usize, mode: HopperMode, t: f64, x: f64, v: f64) -> f64 {
        let q = self.hopper.params();
        let s = mode.switch();
        let force = -q.m * q.g - q.c * s * v - q.k * (x - q.x0) + self.hopper.forcing(t);
        match NAMES[p] {
            "m" => -q.g / q.m - force / (q.m * q.m),
            "k" => -(x - q.x0) / q.m,
            "c" => -s * v / q.m,
            "g" => -1.0,
            "x0" => q.k / q.m,
            "a" => htfid_trig::cos(q.pump_frequency() * t) / q.m,
            _ => unreachable!("NAMES lists every parameter"),
        }
    }
}

impl HybridSystem for Sensitive<'_> {
    type Mode = HopperMode;

    fn dim(&self) -> usize {
        2 + 2 * self.which.len()
    }

    fn vector_field(&self, mode: HopperMode, t: f64, z: &[f64], dz: &mut [f64]) {
        self.hopper.vector_field(mode, t, &z[..2], &mut dz[..2]);
        let q = self.hopper.params();
        let s = mode.switch();
        for (j, &p) in self.which.iter().enumerate() {
            let (xp, vp) = (z[2 + 2 * j], z[3 + 2 * j]);
            dz[2 + 2 * j] = vp;
            dz[3 + 2 * j] = (-q.k * xp - q.c * s * vp) / q.m + self.forcing(p, mode, t, z[0], z[1]);
        }
    }

    fn num_guards(&self, mode: HopperMode) -> usize {
        self.hopper.num_guards(mode)
    }

    fn guard(&self, mode: HopperMode, index: usize, t: f64, z: &[f64]) -> f64 {
        self.hopper.guard(mode, index, t, &z[..2])
    }

    fn guard_direction(&self, mode: HopperMode, index: usize) -> Crossing {
        self.hopper.guard_direction(mode, index)
    }

    fn transition(&self, mode: HopperMode, index: usize, t: f64, z: &mut [f64]) -> HopperMode {
        self.hopper.transition(mode, index, t, &mut z[..2])
    }
}

/// The tangents of the hopper's piecewise linearisation `lin` about `cycle` along each of
/// `names`: `None` when the hopper carries effects (its linearisation then depends on the
/// state within a chart, or its switch moves off `v = 0`) or a name is not one of
/// `m, k, c, g, x0, a`.
pub(crate) fn tangents(
    hopper: &Hopper,
    names: &[&str],
    cycle: &LimitCycle<HopperMode>,
    lin: &Linearisation<HopperMode>,
    opts: &Options,
) -> Option<Result<Vec<PiecewiseTangent>, String>> {
    if *hopper.effects() != Effects::default() {
        return None;
    }
    let which: Vec<usize> = names
        .iter()
        .map(|n| NAMES.iter().position(|m| m == n))
        .collect::<Option<_>>()?;
    Some(compute(hopper, &which, cycle, lin, opts))
}

fn compute(
    hopper: &Hopper,
    which: &[usize],
    cycle: &LimitCycle<HopperMode>,
    lin: &Linearisation<HopperMode>,
    opts: &Options,
) -> Result<Vec<PiecewiseTangent>, String> {
    let q = *hopper.params();
    let sys = Sensitive { hopper, which };
    let dim = sys.dim();
    let (t0, period) = (cycle.t0, cycle.period);
    let run = |z0: &[f64]| {
        simulate(&sys, cycle.mode0, t0, z0, t0 + period, &[], opts).map_err(|e| e.to_string())
    };
    // One period from the zero sensitivity, then the periodic one from the monodromy.
    let mut z0 = cycle.state0.clone();
    z0.resize(dim, 0.0);
    let particular = run(&z0)?;
    let m = &cycle.jacobian;
    let lhs = DMatrix::<f64>::identity(2, 2) - m;
    let lu = lhs.lu();
    for j in 0..which.len() {
        let end = &particular.final_state[2 + 2 * j..4 + 2 * j];
        let start = lu
            .solve(&DVector::from_column_slice(end))
            .ok_or("the orbit's monodromy has a multiplier of 1: its sensitivity is undefined")?;
        z0[2 + 2 * j] = start[0];
        z0[3 + 2 * j] = start[1];
    }
    let periodic = run(&z0)?;
    // Piece i opens at switch i (`Linearisation::piecewise`); each switch moves at
    // `-v_p / v'` there.
    let piecewise = &lin.piecewise;
    let n_pieces = piecewise.pieces().len();
    let mut dtau = vec![vec![0.0; n_pieces]; which.len()];
    for (i, switch) in lin.switches.iter().enumerate() {
        let opens = piecewise.boundaries().get(i).copied().unwrap_or(f64::NAN);
        let apart = (opens - switch.time).rem_euclid(period);
        if apart.min(period - apart) > 1e-9 * period {
            return Err(format!(
                "switch {i} at t = {} s opens no piece of the linearisation",
                switch.time
            ));
        }
        let event = periodic
            .events
            .iter()
            .min_by(|a, b| {
                (a.time - switch.time)
                    .abs()
                    .total_cmp(&(b.time - switch.time).abs())
            })
            .ok_or("the sensitivity's period has no switch where the orbit has one")?;
        let mut field = [0.0; 2];
        hopper.vector_field(event.from, event.time, &event.state[..2], &mut field);
        for (j, rates) in dtau.iter_mut().enumerate() {
            rates[i] = -event.state[3 + 2 * j] / field[1];
        }
    }
    let mut out = Vec::with_capacity(which.len());
    for (j, &p) in which.iter().enumerate() {
        let mut t = PiecewiseTangent::zero(piecewise);
        for (i, piece) in t.pieces_mut().iter_mut().enumerate() {
            // Whether the damper acts in this piece (an always-on damper's one chart is
            // `Damped`), as in the hopper's own field.
            let on = lin_mode(lin, i).switch();
            let mm = q.m * q.m;
            let (a, b) = match NAMES[p] {
                "m" => ([q.k / mm, q.c * on / mm], -1.0 / mm),
                "k" => ([-1.0 / q.m, 0.0], 0.0),
                "c" => ([0.0, -on / q.m], 0.0),
                _ => ([0.0, 0.0], 0.0),
            };
            piece.a = DMatrix::from_row_slice(2, 2, &[0.0, 0.0, a[0], a[1]]);
            piece.b = DMatrix::from_row_slice(2, 1, &[0.0, b]);
            piece.start = dtau[j][i];
        }
        out.push(t);
    }
    Ok(out)
}

/// The chart of piece `i` of the linearisation: the chart its opening switch leads to, or
/// the orbit's only chart when it has no switch.
fn lin_mode(lin: &Linearisation<HopperMode>, i: usize) -> HopperMode {
    lin.switches
        .get(i)
        .map(|s| s.to)
        .or_else(|| lin.samples.first().map(|s| s.mode))
        .unwrap_or(HopperMode::Damped)
}
