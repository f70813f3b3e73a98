//! Panels for the evidence of a diagnosis: binned means with their bands, and a waterfall.

use crate::figure::{Panel, Role, Scale, Series, Style};

/// Half-width of the band around a bin mean in a [`binned_panel`], in standard errors of the
/// mean (about 95 % for a normal mean).
pub const BIN_BAND_STDERRS: f64 = 2.0;

/// Means of a quantity in bins of another, for [`binned_panel`]. The slices have one entry per
/// bin; a bin without a finite standard error is drawn without a band.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BinnedSeries<'a> {
    /// Legend text, also the start of the band's legend text.
    pub label: &'a str,
    /// Where each bin's mean is drawn (the mean of the binned variable over the bin).
    pub centre: &'a [f64],
    /// The bin means.
    pub mean: &'a [f64],
    /// Their standard errors.
    pub stderr: &'a [f64],
    /// Colour by meaning.
    pub role: Role,
}

/// Bin means as lines through markers, each with its band of `± 2` standard errors of the
/// mean ([`BIN_BAND_STDERRS`]; the legend says so), and zero as a grey reference line: a mean
/// whose band holds zero is noise. A series with an empty label stays out of the legend, band
/// included (for the second and later panels of a figure that share one legend).
pub fn binned_panel(
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[BinnedSeries<'_>],
) -> Panel {
    let mut panel = Panel::new(title, x_label, y_label);
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for s in series {
        let n = s.centre.len().min(s.mean.len()).min(s.stderr.len());
        let x = s.centre[..n].to_vec();
        for &c in &x {
            if c.is_finite() {
                lo = lo.min(c);
                hi = hi.max(c);
            }
        }
        let half = |i: usize| BIN_BAND_STDERRS * s.stderr[i];
        // A bin without a standard error (too few independent blocks) has no band; a series
        // with none at all has no band in the legend either.
        let banded = s.stderr[..n].iter().any(|e| e.is_finite());
        let band_label = if s.label.is_empty() || !banded {
            String::new()
        } else {
            format!("{}: ±2 standard errors of the bin mean", s.label)
        };
        let band = Series::band(
            band_label,
            x.clone(),
            (0..n).map(|i| s.mean[i] - half(i)).collect(),
            (0..n).map(|i| s.mean[i] + half(i)).collect(),
        )
        .with_role(s.role);
        panel.series.push(band);
        panel.series.push(
            Series::new(s.label, x, s.mean[..n].to_vec(), Style::LineMarkers).with_role(s.role),
        );
    }
    if lo < hi {
        panel.series.push(
            Series::new("", vec![lo, hi], vec![0.0, 0.0], Style::Dashed).with_role(Role::Bound),
        );
    }
    panel
}

/// One bar of a [`waterfall_panel`]: a level (`from` 0) or a step from one level to another.
#[derive(Debug, Clone, PartialEq)]
pub struct WaterfallBar {
    /// The bar's name under the axis.
    pub name: String,
    /// Where the bar starts.
    pub from: f64,
    /// Where it ends.
    pub to: f64,
    /// Colour by meaning.
    pub role: Role,
    /// Legend text; empty keeps the bar out of the legend.
    pub legend: String,
}

/// Levels spanning more than this ratio get a logarithmic axis (see [`waterfall_panel`]).
pub const WATERFALL_LOG_SPAN: f64 = 20.0;

/// Bars in order along the horizontal axis, named under it: a level reaches from the bottom of
/// the axis, a step floats between the level before and the level after, joined to the next
/// bar by a dashed grey line at its end value. `reference` (a value and its legend, e.g. the
/// noise floor) is drawn as a dashed line across. The vertical axis starts at zero, unless the
/// levels (and the reference) span more than [`WATERFALL_LOG_SPAN`]: then it is logarithmic,
/// from a decade boundary below the lowest, so that a step from 2e-2 to 2e-4 and the later
/// steps of a few percent there are all seen.
pub fn waterfall_panel(
    title: &str,
    y_label: &str,
    bars: &[WaterfallBar],
    reference: Option<(f64, String)>,
) -> Panel {
    const HALF: f64 = 0.32;
    let mut panel = Panel::new(title, "", y_label);
    let finite = |v: f64| v.is_finite().then_some(v);
    let values = bars
        .iter()
        .flat_map(|b| [finite(b.to), finite(b.from).filter(|&v| v != 0.0)])
        .chain([reference.as_ref().map(|r| r.0)])
        .flatten();
    let (low, top) = values.fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
        (if v > 0.0 { lo.min(v) } else { lo }, hi.max(v))
    });
    let log = low.is_finite() && top > WATERFALL_LOG_SPAN * low;
    // The axis's bottom, where a level starts: zero, or a decade boundary below the lowest.
    let bottom = if log {
        10f64.powf((low / 1.5).log10().floor())
    } else {
        0.0
    };
    for (i, b) in bars.iter().enumerate() {
        let x = i as f64;
        let from = if b.from == 0.0 { bottom } else { b.from };
        let (lo, hi) = (from.min(b.to), from.max(b.to));
        if !(lo.is_finite() && hi.is_finite()) {
            continue;
        }
        panel.series.push(
            Series::band(
                b.legend.clone(),
                vec![x - HALF, x + HALF],
                vec![lo, lo],
                vec![hi, hi],
            )
            .with_role(b.role),
        );
        panel.series.push(
            Series::new(
                "",
                vec![x - HALF, x - HALF, x + HALF, x + HALF, x - HALF],
                vec![lo, hi, hi, lo, lo],
                Style::Line,
            )
            .with_role(b.role),
        );
        if i + 1 < bars.len() {
            panel.series.push(
                Series::new(
                    "",
                    vec![x + HALF, x + 1.0 - HALF],
                    vec![b.to, b.to],
                    Style::Dashed,
                )
                .with_role(Role::Bound),
            );
        }
    }
    panel.x_ticks = bars
        .iter()
        .enumerate()
        .map(|(i, b)| (i as f64, b.name.clone()))
        .collect();
    let x_range = (-0.6, bars.len().max(1) as f64 - 0.4);
    panel.x_range = Some(x_range);
    if let Some((value, legend)) = reference {
        panel.series.push(
            Series::new(
                legend,
                vec![x_range.0, x_range.1],
                vec![value, value],
                Style::Dashed,
            )
            .with_role(Role::Bound),
        );
    }
    if log {
        panel.y_scale = Scale::Log10;
        panel.y_range = Some((bottom, 1.5 * top));
    } else if top > 0.0 {
        panel.y_range = Some((0.0, 1.1 * top));
    }
    panel
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_binned_panel_draws_each_mean_with_its_band_and_zero() {
        let p = binned_panel(
            "t",
            "position (m)",
            "residual (m/s^2)",
            &[BinnedSeries {
                label: "nominal",
                centre: &[0.0, 1.0, 2.0],
                mean: &[1.0, -1.0, 0.5],
                stderr: &[0.1, f64::NAN, 0.2],
                role: Role::Nominal,
            }],
        );
        assert_eq!(p.series.len(), 3);
        let band = &p.series[0];
        assert_eq!(band.style, Style::Band);
        assert!(band.label.contains("±2 standard errors"));
        assert!((band.y[0] - 0.8).abs() < 1e-12 && (band.upper[0] - 1.2).abs() < 1e-12);
        assert!(band.y[1].is_nan());
        assert_eq!(p.series[1].y, vec![1.0, -1.0, 0.5]);
        assert_eq!(p.series[2].role, Some(Role::Bound));
        assert_eq!(p.series[2].x, vec![0.0, 2.0]);
    }

    #[test]
    fn a_waterfall_names_its_bars_and_starts_at_zero() {
        let bar = |name: &str, from: f64, to: f64| WaterfallBar {
            name: name.into(),
            from,
            to,
            role: Role::Nominal,
            legend: String::new(),
        };
        let p = waterfall_panel(
            "held-out error",
            "RMSE (m)",
            &[
                bar("configured", 0.0, 5.0),
                bar("refitted", 5.0, 4.0),
                bar("final", 0.0, 4.0),
            ],
            None,
        );
        let names: Vec<&str> = p.x_ticks.iter().map(|t| t.1.as_str()).collect();
        assert_eq!(names, ["configured", "refitted", "final"]);
        assert_eq!(p.y_range, Some((0.0, 5.5)));
        // A band and an outline per bar, a connector between neighbours.
        assert_eq!(p.series.len(), 3 * 2 + 2);
        let step = &p.series[3];
        assert_eq!((step.y[0], step.upper[0]), (4.0, 5.0));
    }
}

#[cfg(test)]
mod log_tests {
    use super::*;

    /// Levels from 2e-2 to 2.5e-4 (and a floor of 6.5e-5) span more than 20: a logarithmic
    /// axis from the decade below the lowest value (1e-5, below 6.5e-5 / 1.5), the levels drawn
    /// from there, the steps between their levels, and the reference line across.
    #[test]
    fn a_waterfall_over_decades_has_a_log_axis_from_a_decade_below_the_lowest() {
        let bar = |from: f64, to: f64| WaterfallBar {
            name: "b".into(),
            from,
            to,
            role: Role::Extended,
            legend: String::new(),
        };
        let p = waterfall_panel(
            "t",
            "RMSE (V)",
            &[
                bar(0.0, 2e-2),
                bar(2e-2, 7e-3),
                bar(7e-3, 2.5e-4),
                bar(0.0, 2.5e-4),
            ],
            Some((6.5e-5, "noise floor".into())),
        );
        assert_eq!(p.y_scale, Scale::Log10);
        assert_eq!(p.y_range, Some((1e-5, 1.5 * 2e-2)));
        let first = &p.series[0];
        assert_eq!((first.y[0], first.upper[0]), (1e-5, 2e-2));
        let step = &p.series[6];
        assert_eq!((step.y[0], step.upper[0]), (2.5e-4, 7e-3));
        let floor = p.series.last().expect("the reference line");
        assert_eq!(floor.label, "noise floor");
        assert_eq!(floor.y, vec![6.5e-5, 6.5e-5]);
        // Within a decade the axis stays linear from zero.
        let p = waterfall_panel("t", "RMSE (V)", &[bar(0.0, 5.0), bar(5.0, 1.0)], None);
        assert_eq!(p.y_scale, Scale::Linear);
        assert_eq!(p.y_range, Some((0.0, 5.5)));
    }
}
