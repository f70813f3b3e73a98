//! The README's three-line example runs as written (from a model file to its exact HTFs).

#[test]
fn readme_example_runs() -> Result<(), Box<dyn std::error::Error>> {
    std::env::set_current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))?;
    let model = htfid_lang::Model::from_file("models/two-dof.toml".as_ref())?;
    let cycle = model.limit_cycle(&Default::default(), &Default::default())?;
    let grids = htfid_theory::LinearisedHtf::new(&model, &cycle, &Default::default())?
        .grids(&[-1, 0, 1], &[5.0, 10.0])?; // one grid per output
    assert_eq!(grids.len(), 2);
    assert!(grids
        .iter()
        .all(|g| g.values.iter().all(|v| v.norm().is_finite())));
    Ok(())
}
