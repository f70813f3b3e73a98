//! Prints the truncation error of the harmonic state space HTF against the
//! exact HTF for the hopper-like system (the table in the crate docs).
//!
//! `cargo run --release -p htfid-theory --example truncation_table`

use htfid_ltp::{Piece, PiecewiseLti};
use htfid_theory::{ExactHtf, HarmonicTransferFunction, TruncatedHtf};
use nalgebra::{dmatrix, dvector, RowDVector};

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
    let exact = ExactHtf::new(&lti)?;
    let omegas = [3.0, 9.0, 14.0, 20.0, 33.0];
    let all: Vec<i32> = (-10..=10).collect();
    let truth = exact.grid(&all, &omegas);
    let scale = truth.max_abs();
    println!("max|G| = {scale:.4e}");
    println!("N    all |n|<=10   |n|<=3      |n|<=1   (worst |G_n - exact| / max|G|)");
    for n_trunc in [5, 10, 20, 40, 80, 160] {
        let trunc = TruncatedHtf::new(&lti, n_trunc)?.grid(&all, &omegas);
        let worst = |limit: i32| {
            truth
                .values
                .iter()
                .zip(&trunc.values)
                .enumerate()
                .filter(|(i, _)| all[i % all.len()].abs() <= limit)
                .map(|(_, (a, b))| (a - b).norm() / scale)
                .fold(0.0, f64::max)
        };
        println!(
            "{n_trunc:<4} {:<12.3e}  {:<10.3e}  {:<10.3e}",
            worst(10),
            worst(3),
            worst(1)
        );
    }
    Ok(())
}
