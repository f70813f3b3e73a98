use htfid_plot::{save, stacked_figure, time_panel};
use std::path::Path;
fn main() {
    let mk = |n: usize| {
        let t: Vec<f64> = (0..n).map(|i| 20.0 * i as f64 / n as f64).collect();
        let u: Vec<f64> = t.iter().map(|&t| if t % 4.0 < 2.0 { 1.0 } else { -1.0 }).collect();
        (t, u)
    };
    let (t1, u1) = mk(20000);
    let (t2, u2) = mk(3000);
    let fig = stacked_figure("exp", vec![time_panel("20000", "u", &t1, [("u", &u1)]), time_panel("3000", "u", &t2, [("u", &u2)])]);
    save(&fig, Path::new("/tmp/plotexp/sq")).unwrap();
}
