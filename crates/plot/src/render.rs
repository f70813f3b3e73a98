//! Validation, layout and drawing of a [`Figure`] on any plotters backend.

use std::path::Path;

use plotters::coord::ranged1d::{KeyPointHint, NoDefaultFormatting, ValueFormatter};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::error::PlotError;
use crate::figure::{Figure, Role, Scale, Style};
use crate::ticks::{angle_ticks, linear_ticks, log_ticks, Ticks};

/// Smallest and largest accepted image side in pixels. The upper bound keeps the RGB buffer of
/// the PNG renderer below 200 MB.
pub(crate) const MIN_SIDE: u32 = 64;
pub(crate) const MAX_SIDE: u32 = 8192;

/// Colour-blind-tolerant categorical palette (the "tab10" set of matplotlib), cycled by series
/// index.
const PALETTE: [RGBColor; 10] = [
    RGBColor(0x1f, 0x77, 0xb4),
    RGBColor(0xff, 0x7f, 0x0e),
    RGBColor(0x2c, 0xa0, 0x2c),
    RGBColor(0xd6, 0x27, 0x28),
    RGBColor(0x94, 0x67, 0xbd),
    RGBColor(0x8c, 0x56, 0x4b),
    RGBColor(0xe3, 0x77, 0xc2),
    RGBColor(0x7f, 0x7f, 0x7f),
    RGBColor(0xbc, 0xbd, 0x22),
    RGBColor(0x17, 0xbe, 0xcf),
];

/// The colour of each [`Role`], defined once for every figure.
pub(crate) fn role_colour(role: Role) -> RGBColor {
    match role {
        Role::Measured => RGBColor(0x26, 0x26, 0x26),
        Role::Nominal => PALETTE[0],
        Role::Extended => PALETTE[1],
        Role::Theory => PALETTE[2],
        Role::Estimate => PALETTE[3],
        Role::EstimateAlt => PALETTE[4],
        Role::EstimateAlt2 => PALETTE[5],
        Role::Bound => PALETTE[7],
        Role::Refitted => PALETTE[9],
    }
}

/// `colour` blended towards white, keeping `share` of it.
fn faded(colour: RGBColor, share: f64) -> RGBColor {
    let f = |c: u8| (f64::from(c) * share + 255.0 * (1.0 - share)).round() as u8;
    RGBColor(f(colour.0), f(colour.1), f(colour.2))
}

const TEXT: RGBColor = RGBColor(0x20, 0x20, 0x20);
const AXIS: RGBColor = RGBColor(0x40, 0x40, 0x40);
const GRID_MAJOR: RGBColor = RGBColor(0xdc, 0xdc, 0xdc);
const GRID_MINOR: RGBColor = RGBColor(0xf0, 0xf0, 0xf0);
const LEGEND_BORDER: RGBColor = RGBColor(0xb4, 0xb4, 0xb4);

const FONT: &str = "sans-serif";
const FIGURE_TITLE_PX: f64 = 21.0;
const PANEL_TITLE_PX: f64 = 16.0;
const AXIS_DESC_PX: f64 = 14.0;
const TICK_PX: f64 = 13.0;
const LEGEND_PX: f64 = 13.0;

const LINE_WIDTH: u32 = 2;
/// Opacity of a confidence band: light enough that lines and markers read through it.
const BAND_ALPHA: f64 = 0.18;
const MARKER_RADIUS: i32 = 4;
const TICK_LEN: i32 = 5;
/// plotters puts tick labels this far from the axis line.
const LABEL_DIST: u32 = 2 * TICK_LEN as u32;

/// One axis after validation, in plot space (log10 of the value on a logarithmic axis).
#[derive(Debug, Clone, Copy)]
pub(crate) struct AxisRange {
    pub scale: Scale,
    pub lo: f64,
    pub hi: f64,
}

/// A series converted to plot space; `NaN` marks a skipped point (a gap).
#[derive(Debug, Clone)]
pub(crate) struct PlotSeries {
    pub label: String,
    pub style: Style,
    pub color: RGBColor,
    pub points: Vec<(f64, f64)>,
    /// Upper edge of a band, in plot space (NaN where not drawable).
    pub upper: Vec<f64>,
}

#[derive(Debug, Clone)]
pub(crate) struct PlotPanel {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub x: AxisRange,
    pub y: AxisRange,
    pub series: Vec<PlotSeries>,
    /// Named ticks in plot space replacing the automatic ones when not empty.
    pub x_named: Vec<(f64, String)>,
}

/// Largest magnitude drawn on a linear axis; beyond it spans and paddings could overflow.
pub(crate) const MAX_MAGNITUDE: f64 = 1e300;

fn to_plot(v: f64, scale: Scale) -> f64 {
    match scale {
        Scale::Linear | Scale::Degrees if v.abs() <= MAX_MAGNITUDE => v,
        Scale::Log10 if v.is_finite() && v > 0.0 => v.log10(),
        _ => f64::NAN,
    }
}

/// Checks the figure and converts every series to plot space with resolved axis ranges.
pub(crate) fn prepare(fig: &Figure, path: &Path) -> Result<Vec<PlotPanel>, PlotError> {
    if fig.panels.is_empty() {
        return Err(PlotError::EmptyFigure {
            path: path.to_path_buf(),
        });
    }
    if fig.columns == 0 {
        return Err(PlotError::NoColumns {
            path: path.to_path_buf(),
        });
    }
    let side_ok = |s: u32| (MIN_SIDE..=MAX_SIDE).contains(&s);
    if !side_ok(fig.width) || !side_ok(fig.height) {
        return Err(PlotError::InvalidSize {
            path: path.to_path_buf(),
            width: fig.width,
            height: fig.height,
            min: MIN_SIDE,
            max: MAX_SIDE,
        });
    }
    let mut out = Vec::with_capacity(fig.panels.len());
    for (ip, panel) in fig.panels.iter().enumerate() {
        let range_err = |axis: &'static str, (lo, hi): (f64, f64), reason: &'static str| {
            PlotError::InvalidRange {
                path: path.to_path_buf(),
                panel: ip,
                title: panel.title.clone(),
                axis,
                lo,
                hi,
                reason,
            }
        };
        let explicit = |axis: &'static str, r: Option<(f64, f64)>, scale: Scale| {
            r.map(|(lo, hi)| {
                if !(lo.abs() <= MAX_MAGNITUDE && hi.abs() <= MAX_MAGNITUDE) {
                    Err(range_err(
                        axis,
                        (lo, hi),
                        "bounds must be finite and at most 1e300 in magnitude",
                    ))
                } else if lo >= hi {
                    Err(range_err(
                        axis,
                        (lo, hi),
                        "lower bound must be below upper bound",
                    ))
                } else if scale == Scale::Log10 && lo <= 0.0 {
                    Err(range_err(
                        axis,
                        (lo, hi),
                        "a logarithmic axis needs positive bounds",
                    ))
                } else {
                    Ok((to_plot(lo, scale), to_plot(hi, scale)))
                }
            })
            .transpose()
        };
        let x_fixed = explicit("x", panel.x_range, panel.x_scale)?;
        let y_fixed = explicit("y", panel.y_range, panel.y_scale)?;

        let mut series = Vec::with_capacity(panel.series.len());
        for (is, s) in panel.series.iter().enumerate() {
            if s.x.len() != s.y.len() || (s.style == Style::Band && s.upper.len() != s.x.len()) {
                return Err(PlotError::LengthMismatch {
                    path: path.to_path_buf(),
                    panel: ip,
                    title: panel.title.clone(),
                    series: s.label.clone(),
                    x_len: s.x.len(),
                    y_len: if s.x.len() == s.y.len() {
                        s.upper.len()
                    } else {
                        s.y.len()
                    },
                });
            }
            // A band's lower edge may be undrawable (a magnitude bound below zero on a dB or
            // log axis) while its upper edge is: keep the x of such points.
            let band = s.style == Style::Band;
            let points =
                s.x.iter()
                    .zip(&s.y)
                    .map(|(&x, &y)| {
                        let (px, py) = (to_plot(x, panel.x_scale), to_plot(y, panel.y_scale));
                        if band && !px.is_nan() {
                            (px, py)
                        } else if px.is_nan() || py.is_nan() {
                            (f64::NAN, f64::NAN)
                        } else {
                            (px, py)
                        }
                    })
                    .collect();
            let upper = if band {
                s.upper.iter().map(|&v| to_plot(v, panel.y_scale)).collect()
            } else {
                Vec::new()
            };
            series.push(PlotSeries {
                label: s.label.clone(),
                style: s.style,
                color: s.role.map_or(PALETTE[is % PALETTE.len()], role_colour),
                points,
                upper,
            });
        }

        let has_markers = series.iter().any(|s| s.style.has_markers());
        let x = match x_fixed {
            Some((lo, hi)) => (lo, hi),
            None => {
                let (lo, hi) =
                    data_extent(series.iter().flat_map(|s| s.points.iter().map(|p| p.0)));
                // Markers at the very edge would be cut in half.
                let pad = if has_markers { 0.03 } else { 0.0 };
                pad_extent(lo, hi, pad, panel.x_scale)
            }
        };
        let y = match y_fixed {
            Some((lo, hi)) => (lo, hi),
            None => {
                // Fit only what is visible horizontally.
                let (lo, hi) = data_extent(series.iter().flat_map(|s| {
                    let upper = s
                        .points
                        .iter()
                        .zip(&s.upper)
                        .filter(|(p, _)| p.0 >= x.0 && p.0 <= x.1)
                        .map(|(_, u)| *u);
                    s.points
                        .iter()
                        .filter(|p| p.0 >= x.0 && p.0 <= x.1)
                        .map(|p| p.1)
                        .chain(upper)
                }));
                pad_extent(lo, hi, 0.05, panel.y_scale)
            }
        };
        out.push(PlotPanel {
            title: panel.title.clone(),
            x_label: panel.x_label.clone(),
            y_label: panel.y_label.clone(),
            x: AxisRange {
                scale: panel.x_scale,
                lo: x.0,
                hi: x.1,
            },
            y: AxisRange {
                scale: panel.y_scale,
                lo: y.0,
                hi: y.1,
            },
            series,
            x_named: panel
                .x_ticks
                .iter()
                .map(|(v, l)| (to_plot(*v, panel.x_scale), l.clone()))
                .filter(|(v, _)| v.is_finite())
                .collect(),
        });
    }
    Ok(out)
}

fn data_extent(values: impl Iterator<Item = f64>) -> (f64, f64) {
    values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        })
}

/// Widens a data extent by `pad` of its span; an empty or single-valued extent gets a unit
/// (or one-decade) span so the axes stay drawable.
fn pad_extent(lo: f64, hi: f64, pad: f64, scale: Scale) -> (f64, f64) {
    if !(lo.is_finite() && hi.is_finite()) {
        return (0.0, 1.0);
    }
    let span = hi - lo;
    if span <= 1e-12 * lo.abs().max(hi.abs()) || span <= f64::MIN_POSITIVE {
        let half = match scale {
            Scale::Log10 => 0.5,
            Scale::Linear | Scale::Degrees => (0.1 * lo.abs()).max(0.5),
        };
        return (lo - half, hi + half);
    }
    (lo - pad * span, hi + pad * span)
}

fn font(px: f64) -> FontDesc<'static> {
    (FONT, px).into_font()
}

fn text_size(f: &FontDesc<'_>, text: &str) -> (u32, u32) {
    f.box_size(text).unwrap_or((0, 0))
}

type DrawResult<DB> = Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

/// Draws the whole figure on `root`; `raster` selects line drawing suited to bitmaps.
pub(crate) fn draw_figure<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    fig: &Figure,
    panels: &[PlotPanel],
    raster: bool,
) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let body = if fig.title.is_empty() {
        root.clone()
    } else {
        root.margin(8, 0, 0, 0)
            .titled(&fig.title, font(FIGURE_TITLE_PX).color(&TEXT))?
    };
    let cols = fig.columns.min(panels.len()).max(1);
    let rows = panels.len().div_ceil(cols);
    let cells = body.split_evenly((rows, cols));
    for (cell, panel) in cells.iter().zip(panels) {
        draw_panel(cell, panel, raster)?;
    }
    Ok(())
}

fn draw_panel<DB: DrawingBackend>(
    cell: &DrawingArea<DB, Shift>,
    p: &PlotPanel,
    raster: bool,
) -> DrawResult<DB> {
    let cell = cell.margin(10, 8, 8, 22);
    let area = if p.title.is_empty() {
        cell
    } else {
        cell.titled(&p.title, font(PANEL_TITLE_PX).color(&TEXT))?
    };
    let (w, h) = area.dim_in_pixel();

    let tick_font = font(TICK_PX);
    let desc_font = font(AXIS_DESC_PX);
    let tick_h = text_size(&tick_font, "0123456789").1;
    let desc_h = text_size(&desc_font, "Ag(|").1;

    // Room above the plot so the topmost y label is not cut.
    let top_pad = tick_h / 2 + 2;
    let x_area_h = LABEL_DIST + tick_h + if p.x_label.is_empty() { 4 } else { 10 + desc_h };
    let plot_h = h.saturating_sub(top_pad + x_area_h).max(10);

    let y_span_px = f64::from(plot_h) / (p.y.hi - p.y.lo);
    let min_y_gap = (2.4 * f64::from(tick_h)).max(30.0);
    let fits_y = |pos: &[f64], _: &[String]| {
        pos.windows(2)
            .all(|w| (w[1] - w[0]).abs() * y_span_px >= min_y_gap)
    };
    let y_ticks = axis_ticks(&p.y, &fits_y);
    let y_label_w = y_ticks
        .labels
        .iter()
        .map(|l| text_size(&tick_font, l).0)
        .max()
        .unwrap_or(0);
    let y_area_w = LABEL_DIST + y_label_w + if p.y_label.is_empty() { 4 } else { 12 + desc_h };
    let plot_w = w.saturating_sub(y_area_w).max(10);

    let x_span_px = f64::from(plot_w) / (p.x.hi - p.x.lo);
    let fits_x = |pos: &[f64], labels: &[String]| {
        let widths: Vec<f64> = labels
            .iter()
            .map(|l| f64::from(text_size(&tick_font, l).0))
            .collect();
        pos.windows(2).zip(widths.windows(2)).all(|(pp, ww)| {
            let gap = (pp[1] - pp[0]).abs() * x_span_px;
            gap >= 0.5 * (ww[0] + ww[1]) + 18.0 && gap >= 45.0
        })
    };
    let x_ticks = if p.x_named.is_empty() {
        axis_ticks(&p.x, &fits_x)
    } else {
        Ticks {
            major: p.x_named.iter().map(|t| t.0).collect(),
            labels: p.x_named.iter().map(|t| t.1.clone()).collect(),
            minor: Vec::new(),
        }
    };

    let mut chart = ChartBuilder::on(&area)
        .margin_top(top_pad)
        .x_label_area_size(x_area_h)
        .y_label_area_size(y_area_w)
        .build_cartesian_2d(
            TickedAxis::new(&p.x, x_ticks),
            TickedAxis::new(&p.y, y_ticks),
        )?;

    chart
        .configure_mesh()
        .x_desc(p.x_label.as_str())
        .y_desc(p.y_label.as_str())
        .label_style(tick_font.color(&TEXT))
        .axis_desc_style(desc_font.color(&TEXT))
        .bold_line_style(GRID_MAJOR.stroke_width(1))
        .light_line_style(GRID_MINOR.stroke_width(1))
        .axis_style(AXIS.stroke_width(1))
        .set_all_tick_mark_size(TICK_LEN)
        .draw()?;

    let pieces: Vec<Vec<Vec<(f64, f64)>>> = p
        .series
        .iter()
        .map(|s| {
            if s.style.has_line() {
                line_pieces(&s.points, &p.x, &p.y)
            } else {
                Vec::new()
            }
        })
        .collect();
    let markers: Vec<Vec<(f64, f64)>> = p
        .series
        .iter()
        .map(|s| {
            if s.style.has_markers() {
                visible_markers(&s.points, &p.x, &p.y)
            } else {
                Vec::new()
            }
        })
        .collect();

    let plot = chart.plotting_area().strip_coord_spec();
    let (pw, ph) = plot.dim_in_pixel();
    // The same affine map plotters applies to the mesh (pixel centres 0 ..= size - 1), kept in
    // floating point so lines can be simplified before rounding.
    let (sx, sy) = (
        f64::from(pw.saturating_sub(1)) / (p.x.hi - p.x.lo),
        f64::from(ph.saturating_sub(1)) / (p.y.hi - p.y.lo),
    );
    let y_bottom = f64::from(ph.saturating_sub(1));
    let to_fpx = |pt: &(f64, f64)| ((pt.0 - p.x.lo) * sx, y_bottom - (pt.1 - p.y.lo) * sy);
    let round = |pt: (f64, f64)| (pt.0.round() as i32, pt.1.round() as i32);
    let px_lines: Vec<Vec<Vec<(i32, i32)>>> = pieces
        .iter()
        .map(|lines| {
            lines
                .iter()
                .map(|l| {
                    let fpx = thin(l.iter().map(to_fpx).collect(), pw as usize);
                    dedup(simplify(&fpx, SIMPLIFY_PX).into_iter().map(round))
                })
                .collect()
        })
        .collect();
    // Markers landing on the same pixel add nothing but file size.
    let px_markers: Vec<Vec<(i32, i32)>> = markers
        .iter()
        .map(|pts| dedup(pts.iter().map(|pt| round(to_fpx(pt)))))
        .collect();

    // Bands under everything else, each contiguous drawable stretch one polygon.
    for s in p.series.iter().filter(|s| s.style == Style::Band) {
        let fill = s.color.mix(BAND_ALPHA).filled();
        for poly in band_polygons(s, &p.x, &p.y) {
            let px: Vec<(i32, i32)> = poly.iter().map(|pt| round(to_fpx(pt))).collect();
            plot.draw(&Polygon::new(px, fill))?;
        }
    }
    // Stems from zero (or the nearest horizontal edge) to each visible value.
    let zero = 0.0f64.clamp(p.y.lo, p.y.hi);
    for (s, pts) in p.series.iter().zip(&markers) {
        if s.style != Style::Stems {
            continue;
        }
        for pt in pts {
            let a = round(to_fpx(&(pt.0, zero)));
            let b = round(to_fpx(pt));
            stroke(&plot, &[a, b], s.color, raster)?;
        }
    }
    for (s, lines) in p.series.iter().zip(&px_lines) {
        for line in lines {
            if s.style == Style::Dashed {
                for dash in dashes(line) {
                    stroke(&plot, &dash, s.color, raster)?;
                }
            } else {
                stroke(&plot, line, s.color, raster)?;
            }
        }
    }
    for (s, pts) in p.series.iter().zip(&px_markers) {
        for &pt in pts {
            draw_marker(&plot, pt, s)?;
        }
    }

    let (pw, ph) = (pw as i32, ph as i32);
    // Close the frame: plotters draws only the left and bottom axes.
    plot.draw(&PathElement::new(
        vec![(0, 0), (pw - 1, 0), (pw - 1, ph - 1)],
        AXIS.stroke_width(1),
    ))?;

    draw_legend(&plot, &p.series, &px_lines, &px_markers, raster)
}

/// One marker in the style of its series.
fn draw_marker<DB: DrawingBackend>(
    plot: &DrawingArea<DB, Shift>,
    pt: (i32, i32),
    s: &PlotSeries,
) -> DrawResult<DB> {
    match s.style {
        Style::FadedMarkers => {
            plot.draw(&Circle::new(
                pt,
                MARKER_RADIUS - 1,
                faded(s.color, 0.45).stroke_width(1),
            ))?;
        }
        Style::Stems => {
            plot.draw(&Circle::new(pt, MARKER_RADIUS - 1, s.color.filled()))?;
        }
        _ => {
            plot.draw(&Circle::new(
                pt,
                MARKER_RADIUS,
                s.color.stroke_width(LINE_WIDTH),
            ))?;
        }
    }
    Ok(())
}

/// The polygons of a band in plot space: upper edge forward, lower edge back, over each run of
/// points whose x and upper edge are drawable, clipped to the axes vertically. An undrawable
/// lower edge reaches the bottom of the axes.
fn band_polygons(s: &PlotSeries, x: &AxisRange, y: &AxisRange) -> Vec<Vec<(f64, f64)>> {
    let mut out = Vec::new();
    let mut run: Vec<(f64, f64, f64)> = Vec::new();
    let flush = |run: &mut Vec<(f64, f64, f64)>, out: &mut Vec<Vec<(f64, f64)>>| {
        if run.len() >= 2 {
            let mut poly: Vec<(f64, f64)> = run.iter().map(|r| (r.0, r.2)).collect();
            poly.extend(run.iter().rev().map(|r| (r.0, r.1)));
            out.push(poly);
        }
        run.clear();
    };
    for (pt, &up) in s.points.iter().zip(&s.upper) {
        let inside = pt.0.is_finite() && pt.0 >= x.lo && pt.0 <= x.hi && up.is_finite();
        if !inside {
            flush(&mut run, &mut out);
            continue;
        }
        let lo = if pt.1.is_finite() { pt.1 } else { y.lo };
        let (lo, hi) = (lo.min(up), lo.max(up));
        run.push((pt.0, lo.clamp(y.lo, y.hi), hi.clamp(y.lo, y.hi)));
    }
    flush(&mut run, &mut out);
    out
}

fn dedup(points: impl Iterator<Item = (i32, i32)>) -> Vec<(i32, i32)> {
    let mut out: Vec<(i32, i32)> = Vec::new();
    for p in points {
        if out.last() != Some(&p) {
            out.push(p);
        }
    }
    out
}

/// Dash length and gap in pixels.
const DASH: (f64, f64) = (9.0, 5.0);

/// Splits a pixel polyline into dashes whose pattern runs on across vertices.
fn dashes(line: &[(i32, i32)]) -> Vec<Vec<(i32, i32)>> {
    let mut out = Vec::new();
    let mut cur: Vec<(i32, i32)> = Vec::new();
    let mut on = true;
    let mut left = DASH.0;
    let round = |x: f64, y: f64| (x.round() as i32, y.round() as i32);
    for w in line.windows(2) {
        let (a, b) = (w[0], w[1]);
        let (ax, ay) = (f64::from(a.0), f64::from(a.1));
        let (dx, dy) = (f64::from(b.0) - ax, f64::from(b.1) - ay);
        let len = dx.hypot(dy);
        let mut t = 0.0;
        if on && cur.is_empty() {
            cur.push(a);
        }
        while len - t > left {
            t += left;
            let p = round(ax + dx * t / len, ay + dy * t / len);
            if on {
                cur.push(p);
                out.push(std::mem::take(&mut cur));
                left = DASH.1;
            } else {
                cur.push(p);
                left = DASH.0;
            }
            on = !on;
        }
        left -= len - t;
        if on {
            cur.push(b);
        }
    }
    if on && cur.len() >= 2 {
        out.push(cur);
    }
    out
}

/// Draws a polyline two pixels wide. Raster output strokes three one-pixel anti-aliased copies
/// offset by a pixel, because plotters fills wide bitmap paths as one polygon whose integer
/// vertices fray on dense data.
fn stroke<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    line: &[(i32, i32)],
    color: RGBColor,
    raster: bool,
) -> DrawResult<DB> {
    if line.len() < 2 {
        return Ok(());
    }
    if raster {
        for (dx, dy) in [(0, 0), (1, 0), (0, 1)] {
            let shifted: Vec<(i32, i32)> = line.iter().map(|&(x, y)| (x + dx, y + dy)).collect();
            area.draw(&PathElement::new(shifted, color.stroke_width(1)))?;
        }
        Ok(())
    } else {
        area.draw(&PathElement::new(
            line.to_vec(),
            color.stroke_width(LINE_WIDTH),
        ))
    }
}

/// A linear plot-space axis whose grid lines and labels come from precomputed [`Ticks`].
struct TickedAxis {
    lo: f64,
    hi: f64,
    ticks: Ticks,
}

impl TickedAxis {
    fn new(axis: &AxisRange, ticks: Ticks) -> Self {
        Self {
            lo: axis.lo,
            hi: axis.hi,
            ticks,
        }
    }
}

impl Ranged for TickedAxis {
    type FormatOption = NoDefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        let frac = (value - self.lo) / (self.hi - self.lo);
        let px = f64::from(limit.0) + frac * f64::from(limit.1 - limit.0);
        // Values are clipped to the axis before drawing; the clamp only guards the cast.
        px.round()
            .clamp(f64::from(i32::MIN / 2), f64::from(i32::MAX / 2)) as i32
    }

    fn key_points<H: KeyPointHint>(&self, hint: H) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            self.ticks.minor.clone()
        } else {
            self.ticks.major.clone()
        }
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.lo..self.hi
    }
}

impl ValueFormatter<f64> for TickedAxis {
    fn format_ext(&self, value: &f64) -> String {
        self.ticks.label_at(*value)
    }
}

fn axis_ticks(axis: &AxisRange, fits: crate::ticks::Fits<'_>) -> Ticks {
    match axis.scale {
        Scale::Linear => linear_ticks(axis.lo, axis.hi, fits),
        Scale::Log10 => log_ticks(axis.lo, axis.hi, fits),
        Scale::Degrees => angle_ticks(axis.lo, axis.hi, fits),
    }
}

/// The visible part of a segment, and whether its start and end were moved by clipping.
#[derive(Debug, Clone, Copy)]
struct Clipped {
    start: (f64, f64),
    end: (f64, f64),
    start_moved: bool,
    end_moved: bool,
}

/// Clips the segment `a`-`b` to the rectangle (Liang-Barsky).
fn clip_segment(
    a: (f64, f64),
    b: (f64, f64),
    (x0, x1): (f64, f64),
    (y0, y1): (f64, f64),
) -> Option<Clipped> {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let mut t0 = 0.0_f64;
    let mut t1 = 1.0_f64;
    for (p, q) in [
        (-dx, a.0 - x0),
        (dx, x1 - a.0),
        (-dy, a.1 - y0),
        (dy, y1 - a.1),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
        }
    }
    if t0 > t1 {
        return None;
    }
    let at = |t: f64| (a.0 + t * dx, a.1 + t * dy);
    Some(Clipped {
        start: at(t0),
        end: at(t1),
        start_moved: t0 > 0.0,
        end_moved: t1 < 1.0,
    })
}

/// Splits a plot-space polyline at gaps (NaN) and at the axis box into visible pieces.
fn line_pieces(points: &[(f64, f64)], x: &AxisRange, y: &AxisRange) -> Vec<Vec<(f64, f64)>> {
    let mut pieces = Vec::new();
    let mut cur: Vec<(f64, f64)> = Vec::new();
    let mut open = false;
    let flush = |cur: &mut Vec<(f64, f64)>, pieces: &mut Vec<Vec<(f64, f64)>>| {
        if cur.len() >= 2 {
            pieces.push(std::mem::take(cur));
        } else {
            cur.clear();
        }
    };
    for w in points.windows(2) {
        let (a, b) = (w[0], w[1]);
        if a.0.is_nan() || b.0.is_nan() {
            flush(&mut cur, &mut pieces);
            open = false;
            continue;
        }
        match clip_segment(a, b, (x.lo, x.hi), (y.lo, y.hi)) {
            Some(c) => {
                // Continue the current piece only if this segment starts where the last ended.
                if !open || c.start_moved {
                    flush(&mut cur, &mut pieces);
                    cur.push(c.start);
                }
                cur.push(c.end);
                open = !c.end_moved;
            }
            None => {
                flush(&mut cur, &mut pieces);
                open = false;
            }
        }
    }
    flush(&mut cur, &mut pieces);
    pieces
}

/// Keeps the first, lowest, highest and last point of each run of pixel-space points falling in
/// one pixel column, which draws the same picture as the full line.
fn thin(line: Vec<(f64, f64)>, width: usize) -> Vec<(f64, f64)> {
    // Below one point per column thinning saves little.
    if line.len() <= width.max(1) {
        return line;
    }
    let column = |p: &(f64, f64)| p.0.floor() as i64;
    let mut out = Vec::with_capacity(4 * width + 4);
    let mut start = 0;
    while start < line.len() {
        let col = column(&line[start]);
        let mut end = start + 1;
        let (mut lo, mut hi) = (start, start);
        while end < line.len() && column(&line[end]) == col {
            if line[end].1 < line[lo].1 {
                lo = end;
            }
            if line[end].1 > line[hi].1 {
                hi = end;
            }
            end += 1;
        }
        let mut keep = [start, lo, hi, end - 1];
        keep.sort_unstable();
        let mut prev = usize::MAX;
        for i in keep {
            if i != prev {
                out.push(line[i]);
                prev = i;
            }
        }
        start = end;
    }
    out
}

/// Largest distance, in pixels, a simplified line may stray from the data. Long segments let the
/// anti-aliased rasteriser render slopes smoothly instead of as one-pixel stairs.
const SIMPLIFY_PX: f64 = 0.3;

/// Ramer-Douglas-Peucker simplification of a pixel-space polyline: the result keeps the end
/// points and stays within `eps` of every dropped point.
fn simplify(line: &[(f64, f64)], eps: f64) -> Vec<(f64, f64)> {
    if line.len() <= 2 {
        return line.to_vec();
    }
    let mut keep = vec![false; line.len()];
    keep[0] = true;
    keep[line.len() - 1] = true;
    let mut stack = vec![(0, line.len() - 1)];
    while let Some((i, j)) = stack.pop() {
        let mut worst = (0.0, i);
        for k in i + 1..j {
            let d = segment_distance(line[k], line[i], line[j]);
            if d > worst.0 {
                worst = (d, k);
            }
        }
        if worst.0 > eps {
            keep[worst.1] = true;
            stack.push((i, worst.1));
            stack.push((worst.1, j));
        }
    }
    line.iter()
        .zip(keep)
        .filter_map(|(p, k)| k.then_some(*p))
        .collect()
}

fn segment_distance(p: (f64, f64), a: (f64, f64), b: (f64, f64)) -> f64 {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p.0 - a.0 - t * dx).hypot(p.1 - a.1 - t * dy)
}

fn visible_markers(points: &[(f64, f64)], x: &AxisRange, y: &AxisRange) -> Vec<(f64, f64)> {
    points
        .iter()
        .copied()
        .filter(|p| p.0 >= x.lo && p.0 <= x.hi && p.1 >= y.lo && p.1 <= y.hi)
        .collect()
}

/// Draws the legend in the corner of the plot where it covers the least data.
fn draw_legend<DB: DrawingBackend>(
    plot: &DrawingArea<DB, Shift>,
    series: &[PlotSeries],
    lines: &[Vec<Vec<(i32, i32)>>],
    markers: &[Vec<(i32, i32)>],
    raster: bool,
) -> DrawResult<DB> {
    let entries: Vec<&PlotSeries> = series.iter().filter(|s| !s.label.is_empty()).collect();
    if entries.is_empty() {
        return Ok(());
    }
    let f = font(LEGEND_PX);
    let text_w = entries
        .iter()
        .map(|s| text_size(&f, &s.label).0)
        .max()
        .unwrap_or(0) as i32;
    let row_h = text_size(&f, "Ag(|").1 as i32 + 6;
    let (pad, sample_w, gap, inset) = (6, 30, 8, 8);
    let bw = pad + sample_w + gap + text_w + pad + 2;
    let bh = 2 * pad + row_h * entries.len() as i32 - 4;
    let (pw, ph) = plot.dim_in_pixel();
    let (pw, ph) = (pw as i32, ph as i32);

    let left = inset;
    let right = (pw - inset - bw).max(inset);
    let top = inset;
    let bottom = (ph - inset - bh).max(inset);
    // Preference order on ties: upper right, upper left, lower right, lower left.
    let corners = [(right, top), (left, top), (right, bottom), (left, bottom)];
    let cost = |(cx, cy): (i32, i32)| {
        let m = 4.0;
        let xr = (f64::from(cx) - m, f64::from(cx + bw) + m);
        let yr = (f64::from(cy) - m, f64::from(cy + bh) + m);
        let f = |p: (i32, i32)| (f64::from(p.0), f64::from(p.1));
        let segs: usize = lines
            .iter()
            .flatten()
            .map(|l| {
                l.windows(2)
                    .filter(|w| clip_segment(f(w[0]), f(w[1]), xr, yr).is_some())
                    .count()
            })
            .sum();
        let pts = markers
            .iter()
            .flatten()
            .map(|&p| f(p))
            .filter(|p| p.0 >= xr.0 && p.0 <= xr.1 && p.1 >= yr.0 && p.1 <= yr.1)
            .count();
        segs + pts
    };
    let (x0, y0) = corners
        .iter()
        .copied()
        .min_by_key(|&c| cost(c))
        .unwrap_or(corners[0]);

    plot.draw(&Rectangle::new(
        [(x0, y0), (x0 + bw, y0 + bh)],
        WHITE.mix(0.85).filled(),
    ))?;
    plot.draw(&Rectangle::new(
        [(x0, y0), (x0 + bw, y0 + bh)],
        LEGEND_BORDER.stroke_width(1),
    ))?;
    let text_style = f.color(&TEXT).pos(Pos::new(HPos::Left, VPos::Center));
    for (i, s) in entries.iter().enumerate() {
        let yc = y0 + pad + row_h * i as i32 + (row_h - 4) / 2;
        let xs = x0 + pad;
        let sample = [(xs, yc), (xs + sample_w, yc)];
        match s.style {
            Style::Line | Style::LineMarkers => stroke(plot, &sample, s.color, raster)?,
            Style::Dashed => {
                for dash in dashes(&sample) {
                    stroke(plot, &dash, s.color, raster)?;
                }
            }
            Style::Band => {
                plot.draw(&Rectangle::new(
                    [(xs, yc - 6), (xs + sample_w, yc + 6)],
                    s.color.mix(BAND_ALPHA).filled(),
                ))?;
            }
            Style::Stems => {
                let xm = xs + sample_w / 2;
                stroke(plot, &[(xm, yc + 7), (xm, yc - 3)], s.color, raster)?;
            }
            Style::Markers | Style::FadedMarkers => {}
        }
        if s.style.has_markers() {
            let c = if s.style == Style::Stems {
                (xs + sample_w / 2, yc - 3)
            } else {
                (xs + sample_w / 2, yc)
            };
            draw_marker(plot, c, s)?;
        }
        plot.draw(&Text::new(
            s.label.as_str(),
            (xs + sample_w + gap, yc),
            text_style.clone(),
        ))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    #[test]
    fn roles_colour_series_whatever_their_index() {
        use crate::figure::{Panel, Series};
        let mut panel = Panel::new("", "", "");
        panel.series = vec![
            Series::new("a", vec![0.0, 1.0], vec![0.0, 1.0], Style::Line),
            Series::new("m", vec![0.0, 1.0], vec![1.0, 0.0], Style::Line).with_role(Role::Measured),
        ];
        let fig = crate::grid_figure("", vec![panel], 1);
        let p = prepare(&fig, Path::new("x")).unwrap();
        assert_eq!(p[0].series[0].color, PALETTE[0]);
        assert_eq!(p[0].series[1].color, role_colour(Role::Measured));
    }

    #[test]
    fn band_with_an_undrawable_lower_edge_reaches_the_bottom() {
        // On a log axis a lower edge of -1 cannot be drawn: the band runs from the axis bottom
        // (plot-space 0 = log10 1) to the upper edge (log10 100 = 2).
        use crate::figure::{Panel, Series};
        let mut panel = Panel::new("", "", "");
        panel.y_scale = Scale::Log10;
        panel.series = vec![
            Series::new("g", vec![0.0, 1.0, 2.0], vec![1.0, 10.0, 1.0], Style::Line),
            Series::band(
                "band",
                vec![0.0, 1.0, 2.0],
                vec![1.0, -1.0, 1.0],
                vec![10.0, 100.0, 10.0],
            ),
        ];
        let fig = crate::grid_figure("", vec![panel], 1);
        let p = prepare(&fig, Path::new("x")).unwrap();
        // The y range covers the upper edge (2 in log10) with its 5 % margin.
        assert!(p[0].y.hi >= 2.0);
        let polys = band_polygons(&p[0].series[1], &p[0].x, &p[0].y);
        assert_eq!(polys.len(), 1);
        let lowest = polys[0].iter().map(|q| q.1).fold(f64::INFINITY, f64::min);
        assert_abs_diff_eq!(lowest, p[0].y.lo, epsilon = 1e-12);
    }

    #[test]
    fn band_with_a_short_upper_edge_is_an_error() {
        use crate::figure::{Panel, Series};
        let mut panel = Panel::new("", "", "");
        panel.series = vec![Series::band("b", vec![0.0, 1.0], vec![0.0, 1.0], vec![1.0])];
        let fig = crate::grid_figure("", vec![panel], 1);
        assert!(matches!(
            prepare(&fig, Path::new("x")),
            Err(PlotError::LengthMismatch { .. })
        ));
    }

    fn axis(lo: f64, hi: f64) -> AxisRange {
        AxisRange {
            scale: Scale::Linear,
            lo,
            hi,
        }
    }

    #[test]
    fn clipping_matches_the_line_equation() {
        // y = x from (-1,-1) to (2,2) in the unit box enters at (0,0) and leaves at (1,1).
        let c = clip_segment((-1.0, -1.0), (2.0, 2.0), (0.0, 1.0), (0.0, 1.0))
            .expect("the diagonal crosses the box");
        let (p, q, s, e) = (c.start, c.end, c.start_moved, c.end_moved);
        // Exact up to one rounding of t * d.
        assert_abs_diff_eq!(p.0, 0.0, epsilon = 1e-15);
        assert_abs_diff_eq!(p.1, 0.0, epsilon = 1e-15);
        assert_abs_diff_eq!(q.0, 1.0, epsilon = 1e-15);
        assert_abs_diff_eq!(q.1, 1.0, epsilon = 1e-15);
        assert!(s && e);
        assert!(clip_segment((2.0, 0.0), (3.0, 1.0), (0.0, 1.0), (0.0, 1.0)).is_none());
    }

    #[test]
    fn gaps_and_excursions_split_lines() {
        let nan = (f64::NAN, f64::NAN);
        // A spike through the top of the box splits the line into two pieces; the NaN a third.
        let pts = [
            (0.0, 0.5),
            (1.0, 0.5),
            (2.0, 5.0),
            (3.0, 0.5),
            (4.0, 0.5),
            nan,
            (5.0, 0.5),
            (6.0, 0.5),
        ];
        let pieces = line_pieces(&pts, &axis(0.0, 6.0), &axis(0.0, 1.0));
        assert_eq!(pieces.len(), 3);
        // First piece: (0,.5), (1,.5), then the exit on y = 1 at x = 1 + 0.5/4.5.
        assert_eq!(pieces[0].len(), 3);
        assert_abs_diff_eq!(pieces[0][2].0, 1.0 + 0.5 / 4.5, epsilon = 1e-12);
        assert_abs_diff_eq!(pieces[0][2].1, 1.0, epsilon = 1e-12);
        assert_eq!(pieces[1].len(), 3);
        assert_eq!(pieces[2].len(), 2);
        for p in pieces.iter().flatten() {
            assert!(p.0.is_finite() && p.1 <= 1.0 + 1e-12);
        }
    }

    #[test]
    fn thinning_keeps_the_envelope() {
        // 100 000 samples of a sine over 100 pixel columns: per column the extremes survive.
        let n = 100_000;
        let line: Vec<(f64, f64)> = (0..n)
            .map(|i| {
                let x = 100.0 * i as f64 / (n - 1) as f64;
                (x, 50.0 * (2.0 * x).sin())
            })
            .collect();
        let out = thin(line.clone(), 100);
        assert!(out.len() <= 4 * 101, "{} points kept", out.len());
        let max_in = line.iter().fold(f64::MIN, |m, p| m.max(p.1));
        let max_out = out.iter().fold(f64::MIN, |m, p| m.max(p.1));
        // The maximum sample is kept exactly.
        assert_abs_diff_eq!(max_in, max_out, epsilon = 0.0);
        // Thinning never reorders points.
        assert!(out.windows(2).all(|w| w[0].0 <= w[1].0));
    }

    #[test]
    fn simplification_stays_within_tolerance() {
        // A straight line collapses to its end points.
        let straight: Vec<(f64, f64)> = (0..1000)
            .map(|i| (f64::from(i), 0.5 * f64::from(i)))
            .collect();
        assert_eq!(simplify(&straight, 0.3).len(), 2);
        // A sine of 40 px amplitude over 800 px: every dropped point lies within 0.3 px of the
        // simplified polyline (checked by brute force against all its segments).
        let wave: Vec<(f64, f64)> = (0..8000)
            .map(|i| {
                let x = 0.1 * f64::from(i);
                (x, 40.0 * (x / 50.0).sin())
            })
            .collect();
        let simple = simplify(&wave, 0.3);
        assert!(
            simple.len() < wave.len() / 10,
            "{} points kept",
            simple.len()
        );
        for p in &wave {
            let d = simple
                .windows(2)
                .map(|w| segment_distance(*p, w[0], w[1]))
                .fold(f64::INFINITY, f64::min);
            assert!(d <= 0.3 + 1e-9, "point {p:?} is {d} px away");
        }
    }

    #[test]
    fn dashes_follow_the_pattern_across_vertices() {
        // An L-shaped path of 60 + 80 px: 140 px at 9 px on, 5 px off gives dashes starting
        // every 14 px, ten in all.
        let path = [(0, 0), (60, 0), (60, 80)];
        let d = dashes(&path);
        assert_eq!(d.len(), 10);
        // The fifth dash (56 .. 65 px along the path) bends round the corner at 60 px.
        assert_eq!(d[4], vec![(56, 0), (60, 0), (60, 5)]);
        assert_eq!(d[9], vec![(60, 66), (60, 75)]);
    }

    #[test]
    fn padding_handles_empty_and_constant_data() {
        let (lo, hi) = pad_extent(f64::INFINITY, f64::NEG_INFINITY, 0.05, Scale::Linear);
        assert_abs_diff_eq!(lo, 0.0);
        assert_abs_diff_eq!(hi, 1.0);
        let (lo, hi) = pad_extent(3.0, 3.0, 0.05, Scale::Linear);
        assert!(lo < 3.0 && hi > 3.0);
        let (lo, hi) = pad_extent(0.0, 10.0, 0.05, Scale::Linear);
        assert_abs_diff_eq!(lo, -0.5, epsilon = 1e-12);
        assert_abs_diff_eq!(hi, 10.5, epsilon = 1e-12);
    }
}
