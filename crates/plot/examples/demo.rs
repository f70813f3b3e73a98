//! Bode plot of G(s) = 1 / (s^2 + 2 s + 200) with a perturbed "estimate" at sparse frequencies.
//!
//! Run with `cargo run -p htfid-plot --example demo`; writes /tmp/htfid-plot-demo.{svg,png}.

use std::path::Path;

use htfid_plot::{bode_panels_each, save, stacked_figure, BodeSeries, Style};
use num_complex::Complex64;

fn g(w: f64) -> Complex64 {
    let s = Complex64::new(0.0, w);
    1.0 / (s * s + 2.0 * s + 200.0)
}

fn log_grid(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| lo * (hi / lo).powf(i as f64 / (n - 1) as f64))
        .collect()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let w_theory = log_grid(0.1, 1000.0, 600);
    let g_theory: Vec<Complex64> = w_theory.iter().map(|&w| g(w)).collect();

    // A deterministic few-percent error stands in for estimation noise.
    let w_est = log_grid(0.3, 300.0, 31);
    let g_est: Vec<Complex64> = w_est
        .iter()
        .enumerate()
        .map(|(k, &w)| {
            let k = k as f64;
            g(w) * Complex64::from_polar(1.0 + 0.06 * (7.3 * k).sin(), 0.05 * (5.1 * k).cos())
        })
        .collect();

    let panels = bode_panels_each(
        "G(s) = 1/(s\u{b2} + 2s + 200)",
        &[
            BodeSeries {
                label: "theory",
                omega: &w_theory,
                response: &g_theory,
                style: Style::Line,
            },
            BodeSeries {
                label: "estimate",
                omega: &w_est,
                response: &g_est,
                style: Style::Markers,
            },
        ],
    );
    let fig = stacked_figure("Bode plot", panels.to_vec());
    for path in save(&fig, Path::new("/tmp/htfid-plot-demo"))? {
        println!("{}", path.display());
    }
    Ok(())
}
