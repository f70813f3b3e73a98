use htfid_plot::{grid_figure, save, stacked_figure, Panel, Scale, Series, Style};
use std::path::Path;
fn main() {
    let x = vec![-1.0, 0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0];
    let y = vec![1.0, 1.0, 1.0, 2.0, 3.0, f64::NAN, 2.0, 1.0, 2.0, 3.0];
    let mut gaps = Panel::new("gaps", "x", "y");
    gaps.x_scale = Scale::Log10;
    gaps.series = vec![
        Series::new("data", x, y, Style::LineMarkers),
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
        Series::new("dashed", vec![1.0, 8.0], vec![1.5, 2.5], Style::Dashed),
    ];
    let mut nothing = Panel::new("nothing", "x", "y");
    nothing.y_scale = Scale::Log10;
    nothing.series = vec![Series::new(
        "negative",
        vec![1.0, 2.0],
        vec![-1.0, -2.0],
        Style::Line,
    )];
    let fig = grid_figure("skipping", vec![gaps, nothing], 2);
    save(&fig, Path::new("/tmp/plotexp/nan")).unwrap();

    let x: Vec<f64> = (0..=200).map(|i| 0.5 + f64::from(i) / 400.0).collect();
    let y: Vec<f64> = (0..=200)
        .map(|i| if i % 2 == 0 { 0.0 } else { 1.0 })
        .collect();
    let mut panel = Panel::new("right half", "x", "y");
    panel.x_range = Some((0.0, 1.0));
    panel.series = vec![Series::new("zigzag", x, y, Style::Line)];
    let xs: Vec<f64> = (0..=100).map(|i| f64::from(i) / 10.0).collect();
    let ys: Vec<f64> = xs.iter().map(|x| 1e6 * (x - 5.0)).collect();
    let mut clip = Panel::new("clipped", "x", "y");
    clip.y_range = Some((-1.0, 1.0));
    clip.series = vec![Series::new("steep", xs, ys, Style::Line)];
    let mut small = Panel::new("small numbers", "t (s)", "e (m)");
    let t: Vec<f64> = (0..500).map(|i| 1e-4 * f64::from(i)).collect();
    small.series = vec![
        Series::new(
            "tiny",
            t.clone(),
            t.iter().map(|t| 3e-6 * (1000.0 * t).sin()).collect(),
            Style::Line,
        ),
        Series::new(
            "big",
            t.clone(),
            t.iter().map(|t| 2e-6 + 1e-7 * t).collect(),
            Style::Dashed,
        ),
    ];
    save(
        &stacked_figure("", vec![panel, clip, small]),
        Path::new("/tmp/plotexp/misc"),
    )
    .unwrap();
}
