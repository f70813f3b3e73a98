//! Exact parameter derivatives against central finite differences of the model itself
//! (recompiled with perturbed parameter values).

use std::path::Path;

use htfid_hybrid::HybridSystem;
use htfid_lang::Model;

fn load(name: &str) -> Model {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../models/{name}.toml"));
    Model::from_file(&path).unwrap()
}

/// Central differences with step `1e-6 max(1, |p|)`: truncation about `1e-12` relative, round-off
/// about `1e-10` relative for these magnitudes, so `1e-6` relative is a safe bound that a wrong
/// derivative (a missing term, a wrong sign) still fails by orders of magnitude.
fn check(model: &Model, params: &[&str], t: f64, x: &[f64]) {
    let sens = model.parameter_sensitivity(params).unwrap();
    let (n, k) = (model.dim(), params.len());
    for m in 0..model.modes().len() {
        let mode = model.mode(&model.modes()[m]).unwrap();
        let mut exact = vec![0.0; n * k];
        sens.flow(mode, t, x, 0.0, &mut exact);
        for (j, p) in params.iter().enumerate() {
            let v = model.parameter(p).unwrap();
            let h = 1e-6 * v.abs().max(1.0);
            let (mut fp, mut fm) = (vec![0.0; n], vec![0.0; n]);
            model
                .with_parameters(&[(p, v + h)])
                .unwrap()
                .vector_field(mode, t, x, &mut fp);
            model
                .with_parameters(&[(p, v - h)])
                .unwrap()
                .vector_field(mode, t, x, &mut fm);
            for i in 0..n {
                let fd = (fp[i] - fm[i]) / (2.0 * h);
                let e = exact[i * k + j];
                assert!(
                    (e - fd).abs() <= 1e-6 * fd.abs().max(1.0),
                    "{} mode {m}: df{i}/d{p} = {e} vs {fd}",
                    model.name()
                );
            }
        }
    }
    for g in 0..model.guard_names().len() {
        let mut exact = vec![0.0; k];
        sens.guard(g, t, x, 0.0, &mut exact);
        let mut reset = vec![0.0; n * k];
        sens.reset(g, t, x, 0.0, &mut reset);
        // The guard's own mode: guards are listed per mode in declaration order.
        let (mode, local) = (0..model.modes().len())
            .flat_map(|m| {
                let mode = model.mode(&model.modes()[m]).unwrap();
                (0..model.num_guards(mode)).map(move |i| (mode, i))
            })
            .nth(g)
            .unwrap();
        for (j, p) in params.iter().enumerate() {
            let v = model.parameter(p).unwrap();
            let h = 1e-6 * v.abs().max(1.0);
            let (mp, mm) = (
                model.with_parameters(&[(p, v + h)]).unwrap(),
                model.with_parameters(&[(p, v - h)]).unwrap(),
            );
            let fd = (mp.guard(mode, local, t, x) - mm.guard(mode, local, t, x)) / (2.0 * h);
            assert!((exact[j] - fd).abs() <= 1e-6 * fd.abs().max(1.0), "dh/d{p}");
            let (mut xp, mut xm) = (x.to_vec(), x.to_vec());
            mp.transition(mode, local, t, &mut xp);
            mm.transition(mode, local, t, &mut xm);
            for i in 0..n {
                let fd = (xp[i] - xm[i]) / (2.0 * h);
                assert!(
                    (reset[i * k + j] - fd).abs() <= 1e-6 * fd.abs().max(1.0),
                    "dR{i}/d{p}"
                );
            }
        }
    }
}

#[test]
fn parameter_derivatives_match_finite_differences() {
    check(
        &load("two-dof"),
        &["k1", "k3", "c1", "c2", "m2", "a"],
        0.37,
        &[0.08, -0.3, 0.11, 0.2],
    );
    check(
        &load("bouncing-ball"),
        &["e", "A", "g", "T"],
        0.031,
        &[0.004, -1.2],
    );
    check(
        &load("flight-hopper"),
        &["k", "c", "L0", "a", "m"],
        0.21,
        &[0.47, -0.8],
    );
    check(
        &load("closed-loop-friction"),
        &["Fc", "vs", "b", "kp"],
        0.4,
        &[0.01, 0.003],
    );
}

#[test]
fn unknown_parameter_is_named() {
    let err = load("hopper").parameter_sensitivity(&["kk"]).unwrap_err();
    assert!(err.to_string().contains("kk"));
}
