//! Evaluation time per call of a vector field plus its Jacobian: hand-written Rust (the
//! floor), the compiled [`Program`], and the tree walk. Best of N rounds, printed as a table.
//!
//! `cargo bench -p htfid-expr --bench eval`. The figures are recorded in docs/expressions.md.

mod workloads;

use std::hint::black_box;

use htfid_expr::Program;
use workloads::best_ns;

const ROUNDS: usize = 400;
const ITERS: usize = 10_000;

fn main() {
    println!("| workload | ops | hand-written Rust | htfid-expr Program | ratio | tree walk (eval_with) |");
    println!("|---|---|---|---|---|---|");
    for w in workloads::all() {
        let exprs = w.exprs();
        let program = Program::compile(&exprs, w.vars).unwrap();
        let n = exprs.len();
        let ts = w.time_slot();

        // Same numbers from both paths, or the comparison is meaningless.
        let (mut a, mut b) = (vec![0.0; n], vec![0.0; n]);
        (w.hand)(w.point, &mut a);
        program.eval(w.point, &mut b);
        for i in 0..n {
            assert!(
                (a[i] - b[i]).abs() <= 1e-12 * a[i].abs().max(1.0),
                "{}: output {i}: {} vs {}",
                w.name,
                a[i],
                b[i]
            );
        }

        let mut vars = w.point.to_vec();
        let mut out = vec![0.0; n];
        let hand = best_ns(ROUNDS, ITERS, |i| {
            vars[ts] = i as f64 * 1e-4;
            (w.hand)(black_box(&vars), &mut out);
            black_box(&out);
        });
        let compiled = best_ns(ROUNDS, ITERS, |i| {
            vars[ts] = i as f64 * 1e-4;
            program.eval(black_box(&vars), &mut out);
            black_box(&out);
        });
        let names = w.vars;
        let walk = best_ns(ROUNDS / 10, ITERS / 10, |i| {
            vars[ts] = i as f64 * 1e-4;
            let v = &vars;
            let look = |name: &str| names.iter().position(|x| *x == name).map(|j| v[j]);
            for (o, e) in out.iter_mut().zip(&exprs) {
                *o = e.eval_with(&look).unwrap();
            }
            black_box(&out);
        });
        println!(
            "| {} | {} | {hand:.1} ns | {compiled:.1} ns | {:.2} | {walk:.0} ns |",
            w.name,
            program.ops(),
            compiled / hand
        );
    }
}
