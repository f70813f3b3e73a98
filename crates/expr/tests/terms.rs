//! The additive terms of an expression: they add up to it, and products are not multiplied
//! out.

use htfid_expr::{parse, Expr};

fn value(e: &Expr, x: f64) -> f64 {
    e.eval_with(&|n| match n {
        "x" => Some(x),
        "v" => Some(0.3 - x),
        "m" => Some(1.7),
        "g" => Some(9.81),
        "k" => Some(200.0),
        "x0" => Some(0.2),
        "c" => Some(2.0),
        "u" => Some(x * x),
        _ => None,
    })
    .unwrap()
}

#[test]
fn the_terms_add_up_to_the_expression() {
    for src in [
        "(-m*g - k*(x - x0) - c*v + u) / m",
        "-(x - 2*v) - (u + -x)/(m - v) + sin(x)*(v + 1)",
        "k*x",
        "-(-(x + v))",
        "((x + v)/m - u)/k",
    ] {
        let e = parse(src).unwrap();
        let terms = e.terms();
        for x in [-1.3, 0.0, 0.4, 2.5] {
            let sum: f64 = terms.iter().map(|t| value(t, x)).sum();
            let whole = value(&e, x);
            // Rounding only: the terms are the same operations regrouped (a few ulps of the
            // largest term, here under 1e3).
            assert!(
                (sum - whole).abs() <= 1e-12 * whole.abs().max(1e3),
                "{src} at {x}: {sum} vs {whole}"
            );
        }
    }
}

#[test]
fn a_spring_in_a_velocity_equation_is_one_term() {
    let e = parse("(-m*g - k*(x - x0) - c*v + u) / m").unwrap();
    let terms = e.terms();
    assert_eq!(terms.len(), 4, "{terms:?}");
    // Exactly one term depends on x, and it is the whole spring over the mass.
    let on_x: Vec<&Expr> = terms.iter().filter(|t| t.depends_on("x")).collect();
    assert_eq!(on_x.len(), 1);
    assert!(!on_x[0].depends_on("v") && on_x[0].depends_on("x0"));
    // -k (x - x0) / m at x = 0.5: -200 * 0.3 / 1.7.
    assert!((value(on_x[0], 0.5) + 200.0 * 0.3 / 1.7).abs() < 1e-12);
    // A product of sums stays whole.
    assert_eq!(parse("(x + 1)*(v + 2)").unwrap().terms().len(), 1);
}
