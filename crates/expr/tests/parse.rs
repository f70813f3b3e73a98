//! Syntax: precedence against hand-computed values, printing round trips, and every error
//! with its exact position.

mod common;

use common::{close, lookup, random_expr, Rng};
use htfid_expr::{parse, Expr, ExprError};

fn value(src: &str) -> f64 {
    let e = parse(src).unwrap_or_else(|err| panic!("{src}: {err}"));
    e.eval_with(&lookup([2.0, 3.0, -0.5])).unwrap()
}

#[test]
fn precedence_table() {
    // x = 2, y = 3, z = -0.5; every value worked out by hand.
    let table: &[(&str, f64)] = &[
        ("1 + 2*3", 7.0),
        ("(1 + 2)*3", 9.0),
        ("2^3^2", 512.0),
        ("(2^3)^2", 64.0),
        ("-x^2", -4.0),
        ("(-x)^2", 4.0),
        ("-2^2", -4.0),
        ("2^-1", 0.5),
        ("2^-1^2", 0.5),
        ("10 - 4 - 3", 3.0),
        ("24 / 4 / 3", 2.0),
        ("2*3^2", 18.0),
        ("-x*y", -6.0),
        ("--x", 2.0),
        ("+x", 2.0),
        ("-+-x", 2.0),
        ("x - -y", 5.0),
        ("x*-y", -6.0),
        ("1 + 2 < 4", 1.0),
        ("1 + 2 < 3", 0.0),
        ("x <= 2", 1.0),
        ("x >= 2.5", 0.0),
        ("y > x", 1.0),
        (".5 + 1e-3 + 2.5E+4 + 2.", 25_002.501),
        ("1e2", 100.0),
        ("2*pi", std::f64::consts::TAU),
        ("e", f64::NAN), // placeholder, replaced below: `e` is a variable, not Euler's number
        ("  x\t*\n y ", 6.0),
        ("sign(0) + sign(-3) + sign(z)", -2.0),
        ("step(0) + step(1) + step(-1)", 1.0),
        ("pos(-2) + pos(3)", 3.0),
        ("sat(5) + sat(-7) + sat(z)", -0.5),
        ("clamp(x, 0, 1) + clamp(z, 0, 1) + clamp(0.25, 0, 1)", 1.25),
        ("if(x - 1, 10, 20) + if(0, 1, 2)", 12.0),
        ("min(x, y) + max(x, y)", 5.0),
        ("atan2(1, 1)", std::f64::consts::FRAC_PI_4),
        ("hypot(3, 4)", 5.0),
        ("pow(2, 10)", 1024.0),
        ("log(exp(2)) + ln(1) + log10(1000)", 5.0),
        ("sqrt(16) + abs(z)", 4.5),
        (
            "cosh(0) + sinh(0) + tanh(0) + cos(0) + sin(0) + tan(0)",
            2.0,
        ),
        ("asin(1) + acos(1) + atan(0)", std::f64::consts::FRAC_PI_2),
    ];
    for &(src, want) in table {
        if src == "e" {
            let e = parse(src).unwrap();
            assert_eq!(e.variables().into_iter().collect::<Vec<_>>(), ["e"]);
            continue;
        }
        let got = value(src);
        assert!(
            close(got, want, 1e-15) || (got - want).abs() < 1e-15,
            "{src}: got {got}, want {want}"
        );
    }
}

#[test]
fn display_is_minimal_and_reparses() {
    let cases = [
        ("1 + 2*3", "1 + 2*3"),
        ("(1 + 2)*3", "(1 + 2)*3"),
        ("2^3^2", "2^3^2"),
        ("(2^3)^2", "(2^3)^2"),
        ("-x^2", "-x^2"),
        ("(-x)^2", "(-x)^2"),
        ("a - (b - c)", "a - (b - c)"),
        ("(a - b) - c", "a - b - c"),
        ("a/(b*c)", "a/(b*c)"),
        ("x*-y", "x*(-y)"),
        ("2*pi*t", "2*pi*t"),
        ("if(a < b, 1, 2.5e-7)", "if(a < b, 1, 2.5e-7)"),
        ("log(x)", "ln(x)"),
        ("pow(x, y)", "x^y"),
    ];
    for (src, want) in cases {
        let e = parse(src).unwrap();
        assert_eq!(e.to_string(), want, "{src}");
        assert_eq!(parse(&e.to_string()).unwrap(), e, "{src}");
    }
    // Non-finite constants print as parseable expressions.
    for v in [
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NAN,
        -0.0,
        1e300,
        -1.5e-300,
    ] {
        let text = Expr::constant(v).to_string();
        let back = parse(&text).unwrap().eval_with(&|_| None).unwrap();
        assert!(
            back.to_bits() == v.to_bits() || (v.is_nan() && back.is_nan()),
            "{v} -> {text}"
        );
    }
}

#[test]
fn random_round_trips_evaluate_identically() {
    let mut rng = Rng::new(0x5eed_0001);
    for _ in 0..2000 {
        let src = random_expr(&mut rng, 5);
        let e = parse(&src).unwrap();
        let text = e.to_string();
        let back = parse(&text).unwrap_or_else(|err| panic!("{src} -> {text}: {err}"));
        let vals = [
            rng.uniform(-2.0, 2.0),
            rng.uniform(-2.0, 2.0),
            rng.uniform(-2.0, 2.0),
        ];
        let a = e.eval_with(&lookup(vals)).unwrap();
        let b = back.eval_with(&lookup(vals)).unwrap();
        assert!(
            a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()),
            "{src} -> {text}"
        );
        // Printing is a fixed point after one round.
        assert_eq!(back.to_string(), text);
    }
}

#[test]
fn variables_spans_and_substitution() {
    let e = parse("k*(x - x0) + k").unwrap();
    let names: Vec<String> = e.variables().into_iter().collect();
    assert_eq!(names, ["k", "x", "x0"]);
    assert!(e.depends_on("x0") && !e.depends_on("m"));
    assert_eq!(e.span_of("k"), Some(0..1));
    assert_eq!(e.span_of("x0"), Some(7..9));
    assert_eq!(e.span_of("m"), None);
    // Character offsets, not bytes: the comment-free source has a 2-byte space before `k`.
    assert_eq!(parse("\u{a0}k").unwrap().span_of("k"), Some(1..2));

    let f = e.substitute("x", &parse("y^2").unwrap());
    assert_eq!(f.to_string(), "k*(y^2 - x0) + k");
    assert!(!f.depends_on("x"));
    assert_eq!(Expr::var("x"), parse("x").unwrap());
    assert_eq!(parse("2*3 + 0*m").unwrap().as_constant(), Some(6.0));
    assert_eq!(parse("2*m").unwrap().as_constant(), None);
}

fn err(src: &str) -> ExprError {
    match parse(src) {
        Ok(e) => panic!("{src} parsed as {e}"),
        Err(e) => e,
    }
}

#[test]
fn every_parse_error_is_located() {
    // (source, span, column, message)
    let cases: &[(&str, Option<std::ops::Range<usize>>, &str)] = &[
        ("", None, "empty expression"),
        ("   ", None, "empty expression"),
        (
            "k*(x + ",
            Some(7..7),
            "expected a number, a name or `(`, found end of input",
        ),
        (
            "k*(x + 1",
            Some(2..3),
            "unbalanced parenthesis: this `(` is never closed",
        ),
        (
            "x + 1)",
            Some(5..6),
            "unbalanced parenthesis: this `)` has no matching `(`",
        ),
        (
            "sin(x",
            Some(3..4),
            "unbalanced parenthesis: this `(` is never closed",
        ),
        ("sin(x, y)", Some(0..3), "`sin` takes 1 argument, found 2"),
        ("max(x)", Some(0..3), "`max` takes 2 arguments, found 1"),
        ("clamp()", Some(0..5), "`clamp` takes 3 arguments, found 0"),
        (
            "1 + sinn(x)",
            Some(4..8),
            "unknown function `sinn` (did you mean `sin`?)",
        ),
        ("foo(x)", Some(0..3), "unknown function `foo`"),
        ("pi(2)", Some(0..2), "unknown function `pi`"),
        (
            "2 * sin",
            Some(4..7),
            "`sin` is a function: call it with arguments in parentheses, as in `sin(x)`",
        ),
        (
            "x $ y",
            Some(2..3),
            "expected a number, a name, an operator, a parenthesis or `,`, found `$`",
        ),
        (
            "é + x",
            Some(0..1),
            "expected a number, a name, an operator, a parenthesis or `,`, found `é`",
        ),
        (
            "x == y",
            Some(2..3),
            "expected a number, a name, an operator, a parenthesis or `,`, found `=`",
        ),
        (
            "x y",
            Some(2..3),
            "expected an operator or the end of the expression, found `y`",
        ),
        (
            "(x y)",
            Some(3..4),
            "expected an operator or `)`, found `y`",
        ),
        (
            "min(x y)",
            Some(6..7),
            "expected an operator, `,` or `)`, found `y`",
        ),
        (
            "x * * y",
            Some(4..5),
            "expected a number, a name or `(`, found `*`",
        ),
        (
            "()",
            Some(1..2),
            "expected a number, a name or `(`, found `)`",
        ),
        (
            "min(x,)",
            Some(6..7),
            "expected a number, a name or `(`, found `)`",
        ),
        (
            "a < b < c",
            Some(6..7),
            "expected no second comparison (comparisons do not chain), found `<`",
        ),
        ("1.2.3 + x", Some(0..5), "invalid number `1.2.3`"),
        ("x + 2x", Some(4..6), "invalid number `2x`"),
        ("3 * 1e", Some(4..6), "invalid number `1e`"),
        ("1e400", Some(0..5), "invalid number `1e400`"),
        ("x + .", Some(4..5), "invalid number `.`"),
    ];
    for (src, span, msg) in cases {
        let e = err(src);
        assert_eq!(e.span(), *span, "{src}: {e:?}");
        assert_eq!(e.column(), span.as_ref().map(|s| s.start + 1), "{src}");
        assert_eq!(e.to_string(), *msg, "{src}");
    }
    assert_eq!(
        err("sin(x, y)"),
        ExprError::WrongArity {
            span: 0..3,
            name: "sin".into(),
            expected: 1,
            found: 2
        }
    );
    assert!(matches!(err("k*(x + "), ExprError::UnexpectedToken { found, .. } if found.is_empty()));
}

#[test]
fn depth_is_bounded() {
    let deep = |n: usize| format!("{}x{}", "(".repeat(n), ")".repeat(n));
    assert!(parse(&deep(200)).is_ok());
    assert_eq!(err(&deep(10_000)), ExprError::TooDeep { depth: 256 });
    assert_eq!(err(&"-".repeat(10_000)), ExprError::TooDeep { depth: 256 });
    // Shallow to parse, but a left-deep tree: the bound is on the tree.
    let long_sum = vec!["x"; 100_000].join(" + ");
    assert_eq!(err(&long_sum), ExprError::TooDeep { depth: 256 });
    assert!(parse(&vec!["x"; 200].join(" + ")).is_ok());
    let tower = vec!["x"; 10_000].join("^");
    assert_eq!(err(&tower), ExprError::TooDeep { depth: 256 });
    assert_eq!(ExprError::TooDeep { depth: 256 }.span(), None);
}
