//! Composition of the catalogue, and (ignored, ~30 s in release) that every effect changes
//! the output by at least five noise standard deviations.

use std::collections::BTreeSet;

use htfid_truth::{
    catalogue, core_size, effect_rms, Effect, Excitation, LabelClass, SampleRate, Scenario,
    MIN_SNR, NOISE_LEVELS,
};

fn has(cat: &[Scenario], pred: impl Fn(&Effect) -> bool) -> bool {
    cat.iter().any(|s| s.effects.iter().any(&pred))
}

#[test]
fn catalogue_is_deterministic_per_seed() {
    let n = core_size() + 5;
    assert_eq!(catalogue(7, n), catalogue(7, n));
    assert_ne!(catalogue(7, n), catalogue(8, n));
}

#[test]
fn core_catalogue_covers_every_cell() {
    let n = core_size();
    assert!(n >= 70, "{n}");
    let cat = catalogue(1, n);
    let names: BTreeSet<String> = cat
        .iter()
        .flat_map(|s| s.label().effects)
        .map(|e| e.name)
        .collect();
    for name in [
        "cubic_stiffness",
        "coulomb_friction",
        "asymmetric_friction",
        "flight_damping",
        "quadratic_drag",
        "actuator_lag",
        "input_delay",
        "input_offset",
        "switch_threshold",
        "hard_stop",
        "parameter_error",
        "sensor_lag",
        "sensor_offset_gain",
        "backlash",
        "second_mode",
        "pos_vel_force",
        "slow_forcing_amplitude",
    ] {
        assert!(names.contains(name), "{name} missing");
    }
    // Both signs where the sign matters.
    for sign in [1.0, -1.0] {
        assert!(has(
            &cat,
            |e| matches!(e, Effect::SwitchThreshold { v_th } if v_th * sign > 0.0)
        ));
        assert!(has(
            &cat,
            |e| matches!(e, Effect::InputOffset { offset } if offset * sign > 0.0)
        ));
        assert!(has(
            &cat,
            |e| matches!(e, Effect::SensorOffsetGain { b, .. } if b * sign > 0.0)
        ));
        assert!(cat.iter().any(|s| s.parameter_errors.k * sign > 0.0));
        assert!(cat.iter().any(|s| s.parameter_errors.c * sign > 0.0));
    }
    // Small and large sizes: a factor of ten between the extremes of each single effect.
    let spread = |f: &dyn Fn(&Effect) -> Option<f64>| {
        let v: Vec<f64> = cat
            .iter()
            .filter(|s| s.effects.len() == 1)
            .filter_map(|s| f(&s.effects[0]))
            .map(f64::abs)
            .collect();
        v.iter().copied().fold(0.0, f64::max) / v.iter().copied().fold(f64::INFINITY, f64::min)
    };
    assert!(
        spread(&|e| match e {
            Effect::CoulombFriction { mu } => Some(*mu),
            _ => None,
        }) > 5.0
    );
    assert!(
        spread(&|e| match e {
            Effect::ActuatorLag { tau } => Some(*tau),
            _ => None,
        }) > 5.0
    );
    // Classes, pairs, rates, noise levels, excitations.
    let classes: BTreeSet<String> = cat
        .iter()
        .map(|s| format!("{:?}", s.label().class))
        .collect();
    assert_eq!(classes.len(), 4, "{classes:?}");
    let pairs = cat
        .iter()
        .filter(|s| s.label().effects.len() == 2 && s.label().class == LabelClass::InLibrary)
        .count();
    assert!(pairs >= 8, "{pairs}");
    for rate in SampleRate::ALL {
        assert!(cat.iter().any(|s| s.sample_rate == rate), "{rate:?}");
        assert!(
            cat.iter()
                .any(|s| s.sample_rate == rate && s.label().class == LabelClass::Clean),
            "no clean record at {rate:?}"
        );
    }
    for sigma in NOISE_LEVELS {
        assert!(cat.iter().any(
            |s| (s.noise.sigma_x - sigma).abs() < 1e-15 && s.label().class == LabelClass::Clean
        ));
        assert!(cat.iter().any(
            |s| (s.noise.sigma_x - sigma).abs() < 1e-15 && s.label().class != LabelClass::Clean
        ));
    }
    assert!(cat
        .iter()
        .any(|s| matches!(s.excitation, Excitation::Multisine { .. })));
    for s in &cat {
        s.validate().unwrap();
    }
}

#[test]
fn any_prefix_covers_the_four_groups() {
    let cat = catalogue(3, 8);
    let classes: BTreeSet<String> = cat
        .iter()
        .map(|s| format!("{:?}", s.label().class))
        .collect();
    assert!(classes.len() >= 3, "{classes:?}");
    assert!(cat.iter().any(|s| s.label().class == LabelClass::Clean));
}

#[test]
fn draws_beyond_the_core_are_pairs_of_different_effects() {
    let n = core_size();
    for s in &catalogue(2, n + 200)[n..] {
        s.validate().unwrap();
        let l = s.label();
        assert_eq!(l.effects.len(), 2, "{}", s.name);
        assert_ne!(l.effects[0].name, l.effects[1].name);
    }
}

/// Every scenario's effects move the noise-free output by at least `MIN_SNR` noise standard
/// deviations (RMS over the record). Slow: run with
/// `cargo test --release -p htfid-truth --test catalogue -- --ignored`.
#[test]
#[ignore = "slow in debug builds (about 11 s in release): run with --release -- --ignored"]
fn every_effect_exceeds_five_sigma() {
    let cat = catalogue(1, core_size() + 10);
    let mut low = Vec::new();
    std::thread::scope(|scope| {
        let handles: Vec<_> = (0..2)
            .map(|w| {
                let cat = &cat;
                scope.spawn(move || {
                    let mut low = Vec::new();
                    for s in cat.iter().skip(w).step_by(2) {
                        if s.label().class == LabelClass::Clean {
                            continue;
                        }
                        let r = effect_rms(s).unwrap();
                        if r < MIN_SNR * s.noise.sigma_x || r < 5e-6 {
                            low.push(format!(
                                "{}: rms {r:e}, sigma {:e}",
                                s.name, s.noise.sigma_x
                            ));
                        }
                    }
                    low
                })
            })
            .collect();
        for h in handles {
            low.extend(h.join().unwrap());
        }
    });
    assert!(low.is_empty(), "{low:#?}");
}
