//! Tick placement and tick labels, in plot space (log10 of the value on logarithmic axes).

/// Major ticks with their labels, and unlabelled minor ticks, all in plot space.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct Ticks {
    pub major: Vec<f64>,
    pub labels: Vec<String>,
    pub minor: Vec<f64>,
}

impl Ticks {
    /// The label of the major tick at plot-space position `v`, or an empty string.
    pub fn label_at(&self, v: f64) -> String {
        let spacing = match (self.major.first(), self.major.last()) {
            (Some(a), Some(b)) if self.major.len() > 1 => (b - a) / (self.major.len() - 1) as f64,
            _ => 1.0,
        };
        // plotters asks for labels at exactly the tick values; the tolerance only absorbs
        // rounding, far below the tick spacing at any magnitude.
        let tol = 1e-6 * spacing.abs().max(f64::MIN_POSITIVE);
        self.major
            .iter()
            .zip(&self.labels)
            .map(|(m, l)| ((m - v).abs(), l))
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .filter(|(d, _)| *d <= tol)
            .map(|(_, l)| l.clone())
            .unwrap_or_default()
    }
}

/// Decides whether labels at the given plot-space positions can be drawn without crowding.
pub(crate) type Fits<'a> = &'a dyn Fn(&[f64], &[String]) -> bool;

const MINUS: char = '\u{2212}';

/// "Nice" ticks (multiples of 1, 2, 2.5 or 5 times a power of ten) on a linear axis: the
/// densest such set whose labels fit.
pub(crate) fn linear_ticks(lo: f64, hi: f64, fits: Fits<'_>) -> Ticks {
    let span = hi - lo;
    if !(span.is_finite() && span > 0.0) {
        return Ticks::default();
    }
    // Never more than about 15 major ticks: beyond that a grid is noise.
    let finest = span / 15.0;
    let e0 = finest.log10().floor() as i32;
    let mut fallback: Option<Ticks> = None;
    for e in e0..=e0 + 4 {
        for m in [1.0, 2.0, 2.5, 5.0] {
            let step = m * 10f64.powi(e);
            if step < finest {
                continue;
            }
            let major = multiples(lo, hi, step);
            if major.is_empty() {
                return fallback.unwrap_or_default();
            }
            let labels = linear_labels(&major, step);
            let fit = fits(&major, &labels);
            let ticks = Ticks {
                major,
                labels,
                minor: Vec::new(),
            };
            if fit {
                return ticks;
            }
            fallback = Some(ticks);
        }
    }
    fallback.unwrap_or_default()
}

/// Ticks at multiples of 15, 30, 45, 90 or 180 degrees (at least three of them, the densest
/// set that fits), else the ordinary linear ticks.
pub(crate) fn angle_ticks(lo: f64, hi: f64, fits: Fits<'_>) -> Ticks {
    if !(lo.is_finite() && hi.is_finite() && hi > lo) {
        return Ticks::default();
    }
    for step in [15.0, 30.0, 45.0, 90.0, 180.0, 360.0, 720.0, 1440.0, 2880.0] {
        let major = multiples(lo, hi, step);
        if major.len() < 3 {
            break;
        }
        if major.len() > 15 {
            continue;
        }
        let labels: Vec<String> = major.iter().map(|v| fixed(*v, 0)).collect();
        if fits(&major, &labels) {
            return Ticks {
                major,
                labels,
                minor: Vec::new(),
            };
        }
    }
    linear_ticks(lo, hi, fits)
}

fn multiples(lo: f64, hi: f64, step: f64) -> Vec<f64> {
    let slack = 1e-9;
    let k0 = (lo / step - slack).ceil() as i64;
    let k1 = (hi / step + slack).floor() as i64;
    if k1 < k0 || k1 - k0 > 10_000 {
        return Vec::new();
    }
    (k0..=k1).map(|k| k as f64 * step).collect()
}

/// Number of decimals needed to print multiples of `step` exactly.
fn decimals_for(step: f64) -> usize {
    let mut scaled = step.abs();
    for d in 0..12 {
        if (scaled - scaled.round()).abs() <= 1e-6 * scaled.max(1e-300) {
            return d;
        }
        scaled *= 10.0;
    }
    12
}

fn linear_labels(major: &[f64], step: f64) -> Vec<String> {
    let mag = major.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
    let scientific = !(1e-3..1e5).contains(&mag);
    if scientific && mag > 0.0 {
        let e = mag.log10().floor() as i32;
        let scale = 10f64.powi(e);
        let d = decimals_for(step / scale);
        major
            .iter()
            .map(|v| {
                let m = v / scale;
                if m.abs() < 0.5 * 10f64.powi(-(d as i32)) {
                    "0".to_string()
                } else {
                    format!("{}\u{d7}10{}", signed(&format!("{m:.d$}")), superscript(e))
                }
            })
            .collect()
    } else {
        let d = decimals_for(step);
        major.iter().map(|v| fixed(*v, d)).collect()
    }
}

fn fixed(v: f64, d: usize) -> String {
    let s = format!("{v:.d$}");
    // A tick at -0.000 must read as 0.
    if s.trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        s.trim_start_matches('-').to_string()
    } else {
        signed(&s)
    }
}

fn signed(s: &str) -> String {
    s.replacen('-', &MINUS.to_string(), 1)
}

pub(crate) fn superscript(e: i32) -> String {
    e.to_string()
        .chars()
        .map(|c| match c {
            '-' => '\u{207b}',
            '0' => '\u{2070}',
            '1' => '\u{b9}',
            '2' => '\u{b2}',
            '3' => '\u{b3}',
            d => char::from_u32(0x2070 + d.to_digit(10).unwrap_or(0)).unwrap_or(d),
        })
        .collect()
}

/// `m x 10^k` printed exactly, either as a plain decimal or with a power of ten.
fn log_label(m: u32, k: i32, plain: bool) -> String {
    if plain {
        let digits = m.to_string();
        if k >= 0 {
            format!("{digits}{}", "0".repeat(k as usize))
        } else {
            let zeros = (-k - 1) as usize;
            format!("0.{}{digits}", "0".repeat(zeros))
        }
    } else if m == 1 {
        format!("10{}", superscript(k))
    } else {
        format!("{m}\u{d7}10{}", superscript(k))
    }
}

/// Plain decimals read best for values an engineer writes out (0.001 .. 10000); outside that
/// range powers of ten are shorter.
fn plain_range(ks: impl IntoIterator<Item = i32>) -> bool {
    ks.into_iter().all(|k| (-3..=4).contains(&k))
}

/// Ticks on a log10 axis spanning plot-space `lo..hi` (base-10 exponents).
pub(crate) fn log_ticks(lo: f64, hi: f64, fits: Fits<'_>) -> Ticks {
    if !(lo.is_finite() && hi.is_finite() && hi > lo) {
        return Ticks::default();
    }
    let k_lo = lo.floor() as i32;
    let k_hi = hi.ceil() as i32;
    let inside = |p: f64| p >= lo - 1e-9 && p <= hi + 1e-9;
    let decades: Vec<i32> = (k_lo..=k_hi).filter(|&k| inside(f64::from(k))).collect();

    if decades.len() >= 3 {
        let plain = plain_range(decades.iter().copied());
        for stride in [1, 2, 3, 5, 10, 20, 50, 100] {
            let ks: Vec<i32> = decades
                .iter()
                .copied()
                .filter(|k| k.rem_euclid(stride) == 0)
                .collect();
            if ks.len() < 2 && stride > 1 {
                break;
            }
            let major: Vec<f64> = ks.iter().map(|&k| f64::from(k)).collect();
            let labels: Vec<String> = ks.iter().map(|&k| log_label(1, k, plain)).collect();
            if fits(&major, &labels) || stride == 100 {
                let minor = if stride == 1 && decades.len() <= 12 {
                    mantissa_points(k_lo, k_hi, &[2, 3, 4, 5, 6, 7, 8, 9], &inside)
                        .into_iter()
                        .map(|(p, _, _)| p)
                        .collect()
                } else {
                    decades
                        .iter()
                        .filter(|k| k.rem_euclid(stride) != 0)
                        .map(|&k| f64::from(k))
                        .collect()
                };
                return Ticks {
                    major,
                    labels,
                    minor,
                };
            }
        }
        // Even every 100th decade crowds: label the ends only.
        let major = vec![f64::from(decades[0]), f64::from(decades[decades.len() - 1])];
        let labels = vec![
            log_label(1, decades[0], false),
            log_label(1, decades[decades.len() - 1], false),
        ];
        return Ticks {
            major,
            labels,
            minor: Vec::new(),
        };
    }

    for set in [&[1u32, 2, 5][..], &[1, 2, 3, 4, 5, 6, 7, 8, 9][..]] {
        let pts = mantissa_points(k_lo, k_hi, set, &inside);
        if pts.len() < 3 {
            continue;
        }
        let plain = plain_range(pts.iter().map(|&(_, _, k)| k));
        let major: Vec<f64> = pts.iter().map(|&(p, _, _)| p).collect();
        let labels: Vec<String> = pts
            .iter()
            .map(|&(_, m, k)| log_label(m, k, plain))
            .collect();
        if fits(&major, &labels) {
            let minor = mantissa_points(k_lo, k_hi, &[1, 2, 3, 4, 5, 6, 7, 8, 9], &inside)
                .into_iter()
                .filter(|&(_, m, _)| !set.contains(&m))
                .map(|(p, _, _)| p)
                .collect();
            return Ticks {
                major,
                labels,
                minor,
            };
        }
    }

    // Less than about a factor of three: nice linear ticks in value space read best.
    let (vlo, vhi) = (10f64.powf(lo), 10f64.powf(hi));
    let fits_value = |vals: &[f64], labels: &[String]| {
        let pos: Vec<f64> = vals.iter().map(|v| v.log10()).collect();
        fits(&pos, labels)
    };
    let lin = linear_ticks(vlo, vhi, &fits_value);
    let keep: Vec<usize> = (0..lin.major.len())
        .filter(|&i| lin.major[i] > 0.0)
        .collect();
    Ticks {
        major: keep.iter().map(|&i| lin.major[i].log10()).collect(),
        labels: keep.iter().map(|&i| lin.labels[i].clone()).collect(),
        minor: Vec::new(),
    }
}

/// Points `log10(m * 10^k)` inside the axis, in increasing order, with their `m` and `k`.
fn mantissa_points(
    k_lo: i32,
    k_hi: i32,
    set: &[u32],
    inside: &dyn Fn(f64) -> bool,
) -> Vec<(f64, u32, i32)> {
    let mut out = Vec::new();
    for k in k_lo..=k_hi {
        for &m in set {
            let p = f64::from(m).log10() + f64::from(k);
            if inside(p) {
                out.push((p, m, k));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    fn always(_: &[f64], _: &[String]) -> bool {
        true
    }

    /// Accepts at most `n` labels, standing in for an axis of limited length.
    fn at_most(n: usize) -> impl Fn(&[f64], &[String]) -> bool {
        move |p: &[f64], _: &[String]| p.len() <= n
    }

    #[test]
    fn linear_ticks_are_nice_multiples_inside_the_range() {
        let t = linear_ticks(-0.3, 10.2, &at_most(6));
        // 0, 2, ..., 10: step 2 is the densest nice step giving at most 6 labels.
        assert_eq!(t.labels, ["0", "2", "4", "6", "8", "10"]);
        for (m, want) in t.major.iter().zip([0.0, 2.0, 4.0, 6.0, 8.0, 10.0]) {
            // Ticks are k * step with integer k, so only rounding of one product remains.
            assert_abs_diff_eq!(*m, want, epsilon = 1e-12);
        }
    }

    #[test]
    fn linear_labels_use_enough_decimals_and_a_true_minus() {
        // Step 0.2 would need 7 labels; 0.25 needs two decimals.
        let t = linear_ticks(-0.6, 0.6, &at_most(5));
        assert_eq!(
            t.labels,
            ["\u{2212}0.50", "\u{2212}0.25", "0.00", "0.25", "0.50"]
        );
    }

    #[test]
    fn large_values_use_powers_of_ten() {
        let t = linear_ticks(0.0, 3e6, &at_most(4));
        assert_eq!(
            t.labels,
            [
                "0",
                "1\u{d7}10\u{2076}",
                "2\u{d7}10\u{2076}",
                "3\u{d7}10\u{2076}"
            ]
        );
    }

    #[test]
    fn crowded_axis_falls_back_to_fewer_ticks() {
        let t = linear_ticks(0.0, 1.0, &at_most(3));
        assert_eq!(t.labels, ["0.0", "0.5", "1.0"]);
    }

    #[test]
    fn log_axis_over_many_decades_labels_decades() {
        // 0.1 .. 1000 rad/s.
        let t = log_ticks(-1.0, 3.0, &always);
        assert_eq!(t.labels, ["0.1", "1", "10", "100", "1000"]);
        // Minor ticks at 2..9 times each decade: 8 per decade over 4 decades.
        assert_eq!(t.minor.len(), 32);
        let t = log_ticks(-6.0, 2.0, &at_most(5));
        assert_eq!(
            t.labels,
            [
                "10\u{207b}\u{2076}",
                "10\u{207b}\u{2074}",
                "10\u{207b}\u{b2}",
                "10\u{2070}",
                "10\u{b2}"
            ]
        );
    }

    #[test]
    fn short_log_axis_uses_one_two_five() {
        // 0.5 .. 20
        let t = log_ticks(0.5f64.log10(), 20f64.log10(), &always);
        assert_eq!(t.labels, ["0.5", "1", "2", "5", "10", "20"]);
    }

    #[test]
    fn very_short_log_axis_uses_linear_values() {
        let t = log_ticks(1.0, 1.2f64.log10() + 1.0, &at_most(3));
        assert_eq!(t.labels, ["10", "11", "12"]);
        assert_abs_diff_eq!(t.major[1], 11f64.log10(), epsilon = 1e-12);
    }

    #[test]
    fn angle_ticks_prefer_multiples_of_45_degrees() {
        let t = angle_ticks(-190.0, 10.0, &at_most(6));
        assert_eq!(
            t.labels,
            [
                "\u{2212}180",
                "\u{2212}135",
                "\u{2212}90",
                "\u{2212}45",
                "0"
            ]
        );
        // A range narrower than two multiples of 15 degrees falls back to decimal steps.
        let t = angle_ticks(-3.0, 4.0, &at_most(8));
        assert_eq!(
            t.labels,
            [
                "\u{2212}3",
                "\u{2212}2",
                "\u{2212}1",
                "0",
                "1",
                "2",
                "3",
                "4"
            ]
        );
    }

    #[test]
    fn degenerate_ranges_give_no_ticks() {
        assert!(linear_ticks(1.0, 1.0, &always).major.is_empty());
        assert!(linear_ticks(f64::NAN, 1.0, &always).major.is_empty());
        assert!(log_ticks(2.0, 1.0, &always).major.is_empty());
    }

    #[test]
    fn label_lookup_matches_major_ticks() {
        let t = linear_ticks(0.0, 1.0, &at_most(3));
        assert_eq!(t.label_at(0.5), "0.5");
        assert_eq!(t.label_at(0.25), "");
        // Ticks 1e-301 apart stay distinct.
        let t = linear_ticks(0.0, 2e-300, &at_most(3));
        assert_eq!(
            t.labels,
            [
                "0",
                "1\u{d7}10\u{207b}\u{b3}\u{2070}\u{2070}",
                "2\u{d7}10\u{207b}\u{b3}\u{2070}\u{2070}"
            ]
        );
        assert_eq!(t.label_at(t.major[1]), t.labels[1]);
    }
}
