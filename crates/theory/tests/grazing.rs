//! An orbit that touches a guard without crossing it has no linearisation: the HTFs are
//! refused with the guard and the time named, never given as the guard-free system's.

use htfid_hybrid::{Crossing, HybridSystem, Options};
use htfid_ltp::{InputOutput, LtpError};
use htfid_orbit::{find_limit_cycle, ShootingOptions};
use htfid_theory::{HarmonicTransferFunction, LinearisedHtf, TheoryError};

/// `x'' = -x - c x' + cos(w t)` with a guard `x - d` (rising) that resets nothing.
struct Touch {
    c: f64,
    w: f64,
    d: f64,
}

impl Touch {
    /// The steady state's amplitude, `1 / |1 - w^2 + j c w|`.
    fn amplitude(&self) -> f64 {
        1.0 / ((1.0 - self.w * self.w).powi(2) + (self.c * self.w).powi(2)).sqrt()
    }
}

impl HybridSystem for Touch {
    type Mode = ();
    fn dim(&self) -> usize {
        2
    }
    fn vector_field(&self, _: (), t: f64, x: &[f64], dx: &mut [f64]) {
        dx[0] = x[1];
        dx[1] = -x[0] - self.c * x[1] + (self.w * t).cos();
    }
    fn num_guards(&self, _: ()) -> usize {
        1
    }
    fn guard(&self, _: (), _: usize, _t: f64, x: &[f64]) -> f64 {
        x[0] - self.d
    }
    fn guard_direction(&self, _: (), _: usize) -> Crossing {
        Crossing::Rising
    }
}

impl InputOutput for Touch {
    fn input_gain(&self, _: (), _t: f64, _x: &[f64], b: &mut [f64]) {
        b[0] = 0.0;
        b[1] = 1.0;
    }
    fn num_outputs(&self) -> usize {
        1
    }
    fn output_gain(&self, _: (), _t: f64, _x: &[f64], c: &mut [f64]) {
        c.copy_from_slice(&[1.0, 0.0]);
    }
}

/// The guard 1e-9 above the orbit's peak (within the integrator's graze tolerance, 1e-8) is a
/// graze: refused. A tenth above it, the guard is out of reach and the HTF is the linear
/// oscillator's, `G_0(jw) = 1 / (1 - w^2 + j c w)` (to 1e-8 of it: the integrator's tolerance).
#[test]
fn a_grazed_guard_is_refused_and_a_distant_one_changes_nothing() {
    let opts = Options {
        rtol: 1e-11,
        atol: 1e-13,
        ..Options::default()
    };
    let period = std::f64::consts::TAU / 0.8;
    for (gap, grazes) in [(1e-9, true), (0.1, false)] {
        let mut sys = Touch {
            c: 0.1,
            w: 0.8,
            d: 0.0,
        };
        sys.d = sys.amplitude() + gap;
        // The steady state at t = 0: x = Re(X), x' = Re(j w X).
        let x = num_complex::Complex64::new(1.0 - sys.w * sys.w, sys.c * sys.w).inv();
        let start = [x.re, (num_complex::Complex64::i() * sys.w * x).re];
        let cycle = find_limit_cycle(
            &sys,
            (),
            0.0,
            &start,
            period,
            &ShootingOptions::default(),
            &opts,
        )
        .unwrap();
        match (LinearisedHtf::new(&sys, &cycle, &opts), grazes) {
            (Err(TheoryError::Ltp(LtpError::GrazingOrbit { guard, time })), true) => {
                assert_eq!(guard, 0);
                // The peak of x = |X| cos(w t + arg X) is where w t = -arg X (mod 2 pi).
                let peak = (-x.arg()).rem_euclid(std::f64::consts::TAU) / sys.w;
                let off = (time - cycle.t0 - peak).rem_euclid(period);
                assert!(
                    off.min(period - off) < 1e-3,
                    "graze at {time}, peak at {peak}"
                );
            }
            (Ok(htf), false) => {
                for w in [0.3, 1.0, 2.5] {
                    let want = num_complex::Complex64::new(1.0 - w * w, sys.c * w).inv();
                    let got = htf.channel(0).unwrap().g(0, w);
                    assert!(
                        (got - want).norm() < 1e-8 * want.norm(),
                        "{w}: {got} against {want}"
                    );
                }
            }
            (other, _) => panic!("gap {gap}: {:?}", other.map(|_| "an HTF")),
        }
    }
}
