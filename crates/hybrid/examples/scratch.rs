#[path = "../tests/problems/mod.rs"]
mod problems;
use htfid_hybrid::*;
use problems::*;

fn main() {
    let ball = Ball { g: 9.81, e: 0.8 };
    let t1 = (2.0 / 9.81f64).sqrt();
    let v1 = 9.81 * t1;
    println!("t_inf = {}", t1 + 2.0 * v1 / 9.81 * 0.8 / 0.2);
    for cap in [100, 20] {
        for m in METHODS {
            let opts = Options { method: m, zeno_max_events: cap, ..Options::default() };
            let r = simulate(&ball, (), 0.0, &[1.0, 0.0], 10.0, &[], &opts);
            match r { Ok(tr) => println!("ok?? {:?}", tr.stats), Err(e) => println!("{m:?} cap {cap}: {e} {e:?}") }
        }
    }
}
