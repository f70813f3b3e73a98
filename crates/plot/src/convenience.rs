//! Ready-made panels and figures for frequency responses, time series and spectra.

use num_complex::Complex64;

use crate::figure::{Figure, Panel, Scale, Series, Style};

/// Axis label for angular frequency.
pub const FREQUENCY_LABEL: &str = "frequency (rad/s)";
/// Axis label for magnitude in decibels.
pub const MAGNITUDE_DB_LABEL: &str = "|G| (dB)";
/// Axis label for phase in degrees.
pub const PHASE_DEG_LABEL: &str = "phase (deg)";
/// Axis label for time.
pub const TIME_LABEL: &str = "time (s)";

/// Pixel size of one cell chosen by [`grid_figure`].
const CELL_WIDTH: u32 = 520;
const CELL_HEIGHT: u32 = 360;
/// Pixel size of one row chosen by [`stacked_figure`].
const STACK_WIDTH: u32 = 1000;
const STACK_HEIGHT: u32 = 280;
/// Extra height for a figure title.
const TITLE_HEIGHT: u32 = 40;

/// A frequency response on its own frequency grid, for [`magnitude_panel`], [`phase_panel`] and
/// [`bode_panels_each`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodeSeries<'a> {
    /// Legend text.
    pub label: &'a str,
    /// Angular frequencies in rad/s; values that are not positive are skipped on the log axis.
    pub omega: &'a [f64],
    /// Complex response at each frequency (same length as `omega`).
    pub response: &'a [Complex64],
    /// Drawing style.
    pub style: Style,
}

/// Magnitude (dB) and phase (degrees) panels of responses sharing one frequency grid.
///
/// Each item is `(label, response, style)` with `response[i]` taken at `omega[i]` (rad/s).
/// See [`bode_panels_each`] for the conventions.
pub fn bode_panels<L, R>(
    title: &str,
    omega: &[f64],
    series: impl IntoIterator<Item = (L, R, Style)>,
) -> [Panel; 2]
where
    L: AsRef<str>,
    R: AsRef<[Complex64]>,
{
    let owned: Vec<(L, R, Style)> = series.into_iter().collect();
    let borrowed: Vec<BodeSeries<'_>> = owned
        .iter()
        .map(|(l, r, s)| BodeSeries {
            label: l.as_ref(),
            omega,
            response: r.as_ref(),
            style: *s,
        })
        .collect();
    bode_panels_each(title, &borrowed)
}

/// Magnitude and phase panels, each series on its own frequency grid (a dense theory curve
/// beside sparse estimates, say).
///
/// Magnitude is `20 log10 |G|` in dB; phase is `arg G` in degrees, unwrapped along each series
/// (see [`phase_panel`]). Frequency is on a log10 axis labelled in rad/s. Zero or non-finite
/// responses are skipped. Panel titles are `"<title>: magnitude"` and `"<title>: phase"`.
pub fn bode_panels_each(title: &str, series: &[BodeSeries<'_>]) -> [Panel; 2] {
    let suffixed = |what: &str| {
        if title.is_empty() {
            what.to_string()
        } else {
            format!("{title}: {what}")
        }
    };
    [
        magnitude_panel(&suffixed("magnitude"), series),
        phase_panel(&suffixed("phase"), series),
    ]
}

/// One panel of `20 log10 |G|` (dB) against frequency (rad/s, log10 axis).
pub fn magnitude_panel(title: &str, series: &[BodeSeries<'_>]) -> Panel {
    let mut panel = Panel::new(title, FREQUENCY_LABEL, MAGNITUDE_DB_LABEL);
    panel.x_scale = Scale::Log10;
    panel.series = series
        .iter()
        .map(|s| {
            let db = s.response.iter().map(|g| 20.0 * g.norm().log10()).collect();
            Series::new(s.label, s.omega.to_vec(), db, s.style)
        })
        .collect();
    panel
}

/// One panel of the phase `arg G` in degrees against frequency (rad/s, log10 axis).
///
/// Each series is unwrapped in its stored order (jumps above 180 degrees between consecutive
/// finite points are removed), starting from the principal value in (-180, 180]. Every later
/// series is then shifted by a whole number of turns to agree with the first series at the
/// nearest frequency, so an estimate and its theory curve are drawn on the same branch.
pub fn phase_panel(title: &str, series: &[BodeSeries<'_>]) -> Panel {
    let mut panel = Panel::new(title, FREQUENCY_LABEL, PHASE_DEG_LABEL);
    panel.x_scale = Scale::Log10;
    panel.y_scale = Scale::Degrees;
    let mut phases: Vec<Vec<f64>> = series
        .iter()
        .map(|s| unwrap_phase_deg(s.response))
        .collect();
    if let Some((reference, rest)) = phases.split_first_mut() {
        for (s, ph) in series.iter().skip(1).zip(rest.iter_mut()) {
            align_branch(series[0].omega, reference, s.omega, ph);
        }
    }
    panel.series = series
        .iter()
        .zip(phases)
        .map(|(s, ph)| Series::new(s.label, s.omega.to_vec(), ph, s.style))
        .collect();
    panel
}

/// Phase in degrees, unwrapped along the slice; zero or non-finite values give NaN and do not
/// reset the unwrapping.
pub(crate) fn unwrap_phase_deg(response: &[Complex64]) -> Vec<f64> {
    let mut prev: Option<f64> = None;
    response
        .iter()
        .map(|g| {
            if !(g.re.is_finite() && g.im.is_finite()) || g.norm() == 0.0 {
                return f64::NAN;
            }
            let mut p = g.arg().to_degrees();
            if let Some(q) = prev {
                p += 360.0 * ((q - p) / 360.0).round();
            }
            prev = Some(p);
            p
        })
        .collect()
}

/// Shifts `phase` by whole turns so its first finite point matches `reference` at the nearest
/// frequency (distance measured in log frequency when both are positive).
fn align_branch(ref_omega: &[f64], reference: &[f64], omega: &[f64], phase: &mut [f64]) {
    let Some((w0, p0)) = omega
        .iter()
        .zip(phase.iter())
        .find(|(w, p)| w.is_finite() && p.is_finite())
        .map(|(w, p)| (*w, *p))
    else {
        return;
    };
    let distance = |w: f64| {
        if w > 0.0 && w0 > 0.0 {
            (w.ln() - w0.ln()).abs()
        } else {
            (w - w0).abs()
        }
    };
    let nearest = ref_omega
        .iter()
        .zip(reference)
        .filter(|(w, p)| w.is_finite() && p.is_finite())
        .map(|(w, p)| (distance(*w), *p))
        .min_by(|a, b| a.0.total_cmp(&b.0));
    if let Some((_, r)) = nearest {
        let turns = ((r - p0) / 360.0).round();
        for p in phase.iter_mut() {
            *p += 360.0 * turns;
        }
    }
}

/// Two-sided 95 % quantile of the standard normal distribution: confidence regions are
/// `estimate +- Z_95 stderr`.
pub const Z_95: f64 = 1.959_963_984_540_054;
/// An estimate with `|G| / stderr` below this is not significant (about 95 % two-sided for a
/// complex estimate whose parts each carry `stderr / sqrt(2)`).
pub const SIGNIFICANT_RATIO: f64 = 2.0;

/// Is `|g|` significant against its standard error (NaN standard errors count as significant:
/// nothing says otherwise)?
fn significant(g: Complex64, stderr: f64) -> bool {
    !(stderr.is_finite() && g.norm() < SIGNIFICANT_RATIO * stderr)
}

/// Adds the 95 % confidence region of series `index` of a [`magnitude_panel`], whose
/// response and standard errors (same length, same order) are given, as a shaded band in dB;
/// its points that are not significant (`|G| < 2 stderr`) are taken out of the series and
/// drawn as faded markers (left out altogether for a series drawn as a line, where the band
/// alone shows the noise floor, as its legend entry says). Where `|G| - 1.96 stderr <= 0` the band reaches the bottom of the
/// axes: the estimate cannot be told from zero there. New series' labels start with the
/// series' own label. Does nothing when `index` is out of range or the lengths differ.
pub fn add_magnitude_confidence(
    panel: &mut Panel,
    index: usize,
    response: &[Complex64],
    stderr: &[f64],
) {
    add_confidence(panel, index, response, stderr, true, |g, se| {
        let m = g.norm();
        let lo = m - Z_95 * se;
        (
            if lo > 0.0 {
                20.0 * lo.log10()
            } else {
                f64::NAN
            },
            20.0 * (m + Z_95 * se).log10(),
        )
    });
}

/// As [`add_magnitude_confidence`] for a [`phase_panel`]: the band is the phase +-
/// `asin(1.96 stderr / |G|)` degrees, drawn only where the estimate is significant.
pub fn add_phase_confidence(
    panel: &mut Panel,
    index: usize,
    response: &[Complex64],
    stderr: &[f64],
) {
    let phase = match panel.series.get(index) {
        Some(s) => s.y.clone(),
        None => return,
    };
    let mut i = 0usize;
    add_confidence(panel, index, response, stderr, false, move |g, se| {
        let p = phase.get(i).copied().unwrap_or(f64::NAN);
        i += 1;
        let half = (Z_95 * se / g.norm()).min(1.0).asin().to_degrees();
        (p - half, p + half)
    });
}

fn add_confidence(
    panel: &mut Panel,
    index: usize,
    response: &[Complex64],
    stderr: &[f64],
    keep_insignificant: bool,
    mut edges: impl FnMut(Complex64, f64) -> (f64, f64),
) {
    let Some(series) = panel.series.get(index) else {
        return;
    };
    if response.len() != series.x.len() || stderr.len() != series.x.len() {
        return;
    }
    let label = series.label.clone();
    let x = series.x.clone();
    let mut y = series.y.clone();
    let (mut lo, mut hi) = (Vec::with_capacity(x.len()), Vec::with_capacity(x.len()));
    let (mut fx, mut fy) = (Vec::new(), Vec::new());
    for i in 0..x.len() {
        let (a, b) = edges(response[i], stderr[i]);
        if significant(response[i], stderr[i]) {
            lo.push(a);
            hi.push(b);
        } else {
            fx.push(x[i]);
            fy.push(y[i]);
            y[i] = f64::NAN;
            // The band is kept on the magnitude, where it shows the noise floor; on the
            // phase an insignificant estimate has no confidence region worth drawing.
            lo.push(a);
            hi.push(if keep_insignificant { b } else { f64::NAN });
        }
    }
    let role = series.role;
    // A dense estimate drawn as a line would bury the band under hundreds of faded markers:
    // its insignificant bins are left out, and the band alone shows the noise floor there.
    let omit = matches!(series.style, Style::Line | Style::Dashed);
    let band_label = if omit && !fx.is_empty() {
        format!("{label}: 95 % confidence; |G| < 2 stderr not drawn")
    } else {
        format!("{label}: 95 % confidence")
    };
    if omit {
        fx.clear();
        fy.clear();
    }
    // A significant bin between two left-out ones would vanish from a line: mark it.
    let isolated: Vec<usize> = if omit {
        (0..y.len())
            .filter(|&i| {
                y[i].is_finite()
                    && (i == 0 || y[i - 1].is_nan())
                    && (i + 1 == y.len() || y[i + 1].is_nan())
            })
            .collect()
    } else {
        Vec::new()
    };
    let mut lone = Series::new(
        "",
        isolated.iter().map(|&i| x[i]).collect(),
        isolated.iter().map(|&i| y[i]).collect(),
        Style::Markers,
    );
    lone.role = role;
    let mut band = Series::band(band_label, x, lo, hi);
    band.role = role;
    let mut faded = Series::new(
        format!("{label}: not significant (|G| < 2 stderr)"),
        fx,
        fy,
        Style::FadedMarkers,
    );
    faded.role = role;
    panel.series[index].y = y;
    panel.series.push(band);
    if !faded.x.is_empty() {
        panel.series.push(faded);
    }
    if !lone.x.is_empty() {
        panel.series.push(lone);
    }
}

/// A figure of `panels` in `columns` columns, sized 520 x 360 px per cell plus room for the
/// title. Suits a grid of harmonics `G_k` (one panel per `k`).
///
/// A `columns` of 0 is kept so that [`save`](crate::save) reports it.
pub fn grid_figure(title: impl Into<String>, panels: Vec<Panel>, columns: usize) -> Figure {
    let title = title.into();
    let cols = columns.clamp(1, panels.len().max(1));
    let rows = panels.len().div_ceil(cols).max(1);
    let title_h = if title.is_empty() { 0 } else { TITLE_HEIGHT };
    Figure {
        width: pixels(cols, CELL_WIDTH),
        height: pixels(rows, CELL_HEIGHT).saturating_add(title_h),
        title,
        panels,
        columns,
    }
}

/// Panels stacked in one column, 1000 px wide and 280 px per panel, for time series and spectra.
pub fn stacked_figure(title: impl Into<String>, panels: Vec<Panel>) -> Figure {
    let title = title.into();
    let title_h = if title.is_empty() { 0 } else { TITLE_HEIGHT };
    Figure {
        width: STACK_WIDTH,
        height: pixels(panels.len().max(1), STACK_HEIGHT).saturating_add(title_h),
        title,
        panels,
        columns: 1,
    }
}

fn pixels(count: usize, cell: u32) -> u32 {
    u32::try_from(count)
        .unwrap_or(u32::MAX)
        .saturating_mul(cell)
}

/// Signals sampled at common times `t` (s) as solid lines on linear axes.
///
/// Each item is `(label, values)` with `values[i]` taken at `t[i]`.
pub fn time_panel<L, V>(
    title: &str,
    y_label: &str,
    t: &[f64],
    series: impl IntoIterator<Item = (L, V)>,
) -> Panel
where
    L: AsRef<str>,
    V: AsRef<[f64]>,
{
    let mut panel = Panel::new(title, TIME_LABEL, y_label);
    panel.series = series
        .into_iter()
        .map(|(l, v)| Series::new(l.as_ref(), t.to_vec(), v.as_ref().to_vec(), Style::Line))
        .collect();
    panel
}

/// Vertical scale of a [`spectrum_panel`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SpectrumScale {
    /// Amplitude on a log10 axis.
    #[default]
    LogLog,
    /// Amplitude in decibels, `20 log10 |X|`, on a linear axis.
    Decibel,
}

/// Amplitude spectra `|X|` at common angular frequencies `omega` (rad/s, log10 axis) as solid
/// lines. Zero amplitudes and the zero frequency are skipped on the log axes; set
/// `panel.x_scale = Scale::Linear` afterwards for evenly spaced harmonics.
pub fn spectrum_panel<L, V>(
    title: &str,
    omega: &[f64],
    series: impl IntoIterator<Item = (L, V)>,
    scale: SpectrumScale,
) -> Panel
where
    L: AsRef<str>,
    V: AsRef<[f64]>,
{
    let y_label = match scale {
        SpectrumScale::LogLog => "amplitude",
        SpectrumScale::Decibel => "amplitude (dB)",
    };
    let mut panel = Panel::new(title, FREQUENCY_LABEL, y_label);
    panel.x_scale = Scale::Log10;
    if scale == SpectrumScale::LogLog {
        panel.y_scale = Scale::Log10;
    }
    panel.series = series
        .into_iter()
        .map(|(l, v)| {
            let y = match scale {
                SpectrumScale::LogLog => v.as_ref().iter().map(|a| a.abs()).collect(),
                SpectrumScale::Decibel => {
                    v.as_ref().iter().map(|a| 20.0 * a.abs().log10()).collect()
                }
            };
            Series::new(l.as_ref(), omega.to_vec(), y, Style::Line)
        })
        .collect();
    panel
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    #[test]
    fn unwrapping_follows_a_phase_ramp_through_many_turns() {
        // exp(-i w) for w in [0, 30] rad: the true phase is -w, i.e. about -1719 degrees at the end.
        let w: Vec<f64> = (0..=300).map(|i| 0.1 * f64::from(i)).collect();
        let g: Vec<Complex64> = w.iter().map(|&w| Complex64::from_polar(1.0, -w)).collect();
        let ph = unwrap_phase_deg(&g);
        for (p, w) in ph.iter().zip(&w) {
            // Only rounding in arg and to_degrees remains: 1e-9 deg is far below any branch error.
            assert_abs_diff_eq!(*p, -w.to_degrees(), epsilon = 1e-9);
        }
    }

    #[test]
    fn unwrapping_skips_zero_and_nan_without_resetting() {
        let g = [
            Complex64::from_polar(1.0, 3.0),
            Complex64::new(0.0, 0.0),
            Complex64::new(f64::NAN, 1.0),
            Complex64::from_polar(1.0, 3.3),
        ];
        let ph = unwrap_phase_deg(&g);
        assert!(ph[1].is_nan() && ph[2].is_nan());
        // 3.3 rad wraps to 3.3 - 2 pi; unwrapping against 3.0 rad restores 3.3 rad.
        assert_abs_diff_eq!(ph[3], 3.3_f64.to_degrees(), epsilon = 1e-9);
    }

    #[test]
    fn estimate_is_put_on_the_branch_of_the_theory() {
        // Theory: pure delay exp(-i w) on a dense grid, unwrapped from 0 to -1146 deg.
        let w_th: Vec<f64> = (1..=200).map(|i| 0.1 * f64::from(i)).collect();
        let g_th: Vec<Complex64> = w_th
            .iter()
            .map(|&w| Complex64::from_polar(1.0, -w))
            .collect();
        // Estimate starts at w = 15 rad/s, where the principal value differs by whole turns.
        let w_est = [15.0, 17.0, 19.0];
        let g_est: Vec<Complex64> = w_est
            .iter()
            .map(|&w| Complex64::from_polar(1.0, -w))
            .collect();
        let panel = phase_panel(
            "delay",
            &[
                BodeSeries {
                    label: "theory",
                    omega: &w_th,
                    response: &g_th,
                    style: Style::Line,
                },
                BodeSeries {
                    label: "estimate",
                    omega: &w_est,
                    response: &g_est,
                    style: Style::Markers,
                },
            ],
        );
        for (p, w) in panel.series[1].y.iter().zip(w_est) {
            assert_abs_diff_eq!(*p, -w.to_degrees(), epsilon = 1e-9);
        }
    }

    #[test]
    fn magnitude_is_twenty_log10_of_the_modulus() {
        let g = [Complex64::new(3.0, 4.0), Complex64::new(0.0, 0.0)];
        let [mag, phase] = bode_panels("G", &[1.0, 2.0], [("g", g, Style::Line)]);
        // |3 + 4i| = 5 exactly.
        assert_abs_diff_eq!(mag.series[0].y[0], 20.0 * 5f64.log10(), epsilon = 1e-12);
        assert!(mag.series[0].y[1].is_infinite());
        assert_eq!(mag.x_scale, Scale::Log10);
        assert_eq!(mag.y_label, MAGNITUDE_DB_LABEL);
        assert_eq!(phase.y_label, PHASE_DEG_LABEL);
        assert_eq!(phase.title, "G: phase");
    }

    #[test]
    fn confidence_band_and_faded_points_follow_significance() {
        // |G| = 1 everywhere; stderr 0.1 (significant), 0.6 (|G| < 2 se: faded, and
        // 1 - 1.96 * 0.6 < 0 so the band's lower edge is undrawable).
        let w = [1.0, 2.0];
        let g = [Complex64::new(1.0, 0.0); 2];
        let se = [0.1, 0.6];
        let mut mag = magnitude_panel(
            "",
            &[BodeSeries {
                label: "est",
                omega: &w,
                response: &g,
                style: Style::Markers,
            }],
        );
        add_magnitude_confidence(&mut mag, 0, &g, &se);
        assert_eq!(mag.series.len(), 3);
        assert!(mag.series[0].y[1].is_nan() && mag.series[0].y[0].is_finite());
        let band = &mag.series[1];
        assert_eq!(band.style, Style::Band);
        // 20 log10(1 -+ 1.96 * 0.1), exactly as defined.
        assert_abs_diff_eq!(
            band.y[0],
            20.0 * (1.0 - Z_95 * 0.1).log10(),
            epsilon = 1e-12
        );
        assert_abs_diff_eq!(
            band.upper[0],
            20.0 * (1.0 + Z_95 * 0.1).log10(),
            epsilon = 1e-12
        );
        assert!(band.y[1].is_nan() && band.upper[1].is_finite());
        assert_eq!(mag.series[2].style, Style::FadedMarkers);
        assert_eq!(mag.series[2].x, vec![2.0]);
        assert!(mag.series[2].label.starts_with("est"));

        let mut ph = phase_panel(
            "",
            &[BodeSeries {
                label: "est",
                omega: &w,
                response: &g,
                style: Style::Markers,
            }],
        );
        add_phase_confidence(&mut ph, 0, &g, &se);
        // asin(0.196) in degrees either side of 0; none for the insignificant point.
        let half = (Z_95 * 0.1f64).asin().to_degrees();
        assert_abs_diff_eq!(ph.series[1].upper[0], half, epsilon = 1e-12);
        assert!(ph.series[1].upper[1].is_nan());
    }

    #[test]
    fn grid_size_follows_rows_and_columns() {
        let panels = vec![Panel::default(); 7];
        let fig = grid_figure("harmonics", panels, 3);
        assert_eq!(
            (fig.width, fig.height),
            (3 * CELL_WIDTH, 3 * CELL_HEIGHT + TITLE_HEIGHT)
        );
    }
}
