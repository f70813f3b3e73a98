//! `OrbitHtf` (linearisation integrated along the orbit) against `ExactHtf` (closed-form
//! piecewise-LTI) for the paper's hopper: harmonics -10..=10 on 200 output frequencies in
//! 1..40 rad/s, best of N wall-clock runs.
//!
//! ```text
//! cargo bench -p htfid-theory --bench orbit_htf
//! ```

use std::hint::black_box;
use std::time::{Duration, Instant};

use htfid_hybrid::Options;
use htfid_ltp::linearise;
use htfid_model::{Hopper, HopperParams};
use htfid_orbit::ShootingOptions;
use htfid_theory::{ExactHtf, HarmonicTransferFunction, OrbitHtf};

fn best_of<T>(runs: usize, mut f: impl FnMut() -> T) -> Duration {
    (0..runs)
        .map(|_| {
            let start = Instant::now();
            black_box(f());
            start.elapsed()
        })
        .min()
        .unwrap_or_default()
}

fn main() {
    let hopper = Hopper::new(HopperParams::paper()).unwrap();
    let harmonics: Vec<i32> = (-10..=10).collect();
    let omegas: Vec<f64> = (0..200)
        .map(|i| 1.0 + 39.0 * f64::from(i) / 199.0)
        .collect();
    let points = harmonics.len() * omegas.len();
    println!(
        "hopper, {} harmonics x {} frequencies = {points} values",
        harmonics.len(),
        omegas.len()
    );
    for (label, rtol, atol) in [
        ("rtol 1e-10 (default)", 1e-10, 1e-12),
        ("rtol 1e-12", 1e-12, 1e-14),
    ] {
        let opts = Options {
            rtol,
            atol,
            ..Options::default()
        };
        let orbit = hopper
            .limit_cycle(&ShootingOptions::default(), &opts)
            .unwrap();
        let cycle = &orbit.cycle;
        let lin = linearise(&hopper, cycle, 16, &opts).unwrap();
        let exact = ExactHtf::new(&lin.piecewise).unwrap();
        let t_exact = best_of(5, || exact.grid(&harmonics, &omegas));
        let t_build = best_of(5, || OrbitHtf::new(&hopper, cycle, &opts).unwrap());
        let htf = OrbitHtf::new(&hopper, cycle, &opts).unwrap();
        let t_orbit = best_of(3, || htf.grid(&harmonics, &omegas));
        let want = exact.grid(&harmonics, &omegas);
        let got = htf.grid(&harmonics, &omegas);
        let err = got
            .values
            .iter()
            .zip(&want.values)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max)
            / want.max_abs();
        let t_response = best_of(5, || htf.response(13.5, &harmonics).unwrap());
        println!("{label}:");
        println!(
            "  ExactHtf::grid    {:>10.3} ms ({:.2} us per value)",
            t_exact.as_secs_f64() * 1e3,
            t_exact.as_secs_f64() * 1e6 / points as f64
        );
        println!(
            "  OrbitHtf::new     {:>10.3} ms",
            t_build.as_secs_f64() * 1e3
        );
        println!(
            "  OrbitHtf::grid    {:>10.3} ms ({:.2} us per value), worst |diff| / max|G| = {err:.1e}",
            t_orbit.as_secs_f64() * 1e3,
            t_orbit.as_secs_f64() * 1e6 / points as f64
        );
        println!(
            "  OrbitHtf::response (one input frequency, 21 harmonics) {:.3} ms",
            t_response.as_secs_f64() * 1e3
        );
    }
}
