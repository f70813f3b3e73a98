//! From a scenario to a record: simulate, measure, add noise, write CSV.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use crate::error::Error;
use crate::label::Label;
use crate::plant::Plant;
use crate::scenario::Scenario;
use crate::simulate::{SimOptions, Trajectory};

/// A generated record: what a user would measure, and the expected answer.
#[derive(Clone, Debug)]
pub struct Record {
    /// Absolute sample times, s (`t = 0` is phase 0 of the forcing).
    pub t: Vec<f64>,
    /// Commanded force, N (with its noise, if any).
    pub f: Vec<f64>,
    /// Measured position, m (with its noise, if any).
    pub x: Vec<f64>,
    /// The expected answer.
    pub label: Label,
}

impl Record {
    /// Write `t,f,x` with a one-line header, one row per sample, every number in the shortest
    /// form that reads back to the identical `f64`.
    ///
    /// # Errors
    /// [`Error::Io`] naming the file.
    pub fn write_csv(&self, path: &Path) -> Result<(), Error> {
        let io = |source| Error::Io {
            path: path.to_path_buf(),
            source,
        };
        let mut w = BufWriter::new(File::create(path).map_err(io)?);
        writeln!(w, "t,f,x").map_err(io)?;
        for i in 0..self.t.len() {
            // `{:?}` is Rust's shortest round-trip form (like %.17g after trimming).
            writeln!(w, "{:?},{:?},{:?}", self.t[i], self.f[i], self.x[i]).map_err(io)?;
        }
        w.flush().map_err(io)
    }
}

/// Sample instants of a scenario: `settle_s + n / fs` for `n = 0 .. round(record_s * fs)`.
pub fn sample_times(s: &Scenario) -> Vec<f64> {
    let fs = f64::from(s.sample_rate.hz());
    let n = (s.record_s * fs).round() as usize;
    (0..n).map(|i| s.settle_s + i as f64 / fs).collect()
}

/// Generate a scenario's record with the default integration settings.
///
/// # Errors
/// See [`generate_with`].
pub fn generate(s: &Scenario) -> Result<Record, Error> {
    generate_with(s, &SimOptions::default())
}

/// Generate a scenario's record.
///
/// # Errors
/// [`Error::InvalidParameter`] or [`Error::ConflictingEffects`] for a bad scenario, and the
/// integrator's errors ([`Error::StepSizeTooSmall`], [`Error::NoConsistentMode`],
/// [`Error::EventStorm`]).
pub fn generate_with(s: &Scenario, opts: &SimOptions) -> Result<Record, Error> {
    let (plant, traj) = simulate_scenario(s, opts)?;
    let mut x: Vec<f64> = traj.states.iter().map(|y| plant.measured(y)).collect();
    let mut f: Vec<f64> = traj.t.iter().map(|&t| plant.commanded_force(t)).collect();
    add_noise(&mut x, s.noise.sigma_x, s.seed, 0);
    add_noise(&mut f, s.noise.sigma_f, s.seed, 1);
    Ok(Record {
        t: traj.t,
        f,
        x,
        label: s.label(),
    })
}

/// The plant and its full trajectory at the scenario's sample instants, from the rest state
/// at `t = 0`.
///
/// # Errors
/// As [`generate_with`].
pub fn simulate_scenario(s: &Scenario, opts: &SimOptions) -> Result<(Plant, Trajectory), Error> {
    let plant = Plant::new(s)?;
    let times = sample_times(s);
    let traj = plant.simulate(0.0, plant.rest_state(0.0), &times, opts)?;
    Ok((plant, traj))
}

/// Add white Gaussian noise from ChaCha8 stream `stream` of `seed`; nothing is drawn when
/// `sigma` is zero, so the noise on x does not depend on whether f is noisy.
fn add_noise(v: &mut [f64], sigma: f64, seed: u64, stream: u64) {
    if sigma <= 0.0 {
        return;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(stream);
    let normal = Normal::new(0.0, sigma).expect("sigma is finite and positive (validated)");
    for e in v.iter_mut() {
        *e += normal.sample(&mut rng);
    }
}

/// RMS over the record of how much the scenario's effects and parameter errors change the
/// measured position, noise excluded: the noise-free record against its
/// [`Scenario::nominal_twin`], m.
///
/// # Errors
/// As [`generate_with`].
pub fn effect_rms(s: &Scenario) -> Result<f64, Error> {
    let quiet = Scenario {
        noise: crate::scenario::Noise::default(),
        ..s.clone()
    };
    let a = generate(&quiet)?;
    let b = generate(&s.nominal_twin())?;
    let ss: f64 = a.x.iter().zip(&b.x).map(|(p, q)| (p - q).powi(2)).sum();
    Ok((ss / a.x.len().max(1) as f64).sqrt())
}
