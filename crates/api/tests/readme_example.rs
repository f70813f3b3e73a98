//! The README's facade example runs as written: the hopper and a model file to their exact
//! HTFs, three lines each.

use htfid_api::{Hopper, HopperParams, Htf, Model};

#[test]
fn readme_example_runs() -> Result<(), Box<dyn std::error::Error>> {
    std::env::set_current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))?;
    // As in the README.
    let hopper = Hopper::new(HopperParams::paper())?;
    let htf = Htf::of(&hopper)?; // limit cycle, linearisation, exact HTFs
    let g0 = htf.g(0, 10.0)?; // G_0 at 10 rad/s, in m/N

    let model = Model::from_file("models/two-dof.toml".as_ref())?;
    let grids = Htf::of(&model)?.grids(&[-1, 0, 1], &[5.0, 10.0])?; // one grid per output

    // Below resonance (sqrt(k/m) = 14.1 rad/s) the hopper's G_0 exceeds its static 1/k.
    assert!(g0.norm() > 1.0 / 200.0 && g0.norm() < 1.0, "{g0}");
    assert_eq!(grids.len(), 2);
    assert!(grids
        .iter()
        .all(|g| g.values.iter().all(|v| v.norm().is_finite())));
    Ok(())
}

/// The facade gives the same HTF as the crates underneath.
#[test]
fn the_facade_adds_nothing_to_the_numbers() -> Result<(), Box<dyn std::error::Error>> {
    let hopper = Hopper::new(HopperParams::paper())?;
    let htf = Htf::of(&hopper)?;
    let orbit = hopper.limit_cycle(&Default::default(), &Default::default())?;
    let direct = htfid_theory::LinearisedHtf::new(&hopper, &orbit.cycle, &Default::default())?;
    let grid = &direct.grids(&[-2, 0, 1], &[3.0, 12.5])?[0];
    for (j, &n) in grid.harmonics.iter().enumerate() {
        for (i, &w) in grid.omegas.iter().enumerate() {
            let d = htf.g(n, w)? - grid.values[i * grid.harmonics.len() + j];
            assert!(d.norm() < 1e-12, "G_{n}({w}): {d}");
        }
    }
    Ok(())
}
