//! Timing of the project's headline workloads (best of several runs, one thread).
//!
//! `cargo bench -p htfid --bench pipeline` prints a table; the figures in
//! docs/performance.md come from it.

use std::hint::black_box;
use std::process::Command;
use std::time::Instant;

use htfid_excite::{PhaseShiftedTrain, Signal};
use htfid_hybrid::{simulate, Options};
use htfid_ltp::linearise;
use htfid_model::{Hopper, HopperParams, InputFn};
use htfid_orbit::ShootingOptions;
use htfid_theory::{ExactHtf, HarmonicTransferFunction};

fn best_of<T>(runs: usize, mut f: impl FnMut() -> T) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..runs {
        let t = Instant::now();
        black_box(f());
        best = best.min(t.elapsed().as_secs_f64() * 1e3);
    }
    best
}

fn main() {
    let hopper = Hopper::new(HopperParams::paper()).unwrap();
    let opts = Options::default(); // rtol 1e-10, DOP853
    let orbit = hopper
        .limit_cycle(&ShootingOptions::default(), &opts)
        .unwrap();

    let train = std::sync::Arc::new(PhaseShiftedTrain::paper(30.0).unwrap());
    let input: InputFn = {
        let train = train.clone();
        std::sync::Arc::new(move |t| train.value(t))
    };
    let driven = hopper.with_input(Some(input));
    let mut switches = 0;
    let mut steps = 0;
    let sim_ms = best_of(20, || {
        let traj = simulate(
            &driven,
            orbit.cycle.mode0,
            0.0,
            &orbit.cycle.state0,
            301.0,
            &[],
            &opts,
        )
        .unwrap();
        switches = traj.transitions().count();
        steps = traj.stats.steps;
        traj.final_state
    });
    let lc_ms = best_of(20, || {
        hopper
            .limit_cycle(&ShootingOptions::default(), &opts)
            .unwrap()
    });

    // The same experiment with the hopper written in the model language (models/hopper.toml).
    let model_path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../models/hopper.toml");
    let model = htfid_lang::Model::from_file(std::path::Path::new(model_path)).unwrap();
    let model_cycle = model
        .limit_cycle(&ShootingOptions::default(), &opts)
        .unwrap();
    let model_driven = model.with_input(Some({
        let train = train.clone();
        std::sync::Arc::new(move |t| train.value(t))
    }));
    let mut model_steps = 0;
    let model_sim_ms = best_of(20, || {
        let traj = simulate(
            &model_driven,
            model_cycle.mode0,
            0.0,
            &model_cycle.state0,
            301.0,
            &[],
            &opts,
        )
        .unwrap();
        model_steps = traj.stats.steps;
        traj.final_state
    });
    let model_lc_ms = best_of(20, || {
        model
            .limit_cycle(&ShootingOptions::default(), &opts)
            .unwrap()
    });
    let model_htf_ms = best_of(5, || {
        let htf = htfid_theory::LinearisedHtf::new(&model, &model_cycle, &opts).unwrap();
        htf.grids(&(-10..=10).collect::<Vec<i32>>(), &[5.0, 10.0])
            .unwrap()
    });

    let lin = linearise(&hopper, &orbit.cycle, 16, &opts).unwrap();
    let exact = ExactHtf::new(&lin.piecewise).unwrap();
    let harmonics: Vec<i32> = (-10..=10).collect();
    let omegas: Vec<f64> = (0..2000)
        .map(|i| 0.5 + 59.5 * f64::from(i) / 1999.0)
        .collect();
    let htf_ms = best_of(20, || exact.grid(&harmonics, &omegas));

    println!("workload | best of runs (ms) | notes");
    println!("---|---|---");
    println!("paper experiment, 301 s forced simulation at rtol 1e-10 (DOP853) | {sim_ms:.2} | {steps} steps, {switches} switches");
    println!("limit cycle (30 settling periods + Newton shooting) | {lc_ms:.2} |");
    println!("exact HTF, n = -10..10 on 2000 frequencies | {htf_ms:.2} | 42 000 values");
    println!("model-language hopper (models/hopper.toml): the same 301 s simulation | {model_sim_ms:.2} | {model_steps} steps, {:.2}x the built-in", model_sim_ms / sim_ms);
    println!(
        "model-language hopper: limit cycle | {model_lc_ms:.2} | {:.2}x the built-in",
        model_lc_ms / lc_ms
    );
    println!(
        "model-language hopper: linearise + exact HTF setup, 2 frequencies | {model_htf_ms:.2} |"
    );

    // The whole `htfid run` of the paper config, as a user runs it (wall time, no plots).
    let exe = env!("CARGO_BIN_EXE_htfid");
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");
    let dir = std::env::temp_dir().join(format!("htfid-bench-{}", std::process::id()));
    for (config, label) in [
        (
            "configs/paper.toml",
            "htfid run configs/paper.toml --no-plots",
        ),
        (
            "configs/paper-model.toml",
            "htfid run configs/paper-model.toml --no-plots (the hopper as models/hopper.toml)",
        ),
        (
            "configs/paper-improved.toml",
            "htfid run configs/paper-improved.toml --no-plots",
        ),
    ] {
        let runs = if config.contains("improved") { 3 } else { 10 };
        let ms = best_of(runs, || {
            let status = Command::new(exe)
                .args(["run", config, "--no-plots", "--force", "--out"])
                .arg(&dir)
                .current_dir(root)
                .stderr(std::process::Stdio::null())
                .status()
                .unwrap();
            assert!(status.success());
        });
        println!("{label} (wall, whole process) | {ms:.1} |");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
