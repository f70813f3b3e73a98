use std::collections::BTreeSet;
use std::fmt;
use std::ops::Range;

use crate::error::ExprError;
use crate::func::{BinOp, Func};

/// A parsed scalar expression: a tree of numbers, variables, operators and function calls.
///
/// Equality is structural: two trees are equal when they have the same shape, the same names
/// and bit-identical numbers; the source positions of variables are ignored, so
/// `parse("x")? == Expr::var("x")`. Make one with [`parse`](crate::parse), [`Expr::constant`] or
/// [`Expr::var`].
#[derive(Clone, Debug)]
pub struct Expr(pub(crate) Node);

#[derive(Clone, Debug)]
pub(crate) enum Node {
    Num(f64),
    /// A variable and where it appears in its source (`0..0` when it has none).
    Var(String, Range<usize>),
    Neg(Box<Expr>),
    Bin(BinOp, Box<Expr>, Box<Expr>),
    Call(Func, Vec<Expr>),
}

impl PartialEq for Node {
    fn eq(&self, other: &Node) -> bool {
        match (self, other) {
            // Bitwise, so that equality is an equivalence relation (NaN == NaN) and -0 != 0.
            (Node::Num(a), Node::Num(b)) => a.to_bits() == b.to_bits(),
            (Node::Var(a, _), Node::Var(b, _)) => a == b,
            (Node::Neg(a), Node::Neg(b)) => a == b,
            (Node::Bin(o, a, b), Node::Bin(p, c, d)) => o == p && a == c && b == d,
            (Node::Call(f, a), Node::Call(g, b)) => f == g && a == b,
            _ => false,
        }
    }
}

impl PartialEq for Expr {
    fn eq(&self, other: &Expr) -> bool {
        self.0 == other.0
    }
}

impl Expr {
    /// A number.
    pub fn constant(v: f64) -> Expr {
        Expr(Node::Num(v))
    }

    /// A variable with no source position. The name should be an identifier
    /// (`[A-Za-z_][A-Za-z0-9_]*`, not a function name nor `pi`), or [`Display`](fmt::Display)
    /// output will not parse back.
    pub fn var(name: &str) -> Expr {
        Expr(Node::Var(name.to_owned(), 0..0))
    }

    /// The sum `self + other` (unsimplified).
    pub fn plus(self, other: Expr) -> Expr {
        Expr::bin(BinOp::Add, self, other)
    }

    /// The difference `self - other` (unsimplified).
    pub fn minus(self, other: Expr) -> Expr {
        Expr::bin(BinOp::Sub, self, other)
    }

    /// The product `self * other` (unsimplified).
    pub fn times(self, other: Expr) -> Expr {
        Expr::bin(BinOp::Mul, self, other)
    }

    /// The quotient `self / other` (unsimplified).
    pub fn over(self, other: Expr) -> Expr {
        Expr::bin(BinOp::Div, self, other)
    }

    pub(crate) fn neg(a: Expr) -> Expr {
        Expr(Node::Neg(Box::new(a)))
    }

    pub(crate) fn bin(op: BinOp, a: Expr, b: Expr) -> Expr {
        Expr(Node::Bin(op, Box::new(a), Box::new(b)))
    }

    pub(crate) fn call(f: Func, args: Vec<Expr>) -> Expr {
        Expr(Node::Call(f, args))
    }

    pub(crate) fn num(&self) -> Option<f64> {
        match self.0 {
            Node::Num(v) => Some(v),
            _ => None,
        }
    }

    pub(crate) fn is_num(&self, v: f64) -> bool {
        self.num()
            .is_some_and(|x| x.to_bits() == v.to_bits() || (v == 0.0 && x == 0.0))
    }

    /// Every variable name the expression uses.
    pub fn variables(&self) -> BTreeSet<String> {
        let mut names = BTreeSet::new();
        self.visit_vars(&mut |name, _| {
            names.insert(name.to_owned());
        });
        names
    }

    /// The additive terms of the expression: a sum or difference is split into its operands'
    /// terms (the subtracted ones negated), a negation negates each term, and a quotient splits
    /// its numerator's terms, each over the same denominator; anything else is one term.
    /// Products are not multiplied out, so `-k*(x - x0)` stays one term. The terms add up to
    /// the expression: `(-m*g + s - c*v)/m` gives `-m*g/m`, `s/m` and `-(c*v)/m`.
    pub fn terms(&self) -> Vec<Expr> {
        match &self.0 {
            Node::Bin(BinOp::Add, a, b) => {
                let mut t = a.terms();
                t.extend(b.terms());
                t
            }
            Node::Bin(BinOp::Sub, a, b) => {
                let mut t = a.terms();
                t.extend(b.terms().into_iter().map(Expr::neg));
                t
            }
            Node::Neg(a) => a.terms().into_iter().map(Expr::neg).collect(),
            Node::Bin(BinOp::Div, a, b) => a
                .terms()
                .into_iter()
                .map(|t| Expr::bin(BinOp::Div, t, (**b).clone()))
                .collect(),
            _ => vec![self.clone()],
        }
    }

    /// Whether the expression uses the variable `name`.
    pub fn depends_on(&self, name: &str) -> bool {
        match &self.0 {
            Node::Num(_) => false,
            Node::Var(n, _) => n == name,
            Node::Neg(a) => a.depends_on(name),
            Node::Bin(_, a, b) => a.depends_on(name) || b.depends_on(name),
            Node::Call(_, args) => args.iter().any(|a| a.depends_on(name)),
        }
    }

    /// Where the variable `name` first appears in the source, as 0-based character offsets.
    /// `None` if it is not used, or only where it has no source (made by [`Expr::var`]).
    /// After [`Expr::substitute`], positions inside the substituted expression refer to *its*
    /// source.
    pub fn span_of(&self, name: &str) -> Option<Range<usize>> {
        let mut first: Option<Range<usize>> = None;
        self.visit_vars(&mut |n, span| {
            let earlier = first.as_ref().map_or(true, |f| span.start < f.start);
            if n == name && !span.is_empty() && earlier {
                first = Some(span.clone());
            }
        });
        first
    }

    pub(crate) fn visit_vars(&self, f: &mut dyn FnMut(&str, &Range<usize>)) {
        match &self.0 {
            Node::Num(_) => {}
            Node::Var(n, span) => f(n, span),
            Node::Neg(a) => a.visit_vars(f),
            Node::Bin(_, a, b) => {
                a.visit_vars(f);
                b.visit_vars(f);
            }
            Node::Call(_, args) => args.iter().for_each(|a| a.visit_vars(f)),
        }
    }

    /// The expression with every occurrence of the variable `name` replaced by `with`; used to
    /// inline named definitions. Not simplified.
    pub fn substitute(&self, name: &str, with: &Expr) -> Expr {
        match &self.0 {
            Node::Var(n, _) if n == name => with.clone(),
            Node::Num(_) | Node::Var(..) => self.clone(),
            Node::Neg(a) => Expr::neg(a.substitute(name, with)),
            Node::Bin(op, a, b) => {
                Expr::bin(*op, a.substitute(name, with), b.substitute(name, with))
            }
            Node::Call(f, args) => {
                Expr::call(*f, args.iter().map(|a| a.substitute(name, with)).collect())
            }
        }
    }

    /// The value, if the expression uses no variable after [`Expr::simplify`]. (`0 * x`
    /// simplifies to `0`, so it is a constant.)
    pub fn as_constant(&self) -> Option<f64> {
        self.simplify().num()
    }

    /// Evaluates by walking the tree, asking `lookup` for each variable's value. Slow; it is
    /// the obvious reference that the compiled [`Program`](crate::Program) is tested against.
    ///
    /// # Errors
    ///
    /// [`ExprError::UnknownVariable`] (with the variable's span) when `lookup` returns `None`.
    pub fn eval_with(&self, lookup: &dyn Fn(&str) -> Option<f64>) -> Result<f64, ExprError> {
        Ok(match &self.0 {
            Node::Num(v) => *v,
            Node::Var(n, span) => lookup(n).ok_or_else(|| ExprError::UnknownVariable {
                span: span.clone(),
                name: n.clone(),
                suggestion: None,
            })?,
            Node::Neg(a) => -a.eval_with(lookup)?,
            Node::Bin(op, a, b) => op.apply(a.eval_with(lookup)?, b.eval_with(lookup)?),
            Node::Call(f, args) => {
                let mut v = [0.0; 3];
                for (slot, a) in v.iter_mut().zip(args) {
                    *slot = a.eval_with(lookup)?;
                }
                f.apply(v[0], v[1], v[2])
            }
        })
    }

    /// Binding strength, for printing: 1 comparison, 2 `+ -`, 3 `* /`, 4 unary minus,
    /// 5 `^`, 6 atoms.
    fn precedence(&self) -> u8 {
        match &self.0 {
            Node::Num(v) if v.is_finite() && v.is_sign_negative() => 4,
            Node::Num(_) | Node::Var(..) | Node::Call(..) => 6,
            Node::Neg(_) => 4,
            Node::Bin(op, ..) => match op {
                BinOp::Add | BinOp::Sub => 2,
                BinOp::Mul | BinOp::Div => 3,
                BinOp::Pow => 5,
                _ => 1,
            },
        }
    }

    fn write_operand(&self, f: &mut fmt::Formatter<'_>, min: u8, right: bool) -> fmt::Result {
        // `a * -b` parses, but `a * (-b)` reads better.
        let paren = self.precedence() < min || (right && self.precedence() == 4);
        if paren {
            write!(f, "({self})")
        } else {
            write!(f, "{self}")
        }
    }
}

/// Prints text that parses back to a tree evaluating bit-identically (`parse(&e.to_string())`),
/// with as few parentheses as the precedence rules allow. Non-finite numbers print as `(1/0)`,
/// `(-1/0)` and `(0/0)`.
impl fmt::Display for Expr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.0 {
            Node::Num(v) => write_number(f, *v),
            Node::Var(n, _) => f.write_str(n),
            Node::Neg(a) => {
                f.write_str("-")?;
                a.write_operand(f, 4, false)
            }
            Node::Bin(op, a, b) => {
                let (left, right, spaced) = match op {
                    BinOp::Add | BinOp::Sub => (2, 3, true),
                    BinOp::Mul | BinOp::Div => (3, 4, false),
                    // Right-associative, and the exponent may carry a sign.
                    BinOp::Pow => (6, 4, false),
                    _ => (2, 2, true),
                };
                a.write_operand(f, left, false)?;
                if spaced {
                    write!(f, " {} ", op.symbol())?;
                } else {
                    f.write_str(op.symbol())?;
                }
                b.write_operand(f, right, true)
            }
            Node::Call(func, args) => {
                write!(f, "{}(", func.name())?;
                for (i, a) in args.iter().enumerate() {
                    if i > 0 {
                        f.write_str(", ")?;
                    }
                    write!(f, "{a}")?;
                }
                f.write_str(")")
            }
        }
    }
}

fn write_number(f: &mut fmt::Formatter<'_>, v: f64) -> fmt::Result {
    if v.is_nan() {
        f.write_str("(0/0)")
    } else if v.is_infinite() {
        f.write_str(if v > 0.0 { "(1/0)" } else { "(-1/0)" })
    } else if v.abs().to_bits() == std::f64::consts::PI.to_bits() {
        f.write_str(if v < 0.0 { "-pi" } else { "pi" })
    } else if v.fract() == 0.0 && v.abs() < 1e15 {
        // Whole numbers without a trailing `.0`; `{}` keeps the sign of -0.
        write!(f, "{v}")
    } else {
        // `{:?}` is the shortest text that reads back to the same bits, with an exponent for
        // very large and very small magnitudes.
        write!(f, "{v:?}")
    }
}
