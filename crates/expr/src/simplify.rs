//! Algebraic simplification and symbolic differentiation.
//!
//! The rewrites are exact in floating point for finite values (`x + 0`, `x * 1`, `--x`,
//! `a - (-b) = a + b`, commuting a constant factor to the left), with two deliberate
//! exceptions that the derivative rules need to stay small: `x * 0 = 0` and `x - x = 0` also
//! for an infinite or NaN `x`. Constant subtrees are folded with the same arithmetic as
//! evaluation. Nothing is reassociated, so `2 * (3 * x)` stays as written.

use crate::expr::{Expr, Node};
use crate::func::{BinOp, Func};

impl Expr {
    /// Constant folding and the identities `x*0`, `x*1`, `x+0`, `x-0`, `0-x`, `x/1`, `0/x`,
    /// `x^1`, `x^0`, `--x`, `x-x`, `if(constant, a, b)`, `if(c, a, a)`, sign pushing through
    /// products and quotients.
    pub fn simplify(&self) -> Expr {
        match &self.0 {
            Node::Num(_) | Node::Var(..) => self.clone(),
            Node::Neg(a) => neg(a.simplify()),
            Node::Bin(op, a, b) => bin(*op, a.simplify(), b.simplify()),
            Node::Call(f, args) => call(*f, args.iter().map(Expr::simplify).collect()),
        }
    }

    /// The exact derivative with respect to the variable `name`, simplified. At the kinks of
    /// the non-smooth functions the derivative is that of the branch the value comes from (see
    /// the crate docs: `abs'(0) = sign(0) = 0`, `max(a, b)' = b'` on a tie, ...).
    pub fn derivative(&self, name: &str) -> Expr {
        self.simplify().diff(name).simplify()
    }

    /// Differentiates an already simplified tree.
    fn diff(&self, x: &str) -> Expr {
        if !self.depends_on(x) {
            return Expr::constant(0.0);
        }
        match &self.0 {
            Node::Num(_) => Expr::constant(0.0),
            Node::Var(n, _) => Expr::constant(if n == x { 1.0 } else { 0.0 }),
            Node::Neg(a) => neg(a.diff(x)),
            Node::Bin(op, a, b) => {
                let (u, v) = (a.as_ref(), b.as_ref());
                match op {
                    BinOp::Add => add(u.diff(x), v.diff(x)),
                    BinOp::Sub => sub(u.diff(x), v.diff(x)),
                    BinOp::Mul => add(mul(u.diff(x), v.clone()), mul(u.clone(), v.diff(x))),
                    BinOp::Div => {
                        if !v.depends_on(x) {
                            div(u.diff(x), v.clone())
                        } else {
                            // (u/v)' = u'/v - u v' / v^2, written as (u' - (u/v) v') / v so that
                            // it reuses u/v, which the compiled program already has.
                            div(sub(u.diff(x), mul(self.clone(), v.diff(x))), v.clone())
                        }
                    }
                    BinOp::Pow => {
                        if !v.depends_on(x) {
                            // b a^(b-1) a', without ln(a), so x^2 on x < 0 is fine.
                            let b1 = bin(BinOp::Sub, v.clone(), Expr::constant(1.0));
                            mul(mul(v.clone(), bin(BinOp::Pow, u.clone(), b1)), u.diff(x))
                        } else if !u.depends_on(x) {
                            mul(mul(self.clone(), ln(u.clone())), v.diff(x))
                        } else {
                            let t1 = mul(v.diff(x), ln(u.clone()));
                            let t2 = div(mul(v.clone(), u.diff(x)), u.clone());
                            mul(self.clone(), add(t1, t2))
                        }
                    }
                    // Comparisons are piecewise constant.
                    BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge => Expr::constant(0.0),
                }
            }
            Node::Call(f, args) => diff_call(self, *f, args, x),
        }
    }
}

fn diff_call(this: &Expr, f: Func, args: &[Expr], x: &str) -> Expr {
    let arg = |i: usize| args.get(i).cloned().unwrap_or(Expr::constant(0.0));
    let d = |i: usize| args.get(i).map_or(Expr::constant(0.0), |a| a.diff(x));
    let u = arg(0);
    let c = Expr::constant;
    let f1 = |g: Func, a: Expr| call(g, vec![a]);
    let square = |a: Expr| bin(BinOp::Pow, a, c(2.0));
    // g'(u) for the one-argument functions; the chain rule multiplies by u'.
    let outer = match f {
        Func::Sin => f1(Func::Cos, u),
        Func::Cos => neg(f1(Func::Sin, u)),
        Func::Tan => div(c(1.0), square(f1(Func::Cos, u))),
        Func::Asin => div(c(1.0), f1(Func::Sqrt, sub(c(1.0), square(u)))),
        Func::Acos => neg(div(c(1.0), f1(Func::Sqrt, sub(c(1.0), square(u))))),
        Func::Atan => div(c(1.0), add(c(1.0), square(u))),
        Func::Sinh => f1(Func::Cosh, u),
        Func::Cosh => f1(Func::Sinh, u),
        Func::Tanh => sub(c(1.0), square(this.clone())),
        Func::Exp => this.clone(),
        Func::Ln => div(c(1.0), u),
        Func::Log10 => div(c(1.0), mul(u, c(std::f64::consts::LN_10))),
        Func::Sqrt => div(c(0.5), this.clone()),
        Func::Abs => f1(Func::Sign, u),
        Func::Sign | Func::Step => c(0.0),
        Func::Pos => f1(Func::Step, u),
        // sat(u) = clamp(u, -1, 1): slope 1 strictly inside, 0 at and beyond the bounds.
        Func::Sat => f1(Func::Step, sub(c(1.0), f1(Func::Abs, u))),
        // Several arguments: branch-wise, with the branch chosen exactly as the value is.
        Func::Min => return if3(sub(arg(1), arg(0)), d(0), d(1)),
        Func::Max => return if3(sub(arg(0), arg(1)), d(0), d(1)),
        Func::If => return if3(arg(0), d(1), d(2)),
        Func::Clamp => {
            let inside = if3(sub(arg(2), arg(0)), d(0), d(2));
            return if3(sub(arg(0), arg(1)), inside, d(1));
        }
        Func::Atan2 => {
            // atan2(y, x)' = (x y' - y x') / (x^2 + y^2)
            let (y, xx) = (arg(0), arg(1));
            let num = sub(mul(xx.clone(), d(0)), mul(y.clone(), d(1)));
            return div(num, add(square(xx), square(y)));
        }
        Func::Hypot => {
            let num = add(mul(arg(0), d(0)), mul(arg(1), d(1)));
            return div(num, this.clone());
        }
    };
    mul(outer, d(0))
}

fn if3(c: Expr, a: Expr, b: Expr) -> Expr {
    call(Func::If, vec![c, a, b])
}

fn ln(a: Expr) -> Expr {
    call(Func::Ln, vec![a])
}

fn add(a: Expr, b: Expr) -> Expr {
    bin(BinOp::Add, a, b)
}

fn sub(a: Expr, b: Expr) -> Expr {
    bin(BinOp::Sub, a, b)
}

fn mul(a: Expr, b: Expr) -> Expr {
    bin(BinOp::Mul, a, b)
}

fn div(a: Expr, b: Expr) -> Expr {
    bin(BinOp::Div, a, b)
}

/// `-a` for a simplified `a`, simplified one level.
pub(crate) fn neg(a: Expr) -> Expr {
    match a.0 {
        Node::Num(v) => Expr::constant(-v),
        Node::Neg(inner) => *inner,
        Node::Bin(BinOp::Sub, l, r) => Expr(Node::Bin(BinOp::Sub, r, l)),
        _ => Expr::neg(a),
    }
}

/// `a op b` for simplified operands, simplified one level.
pub(crate) fn bin(op: BinOp, a: Expr, b: Expr) -> Expr {
    if let (Some(x), Some(y)) = (a.num(), b.num()) {
        return Expr::constant(op.apply(x, y));
    }
    match op {
        BinOp::Add => {
            if a.is_num(0.0) {
                b
            } else if b.is_num(0.0) {
                a
            } else if let Node::Neg(c) = b.0 {
                sub(a, *c)
            } else if let Node::Neg(c) = a.0 {
                sub(b, *c)
            } else {
                Expr::bin(op, a, b)
            }
        }
        BinOp::Sub => {
            if b.is_num(0.0) {
                a
            } else if a.is_num(0.0) {
                neg(b)
            } else if a == b {
                Expr::constant(0.0)
            } else if let Node::Neg(c) = b.0 {
                add(a, *c)
            } else {
                Expr::bin(op, a, b)
            }
        }
        BinOp::Mul => {
            if a.is_num(0.0) || b.is_num(0.0) {
                Expr::constant(0.0)
            } else if a.is_num(1.0) {
                b
            } else if b.is_num(1.0) {
                a
            } else if a.is_num(-1.0) {
                neg(b)
            } else if b.is_num(-1.0) {
                neg(a)
            } else if b.num().is_some() {
                // Constant factors first: exact (commutative) and it lets `2*x` and `x*2` meet.
                mul(b, a)
            } else {
                match (a.0, b.0) {
                    (Node::Neg(x), Node::Neg(y)) => mul(*x, *y),
                    (Node::Neg(x), y) => neg(mul(*x, Expr(y))),
                    (x, Node::Neg(y)) => neg(mul(Expr(x), *y)),
                    (x, y) => Expr::bin(op, Expr(x), Expr(y)),
                }
            }
        }
        BinOp::Div => {
            if a.is_num(0.0) {
                Expr::constant(0.0)
            } else if b.is_num(1.0) {
                a
            } else if b.is_num(-1.0) {
                neg(a)
            } else {
                match (a.0, b.0) {
                    (Node::Neg(x), Node::Neg(y)) => div(*x, *y),
                    (Node::Neg(x), y) => neg(div(*x, Expr(y))),
                    (x, Node::Neg(y)) => neg(div(Expr(x), *y)),
                    (x, y) => Expr::bin(op, Expr(x), Expr(y)),
                }
            }
        }
        BinOp::Pow => {
            if b.is_num(1.0) {
                a
            } else if b.is_num(0.0) {
                // powf(x, 0) is 1 for every x, NaN included.
                Expr::constant(1.0)
            } else {
                Expr::bin(op, a, b)
            }
        }
        BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge => Expr::bin(op, a, b),
    }
}

/// `f(args)` for simplified arguments, simplified one level.
pub(crate) fn call(f: Func, mut args: Vec<Expr>) -> Expr {
    if args.len() == f.arity() && args.iter().all(|a| a.num().is_some()) {
        let v: Vec<f64> = args.iter().filter_map(Expr::num).collect();
        let at = |i: usize| v.get(i).copied().unwrap_or(0.0);
        return Expr::constant(f.apply(at(0), at(1), at(2)));
    }
    if f == Func::If && args.len() == 3 {
        if let Some(c) = args[0].num() {
            let pick = if c > 0.0 { 1 } else { 2 };
            return args.swap_remove(pick);
        }
        if args[1] == args[2] {
            return args.swap_remove(1);
        }
    }
    Expr::call(f, args)
}
