//! Linear time-periodic (LTP) models for htfid.
//!
//! An LTP system is `x' = A(t) x + B(t) u`, `y = C(t) x + D(t) u` with
//! matrices of period `T`; `wp = 2 pi / T` is the pumping frequency. Time is
//! absolute: `t = 0` is phase 0 of the orbit (the phase 0 of the forcing).
//!
//! - [`PiecewiseLti`]: a periodic system made of time-invariant [`Piece`]s
//!   tiling one period from a start time `tau_0` (pieces wrap modulo `T`),
//!   each with constant `A_i, B_i, C_i, D_i` and a jump `x -> J_i x` at its
//!   start. Built by a validating constructor.
//! - Fourier coefficients, `M(t) = sum_n M_n exp(j n wp t)` with
//!   `M_n = (1/T) int_0^T M(t) exp(-j n wp t) dt`:
//!   [`PiecewiseLti::fourier_coefficient`] and [`square_wave_fourier`] in
//!   closed form, [`fft_fourier`] for sampled periodic matrices.
//! - Floquet analysis: [`expm`] (Pade-13 scaling and squaring),
//!   [`PiecewiseLti::monodromy`], [`Floquet`] multipliers and exponents,
//!   [`PiecewiseLti::liouville_determinant`].
//! - Linearisation of a hybrid system about its limit cycle: [`linearise`] samples
//!   `A(t), B(t), C(t), D(t)` along the orbit of any [`InputOutput`] system built on
//!   `htfid-hybrid` (one scalar input, [`InputOutput::num_outputs`] outputs: `C` is
//!   `p x n`, `D` has length `p`), computes the saltation matrix at every [`Switch`], and
//!   builds the piecewise-LTI approximation (one constant matrix set per chart, averaged over
//!   the chart's interval; the saltations become the jumps), a `p`-output [`PiecewiseLti`]
//!   whose SISO channels [`PiecewiseLti::channel`] selects. The approximation is exact when
//!   every chart's matrices are constant along the orbit (the paper's hopper); when `A(t)`
//!   varies within a chart, `htfid-theory`'s `OrbitHtf` integrates the linearisation along the
//!   orbit instead. For the hopper the damper force
//!   `c x'` vanishes on the switching surface `x' = 0`, so every saltation is the identity
//!   and the clock-driven LTP model is exact to first order; a damper that engages at
//!   `x' > v_th` makes the vector field jump at the switch and `S != I`.
//!
//! ```
//! use htfid_ltp::{Floquet, Piece, PiecewiseLti};
//! use nalgebra::{dmatrix, dvector, RowDVector};
//!
//! // Mass-spring system whose damper is on during [0.2, 0.7) of each period.
//! let (k, c) = (200.0, 2.0);
//! let b = dvector![0.0, 1.0];
//! let out = RowDVector::from_row_slice(&[1.0, 0.0]);
//! let on = Piece::siso(0.5, dmatrix![0.0, 1.0; -k, -c], b.clone(), out.clone(), 0.0);
//! let off = Piece::siso(0.5, dmatrix![0.0, 1.0; -k, 0.0], b, out, 0.0);
//! let lti = PiecewiseLti::new(1.0, 0.2, vec![on, off])?;
//!
//! let floquet = Floquet::new(&lti);
//! assert!(floquet.spectral_radius() < 1.0);
//! // det(monodromy) = exp(int trace A) = exp(-c * 0.5).
//! assert!((floquet.monodromy().determinant() - (-1.0_f64).exp()).abs() < 1e-12);
//! # Ok::<(), htfid_ltp::LtpError>(())
//! ```

mod floquet;
mod fourier;
mod linearise;
mod orbit_tangents;
mod piecewise;
mod tangent;

pub use floquet::{expm, Floquet};
pub use fourier::{fft_fourier, fft_fourier_fn, square_wave_fourier, MatrixFourierSeries};
pub use linearise::{linearise, refuse_grazes, InputOutput, LinearSample, Linearisation, Switch};
pub use orbit_tangents::OrbitTangents;
pub use piecewise::{LtpError, Piece, PiecewiseLti, SystemMatrix};
pub use tangent::{PieceTangent, PiecewiseTangent};
