//! Piecewise-LTI periodic systems and the crate's error type.

use nalgebra::{DMatrix, DVector, RowDVector};

/// Errors of the LTP model layer.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum LtpError {
    /// Integration along the orbit failed while linearising.
    #[error("integration along the orbit failed: {0}")]
    Integration(String),
    /// The orbit slides along a switching surface (a mass stuck by friction, for instance);
    /// the linearisation through sliding (its saltation matrices and the variation of the
    /// Filippov field) is not implemented, so no linear model is built rather than a wrong one.
    #[error(
        "the orbit slides along guard {guard} from t = {start} s to t = {end} s \
         ({intervals} sliding interval(s) per period); linearisation through sliding is not \
         implemented, so no LTP model or HTF can be given for this orbit"
    )]
    SlidingOrbit {
        /// The surface of the first interval: guard index in its chart.
        guard: usize,
        /// Start of the first interval (s).
        start: f64,
        /// End of the first interval (s).
        end: f64,
        /// Number of sliding intervals in the period.
        intervals: usize,
    },
    /// The orbit touches a guard without crossing it (a graze): there the motion is not a
    /// smooth function of its initial state (a small input makes it cross, or not), so no
    /// linear model describes it, and none is built rather than a wrong one.
    #[error(
        "the orbit grazes guard {guard} at t = {time} s (it touches the guard and turns back \
         without crossing): at a graze the motion does not depend linearly on a small input, \
         so no LTP model or HTF can be given for this orbit; move the guard or the orbit so \
         that the orbit crosses it clearly or stays clear of it"
    )]
    GrazingOrbit {
        /// The guard grazed: its index in the chart.
        guard: usize,
        /// Time of the first graze in the period (s).
        time: f64,
    },
    /// The period must be finite and strictly positive.
    #[error("period must be finite and > 0 (got {period})")]
    InvalidPeriod {
        /// The rejected period.
        period: f64,
    },
    /// The start time of the first piece must be finite.
    #[error("start time of the first piece must be finite (got {start})")]
    InvalidStart {
        /// The rejected start time.
        start: f64,
    },
    /// A system needs at least one piece.
    #[error("a piecewise-LTI system needs at least one piece")]
    NoPieces,
    /// A piece duration must be finite and strictly positive.
    #[error("piece {piece}: duration must be finite and > 0 (got {duration})")]
    InvalidDuration {
        /// Index of the offending piece.
        piece: usize,
        /// The rejected duration.
        duration: f64,
    },
    /// The piece durations must add up to the period.
    #[error("piece durations sum to {sum}, but the period is {period}")]
    DurationsDoNotSumToPeriod {
        /// Sum of all piece durations.
        sum: f64,
        /// The period.
        period: f64,
    },
    /// A matrix has the wrong shape.
    #[error("piece {piece}: matrix {matrix} is {found_rows}x{found_cols}, expected {expected_rows}x{expected_cols}")]
    WrongShape {
        /// Index of the offending piece.
        piece: usize,
        /// Which matrix (`"A"`, `"B"`, `"C"`, `"D"` or `"J"`; a tangent's `"dA"` ... `"dJ"`,
        /// `"dtau"`).
        matrix: &'static str,
        /// Expected number of rows.
        expected_rows: usize,
        /// Expected number of columns.
        expected_cols: usize,
        /// Actual number of rows.
        found_rows: usize,
        /// Actual number of columns.
        found_cols: usize,
    },
    /// A matrix entry is NaN or infinite.
    #[error("piece {piece}: matrix {matrix} has a non-finite entry at ({row}, {col})")]
    NonFinite {
        /// Index of the offending piece.
        piece: usize,
        /// Which matrix (`"A"`, `"B"`, `"C"`, `"D"` or `"J"`; a tangent's `"dA"` ... `"dJ"`,
        /// `"dtau"`).
        matrix: &'static str,
        /// Row of the first non-finite entry.
        row: usize,
        /// Column of the first non-finite entry.
        col: usize,
    },
    /// The state dimension must be at least one.
    #[error("the state dimension must be at least 1")]
    EmptyState,
    /// A tangent ([`crate::PiecewiseTangent`]) with another number of pieces than its system.
    #[error("a tangent of {found} pieces for a system of {expected}")]
    TangentPieces {
        /// Pieces of the system.
        expected: usize,
        /// Pieces of the tangent.
        found: usize,
    },
    /// Sampled Fourier analysis needs samples of equal shape.
    #[error(
        "sample {index} is {found_rows}x{found_cols}, expected {expected_rows}x{expected_cols}"
    )]
    SampleShapeMismatch {
        /// Index of the offending sample.
        index: usize,
        /// Expected number of rows (shape of sample 0).
        expected_rows: usize,
        /// Expected number of columns (shape of sample 0).
        expected_cols: usize,
        /// Actual number of rows.
        found_rows: usize,
        /// Actual number of columns.
        found_cols: usize,
    },
    /// A requested input/output channel does not exist.
    #[error("channel (output {output}, input {input}) out of range for a system with {n_outputs} outputs and {n_inputs} inputs")]
    ChannelOutOfRange {
        /// Requested output index.
        output: usize,
        /// Requested input index.
        input: usize,
        /// Number of outputs of the system.
        n_outputs: usize,
        /// Number of inputs of the system.
        n_inputs: usize,
    },
    /// A sample of a periodic matrix function is NaN or infinite.
    #[error("sample {index} has a non-finite entry at ({row}, {col})")]
    NonFiniteSample {
        /// Index of the offending sample.
        index: usize,
        /// Row of the first non-finite entry.
        row: usize,
        /// Column of the first non-finite entry.
        col: usize,
    },
    /// Sampled Fourier analysis needs at least one sample.
    #[error("need at least one sample per period (got {count})")]
    TooFewSamples {
        /// Number of samples given.
        count: usize,
    },
}

/// One time-invariant piece of a [`PiecewiseLti`].
///
/// On its interval the system is `x' = A x + B u`, `y = C x + D u`. The jump
/// matrix `J` acts once at the start of the piece: `x(tau_i+) = J x(tau_i-)`
/// (the identity unless set with [`Piece::with_jump`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Piece {
    duration: f64,
    a: DMatrix<f64>,
    b: DMatrix<f64>,
    c: DMatrix<f64>,
    d: DMatrix<f64>,
    jump: Option<DMatrix<f64>>,
}

impl Piece {
    /// A piece of length `duration` with `A` (n x n), `B` (n x m), `C` (p x n)
    /// and `D` (p x m). Shapes and values are checked by [`PiecewiseLti::new`].
    pub fn new(
        duration: f64,
        a: DMatrix<f64>,
        b: DMatrix<f64>,
        c: DMatrix<f64>,
        d: DMatrix<f64>,
    ) -> Self {
        Self {
            duration,
            a,
            b,
            c,
            d,
            jump: None,
        }
    }

    /// A single-input single-output piece: `B` is a column, `C` a row, `D` a scalar.
    pub fn siso(
        duration: f64,
        a: DMatrix<f64>,
        b: DVector<f64>,
        c: RowDVector<f64>,
        d: f64,
    ) -> Self {
        let n_b = b.len();
        let n_c = c.len();
        Self::new(
            duration,
            a,
            DMatrix::from_column_slice(n_b, 1, b.as_slice()),
            DMatrix::from_row_slice(1, n_c, c.as_slice()),
            DMatrix::from_element(1, 1, d),
        )
    }

    /// Sets the jump matrix applied at the start of this piece.
    #[must_use]
    pub fn with_jump(mut self, jump: DMatrix<f64>) -> Self {
        self.jump = Some(jump);
        self
    }

    /// Length of the piece.
    pub fn duration(&self) -> f64 {
        self.duration
    }

    /// State matrix `A_i`.
    pub fn a(&self) -> &DMatrix<f64> {
        &self.a
    }

    /// Input matrix `B_i`.
    pub fn b(&self) -> &DMatrix<f64> {
        &self.b
    }

    /// Output matrix `C_i`.
    pub fn c(&self) -> &DMatrix<f64> {
        &self.c
    }

    /// Feedthrough matrix `D_i`.
    pub fn d(&self) -> &DMatrix<f64> {
        &self.d
    }

    /// Jump matrix at the start of the piece (`None` means the identity).
    pub fn jump(&self) -> Option<&DMatrix<f64>> {
        self.jump.as_ref()
    }

    /// Jump matrix at the start of the piece, the identity materialised.
    pub fn jump_matrix(&self) -> DMatrix<f64> {
        self.jump
            .clone()
            .unwrap_or_else(|| DMatrix::identity(self.a.nrows(), self.a.nrows()))
    }

    /// The matrix selected by `which`.
    pub fn matrix(&self, which: SystemMatrix) -> &DMatrix<f64> {
        match which {
            SystemMatrix::A => &self.a,
            SystemMatrix::B => &self.b,
            SystemMatrix::C => &self.c,
            SystemMatrix::D => &self.d,
        }
    }
}

/// Names one of the four state-space matrices of `x' = A x + B u, y = C x + D u`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum SystemMatrix {
    /// State matrix (n x n).
    A,
    /// Input matrix (n x m).
    B,
    /// Output matrix (p x n).
    C,
    /// Feedthrough matrix (p x m).
    D,
}

/// A `T`-periodic system made of time-invariant pieces.
///
/// Piece `i` is active on `[tau_i, tau_{i+1})` with `tau_{i+1} = tau_i + h_i`,
/// `tau_0 = start` and `tau_N = start + T`: the pieces tile one period
/// starting at `start`, which may be anywhere (it is reduced to `[0, T)`).
/// If `start > 0` the last piece wraps around: it covers `[tau_{N-1}, T)`
/// and `[0, start)` of every period. Times are absolute (phase 0 of the orbit
/// at `t = 0`).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(
    feature = "serde",
    serde(try_from = "raw::PiecewiseLtiRaw", into = "raw::PiecewiseLtiRaw")
)]
pub struct PiecewiseLti {
    period: f64,
    start: f64,
    pieces: Vec<Piece>,
    /// `tau_0 .. tau_N` (length `N + 1`), `tau_N = tau_0 + T` exactly.
    boundaries: Vec<f64>,
    n_states: usize,
    n_inputs: usize,
    n_outputs: usize,
}

/// Relative tolerance on `sum(h_i) = T`: durations usually come from
/// subtracting event times, which costs a few ulps each.
const DURATION_SUM_RTOL: f64 = 1e-9;

impl PiecewiseLti {
    /// Validates and builds a piecewise-LTI system of period `period` whose
    /// first piece starts at `start` (any finite time, reduced modulo the
    /// period).
    ///
    /// Checks: `period > 0`, at least one piece, each duration `> 0`, the
    /// durations sum to the period (relative tolerance 1e-9; the last
    /// boundary is then set to exactly `start + period`), all matrices
    /// finite with consistent shapes (`A` n x n with n >= 1, `B` n x m,
    /// `C` p x n, `D` p x m, `J` n x n).
    pub fn new(period: f64, start: f64, pieces: Vec<Piece>) -> Result<Self, LtpError> {
        if !(period.is_finite() && period > 0.0) {
            return Err(LtpError::InvalidPeriod { period });
        }
        if !start.is_finite() {
            return Err(LtpError::InvalidStart { start });
        }
        let first = pieces.first().ok_or(LtpError::NoPieces)?;
        let n = first.a.nrows();
        let m = first.b.ncols();
        let p = first.c.nrows();
        if n == 0 {
            return Err(LtpError::EmptyState);
        }
        let mut sum = 0.0;
        for (i, piece) in pieces.iter().enumerate() {
            if !(piece.duration.is_finite() && piece.duration > 0.0) {
                return Err(LtpError::InvalidDuration {
                    piece: i,
                    duration: piece.duration,
                });
            }
            sum += piece.duration;
            check_matrix(i, "A", &piece.a, n, n)?;
            check_matrix(i, "B", &piece.b, n, m)?;
            check_matrix(i, "C", &piece.c, p, n)?;
            check_matrix(i, "D", &piece.d, p, m)?;
            if let Some(j) = &piece.jump {
                check_matrix(i, "J", j, n, n)?;
            }
        }
        if (sum - period).abs() > DURATION_SUM_RTOL * period {
            return Err(LtpError::DurationsDoNotSumToPeriod { sum, period });
        }
        let start = start.rem_euclid(period);
        // rem_euclid can round up to exactly `period` for tiny negative inputs.
        let start = if start >= period { 0.0 } else { start };
        let mut boundaries = Vec::with_capacity(pieces.len() + 1);
        let mut t = start;
        boundaries.push(t);
        for piece in &pieces[..pieces.len() - 1] {
            t += piece.duration;
            boundaries.push(t);
        }
        boundaries.push(start + period);
        Ok(Self {
            period,
            start,
            pieces,
            boundaries,
            n_states: n,
            n_inputs: m,
            n_outputs: p,
        })
    }

    /// A time-invariant system viewed as `T`-periodic (one piece).
    pub fn lti(
        period: f64,
        a: DMatrix<f64>,
        b: DMatrix<f64>,
        c: DMatrix<f64>,
        d: DMatrix<f64>,
    ) -> Result<Self, LtpError> {
        Self::new(period, 0.0, vec![Piece::new(period, a, b, c, d)])
    }

    /// The period `T`.
    pub fn period(&self) -> f64 {
        self.period
    }

    /// The pumping frequency `wp = 2 pi / T` in rad per time unit.
    pub fn pumping_frequency(&self) -> f64 {
        std::f64::consts::TAU / self.period
    }

    /// Start `tau_0` of the first piece, in `[0, T)`.
    pub fn start(&self) -> f64 {
        self.start
    }

    /// The pieces in time order from `tau_0`.
    pub fn pieces(&self) -> &[Piece] {
        &self.pieces
    }

    /// Piece boundaries `tau_0, ..., tau_N` with `tau_N = tau_0 + T`; values
    /// may exceed `T` (they are not reduced modulo `T`).
    pub fn boundaries(&self) -> &[f64] {
        &self.boundaries
    }

    /// Start time `tau_i` of piece `i` (not reduced modulo `T`).
    ///
    /// # Panics
    /// If `i >= self.pieces().len()`.
    pub fn piece_start(&self, i: usize) -> f64 {
        self.boundaries[i]
    }

    /// Number of states n.
    pub fn n_states(&self) -> usize {
        self.n_states
    }

    /// Number of inputs m.
    pub fn n_inputs(&self) -> usize {
        self.n_inputs
    }

    /// Number of outputs p.
    pub fn n_outputs(&self) -> usize {
        self.n_outputs
    }

    /// Whether any piece has a jump matrix other than the identity.
    pub fn has_jumps(&self) -> bool {
        self.first_jump().is_some()
    }

    /// Index of the first piece whose jump matrix differs from the identity.
    pub fn first_jump(&self) -> Option<usize> {
        self.pieces.iter().position(|piece| {
            piece
                .jump
                .as_ref()
                .is_some_and(|j| j != &DMatrix::identity(self.n_states, self.n_states))
        })
    }

    /// Index of the piece active at absolute time `t` (any finite `t`;
    /// intervals are closed on the left). Returns `None` for non-finite `t`.
    pub fn piece_index_at(&self, t: f64) -> Option<usize> {
        if !t.is_finite() {
            return None;
        }
        // Map t into [tau_0, tau_0 + T).
        let mut u = self.start + (t - self.start).rem_euclid(self.period);
        if u >= self.start + self.period {
            u = self.start;
        }
        let upper = self.boundaries[1..].partition_point(|&b| b <= u);
        Some(upper.min(self.pieces.len() - 1))
    }

    /// The piece active at absolute time `t` (`None` for non-finite `t`).
    pub fn piece_at(&self, t: f64) -> Option<&Piece> {
        self.piece_index_at(t).map(|i| &self.pieces[i])
    }

    /// Restricts the system to one input column and one output row (a SISO
    /// channel), keeping durations and jumps.
    pub fn channel(&self, output: usize, input: usize) -> Result<Self, LtpError> {
        if output >= self.n_outputs || input >= self.n_inputs {
            return Err(LtpError::ChannelOutOfRange {
                output,
                input,
                n_outputs: self.n_outputs,
                n_inputs: self.n_inputs,
            });
        }
        let pieces = self
            .pieces
            .iter()
            .map(|piece| Piece {
                duration: piece.duration,
                a: piece.a.clone(),
                b: piece.b.columns(input, 1).into_owned(),
                c: piece.c.rows(output, 1).into_owned(),
                d: piece.d.view((output, input), (1, 1)).into_owned(),
                jump: piece.jump.clone(),
            })
            .collect();
        Self::new(self.period, self.start, pieces)
    }
}

pub(crate) fn check_matrix(
    piece: usize,
    matrix: &'static str,
    m: &DMatrix<f64>,
    rows: usize,
    cols: usize,
) -> Result<(), LtpError> {
    if m.nrows() != rows || m.ncols() != cols {
        return Err(LtpError::WrongShape {
            piece,
            matrix,
            expected_rows: rows,
            expected_cols: cols,
            found_rows: m.nrows(),
            found_cols: m.ncols(),
        });
    }
    for c in 0..cols {
        for r in 0..rows {
            if !m[(r, c)].is_finite() {
                return Err(LtpError::NonFinite {
                    piece,
                    matrix,
                    row: r,
                    col: c,
                });
            }
        }
    }
    Ok(())
}

#[cfg(feature = "serde")]
mod raw {
    //! Serialised form: deserialising goes through [`PiecewiseLti::new`].

    use super::{LtpError, Piece, PiecewiseLti};
    use nalgebra::DMatrix;

    #[derive(serde::Serialize, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    pub(super) struct PieceRaw {
        duration: f64,
        a: DMatrix<f64>,
        b: DMatrix<f64>,
        c: DMatrix<f64>,
        d: DMatrix<f64>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        jump: Option<DMatrix<f64>>,
    }

    #[derive(serde::Serialize, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    pub(super) struct PiecewiseLtiRaw {
        period: f64,
        start: f64,
        pieces: Vec<PieceRaw>,
    }

    impl TryFrom<PiecewiseLtiRaw> for PiecewiseLti {
        type Error = LtpError;

        fn try_from(raw: PiecewiseLtiRaw) -> Result<Self, LtpError> {
            let pieces = raw
                .pieces
                .into_iter()
                .map(|p| Piece {
                    duration: p.duration,
                    a: p.a,
                    b: p.b,
                    c: p.c,
                    d: p.d,
                    jump: p.jump,
                })
                .collect();
            PiecewiseLti::new(raw.period, raw.start, pieces)
        }
    }

    impl From<PiecewiseLti> for PiecewiseLtiRaw {
        fn from(lti: PiecewiseLti) -> Self {
            Self {
                period: lti.period,
                start: lti.start,
                pieces: lti
                    .pieces
                    .into_iter()
                    .map(|p| PieceRaw {
                        duration: p.duration,
                        a: p.a,
                        b: p.b,
                        c: p.c,
                        d: p.d,
                        jump: p.jump,
                    })
                    .collect(),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::dmatrix;

    fn piece(duration: f64) -> Piece {
        Piece::new(
            duration,
            dmatrix![0.0, 1.0; -4.0, -0.1],
            dmatrix![0.0; 1.0],
            dmatrix![1.0, 0.0],
            dmatrix![0.0],
        )
    }

    #[test]
    fn constructor_validates() {
        assert_eq!(
            PiecewiseLti::new(0.0, 0.0, vec![piece(1.0)]),
            Err(LtpError::InvalidPeriod { period: 0.0 })
        );
        assert_eq!(PiecewiseLti::new(1.0, 0.0, vec![]), Err(LtpError::NoPieces));
        assert!(matches!(
            PiecewiseLti::new(1.0, f64::NAN, vec![piece(1.0)]),
            Err(LtpError::InvalidStart { .. })
        ));
        assert_eq!(
            PiecewiseLti::new(1.0, 0.0, vec![piece(1.2), piece(-0.2)]),
            Err(LtpError::InvalidDuration {
                piece: 1,
                duration: -0.2
            })
        );
        assert!(matches!(
            PiecewiseLti::new(1.0, 0.0, vec![piece(0.5), piece(0.4)]),
            Err(LtpError::DurationsDoNotSumToPeriod { .. })
        ));
        let bad_b = Piece::new(
            1.0,
            dmatrix![0.0, 1.0; -4.0, -0.1],
            dmatrix![0.0; 1.0; 2.0],
            dmatrix![1.0, 0.0],
            dmatrix![0.0],
        );
        assert_eq!(
            PiecewiseLti::new(1.0, 0.0, vec![bad_b]),
            Err(LtpError::WrongShape {
                piece: 0,
                matrix: "B",
                expected_rows: 2,
                expected_cols: 1,
                found_rows: 3,
                found_cols: 1
            })
        );
        let nan_a = Piece::new(
            1.0,
            dmatrix![0.0, 1.0; f64::NAN, -0.1],
            dmatrix![0.0; 1.0],
            dmatrix![1.0, 0.0],
            dmatrix![0.0],
        );
        assert_eq!(
            PiecewiseLti::new(1.0, 0.0, vec![nan_a]),
            Err(LtpError::NonFinite {
                piece: 0,
                matrix: "A",
                row: 1,
                col: 0
            })
        );
        let bad_jump = piece(1.0).with_jump(dmatrix![1.0]);
        assert!(matches!(
            PiecewiseLti::new(1.0, 0.0, vec![bad_jump]),
            Err(LtpError::WrongShape { matrix: "J", .. })
        ));
        // Rounding in the durations is tolerated.
        assert!(PiecewiseLti::new(1.0, 0.0, vec![piece(0.1 + 0.2), piece(0.7)]).is_ok());
    }

    #[test]
    fn pieces_wrap_modulo_the_period() {
        let lti = PiecewiseLti::new(2.0, -0.5, vec![piece(1.0), piece(0.6), piece(0.4)]).unwrap();
        // start -0.5 -> 1.5: pieces [1.5, 2.5), [2.5, 3.1), [3.1, 3.5).
        assert!((lti.start() - 1.5).abs() < 1e-15);
        assert!((lti.boundaries()[3] - 3.5).abs() < 1e-15);
        let cases = [
            (1.5, 0),
            (1.99, 0),
            (0.0, 0),
            (0.49, 0),
            (0.5, 1),
            (1.09, 1),
            (1.1, 2),
            (1.49, 2),
            (-0.6, 2),
            (7.5, 0),
        ];
        for (t, want) in cases {
            assert_eq!(lti.piece_index_at(t), Some(want), "t = {t}");
        }
        assert_eq!(lti.piece_index_at(f64::INFINITY), None);
    }

    #[test]
    fn jumps_and_channels() {
        let lti = PiecewiseLti::new(
            1.0,
            0.0,
            vec![
                piece(0.5).with_jump(dmatrix![1.0, 0.0; 0.0, 1.0]),
                piece(0.5),
            ],
        )
        .unwrap();
        assert!(!lti.has_jumps());
        let lti = PiecewiseLti::new(
            1.0,
            0.0,
            vec![
                piece(0.5),
                piece(0.5).with_jump(dmatrix![1.0, 0.0; 0.3, 1.0]),
            ],
        )
        .unwrap();
        assert_eq!(lti.first_jump(), Some(1));
        let mimo = PiecewiseLti::lti(
            1.0,
            dmatrix![-1.0],
            dmatrix![1.0, 2.0],
            dmatrix![3.0; 4.0],
            dmatrix![5.0, 6.0; 7.0, 8.0],
        )
        .unwrap();
        let ch = mimo.channel(1, 0).unwrap();
        assert_eq!((ch.n_inputs(), ch.n_outputs()), (1, 1));
        let p = &ch.pieces()[0];
        assert!((p.b()[(0, 0)] - 1.0).abs() < 1e-15);
        assert!((p.c()[(0, 0)] - 4.0).abs() < 1e-15);
        assert!((p.d()[(0, 0)] - 7.0).abs() < 1e-15);
        assert_eq!(
            mimo.channel(2, 0),
            Err(LtpError::ChannelOutOfRange {
                output: 2,
                input: 0,
                n_outputs: 2,
                n_inputs: 2
            })
        );
    }

    #[cfg(feature = "serde")]
    #[test]
    fn serde_round_trip_revalidates() {
        let lti = PiecewiseLti::new(
            1.0,
            0.3,
            vec![
                piece(0.5).with_jump(dmatrix![1.0, 0.0; 0.3, 1.0]),
                piece(0.5),
            ],
        )
        .unwrap();
        let json = serde_json::to_string(&lti).unwrap();
        let back: PiecewiseLti = serde_json::from_str(&json).unwrap();
        assert_eq!(back, lti);
        let broken = json.replace("\"period\":1.0", "\"period\":2.0");
        let err = serde_json::from_str::<PiecewiseLti>(&broken).unwrap_err();
        assert!(err.to_string().contains("piece durations sum to"), "{err}");
    }
}
