mod common;
use common::*;
use htfid_estimate::*;
use num_complex::Complex64;

#[test]
fn explore() {
    for (nmax, damp, p) in [(1, 1.0, 128usize), (3, 1.0, 128)] {
        let grid = Grid { n: p * 25, dt: 0.04, period: 1.0 };
        let truth = Rational::damped(nmax, damp);
        let band = (0.5, 25.0);
        let kmax = (25.0 / grid.dw()) as i64 + 1 + nmax as i64 * grid.p();
        let c = random_spectrum(kmax, 1);
        let rec0 = synth_record(grid, &c, 0.0, 12.34, &truth);
        let rms = (rec0.y().iter().map(|v| v*v).sum::<f64>() / rec0.len() as f64).sqrt();
        let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(5);
        let rec = with_noise(&rec0, 0.1 * rms, &mut rng);
        let hs: Vec<i32> = (-nmax..=nmax).collect();
        let err = |e: &HtfEstimate| -> f64 {
            hs.iter().map(|&n| { let s = e.harmonic(n).unwrap(); let w: Vec<Complex64> = s.omegas.iter().map(|&w| truth.g(n, w)).collect(); rms_rel_err(s.values, &w)}).fold(0.0, f64::max)
        };
        let mut line = format!("nmax {nmax} damp {damp} P {p}:");
        for a in [1e-4, 1e-2, 1e-1, 1.0, 10.0, 1e2, 1e3] {
            let e = siddiqi(&rec, 1.0, &hs, band, Alpha::Fixed(a)).unwrap();
            line += &format!(" a={a:e}:{:.2e}", err(&e));
        }
        std::env::set_var("DBG_GCV", "1"); let e = siddiqi(&rec, 1.0, &hs, band, Alpha::Gcv).unwrap(); std::env::remove_var("DBG_GCV");
        line += &format!(" gcv a={:.2e}:{:.2e}", e.alpha().unwrap(), err(&e));
        println!("{line}");
    }
}
