//! Extending a model with terms: the extended model must be the model one would write by
//! hand with the terms in place. The hand-written file is the independent route (its own
//! parse and resolution); the two are compared on vector fields, exact Jacobians, guards and
//! guard gradients at scattered points, and on the limit cycle.

use std::path::Path;

use htfid_hybrid::{HybridSystem, Options};
use htfid_lang::{Extension, Model, Parameter, Site};
use htfid_orbit::ShootingOptions;

fn hopper() -> Model {
    Model::from_file(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/hopper.toml"))
        .unwrap()
}

fn parameter(name: &str, value: f64) -> Parameter {
    Parameter {
        name: name.into(),
        value,
        unit: None,
        min: f64::NEG_INFINITY,
        max: f64::INFINITY,
        free: true,
    }
}

/// The hopper file with quadratic drag in both modes, extra damping in mode `free`, a cubic
/// spring written through the definition `spring`, and the switching surface moved to
/// `v = v_th`, written out by hand.
fn by_hand() -> Model {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/hopper.toml"),
    )
    .unwrap();
    let text = text
        .replace(
            "x0 = { value = 0.2,   unit = \"m\" }",
            "x0 = { value = 0.2,   unit = \"m\" }\nd2 = 0.7\nk3 = 900.0\ncf = 0.4\nv_th = 0.01",
        )
        .replace(
            "v = \"(-m*g + spring + f0 + u) / m\"",
            "v = \"(-m*g + spring + f0 + u) / m - d2*abs(v)*v - k3*(x - x0)^3 - cf*v\"",
        )
        .replace(
            "v = \"(-m*g + spring - c*v + f0 + u) / m\"",
            "v = \"(-m*g + spring - c*v + f0 + u) / m - d2*abs(v)*v - k3*(x - x0)^3\"",
        )
        .replace("when = \"v\"", "when = \"v - v_th\"");
    Model::parse(&text).unwrap()
}

fn extended() -> Model {
    let flow = |mode: Option<&str>| Site::Flow {
        state: "v".into(),
        mode: mode.map(String::from),
    };
    let ext = Extension {
        parameters: vec![
            parameter("d2", 0.7),
            parameter("k3", 900.0),
            parameter("cf", 0.4),
            parameter("v_th", 0.01),
        ],
        terms: vec![
            (flow(None), "-d2*abs(v)*v".into()),
            // Through the model's definition: spring = -k*(x - x0).
            (flow(None), "-k3*(-spring/k)^3".into()),
            (flow(Some("free")), "-cf*v".into()),
            (
                Site::Guard {
                    name: "free->damped".into(),
                },
                "-v_th".into(),
            ),
            (
                Site::Guard {
                    name: "damped->free".into(),
                },
                "-v_th".into(),
            ),
        ],
    };
    hopper().with_extension(&ext).unwrap()
}

/// Relative agreement of two numbers: the two routes build differently shaped expression
/// trees, so they agree to rounding (a few ulps times the terms' size), well inside 1e-12.
fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * (1.0 + a.abs().max(b.abs()))
}

#[test]
fn an_extended_model_is_the_model_written_by_hand() {
    let (a, b) = (extended(), by_hand());
    assert_eq!(a.dim(), 2);
    for mode in ["free", "damped"] {
        let (ma, mb) = (a.mode(mode).unwrap(), b.mode(mode).unwrap());
        for i in 0..25 {
            let s = i as f64;
            let t = 0.37 * s;
            let x = [0.12 + 0.004 * s, -0.6 + 0.05 * s];
            let (mut fa, mut fb) = ([0.0; 2], [0.0; 2]);
            a.vector_field(ma, t, &x, &mut fa);
            b.vector_field(mb, t, &x, &mut fb);
            for j in 0..2 {
                assert!(close(fa[j], fb[j]), "{mode} f[{j}] at {x:?}: {fa:?} {fb:?}");
            }
            let (mut ja, mut jb) = ([0.0; 4], [0.0; 4]);
            assert!(a.jacobian(ma, t, &x, &mut ja) && b.jacobian(mb, t, &x, &mut jb));
            for j in 0..4 {
                assert!(close(ja[j], jb[j]), "{mode} J[{j}] at {x:?}: {ja:?} {jb:?}");
            }
            let (ga, gb) = (a.guard(ma, 0, t, &x), b.guard(mb, 0, t, &x));
            assert!(close(ga, gb), "{mode} guard at {x:?}: {ga} {gb}");
        }
    }
    let opts = Options::default();
    let shooting = ShootingOptions::default();
    let (ca, cb) = (
        a.limit_cycle(&shooting, &opts).unwrap(),
        b.limit_cycle(&shooting, &opts).unwrap(),
    );
    // Both orbits are solved to the shooting tolerance from the same start by the same
    // method; 1e-9 m leaves room for the integrator's tolerance, not for a different term.
    for j in 0..2 {
        assert!((ca.state0[j] - cb.state0[j]).abs() < 1e-9, "{ca:?} {cb:?}");
    }
    // The new parameters are parameters like any other.
    let changed = a.with_parameters(&[("d2", 0.0), ("k3", 0.0), ("cf", 0.0), ("v_th", 0.0)]);
    let plain = hopper();
    let (mut fa, mut fb) = ([0.0; 2], [0.0; 2]);
    let x = [0.18, 0.3];
    changed
        .unwrap()
        .vector_field(plain.mode("damped").unwrap(), 0.4, &x, &mut fa);
    plain.vector_field(plain.mode("damped").unwrap(), 0.4, &x, &mut fb);
    assert!(close(fa[1], fb[1]), "{fa:?} {fb:?}");
}

#[test]
fn a_bad_extension_names_the_term_and_what_is_wrong() {
    let m = hopper();
    let cases: [(Extension, &str); 5] = [
        (
            Extension {
                parameters: vec![parameter("k", 1.0)],
                terms: vec![],
            },
            "parameters.k: `k` is already a name of the model",
        ),
        (
            Extension {
                parameters: vec![],
                terms: vec![(
                    Site::Flow {
                        state: "w".into(),
                        mode: None,
                    },
                    "v".into(),
                )],
            },
            "terms[0]: `w` is not a state",
        ),
        (
            Extension {
                parameters: vec![],
                terms: vec![(
                    Site::Flow {
                        state: "v".into(),
                        mode: None,
                    },
                    "-d*v".into(),
                )],
            },
            "terms[0]: `-d*v`: unknown name `d`",
        ),
        (
            Extension {
                parameters: vec![],
                terms: vec![(
                    Site::Guard {
                        name: "touchdown".into(),
                    },
                    "1".into(),
                )],
            },
            "terms[0]: no guard `touchdown`",
        ),
        (
            Extension {
                parameters: vec![],
                terms: vec![(
                    Site::Flow {
                        state: "v".into(),
                        mode: Some("flight".into()),
                    },
                    "1".into(),
                )],
            },
            "terms[0]: no mode `flight`",
        ),
    ];
    for (ext, needle) in cases {
        let e = m.with_extension(&ext).unwrap_err().to_string();
        assert!(e.contains(needle), "{e}");
    }
}
