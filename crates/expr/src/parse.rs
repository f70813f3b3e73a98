//! Lexer and recursive-descent parser.
//!
//! Grammar, loosest binding first:
//!
//! ```text
//! expr    = sum [ ("<" | "<=" | ">" | ">=") sum ]      comparisons do not chain
//! sum     = product { ("+" | "-") product }
//! product = unary { ("*" | "/") unary }
//! unary   = ("-" | "+") unary | power
//! power   = atom [ "^" unary ]                         right-associative, -x^2 = -(x^2)
//! atom    = number | "pi" | name | name "(" [ expr { "," expr } ] ")" | "(" expr ")"
//! ```

use std::ops::Range;

use crate::error::{suggest, ExprError};
use crate::expr::{Expr, Node};
use crate::func::{BinOp, Callee};

/// Deepest expression tree the parser builds. Every algorithm on [`Expr`] recurses over the
/// tree, so bounding its depth bounds their stack use; real model expressions are a few tens
/// of levels deep.
pub(crate) const MAX_DEPTH: usize = 256;

/// Parses one expression.
///
/// # Errors
///
/// Any [`ExprError`] with its position; see the crate docs for the syntax.
pub fn parse(src: &str) -> Result<Expr, ExprError> {
    let tokens = lex(src)?;
    if tokens.len() == 1 {
        return Err(ExprError::Empty);
    }
    let mut p = Parser { tokens, pos: 0 };
    let (e, _) = p.expr(0)?;
    let t = p.peek();
    match t.tok {
        Tok::End => Ok(e),
        Tok::RParen => Err(ExprError::UnbalancedParen {
            span: t.span.clone(),
            paren: ')',
        }),
        _ => Err(p.unexpected("an operator or the end of the expression")),
    }
}

#[derive(Clone, Debug, PartialEq)]
enum Tok {
    Num(f64),
    Name(String),
    Op(BinOp),
    LParen,
    RParen,
    Comma,
    End,
}

#[derive(Debug)]
struct Token {
    tok: Tok,
    span: Range<usize>,
    text: String,
}

fn lex(src: &str) -> Result<Vec<Token>, ExprError> {
    let chars: Vec<char> = src.chars().collect();
    let mut tokens = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let start = i;
        let tok = if c.is_whitespace() {
            i += 1;
            continue;
        } else if c.is_ascii_digit() || c == '.' {
            while i < chars.len() && (chars[i].is_ascii_digit() || chars[i] == '.') {
                i += 1;
            }
            if i < chars.len() && matches!(chars[i], 'e' | 'E') {
                i += 1;
                if i < chars.len() && matches!(chars[i], '+' | '-') {
                    i += 1;
                }
            }
            // Swallow trailing name characters so that `2x` or `1e` is one bad number rather
            // than a confusing "expected an operator".
            while i < chars.len()
                && (chars[i].is_ascii_alphanumeric() || matches!(chars[i], '_' | '.'))
            {
                i += 1;
            }
            let text: String = chars[start..i].iter().collect();
            match text.parse::<f64>() {
                Ok(v) if v.is_finite() => Tok::Num(v),
                _ => {
                    return Err(ExprError::InvalidNumber {
                        span: start..i,
                        text,
                    })
                }
            }
        } else if c.is_ascii_alphabetic() || c == '_' {
            while i < chars.len() && (chars[i].is_ascii_alphanumeric() || chars[i] == '_') {
                i += 1;
            }
            Tok::Name(chars[start..i].iter().collect())
        } else {
            i += 1;
            let eq = chars.get(i) == Some(&'=');
            match c {
                '+' => Tok::Op(BinOp::Add),
                '-' => Tok::Op(BinOp::Sub),
                '*' => Tok::Op(BinOp::Mul),
                '/' => Tok::Op(BinOp::Div),
                '^' => Tok::Op(BinOp::Pow),
                '(' => Tok::LParen,
                ')' => Tok::RParen,
                ',' => Tok::Comma,
                '<' | '>' => {
                    i += usize::from(eq);
                    Tok::Op(match (c, eq) {
                        ('<', false) => BinOp::Lt,
                        ('<', true) => BinOp::Le,
                        (_, false) => BinOp::Gt,
                        (_, true) => BinOp::Ge,
                    })
                }
                _ => {
                    return Err(ExprError::UnexpectedToken {
                        span: start..i,
                        found: c.to_string(),
                        expected: "a number, a name, an operator, a parenthesis or `,`",
                    })
                }
            }
        };
        tokens.push(Token {
            tok,
            span: start..i,
            text: chars[start..i].iter().collect(),
        });
    }
    let n = chars.len();
    tokens.push(Token {
        tok: Tok::End,
        span: n..n,
        text: String::new(),
    });
    Ok(tokens)
}

struct Parser {
    tokens: Vec<Token>,
    pos: usize,
}

/// A parsed subtree and its depth, tracked so that the depth bound holds for the tree itself
/// (a sum of 100 000 terms is shallow to parse but 100 000 levels deep as a tree).
type Parsed = (Expr, usize);

const OPERAND: &str = "a number, a name or `(`";

impl Parser {
    fn peek(&self) -> &Token {
        &self.tokens[self.pos]
    }

    fn next(&mut self) -> &Token {
        let t = &self.tokens[self.pos];
        if self.pos + 1 < self.tokens.len() {
            self.pos += 1;
        }
        t
    }

    fn unexpected(&self, expected: &'static str) -> ExprError {
        let t = self.peek();
        ExprError::UnexpectedToken {
            span: t.span.clone(),
            found: t.text.clone(),
            expected,
        }
    }

    fn binary(op: BinOp, (a, da): Parsed, (b, db): Parsed) -> Result<Parsed, ExprError> {
        let depth = da.max(db) + 1;
        if depth > MAX_DEPTH {
            return Err(ExprError::TooDeep { depth: MAX_DEPTH });
        }
        Ok((Expr::bin(op, a, b), depth))
    }

    /// `nest` counts the recursion of the parser itself, which can run ahead of the tree depth
    /// (`((((x))))` is a tree of depth 1).
    fn expr(&mut self, nest: usize) -> Result<Parsed, ExprError> {
        if nest > MAX_DEPTH {
            return Err(ExprError::TooDeep { depth: MAX_DEPTH });
        }
        let a = self.sum(nest)?;
        match self.peek().tok {
            Tok::Op(op) if op.is_comparison() => {
                self.next();
                let b = self.sum(nest)?;
                if matches!(self.peek().tok, Tok::Op(o) if o.is_comparison()) {
                    return Err(self.unexpected("no second comparison (comparisons do not chain)"));
                }
                Self::binary(op, a, b)
            }
            _ => Ok(a),
        }
    }

    fn sum(&mut self, nest: usize) -> Result<Parsed, ExprError> {
        let mut a = self.product(nest)?;
        while let Tok::Op(op @ (BinOp::Add | BinOp::Sub)) = self.peek().tok {
            self.next();
            let b = self.product(nest)?;
            a = Self::binary(op, a, b)?;
        }
        Ok(a)
    }

    fn product(&mut self, nest: usize) -> Result<Parsed, ExprError> {
        let mut a = self.unary(nest)?;
        while let Tok::Op(op @ (BinOp::Mul | BinOp::Div)) = self.peek().tok {
            self.next();
            let b = self.unary(nest)?;
            a = Self::binary(op, a, b)?;
        }
        Ok(a)
    }

    fn unary(&mut self, nest: usize) -> Result<Parsed, ExprError> {
        if nest > MAX_DEPTH {
            return Err(ExprError::TooDeep { depth: MAX_DEPTH });
        }
        match self.peek().tok {
            Tok::Op(BinOp::Sub) => {
                self.next();
                let (a, d) = self.unary(nest + 1)?;
                if d + 1 > MAX_DEPTH {
                    return Err(ExprError::TooDeep { depth: MAX_DEPTH });
                }
                Ok((Expr::neg(a), d + 1))
            }
            Tok::Op(BinOp::Add) => {
                self.next();
                self.unary(nest + 1)
            }
            _ => self.power(nest),
        }
    }

    fn power(&mut self, nest: usize) -> Result<Parsed, ExprError> {
        let base = self.atom(nest)?;
        if self.peek().tok == Tok::Op(BinOp::Pow) {
            self.next();
            let exponent = self.unary(nest + 1)?;
            return Self::binary(BinOp::Pow, base, exponent);
        }
        Ok(base)
    }

    fn atom(&mut self, nest: usize) -> Result<Parsed, ExprError> {
        let t = self.peek();
        let span = t.span.clone();
        match t.tok.clone() {
            Tok::Num(v) => {
                self.next();
                Ok((Expr::constant(v), 1))
            }
            Tok::LParen => {
                self.next();
                let inner = self.expr(nest + 1)?;
                self.close(span, "an operator or `)`")?;
                Ok(inner)
            }
            Tok::Name(name) => {
                self.next();
                if self.peek().tok == Tok::LParen {
                    self.call(name, span, nest)
                } else if name == "pi" {
                    Ok((Expr::constant(std::f64::consts::PI), 1))
                } else if Callee::lookup(&name).is_some() {
                    Err(ExprError::FunctionNotCalled { span, name })
                } else {
                    Ok((Expr(Node::Var(name, span)), 1))
                }
            }
            _ => Err(self.unexpected(OPERAND)),
        }
    }

    /// Consumes the `)` matching the `(` at `open`.
    fn close(&mut self, open: Range<usize>, expected: &'static str) -> Result<(), ExprError> {
        match self.peek().tok {
            Tok::RParen => {
                self.next();
                Ok(())
            }
            Tok::End => Err(ExprError::UnbalancedParen {
                span: open,
                paren: '(',
            }),
            _ => Err(self.unexpected(expected)),
        }
    }

    fn call(&mut self, name: String, span: Range<usize>, nest: usize) -> Result<Parsed, ExprError> {
        let Some(callee) = Callee::lookup(&name) else {
            let suggestion = suggest(&name, Callee::names());
            return Err(ExprError::UnknownFunction {
                span,
                name,
                suggestion,
            });
        };
        let open = self.next().span.clone();
        let mut args = Vec::new();
        let mut depth = 0;
        if self.peek().tok != Tok::RParen {
            loop {
                let (a, d) = self.expr(nest + 1)?;
                depth = depth.max(d);
                args.push(a);
                if self.peek().tok == Tok::Comma {
                    self.next();
                } else {
                    break;
                }
            }
        }
        self.close(open, "an operator, `,` or `)`")?;
        if args.len() != callee.arity() {
            return Err(ExprError::WrongArity {
                span,
                name,
                expected: callee.arity(),
                found: args.len(),
            });
        }
        if depth + 1 > MAX_DEPTH {
            return Err(ExprError::TooDeep { depth: MAX_DEPTH });
        }
        let e = match callee {
            Callee::Func(f) => Expr::call(f, args),
            Callee::Pow => {
                let mut it = args.into_iter();
                match (it.next(), it.next()) {
                    (Some(a), Some(b)) => Expr::bin(BinOp::Pow, a, b),
                    _ => {
                        return Err(ExprError::WrongArity {
                            span,
                            name,
                            expected: 2,
                            found: 0,
                        })
                    }
                }
            }
        };
        Ok((e, depth + 1))
    }
}
