//! A model-language model whose two modes meet on one surface without a reset slides along it:
//! the stick-slip belt `m x'' = -k x - F sign(x' - vb)` of `crates/hybrid/tests/sliding.rs`,
//! written as a model file, against its closed form.
//!
//! From rest at `x = 0` the mass slips behind the belt (`x = F/k (1 - cos wt)`), reaches the
//! belt speed at `t1 = asin(vb k / (F w)) / w`, sticks (`x' = vb`) and slips back when
//! `k x = F`, at `t2 = t1 + (F/k - x1) / vb`. Tolerance 1e-9: events are located to 1e-12 s
//! and the state carries the `rtol = 1e-10` integration error over one oscillation, with
//! crossing and exit speeds of order 1 (see the hybrid test for the measured 1e-10).

use htfid_hybrid::{simulate, EventKind, HybridSystem, Options};
use htfid_lang::Model;

const BELT: &str = r#"
name = "belt"
states = [{ name = "x", unit = "m" }, { name = "v", unit = "m/s" }]

[parameters]
m  = { value = 1.0 }
k  = { value = 4.0 }
F  = { value = 1.0 }
vb = { value = 0.2 }

[input]
name = "u"

[flow]
x = "v"

[modes.behind]
v = "(-k * x + F + u) / m"

[modes.ahead]
v = "(-k * x - F + u) / m"

[[guards]]
from = "behind"
to = "ahead"
when = "v - vb"
direction = "rising"

[[guards]]
from = "ahead"
to = "behind"
when = "v - vb"
direction = "falling"
"#;

#[test]
fn a_belt_written_as_a_model_file_sticks_like_its_closed_form() {
    let model = Model::parse(BELT).unwrap();
    let behind = model.mode("behind").unwrap();
    let ahead = model.mode("ahead").unwrap();
    assert_eq!(model.sliding_chart(behind, 0), Some(ahead));
    let (m, k, f, vb): (f64, f64, f64, f64) = (1.0, 4.0, 1.0, 0.2);
    let w = (k / m).sqrt();
    let t1 = (vb * k / (f * w)).asin() / w;
    let x1 = f / k * (1.0 - (w * t1).cos());
    let t2 = t1 + (f / k - x1) / vb;
    let t_end = t2 + 1.0;
    let traj = simulate(
        &model,
        behind,
        0.0,
        &[0.0, 0.0],
        t_end,
        &[t_end],
        &Options::default(),
    )
    .unwrap();
    let kinds: Vec<EventKind> = traj.events.iter().map(|e| e.kind).collect();
    assert_eq!(kinds, [EventKind::SlideStart, EventKind::SlideEnd]);
    assert_eq!(traj.sliding.len(), 1);
    let stick = traj.sliding[0];
    assert!((stick.start - t1).abs() < 1e-9, "{} vs {t1}", stick.start);
    assert!((stick.end - t2).abs() < 1e-9, "{} vs {t2}", stick.end);
    assert_eq!(stick.exit, Some(behind));
    let x_end = f / k + vb / w * (w * (t_end - t2)).sin();
    assert!((traj.final_state[0] - x_end).abs() < 1e-9);
}

#[test]
fn guards_with_a_reset_or_on_different_surfaces_do_not_slide() {
    // The bouncing ball's impact has a reset; the flight hopper's touchdown and liftoff are
    // different surfaces.
    for file in ["bouncing-ball.toml", "flight-hopper.toml"] {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../models")
            .join(file);
        let model = Model::from_file(&path).unwrap();
        for mode in model.modes().iter().filter_map(|n| model.mode(n)) {
            for g in 0..model.num_guards(mode) {
                assert_eq!(model.sliding_chart(mode, g), None, "{file}");
            }
        }
    }
}
