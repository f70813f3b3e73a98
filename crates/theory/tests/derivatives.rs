//! `ExactHtf::derivatives` against truth found elsewhere: Richardson-extrapolated central
//! differences of the exact HTF of the moved system (`PiecewiseLti::moved`), and the exact
//! linearity of the HTF in `B`, `C` and `D`.

use htfid_ltp::{Piece, PieceTangent, PiecewiseLti, PiecewiseTangent};
use htfid_theory::{ExactHtf, ExactMethod, HarmonicTransferFunction, TheoryError};
use nalgebra::DMatrix;
use num_complex::Complex64;

fn m(rows: usize, cols: usize, v: &[f64]) -> DMatrix<f64> {
    DMatrix::from_row_slice(rows, cols, v)
}

/// The paper's hopper linearised: stance with the damper (`c = 2`), flight without, identity
/// jumps, the first piece starting at 0.31 s of a 1 s period.
fn hopper() -> PiecewiseLti {
    let c = m(1, 2, &[1.0, 0.0]);
    let d = m(1, 1, &[0.0]);
    let b = m(2, 1, &[0.0, 1.0]);
    PiecewiseLti::new(
        1.0,
        0.31,
        vec![
            Piece::new(
                0.43,
                m(2, 2, &[0.0, 1.0, -200.0, -2.0]),
                b.clone(),
                c.clone(),
                d.clone(),
            ),
            Piece::new(0.57, m(2, 2, &[0.0, 1.0, -200.0, 0.0]), b, c, d),
        ],
    )
    .unwrap()
}

/// Three states, three pieces, non-identity jumps, an output matrix and a feedthrough that
/// change from piece to piece (so the output jumps where the pieces meet), period 1.3 s.
fn rich() -> PiecewiseLti {
    PiecewiseLti::new(
        1.3,
        -0.2,
        vec![
            Piece::new(
                0.4,
                m(3, 3, &[-0.5, 3.0, 0.1, -4.0, -0.7, 0.3, 0.2, 0.0, -2.0]),
                m(3, 1, &[0.3, 1.0, -0.4]),
                m(1, 3, &[1.0, 0.2, 0.0]),
                m(1, 1, &[0.05]),
            )
            .with_jump(m(3, 3, &[1.0, 0.0, 0.0, -0.3, 0.8, 0.0, 0.1, 0.0, 1.1])),
            Piece::new(
                0.5,
                m(3, 3, &[0.0, 1.0, 0.0, -9.0, -0.2, 1.0, 0.0, 0.5, -1.0]),
                m(3, 1, &[0.0, 1.2, 0.1]),
                m(1, 3, &[0.8, 0.0, 0.4]),
                m(1, 1, &[-0.1]),
            )
            .with_jump(m(3, 3, &[0.9, 0.1, 0.0, 0.0, 0.7, 0.0, 0.0, 0.2, 1.0])),
            Piece::new(
                0.4,
                m(3, 3, &[-1.0, 2.0, 0.0, -2.0, -1.0, 0.0, 0.4, 0.1, -3.0]),
                m(3, 1, &[0.2, 0.5, 0.3]),
                m(1, 3, &[1.0, -0.3, 0.2]),
                m(1, 1, &[0.0]),
            ),
        ],
    )
    .unwrap()
}

/// A tangent with every kind of change, its entries spread in [-1, 1] by a fixed recurrence.
fn everything(lti: &PiecewiseLti, seed: u64) -> PiecewiseTangent {
    let mut state = seed;
    let mut next = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    };
    let (n, p) = (lti.n_states(), lti.n_outputs());
    let pieces = lti
        .pieces()
        .iter()
        .map(|_| PieceTangent {
            a: DMatrix::from_fn(n, n, |_, _| 3.0 * next()),
            b: DMatrix::from_fn(n, 1, |_, _| next()),
            c: DMatrix::from_fn(p, n, |_, _| next()),
            d: DMatrix::from_fn(p, 1, |_, _| 0.1 * next()),
            jump: DMatrix::from_fn(n, n, |_, _| 0.2 * next()),
            start: 0.05 * next(),
        })
        .collect();
    PiecewiseTangent::new(lti, pieces).unwrap()
}

/// Output frequencies and harmonics off the poles: a spread over the band of the paper, with
/// harmonics -2 to 2.
fn points() -> Vec<(i32, f64)> {
    let mut v = Vec::new();
    for k in -2..=2 {
        for w in [0.7, 3.1, 9.4, 14.3, 27.0, 41.5] {
            v.push((k, w));
        }
    }
    v
}

/// Central differences of step `h` along `t`, extrapolated with `h / 2` (Richardson): the
/// error is `O(h^4)` of the HTF's fifth derivative along the tangent, plus rounding of about
/// `1e-16 |G| / h`.
fn extrapolated(
    lti: &PiecewiseLti,
    t: &PiecewiseTangent,
    h: f64,
    pts: &[(i32, f64)],
) -> Vec<Complex64> {
    let central = |h: f64| -> Vec<Complex64> {
        let plus = ExactHtf::new(&lti.moved(t, h).unwrap())
            .unwrap()
            .values(pts);
        let minus = ExactHtf::new(&lti.moved(t, -h).unwrap())
            .unwrap()
            .values(pts);
        plus.iter()
            .zip(&minus)
            .map(|(a, b)| (a - b) / (2.0 * h))
            .collect()
    };
    let coarse = central(h);
    let fine = central(h / 2.0);
    fine.iter()
        .zip(&coarse)
        .map(|(f, c)| (4.0 * f - c) / 3.0)
        .collect()
}

/// The largest error against the largest value of the reference.
fn relative_error(got: &[Complex64], want: &[Complex64]) -> f64 {
    let scale = want.iter().map(|v| v.norm()).fold(0.0, f64::max);
    got.iter()
        .zip(want)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max)
        / scale
}

#[test]
fn derivatives_match_extrapolated_differences() {
    // Step 1e-4 of tangents of order one (the starts' of order 0.05 s): the truncation error
    // of the extrapolated difference is about 1e-16 relative and its rounding about
    // 1e-16 / 1e-4 = 1e-12; 1e-8 leaves room for the HTF's own conditioning near its
    // resonances while a wrong term (of the size of the derivative) could not pass.
    let pts = points();
    for (name, lti) in [("hopper", hopper()), ("three states", rich())] {
        let htf = ExactHtf::new(&lti).unwrap();
        for seed in [1, 2, 3] {
            let t = everything(&lti, seed);
            let got = htf
                .derivatives(std::slice::from_ref(&t), &pts)
                .unwrap()
                .remove(0);
            let want = extrapolated(&lti, &t, 1e-4, &pts);
            let err = relative_error(&got, &want);
            eprintln!("{name}, seed {seed}: {err:e}");
            assert!(err < 1e-8, "{name}, seed {seed}: {err:e}");
        }
    }
}

/// What a test keeps of a piece's tangent.
type Keep = fn(&mut PieceTangent);

/// Each kind of change alone: the matrices `A`, the matrices `B`, `C`, `D`, the jumps, and the
/// moved starts (which carry the output's jumps and the stretch of flow handed from piece to
/// piece).
fn kinds() -> [(&'static str, Keep); 4] {
    [
        ("dA", |p| {
            p.b.fill(0.0);
            p.c.fill(0.0);
            p.d.fill(0.0);
            p.jump.fill(0.0);
            p.start = 0.0;
        }),
        ("dB, dC, dD", |p| {
            p.a.fill(0.0);
            p.jump.fill(0.0);
            p.start = 0.0;
        }),
        ("dJ", |p| {
            p.a.fill(0.0);
            p.b.fill(0.0);
            p.c.fill(0.0);
            p.d.fill(0.0);
            p.start = 0.0;
        }),
        ("d tau", |p| {
            p.a.fill(0.0);
            p.b.fill(0.0);
            p.c.fill(0.0);
            p.d.fill(0.0);
            p.jump.fill(0.0);
        }),
    ]
}

/// `full` cut to each of [`kinds`].
fn each_kind(full: &PiecewiseTangent) -> Vec<PiecewiseTangent> {
    kinds()
        .iter()
        .map(|(_, keep)| {
            let mut t = full.clone();
            t.pieces_mut().iter_mut().for_each(keep);
            t
        })
        .collect()
}

#[test]
fn each_kind_of_change_alone_matches_differences() {
    // One kind at a time, so a term that cancels against another in the combined tangent
    // cannot hide. Tolerance as above.
    let lti = rich();
    let htf = ExactHtf::new(&lti).unwrap();
    let pts = points();
    let tangents = each_kind(&everything(&lti, 7));
    let got = htf.derivatives(&tangents, &pts).unwrap();
    for ((name, _), (t, got)) in kinds().iter().zip(tangents.iter().zip(&got)) {
        let want = extrapolated(&lti, t, 1e-4, &pts);
        let err = relative_error(got, &want);
        eprintln!("{name}: {err:e}");
        assert!(err < 1e-8, "{name}: {err:e}");
        assert!(
            want.iter().any(|v| v.norm() > 1e-3),
            "{name} changes nothing here"
        );
    }
}

#[test]
fn the_htf_is_linear_in_b_c_and_d() {
    // G is linear in (B, D) and, separately, in (C, D): along dB = B, dD = D the derivative
    // is G itself, and along dC = C, dD = D too. Exact algebra, so the tolerance is rounding:
    // 1e-12 relative.
    let lti = rich();
    let htf = ExactHtf::new(&lti).unwrap();
    let pts = points();
    let mut along_b = PiecewiseTangent::zero(&lti);
    let mut along_cd = PiecewiseTangent::zero(&lti);
    for (i, piece) in lti.pieces().iter().enumerate() {
        along_b.pieces_mut()[i].b = piece.b().clone();
        along_b.pieces_mut()[i].d = piece.d().clone();
        along_cd.pieces_mut()[i].c = piece.c().clone();
        along_cd.pieces_mut()[i].d = piece.d().clone();
    }
    let g = htf.values(&pts);
    let got = htf
        .derivatives(&[along_b, along_cd, PiecewiseTangent::zero(&lti)], &pts)
        .unwrap();
    assert!(
        relative_error(&got[0], &g) < 1e-12,
        "{:e}",
        relative_error(&got[0], &g)
    );
    assert!(
        relative_error(&got[1], &g) < 1e-12,
        "{:e}",
        relative_error(&got[1], &g)
    );
    assert!(got[2].iter().all(|v| v.norm() == 0.0));
}

#[test]
fn a_tangent_of_another_system_is_refused() {
    let htf = ExactHtf::new(&hopper()).unwrap();
    let other = PiecewiseTangent::zero(&rich());
    assert!(matches!(
        htf.derivatives(&[other], &points()),
        Err(TheoryError::Ltp(_))
    ));
}

/// A flight-and-impact system as a linearised bouncing ball gives it: free flight
/// (`[[0, 1], [0, 0]]`, a Jordan block: no eigenvector basis, so the block-exponential path)
/// between impacts whose jump is not the identity, and a short contact piece with a spring
/// and damper, period 0.25 s.
fn flight() -> PiecewiseLti {
    let c = m(1, 2, &[1.0, 0.0]);
    PiecewiseLti::new(
        0.25,
        0.03,
        vec![
            Piece::new(
                0.2,
                m(2, 2, &[0.0, 1.0, 0.0, 0.0]),
                m(2, 1, &[0.0, 1.0]),
                c.clone(),
                m(1, 1, &[0.0]),
            )
            .with_jump(m(2, 2, &[1.0, 0.0, 31.0, -0.8])),
            Piece::new(
                0.05,
                m(2, 2, &[0.0, 1.0, -900.0, -6.0]),
                m(2, 1, &[0.0, 1.0]),
                c,
                m(1, 1, &[0.02]),
            ),
        ],
    )
    .unwrap()
}

/// The block-exponential path against the modal path, on systems both can take: the two
/// compute the same derivatives by different algebra (an augmented matrix exponential per
/// piece against divided differences in eigenvector coordinates). Both are exact, so the
/// tolerance, 1e-10 of the largest derivative, is rounding amplified by the conditioning of
/// the eigenvector bases and of the matrix exponential's scaling and squaring.
#[test]
fn the_block_path_matches_the_modal_path() {
    let pts = points();
    for (name, lti) in [("hopper", hopper()), ("three states", rich())] {
        let modal = ExactHtf::with_method(&lti, ExactMethod::Modal).unwrap();
        let block = ExactHtf::with_method(&lti, ExactMethod::BlockExponential).unwrap();
        let tangents: Vec<PiecewiseTangent> = (1..=3).map(|s| everything(&lti, s)).collect();
        let want = modal.derivatives(&tangents, &pts).unwrap();
        let got = block.derivatives(&tangents, &pts).unwrap();
        for (seed, (got, want)) in got.iter().zip(&want).enumerate() {
            let err = relative_error(got, want);
            eprintln!("{name}, seed {}: block against modal {err:e}", seed + 1);
            assert!(err < 1e-10, "{name}, seed {}: {err:e}", seed + 1);
        }
    }
}

/// A system only the block path takes (a Jordan block in flight), every kind of change at
/// once and each alone, against extrapolated differences of the moved system. The values of
/// the block path carry more rounding than the modal path's, which the differences amplify
/// by about `1/h`: against these derivatives the reference is off by 7e-5 at `h = 1e-5`, 3e-6
/// at `1e-4` and 2e-8 at `1e-3` (measured), while its truncation, `O(h^4)` along tangents of
/// order one, stays near 1e-12 at `1e-3`. So the step is `1e-3` and the tolerance 1e-6, fifty
/// times the reference's measured error and far below a wrong term's (of the size of the
/// derivative). Measured at 1e-3: 2e-8 for every kind at once, 7e-8 for `dA` alone, 1e-13
/// to 4e-12 for the other kinds alone.
#[test]
fn a_defective_system_matches_differences() {
    let lti = flight();
    let htf = ExactHtf::new(&lti).unwrap();
    assert_eq!(htf.method(), ExactMethod::BlockExponential);
    let wp = std::f64::consts::TAU / 0.25;
    let pts: Vec<(i32, f64)> = (-2..=2)
        .flat_map(|k| [0.3, 0.9, 1.7, 2.6].map(|r| (k, r * wp)))
        .collect();
    let full = everything(&lti, 11);
    let mut tangents = vec![full.clone()];
    tangents.extend(each_kind(&full));
    let got = htf.derivatives(&tangents, &pts).unwrap();
    let names = std::iter::once("all").chain(kinds().map(|(name, _)| name));
    for (name, (t, got)) in names.zip(tangents.iter().zip(&got)) {
        let want = extrapolated(&lti, t, 1e-3, &pts);
        let err = relative_error(got, &want);
        eprintln!("flight, {name}: {err:e}");
        assert!(err < 1e-6, "flight, {name}: {err:e}");
        assert!(
            want.iter().any(|v| v.norm() > 1e-6),
            "{name} changes nothing here"
        );
    }
}
