//! The fixed-step integrator against the adaptive one (a second method): on a forced
//! oscillator with a switching damper, the error falls like h^4 as the steps are refined.

use htfid_hybrid::{
    simulate, simulate_fixed_step, simulate_fixed_step_states, Crossing, HybridError, HybridSystem,
    Options,
};

/// x'' = -k x - c s x' + cos(w t), s = 1 while x' > 0.
struct Switching;

impl HybridSystem for Switching {
    type Mode = bool;
    fn dim(&self) -> usize {
        2
    }
    fn vector_field(&self, damped: bool, t: f64, x: &[f64], d: &mut [f64]) {
        let s = if damped { 1.0 } else { 0.0 };
        d[0] = x[1];
        d[1] = -50.0 * x[0] - 3.0 * s * x[1] + (4.0 * t).cos();
    }
    fn num_guards(&self, _: bool) -> usize {
        1
    }
    fn guard(&self, _: bool, _: usize, _t: f64, x: &[f64]) -> f64 {
        x[1]
    }
    fn guard_direction(&self, damped: bool, _: usize) -> Crossing {
        if damped {
            Crossing::Falling
        } else {
            Crossing::Rising
        }
    }
    fn transition(&self, damped: bool, _: usize, _t: f64, _x: &mut [f64]) -> bool {
        !damped
    }
}

#[test]
fn fixed_step_converges_at_fourth_order_to_the_adaptive_solution() {
    let (dt, n) = (0.05, 201);
    let grid: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
    let opts = Options {
        rtol: 1e-12,
        atol: 1e-14,
        ..Options::default()
    };
    let reference = simulate(&Switching, false, 0.0, &[0.1, -0.2], 10.0, &grid, &opts).unwrap();
    assert!(reference.transitions().count() > 10);
    let error = |substeps: usize| {
        let mut out = vec![0.0; n];
        simulate_fixed_step(
            &Switching,
            false,
            0.0,
            &[0.1, -0.2],
            dt,
            substeps,
            0,
            &mut out,
        )
        .unwrap();
        (0..n)
            .map(|i| (out[i] - reference.state(i)[0]).abs())
            .fold(0.0, f64::max)
    };
    let (e1, e2) = (error(4), error(8));
    // Halving the step divides an RK4 error by 16; the located switches keep the order.
    let ratio = e1 / e2;
    assert!(ratio > 12.0 && ratio < 20.0, "{e1:e} / {e2:e} = {ratio}");
    assert!(e2 < 1e-7, "{e2:e}");
}

#[test]
fn a_wrong_state_length_is_an_error() {
    let mut out = vec![0.0; 3];
    assert!(simulate_fixed_step(&Switching, false, 0.0, &[0.1], 0.1, 1, 0, &mut out).is_err());
}

/// The whole-state writer takes the same steps as the one-component one: both components of
/// every sample equal, bit for bit, what `simulate_fixed_step` writes for each (through more
/// than ten damper switches); a dimension other than the system's is refused.
#[test]
fn the_whole_state_is_written_as_each_component_is() {
    let (dt, n, x0) = (0.05, 201, [0.1, -0.2]);
    let mut states = vec![[f64::NAN; 2]; n];
    simulate_fixed_step_states::<_, 2>(&Switching, false, 0.0, &x0, dt, 3, n, |i, x| {
        states[i].copy_from_slice(x);
    })
    .unwrap();
    for component in 0..2 {
        let mut out = vec![0.0; n];
        simulate_fixed_step(&Switching, false, 0.0, &x0, dt, 3, component, &mut out).unwrap();
        for (i, v) in out.iter().enumerate() {
            assert_eq!(v.to_bits(), states[i][component].to_bits(), "sample {i}");
        }
    }
    let wrong =
        simulate_fixed_step_states::<_, 3>(&Switching, false, 0.0, &x0, dt, 3, n, |_, _| {});
    assert!(matches!(
        wrong,
        Err(HybridError::DimensionMismatch {
            expected: 3,
            found: 2
        })
    ));
}
