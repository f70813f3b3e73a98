//! Every value against the C library's `sin` and `cos`, which are within half a unit in the
//! last place of the exact values almost everywhere.

/// A seeded xorshift generator: uniform in [0, 1).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Largest error of `ours` against `libm` over the arguments: (units in the last place of
/// the C library's value where it exceeds 1e-3 in magnitude, absolute error everywhere).
fn errors(x: &[f64], ours: &[f64], libm: impl Fn(f64) -> f64) -> (f64, f64) {
    let (mut ulps, mut abs) = (0.0_f64, 0.0_f64);
    for (&x, &v) in x.iter().zip(ours) {
        let truth = libm(x);
        let e = (v - truth).abs();
        abs = abs.max(e);
        if truth.abs() > 1e-3 {
            ulps = ulps.max(e / (f64::EPSILON * truth.abs()));
        }
    }
    (ulps, abs)
}

/// One unit in the last place relative to the C library where the value exceeds 1e-3 (the
/// remainder's own rounding and the polynomials' error, each below half a unit), and `2^-53`
/// absolute everywhere (half an ulp of 1: near a zero the value is the remainder itself).
#[test]
fn every_value_is_within_an_ulp_of_the_c_librarys() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    for range in [1.0, 10.0, 2000.0, 1e5, 1e6] {
        let x: Vec<f64> = (0..1_000_000)
            .map(|_| (2.0 * rng.next() - 1.0) * range)
            .collect();
        let (mut s, mut c) = (vec![0.0; x.len()], vec![0.0; x.len()]);
        htfid_trig::sin_many(&x, &mut s);
        htfid_trig::cos_many(&x, &mut c);
        let (su, sa) = errors(&x, &s, f64::sin);
        let (cu, ca) = errors(&x, &c, f64::cos);
        assert!(su <= 1.0 && cu <= 1.0, "range {range}: {su} and {cu} ulp");
        assert!(
            sa <= 2f64.powi(-53) && ca <= 2f64.powi(-53),
            "range {range}: {sa:e}, {ca:e}"
        );
    }
}

/// Near multiples of pi/2, where the reduction cancels most of the argument, the values stay
/// within 2^-53 absolute of the C library's.
#[test]
fn near_multiples_of_half_pi_the_reduction_holds() {
    for k in [1.0_f64, 2.0, 3.0, 4.0, 101.0, 1234.0, 99_999.0, 600_000.0] {
        let centre = k * std::f64::consts::FRAC_PI_2;
        let mut x = centre;
        for _ in 0..64 {
            for v in [x, -x] {
                let (s, c) = (htfid_trig::sin(v), htfid_trig::cos(v));
                assert!((s - v.sin()).abs() <= 2f64.powi(-53), "sin({v:e})");
                assert!((c - v.cos()).abs() <= 2f64.powi(-53), "cos({v:e})");
            }
            x = x.next_up_compat();
        }
    }
}

/// The slice functions and the one-argument ones are the same code: the same bits, for
/// arguments inside and outside the reduced range and for special values.
#[test]
fn batches_and_single_values_agree_bit_for_bit() {
    let x = [
        0.0,
        -0.0,
        1e-300,
        -2.5,
        0.785,
        1e5 + 0.3,
        htfid_trig::REDUCED_UP_TO,
        2e6,
        -7.5e12,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NAN,
    ];
    let (mut s, mut c) = ([0.0; 12], [0.0; 12]);
    htfid_trig::sin_many(&x, &mut s);
    htfid_trig::cos_many(&x, &mut c);
    for i in 0..x.len() {
        let (one_s, one_c) = (htfid_trig::sin(x[i]), htfid_trig::cos(x[i]));
        assert!(
            s[i].to_bits() == one_s.to_bits() || (s[i].is_nan() && one_s.is_nan()),
            "sin({})",
            x[i]
        );
        assert!(
            c[i].to_bits() == one_c.to_bits() || (c[i].is_nan() && one_c.is_nan()),
            "cos({})",
            x[i]
        );
    }
    // Exact values: signed zero, and the C library beyond the reduced range.
    assert_eq!(htfid_trig::sin(-0.0).to_bits(), (-0.0_f64).to_bits());
    assert_eq!(htfid_trig::cos(0.0).to_bits(), 1.0_f64.to_bits());
    assert_eq!(htfid_trig::sin(2e6).to_bits(), 2e6_f64.sin().to_bits());
    assert!(htfid_trig::sin(f64::INFINITY).is_nan() && htfid_trig::cos(f64::NAN).is_nan());
}

/// `f64::next_up` is stable only from Rust 1.86; the workspace supports 1.80.
trait NextUp {
    fn next_up_compat(self) -> Self;
}
impl NextUp for f64 {
    fn next_up_compat(self) -> f64 {
        // Positive finite values only (as used above).
        f64::from_bits(self.to_bits() + 1)
    }
}
