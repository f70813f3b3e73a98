//! Excitation signals and experiment design for harmonic transfer function
//! (HTF) identification of systems with a T-periodic limit cycle.
//!
//! # Main types
//!
//! - [`Signal`]: a real function of absolute time, with sampling helpers.
//! - Sweeps: [`LinearChirp`], [`LogChirp`], and [`PaperChirp`] (the
//!   reference paper's printed formula).
//! - [`PhaseShiftedTrain`]: K copies of a waveform, copy k delayed by
//!   `k T / K` against the forcing; [`alias_map`] says which harmonics such a
//!   train cannot separate.
//! - [`Multisine`]: periodic sum of cosines on integer bins, with Schroeder or
//!   seeded random phases, RMS/peak scaling and fast uniform sampling.
//! - [`design_htf_multisine`]: from a [`DesignSpec`] (period, harmonics,
//!   band, spacing, level, budget) to a [`Design`] whose output bins never
//!   alias between harmonics, with its record layout ([`Block`]), the signal
//!   to apply ([`DesignInput`]), where to read each `G_n` ([`HtfPoint`]) and
//!   a [`DesignReport`].
//!
//! # Conventions
//!
//! - Time in seconds. Every signal is a function of **absolute** time `t`;
//!   `t = 0` is phase 0 of the periodic forcing, whose period is `T` and
//!   pumping frequency `wp = 2 pi / T` (rad/s).
//! - Chirp band parameters and multisine band selections are in **Hz**
//!   (fields end in `_hz`); everything named `omega`, the design band and
//!   the design spacing are in **rad/s**.
//! - Multisine lines are cosines: `A cos(2 pi b t / Tm + phi)`, `b >= 1` an
//!   integer bin of a period-`Tm` grid. An N-sample DFT of one period,
//!   `X[c] = sum_k x_k exp(-j 2 pi c k / N)`, gives `X[b] = N A exp(j phi) / 2`.
//! - HTF index convention (the paper's):
//!   `Y(jw) = sum_n G_n(jw) U(jw - j n wp)`, so `G_n` carries input at
//!   `w - n wp` to output at `w`, and is evaluated at the *output* frequency.
//!   For a real system `G_n(-jw) = conj(G_{-n}(jw))`.
//!
//! # The paper's chirp
//!
//! The paper prints `u(t) = 0.004 sin(14 pi t^2 / 30)`, `0 <= t < 30`, and
//! says the sweep covers (0, 7] Hz. The printed formula's instantaneous
//! frequency is `(1 / 2 pi) d/dt (14 pi t^2 / 30) = 14 t / 30` Hz, which
//! reaches **14 Hz** at `t = 30 s`. [`PaperChirp`] implements the formula as
//! printed (equal to `LinearChirp::new(0.0, 14.0, 30.0, 0.004)`); the text's
//! sweep is `LinearChirp::new(0.0, 7.0, 30.0, 0.004)`.
//!
//! # Example
//!
//! The headline design: T = 1 s, `|n| <= 3`, 1..40 rad/s at spacing
//! <= 0.45 rad/s, peak 0.004, sign reversal, at most 600 s.
//!
//! ```
//! use htfid_excite::{
//!     design_htf_multisine, Amplitude, DesignSpec, EvenOrder, PhaseRule, Signal,
//! };
//!
//! let design = design_htf_multisine(DesignSpec {
//!     period: 1.0,
//!     max_harmonic: 3,
//!     omega_lo: 1.0,
//!     omega_hi: 40.0,
//!     spacing: 0.45,
//!     amplitude: Amplitude::Peak(0.004),
//!     phases: PhaseRule::Schroeder,
//!     even_order: EvenOrder::SignReversal,
//!     settle: 10.0,
//!     start: 30.0,
//!     max_record: 600.0,
//! })?;
//! let report = design.report();
//! assert!(report.harmonics.iter().all(|c| c.meets_target));
//! assert!(design.total_duration() <= 600.0);
//!
//! // The signal to feed the simulation, sampled at 1 kHz.
//! let u = design.input().sample_uniform(0.0, 1e-3, 10_000);
//! assert_eq!(u.len(), 10_000);
//! println!("{report}");
//! # Ok::<(), htfid_excite::ExciteError>(())
//! ```

mod chirp;
mod design;
mod error;
mod input;
mod multisine;
mod report;
mod signal;
mod train;

pub use chirp::{LinearChirp, LogChirp, PaperChirp};
pub use design::{
    design_htf_multisine, design_size, BinOwner, Block, Branch, Design, DesignLine, DesignSize,
    DesignSpec, EvenOrder, HtfPoint, Polarity,
};
pub use error::ExciteError;
pub use input::DesignInput;
pub use multisine::{Amplitude, BinSelection, Line, Multisine, Parity, PhaseRule};
pub use report::{DesignReport, HarmonicCoverage};
pub use signal::Signal;
pub use train::{
    alias_map, alias_sizes, AliasEntry, AliasSize, AliasSizes, AliasedHarmonic, PhaseShiftedTrain,
    Segment, TrainLayout,
};
