//! Scalar math expressions for model files: parsing with located errors, exact symbolic
//! derivatives, and a compiled evaluator for the hot loop.
//!
//! [`parse`] turns text such as `(-m*g - c*v - k*(x - x0))/m` into an [`Expr`], or an
//! [`ExprError`] that says where (character offsets, [`ExprError::column`]) and what was
//! expected. An [`Expr`] can be simplified, differentiated ([`Expr::derivative`]), have named
//! definitions substituted into it and be printed back as parseable text. [`Program::compile`]
//! turns several expressions over one variable layout (states, time, parameters: all are
//! variables, read from one slice or written in place through [`Variables`]) into a flat
//! register program; [`Program::eval`] computes all of them at once without allocating.
//! Subexpressions shared between the expressions, as between a vector field and its Jacobian,
//! are computed once.
//!
//! ```
//! use htfid_expr::{parse, Program};
//!
//! let f = parse("-k*x^2 + a*cos(w*t)")?;
//! let dfdx = f.derivative("x");
//! assert_eq!(dfdx.to_string(), "-(k*(2*x))");
//!
//! let vars = ["t", "x", "k", "a", "w"];
//! let program = Program::compile(&[f, dfdx], &vars)?;
//! let mut out = [0.0; 2];
//! program.eval(&[0.0, 3.0, 0.5, 2.0, 1.0], &mut out);
//! assert!((out[0] - (-4.5 + 2.0)).abs() < 1e-12);
//! assert!((out[1] - (-3.0)).abs() < 1e-12);
//!
//! let err = parse("k*(x + ").unwrap_err();
//! assert_eq!(err.column(), Some(8));
//! assert_eq!(err.to_string(), "expected a number, a name or `(`, found end of input");
//! # Ok::<(), htfid_expr::ExprError>(())
//! ```
//!
//! # Syntax
//!
//! - Numbers `2`, `2.5`, `.5`, `1e-3`, `2.5E+4`; names `[A-Za-z_][A-Za-z0-9_]*`; whitespace
//!   anywhere between tokens.
//! - Operators, tightest first: `^` (right-associative, and tighter than a sign: `-x^2` is
//!   `-(x^2)`, `2^3^2` is `2^9`, `2^-1` is allowed); unary `-` and `+`; `*` and `/`; `+` and `-`
//!   (left-associative); comparisons `<`, `<=`, `>`, `>=`, loosest and not chainable, worth
//!   1 or 0.
//! - The only constant is `pi`. There is no `e`: models use `e` as a parameter name.
//! - Functions (arity checked when parsing): `sin cos tan asin acos atan sinh cosh tanh exp
//!   ln log10 sqrt abs`, `log` (natural, the same as `ln`), `sign` (with `sign(0) = 0`),
//!   `step(x)` (1 if `x > 0`, else 0), `pos(x)` (`max(x, 0)`), `sat(x)` (`clamp(x, -1, 1)`),
//!   `min(a, b)`, `max(a, b)`, `atan2(y, x)`, `pow(a, b)` (the same as `a^b`), `hypot(a, b)`,
//!   `clamp(x, lo, hi)`, `if(c, a, b)` (`a` if `c > 0`, else `b`). A function name used without
//!   parentheses is an error.
//!
//! # Derivative conventions
//!
//! Derivatives are exact for the smooth functions. At a kink the derivative is the one of the
//! branch that produced the value, with ties resolved as the value is:
//! `min(a, b)` is `a` if `a < b` else `b`, so on a tie its derivative is `b'`; likewise
//! `max(a, b)` (`a` if `a > b`); `clamp(x, lo, hi)` takes the bound at a tie, so its
//! derivative there is `lo'` or `hi'`; `sat'(+-1) = 0`; `pos'(x) = step(x)` (0 at 0);
//! `abs' = sign` (0 at 0); `if(c, a, b)' = if(c, a', b')`; `sign`, `step` and comparisons have
//! derivative 0 (the Dirac masses are dropped). `a^b` with `b` free of the variable is
//! `b a^(b-1) a'`, with no logarithm, so `x^2` differentiates to `2*x` for every `x`.
//!
//! # Numerics and limits
//!
//! - [`Expr::simplify`] folds constants and applies identities exact in floating point, except
//!   `x*0 = 0` and `x - x = 0`, which also hold for infinite `x` here.
//! - `x^0.5` (and `pow(x, 0.5)`) is `sqrt(x)` everywhere, so `(-inf)^0.5` is NaN, not +inf as
//!   in `f64::powf`.
//! - The compiled program may differ from [`Expr::eval_with`] by a few units in the last place
//!   in one respect: it computes `x^n` for integers `|n| <= 32` by repeated multiplication and
//!   other halves `x^(k/2)` through `sqrt`. Everything else (folding, sharing, commuting
//!   `a + b` to `b + a`, fusing `a*b + c` into one instruction with two roundings) is
//!   bit-identical.
//! - Parsed trees are at most 256 levels deep ([`ExprError::TooDeep`]), so no input string can
//!   overflow the stack. [`Expr::derivative`] and [`Expr::substitute`] build deeper trees by
//!   a small factor; do not nest substitutions without bound.
//! - Spans count characters, not bytes. Variables built by [`Expr::var`] have none.
//!
//! # Performance
//!
//! [`Program::eval`] interprets a flat list of register instructions; products used once are
//! fused into their consumer (`a*b + c`, `c - a*b`, `a*b/c`, ...). The hopper's vector field
//! with its 2x2 Jacobian (6 outputs, 13 instructions) takes about 51 ns against 15.5 ns
//! written by hand in Rust; `cargo bench -p htfid-expr --bench eval` prints the table, and
//! docs/expressions.md records it with a comparison against the `exmex` crate.

mod error;
mod expr;
mod func;
mod parse;
mod program;
mod simplify;

pub use error::ExprError;
pub use expr::Expr;
pub use parse::parse;
pub use program::{Program, Variables};
