//! Sines and cosines of many arguments at once.
//!
//! A simulation of a forced system asks for the forcing and the input at every stage of
//! every step: hundreds of thousands of sines and cosines whose arguments depend on time
//! alone. The C library's functions take one argument per call and save and restore the
//! rounding mode each time. Here the same functions are written as straight-line code with no
//! branch on the argument, so that a loop over several arguments compiles to vector
//! instructions: [`sin_many`] and [`cos_many`] take a slice. [`sin`] and [`cos`] are the same
//! code for one argument, so a value computed alone and one computed in a batch agree bit for
//! bit, whichever a caller uses.
//!
//! # Accuracy
//! - Against the exact values (mpmath at 160 bits, 40 000 arguments in each of `[-1, 1]`,
//!   `[-2000, 2000]` and `[-1e6, 1e6]`, `tests/oracle/trig_exact.py`): at most 1.05 units in
//!   the last place of the exact value on `[-1, 1]` and 1.42 beyond, at most `1.2e-16`
//!   absolute. The C library's functions, measured the same way: 0.51 units.
//! - Against the C library's `sin` and `cos` (a million arguments in each of `[-1, 1]`,
//!   `[-10, 10]`, `[-2000, 2000]`, `[-1e5, 1e5]` and `[-1e6, 1e6]`, `tests/accuracy.rs`): at
//!   most one unit in the last place where `|value| > 1e-3`, at most `2^-53` absolute. About
//!   30 % of the values differ from the C library's in the last bit.
//!
//! # Method
//! The argument is reduced by the nearest multiple `k` of `pi/2`, written as the sum of three
//! doubles and subtracted with fused multiply-adds (exactly rounded on every platform, in
//! hardware where the processor has them); the remainder `|r| <= pi/4` goes to the minimax
//! polynomials of FreeBSD's `__kernel_sin` and `__kernel_cos` (fdlibm), and the quadrant
//! `k mod 4` picks the sign and which of the two is the answer. Arguments beyond
//! [`REDUCED_UP_TO`] in magnitude, and non-finite ones, are passed to the C library.
//!
//! ```
//! let t = [0.0, 0.5, 1.0, 2.0];
//! let mut c = [0.0; 4];
//! htfid_trig::cos_many(&t, &mut c);
//! assert_eq!(c[2].to_bits(), htfid_trig::cos(1.0).to_bits());
//! assert!((c[3] - 2.0_f64.cos()).abs() <= f64::EPSILON);
//! ```

/// `pi/2` as the unevaluated sum of three doubles (each the rounding of what is left).
const PIO2_HI: f64 = std::f64::consts::FRAC_PI_2;
const PIO2_MID: f64 = 6.123233995736766e-17;
const PIO2_LO: f64 = -1.4973849048591698e-33;

/// `1.5 * 2^52`: adding and subtracting it rounds to the nearest integer (ties to even), and
/// the low bits of the sum are that integer's.
const ROUNDER: f64 = 6755399441055744.0;

/// Largest `|x|` reduced here; beyond it (or for a non-finite `x`) the C library's functions
/// answer. Up to here `k = x * 2/pi` is below `2^20` and the reduction keeps `r` to within an
/// ulp.
pub const REDUCED_UP_TO: f64 = 1.0e6;

/// `2^-27`: below it `sin r = r` and `cos r = 1` to the last bit.
const TINY: f64 = 7.450580596923828e-9;

/// FreeBSD msun `k_sin.c` and `k_cos.c` (fdlibm): minimax polynomials on `[-pi/4, pi/4]`,
/// written as there (their decimal texts carry more digits than a double keeps; the nearest
/// doubles are the coefficients).
#[allow(clippy::excessive_precision)]
mod kernel {
    pub(crate) const S1: f64 = -1.666_666_666_666_663_243_48e-1;
    pub(crate) const S2: f64 = 8.333_333_333_322_489_461_24e-3;
    pub(crate) const S3: f64 = -1.984_126_982_985_794_931_34e-4;
    pub(crate) const S4: f64 = 2.755_731_370_707_006_767_89e-6;
    pub(crate) const S5: f64 = -2.505_076_025_340_686_341_95e-8;
    pub(crate) const S6: f64 = 1.589_690_995_211_550_102_21e-10;
    pub(crate) const C1: f64 = 4.166_666_666_666_660_190_37e-2;
    pub(crate) const C2: f64 = -1.388_888_888_887_410_957_49e-3;
    pub(crate) const C3: f64 = 2.480_158_728_947_672_941_78e-5;
    pub(crate) const C4: f64 = -2.755_731_435_139_066_330_35e-7;
    pub(crate) const C5: f64 = 2.087_572_321_298_174_827_90e-9;
    pub(crate) const C6: f64 = -1.135_964_755_778_819_482_65e-11;
}
use kernel::{C1, C2, C3, C4, C5, C6, S1, S2, S3, S4, S5, S6};

/// `(sin x, cos x)` for `|x| <= REDUCED_UP_TO`, without a branch on `x`.
#[inline(always)]
fn reduced(x: f64) -> (f64, f64) {
    let t = x * std::f64::consts::FRAC_2_PI + ROUNDER;
    let quadrant = t.to_bits() & 3;
    let k = t - ROUNDER;
    let r = (-k).mul_add(PIO2_HI, x);
    let r = (-k).mul_add(PIO2_MID, r);
    // With k = 0 the last term is a signed zero that would turn sin(-0) into +0.
    let r = if k.abs() < 0.5 {
        r
    } else {
        (-k).mul_add(PIO2_LO, r)
    };
    let z = r * r;
    let w = z * z;
    let poly_s = S2 + z * (S3 + z * S4) + z * w * (S5 + z * S6);
    // Below 2^-27, sin r rounds to r itself (fdlibm returns it there too), and the
    // polynomial would turn -0 into +0.
    let s = if r.abs() < TINY {
        r
    } else {
        r + z * r * (S1 + z * poly_s)
    };
    let poly_c = z * (C1 + z * (C2 + z * C3)) + w * w * (C4 + z * (C5 + z * C6));
    let half = 0.5 * z;
    let one_minus = 1.0 - half;
    let c = one_minus + (((1.0 - one_minus) - half) + z * poly_c);
    // x = k pi/2 + r: quadrants 1 and 3 swap sine and cosine; the sine is negative in
    // quadrants 2 and 3, the cosine in 1 and 2.
    let (s, c) = if quadrant & 1 == 1 { (c, s) } else { (s, c) };
    let sin = f64::from_bits(s.to_bits() ^ ((quadrant & 2) << 62));
    let cos = f64::from_bits(c.to_bits() ^ (((quadrant + 1) & 2) << 62));
    (sin, cos)
}

/// Whether `x` is reduced here (else the C library answers).
#[inline(always)]
fn in_range(x: f64) -> bool {
    x.abs() <= REDUCED_UP_TO
}

/// One of the pair, `pick`, for `x`: the reduction here, the C library's `libm` beyond it.
#[inline(always)]
fn one(x: f64, pick: impl Fn((f64, f64)) -> f64, libm: impl Fn(f64) -> f64) -> f64 {
    if in_range(x) {
        pick(reduced(x))
    } else {
        libm(x)
    }
}

/// [`one`] over a slice: every argument through the branch-free reduction (so the loop
/// vectorises), then the few beyond its range again through the C library.
#[inline(always)]
fn many(x: &[f64], out: &mut [f64], pick: impl Fn((f64, f64)) -> f64, libm: impl Fn(f64) -> f64) {
    let out = &mut out[..x.len()];
    for (o, &v) in out.iter_mut().zip(x) {
        *o = pick(reduced(v));
    }
    for (o, &v) in out.iter_mut().zip(x) {
        if !in_range(v) {
            *o = libm(v);
        }
    }
}

/// `sin x`, the same bits as [`sin_many`] gives for `x`.
#[inline]
pub fn sin(x: f64) -> f64 {
    one(x, |(s, _)| s, f64::sin)
}

/// `cos x`, the same bits as [`cos_many`] gives for `x`.
#[inline]
pub fn cos(x: f64) -> f64 {
    one(x, |(_, c)| c, f64::cos)
}

/// `out[i] = sin(x[i])` for every `i < x.len()`.
///
/// # Panics
/// If `out` is shorter than `x`.
pub fn sin_many(x: &[f64], out: &mut [f64]) {
    many(x, out, |(s, _)| s, f64::sin);
}

/// `out[i] = cos(x[i])` for every `i < x.len()`.
///
/// # Panics
/// If `out` is shorter than `x`.
pub fn cos_many(x: &[f64], out: &mut [f64]) {
    many(x, out, |(_, c)| c, f64::cos);
}
