//! Ground truth for htfid: records of the forced vertical hopper ("the paper's hopper") with
//! known effects, written from the equations below and nothing else. No code is shared with
//! the htfid crates under test, so a sign error there cannot hide here.
//!
//! The main types: a [`Scenario`] (serde) says what is in the true system and how it is
//! measured; [`generate`] turns it into a [`Record`] (`t, f, x` and the expected answer, a
//! [`Label`]); [`catalogue`] draws a covering set of scenarios from a seed. Underneath,
//! [`Plant`] is the resolved true system and [`Plant::simulate`] its event-driven integrator.
//!
//! ```
//! use htfid_truth::{generate, Effect, Scenario};
//!
//! let s = Scenario {
//!     effects: vec![Effect::CoulombFriction { mu: 0.05 }],
//!     record_s: 10.0,
//!     ..Scenario::default()
//! };
//! let rec = generate(&s)?;
//! assert_eq!(rec.t.len(), 1000); // 10 s at 100 Hz, from t = 30 s
//! assert!((rec.t[0] - 30.0).abs() < 1e-12);
//! assert_eq!(rec.label.effects[0].name, "coulomb_friction");
//! # Ok::<(), htfid_truth::Error>(())
//! ```
//!
//! # The true system
//!
//! SI units throughout. State `(x, v)`: position and velocity of the measured body.
//! Nominal `m = 1 kg, k = 200 N/m, c = 2 N s/m, g = 9.81 m/s^2, x0 = 0.2 m`, forcing
//! `A cos(2 pi t / T)` with `A = 1 N, T = 1 s`; `t = 0` is phase 0 of the forcing and every
//! time in a record is absolute.
//!
//! ```text
//! m v' = -m g - k (x - x0) - c s v + F_applied(t) + (effect forces)
//! s = 1 (damper on) while v > v_th, s = 0 otherwise;  v_th = 0 nominally
//! ```
//!
//! The commanded force is `f(t) = A cos(2 pi t / T) + u(t)`; the record stores `t`, `f` and
//! the measured position. Without input effects `F_applied = f`.
//!
//! # Protocol and excitation
//!
//! The simulation starts at `t = 0` from `x = x0 - m g / k` (true parameters), `v = 0`, with
//! `u = 0`, and settles for `settle_s` (default 30 s = 30 periods). The record then covers
//! `record_s` (default 270 s) at `settle_s + n / fs`, `fs` in {50, 100, 200, 1000} Hz.
//! - [`Excitation::PaperChirps`] (default): back-to-back 30 s chirps; chirp `i` occupies
//!   `[settle_s + 30 i, settle_s + 30 (i + 1))` and is `0.004 sin(14 pi tau^2 / 30 + phi_i)`,
//!   `tau` the time since it started (instantaneous frequency `14 tau / 30` Hz, 0 to 14 Hz),
//!   `phi_i = 2 pi (i mod 9) / 9`. Because of the phases `u` jumps (by at most 0.0027 N) where
//!   chirps meet; the integrator stops exactly there.
//! - [`Excitation::Multisine`]: 68 lines at 0.25, 0.35, ..., 6.95 Hz (odd multiples of
//!   0.05 Hz, so none coincides with a forcing harmonic), each `a sin(2 pi f tau + p)` with
//!   seeded uniform phases and `a = 0.004 / sqrt 68`, so the RMS equals the chirp's
//!   (`0.004 / sqrt 2` N). Period 20 s.
//! - [`Excitation::ForcingOnly`]: `u = 0`.
//!
//! # Effects
//!
//! Each effect may appear alone or with others (each kind at most once; the two frictions
//! exclude each other). In the library (the diagnosis should name them):
//! - `cubic_stiffness {k3}`: force `-k3 (x - x0)^3`.
//! - `coulomb_friction {mu}`: force `-mu sign(v)`; `asymmetric_friction {mu_pos, mu_neg}`:
//!   `-mu_pos` while `v > 0`, `+mu_neg` while `v < 0`. At `v = 0` the body sticks (Filippov):
//!   with `F_o` the sum of all other forces at `v = 0`, it stays at `v = 0` while
//!   `-mu_neg <= F_o <= mu_pos` and leaves upward when `F_o > mu_pos`, downward when
//!   `F_o < -mu_neg`.
//! - `flight_damping {c_f}`: force `-c_f (1 - s) v` (damping while the damper is off).
//! - `quadratic_drag {c2}`: force `-c2 v |v|`.
//! - `actuator_lag {tau}`: `F_applied` is a state, `tau F_applied' = f_in - F_applied`.
//! - `input_delay {delay}`: `f_in(t) = f(t - delay)`; for `t < 0` the forcing alone.
//! - `input_offset {offset}`: `f_in = f + offset`.
//! - `switch_threshold {v_th}`: the damper is on while `v > v_th`. When the damping force
//!   jumps at `v = v_th` (`v_th != 0` and `c != c_f`) the flow may slide along `v = v_th`
//!   (Filippov: `x' = v_th`, `v' = 0`, `s` in (0, 1) balancing the forces); handled exactly.
//! - `hard_stop {k_stop, x_stop}`: force `-k_stop (x - x_stop)` while `x < x_stop`.
//! - parameter errors ([`ParameterErrors`]): `m, k, c, g, x0` are `nominal * (1 + error)`.
//! - `sensor_lag {tau_s}`: the sensor reads `x_m`, `tau_s x_m' = x - x_m`.
//! - `sensor_offset_gain {b, gain}`: `x_measured = gain * x_sensor + b`, where `x_sensor` is
//!   `x`, or `x_m` with a sensor lag.
//!
//! Outside the library (the diagnosis must not claim them with confidence):
//! - `backlash {gap}`: a play operator of total width `gap` (half-width `r = gap / 2`) between
//!   the actuator input `f_in` and its output `y`: `y` stays constant while `|f_in - y| < r`;
//!   while `f_in - y = r` and `f_in` rises, `y = f_in - r`; while `f_in - y = -r` and `f_in`
//!   falls, `y = f_in + r`. If `f_in` jumps, `y` is clamped into `[f_in - r, f_in + r]`.
//!   Initially `y = f_in(0) - r`. `y` then drives the actuator lag if there is one, else
//!   `F_applied = y`.
//! - `second_mode {m2, k2, c2}`: part `m2` of the total mass hangs from the measured body on a
//!   spring `k2` and damper `c2` (the measured body has mass `m - m2`, so the static
//!   equilibrium and the total mass are unchanged). With `q` the link extension from its static
//!   value: `(m - m2) v' = -m g - k (x - x0) - ... + k2 q + c2 q'`,
//!   `m2 (v' + q'') = -k2 q - c2 q'`. All other forces act on the measured body.
//! - `pos_vel_force {a}`: force `-a (x - x_eq) v`, `x_eq = x0 - m g / k`.
//! - `slow_forcing_amplitude {depth, period}`: the true forcing amplitude is
//!   `A (1 + depth sin(2 pi t / period))`; the recorded `f` keeps `A cos(...) + u` (the
//!   modulation is unmeasured).
//!
//! The applied-force chain is: true command (with the slow modulation) -> delay -> offset ->
//! backlash -> actuator lag -> `F_applied`.
//!
//! Noise ([`Noise`]): white Gaussian, added to `x_measured` (`sigma_x`) and optionally to the
//! recorded `f` (`sigma_f`, the applied force is unaffected), from ChaCha8 streams 0 and 1 of
//! the scenario's seed.
//!
//! # Integrator
//!
//! Dormand-Prince 5(4) with tolerance 1e-12 (absolute and relative, forces weighted as the
//! displacement they cause through the spring) and steps of at most 2 ms. Guards of the
//! current discrete modes (damper, friction, hard stop, backlash) are checked at four points of
//! each step's dense output; the first crossing is located by Brent's method to 1e-14 s and the
//! step is redone exactly to it. There the modes are chosen by Filippov's rule: the first
//! combination whose guards are positive, or zero and not decreasing along its own flow over
//! 1 us, and the state is projected onto the surface (`v = 0` when stuck, `v = v_th` when
//! sliding). Sample instants and excitation breakpoints are stepped to exactly. Measured:
//! halving the tolerance and step cap changes a record by ~2e-13 m; switch times agree with the
//! piecewise closed form to < 1e-10 s (see `tests/reference.rs`).

mod catalogue;
mod dopri;
mod error;
mod input;
mod label;
mod plant;
mod record;
mod scenario;
mod simulate;

pub use catalogue::{catalogue, core_size, MIN_SNR, NOISE_LEVELS};
pub use error::Error;
pub use label::{EffectLabel, Label, LabelClass};
pub use plant::{Damper, Friction, Lash, Modes, Plant, State, Stop, FA, NX, Q, V, W, X, XM, YB};
pub use record::{effect_rms, generate, generate_with, sample_times, simulate_scenario, Record};
pub use scenario::{
    Effect, Excitation, Noise, ParameterErrors, SampleRate, Scenario, C, FORCING_AMPLITUDE,
    FORCING_PERIOD, G, K, M, X0,
};
pub use simulate::{describe, Event, SimOptions, Stats, Trajectory};
