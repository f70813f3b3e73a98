//! Theoretical harmonic transfer functions (HTFs) of linear time-periodic
//! systems, the ground truth that htfid's estimates are compared with.
//!
//! - [`ExactHtf`]: the exact, untruncated HTF of a SISO
//!   [`PiecewiseLti`](htfid_ltp::PiecewiseLti), state jumps included,
//!   integrated in closed form piece by piece.
//! - [`TruncatedHtf`]: Wereley's harmonic state space truncated to
//!   harmonics `-N..=N`, from a piecewise-LTI system or any
//!   [`FourierCoefficients`] provider such as [`FourierLtp`].
//! - [`OrbitHtf`]: the HTFs of the linearisation of *any* hybrid system
//!   ([`InputOutput`](htfid_ltp::InputOutput)) about its
//!   [`LimitCycle`](htfid_orbit::LimitCycle), several outputs, integrated
//!   along the orbit by `htfid-hybrid`'s integrator with the saltation matrix
//!   at every switch: exact up to the integrator's tolerance also when `A(t)`
//!   varies within a chart, where the piecewise-LTI model is only an
//!   approximation (section "HTFs along the orbit").
//! - [`HarmonicTransferFunction`]: the common interface (`g`, `grid`), and
//!   [`HtfGrid`], values tabulated over frequencies and harmonics.
//!
//! ```
//! use htfid_ltp::{Piece, PiecewiseLti};
//! use htfid_theory::{ExactHtf, HarmonicTransferFunction, TruncatedHtf};
//! use nalgebra::{dmatrix, dvector, RowDVector};
//!
//! // The hopper's error dynamics: damper on during [0.23, 0.71) of T = 1.
//! let (k, c) = (200.0, 2.0);
//! let b = dvector![0.0, 1.0];
//! let y = RowDVector::from_row_slice(&[1.0, 0.0]);
//! let on = Piece::siso(0.48, dmatrix![0.0, 1.0; -k, -c], b.clone(), y.clone(), 0.0);
//! let off = Piece::siso(0.52, dmatrix![0.0, 1.0; -k, 0.0], b, y, 0.0);
//! let lti = PiecewiseLti::new(1.0, 0.23, vec![on, off])?;
//!
//! let exact = ExactHtf::new(&lti)?;
//! let truncated = TruncatedHtf::new(&lti, 40)?;
//! let grid = exact.grid(&[-1, 0, 1], &[5.0, 10.0, 20.0]);
//! let w = 10.0;
//! assert!((exact.g(0, w) - grid.get(1, 1).unwrap()).norm() < 1e-12);
//! assert!((exact.g(1, w) - truncated.g(1, w)).norm() < 1e-3 * grid.max_abs());
//! # Ok::<(), htfid_theory::TheoryError>(())
//! ```
//!
//! [`OrbitHtf`] starts from the hybrid system itself:
//!
//! ```
//! use htfid_hybrid::{HybridSystem, Options};
//! use htfid_ltp::InputOutput;
//! use htfid_orbit::{find_limit_cycle, ShootingOptions};
//! use htfid_theory::{HarmonicTransferFunction, OrbitHtf};
//! use num_complex::Complex64;
//!
//! /// x' = -x + cos(t) + u, y = x: its linearisation is LTI, G_0(jw) = 1 / (1 + jw).
//! struct Forced;
//! impl HybridSystem for Forced {
//!     type Mode = ();
//!     fn dim(&self) -> usize { 1 }
//!     fn vector_field(&self, _: (), t: f64, x: &[f64], dx: &mut [f64]) { dx[0] = -x[0] + t.cos(); }
//! }
//! impl InputOutput for Forced {
//!     fn input_gain(&self, _: (), _t: f64, _x: &[f64], b: &mut [f64]) { b[0] = 1.0; }
//!     fn output_gain(&self, _: (), _t: f64, _x: &[f64], c: &mut [f64]) { c[0] = 1.0; }
//! }
//!
//! let opts = Options::default();
//! let period = 2.0 * std::f64::consts::PI;
//! let cycle = find_limit_cycle(&Forced, (), 0.0, &[0.0], period, &ShootingOptions::default(), &opts)?;
//! let htf = OrbitHtf::new(&Forced, &cycle, &opts)?;
//! let w = 3.0;
//! let want = 1.0 / Complex64::new(1.0, w);
//! assert!((htf.g(0, w) - want).norm() < 1e-9);
//! assert!(htf.g(1, w).norm() < 1e-9);
//! // All outputs and harmonics for one input frequency: Y_k = G_k(j (w_in + k wp)).
//! let y = htf.response(w, &[-1, 0, 1])?;
//! assert!((y[(0, 1)] - want).norm() < 1e-9);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Conventions
//!
//! The system is `x' = A(t) x + B(t) u`, `y = C(t) x + D(t) u` with period
//! `T` and pumping frequency `wp = 2 pi / T`. Time is absolute: `t = 0` is
//! phase 0 of the orbit (phase 0 of the forcing). Fourier coefficients are
//! `A(t) = sum_n A_n exp(j n wp t)`, `A_n = (1/T) int_0^T A(t) exp(-j n wp t) dt`.
//! Frequencies are in rad per time unit.
//!
//! **Estimation convention** (the paper's output equation):
//! `Y(jw) = sum_n G_n(jw) U(jw - j n wp)`. `G_n(jw)` is the response at
//! *output* frequency `w` to input at `w - n wp`: for `u(t) = exp(j w0 t)`
//! the steady state is `y(t) = sum_n G_n(j (w0 + n wp)) exp(j (w0 + n wp) t)`.
//! Every `g(n, w)` in this crate is `G_n(jw)` in this convention.
//!
//! **Relation to Wereley's HTF matrix.** Wereley writes the input as an
//! exponentially modulated periodic signal `u(t) = sum_q u_q exp((s + j q wp) t)`
//! and the output likewise with coefficients `y_p`; harmonic balance gives
//! `y_p = sum_q G_{p,q}(s) u_q`, block `(p, q)` mapping input harmonic `q` to
//! output harmonic `p`. Take `s = jw`, a single input harmonic `q = -n`
//! (frequency `w - n wp`) and read output harmonic `p = 0` (frequency `w`):
//! that is `G_n(jw)`, so `G_n(jw) = G_{0,-n}(jw)`. Taking instead
//! `s = j (w - n wp)`, input harmonic `q = 0` and output harmonic `p = n`
//! describes the same input and output sinusoids, so also
//! `G_n(jw) = G_{n,0}(j (w - n wp))`. (The two agree by the Toeplitz
//! identity `G_{p,q}(s) = G_{p-q,0}(s + j q wp)`: shifting `s` by `j wp`
//! relabels harmonics.)
//!
//! # Truncated harmonic state space
//!
//! Substituting `x = sum_p x_p exp((s + j p wp) t)` into the state equation
//! and collecting `exp((s + j p wp) t)` gives
//! `(s + j p wp) x_p = sum_q A_{p-q} x_q + sum_q B_{p-q} u_q`, i.e.
//! `s X = (A - N) X + B U` with block-Toeplitz `A` (block `(p, q)` = `A_{p-q}`)
//! and `N = blockdiag(j p wp I)`; likewise `Y = C X + D U`, hence
//! `G(s) = C (sI - (A - N))^{-1} B + D`. [`TruncatedHtf`] keeps `|p|, |q| <= N`
//! and reads the middle block row, `G_n(jw) = G_{0,-n}(jw)`. Piecewise-constant
//! matrices have closed-form coefficients
//! `A_n = sum_i A_i (exp(-j n wp tau_{i+1}) - exp(-j n wp tau_i)) / (-j n wp T)`.
//! A state jump `x -> J x` is an impulse in `A(t)` with no such series, so
//! systems with jumps are rejected ([`TheoryError::JumpNotRepresentable`]).
//!
//! **Truncation error.** A switch makes `A(t)` a square wave in time, whose
//! coefficients decay only like `|A_n| ~ 1/n` (`|s_n| <= 1 / (pi |n|)`), so
//! the state harmonics that truncation discards decay algebraically too, and
//! so does the error in `G_n`: no geometric convergence as for smooth `A(t)`
//! (for a single-cosine `A(t)` the error is 8.5e-7 at N = 5 and 3e-17 at
//! N = 10). How fast it decays depends on how many integrations separate the
//! switched entry from the output. In the hopper the switched term
//! `-c s(t) v` drives the velocity, which is continuous with kinks
//! (harmonics `~1/n^2`), and the measured position is one integration
//! further (`~1/n^3`); the truncation error falls like `N^-3`. A switched
//! entry closer to the output decays more slowly. Measured for the
//! hopper-like system (`k = 200, c = 2, m = 1`, damper on `[0.23, 0.71)`,
//! `T = 1`), worst `|G_n^N - G_n| / max|G|` over output frequencies
//! `w in {3, 9, 14, 20, 33}` rad/s (`examples/truncation_table.rs`; the test
//! `truncation_error_table` pins the trend):
//!
//! | N   | n in -10..=10                     | n in -3..=3 |
//! |-----|-----------------------------------|-------------|
//! | 5   | 3.6e-3 (harmonics beyond 5 absent) | 3.5e-4     |
//! | 10  | 4.8e-5                            | 4.8e-5      |
//! | 20  | 5.3e-6                            | 5.3e-6      |
//! | 40  | 7.7e-7                            | 7.7e-7      |
//! | 80  | 9.3e-8                            | 9.3e-8      |
//! | 160 | 1.2e-8                            | 1.2e-8      |
//!
//! The worst case sits at the central harmonics, and each doubling of N
//! gains the factor 8 of `N^-3`. An estimate compared with a truncated HTF
//! therefore inherits a floor of about 5e-5 of max|G| at N = 10; compare
//! with [`ExactHtf`] instead.
//!
//! # Exact HTF of a piecewise-LTI system
//!
//! For the input `u = exp(s t)`, `s = j w_in`, look for the steady state
//! `x(t) = exp(s t) p(t)` with `p` T-periodic. On piece `i`
//! (`[tau_i, tau_{i+1})`, length `h_i`) `p' = (A_i - s I) p + B_i`, and at its
//! start `p(tau_i+) = J_i p(tau_i-)` (the factor `exp(s t)` is continuous).
//! Over one piece, with `r = t - tau_i`,
//! `p(tau_i + r) = exp((A_i - s) r) p(tau_i+) + int_0^r exp((A_i - s) q) dq B_i`.
//! Chaining the pieces over a period gives an affine map
//! `p(tau_0+) -> J_0 p(tau_0 + T-) = Phi(s) p(tau_0+) + psi(s)` with
//! `Phi(s) = exp(-sT) M` and `M` the monodromy matrix from `tau_0+`; periodicity
//! is the linear system `(I - Phi(s)) p(tau_0+) = psi(s)`, singular exactly
//! when `exp(sT)` is a Floquet multiplier: a pole of the HTF (`g` returns NaN
//! only if the solve meets an exactly zero pivot). The output is
//! `y = exp(s t) (C(t) p(t) + D(t))`, so
//! `y(t) = sum_k Y_k exp((s + j k wp) t)` with
//! `Y_k = (1/T) int_{tau_0}^{tau_0 + T} (C(t) p(t) + D(t)) exp(-j k wp t) dt`
//! and `G_k(j (w_in + k wp)) = Y_k`. For the grid point `(w, n)` the input
//! frequency is `w_in = w - n wp`.
//!
//! *Modal method* (default). With `A_i = V diag(lambda) V^{-1}` computed once,
//! in modal coordinates `z = V^{-1} p`, `beta = V^{-1} B_i`, `mu = lambda - s`:
//! `z_j(r) = exp(mu_j r) z_j(0) + r phi1(mu_j r) beta_j` with
//! `phi1(x) = (e^x - 1)/x`. Writing `b = -j k wp h_i` and
//! `c_j = mu_j h_i + b = (lambda_j - j w) h_i`, `Y_k` is `1/T` times the sum
//! over pieces of `exp(-j k wp tau_i) [ sum_j (C_i V)_j ( h phi1(c_j) z_j(0)
//! + h^2 e[0, b, c_j] beta_j ) + D_i h phi1(b) ]`,
//! where `e[0, b, c]` is the second divided difference of the exponential
//! (`int_0^h int_0^r exp(mu q + nu r) dq dr = h^2 e[0, nu h, (mu + nu) h]`,
//! Hermite-Genocchi). `phi1` and the divided differences switch to Taylor
//! series near coincident arguments, so nothing cancels as `mu -> 0`. All
//! exponentials are products of cached factors (`exp(lambda h)`,
//! `exp(-j w h)`, `exp(j n wp h)`), so a grid point costs arithmetic only.
//! Near a defective `A_i` the eigenvalues are only accurate to
//! `~cond(V) eps` and the modal sum cancels terms of size `~cond(V)`, so the
//! modal error grows like `cond(V)^2 eps` (measured ~1e-20 cond^2). Pieces
//! whose eigenvector matrix has condition above 1e4 (modal error ~1e-12), or
//! that are defective, make [`ExactMethod::Auto`] use the
//!
//! *block-exponential method*: per piece, `exp([[A - sI, B], [0, 0]] h)` gives
//! the propagator and forced response, and with `nu = -j k wp`,
//! `exp([[A - s + nu, B, 0], [0, nu, 0], [C, D, 0]] h)` applied to
//! `[p(tau_i+); 1; 0]` ends with `int_0^h exp(nu r) (C p + D) dr` (Van Loan).
//! The two methods share no numerical kernel and are tested against each
//! other and against brute-force simulation.

//!
//! # HTFs along the orbit
//!
//! [`ExactHtf`] is exact for a piecewise-LTI system, and the hopper's
//! linearisation is one (constant `A` per chart, `S = I`). In general `A(t)`
//! varies along the orbit within a chart (a cubic spring, a position-dependent
//! damper), and [`OrbitHtf`] integrates the linearisation instead. Write the
//! steady state as above, `x = exp(s t) q(t)` (`q` is `p` there), `s = j w_in`:
//! `q' = (A(t) - s I) q + B(t)` between switches and `q+ = S q-` at each one,
//! where `A = df/dx`, `B = df/du` are evaluated on the orbit `x_o(t)` as it is
//! integrated and `S` is the saltation matrix (`htfid_orbit::saltation`). Per
//! input frequency, two integrations over one period from the cycle's phase
//! origin `t0` of an augmented hybrid system
//! `[x_o, Re q, Im q, Fourier integrals]`, whose guards are the model's own
//! guards on `x_o` and whose reset applies the model's reset to `x_o` and `S`
//! to `q`:
//!
//! 1. from `q(t0) = 0`, giving `q_part(t0 + T)`;
//! 2. periodicity, `q(t0 + T) = exp(-s T) M q(t0) + q_part(t0 + T) = q(t0)`
//!    with `M` the monodromy (saltations included, recomputed once by
//!    [`OrbitHtf::new`]), is one complex `n x n` solve for `q(t0)`;
//! 3. from that `q(t0)`, integrating also
//!    `I_{o,k} = (1/T) int_{t0}^{t0+T} (C_o q + D_o) exp(-j k wp (t - t0)) dt`
//!    for every output `o` and harmonic `k`; then
//!    `Y_{o,k} = exp(-j k wp t0) I_{o,k} = G_k(j (w_in + k wp))` of output `o`.
//!
//! The Fourier integrals are states of the integrator, so their accuracy is
//! under its error control like the rest (no quadrature grid to choose), and
//! a guard that moves in time enters the saltation through
//! `HybridSystem::guard_time_derivative`. There is no truncation and no
//! approximation of `A(t)`: the error is the integrator's (measured for the
//! hopper, worst over `n = -10..=10` and 200 frequencies in `1..40` rad/s,
//! against [`ExactHtf`]: `2e-10` of `max|G|` at the default `rtol = 1e-10`,
//! `1.3e-12` at `rtol = 1e-12`). The cost is that of the integration: each
//! grid point `(w, n)` has its own input frequency `w - n wp`, and points that
//! share one share the integrations ([`OrbitHtf::grids`]). For the hopper
//! that is 0.4 to 0.5 ms per value at the default tolerance, against 0.2 us
//! for [`ExactHtf`] (`cargo bench -p htfid-theory --bench orbit_htf`), so
//! prefer [`ExactHtf`] where the linearisation is piecewise-LTI exactly.
//!
//! **Orbits that slide.** The linearisation through a sliding segment (a mass stuck by
//! Coulomb friction: the saltation matrices at the start and end of sliding and the variation
//! of the Filippov field) is not implemented. [`OrbitHtf::new`], and through
//! `htfid_ltp::linearise` [`LinearisedHtf::new`], refuse an orbit with sliding intervals with
//! [`TheoryError::Ltp`]`(LtpError::SlidingOrbit)`, naming the first interval, rather than give
//! an HTF that leaves the sticking out.
mod about_orbit;
mod coefficients;
mod error;
mod exact;
mod grid;
mod kernels;
mod orbit;
mod truncated;

pub use about_orbit::{HtfChannel, HtfMethod, LinearisedHtf};
pub use coefficients::{FourierCoefficients, FourierLtp};
pub use error::TheoryError;
pub use exact::{ExactHtf, ExactMethod};
pub use grid::{HarmonicTransferFunction, HtfGrid, Tabulated};
pub use orbit::OrbitHtf;
pub use truncated::TruncatedHtf;
