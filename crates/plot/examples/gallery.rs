//! One figure of each kind the crate offers, written to /tmp/htfid-plot-gallery/.
//!
//! Run with `cargo run -p htfid-plot --example gallery`.

use std::f64::consts::PI;
use std::path::Path;

use htfid_plot::{
    grid_figure, magnitude_panel, save, spectrum_panel, stacked_figure, time_panel, BodeSeries,
    SpectrumScale, Style,
};
use num_complex::Complex64;

fn log_grid(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| lo * (hi / lo).powf(i as f64 / (n - 1) as f64))
        .collect()
}

/// A made-up harmonic transfer function component: a resonance shifted by k times 2 rad/s and
/// scaled down with |k|.
fn harmonic(k: i32, w: f64) -> Complex64 {
    let s = Complex64::new(0.0, w + 2.0 * f64::from(k));
    0.5f64.powi(k.abs()) / (s * s + 0.8 * s + 25.0)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = Path::new("/tmp/htfid-plot-gallery");

    let w_th = log_grid(0.1, 100.0, 400);
    let w_est = log_grid(0.2, 50.0, 25);
    let mut panels = Vec::new();
    for k in -3..=3 {
        let g_th: Vec<Complex64> = w_th.iter().map(|&w| harmonic(k, w)).collect();
        let g_est: Vec<Complex64> = w_est
            .iter()
            .enumerate()
            .map(|(i, &w)| harmonic(k, w) * (1.0 + 0.1 * (3.7 * i as f64 + f64::from(k)).sin()))
            .collect();
        panels.push(magnitude_panel(
            &format!("G_{k}"),
            &[
                BodeSeries {
                    label: "theory",
                    omega: &w_th,
                    response: &g_th,
                    style: Style::Line,
                },
                BodeSeries {
                    label: "estimate",
                    omega: &w_est,
                    response: &g_est,
                    style: Style::Markers,
                },
            ],
        ));
    }
    let fig = grid_figure("Harmonic transfer function magnitudes", panels, 3);
    print_paths(save(&fig, &out.join("harmonics"))?);

    let t: Vec<f64> = (0..20_000).map(|i| f64::from(i) * 1e-3).collect();
    let x: Vec<f64> = t
        .iter()
        .map(|&t| (2.0 * PI * 0.5 * t).sin() + 0.2 * (2.0 * PI * 7.0 * t).sin())
        .collect();
    let mut v: Vec<f64> = t
        .iter()
        .map(|&t| 2.0 * PI * 0.5 * (2.0 * PI * 0.5 * t).cos())
        .collect();
    // A dropout and a diverging stretch: skipped and clipped, not drawn as garbage.
    for (i, vi) in v.iter_mut().enumerate() {
        if (5000..5600).contains(&i) {
            *vi = f64::NAN;
        }
        if i == 9000 {
            *vi = f64::INFINITY;
        }
    }
    let u: Vec<f64> = t
        .iter()
        .map(|&t| if t % 4.0 < 2.0 { 1.0 } else { -1.0 })
        .collect();
    let fig = stacked_figure(
        "Simulated response",
        vec![
            time_panel("position", "x (m)", &t, [("x", &x)]),
            time_panel("velocity", "v (m/s)", &t, [("v", &v), ("dx/dt", &x)]),
            time_panel("input", "u (N)", &t, [("u", &u)]),
        ],
    );
    print_paths(save(&fig, &out.join("time"))?);

    let w = log_grid(0.01, 1000.0, 2000);
    let a: Vec<f64> = w
        .iter()
        .map(|&w| 1.0 / (1.0 + (w / 3.0).powi(2)).sqrt() + 1e-4)
        .collect();
    let b: Vec<f64> = w.iter().map(|&w| harmonic(0, w).norm()).collect();
    let fig = stacked_figure(
        "Spectra",
        vec![
            spectrum_panel(
                "log-log",
                &w,
                [("low-pass", &a), ("resonance", &b)],
                SpectrumScale::LogLog,
            ),
            spectrum_panel(
                "decibel",
                &w,
                [("low-pass", &a), ("resonance", &b)],
                SpectrumScale::Decibel,
            ),
        ],
    );
    print_paths(save(&fig, &out.join("spectra"))?);
    Ok(())
}

fn print_paths(paths: Vec<std::path::PathBuf>) {
    for p in paths {
        println!("{}", p.display());
    }
}
