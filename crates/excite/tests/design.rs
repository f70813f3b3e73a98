//! Design properties checked by brute force, independently of the design code.

use std::collections::{HashMap, HashSet};
use std::f64::consts::TAU;

use approx::assert_abs_diff_eq;
use htfid_excite::{
    design_htf_multisine, Amplitude, BinOwner, Branch, Design, DesignSpec, EvenOrder, ExciteError,
    PhaseRule, Polarity, Signal,
};

fn headline() -> DesignSpec {
    DesignSpec {
        period: 1.0,
        max_harmonic: 3,
        omega_lo: 1.0,
        omega_hi: 40.0,
        spacing: 0.45,
        amplitude: Amplitude::Peak(0.004),
        phases: PhaseRule::Schroeder,
        even_order: EvenOrder::SignReversal,
        settle: 10.0,
        start: 30.0,
        max_record: 600.0,
    }
}

fn specs() -> Vec<DesignSpec> {
    let h = headline();
    vec![
        h.clone(),
        DesignSpec {
            even_order: EvenOrder::Unprotected,
            ..h.clone()
        },
        // Non-unit period, band from DC, random phases, RMS level.
        DesignSpec {
            period: 0.5,
            max_harmonic: 2,
            omega_lo: 0.0,
            omega_hi: 30.0,
            spacing: 1.0,
            amplitude: Amplitude::Rms(0.01),
            phases: PhaseRule::Random { seed: 5 },
            even_order: EvenOrder::QuadraticGuard,
            settle: 0.3,
            start: 2.0,
            max_record: 1000.0,
        },
        // Narrow band far from DC: lines that serve no harmonic are dropped.
        DesignSpec {
            period: 1.0,
            max_harmonic: 1,
            omega_lo: 30.0,
            omega_hi: 32.0,
            spacing: 0.3,
            amplitude: Amplitude::Peak(1.0),
            phases: PhaseRule::Schroeder,
            even_order: EvenOrder::SignReversal,
            settle: 0.0,
            start: 0.0,
            max_record: 2000.0,
        },
        // LTI-only request (H = 0).
        DesignSpec {
            period: 2.0,
            max_harmonic: 0,
            omega_lo: 0.5,
            omega_hi: 5.0,
            spacing: 0.2,
            amplitude: Amplitude::Peak(1.0),
            phases: PhaseRule::Zero,
            even_order: EvenOrder::Unprotected,
            settle: 3.0,
            start: -4.0,
            max_record: 500.0,
        },
    ]
}

#[test]
fn headline_design_is_feasible_and_as_reported() {
    let d = design_htf_multisine(headline()).unwrap();
    let r = d.report();
    // P >= 2 (w_hi + H wp) / spacing + 2 = 263.6 is the line-count bound;
    // the design must be no more than 10 % above it.
    let bound = 2.0 * (40.0 + 3.0 * TAU) / 0.45 + 2.0;
    let p = d.periods_per_multisine() as f64;
    assert!(p >= bound && p <= 1.1 * bound, "P = {p}, bound {bound}");
    assert_abs_diff_eq!(d.multisine_period(), p, epsilon = 1e-9);
    assert!(d.total_duration() <= 600.0);
    assert_eq!(d.blocks().len(), 2);
    assert_eq!(r.line_count, d.lines().len());
    assert!(r.harmonics.iter().all(|c| c.meets_target));
    assert_abs_diff_eq!(d.multisine().peak(), 0.004, epsilon = 1e-15);
    let json = serde_json::to_value(&r).unwrap();
    assert_eq!(json["periods_per_multisine"], d.periods_per_multisine());
    assert_eq!(json["even_order"], "sign_reversal");
    let text = r.to_string();
    assert!(text.contains("does not resolve"), "{text}");
}

#[test]
fn output_bins_are_distinct_for_all_lines_and_harmonics_up_to_20() {
    for spec in specs() {
        let d = design_htf_multisine(spec).unwrap();
        let p = d.periods_per_multisine() as i64;
        let mut seen = HashSet::new();
        for l in d.lines() {
            let b = l.bin as i64;
            for n in -20..=20 {
                for c in [b + n * p, -b + n * p] {
                    assert!(seen.insert(c), "bin {c} hit twice (P = {p})");
                    // Never on the periodic-orbit bins.
                    assert_ne!(c.rem_euclid(p), 0);
                }
            }
        }
        assert_eq!(seen.len(), d.lines().len() * 2 * 41);
    }
}

#[test]
fn every_harmonic_brackets_the_band_at_the_target_spacing() {
    for spec in specs() {
        let d = design_htf_multisine(spec.clone()).unwrap();
        let wp = TAU / spec.period;
        let tm = d.multisine_period();
        assert_abs_diff_eq!(
            tm,
            d.periods_per_multisine() as f64 * spec.period,
            epsilon = 1e-9
        );
        for l in d.lines() {
            assert_abs_diff_eq!(l.omega, TAU * l.bin as f64 / tm, epsilon = 1e-9);
        }
        let h = spec.max_harmonic as i32;
        for n in -h..=h {
            // Estimate frequencies of G_n from the line list alone.
            let mut w: Vec<f64> = d
                .lines()
                .iter()
                .flat_map(|l| [f64::from(n) * wp + l.omega, f64::from(n) * wp - l.omega])
                .collect();
            w.sort_by(f64::total_cmp);
            let below = w.iter().rposition(|&x| x <= spec.omega_lo + 1e-9);
            let above = w.iter().position(|&x| x >= spec.omega_hi - 1e-9);
            let (a, b) = (
                below.expect("point below band"),
                above.expect("point above band"),
            );
            let gap = w[a..=b].windows(2).map(|p| p[1] - p[0]).fold(0.0, f64::max);
            // 1e-9 relative: spacing is met exactly by construction, up to rounding.
            assert!(
                gap <= spec.spacing * (1.0 + 1e-9),
                "n = {n}: gap {gap} > {}",
                spec.spacing
            );
            let pts = d.htf_points(n);
            assert_eq!(pts.len(), 2 * d.lines().len());
            for q in pts {
                assert_abs_diff_eq!(q.omega, q.output_bin as f64 * TAU / tm, epsilon = 1e-9);
            }
        }
    }
}

#[test]
fn narrow_band_design_drops_unneeded_lines() {
    let spec = specs()[3].clone();
    let d = design_htf_multisine(spec.clone()).unwrap();
    let wp = TAU / spec.period;
    // Inputs serving outputs in 30..32 rad/s through |n| <= 1 lie near
    // |w - n wp| in [23.7, 25.7], [30, 32], [36.3, 38.3].
    for l in d.lines() {
        let near = [-1.0, 0.0, 1.0].iter().any(|&n| {
            let lo = (spec.omega_lo - n * wp)
                .abs()
                .min((spec.omega_hi - n * wp).abs());
            let hi = (spec.omega_lo - n * wp)
                .abs()
                .max((spec.omega_hi - n * wp).abs());
            l.omega >= lo - 1.0 && l.omega <= hi + 1.0
        });
        assert!(near, "line at {} rad/s serves no harmonic", l.omega);
    }
    assert!(d.lines()[0].omega > 20.0);
}

#[test]
fn bin_owner_names_line_harmonic_and_branch() {
    let d = design_htf_multisine(headline()).unwrap();
    let p = d.periods_per_multisine() as i64;
    for (i, l) in d.lines().iter().enumerate().step_by(7) {
        for n in -20i64..=20 {
            let b = l.bin as i64;
            assert_eq!(
                d.bin_owner(b + n * p),
                BinOwner::Line {
                    line: i,
                    harmonic: n,
                    branch: Branch::Direct
                }
            );
            assert_eq!(
                d.bin_owner(-b + n * p),
                BinOwner::Line {
                    line: i,
                    harmonic: n,
                    branch: Branch::Mirror
                }
            );
        }
    }
    assert_eq!(d.bin_owner(-3 * p), BinOwner::Periodic { harmonic: -3 });
    // The headline uses 133 of 140 residue pairs; the rest are unused.
    let used: HashSet<u64> = d
        .lines()
        .iter()
        .flat_map(|l| [l.bin % p as u64, p as u64 - l.bin % p as u64])
        .collect();
    let free = (1..p as u64).find(|r| !used.contains(r)).unwrap();
    assert_eq!(d.bin_owner(free as i64 + 5 * p), BinOwner::Unused);
}

/// For each line, whether some `+-b_i +- b_j (mod P)` equals `+-b_k (mod P)`,
/// by enumerating every product and sign.
fn brute_exposure(d: &Design) -> Vec<bool> {
    let p = d.periods_per_multisine() as i64;
    let mut owner: HashMap<i64, usize> = HashMap::new();
    for (k, l) in d.lines().iter().enumerate() {
        owner.insert((l.bin as i64).rem_euclid(p), k);
        owner.insert((-(l.bin as i64)).rem_euclid(p), k);
    }
    let mut hit = vec![false; d.lines().len()];
    for li in d.lines() {
        for lj in d.lines() {
            for (si, sj) in [(1, 1), (1, -1), (-1, 1), (-1, -1)] {
                let r = (si * li.bin as i64 + sj * lj.bin as i64).rem_euclid(p);
                if let Some(&k) = owner.get(&r) {
                    hit[k] = true;
                }
            }
        }
    }
    hit
}

#[test]
fn quadratic_guard_keeps_second_order_products_off_every_line() {
    let spec = specs()[2].clone();
    let d = design_htf_multisine(spec).unwrap();
    assert!(brute_exposure(&d).iter().all(|&e| !e));
    assert!(d.lines().iter().all(|l| !l.second_order_exposed));
    assert_eq!(d.report().second_order_exposed_lines, 0);
}

#[test]
fn exposure_flags_match_brute_force() {
    for spec in specs() {
        let d = design_htf_multisine(spec).unwrap();
        let flags: Vec<bool> = d.lines().iter().map(|l| l.second_order_exposed).collect();
        assert_eq!(flags, brute_exposure(&d));
    }
    let unprotected = design_htf_multisine(specs()[1].clone()).unwrap();
    assert!(unprotected.report().second_order_exposed_lines > 0);
    assert!(unprotected
        .report()
        .limitations
        .iter()
        .any(|s| s.contains("second-order")));
}

#[test]
fn infeasible_spec_reports_the_needed_p() {
    let spec = DesignSpec {
        even_order: EvenOrder::QuadraticGuard,
        ..headline()
    };
    let err = design_htf_multisine(spec).unwrap_err();
    match err {
        ExciteError::RecordTooLong {
            needed_p,
            multisine_period,
            record,
            max_record,
        } => {
            // The guard needs 3 J < P with J >= 2 (w_hi + H wp) / spacing.
            assert!(needed_p as f64 >= 6.0 * (40.0 + 3.0 * TAU) / 0.45);
            assert_abs_diff_eq!(multisine_period, needed_p as f64, epsilon = 1e-9);
            assert_abs_diff_eq!(record, 10.0 + needed_p as f64, epsilon = 1e-9);
            assert_abs_diff_eq!(max_record, 600.0);
        }
        other => panic!("unexpected {other:?}"),
    }
    let msg = design_htf_multisine(DesignSpec {
        max_record: 100.0,
        ..headline()
    })
    .unwrap_err()
    .to_string();
    assert!(
        msg.starts_with("infeasible design: needs P >= 281 (Tm = 281 s), record 582 s > max 100 s"),
        "{msg}"
    );
}

#[test]
fn absurd_targets_fail_fast() {
    let spec = DesignSpec {
        spacing: 1e-9,
        ..headline()
    };
    // P >= 2 * 58.85 / 1e-9: far over budget, reported from the bound.
    match design_htf_multisine(spec.clone()).unwrap_err() {
        ExciteError::RecordTooLong { needed_p, .. } => {
            assert!(needed_p as f64 >= 2.0 * (40.0 + 3.0 * TAU) / 1e-9 * 0.999)
        }
        other => panic!("unexpected {other:?}"),
    }
    let unlimited = DesignSpec {
        max_record: 1e300,
        ..spec
    };
    assert!(matches!(
        design_htf_multisine(unlimited),
        Err(ExciteError::NoDesign { .. })
    ));
}

#[test]
fn invalid_specs_are_rejected_with_their_numbers() {
    let bad = |f: fn(&mut DesignSpec)| {
        let mut s = headline();
        f(&mut s);
        design_htf_multisine(s).unwrap_err().to_string()
    };
    assert_eq!(
        bad(|s| s.spacing = -1.0),
        "spacing must be finite and > 0 (got -1)"
    );
    assert_eq!(
        bad(|s| s.omega_hi = 0.5),
        "omega_hi must be > omega_lo (got 0.5)"
    );
    assert_eq!(
        bad(|s| s.start = 0.25),
        "start 0.25 s is not a whole number of forcing periods T = 1 s; \
         measured windows must begin at forcing phase 0"
    );
    assert_eq!(
        bad(|s| s.amplitude = Amplitude::Peak(0.0)),
        "peak amplitude must be finite and > 0 (got 0)"
    );
}

#[test]
fn designs_are_reproducible_from_the_seed() {
    let make = |seed| {
        design_htf_multisine(DesignSpec {
            phases: PhaseRule::Random { seed },
            ..headline()
        })
        .unwrap()
    };
    let bits = |d: &Design| {
        d.lines()
            .iter()
            .map(|l| l.phase.to_bits())
            .collect::<Vec<_>>()
    };
    assert_eq!(bits(&make(1)), bits(&make(1)));
    assert_ne!(bits(&make(1)), bits(&make(2)));
}

#[test]
fn record_layout_and_input_signal() {
    let spec = DesignSpec {
        settle: 9.5,
        ..headline()
    };
    let d = design_htf_multisine(spec).unwrap();
    let tm = d.multisine_period();
    // Settling rounds up to whole periods.
    assert_abs_diff_eq!(d.settle(), 10.0);
    let b = d.blocks();
    assert_eq!(b[0].polarity, Polarity::Positive);
    assert_eq!(b[1].polarity, Polarity::Negative);
    assert_abs_diff_eq!(b[0].start, 30.0);
    assert_abs_diff_eq!(b[1].start, b[0].end, epsilon = 1e-9);
    for blk in b {
        assert_abs_diff_eq!(blk.measure_start - blk.start, 10.0, epsilon = 1e-9);
        assert_abs_diff_eq!(blk.end - blk.measure_start, tm, epsilon = 1e-9);
        // Windows start on forcing phase 0 (T = 1 s).
        assert_abs_diff_eq!(blk.measure_start, blk.measure_start.round(), epsilon = 1e-9);
    }
    assert_abs_diff_eq!(d.record_end(), 30.0 + d.total_duration(), epsilon = 1e-9);

    let u = d.input();
    let m = d.multisine();
    let a_sum: f64 = m.lines().iter().map(|l| l.amplitude).sum();
    for &t in &[0.0, 29.999, d.record_end(), d.record_end() + 5.0] {
        assert_abs_diff_eq!(u.value(t), 0.0);
    }
    // The input never jumps: across every block start it is continuous (the settling segment
    // cross-fades from the previous block, or from zero, over its first half). The bound is the
    // largest change of u over 2e-6 s, |u'| <= sum |A w| <= sum |A| * 60 rad/s.
    for blk in b {
        let (before, after) = (u.value(blk.start - 1e-6), u.value(blk.start + 1e-6));
        assert!(
            (before - after).abs() < 2e-6 * 60.0 * a_sum,
            "jump at {}",
            blk.start
        );
    }
    for k in 0..200 {
        let tau = -5.0 + k as f64 * 1.4567;
        if tau >= tm {
            break;
        }
        // Same window-local time in both blocks: opposite signs, and after the cross-fade
        // (the first half of the 10 s settling) the settling segment is the periodic
        // continuation of the window.
        let plus = u.value(b[0].measure_start + tau);
        let minus = u.value(b[1].measure_start + tau);
        // Tolerance: argument rounding of ~2650 bins at t ~ 600 s, times sum |A|.
        assert_abs_diff_eq!(plus, -minus, epsilon = 1e-11 * a_sum);
        assert_abs_diff_eq!(plus, m.value(tau.rem_euclid(tm)), epsilon = 1e-11 * a_sum);
    }
    // The fast path agrees with point evaluation across every block edge.
    let (t0, dt) = (25.0, 0.01);
    let n = ((d.record_end() + 5.0 - t0) / dt) as usize;
    let fast = u.sample_uniform(t0, dt, n);
    for (i, f) in fast.iter().enumerate() {
        assert_abs_diff_eq!(*f, u.value(t0 + i as f64 * dt), epsilon = 1e-11 * a_sum);
    }
}

/// A spacing far below what the band can use ends the search with an error instead of
/// searching for hours; the bound is on work, so the record budget alone cannot hold it.
#[test]
fn an_absurdly_fine_spacing_ends_the_search() {
    let spec = DesignSpec {
        spacing: 1e-4,
        max_record: 1e9,
        ..headline()
    };
    let size = htfid_excite::design_size(&spec).unwrap();
    assert!(size.min_p > 1_000_000, "{size:?}");
    match design_htf_multisine(spec) {
        Err(ExciteError::NoDesign { searched_up_to }) => {
            assert!(
                searched_up_to >= size.min_p,
                "{searched_up_to} < {}",
                size.min_p
            )
        }
        other => panic!("expected NoDesign, got {other:?}"),
    }
}

/// The size bound never exceeds the design found, so refusing on it never refuses a feasible one.
#[test]
fn the_size_bound_is_below_every_design() {
    for spec in specs() {
        let size = htfid_excite::design_size(&spec).unwrap();
        let design = design_htf_multisine(spec).unwrap();
        let p = (design.multisine_period() / design.spec().period).round() as u64;
        assert!(size.min_p <= p, "min_p {} > P {p}", size.min_p);
        assert!(size.min_lines <= design.lines().len() as u64);
        assert!(size.min_record <= design.total_duration() * (1.0 + 1e-12));
        let top = design.lines().iter().map(|l| l.omega).fold(0.0, f64::max);
        assert!(
            size.min_top_line <= top * (1.0 + 1e-12),
            "{} > {top}",
            size.min_top_line
        );
        let top_bin = design.lines().iter().map(|l| l.bin).max().unwrap();
        assert!(size.min_peak_samples <= (32 * top_bin).max(64) as f64 * (1.0 + 1e-9));
    }
}
