//! The operators and functions, and the one definition of their values that the tree walk,
//! constant folding and the compiled program all share (so the three cannot disagree).

/// Binary operators of the grammar.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum BinOp {
    Add,
    Sub,
    Mul,
    Div,
    Pow,
    Lt,
    Le,
    Gt,
    Ge,
}

impl BinOp {
    pub(crate) fn apply(self, a: f64, b: f64) -> f64 {
        match self {
            BinOp::Add => a + b,
            BinOp::Sub => a - b,
            BinOp::Mul => a * b,
            BinOp::Div => a / b,
            BinOp::Pow => pow(a, b),
            BinOp::Lt => bool_value(a < b),
            BinOp::Le => bool_value(a <= b),
            BinOp::Gt => bool_value(a > b),
            BinOp::Ge => bool_value(a >= b),
        }
    }

    pub(crate) fn symbol(self) -> &'static str {
        match self {
            BinOp::Add => "+",
            BinOp::Sub => "-",
            BinOp::Mul => "*",
            BinOp::Div => "/",
            BinOp::Pow => "^",
            BinOp::Lt => "<",
            BinOp::Le => "<=",
            BinOp::Gt => ">",
            BinOp::Ge => ">=",
        }
    }

    pub(crate) fn is_comparison(self) -> bool {
        matches!(self, BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge)
    }
}

/// `a^b`. The exponent 0.5 means `sqrt`, which the compiled program uses for it: the two
/// differ only at `a = -inf` (powf gives +inf, sqrt NaN) and `a = -0` (+0 against -0).
#[inline]
pub(crate) fn pow(a: f64, b: f64) -> f64 {
    if b.to_bits() == 0.5f64.to_bits() {
        a.sqrt()
    } else {
        a.powf(b)
    }
}

fn bool_value(b: bool) -> f64 {
    if b {
        1.0
    } else {
        0.0
    }
}

macro_rules! functions {
    ($($variant:ident $name:literal $arity:literal,)*) => {
        /// Built-in functions. `pow(a, b)` is parsed as `a ^ b` and `log` as `ln`, so neither
        /// appears here.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub(crate) enum Func { $($variant,)* }

        impl Func {
            pub(crate) const ALL: &'static [Func] = &[$(Func::$variant,)*];

            pub(crate) fn name(self) -> &'static str {
                match self { $(Func::$variant => $name,)* }
            }

            pub(crate) fn arity(self) -> usize {
                match self { $(Func::$variant => $arity,)* }
            }
        }
    };
}

functions! {
    Sin "sin" 1,
    Cos "cos" 1,
    Tan "tan" 1,
    Asin "asin" 1,
    Acos "acos" 1,
    Atan "atan" 1,
    Sinh "sinh" 1,
    Cosh "cosh" 1,
    Tanh "tanh" 1,
    Exp "exp" 1,
    Ln "ln" 1,
    Log10 "log10" 1,
    Sqrt "sqrt" 1,
    Abs "abs" 1,
    Sign "sign" 1,
    Step "step" 1,
    Pos "pos" 1,
    Sat "sat" 1,
    Min "min" 2,
    Max "max" 2,
    Atan2 "atan2" 2,
    Hypot "hypot" 2,
    Clamp "clamp" 3,
    If "if" 3,
}

/// What a name followed by `(` means.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Callee {
    Func(Func),
    /// `pow(a, b)`, the same as `a ^ b`.
    Pow,
}

impl Callee {
    pub(crate) fn lookup(name: &str) -> Option<Callee> {
        match name {
            "pow" => Some(Callee::Pow),
            "log" => Some(Callee::Func(Func::Ln)),
            _ => Func::ALL
                .iter()
                .find(|f| f.name() == name)
                .map(|&f| Callee::Func(f)),
        }
    }

    pub(crate) fn arity(self) -> usize {
        match self {
            Callee::Func(f) => f.arity(),
            Callee::Pow => 2,
        }
    }

    /// Every callable name, for suggestions.
    pub(crate) fn names() -> impl Iterator<Item = &'static str> {
        Func::ALL.iter().map(|f| f.name()).chain(["pow", "log"])
    }
}

impl Func {
    /// The function's value; arguments past its arity are ignored.
    #[inline]
    pub(crate) fn apply(self, a: f64, b: f64, c: f64) -> f64 {
        match self {
            Func::Sin => htfid_trig::sin(a),
            Func::Cos => htfid_trig::cos(a),
            Func::Tan => a.tan(),
            Func::Asin => a.asin(),
            Func::Acos => a.acos(),
            Func::Atan => a.atan(),
            Func::Sinh => a.sinh(),
            Func::Cosh => a.cosh(),
            Func::Tanh => a.tanh(),
            Func::Exp => a.exp(),
            Func::Ln => a.ln(),
            Func::Log10 => a.log10(),
            Func::Sqrt => a.sqrt(),
            Func::Abs => a.abs(),
            // f64::signum gives +-1 at +-0; the model language wants sign(0) = 0 (and NaN stays NaN).
            Func::Sign => {
                if a > 0.0 {
                    1.0
                } else if a < 0.0 {
                    -1.0
                } else {
                    a * 0.0
                }
            }
            Func::Step => bool_value(a > 0.0),
            Func::Pos => {
                if a > 0.0 {
                    a
                } else {
                    0.0
                }
            }
            Func::Sat => clamp(a, -1.0, 1.0),
            Func::Min => {
                if a < b {
                    a
                } else {
                    b
                }
            }
            Func::Max => {
                if a > b {
                    a
                } else {
                    b
                }
            }
            Func::Atan2 => a.atan2(b),
            Func::Hypot => a.hypot(b),
            Func::Clamp => clamp(a, b, c),
            Func::If => {
                if a > 0.0 {
                    b
                } else {
                    c
                }
            }
        }
    }
}

/// `clamp(x, lo, hi)`: at a tie the bound is taken (which matters only for the derivative), and
/// `x <= lo` is tested first, so `lo > hi` gives `lo` below `lo` and `hi` above it.
#[inline]
fn clamp(x: f64, lo: f64, hi: f64) -> f64 {
    if x <= lo {
        lo
    } else if x >= hi {
        hi
    } else {
        x
    }
}
