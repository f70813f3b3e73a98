//! Shared test helpers: a seeded xorshift generator (no `rand` dependency) and a generator of
//! random expression text.

#![allow(dead_code)] // each test binary uses a different subset

/// Marsaglia's xorshift64*: deterministic, good enough to pick tokens and points.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed.max(1))
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// Uniform in `0..n`.
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    /// Uniform in `[lo, hi)`.
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        let u = (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        lo + (hi - lo) * u
    }

    pub fn pick<'a>(&mut self, items: &[&'a str]) -> &'a str {
        items[self.below(items.len())]
    }
}

pub const VARS: [&str; 3] = ["x", "y", "z"];

/// Random well-formed expression text over `VARS`, using every operator and function.
pub fn random_expr(rng: &mut Rng, depth: usize) -> String {
    random_expr_with(rng, depth, ALL_POWERS)
}

/// Constant exponents used by [`random_expr`].
pub const ALL_POWERS: &[&str] = &["2", "3", "-1", "-2", "0.5", "1.5", "-0.5", "2.7", "4", "y"];

/// Exponents whose compiled form rounds exactly once, as `powf` does: `x*x`, `1/x`, `sqrt(x)`
/// and `powf` itself. Other small integers and halves are compiled to chains of
/// multiplications, a few units in the last place away from `powf`.
pub const SINGLE_ROUNDING_POWERS: &[&str] = &["2", "-1", "0.5", "2.7", "y"];

/// [`random_expr`] with the constant exponents drawn from `powers`.
pub fn random_expr_with(rng: &mut Rng, depth: usize, powers: &[&str]) -> String {
    if depth == 0 || rng.below(5) == 0 {
        return match rng.below(4) {
            0 => format!("{}", (rng.uniform(-3.0, 3.0) * 100.0).round() / 100.0),
            1 => "pi".to_owned(),
            _ => rng.pick(&VARS).to_owned(),
        };
    }
    let a = random_expr_with(rng, depth - 1, powers);
    let b = random_expr_with(rng, depth - 1, powers);
    match rng.below(16) {
        0 => format!("{a} + ({b})"),
        1 => format!("({a}) - ({b})"),
        2 => format!("({a})*({b})"),
        3 => format!("({a})/({b})"),
        4 => format!("-({a})"),
        5 => {
            let p = rng.pick(powers);
            format!("({a})^{p}")
        }
        6 => format!("({a}) < ({b})"),
        7 => format!("({a}) >= ({b})"),
        8 => format!("pow({a}, {b})"),
        9 => {
            let f = rng.pick(&["min", "max", "atan2", "hypot"]);
            format!("{f}({a}, {b})")
        }
        10 => {
            let c = random_expr_with(rng, depth - 1, powers);
            let f = rng.pick(&["clamp", "if"]);
            format!("{f}({a}, {b}, {c})")
        }
        _ => {
            let f = rng.pick(&[
                "sin", "cos", "tan", "asin", "acos", "atan", "sinh", "cosh", "tanh", "exp", "ln",
                "log", "log10", "sqrt", "abs", "sign", "step", "pos", "sat",
            ]);
            format!("{f}({a})")
        }
    }
}

/// Whether two results agree to `rel` relative tolerance, NaN matching NaN and infinities
/// matching exactly.
pub fn close(a: f64, b: f64, rel: f64) -> bool {
    if a.is_nan() || b.is_nan() {
        return a.is_nan() && b.is_nan();
    }
    if a.is_infinite() || b.is_infinite() {
        return a.to_bits() == b.to_bits();
    }
    (a - b).abs() <= rel * a.abs().max(b.abs())
}

/// Lookup for `eval_with` over `VARS`.
pub fn lookup(vals: [f64; 3]) -> impl Fn(&str) -> Option<f64> {
    move |n: &str| VARS.iter().position(|v| *v == n).map(|i| vals[i])
}
