//! Times the exact HTF of the hopper (2 states, 2 pieces) for harmonics
//! -10..=10 on 2000 frequencies, single-threaded.
//!
//! `cargo run --release -p htfid-theory --example exact_htf_speed`

use htfid_ltp::{Piece, PiecewiseLti};
use htfid_theory::{ExactHtf, ExactMethod, HarmonicTransferFunction, TruncatedHtf};
use nalgebra::{dmatrix, dvector, RowDVector};
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (k, c, t_on, t_off) = (200.0, 2.0, 0.23, 0.71);
    let piece = |duration: f64, damping: f64| {
        Piece::siso(
            duration,
            dmatrix![0.0, 1.0; -k, -damping],
            dvector![0.0, 1.0],
            RowDVector::from_row_slice(&[1.0, 0.0]),
            0.0,
        )
    };
    let lti = PiecewiseLti::new(
        1.0,
        t_on,
        vec![piece(t_off - t_on, c), piece(1.0 - (t_off - t_on), 0.0)],
    )?;
    let harmonics: Vec<i32> = (-10..=10).collect();
    let omegas: Vec<f64> = (0..2000).map(|i| 0.05 * f64::from(i + 1)).collect();
    let points = harmonics.len() * omegas.len();

    let time = |label: &str, reps: usize, f: &dyn Fn() -> f64| {
        let mut best = f64::INFINITY;
        let mut checksum = 0.0;
        for _ in 0..reps {
            let start = Instant::now();
            checksum += f();
            best = best.min(start.elapsed().as_secs_f64());
        }
        println!(
            "{label:<40} {:>9.3} ms  ({:.0} ns per point; checksum {checksum:.6e})",
            best * 1e3,
            best * 1e9 / points as f64
        );
    };

    let build = Instant::now();
    let modal = ExactHtf::new(&lti)?;
    println!(
        "ExactHtf::new (modal)                    {:>9.3} ms",
        build.elapsed().as_secs_f64() * 1e3
    );
    time("exact modal grid 21 x 2000", 20, &|| {
        modal.grid(&harmonics, &omegas).max_abs()
    });
    let block = ExactHtf::with_method(&lti, ExactMethod::BlockExponential)?;
    time("exact block-exponential grid 21 x 2000", 2, &|| {
        block.grid(&harmonics, &omegas).max_abs()
    });
    let truncated = TruncatedHtf::new(&lti, 10)?;
    time("truncated N = 10 grid 21 x 2000", 2, &|| {
        truncated.grid(&harmonics, &omegas).max_abs()
    });
    Ok(())
}
