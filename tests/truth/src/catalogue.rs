//! A seeded catalogue of scenarios covering every effect, sign and size, compound pairs,
//! out-of-library effects and clean records.
//!
//! The catalogue is a fixed list of *cells* (what must be covered), each turned into a
//! scenario by seeded draws: the size is multiplied by a factor in [1, 1.3] (sizes are the
//! calibrated minimum, so the draw never makes an effect harder to see), the noise level is
//! drawn from those at most a fifth of the effect's calibrated output change, the sample rate
//! and the excitation are drawn (chirps 80 %, multisine 20 %). Cells are taken round-robin over
//! the four groups (single in-library effects, compound pairs, out-of-library effects, clean
//! records), so any prefix covers all groups; with `n >= CORE_CELLS` every cell is present
//! and the rest are random compound pairs.

use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::scenario::{Effect, Excitation, Noise, ParameterErrors, SampleRate, Scenario};

/// Noise levels on x, m.
pub const NOISE_LEVELS: [f64; 4] = [0.0, 1e-6, 2e-5, 1e-4];
/// An effect's output change must be at least this many noise standard deviations.
pub const MIN_SNR: f64 = 5.0;

/// Upper bound (exclusive) of drawn seeds: 2^53.
const JSON_SAFE_SEEDS: u64 = 1 << 53;

/// One thing the catalogue must cover.
#[derive(Clone, Debug)]
struct Cell {
    name: &'static str,
    effects: Vec<Effect>,
    errors: ParameterErrors,
    /// Calibrated RMS change of the measured x at the listed size (lower bound for the
    /// jittered sizes), m; for pairs, the smaller of the two. `None` for clean cells.
    est_rms: Option<f64>,
    /// Fixed noise and rate (clean cells), else drawn.
    fixed: Option<(f64, SampleRate, Excitation)>,
}

fn single(name: &'static str, e: Effect, est: f64) -> Cell {
    Cell {
        name,
        effects: vec![e],
        errors: ParameterErrors::default(),
        est_rms: Some(est),
        fixed: None,
    }
}

fn pair(name: &'static str, a: &Cell, b: &Cell) -> Cell {
    Cell {
        name,
        effects: a.effects.iter().chain(&b.effects).copied().collect(),
        errors: ParameterErrors {
            m: a.errors.m + b.errors.m,
            k: a.errors.k + b.errors.k,
            c: a.errors.c + b.errors.c,
            g: a.errors.g + b.errors.g,
            x0: a.errors.x0 + b.errors.x0,
        },
        est_rms: Some(a.est_rms.unwrap_or(0.0).min(b.est_rms.unwrap_or(0.0))),
        fixed: None,
    }
}

fn param(name: &'static str, errors: ParameterErrors, est: f64) -> Cell {
    Cell {
        name,
        effects: Vec::new(),
        errors,
        est_rms: Some(est),
        fixed: None,
    }
}

fn clean(name: &'static str, sigma: f64, rate: SampleRate, exc: Excitation) -> Cell {
    Cell {
        name,
        effects: Vec::new(),
        errors: ParameterErrors::default(),
        est_rms: None,
        fixed: Some((sigma, rate, exc)),
    }
}

/// The single in-library cells (sizes and calibrated output changes, see README).
fn in_library_cells() -> Vec<Cell> {
    use Effect::*;
    let pe = |f: fn(&mut ParameterErrors, f64), v: f64| {
        let mut e = ParameterErrors::default();
        f(&mut e, v);
        e
    };
    vec![
        single(
            "cubic_stiffness+small",
            CubicStiffness { k3: 200.0 },
            1.2e-4,
        ),
        single(
            "cubic_stiffness-small",
            CubicStiffness { k3: -200.0 },
            1.2e-4,
        ),
        single(
            "cubic_stiffness+large",
            CubicStiffness { k3: 2000.0 },
            1.2e-3,
        ),
        single(
            "cubic_stiffness-large",
            CubicStiffness { k3: -2000.0 },
            1.2e-3,
        ),
        single("coulomb_friction-small", CoulombFriction { mu: 0.01 }, 6e-5),
        single("coulomb_friction-large", CoulombFriction { mu: 0.1 }, 6e-4),
        single(
            "asymmetric_friction+small",
            AsymmetricFriction {
                mu_pos: 0.02,
                mu_neg: 0.005,
            },
            6e-5,
        ),
        single(
            "asymmetric_friction-small",
            AsymmetricFriction {
                mu_pos: 0.005,
                mu_neg: 0.02,
            },
            6e-5,
        ),
        single(
            "asymmetric_friction+large",
            AsymmetricFriction {
                mu_pos: 0.1,
                mu_neg: 0.03,
            },
            4e-4,
        ),
        single(
            "asymmetric_friction-large",
            AsymmetricFriction {
                mu_pos: 0.03,
                mu_neg: 0.1,
            },
            4e-4,
        ),
        single("flight_damping-small", FlightDamping { c_f: 0.1 }, 1.9e-5),
        single("flight_damping-large", FlightDamping { c_f: 1.0 }, 1.9e-4),
        single("quadratic_drag-small", QuadraticDrag { c2: 2.0 }, 1.4e-5),
        single("quadratic_drag-large", QuadraticDrag { c2: 20.0 }, 1.4e-4),
        single("actuator_lag-small", ActuatorLag { tau: 0.002 }, 5.5e-5),
        single("actuator_lag-large", ActuatorLag { tau: 0.02 }, 5.5e-4),
        single("input_delay-small", InputDelay { delay: 0.002 }, 5.5e-5),
        single("input_delay-large", InputDelay { delay: 0.02 }, 5.5e-4),
        single("input_offset+small", InputOffset { offset: 0.005 }, 2.5e-5),
        single("input_offset-small", InputOffset { offset: -0.005 }, 2.5e-5),
        single("input_offset+large", InputOffset { offset: 0.12 }, 6e-4),
        single("input_offset-large", InputOffset { offset: -0.12 }, 6e-4),
        single(
            "switch_threshold+small",
            SwitchThreshold { v_th: 0.005 },
            7e-6,
        ),
        single(
            "switch_threshold-small",
            SwitchThreshold { v_th: -0.005 },
            6.5e-6,
        ),
        single(
            "switch_threshold+large",
            SwitchThreshold { v_th: 0.03 },
            1.4e-4,
        ),
        single(
            "switch_threshold-large",
            SwitchThreshold { v_th: -0.03 },
            1.2e-4,
        ),
        single(
            "hard_stop-small",
            HardStop {
                k_stop: 1000.0,
                x_stop: 0.1452,
            },
            3e-5,
        ),
        single(
            "hard_stop-large",
            HardStop {
                k_stop: 5000.0,
                x_stop: 0.147,
            },
            2.9e-3,
        ),
        single("sensor_lag-small", SensorLag { tau_s: 0.001 }, 2.7e-5),
        single("sensor_lag-large", SensorLag { tau_s: 0.01 }, 2.7e-4),
        single(
            "sensor_offset+small",
            SensorOffsetGain { b: 2e-5, gain: 1.0 },
            2e-5,
        ),
        single(
            "sensor_offset-small",
            SensorOffsetGain {
                b: -2e-5,
                gain: 1.0,
            },
            2e-5,
        ),
        single(
            "sensor_offset+large",
            SensorOffsetGain { b: 5e-4, gain: 1.0 },
            5e-4,
        ),
        single(
            "sensor_offset-large",
            SensorOffsetGain {
                b: -5e-4,
                gain: 1.0,
            },
            5e-4,
        ),
        single(
            "sensor_gain-small",
            SensorOffsetGain {
                b: 0.0,
                gain: 0.998,
            },
            3e-4,
        ),
        single(
            "sensor_gain+offset-large",
            SensorOffsetGain {
                b: -5e-4,
                gain: 1.01,
            },
            1e-3,
        ),
        param("k+small", pe(|e, v| e.k = v, 0.03), 1.4e-3),
        param("k-small", pe(|e, v| e.k = v, -0.03), 1.4e-3),
        param("k+large", pe(|e, v| e.k = v, 0.1), 4.5e-3),
        param("k-large", pe(|e, v| e.k = v, -0.1), 4.5e-3),
        param("c+small", pe(|e, v| e.c = v, 0.03), 1e-5),
        param("c-small", pe(|e, v| e.c = v, -0.03), 1e-5),
        param("c+large", pe(|e, v| e.c = v, 0.1), 3.3e-5),
        param("c-large", pe(|e, v| e.c = v, -0.1), 3.3e-5),
        param("m+", pe(|e, v| e.m = v, 0.03), 1.4e-3),
        param("g-", pe(|e, v| e.g = v, -0.01), 4.9e-4),
        param("x0+", pe(|e, v| e.x0 = v, 0.005), 1e-3),
    ]
}

fn find(cells: &[Cell], name: &str) -> Cell {
    cells
        .iter()
        .find(|c| c.name == name)
        .cloned()
        .unwrap_or_else(|| panic!("catalogue cell {name} missing (internal table)"))
}

/// Compound pairs, chosen among the pairs a diagnosis is most likely to confuse.
fn pair_cells(lib: &[Cell]) -> Vec<Cell> {
    let p = |name, a: &str, b: &str| pair(name, &find(lib, a), &find(lib, b));
    vec![
        p(
            "sensor_lag+input_delay",
            "sensor_lag-large",
            "input_delay-large",
        ),
        p(
            "actuator_lag+input_offset",
            "actuator_lag-large",
            "input_offset-large",
        ),
        p(
            "switch_threshold+flight_damping",
            "switch_threshold+large",
            "flight_damping-large",
        ),
        p(
            "cubic_stiffness+coulomb_friction",
            "cubic_stiffness+large",
            "coulomb_friction-large",
        ),
        p(
            "hard_stop+quadratic_drag",
            "hard_stop-large",
            "quadratic_drag-large",
        ),
        p("sensor_gain+k", "sensor_gain+offset-large", "k+small"),
        p(
            "asymmetric_friction+input_offset",
            "asymmetric_friction+large",
            "input_offset+large",
        ),
        p("c+switch_threshold", "c+large", "switch_threshold-large"),
    ]
}

fn out_of_library_cells(lib: &[Cell]) -> Vec<Cell> {
    use Effect::*;
    let backlash_large = single("backlash-large", Backlash { gap: 0.1 }, 3e-4);
    let second_large = single(
        "second_mode-large",
        SecondMode {
            m2: 0.2,
            k2: 79.0,
            c2: 0.4,
        },
        2e-4,
    );
    vec![
        single("backlash-small", Backlash { gap: 0.02 }, 6e-5),
        backlash_large.clone(),
        single(
            "second_mode-small",
            SecondMode {
                m2: 0.1,
                k2: 98.7,
                c2: 0.31,
            },
            2e-5,
        ),
        second_large.clone(),
        single("pos_vel_force+small", PosVelForce { a: 10.0 }, 2e-5),
        single("pos_vel_force-small", PosVelForce { a: -10.0 }, 2e-5),
        single("pos_vel_force+large", PosVelForce { a: 100.0 }, 2e-4),
        single("pos_vel_force-large", PosVelForce { a: -100.0 }, 2e-4),
        single(
            "slow_forcing_amplitude-small",
            SlowForcingAmplitude {
                depth: 0.02,
                period: 100.0,
            },
            6e-5,
        ),
        single(
            "slow_forcing_amplitude-large",
            SlowForcingAmplitude {
                depth: 0.1,
                period: 100.0,
            },
            3e-4,
        ),
        pair(
            "backlash+cubic_stiffness",
            &backlash_large,
            &find(lib, "cubic_stiffness+large"),
        ),
        pair(
            "second_mode+coulomb_friction",
            &second_large,
            &find(lib, "coulomb_friction-large"),
        ),
    ]
}

fn clean_cells() -> Vec<Cell> {
    use SampleRate::*;
    let ch = Excitation::PaperChirps;
    vec![
        clean("clean-0-100", 0.0, Hz100, ch),
        clean("clean-1e-6-50", 1e-6, Hz50, ch),
        clean("clean-2e-5-200", 2e-5, Hz200, ch),
        clean("clean-1e-4-1000", 1e-4, Hz1000, ch),
        clean("clean-0-1000", 0.0, Hz1000, ch),
        clean("clean-1e-6-200", 1e-6, Hz200, ch),
        clean("clean-2e-5-100", 2e-5, Hz100, ch),
        clean("clean-1e-4-50", 1e-4, Hz50, ch),
        clean(
            "clean-multisine-2e-5-100",
            2e-5,
            Hz100,
            Excitation::Multisine { phase_seed: 11 },
        ),
        clean(
            "clean-multisine-0-200",
            0.0,
            Hz200,
            Excitation::Multisine { phase_seed: 12 },
        ),
    ]
}

/// The cells in round-robin order over the four groups.
fn core_cells() -> Vec<Cell> {
    let lib = in_library_cells();
    let groups = [
        lib.clone(),
        pair_cells(&lib),
        out_of_library_cells(&lib),
        clean_cells(),
    ];
    let longest = groups.iter().map(Vec::len).max().unwrap_or(0);
    let mut out = Vec::new();
    for i in 0..longest {
        for g in &groups {
            if let Some(c) = g.get(i) {
                out.push(c.clone());
            }
        }
    }
    out
}

/// Number of cells in the core catalogue: `catalogue(seed, n)` with `n` at least this covers
/// every cell.
pub fn core_size() -> usize {
    core_cells().len()
}

/// Scale an effect's size by `s` (sign kept; the hard stop's stiffness, the second mode's
/// damping and the modulation period are not scaled).
fn scaled(e: Effect, s: f64) -> Effect {
    use Effect::*;
    match e {
        CubicStiffness { k3 } => CubicStiffness { k3: k3 * s },
        CoulombFriction { mu } => CoulombFriction { mu: mu * s },
        AsymmetricFriction { mu_pos, mu_neg } => AsymmetricFriction {
            mu_pos: mu_pos * s,
            mu_neg: mu_neg * s,
        },
        FlightDamping { c_f } => FlightDamping { c_f: c_f * s },
        QuadraticDrag { c2 } => QuadraticDrag { c2: c2 * s },
        ActuatorLag { tau } => ActuatorLag { tau: tau * s },
        InputDelay { delay } => InputDelay { delay: delay * s },
        InputOffset { offset } => InputOffset { offset: offset * s },
        SwitchThreshold { v_th } => SwitchThreshold { v_th: v_th * s },
        HardStop { k_stop, x_stop } => HardStop {
            k_stop: k_stop * s,
            x_stop,
        },
        SensorLag { tau_s } => SensorLag { tau_s: tau_s * s },
        SensorOffsetGain { b, gain } => SensorOffsetGain {
            b: b * s,
            gain: 1.0 + (gain - 1.0) * s,
        },
        Backlash { gap } => Backlash { gap: gap * s },
        SecondMode { m2, k2, c2 } => SecondMode { m2, k2, c2 },
        PosVelForce { a } => PosVelForce { a: a * s },
        SlowForcingAmplitude { depth, period } => SlowForcingAmplitude {
            depth: depth * s,
            period,
        },
    }
}

fn realise(cell: &Cell, rng: &mut ChaCha8Rng, index: usize) -> Scenario {
    // Seeds below 2^53 survive JSON readers that parse numbers as doubles.
    let seed = rng.gen_range(0..JSON_SAFE_SEEDS);
    let (sigma, rate, excitation) = match cell.fixed {
        Some(f) => f,
        None => {
            let allowed: Vec<f64> = NOISE_LEVELS
                .iter()
                .copied()
                .filter(|&s| s > 0.0 && MIN_SNR * s <= cell.est_rms.unwrap_or(0.0))
                .collect();
            let sigma = if allowed.is_empty() || rng.gen_bool(0.1) {
                0.0
            } else {
                *allowed.choose(rng).unwrap_or(&0.0)
            };
            let rate = match rng.gen_range(0..20) {
                0..=2 => SampleRate::Hz50,
                3..=13 => SampleRate::Hz100,
                14..=17 => SampleRate::Hz200,
                _ => SampleRate::Hz1000,
            };
            let excitation = if rng.gen_bool(0.2) {
                Excitation::Multisine {
                    phase_seed: rng.gen_range(0..JSON_SAFE_SEEDS),
                }
            } else {
                Excitation::PaperChirps
            };
            (sigma, rate, excitation)
        }
    };
    let s = if cell.fixed.is_some() {
        1.0
    } else {
        rng.gen_range(1.0..1.3)
    };
    let e = &cell.errors;
    Scenario {
        name: format!("{index:03}-{}", cell.name),
        effects: cell.effects.iter().map(|&x| scaled(x, s)).collect(),
        parameter_errors: ParameterErrors {
            m: e.m * s,
            k: e.k * s,
            c: e.c * s,
            g: e.g * s,
            x0: e.x0 * s,
        },
        noise: Noise {
            sigma_x: sigma,
            sigma_f: 0.0,
        },
        sample_rate: rate,
        excitation,
        seed,
        ..Scenario::default()
    }
}

/// `n` scenarios drawn with `seed`; see the module docs for the composition.
pub fn catalogue(seed: u64, n: usize) -> Vec<Scenario> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let core = core_cells();
    let lib = in_library_cells();
    (0..n)
        .map(|i| match core.get(i) {
            Some(cell) => realise(cell, &mut rng, i),
            None => {
                // A random pair of different in-library effect kinds.
                let a = lib
                    .choose(&mut rng)
                    .cloned()
                    .unwrap_or_else(|| lib[0].clone());
                let b = loop {
                    let b = lib
                        .choose(&mut rng)
                        .cloned()
                        .unwrap_or_else(|| lib[1].clone());
                    if kind(&b) != kind(&a) {
                        break b;
                    }
                };
                let mut cell = pair("random-pair", &a, &b);
                cell.name = "random-pair";
                realise(&cell, &mut rng, i)
            }
        })
        .collect()
}

/// The effect kind of a single cell, for pairing: parameter errors are one kind (one label
/// entry), and the two frictions are one kind (they cannot be combined).
fn kind(c: &Cell) -> &'static str {
    match c.effects.first() {
        None => "parameter_error",
        Some(Effect::CoulombFriction { .. } | Effect::AsymmetricFriction { .. }) => "friction",
        Some(e) => e.name(),
    }
}
