//! The built-in hopper's equations (`Rhythmic::equations`) against the hopper itself: two
//! separately written descriptions of one system, its Rust code and the model-language text
//! that the diagnosis reads, for every extra term the text writes. Each pair gives the same
//! limit cycle, Floquet multipliers and driven record.

use std::sync::Arc;

use htfid_experiment::{drive, Input, Rhythmic};
use htfid_hybrid::Options;
use htfid_lang::Model;
use htfid_model::{DamperLaw, Effects, HardStop, Hopper, HopperParams};
use htfid_orbit::ShootingOptions;

/// The hopper's limit cycle and its equations' (start state, multipliers), and each one's
/// record of 5 s driven by a 0.2 N sine at 9 rad/s from its orbit: the largest differences of
/// the start state, the multipliers and the record, over the record's spread.
fn compare(hopper: &Hopper) -> (f64, f64, f64) {
    let model: Model = hopper
        .equations()
        .expect("the hopper has equations")
        .expect("they read");
    let opts = Options::default();
    let shooting = ShootingOptions::default();
    let a = Rhythmic::limit_cycle(hopper, &shooting, &opts).unwrap();
    let b = Rhythmic::limit_cycle(&model, &shooting, &opts).unwrap();
    assert_eq!(a.state0.len(), b.state0.len());
    let state = a
        .state0
        .iter()
        .zip(&b.state0)
        .map(|(p, q)| (p - q).abs())
        .fold(0.0, f64::max);
    let mut ma = a.multipliers.clone();
    let mut mb = b.multipliers.clone();
    for m in [&mut ma, &mut mb] {
        m.sort_by(|p, q| p.re.total_cmp(&q.re).then(p.im.total_cmp(&q.im)));
    }
    let multipliers = ma
        .iter()
        .zip(&mb)
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, f64::max);
    let input: Input = Arc::new(|t| 0.2 * (9.0 * t).sin());
    let times: Vec<f64> = (0..500).map(|i| 0.01 * f64::from(i)).collect();
    let ra = drive(hopper, &a, Some(input.clone()), &times, &opts).unwrap();
    let rb = drive(&model, &b, Some(input), &times, &opts).unwrap();
    let (lo, hi) = ra.outputs[0]
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
            (l.min(v), h.max(v))
        });
    let record = ra.outputs[0]
        .iter()
        .zip(&rb.outputs[0])
        .map(|(p, q)| (p - q).abs())
        .fold(0.0, f64::max)
        / (hi - lo);
    (state, multipliers, record)
}

fn hopper(damper: DamperLaw, effects: Effects) -> Hopper {
    Hopper::with_effects(HopperParams::paper(), damper, effects).unwrap()
}

/// The nominal hopper, its damper switching or always on, and with every extra term the text
/// writes: a cubic spring, damping in the free mode, quadratic drag, an input offset, a moved
/// switch, an actuator lag (a third state), Coulomb friction of 0.02 N (its sign the chart's)
/// and a contact spring of 1000 N/m below 0.1445 m, which the driven record reaches (a kink in
/// the field that neither integrator locates). Both are integrated to a relative tolerance of
/// 1e-10 and shot to 1e-13: the start states agree to 1e-9 m (measured at most 5e-14), the
/// multipliers to 1e-8 (measured 3e-10) and the driven records to 1e-8 of their spread
/// (measured at most 3e-9, drag on the damper always on).
#[test]
fn the_hoppers_equations_give_its_orbit_and_its_record() {
    let cases = [
        ("nominal", hopper(DamperLaw::Switching, Effects::default())),
        (
            "damper always on",
            hopper(DamperLaw::AlwaysOn, Effects::default()),
        ),
        (
            "cubic spring, drag, damping in flight, input offset, moved switch",
            hopper(
                DamperLaw::Switching,
                Effects {
                    k3: 2.0e4,
                    c_f: 0.5,
                    c2: 3.0,
                    input_offset: 0.1,
                    v_th: 0.01,
                    ..Effects::default()
                },
            ),
        ),
        (
            "actuator lag",
            hopper(
                DamperLaw::Switching,
                Effects {
                    tau: 0.02,
                    ..Effects::default()
                },
            ),
        ),
        (
            "drag on the damper always on",
            hopper(
                DamperLaw::AlwaysOn,
                Effects {
                    c2: 3.0,
                    k3: 2.0e4,
                    ..Effects::default()
                },
            ),
        ),
        (
            "Coulomb friction",
            hopper(
                DamperLaw::Switching,
                Effects {
                    mu: 0.02,
                    ..Effects::default()
                },
            ),
        ),
        (
            "contact spring",
            hopper(
                DamperLaw::Switching,
                Effects {
                    hard_stop: Some(HardStop {
                        x_stop: 0.1445,
                        k_stop: 1000.0,
                    }),
                    ..Effects::default()
                },
            ),
        ),
    ];
    let mut report = Vec::new();
    for (name, h) in &cases {
        let (state, multipliers, record) = compare(h);
        report.push(format!(
            "{name}: state {state:.1e}, multipliers {multipliers:.1e}, record {record:.1e}"
        ));
        assert!(
            state < 1e-9 && multipliers < 1e-8 && record < 1e-8,
            "{}",
            report.join("\n")
        );
    }
    eprintln!("{}", report.join("\n"));
}

/// An input delay has no equation in the model language: the hopper with one has none, and
/// says so rather than giving the equations of another system.
#[test]
fn a_hopper_with_an_input_delay_has_no_equations() {
    let h = hopper(
        DamperLaw::Switching,
        Effects {
            delay: 0.01,
            ..Effects::default()
        },
    );
    assert!(h.equations().is_none());
    assert!(hopper(DamperLaw::Switching, Effects::default())
        .equations()
        .is_some());
}
