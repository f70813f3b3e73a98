//! Wall-clock timing of the estimators on records the size of the paper's experiment (nine
//! 30 s chirps, 270 s at 100 Hz, seven harmonics) and 4x and 16x longer.
//!
//! Run with `cargo bench -p htfid-estimate --bench estimators`. A plain table, no statistics
//! framework: each entry is the fastest of three runs.

use std::f64::consts::PI;
use std::time::Instant;

use htfid_estimate::{
    deviation_record, multi_experiment, siddiqi, Alpha, Leakage, MultiOptions, TimeSeries,
};

const PERIOD: f64 = 1.0;
const DT: f64 = 0.01;
const SEGMENTS: usize = 9;
const BAND: (f64, f64) = (0.05, 44.0);
const HARMONICS: [i32; 7] = [-3, -2, -1, 0, 1, 2, 3];

/// The paper's excitation: nine chirps sweeping (0, 7] Hz, each starting `T / 9` later in the
/// orbit phase, through a modulated first-order system.
fn experiment(segment_seconds: f64) -> (Vec<f64>, Vec<f64>) {
    let per = (segment_seconds / DT).round() as usize;
    let total = SEGMENTS * per;
    let wp = 2.0 * PI / PERIOD;
    let sweep = 7.0 / segment_seconds; // Hz per second
    let mut u = vec![0.0; total];
    for s in 0..SEGMENTS {
        let shift = s as f64 * PERIOD / SEGMENTS as f64;
        for i in 0..per {
            let tau = i as f64 * DT + shift;
            u[s * per + i] = 0.004 * (PI * sweep * tau * tau).sin();
        }
    }
    let phi = (-3.0 * DT).exp();
    let mut y = vec![0.0; total];
    for i in 0..total - 1 {
        let t = i as f64 * DT;
        y[i + 1] = phi * y[i] + DT * (1.0 + 0.4 * (wp * t).cos()) * u[i];
    }
    (u, y)
}

fn best_of_three(mut f: impl FnMut()) -> f64 {
    (0..3)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    println!(
        "{:>6} {:>9} {:>8} {:>14} {:>14} {:>14} {:>14}",
        "scale", "record s", "bins", "siddiqi a=1", "siddiqi GCV", "multi plain", "multi LPM"
    );
    for scale in [1usize, 4, 16] {
        let seg = 30.0 * scale as f64;
        let (u, y) = experiment(seg);
        let whole = deviation_record(u.clone(), y.clone(), DT, 0.0).expect("valid record");
        let per = u.len() / SEGMENTS;
        let segments: Vec<TimeSeries> = (0..SEGMENTS)
            .map(|s| {
                let r = s * per..(s + 1) * per;
                deviation_record(
                    u[r.clone()].to_vec(),
                    y[r].to_vec(),
                    DT,
                    (s * per) as f64 * DT,
                )
                .expect("valid segment")
            })
            .collect();
        let mut bins = 0;
        let fixed = best_of_three(|| {
            let e = siddiqi(&whole, PERIOD, &HARMONICS, BAND, Alpha::Fixed(1.0)).expect("siddiqi");
            bins = e.harmonic(0).map_or(0, |s| s.omegas.len());
        });
        let gcv = best_of_three(|| {
            siddiqi(&whole, PERIOD, &HARMONICS, BAND, Alpha::Gcv).expect("siddiqi gcv");
        });
        let plain = best_of_three(|| {
            multi_experiment(
                &segments,
                PERIOD,
                &HARMONICS,
                BAND,
                &MultiOptions::default(),
            )
            .expect("multi");
        });
        let lpm_opts = MultiOptions {
            leakage: Leakage::Lpm {
                half_width: 3,
                degree: 2,
            },
            ..MultiOptions::default()
        };
        let lpm = best_of_three(|| {
            multi_experiment(&segments, PERIOD, &HARMONICS, BAND, &lpm_opts).expect("lpm");
        });
        println!(
            "{:>6} {:>9.0} {:>8} {:>12.3} s {:>12.3} s {:>12.3} s {:>12.3} s",
            format!("{scale}x"),
            whole.len() as f64 * whole.dt(),
            bins,
            fixed,
            gcv,
            plain,
            lpm
        );
    }
}
