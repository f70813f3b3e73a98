//! Symbolic derivatives against central finite differences (truth the differentiator did not
//! produce) and against hand-written formulas.

mod common;

use common::{lookup, Rng};
use htfid_expr::{parse, Expr};

fn eval(e: &Expr, v: [f64; 3]) -> f64 {
    e.eval_with(&lookup(v)).unwrap()
}

/// Checks d/d`var` of `src` against a central difference at `n` random points drawn from
/// `[lo, hi]^3`. Step `h = 1e-6 max(1, |v|)`: truncation error ~ h^2 f''' ~ 1e-12, rounding
/// ~ eps |f| / h ~ 1e-10, so a tolerance of `1e-6 max(1, |f'|)` leaves a wide margin while a
/// wrong rule (a missing factor, a wrong sign) fails by orders of magnitude.
fn check_fd(src: &str, var: usize, lo: f64, hi: f64, rng: &mut Rng) {
    let e = parse(src).unwrap();
    let name = common::VARS[var];
    let d = e.derivative(name);
    let mut checked = 0;
    for _ in 0..200 {
        let mut p = [
            rng.uniform(lo, hi),
            rng.uniform(lo, hi),
            rng.uniform(lo, hi),
        ];
        let h = 1e-6 * p[var].abs().max(1.0);
        let x0 = p[var];
        p[var] = x0 + h;
        let fp = eval(&e, p);
        p[var] = x0 - h;
        let fm = eval(&e, p);
        p[var] = x0;
        // Stay away from kinks: skip points where a non-smooth piece switches within the stencil.
        let f0 = eval(&e, p);
        if !(fp.is_finite() && fm.is_finite() && f0.is_finite())
            || (fp - f0).abs() > 1e3 * (f0 - fm).abs() + 1e-9
        {
            continue;
        }
        let fd = (fp - fm) / (2.0 * h);
        let exact = eval(&d, p);
        assert!(
            (fd - exact).abs() <= 1e-6 * exact.abs().max(1.0),
            "d/d{name} {src} at {p:?}: symbolic {exact} ({d}), finite difference {fd}"
        );
        checked += 1;
        if checked == 20 {
            return;
        }
    }
    panic!("{src}: only {checked} usable points");
}

#[test]
fn every_function_against_finite_differences() {
    let mut rng = Rng::new(42);
    // Inner functions of x and y make the chain rule matter; domains keep arguments valid.
    let cases: &[(&str, f64, f64)] = &[
        ("sin(x*y + x^2)", -2.0, 2.0),
        ("cos(x*y - x)", -2.0, 2.0),
        ("tan(0.3*x*y)", -1.0, 1.0),
        ("asin(0.4*x*y)", -1.2, 1.2),
        ("acos(0.4*x - 0.3*y)", -1.0, 1.0),
        ("atan(x^3 - y)", -2.0, 2.0),
        ("sinh(x*y)", -1.5, 1.5),
        ("cosh(x - y^2)", -1.5, 1.5),
        ("tanh(2*x*y)", -1.0, 1.0),
        ("exp(x*y)", -1.5, 1.5),
        ("ln(x^2 + y^2 + 0.1)", -2.0, 2.0),
        ("log(1 + x^2*y^2)", -2.0, 2.0),
        ("log10(2 + sin(x*y))", -2.0, 2.0),
        ("sqrt(1 + x^2 + y)", 0.0, 2.0),
        ("abs(x - y)", -2.0, 2.0),
        ("sign(x - y)*x^2", -2.0, 2.0),
        ("step(x - y)*x^2", -2.0, 2.0),
        ("pos(x*y - 0.5)", -2.0, 2.0),
        ("sat(2*x - y)", -2.0, 2.0),
        ("min(x^2, x*y)", -2.0, 2.0),
        ("max(x^2, x*y)", -2.0, 2.0),
        ("atan2(y + x, x - 0.3*y)", -2.0, 2.0),
        ("hypot(x*y, x - 1)", -2.0, 2.0),
        ("pow(x^2 + 1, y)", -2.0, 2.0),
        ("(x^2 + 1)^(x*y)", -1.5, 1.5),
        ("y^x", 0.5, 2.0),
        ("x^3 - 2*x^-2 + x^0.5 + x^2.7", 0.2, 2.0),
        ("clamp(x*y, x - 1, y + 0.5)", -2.0, 2.0),
        ("if(x - y, x^2, sin(x))", -2.0, 2.0),
        ("(x < y)*x + (x >= y)*x^2", -2.0, 2.0),
        ("x/(y + 3) - (x*y)/(1 + x^2)", -2.0, 2.0),
        ("-x*y^2/(2 - z)", -1.0, 1.0),
        // The hopper's vector field with m = z + 3, v = y, t = y.
        (
            "(-(z + 3)*9.81 - 1.2*y - 3*(x - 0.4) + 0.5*cos(2*pi*y/2) + 0.1)/(z + 3)",
            -1.0,
            1.0,
        ),
    ];
    for &(src, lo, hi) in cases {
        check_fd(src, 0, lo, hi, &mut rng);
        check_fd(src, 1, lo, hi, &mut rng);
    }
}

#[test]
fn hand_written_derivatives() {
    let mut rng = Rng::new(7);
    // (expression, d/dx written by hand); compared numerically at random points.
    let cases = [
        ("x^2", "2*x"),
        ("sin(x)*exp(x)", "cos(x)*exp(x) + sin(x)*exp(x)"),
        ("atan2(y, x)", "-y/(x^2 + y^2)"),
        ("x^y", "y*x^(y - 1)"),
        ("y^x", "y^x*ln(y)"),
        ("ln(x)/x", "(1 - ln(x))/x^2"),
        ("sqrt(x^2 + y^2)", "x/sqrt(x^2 + y^2)"),
        ("tanh(x)", "1/cosh(x)^2"),
        ("log10(x)", "1/(x*ln(10))"),
        ("(-m*g - c*v - k*(x - x0) + a*cos(2*pi*t/T) + u)/m", "-k/m"),
    ];
    for (src, want) in cases {
        let d = parse(src).unwrap().derivative("x");
        let want = parse(want).unwrap();
        for _ in 0..20 {
            let vals = [
                rng.uniform(0.2, 2.0),
                rng.uniform(0.2, 2.0),
                rng.uniform(0.2, 2.0),
            ];
            let look = |n: &str| {
                Some(match n {
                    "x" => vals[0],
                    "y" => vals[1],
                    _ => vals[2] + n.len() as f64,
                })
            };
            let (a, b) = (d.eval_with(&look).unwrap(), want.eval_with(&look).unwrap());
            assert!(
                (a - b).abs() <= 1e-13 * b.abs().max(1.0),
                "d/dx {src} = {d}: {a} vs {b}"
            );
        }
    }
}

#[test]
fn derivatives_are_simplified() {
    let d = |src: &str, x: &str| parse(src).unwrap().derivative(x).to_string();
    assert_eq!(d("x^2", "x"), "2*x");
    assert_eq!(d("x^3", "x"), "3*x^2");
    assert_eq!(d("k*x", "x"), "k");
    assert_eq!(d("k*x", "y"), "0");
    assert_eq!(d("-x", "x"), "-1");
    assert_eq!(d("3*x + 2", "x"), "3");
    assert_eq!(d("sin(x)", "x"), "cos(x)");
    assert_eq!(d("x/m", "x"), "1/m");
    assert_eq!(
        d("(-m*g - c*v - k*(x - x0) + a*cos(2*pi*t/T) + u)/m", "v"),
        "-(c/m)"
    );
    assert_eq!(d("abs(x)", "x"), "sign(x)");
    assert_eq!(d("pos(x)", "x"), "step(x)");
    assert_eq!(d("x < y", "x"), "0");
    assert_eq!(d("step(x) + sign(x)", "x"), "0");
    // The derivative of a derivative works on the simplified tree.
    assert_eq!(
        parse("x^3")
            .unwrap()
            .derivative("x")
            .derivative("x")
            .to_string(),
        "3*(2*x)"
    );
}

#[test]
fn kinks_follow_the_branch_of_the_value() {
    let at = |src: &str, x: f64, y: f64| {
        let d = parse(src).unwrap().derivative("x");
        d.eval_with(&|n| Some(if n == "x" { x } else { y }))
            .unwrap()
    };
    // Ties go to the branch whose value is returned.
    assert!((at("max(x, y)", 1.0, 1.0) - 0.0).abs() < 1e-15); // value is y
    assert!((at("max(y, x)", 1.0, 1.0) - 1.0).abs() < 1e-15); // value is x
    assert!((at("min(x, y)", 1.0, 1.0) - 0.0).abs() < 1e-15);
    assert!((at("min(y, x)", 1.0, 1.0) - 1.0).abs() < 1e-15);
    assert!((at("clamp(x, -1, 1)", 1.0, 0.0) - 0.0).abs() < 1e-15); // the bound
    assert!((at("clamp(x, -1, 1)", 0.5, 0.0) - 1.0).abs() < 1e-15);
    assert!((at("clamp(y, x, 1)", 2.0, 0.0) - 1.0).abs() < 1e-15); // below the lower bound x
    assert!((at("sat(x)", -1.0, 0.0) - 0.0).abs() < 1e-15);
    assert!((at("sat(x)", 0.99, 0.0) - 1.0).abs() < 1e-15);
    assert!((at("pos(x)", 0.0, 0.0) - 0.0).abs() < 1e-15);
    assert!((at("abs(x)", 0.0, 0.0) - 0.0).abs() < 1e-15);
    assert!((at("abs(x)", -2.0, 0.0) - -1.0).abs() < 1e-15);
    assert!((at("if(y, x, 2*x)", 1.0, 0.0) - 2.0).abs() < 1e-15); // c = 0 takes the else branch
    assert!((at("if(y, x, 2*x)", 1.0, 1e-300) - 1.0).abs() < 1e-15);
}

/// Expressions built in code (`plus`, `minus`, `times`, `over`) mean what their text means:
/// the same values and the same derivatives as the parsed `(x + y) * x - y / z`.
#[test]
fn built_expressions_match_their_parsed_text() {
    let (x, y, z) = (Expr::var("x"), Expr::var("y"), Expr::var("z"));
    let built = x.clone().plus(y.clone()).times(x).minus(y.over(z));
    let parsed = parse("(x + y) * x - y / z").unwrap();
    assert_eq!(built, parsed);
    for v in [[1.5, -2.0, 4.0], [0.3, 0.7, -1.1]] {
        let (a, b) = (eval(&built, v), eval(&parsed, v));
        assert!((a - b).abs() <= 1e-15 * a.abs().max(1.0), "{a} vs {b}");
        for name in common::VARS {
            let (a, b) = (
                eval(&built.derivative(name), v),
                eval(&parsed.derivative(name), v),
            );
            assert!(
                (a - b).abs() <= 1e-15 * a.abs().max(1.0),
                "d/d{name}: {a} vs {b}"
            );
        }
    }
}
