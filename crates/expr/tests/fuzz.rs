//! No input string makes anything panic: random token soup, hostile nesting, and everything an
//! accepted expression can go through afterwards.

mod common;

use common::Rng;
use htfid_expr::{parse, Program};

const ALPHABET: &[&str] = &[
    "x",
    "y",
    "k",
    "e",
    "pi",
    "2",
    ".5",
    "1e-3",
    "2.5E+4",
    "1e",
    "2x",
    "1.2.3",
    "+",
    "-",
    "*",
    "/",
    "^",
    "(",
    "(",
    ")",
    ")",
    ",",
    "<",
    "<=",
    ">",
    ">=",
    "=",
    "sin",
    "min",
    "clamp",
    "if",
    "pow",
    "atan2",
    "sqrt",
    "foo",
    " ",
    " ",
    "\t",
    "@",
    "é",
    "\u{1F600}",
    "_a1",
];

fn check(src: &str) {
    match parse(src) {
        Ok(e) => {
            // Printing parses back, and every other operation completes.
            let back = parse(&e.to_string()).unwrap_or_else(|err| panic!("{src:?} -> {e}: {err}"));
            assert_eq!(back, e, "{src:?}");
            let vars: Vec<String> = e.variables().into_iter().collect();
            let names: Vec<&str> = vars.iter().map(String::as_str).collect();
            let mut exprs = vec![e.simplify()];
            exprs.extend(names.iter().map(|n| e.derivative(n)));
            let p = Program::compile(&exprs, &names).unwrap();
            let mut out = vec![0.0; p.len()];
            p.eval(&vec![0.7; names.len()], &mut out);
            let _ = e.eval_with(&|_| Some(0.7));
        }
        Err(err) => {
            let len = src.chars().count();
            if let Some(span) = err.span() {
                assert!(
                    span.start <= span.end && span.end <= len,
                    "{src:?}: {err:?}"
                );
            }
            assert!(!err.to_string().is_empty());
        }
    }
}

#[test]
fn random_token_strings_never_panic() {
    let mut rng = Rng::new(0xF00D);
    let mut accepted = 0;
    for _ in 0..20_000 {
        let n = 1 + rng.below(30);
        let src: String = (0..n).map(|_| rng.pick(ALPHABET)).collect();
        if parse(&src).is_ok() {
            accepted += 1;
        }
        check(&src);
    }
    // The soup must reach the success path too, or half of `check` is untested.
    assert!(accepted > 300, "only {accepted} accepted");
}

#[test]
fn hostile_inputs_never_panic() {
    let inputs = [
        "(".repeat(10_000),
        ")".repeat(10_000),
        format!("{}x{}", "(".repeat(10_000), ")".repeat(10_000)),
        "-".repeat(100_000),
        "sin(".repeat(10_000),
        vec!["x"; 10_000].join("^"),
        vec!["x"; 100_000].join("*"),
        vec!["2"; 100_000].join("+"),
        format!("{}x", "-+".repeat(50_000)),
        "9".repeat(400),
        format!("0.{}1", "0".repeat(400)),
        "\u{0}\u{7f}\u{feff}".to_owned(),
        // Deepest accepted nesting, then derivative and compile on it.
        format!("{}x{}", "sin(".repeat(200), ")".repeat(200)),
        format!("{}x{}", "exp(2*".repeat(100), ")".repeat(100)),
    ];
    for src in &inputs {
        check(src);
    }
}
