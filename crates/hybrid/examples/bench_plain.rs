use std::time::Instant;
use htfid_hybrid::{simulate, HybridSystem, Options, Method};
#[derive(Debug)]
struct Osc;
impl HybridSystem for Osc {
    type Mode = ();
    fn dim(&self) -> usize { 2 }
    fn vector_field(&self, _: (), _t: f64, x: &[f64], d: &mut [f64]) { d[0] = x[1]; d[1] = -x[0]; }
}
fn main() {
    for m in [Method::Dop853, Method::Dopri5] {
        let opts = Options { method: m, ..Options::default() };
        let mut best = f64::INFINITY; let mut steps = 0;
        for _ in 0..10 {
            let s = Instant::now();
            let tr = simulate(&Osc, (), 0.0, &[1.0, 0.0], 10000.0, &[], &opts).unwrap();
            best = best.min(s.elapsed().as_secs_f64()); steps = tr.stats.steps;
        }
        println!("{m:?}: {steps} steps, {:.1} ns/step", best * 1e9 / steps as f64);
    }
}
