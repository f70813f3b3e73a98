//! Compilation of several expressions into one flat register program.
//!
//! Pipeline: simplify each expression, intern every node into one DAG shared by all outputs
//! (hash-consing: an identical subtree anywhere becomes one node, which is the common
//! subexpression elimination across a vector field and its Jacobian), fold constants while
//! interning, lower constant powers to multiplications and square roots, then schedule the
//! DAG in creation order (children are always created first), fuse each product used once
//! into its consumer, and allocate registers by last use.

use std::collections::HashMap;

use crate::error::{suggest, ExprError};
use crate::expr::{Expr, Node};
use crate::func::{pow, BinOp, Func};

/// Register files up to this size live on the stack; larger programs use a heap buffer.
const MAX_STACK_REGS: usize = 512;

/// Largest integer exponent lowered to multiplications; beyond it `powf` is both faster and
/// more accurate than a long chain of roundings.
const MAX_INT_POWER: f64 = 32.0;

/// Several expressions compiled over one variable layout, evaluated together.
///
/// Registers `0..num_vars` hold the inputs, the next ones the constants, the rest temporaries.
/// Evaluation takes `&self` only, so one program can be shared by threads; it allocates
/// nothing on the heap unless the program needs more than 512 registers.
#[derive(Clone, Debug)]
pub struct Program {
    code: Vec<Instr>,
    /// The constants, padded with zeros to whole chunks of [`CHUNK`] registers; they are
    /// loaded from register `const_base` on.
    consts: Vec<f64>,
    outputs: Vec<u32>,
    num_vars: usize,
    /// First register of the constants: `num_vars` rounded up to a whole chunk.
    const_base: usize,
    num_regs: usize,
}

/// Registers are loaded in chunks of this many: a copy whose length is known when the code is
/// compiled becomes a few vector moves, where a loop over a length known only at run time
/// becomes a call to `memcpy`, which for a handful of values costs as much as evaluating a
/// small vector field.
const CHUNK: usize = 8;

/// One instruction: destination register first, then operands.
#[derive(Clone, Copy, Debug)]
enum Instr {
    Add(u32, u32, u32),
    Sub(u32, u32, u32),
    Mul(u32, u32, u32),
    Div(u32, u32, u32),
    Neg(u32, u32),
    Sqrt(u32, u32),
    Pow(u32, u32, u32),
    Cmp(BinOp, u32, u32, u32),
    F1(Func, u32, u32),
    F2(Func, u32, u32, u32),
    F3(Func, u32, u32, u32, u32),
    /// `a*b + c`, `a*b - c`, `c - a*b`, `a*b / c`, `-(a*b)`, each with the roundings of the
    /// separate operations (no fused multiply-add).
    MulAdd(u32, u32, u32, u32),
    MulSub(u32, u32, u32, u32),
    SubMul(u32, u32, u32, u32),
    MulDiv(u32, u32, u32, u32),
    NegMul(u32, u32, u32),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Kind {
    Add,
    Sub,
    Mul,
    Div,
    Neg,
    Sqrt,
    Pow,
    Cmp(BinOp),
    F(Func),
}

impl Kind {
    fn apply(self, a: f64, b: f64, c: f64) -> f64 {
        match self {
            Kind::Add => a + b,
            Kind::Sub => a - b,
            Kind::Mul => a * b,
            Kind::Div => a / b,
            Kind::Neg => -a,
            Kind::Sqrt => a.sqrt(),
            Kind::Pow => pow(a, b),
            Kind::Cmp(op) => op.apply(a, b),
            Kind::F(f) => f.apply(a, b, c),
        }
    }

    fn arity(self) -> usize {
        match self {
            Kind::Neg | Kind::Sqrt => 1,
            Kind::F(f) => f.arity(),
            _ => 2,
        }
    }
}

/// A DAG node. Operands past the kind's arity repeat the first one, so every operand is a
/// valid node.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Key {
    Const(u64),
    Var(u32),
    Op(Kind, [u32; 3]),
}

#[derive(Default)]
struct Dag {
    nodes: Vec<Key>,
    index: HashMap<Key, u32>,
}

impl Dag {
    fn intern(&mut self, key: Key) -> u32 {
        let key = match key {
            Key::Op(kind, mut args) => {
                let n = kind.arity();
                let consts: Vec<f64> = args[..n].iter().filter_map(|&a| self.constant(a)).collect();
                if consts.len() == n {
                    let at = |i: usize| consts.get(i).copied().unwrap_or(0.0);
                    Key::Const(kind.apply(at(0), at(1), at(2)).to_bits())
                } else {
                    // a + b and b + a are bit-identical in IEEE arithmetic; order them so they
                    // meet.
                    if matches!(kind, Kind::Add | Kind::Mul) && args[0] > args[1] {
                        args.swap(0, 1);
                    }
                    Key::Op(kind, args)
                }
            }
            k => k,
        };
        if let Some(&id) = self.index.get(&key) {
            return id;
        }
        let id = self.nodes.len() as u32;
        self.nodes.push(key);
        self.index.insert(key, id);
        id
    }

    fn constant(&self, id: u32) -> Option<f64> {
        match self.nodes[id as usize] {
            Key::Const(bits) => Some(f64::from_bits(bits)),
            _ => None,
        }
    }

    fn op(&mut self, kind: Kind, a: u32, b: u32) -> u32 {
        self.intern(Key::Op(kind, [a, b, a]))
    }

    fn lower(&mut self, e: &Expr, slots: &HashMap<&str, u32>) -> u32 {
        match &e.0 {
            Node::Num(v) => self.intern(Key::Const(v.to_bits())),
            // Every name was checked against the layout before lowering.
            Node::Var(n, _) => self.intern(Key::Var(slots.get(n.as_str()).copied().unwrap_or(0))),
            Node::Neg(a) => {
                let a = self.lower(a, slots);
                self.op(Kind::Neg, a, a)
            }
            Node::Bin(op, a, b) => {
                let x = self.lower(a, slots);
                if *op == BinOp::Pow {
                    if let Some(p) = b.num() {
                        return self.power(x, p);
                    }
                }
                let y = self.lower(b, slots);
                let kind = match op {
                    BinOp::Add => Kind::Add,
                    BinOp::Sub => Kind::Sub,
                    BinOp::Mul => Kind::Mul,
                    BinOp::Div => Kind::Div,
                    BinOp::Pow => Kind::Pow,
                    cmp => Kind::Cmp(*cmp),
                };
                self.op(kind, x, y)
            }
            Node::Call(f, args) => {
                let ids: Vec<u32> = args.iter().map(|a| self.lower(a, slots)).collect();
                let first = ids.first().copied().unwrap_or(0);
                let at = |i: usize| ids.get(i).copied().unwrap_or(first);
                self.intern(Key::Op(Kind::F(*f), [at(0), at(1), at(2)]))
            }
        }
    }

    /// `x^p` for a constant `p`: small integers by repeated squaring, halves by `sqrt`.
    fn power(&mut self, x: u32, p: f64) -> u32 {
        let whole = p.fract() == 0.0 && p.abs() <= MAX_INT_POWER;
        if whole && p != 0.0 {
            let pos = self.int_power(x, p.abs() as u32);
            if p < 0.0 {
                let one = self.intern(Key::Const(1f64.to_bits()));
                return self.op(Kind::Div, one, pos);
            }
            return pos;
        }
        let half = (p * 2.0).fract() == 0.0 && p.abs() <= MAX_INT_POWER;
        if half && p.fract() != 0.0 {
            let root = self.op(Kind::Sqrt, x, x);
            let whole_part = p.abs().floor();
            let mag = if whole_part >= 1.0 {
                let w = self.int_power(x, whole_part as u32);
                self.op(Kind::Mul, w, root)
            } else {
                root
            };
            if p < 0.0 {
                let one = self.intern(Key::Const(1f64.to_bits()));
                return self.op(Kind::Div, one, mag);
            }
            return mag;
        }
        let c = self.intern(Key::Const(p.to_bits()));
        self.op(Kind::Pow, x, c)
    }

    fn int_power(&mut self, x: u32, n: u32) -> u32 {
        if n == 1 {
            return x;
        }
        let half = self.int_power(x, n / 2);
        let sq = self.op(Kind::Mul, half, half);
        if n % 2 == 1 {
            self.op(Kind::Mul, sq, x)
        } else {
            sq
        }
    }
}

/// The interpreter loop, written once for both register files; `$idx` maps a register
/// number to an index.
macro_rules! exec {
    ($code:expr, $r:ident, $idx:expr) => {{
        let idx = $idx;
        for ins in $code {
            match *ins {
                Instr::Add(d, a, b) => $r[idx(d)] = $r[idx(a)] + $r[idx(b)],
                Instr::Sub(d, a, b) => $r[idx(d)] = $r[idx(a)] - $r[idx(b)],
                Instr::Mul(d, a, b) => $r[idx(d)] = $r[idx(a)] * $r[idx(b)],
                Instr::Div(d, a, b) => $r[idx(d)] = $r[idx(a)] / $r[idx(b)],
                Instr::Neg(d, a) => $r[idx(d)] = -$r[idx(a)],
                Instr::Sqrt(d, a) => $r[idx(d)] = $r[idx(a)].sqrt(),
                Instr::Pow(d, a, b) => $r[idx(d)] = pow($r[idx(a)], $r[idx(b)]),
                Instr::Cmp(op, d, a, b) => $r[idx(d)] = op.apply($r[idx(a)], $r[idx(b)]),
                Instr::F1(f, d, a) => $r[idx(d)] = f.apply($r[idx(a)], 0.0, 0.0),
                Instr::F2(f, d, a, b) => $r[idx(d)] = f.apply($r[idx(a)], $r[idx(b)], 0.0),
                Instr::F3(f, d, a, b, c) => {
                    $r[idx(d)] = f.apply($r[idx(a)], $r[idx(b)], $r[idx(c)]);
                }
                Instr::MulAdd(d, a, b, c) => $r[idx(d)] = $r[idx(a)] * $r[idx(b)] + $r[idx(c)],
                Instr::MulSub(d, a, b, c) => $r[idx(d)] = $r[idx(a)] * $r[idx(b)] - $r[idx(c)],
                Instr::SubMul(d, a, b, c) => $r[idx(d)] = $r[idx(c)] - $r[idx(a)] * $r[idx(b)],
                Instr::MulDiv(d, a, b, c) => $r[idx(d)] = $r[idx(a)] * $r[idx(b)] / $r[idx(c)],
                Instr::NegMul(d, a, b) => $r[idx(d)] = -($r[idx(a)] * $r[idx(b)]),
            }
        }
    }};
}

impl Program {
    /// Compiles several expressions over one variable layout: variable `vars[i]` is read from
    /// slot `i` of the input slice. Expressions are simplified first; subexpressions shared
    /// between them are computed once.
    ///
    /// # Errors
    ///
    /// [`ExprError::UnknownVariable`] for a name not in `vars` (with where it first appears and
    /// the closest name in `vars`), [`ExprError::DuplicateVariable`] for a name listed twice.
    pub fn compile(exprs: &[Expr], vars: &[&str]) -> Result<Program, ExprError> {
        let mut slots: HashMap<&str, u32> = HashMap::new();
        for (i, &name) in vars.iter().enumerate() {
            if let Some(&first) = slots.get(name) {
                return Err(ExprError::DuplicateVariable {
                    name: name.to_owned(),
                    first: first as usize,
                    second: i,
                });
            }
            slots.insert(name, i as u32);
        }
        for e in exprs {
            if let Some(name) = e
                .variables()
                .into_iter()
                .find(|n| !slots.contains_key(n.as_str()))
            {
                return Err(ExprError::UnknownVariable {
                    span: e.span_of(&name).unwrap_or(0..0),
                    suggestion: suggest(&name, vars.iter().copied()),
                    name,
                });
            }
        }

        let mut dag = Dag::default();
        let roots: Vec<u32> = exprs
            .iter()
            .map(|e| dag.lower(&e.simplify(), &slots))
            .collect();
        Ok(schedule(&dag, &roots, vars.len()))
    }

    /// Number of outputs (expressions compiled).
    pub fn len(&self) -> usize {
        self.outputs.len()
    }

    /// Whether the program has no outputs.
    pub fn is_empty(&self) -> bool {
        self.outputs.is_empty()
    }

    /// Length of the variable layout the program reads.
    pub fn num_vars(&self) -> usize {
        self.num_vars
    }

    /// Number of instructions executed per evaluation: a work counter for tests.
    pub fn ops(&self) -> usize {
        self.code.len()
    }

    /// Evaluates every expression at once: `out[i]` receives expression `i`, with variable `j`
    /// of the layout taken from `vars[j]` (any [`Variables`]: a slice, or values the caller
    /// writes in place).
    ///
    /// # Panics
    ///
    /// If `vars.count() < self.num_vars()` or `out.len() < self.len()`: slice lengths are
    /// fixed by the caller's code, not by user data.
    pub fn eval<V: Variables + ?Sized>(&self, vars: &V, out: &mut [f64]) {
        assert!(
            vars.count() >= self.num_vars,
            "Program::eval: {} variables given, {} needed",
            vars.count(),
            self.num_vars
        );
        assert!(
            out.len() >= self.len(),
            "Program::eval: room for {} outputs, {} needed",
            out.len(),
            self.len()
        );
        self.with_registers(vars, |regs| {
            for (o, &r) in out.iter_mut().zip(&self.outputs) {
                *o = regs[r as usize];
            }
        });
    }

    /// Evaluates the program and returns output `index` alone (all outputs are computed).
    ///
    /// # Panics
    ///
    /// If `index >= self.len()` or `vars.count() < self.num_vars()`.
    pub fn eval_one<V: Variables + ?Sized>(&self, index: usize, vars: &V) -> f64 {
        assert!(
            index < self.len(),
            "Program::eval_one: output {index} of {}",
            self.len()
        );
        assert!(
            vars.count() >= self.num_vars,
            "Program::eval_one: {} variables given, {} needed",
            vars.count(),
            self.num_vars
        );
        let mut value = 0.0;
        self.with_registers(vars, |regs| value = regs[self.outputs[index] as usize]);
        value
    }

    /// Runs the code in a register file sized to the program (zeroing 512 registers would cost
    /// more than evaluating a small vector field), then hands the registers to `read`.
    fn with_registers<V: Variables + ?Sized>(&self, vars: &V, read: impl FnOnce(&[f64])) {
        let n = self.num_regs;
        if n <= 32 {
            let mut regs = [0.0; 32];
            self.run_fixed(&mut regs, vars);
            read(&regs);
        } else if n <= 128 {
            let mut regs = [0.0; 128];
            self.run_fixed(&mut regs, vars);
            read(&regs);
        } else if n <= MAX_STACK_REGS {
            let mut regs = [0.0; MAX_STACK_REGS];
            self.run_fixed(&mut regs, vars);
            read(&regs);
        } else {
            let mut regs = vec![0.0; n];
            self.load(&mut regs, vars);
            exec!(&self.code, regs, |x: u32| x as usize);
            read(&regs);
        }
    }

    /// The hot loop on a power-of-two register file. Every register index is below
    /// `num_regs <= N`, so masking with `N - 1` changes nothing, but it proves to the compiler
    /// that the index is in bounds and removes three bounds checks per instruction.
    #[inline]
    fn run_fixed<V: Variables + ?Sized, const N: usize>(&self, regs: &mut [f64; N], vars: &V) {
        let base = self.const_base;
        vars.load(&mut regs[..self.num_vars]);
        // `base` and the padded constants' length are whole chunks, and `base + consts.len()`
        // is at most `num_regs <= N`.
        for (r, c) in regs[base..]
            .chunks_exact_mut(CHUNK)
            .zip(self.consts.chunks_exact(CHUNK))
        {
            copy_chunk(r, c);
        }
        exec!(&self.code, regs, |x: u32| x as usize & (N - 1));
    }

    #[inline]
    fn load<V: Variables + ?Sized>(&self, regs: &mut [f64], vars: &V) {
        let base = self.const_base;
        vars.load(&mut regs[..self.num_vars]);
        regs[base..base + self.consts.len()].copy_from_slice(&self.consts);
    }
}

/// The values of a program's variables, in the order of its layout, loaded into its
/// registers by [`Program::eval`]. A slice (a `Vec`, an array) is the plain case; a caller
/// that holds its values apart (a time, a state, an input) writes them in place instead, which
/// saves assembling a slice that is then copied again.
///
/// ```
/// use htfid_expr::{parse, Program, Variables};
///
/// /// A time and a state, written into the layout `[t, x, v]` where they lie.
/// struct At<'a> {
///     t: f64,
///     state: &'a [f64],
/// }
///
/// impl Variables for At<'_> {
///     fn count(&self) -> usize {
///         1 + self.state.len()
///     }
///     fn load(&self, regs: &mut [f64]) {
///         let values = std::iter::once(self.t).chain(self.state.iter().copied());
///         for (r, v) in regs.iter_mut().zip(values) {
///             *r = v;
///         }
///     }
/// }
///
/// let field = [parse("v")?, parse("-4*x + cos(t)")?];
/// let program = Program::compile(&field, &["t", "x", "v"])?;
/// let mut dxdt = [0.0; 2];
/// program.eval(&At { t: 0.0, state: &[0.5, 2.0] }, &mut dxdt);
/// assert_eq!(dxdt, [2.0, -1.0]);
/// // The same values as a slice give the same numbers.
/// let mut again = [0.0; 2];
/// program.eval(&[0.0, 0.5, 2.0], &mut again);
/// assert_eq!(dxdt, again);
/// # Ok::<(), htfid_expr::ExprError>(())
/// ```
pub trait Variables {
    /// How many values there are; a program reads the first [`Program::num_vars`].
    fn count(&self) -> usize;
    /// Writes value `j` into `regs[j]` for every `j < regs.len()` (`regs.len() <= count()`).
    fn load(&self, regs: &mut [f64]);
}

impl Variables for [f64] {
    fn count(&self) -> usize {
        self.len()
    }

    fn load(&self, regs: &mut [f64]) {
        regs.copy_from_slice(&self[..regs.len()]);
    }
}

impl Variables for Vec<f64> {
    fn count(&self) -> usize {
        self.len()
    }

    fn load(&self, regs: &mut [f64]) {
        self.as_slice().load(regs);
    }
}

impl<const K: usize> Variables for [f64; K] {
    fn count(&self) -> usize {
        K
    }

    fn load(&self, regs: &mut [f64]) {
        self.as_slice().load(regs);
    }
}

/// One chunk of registers: both slices are [`CHUNK`] long.
#[inline(always)]
fn copy_chunk(to: &mut [f64], from: &[f64]) {
    let to: &mut [f64; CHUNK] = to.try_into().expect("a whole chunk");
    let from: &[f64; CHUNK] = from.try_into().expect("a whole chunk");
    *to = *from;
}

/// What one emitted instruction computes, over DAG node operands.
#[derive(Clone, Copy, Debug)]
enum Form {
    Plain(Kind, [u32; 3]),
    /// A product used once, fused into its consumer: `a*b + c`, `a*b - c`, `c - a*b`,
    /// `a*b / c`, `-(a*b)`. Still two roundings, so the values are bit-identical to the
    /// separate instructions; what is saved is a dispatch and a round trip through memory.
    MulAdd([u32; 3]),
    MulSub([u32; 3]),
    SubMul([u32; 3]),
    MulDiv([u32; 3]),
    NegMul([u32; 3]),
}

impl Form {
    fn operands(&self) -> &[u32] {
        match self {
            Form::Plain(kind, args) => &args[..kind.arity()],
            Form::NegMul(args) => &args[..2],
            Form::MulAdd(args) | Form::MulSub(args) | Form::SubMul(args) | Form::MulDiv(args) => {
                args
            }
        }
    }
}

/// Orders the live nodes, fuses single-use products into their consumers, assigns registers
/// and emits the code.
fn schedule(dag: &Dag, roots: &[u32], num_vars: usize) -> Program {
    let n = dag.nodes.len();
    // Nodes are created after their operands, so one backward sweep marks everything the
    // outputs need and counts the uses of each node (an output counts as a use).
    let mut live = vec![false; n];
    let mut uses = vec![0usize; n];
    for &r in roots {
        live[r as usize] = true;
        uses[r as usize] += 1;
    }
    for i in (0..n).rev() {
        if !live[i] {
            continue;
        }
        if let Key::Op(kind, args) = dag.nodes[i] {
            for &a in &args[..kind.arity()] {
                live[a as usize] = true;
                uses[a as usize] += 1;
            }
        }
    }

    let single_mul = |x: u32| match dag.nodes[x as usize] {
        Key::Op(Kind::Mul, [a, b, _]) if uses[x as usize] == 1 => Some((a, b)),
        _ => None,
    };
    let mut absorbed = vec![false; n];
    let mut forms: Vec<Option<Form>> = vec![None; n];
    for i in 0..n {
        let Key::Op(kind, args) = dag.nodes[i] else {
            continue;
        };
        if !live[i] {
            continue;
        }
        let [x, y, _] = args;
        let (form, mul) = match (kind, single_mul(x), single_mul(y)) {
            // a*b + c and c + a*b are bit-identical.
            (Kind::Add, Some((a, b)), _) => (Form::MulAdd([a, b, y]), x),
            (Kind::Add, None, Some((a, b))) => (Form::MulAdd([a, b, x]), y),
            (Kind::Sub, Some((a, b)), _) => (Form::MulSub([a, b, y]), x),
            (Kind::Sub, None, Some((a, b))) => (Form::SubMul([a, b, x]), y),
            (Kind::Div, Some((a, b)), _) => (Form::MulDiv([a, b, y]), x),
            (Kind::Neg, Some((a, b)), _) => (Form::NegMul([a, b, a]), x),
            _ => (Form::Plain(kind, args), u32::MAX),
        };
        if mul != u32::MAX {
            absorbed[mul as usize] = true;
        }
        forms[i] = Some(form);
    }

    // Last consumer of each node, over the instructions actually emitted.
    let mut last_use = vec![0usize; n];
    for &r in roots {
        last_use[r as usize] = usize::MAX;
    }
    for i in 0..n {
        if let (Some(form), false) = (&forms[i], absorbed[i]) {
            for &a in form.operands() {
                last_use[a as usize] = last_use[a as usize].max(i);
            }
        }
    }

    let mut reg = vec![u32::MAX; n];
    let mut consts = Vec::new();
    let const_base = num_vars.next_multiple_of(CHUNK);
    for (i, key) in dag.nodes.iter().enumerate() {
        match *key {
            Key::Var(slot) => reg[i] = slot,
            Key::Const(bits) if live[i] => {
                reg[i] = (const_base + consts.len()) as u32;
                consts.push(f64::from_bits(bits));
            }
            _ => {}
        }
    }
    // The padding after the constants is loaded with zeros and free for temporaries.
    let num_consts = consts.len();
    consts.resize(num_consts.next_multiple_of(CHUNK), 0.0);
    let mut free: Vec<u32> = (const_base + num_consts..const_base + consts.len())
        .rev()
        .map(|r| r as u32)
        .collect();
    let mut num_regs = const_base + consts.len();
    let mut code = Vec::new();
    for i in 0..n {
        let Some(form) = forms[i] else { continue };
        if absorbed[i] {
            continue;
        }
        // Operands read for the last time free their registers before the destination is
        // chosen: an instruction reads all operands before it writes, so `d` may reuse one.
        let used = form.operands();
        for (k, &x) in used.iter().enumerate() {
            let is_temp = matches!(dag.nodes[x as usize], Key::Op(..));
            if is_temp && last_use[x as usize] == i && !used[..k].contains(&x) {
                free.push(reg[x as usize]);
            }
        }
        let d = free.pop().unwrap_or_else(|| {
            num_regs += 1;
            (num_regs - 1) as u32
        });
        reg[i] = d;
        let r = |k: usize| used.get(k).map_or(0, |&x| reg[x as usize]);
        code.push(match form {
            Form::MulAdd(_) => Instr::MulAdd(d, r(0), r(1), r(2)),
            Form::MulSub(_) => Instr::MulSub(d, r(0), r(1), r(2)),
            Form::SubMul(_) => Instr::SubMul(d, r(0), r(1), r(2)),
            Form::MulDiv(_) => Instr::MulDiv(d, r(0), r(1), r(2)),
            Form::NegMul(_) => Instr::NegMul(d, r(0), r(1)),
            Form::Plain(kind, _) => match kind {
                Kind::Add => Instr::Add(d, r(0), r(1)),
                Kind::Sub => Instr::Sub(d, r(0), r(1)),
                Kind::Mul => Instr::Mul(d, r(0), r(1)),
                Kind::Div => Instr::Div(d, r(0), r(1)),
                Kind::Neg => Instr::Neg(d, r(0)),
                Kind::Sqrt => Instr::Sqrt(d, r(0)),
                Kind::Pow => Instr::Pow(d, r(0), r(1)),
                Kind::Cmp(op) => Instr::Cmp(op, d, r(0), r(1)),
                Kind::F(f) => match f.arity() {
                    1 => Instr::F1(f, d, r(0)),
                    2 => Instr::F2(f, d, r(0), r(1)),
                    _ => Instr::F3(f, d, r(0), r(1), r(2)),
                },
            },
        });
    }
    let outputs = roots.iter().map(|&r| reg[r as usize]).collect();
    Program {
        code,
        consts,
        outputs,
        num_vars,
        const_base,
        num_regs,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parse;

    fn compile(srcs: &[&str], vars: &[&str]) -> Program {
        let exprs: Vec<Expr> = srcs.iter().map(|s| parse(s).unwrap()).collect();
        Program::compile(&exprs, vars).unwrap()
    }

    #[test]
    fn powers_are_lowered() {
        // x^2 is one multiplication, x^3 two, x^8 three squarings, x^0.5 a square root.
        assert_eq!(compile(&["x^2"], &["x"]).ops(), 1);
        assert_eq!(compile(&["x^3"], &["x"]).ops(), 2);
        assert_eq!(compile(&["x^8"], &["x"]).ops(), 3);
        assert_eq!(compile(&["x^0.5"], &["x"]).ops(), 1);
        assert_eq!(compile(&["x^-2"], &["x"]).ops(), 2);
        assert_eq!(compile(&["x^2.7"], &["x"]).ops(), 1);
        assert!(matches!(
            compile(&["x^0.5"], &["x"]).code[0],
            Instr::Sqrt(..)
        ));
        assert!(matches!(
            compile(&["x^2.7"], &["x"]).code[0],
            Instr::Pow(..)
        ));
    }

    #[test]
    fn constants_fold_and_commuted_operands_meet() {
        let p = compile(&["2*pi*x", "x*(2*pi)"], &["x"]);
        assert_eq!(p.ops(), 1);
        // One constant, then the padding of its chunk.
        assert_eq!(p.consts.iter().filter(|c| **c != 0.0).count(), 1);
        assert_eq!(p.consts.len(), CHUNK);
    }

    #[test]
    fn registers_are_reused() {
        // A long chain needs only a couple of temporaries.
        let src = (0..50)
            .map(|i| format!("sin(x + {i})"))
            .collect::<Vec<_>>()
            .join(" + ");
        let p = compile(&[src.as_str()], &["x"]);
        assert!(
            p.num_regs <= (p.const_base + p.consts.len() + 4).next_multiple_of(CHUNK),
            "{} registers",
            p.num_regs
        );
    }
}
