//! End-to-end checks of `save`: files, image headers, SVG text and geometry, errors.

use std::path::{Path, PathBuf};

use htfid_plot::{
    bode_panels, grid_figure, magnitude_panel, save, stacked_figure, BodeSeries, Figure, Panel,
    PlotError, Scale, Series, Style,
};
use num_complex::Complex64;

const PNG_SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];
/// First palette colour (series 0), as the SVG backend spells it.
const FIRST_COLOUR: &str = "#1F77B4";

fn log_grid(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| lo * (hi / lo).powf(i as f64 / (n - 1) as f64))
        .collect()
}

fn second_order(w: f64) -> Complex64 {
    let s = Complex64::new(0.0, w);
    1.0 / (s * s + 2.0 * s + 200.0)
}

/// Width and height from the IHDR chunk, which the PNG format requires to come first.
fn png_size(bytes: &[u8]) -> (u32, u32) {
    assert_eq!(bytes[..8], PNG_SIGNATURE, "PNG signature");
    assert_eq!(&bytes[12..16], b"IHDR", "first chunk is IHDR");
    let be = |b: &[u8]| u32::from_be_bytes([b[0], b[1], b[2], b[3]]);
    (be(&bytes[16..20]), be(&bytes[20..24]))
}

/// The text content of every `<text>` element, trimmed.
fn svg_texts(svg: &str) -> Vec<String> {
    svg.split("<text")
        .skip(1)
        .filter_map(|t| {
            let body = &t[t.find('>')? + 1..];
            Some(body[..body.find("</text>")?].trim().to_string())
        })
        .collect()
}

/// The value of attribute `name` in an SVG tag.
fn attr<'a>(tag: &'a str, name: &str) -> Option<&'a str> {
    let key = format!(" {name}=\"");
    let start = tag.find(&key)? + key.len();
    Some(&tag[start..start + tag[start..].find('"')?])
}

/// Every `<polyline>` tag with its stroke colour and parsed points.
fn polylines(svg: &str) -> Vec<(String, Vec<(f64, f64)>)> {
    svg.split("<polyline")
        .skip(1)
        .map(|t| {
            let tag = &t[..t.find("/>").expect("closed tag")];
            let stroke = attr(tag, "stroke").unwrap_or("").to_string();
            let points = attr(tag, "points")
                .unwrap_or("")
                .split_whitespace()
                .map(|p| {
                    let (x, y) = p.split_once(',').expect("x,y pair");
                    (x.parse().expect("number"), y.parse().expect("number"))
                })
                .collect();
            (stroke, points)
        })
        .collect()
}

fn bode_figure() -> Figure {
    let omega = log_grid(0.1, 1000.0, 400);
    let g: Vec<Complex64> = omega.iter().map(|&w| second_order(w)).collect();
    let est: Vec<Complex64> = g.iter().map(|z| z * 1.05).collect();
    let panels = bode_panels(
        "G(s)",
        &omega,
        [
            ("theory", g, Style::Line),
            ("estimate", est, Style::Markers),
        ],
    );
    stacked_figure("Bode test", panels.to_vec())
}

fn saved(fig: &Figure, dir: &Path, name: &str) -> (PathBuf, PathBuf) {
    let paths = save(fig, &dir.join(name)).expect("save succeeds");
    assert_eq!(paths.len(), 2);
    assert_eq!(paths[0], dir.join(format!("{name}.svg")));
    assert_eq!(paths[1], dir.join(format!("{name}.png")));
    for p in &paths {
        assert!(p.is_file(), "{p:?} exists");
    }
    (paths[0].clone(), paths[1].clone())
}

#[test]
fn bode_figure_writes_svg_and_png() {
    let dir = tempfile::tempdir().expect("tempdir");
    let fig = bode_figure();
    let (svg_path, png_path) = saved(&fig, dir.path(), "bode");

    let png = std::fs::read(&png_path).expect("read png");
    assert_eq!(png_size(&png), (fig.width, fig.height));

    let svg = std::fs::read_to_string(&svg_path).expect("read svg");
    let texts = svg_texts(&svg);
    for want in [
        "Bode test",
        "G(s): magnitude",
        "G(s): phase",
        "frequency (rad/s)",
        "|G| (dB)",
        "phase (deg)",
    ] {
        assert!(
            texts.iter().any(|t| t == want),
            "{want:?} missing from {texts:?}"
        );
    }
    // One legend per panel, each naming both series.
    for label in ["theory", "estimate"] {
        assert_eq!(texts.iter().filter(|t| *t == label).count(), 2, "{label}");
    }
    // 0.1 .. 1000 rad/s spans four decades, labelled as plain numbers on both panels.
    for decade in ["0.1", "1", "10", "100", "1000"] {
        assert_eq!(texts.iter().filter(|t| *t == decade).count(), 2, "{decade}");
    }
    // The phase of 1/(s^2 + 2s + 200) runs from 0 to -180 degrees: ticks at multiples of 45.
    for tick in [
        "0",
        "\u{2212}45",
        "\u{2212}90",
        "\u{2212}135",
        "\u{2212}180",
    ] {
        assert!(texts.iter().any(|t| t == tick), "phase tick {tick:?}");
    }
    // No temporary files are left behind.
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .expect("list")
        .map(|e| e.expect("entry").file_name())
        .collect();
    assert_eq!(names.len(), 2, "{names:?}");
}

#[test]
fn harmonic_grid_has_every_panel() {
    let dir = tempfile::tempdir().expect("tempdir");
    let w = log_grid(0.5, 50.0, 200);
    let mut panels = Vec::new();
    let mut responses = Vec::new();
    for k in -3..=3 {
        let g: Vec<Complex64> = w
            .iter()
            .map(|&w| second_order(w + 2.0 * f64::from(k)) * 0.5f64.powi(k))
            .collect();
        responses.push(g);
    }
    for (k, g) in (-3..=3).zip(&responses) {
        panels.push(magnitude_panel(
            &format!("G_{k}"),
            &[
                BodeSeries {
                    label: "theory",
                    omega: &w,
                    response: g,
                    style: Style::Line,
                },
                BodeSeries {
                    label: "estimate",
                    omega: &w,
                    response: g,
                    style: Style::Markers,
                },
            ],
        ));
    }
    let fig = grid_figure("harmonics", panels, 3);
    let (svg_path, png_path) = saved(&fig, dir.path(), "grid");

    let png = std::fs::read(&png_path).expect("read png");
    assert_eq!(png_size(&png), (fig.width, fig.height));
    // 3 columns of 520 px, 3 rows of 360 px plus 40 px of title.
    assert_eq!((fig.width, fig.height), (1560, 1120));

    let texts = svg_texts(&std::fs::read_to_string(&svg_path).expect("read svg"));
    for k in -3..=3 {
        let title = format!("G_{k}");
        assert_eq!(texts.iter().filter(|t| **t == title).count(), 1, "{title}");
    }
    assert_eq!(texts.iter().filter(|t| *t == "theory").count(), 7);
    assert_eq!(texts.iter().filter(|t| *t == "estimate").count(), 7);
}

#[test]
fn non_finite_and_non_positive_points_are_skipped() {
    let dir = tempfile::tempdir().expect("tempdir");
    // On a log x axis: x = 0 and x < 0 are skipped, as are NaN and infinite y. The finite points
    // form two runs (indices 2..=4 and 6..=9), so the line has exactly two pieces.
    let x = vec![-1.0, 0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0];
    let y = vec![1.0, 1.0, 1.0, 2.0, 3.0, f64::NAN, 2.0, 1.0, 2.0, 3.0];
    let mut gaps = Panel::new("gaps", "x", "y");
    gaps.x_scale = Scale::Log10;
    gaps.series = vec![
        Series::new("data", x, y, Style::Line),
        Series::new("empty", vec![], vec![], Style::Line),
        Series::new(
            "all NaN",
            vec![f64::NAN; 3],
            vec![1.0, 2.0, 3.0],
            Style::Markers,
        ),
        Series::new(
            "infinite",
            vec![1.0, 2.0],
            vec![f64::INFINITY, f64::NEG_INFINITY],
            Style::Dashed,
        ),
    ];
    // A panel with nothing drawable at all still gets axes.
    let mut nothing = Panel::new("nothing", "x", "y");
    nothing.y_scale = Scale::Log10;
    nothing.series = vec![Series::new(
        "negative",
        vec![1.0, 2.0],
        vec![-1.0, -2.0],
        Style::Line,
    )];
    let fig = grid_figure("skipping", vec![gaps, nothing], 2);
    let (svg_path, png_path) = saved(&fig, dir.path(), "nan");

    let png = std::fs::read(&png_path).expect("read png");
    assert_eq!(png_size(&png), (fig.width, fig.height));

    let svg = std::fs::read_to_string(&svg_path).expect("read svg");
    let lines = polylines(&svg);
    for (_, pts) in &lines {
        for &(px, py) in pts {
            assert!(
                (0.0..=f64::from(fig.width)).contains(&px)
                    && (0.0..=f64::from(fig.height)).contains(&py),
                "point ({px}, {py}) outside the image"
            );
        }
    }
    // In the left panel: two data pieces plus the legend sample.
    let half = f64::from(fig.width) / 2.0;
    let first: Vec<_> = lines
        .iter()
        .filter(|(c, p)| c == FIRST_COLOUR && p.iter().all(|q| q.0 < half))
        .collect();
    assert_eq!(first.len(), 3, "{first:?}");
    let texts = svg_texts(&svg);
    for label in ["data", "empty", "all NaN", "infinite", "negative"] {
        assert!(texts.iter().any(|t| t == label), "legend lists {label:?}");
    }
}

#[test]
fn lines_leaving_an_explicit_range_are_clipped_to_the_axes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let x: Vec<f64> = (0..=100).map(|i| f64::from(i) / 10.0).collect();
    let y: Vec<f64> = x.iter().map(|x| 1e6 * (x - 5.0)).collect();
    let mut panel = Panel::new("clipped", "x", "y");
    panel.y_range = Some((-1.0, 1.0));
    panel.series = vec![Series::new("steep", x, y, Style::Line)];
    let fig = stacked_figure("", vec![panel]);
    let (svg_path, _) = saved(&fig, dir.path(), "clip");
    let svg = std::fs::read_to_string(&svg_path).expect("read svg");
    // The frame is the grey polyline through the plot's top-right corner; its extent bounds the
    // plotting area.
    let lines = polylines(&svg);
    let frame = lines
        .iter()
        .filter(|(c, p)| c == "#404040" && p.len() == 3)
        .map(|(_, p)| p.clone())
        .next()
        .expect("frame");
    let (top, right) = (frame[0].1, frame[1].0);
    let data: Vec<_> = lines.iter().filter(|(c, _)| c == FIRST_COLOUR).collect();
    // The steep line crosses the band |y| <= 1 once; the legend sample is the other polyline.
    assert_eq!(data.len(), 2);
    for &(px, py) in &data[0].1 {
        assert!(
            py >= top - 0.5 && px <= right + 0.5,
            "({px}, {py}) outside the axes"
        );
    }
}

#[test]
fn legend_avoids_the_corner_holding_the_data() {
    let dir = tempfile::tempdir().expect("tempdir");
    // Data fill the upper-right and lower-right quadrants of the axes: the preferred upper-right
    // corner is taken, so the legend must move to the left half.
    let x: Vec<f64> = (0..=200).map(|i| 0.5 + f64::from(i) / 400.0).collect();
    let y: Vec<f64> = (0..=200)
        .map(|i| if i % 2 == 0 { 0.0 } else { 1.0 })
        .collect();
    let mut panel = Panel::new("right half", "x", "y");
    panel.x_range = Some((0.0, 1.0));
    panel.series = vec![Series::new("zigzag", x, y, Style::Line)];
    let fig = stacked_figure("", vec![panel]);
    let (svg_path, _) = saved(&fig, dir.path(), "legend");
    let svg = std::fs::read_to_string(&svg_path).expect("read svg");
    let legend = svg
        .split("<rect")
        .skip(1)
        .find(|t| attr(t, "opacity") == Some("0.85"))
        .expect("legend background");
    let lx: f64 = attr(legend, "x").expect("x").parse().expect("number");
    assert!(lx < f64::from(fig.width) / 2.0, "legend at x = {lx}");
}

fn expect_err(fig: &Figure) -> (PlotError, tempfile::TempDir) {
    let dir = tempfile::tempdir().expect("tempdir");
    let err = save(fig, &dir.path().join("bad")).expect_err("save fails");
    let left: Vec<_> = std::fs::read_dir(dir.path()).expect("list").collect();
    assert!(left.is_empty(), "nothing is written for an invalid figure");
    (err, dir)
}

#[test]
fn invalid_figures_are_reported_with_the_path() {
    let (err, dir) = expect_err(&stacked_figure("empty", vec![]));
    assert!(matches!(err, PlotError::EmptyFigure { ref path } if *path == dir.path().join("bad")));
    assert!(err.to_string().contains("bad"), "{err}");

    let mut fig = bode_figure();
    fig.columns = 0;
    assert!(matches!(expect_err(&fig).0, PlotError::NoColumns { .. }));

    let mut fig = bode_figure();
    fig.width = 10;
    let (err, _) = expect_err(&fig);
    assert!(
        matches!(err, PlotError::InvalidSize { width: 10, .. }),
        "{err}"
    );

    let mut fig = bode_figure();
    fig.panels[1].series[0].y.pop();
    let (err, _) = expect_err(&fig);
    match err {
        PlotError::LengthMismatch {
            panel,
            ref series,
            x_len,
            y_len,
            ..
        } => {
            assert_eq!(
                (panel, series.as_str(), x_len, y_len),
                (1, "theory", 400, 399)
            );
        }
        ref other => panic!("unexpected {other}"),
    }

    let mut fig = bode_figure();
    fig.panels[0].x_range = Some((0.0, 10.0));
    let (err, _) = expect_err(&fig);
    assert!(
        matches!(
            err,
            PlotError::InvalidRange {
                axis: "x",
                panel: 0,
                ..
            }
        ),
        "{err}"
    );
    let mut fig = bode_figure();
    fig.panels[1].y_range = Some((5.0, f64::NAN));
    assert!(matches!(
        expect_err(&fig).0,
        PlotError::InvalidRange { axis: "y", .. }
    ));
}

#[test]
fn failed_write_leaves_no_temporary_files() {
    let dir = tempfile::tempdir().expect("tempdir");
    // A directory where the PNG should go makes the final rename fail.
    std::fs::create_dir(dir.path().join("blocked.png")).expect("mkdir");
    let err = save(&bode_figure(), &dir.path().join("blocked")).expect_err("rename fails");
    assert!(
        matches!(err, PlotError::Io { ref path, .. } if path.ends_with("blocked.png")),
        "{err}"
    );
    let leftovers: Vec<String> = std::fs::read_dir(dir.path())
        .expect("list")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".tmp."))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[test]
fn saving_twice_replaces_the_files() {
    let dir = tempfile::tempdir().expect("tempdir");
    let fig = bode_figure();
    saved(&fig, dir.path(), "again");
    let mut smaller = fig.clone();
    smaller.width = 640;
    let (_, png_path) = saved(&smaller, dir.path(), "again");
    let png = std::fs::read(&png_path).expect("read png");
    assert_eq!(png_size(&png), (640, fig.height));
}
