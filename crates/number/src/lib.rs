//! Numbers for people: one place decides how a value, its standard error and its unit read,
//! on the terminal and in every report.
//!
//! - A bare number keeps a given count of significant digits ([`sig`]), in plain notation
//!   between 1e-3 and 1e5 and as `1.234 × 10⁻⁶` outside, never dropping integer digits
//!   (`10002`, not `1.000 × 10⁴`).
//! - A value with a standard error ([`Quantity`]) is shown to the precision the error allows:
//!   the error to one significant digit (two when that digit would be a 1, where rounding to
//!   one digit would move it by up to 50 %), the value to the same decimal place, at most six
//!   significant digits: `1.999 ± 0.001 N s/m`, `(2.13 ± 0.05) × 10⁻⁵ m`.
//! - A missing value (NaN, infinite) reads `—`; the table that shows it says why.

use std::fmt;

/// What a report writes where a number is missing; each report explains it in a footnote.
pub const MISSING: &str = "—";

/// Largest count of significant digits a value with a standard error is given.
const MAX_DIGITS: i32 = 6;

/// A value with an optional standard error and an optional unit, formatted for a reader.
#[derive(Debug, Clone, Copy)]
pub struct Quantity<'a> {
    value: f64,
    stderr: Option<f64>,
    unit: Option<&'a str>,
    digits: usize,
}

impl<'a> Quantity<'a> {
    /// A value alone, with 4 significant digits.
    pub fn new(value: f64) -> Self {
        Quantity {
            value,
            stderr: None,
            unit: None,
            digits: 4,
        }
    }

    /// With its standard error: a non-finite one reads "(no standard error)".
    pub fn stderr(mut self, stderr: f64) -> Self {
        self.stderr = Some(stderr);
        self
    }

    /// In `unit` (`None`, `""` or the dimensionless `"1"` for none).
    pub fn unit(mut self, unit: Option<&'a str>) -> Self {
        self.unit = unit.filter(|u| !u.is_empty() && *u != "1");
        self
    }

    /// Significant digits of a value shown without a standard error (4 unless set).
    pub fn digits(mut self, digits: usize) -> Self {
        self.digits = digits.max(1);
        self
    }
}

impl fmt::Display for Quantity<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if !self.value.is_finite() {
            return f.write_str(MISSING);
        }
        let unit = self.unit.map_or(String::new(), |u| format!(" {u}"));
        match self.stderr {
            Some(s) if s.is_finite() && s > 0.0 => write!(f, "{}{unit}", with_error(self.value, s)),
            Some(0.0) => write!(f, "{} ± 0{unit}", sig(self.value, self.digits)),
            Some(_) => write!(
                f,
                "{}{unit} (no standard error)",
                sig(self.value, self.digits)
            ),
            None => write!(f, "{}{unit}", sig(self.value, self.digits)),
        }
    }
}

/// `x` with `digits` significant digits: plain between 1e-3 and 1e5 (integer digits are never
/// rounded away), else `m × 10^p` with a superscript exponent. `—` when not finite.
pub fn sig(x: f64, digits: usize) -> String {
    if !x.is_finite() {
        return MISSING.into();
    }
    if x == 0.0 {
        return "0".into();
    }
    let digits = digits.max(1) as i32;
    let mut q = magnitude(x) - digits + 1;
    let mag = magnitude(round_at(x, q));
    if mag > magnitude(x) {
        // Rounding carried into a new leading digit (9.9996 -> 10.00): one digit less behind.
        q += 1;
    }
    if plain(mag) {
        fixed(x, q.min(0))
    } else {
        let scale = 10f64.powi(mag);
        format!("{} {}", fixed(x / scale, q - mag), power_of_ten(mag))
    }
}

/// A fraction as a percentage with `digits` significant digits: `0.01234` -> `1.23 %`.
pub fn percent(fraction: f64, digits: usize) -> String {
    if !fraction.is_finite() {
        return MISSING.into();
    }
    format!("{} %", sig(100.0 * fraction, digits))
}

/// `value ± stderr`, both at the last decimal place the error's leading digits reach.
fn with_error(value: f64, stderr: f64) -> String {
    let e = magnitude(stderr);
    let leading = (stderr / 10f64.powi(e)).floor();
    let kept = if leading < 2.0 { 2 } else { 1 };
    let mut q = e - kept + 1;
    if kept == 1 && magnitude(round_at(stderr, q)) > e {
        // 0.00096 rounds to 0.001: one digit, a place further left.
        q += 1;
    }
    let top = magnitude(value.abs().max(stderr));
    // A value known far better than six digits shows six, and its error on its own terms.
    let (q, error) = if top - q + 1 > MAX_DIGITS {
        let q = top - MAX_DIGITS + 1;
        (q, None)
    } else {
        (q, Some(q))
    };
    if plain(top) {
        let s = match error {
            Some(q) => fixed(round_at(stderr, q), q.min(0)),
            None => sig(stderr, kept as usize),
        };
        format!("{} ± {s}", fixed(round_at(value, q), q.min(0)))
    } else {
        let scale = 10f64.powi(top);
        let s = match error {
            Some(q) => fixed(round_at(stderr, q) / scale, q - top),
            None => sig(stderr / scale, kept as usize),
        };
        format!(
            "({} ± {s}) {}",
            fixed(round_at(value, q) / scale, q - top),
            power_of_ten(top)
        )
    }
}

/// Decimal exponent of the leading digit: 0.05 -> -2, 12.0 -> 1.
fn magnitude(x: f64) -> i32 {
    let x = x.abs();
    let m = x.log10().floor() as i32;
    // log10 may land a hair off an exact power of ten.
    if 10f64.powi(m + 1) <= x {
        m + 1
    } else if 10f64.powi(m) > x {
        m - 1
    } else {
        m
    }
}

fn plain(mag: i32) -> bool {
    (-3..5).contains(&mag)
}

/// `x` rounded to a multiple of `10^q`.
fn round_at(x: f64, q: i32) -> f64 {
    if q >= 0 {
        let s = 10f64.powi(q);
        (x / s).round() * s
    } else {
        let s = 10f64.powi(-q);
        (x * s).round() / s
    }
}

/// `x` with `-q` decimals (none for `q >= 0`); a value that rounds to zero loses its sign.
fn fixed(x: f64, q: i32) -> String {
    let decimals = (-q).max(0) as usize;
    let text = format!("{x:.decimals$}");
    match text.strip_prefix('-') {
        Some(rest) if rest.chars().all(|c| c == '0' || c == '.') => rest.to_string(),
        _ => text,
    }
}

/// `× 10⁻⁶`.
fn power_of_ten(p: i32) -> String {
    const SUPERSCRIPT: [char; 10] = ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'];
    let mut s = String::from("× 10");
    if p < 0 {
        s.push('⁻');
    }
    for c in p.unsigned_abs().to_string().chars() {
        s.push(SUPERSCRIPT[c as usize - '0' as usize]);
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn q(v: f64, s: f64, unit: &str) -> String {
        Quantity::new(v).stderr(s).unit(Some(unit)).to_string()
    }

    #[test]
    fn a_value_with_its_error_reads_to_the_errors_precision() {
        assert_eq!(q(1.998806, 9.62e-4, "N s/m"), "1.999 ± 0.001 N s/m");
        assert_eq!(q(10.0123, 0.05214, "N s/m"), "10.01 ± 0.05 N s/m");
        // A leading 1 keeps two digits: 0.0014, not 0.001.
        assert_eq!(q(200.04, 1.3, "N/m"), "200.0 ± 1.3 N/m");
        assert_eq!(q(0.2012, 0.0014, "N s/m"), "0.2012 ± 0.0014 N s/m");
        // An uncertain integer part is rounded too.
        assert_eq!(q(12345.0, 300.0, "N/m"), "12300 ± 300 N/m");
        // Zero keeps no sign.
        assert_eq!(q(-0.0004, 0.02, "m"), "0.00 ± 0.02 m");
        assert_eq!(q(-3.25, 0.5, "m"), "-3.3 ± 0.5 m");
    }

    #[test]
    fn very_small_or_large_values_share_one_power_of_ten() {
        assert_eq!(q(2.13e-5, 4.6e-7, "m"), "(2.13 ± 0.05) × 10⁻⁵ m");
        assert_eq!(q(-4.2e6, 1.5e5, "N/m^3"), "(-4.20 ± 0.15) × 10⁶ N/m^3");
    }

    #[test]
    fn a_value_known_to_more_than_six_digits_shows_six() {
        assert_eq!(q(2000.123456, 1.2e-6, "N/m"), "2000.12 ± 1.2 × 10⁻⁶ N/m");
    }

    #[test]
    fn missing_errors_and_values_say_so() {
        assert_eq!(q(1.0, f64::NAN, "kg"), "1.000 kg (no standard error)");
        assert_eq!(q(1.0, 0.0, "kg"), "1.000 ± 0 kg");
        assert_eq!(q(f64::NAN, 0.1, "kg"), "—");
        assert_eq!(Quantity::new(1.23456).to_string(), "1.235");
        assert_eq!(
            Quantity::new(1.23456).digits(3).unit(Some("s")).to_string(),
            "1.23 s"
        );
        assert_eq!(Quantity::new(2.0).unit(Some("")).to_string(), "2.000");
        assert_eq!(Quantity::new(0.8).unit(Some("1")).to_string(), "0.8000");
    }

    #[test]
    fn bare_numbers_keep_their_significant_digits() {
        assert_eq!(sig(10002.4, 4), "10002");
        assert_eq!(sig(10.0123, 4), "10.01");
        assert_eq!(sig(0.0521234, 3), "0.0521");
        assert_eq!(sig(9.9996, 4), "10.00");
        assert_eq!(sig(0.001, 3), "0.00100");
        assert_eq!(sig(-1.5e-6, 4), "-1.500 × 10⁻⁶");
        assert_eq!(sig(2.5e7, 3), "2.50 × 10⁷");
        assert_eq!(sig(0.0, 4), "0");
        assert_eq!(sig(f64::INFINITY, 4), "—");
    }

    #[test]
    fn fractions_read_as_percentages() {
        assert_eq!(percent(0.01234, 3), "1.23 %");
        assert_eq!(percent(0.5, 3), "50.0 %");
        assert_eq!(percent(1.2e-6, 2), "1.2 × 10⁻⁴ %");
        assert_eq!(percent(f64::NAN, 3), "—");
    }
}
