//! Panels for the evidence of a diagnosis: binned means with their bands, and a waterfall.

use crate::figure::{Panel, Role, Series, Style};

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
        let band_label = if s.label.is_empty() {
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

/// Bars in order along the horizontal axis, named under it: a level reaches from zero, a step
/// floats between the level before and the level after, joined to the next bar by a dashed
/// grey line at its end value. The vertical axis starts at zero.
pub fn waterfall_panel(title: &str, y_label: &str, bars: &[WaterfallBar]) -> Panel {
    const HALF: f64 = 0.32;
    let mut panel = Panel::new(title, "", y_label);
    let mut top = 0.0f64;
    for (i, b) in bars.iter().enumerate() {
        let x = i as f64;
        let (lo, hi) = (b.from.min(b.to), b.from.max(b.to));
        if !(lo.is_finite() && hi.is_finite()) {
            continue;
        }
        top = top.max(hi);
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
    panel.x_range = Some((-0.6, bars.len().max(1) as f64 - 0.4));
    if top > 0.0 {
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
