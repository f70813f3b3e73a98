//! Times uniform sampling of a 150-line multisine against point-by-point evaluation.
//!
//! `cargo run --release -p htfid-excite --example sample_speed`

use std::time::Instant;

use htfid_excite::{Amplitude, BinSelection, Multisine, PhaseRule, Signal};

fn main() -> Result<(), htfid_excite::ExciteError> {
    let m = Multisine::flat(
        300.0,
        &BinSelection::Explicit((1..=150).map(|k| 2 * k - 1).collect()),
        PhaseRule::Schroeder,
        Amplitude::Peak(1.0),
    )?;
    for &n in &[100_000usize, 1_000_000] {
        let dt = 1e-3;
        let t = Instant::now();
        let fast = m.sample_uniform(30.0, dt, n);
        let fast_s = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let slow: Vec<f64> = (0..n).map(|i| m.value(30.0 + i as f64 * dt)).collect();
        let slow_s = t.elapsed().as_secs_f64();
        let err = fast
            .iter()
            .zip(&slow)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        println!(
            "{n:>8} samples x 150 lines: fill_uniform {:.2} ms, value() loop {:.2} ms, max |diff| {err:.2e}",
            fast_s * 1e3,
            slow_s * 1e3
        );
    }
    Ok(())
}
