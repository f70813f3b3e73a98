#[path = "../tests/problems/mod.rs"]
mod problems;
use htfid_hybrid::*;
use problems::*;

fn main() {
    for m in METHODS {
        let opts = Options {
            method: m,
            ..Options::default()
        };
        let r = simulate(&Blowup, (), 0.0, &[1.0], 2.0, &[], &opts);
        println!("{m:?} {:?}", r.map(|t| t.stats));
        for samples in [4usize, 0] {
            let opts = Options {
                method: m,
                rtol: 1e3,
                atol: 1e3,
                h_init: Some(1.0),
                h_max: 1.0,
                guard_samples: samples,
                ..Options::default()
            };
            let sys = LevelCounter {
                level: 0.99,
                dir: htfid_hybrid::Crossing::Either,
            };
            let tr = simulate(&sys, (), 1.0, &[1f64.sin(), 1f64.cos()], 2.0, &[], &opts).unwrap();
            for e in &tr.events {
                println!(
                    "  samples {samples} event {:.15} err {:e} {:?}",
                    e.time,
                    e.time - 0.99f64.asin(),
                    e.kind
                );
            }
            println!(
                "  final err {:e} {:?}",
                tr.final_state[0] - 2f64.sin(),
                tr.stats
            );
        }
    }
}
