mod common;
use common::*;
use htfid_diagnose::*;
use htfid_model::{Effects, HopperParams};

#[test]
#[ignore = "exploration"]
fn explore() {
    let mut p = Protocol::default();
    if let Ok(v) = std::env::var("NX") {
        p.noise_x = v.parse().unwrap();
    }
    if let Ok(v) = std::env::var("NF") {
        p.noise_f = v.parse().unwrap();
    }
    if let Ok(v) = std::env::var("AMP") {
        p.amplitude = v.parse().unwrap();
    }
    let params = HopperParams::paper();
    let which = std::env::var("EFFECT").unwrap_or_default();
    let val: f64 = std::env::var("VAL")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0.0);
    let mut e = Effects::default();
    let mut params = params;
    match which.as_str() {
        "k3" => e.k3 = val,
        "mu" => e.mu = val,
        "c_f" => e.c_f = val,
        "c2" => e.c2 = val,
        "tau" => e.tau = val,
        "delay" => e.delay = val,
        "v_th" => e.v_th = val,
        "stop" => {
            e.hard_stop = Some(htfid_model::HardStop {
                x_stop: val,
                k_stop: std::env::var("KSTOP")
                    .map(|v| v.parse().unwrap())
                    .unwrap_or(2000.0),
            })
        }
        "m" => params.m = val,
        _ => {}
    }
    let t = std::time::Instant::now();
    let extra: Option<ExtraForce> = match which.as_str() {
        "sine" => Some(std::sync::Arc::new(move |t: f64, _x: f64, _v: f64| {
            val * (2.0 * std::f64::consts::PI * 3.3 * t).sin()
        })),
        "quad" => Some(std::sync::Arc::new(move |_t: f64, x: f64, _v: f64| {
            -val * (x - 0.2) * (x - 0.2)
        })),
        "vdamp" => Some(std::sync::Arc::new(move |_t: f64, x: f64, v: f64| {
            -val * (x - 0.151) * v
        })),
        "drift" => Some(std::sync::Arc::new(move |t: f64, x: f64, _v: f64| {
            -val * t / 80.0 * (x - 0.2)
        })),
        _ => None,
    };
    let seed: u64 = std::env::var("SEED")
        .map(|v| v.parse().unwrap())
        .unwrap_or(1);
    let rec = generate(&p, params, e, extra, seed);
    println!("generated in {:?}", t.elapsed());
    let x = rec.x();
    let mean = x.iter().sum::<f64>() / x.len() as f64;
    let sd = (x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / x.len() as f64).sqrt();
    println!(
        "x mean {mean} sd {sd} min {} max {}",
        x.iter().cloned().fold(f64::INFINITY, f64::min),
        x.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
    );
    let nominal = NominalModel::hopper(HopperParams::paper()).unwrap();
    let t = std::time::Instant::now();
    let mut opts = DiagnoseOptions::default();
    if let Ok(v) = std::env::var("RTOL") {
        opts.sim = SimMethod::Adaptive {
            rtol: v.parse().unwrap(),
        };
    }
    if let Ok(v) = std::env::var("MRS") {
        opts.sim = SimMethod::FixedStep {
            max_rate_step: v.parse().unwrap(),
        };
    }
    if let Ok(v) = std::env::var("BURN") {
        opts.burn_in_s = Some(v.parse().unwrap());
    }
    if std::env::var("LIN").is_ok() {
        opts.interpolation = Interpolation::Linear;
    }
    if let Ok(v) = std::env::var("ONLY") {
        opts.candidates = v.split(',').map(|s| s.parse().unwrap()).collect();
    }
    let r = diagnose_with_progress(&rec, &nominal, &opts, &|s| println!("  {s}")).unwrap();
    println!(
        "diagnosed in {:?}, evaluations {}",
        t.elapsed(),
        r.evaluations
    );
    let d = &r.diagnosis;
    println!(
        "cause {} nominal {:.3e} extended {:.3e} gain {:.3}",
        d.cause, d.nominal.rmse, d.extended.rmse, d.gain
    );
    println!("params {:?}", d.parameters);
    if std::env::var("BRIEF").is_ok() {
        println!(
            "BRIEF {which}={val} -> {} ratio {:.2} params {:?}",
            d.cause,
            d.nominal.rmse / r.noise_floor.unwrap(),
            d.parameters
        );
        return;
    }
    for c in &d.candidates {
        println!(
            "  {:18} rmse {:.3e} bic {:.1} sig {} :: {:?} | {}",
            c.effect, c.rmse_validation, c.bic, c.significant, c.parameters, c.note
        );
    }
    for e in &d.evidence {
        println!("  * {e}");
    }
    println!("noise floor {:?} burn-in {}", r.noise_floor, r.burn_in_s);
}
