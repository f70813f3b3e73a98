//! The compiled program against the slow, obvious tree walk, plus its work counters.

mod common;

use common::{close, lookup, random_expr, random_expr_with, Rng, SINGLE_ROUNDING_POWERS, VARS};
use htfid_expr::{parse, Expr, ExprError, Program};

#[test]
fn compiled_agrees_with_tree_walk_on_random_expressions() {
    let mut rng = Rng::new(0xC0FFEE);
    let mut compared = 0;
    for _ in 0..3000 {
        // Several outputs per program, so that shared subexpressions and register reuse
        // across outputs are exercised.
        // Exponents are limited to those compiled with one rounding, like `powf`: with a chain
        // of multiplications the results differ in the last place, which an ill-conditioned
        // random expression (sin of a large argument) amplifies past any fixed tolerance. The
        // other powers are checked on their own below.
        let exprs: Vec<Expr> = (0..3)
            .map(|_| parse(&random_expr_with(&mut rng, 5, SINGLE_ROUNDING_POWERS)).unwrap())
            .collect();
        let p = Program::compile(&exprs, &VARS).unwrap();
        assert_eq!(p.len(), 3);
        for _ in 0..5 {
            let vals = [
                rng.uniform(-2.0, 2.0),
                rng.uniform(-2.0, 2.0),
                rng.uniform(-2.0, 2.0),
            ];
            let mut out = [0.0; 3];
            p.eval(&vals, &mut out);
            // The variables in a longer slice: what lies beyond the layout is never loaded,
            // so NaNs there change nothing.
            let mut padded = [f64::NAN; 8];
            padded[..3].copy_from_slice(&vals);
            let mut out_padded = [0.0; 3];
            p.eval(&padded, &mut out_padded);
            for (a, b) in out.iter().zip(&out_padded) {
                assert!(a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()));
            }
            for (i, e) in exprs.iter().enumerate() {
                // The oracle is the tree walk of the simplified tree: simplification drops
                // `x*0` even where `x` is NaN, which the original tree walk would keep.
                let want = e.simplify().eval_with(&lookup(vals)).unwrap();
                assert!(
                    close(out[i], want, 1e-14),
                    "{e} at {vals:?}: compiled {}, tree walk {want}",
                    out[i]
                );
                assert!(close(p.eval_one(i, &vals), want, 1e-14));
                compared += 1;
            }
        }
    }
    assert_eq!(compared, 45_000);
}

#[test]
fn lowered_powers_are_accurate() {
    let mut rng = Rng::new(5);
    for p in [
        "3", "4", "5", "-2", "-3", "17", "32", "-32", "1.5", "-0.5", "-2.5", "7.5",
    ] {
        let e = parse(&format!("x^{p}")).unwrap();
        let prog = Program::compile(&[e], &["x"]).unwrap();
        let pf: f64 = p.parse().unwrap();
        for _ in 0..1000 {
            let x = rng.uniform(0.01, 3.0);
            let want = x.powf(pf);
            // A chain of k roundings is within k ulp; 32 = 2^5 takes 5 squarings.
            assert!(close(prog.eval_one(0, &[x]), want, 1e-14), "{x}^{p}");
        }
    }
}

#[test]
fn simplification_keeps_finite_values() {
    let mut rng = Rng::new(99);
    for _ in 0..3000 {
        let e = parse(&random_expr(&mut rng, 5)).unwrap();
        let s = e.simplify();
        let vals = [
            rng.uniform(-2.0, 2.0),
            rng.uniform(-2.0, 2.0),
            rng.uniform(-2.0, 2.0),
        ];
        let want = e.eval_with(&lookup(vals)).unwrap();
        if want.is_finite() {
            let got = s.eval_with(&lookup(vals)).unwrap();
            assert!(
                close(got, want, 1e-14),
                "{e} -> {s} at {vals:?}: {got} vs {want}"
            );
        }
    }
}

#[test]
fn common_subexpressions_are_shared_across_outputs() {
    let a = parse("sin(x)*y").unwrap();
    let b = parse("sin(x) + 1").unwrap();
    let together = Program::compile(&[a.clone(), b.clone()], &["x", "y"]).unwrap();
    let apart = Program::compile(&[a], &["x", "y"]).unwrap().ops()
        + Program::compile(&[b], &["x", "y"]).unwrap().ops();
    assert_eq!(together.ops(), 3);
    assert_eq!(apart, 4);
    let mut out = [0.0; 2];
    together.eval(&[0.5, 2.0], &mut out);
    assert!((out[0] - 0.5f64.sin() * 2.0).abs() < 1e-15);
    assert!((out[1] - (0.5f64.sin() + 1.0)).abs() < 1e-15);
}

/// Work counter snapshot for the hopper: a regression in folding or sharing shows here.
#[test]
fn hopper_field_and_jacobian_op_count() {
    let vars = ["t", "x", "v", "m", "g", "c", "k", "x0", "a", "T", "u"];
    let f1 = parse("(-m*g - c*v - k*(x - x0) + a*cos(2*pi*t/T) + u)/m").unwrap();
    let f0 = parse("v").unwrap();
    let exprs = [
        f0.clone(),
        f1.clone(),
        f0.derivative("x"),
        f0.derivative("v"),
        f1.derivative("x"),
        f1.derivative("v"),
    ];
    let p = Program::compile(&exprs, &vars).unwrap();
    // f1 = (-(m*g) - c*v - k*(x - x0) + a*cos(6.283185307179586*t/T) + u)/m with 2*pi folded
    // and single-use products fused: -(m*g), _ - c*v, x - x0, _ - k*_, 2pi*t/T, cos, a*_ + _,
    // + u, /m = 9; the Jacobian's -(k/m) and -(c/m) are a division and a negation each;
    // v, 0 and 1 cost nothing.
    assert_eq!(p.ops(), 13);
    let vals = [0.3, 0.1, -0.4, 80.0, 9.81, 120.0, 2e4, 0.05, 30.0, 1.1, 5.0];
    let mut out = [0.0; 6];
    p.eval(&vals, &mut out);
    let [t, x, v, m, g, c, k, x0, a, tt, u] = vals;
    let want = [
        v,
        (-m * g - c * v - k * (x - x0) + a * (2.0 * std::f64::consts::PI * t / tt).cos() + u) / m,
        0.0,
        1.0,
        -k / m,
        -c / m,
    ];
    for (o, w) in out.iter().zip(want) {
        assert!(
            (o - w).abs() <= 1e-14 * w.abs().max(1.0),
            "{out:?} vs {want:?}"
        );
    }
}

#[test]
fn layout_errors() {
    let e = parse("k*(x - x0) + kk").unwrap();
    let err = Program::compile(&[e], &["x", "x0", "k"]).unwrap_err();
    assert_eq!(
        err,
        ExprError::UnknownVariable {
            span: 13..15,
            name: "kk".into(),
            suggestion: Some("k".into())
        }
    );
    assert_eq!(err.to_string(), "unknown variable `kk` (did you mean `k`?)");
    assert_eq!(err.column(), Some(14));

    // No source position for a variable built in code.
    let err = Program::compile(&[Expr::var("q")], &["x"]).unwrap_err();
    assert_eq!(err.span(), None);
    assert_eq!(err.to_string(), "unknown variable `q`");

    let err = Program::compile(&[Expr::var("x")], &["x", "y", "x"]).unwrap_err();
    assert_eq!(
        err,
        ExprError::DuplicateVariable {
            name: "x".into(),
            first: 0,
            second: 2
        }
    );

    // eval_with reports the span too.
    let err = parse("1 + zz").unwrap().eval_with(&|_| None).unwrap_err();
    assert_eq!(err.span(), Some(4..6));
}

#[test]
fn outputs_that_are_inputs_or_constants() {
    let exprs = [
        parse("y").unwrap(),
        parse("2*pi").unwrap(),
        parse("x*0").unwrap(),
    ];
    let p = Program::compile(&exprs, &["x", "y"]).unwrap();
    assert_eq!(p.ops(), 0);
    assert_eq!((p.len(), p.num_vars(), p.is_empty()), (3, 2, false));
    let mut out = [0.0; 3];
    p.eval(&[1.0, 7.0], &mut out);
    // Copies of an input and of folded constants: exact.
    assert_eq!(
        out.map(f64::to_bits),
        [7.0, std::f64::consts::TAU, 0.0].map(f64::to_bits)
    );
    assert!(Program::compile(&[], &["x"]).unwrap().is_empty());
}

#[test]
fn large_programs_fall_back_to_the_heap() {
    // 600 distinct outputs need more than 512 registers.
    let exprs: Vec<Expr> = (0..600)
        .map(|i| parse(&format!("sin(x*{i}.5)")).unwrap())
        .collect();
    let p = Program::compile(&exprs, &["x"]).unwrap();
    let mut out = vec![0.0; 600];
    p.eval(&[0.25], &mut out);
    for (i, o) in out.iter().enumerate() {
        assert!((o - (0.25 * (i as f64 + 0.5)).sin()).abs() < 1e-15);
    }
}

#[test]
fn program_is_shareable() {
    fn assert_traits<T: Send + Sync + Clone + std::fmt::Debug>() {}
    assert_traits::<Program>();
    let p = Program::compile(&[parse("x^2").unwrap()], &["x"]).unwrap();
    std::thread::scope(|s| {
        for i in 0..2 {
            let p = &p;
            s.spawn(move || assert!((p.eval_one(0, &[i as f64]) - (i * i) as f64).abs() < 1e-15));
        }
    });
}
