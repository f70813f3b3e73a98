//! Directions of change of a piecewise-LTI system: what a parameter moves.

use nalgebra::DMatrix;

use crate::piecewise::{LtpError, Piece, PiecewiseLti};

/// How one piece of a [`PiecewiseLti`] changes along a direction: the rates of change of its
/// matrices, of its start jump, and of the time its piece starts.
///
/// A parameter `p` of a model moves every piece of its linearisation: `dA/dp`, `dB/dp`, ...,
/// and moves the switches that bound the pieces. A moved start `tau_i` lengthens the piece
/// before it and shortens this one; the period stays fixed, so moving the first piece's start
/// also moves the end of the last.
#[derive(Debug, Clone, PartialEq)]
pub struct PieceTangent {
    /// `dA` (n x n).
    pub a: DMatrix<f64>,
    /// `dB` (n x m).
    pub b: DMatrix<f64>,
    /// `dC` (p x n).
    pub c: DMatrix<f64>,
    /// `dD` (p x m).
    pub d: DMatrix<f64>,
    /// `dJ` of the jump at the piece's start (n x n; zero for a jump that does not change).
    pub jump: DMatrix<f64>,
    /// `d tau_i`: how fast the piece's start moves.
    pub start: f64,
}

/// A direction of change of a [`PiecewiseLti`]: one [`PieceTangent`] per piece, in order.
#[derive(Debug, Clone, PartialEq)]
pub struct PiecewiseTangent {
    pieces: Vec<PieceTangent>,
}

impl PiecewiseTangent {
    /// A tangent of `lti` from its pieces' tangents, checked: one per piece, each of the
    /// piece's shapes, every entry finite.
    ///
    /// # Errors
    /// [`LtpError::TangentPieces`], [`LtpError::WrongShape`] or [`LtpError::NonFinite`] naming the
    /// piece and the matrix (`"dA"`, `"dB"`, `"dC"`, `"dD"`, `"dJ"`, `"dtau"`).
    pub fn new(lti: &PiecewiseLti, pieces: Vec<PieceTangent>) -> Result<Self, LtpError> {
        let tangent = Self { pieces };
        tangent.check(lti)?;
        Ok(tangent)
    }

    /// Whether this tangent fits `lti` ([`PiecewiseTangent::new`]'s checks; the pieces may
    /// have been edited through [`PiecewiseTangent::pieces_mut`] since).
    ///
    /// # Errors
    /// As [`PiecewiseTangent::new`].
    pub fn check(&self, lti: &PiecewiseLti) -> Result<(), LtpError> {
        let pieces = &self.pieces;
        if pieces.len() != lti.pieces().len() {
            return Err(LtpError::TangentPieces {
                expected: lti.pieces().len(),
                found: pieces.len(),
            });
        }
        let (n, m, p) = (lti.n_states(), lti.n_inputs(), lti.n_outputs());
        for (i, t) in pieces.iter().enumerate() {
            crate::piecewise::check_matrix(i, "dA", &t.a, n, n)?;
            crate::piecewise::check_matrix(i, "dB", &t.b, n, m)?;
            crate::piecewise::check_matrix(i, "dC", &t.c, p, n)?;
            crate::piecewise::check_matrix(i, "dD", &t.d, p, m)?;
            crate::piecewise::check_matrix(i, "dJ", &t.jump, n, n)?;
            if !t.start.is_finite() {
                return Err(LtpError::NonFinite {
                    piece: i,
                    matrix: "dtau",
                    row: 0,
                    col: 0,
                });
            }
        }
        Ok(())
    }

    /// The tangent that moves nothing.
    pub fn zero(lti: &PiecewiseLti) -> Self {
        let (n, m, p) = (lti.n_states(), lti.n_inputs(), lti.n_outputs());
        let piece = PieceTangent {
            a: DMatrix::zeros(n, n),
            b: DMatrix::zeros(n, m),
            c: DMatrix::zeros(p, n),
            d: DMatrix::zeros(p, m),
            jump: DMatrix::zeros(n, n),
            start: 0.0,
        };
        Self {
            pieces: vec![piece; lti.pieces().len()],
        }
    }

    /// The pieces' tangents.
    pub fn pieces(&self) -> &[PieceTangent] {
        &self.pieces
    }

    /// The pieces' tangents, to fill in.
    pub fn pieces_mut(&mut self) -> &mut [PieceTangent] {
        &mut self.pieces
    }

    /// The tangent of the channel from `input` to `output`, as [`PiecewiseLti::channel`]
    /// selects it (indices are not checked here; `channel` of the system checks them).
    pub fn channel(&self, output: usize, input: usize) -> Self {
        Self {
            pieces: self
                .pieces
                .iter()
                .map(|t| PieceTangent {
                    a: t.a.clone(),
                    b: t.b.columns(input, 1).into_owned(),
                    c: t.c.rows(output, 1).into_owned(),
                    d: t.d.view((output, input), (1, 1)).into_owned(),
                    jump: t.jump.clone(),
                    start: t.start,
                })
                .collect(),
        }
    }
}

impl PiecewiseLti {
    /// The system moved by `step` along `tangent`: every matrix `M + step dM`, every jump
    /// `J + step dJ`, every piece start `tau_i + step d tau_i`, the period unchanged. What a
    /// derivative along the tangent is the rate of.
    ///
    /// # Errors
    /// A tangent that does not fit ([`PiecewiseTangent::check`]), or a step that makes a
    /// piece's duration non-positive ([`PiecewiseLti::new`]'s checks).
    pub fn moved(&self, tangent: &PiecewiseTangent, step: f64) -> Result<Self, LtpError> {
        tangent.check(self)?;
        let t = tangent.pieces();
        let n_pieces = t.len();
        let starts: Vec<f64> = (0..n_pieces)
            .map(|i| self.boundaries()[i] + step * t[i].start)
            .collect();
        let pieces = self
            .pieces()
            .iter()
            .zip(t)
            .enumerate()
            .map(|(i, (p, dt))| {
                let end = if i + 1 < n_pieces {
                    starts[i + 1]
                } else {
                    starts[0] + self.period()
                };
                let moved = |m: &DMatrix<f64>, dm: &DMatrix<f64>| m + dm * step;
                Piece::new(
                    end - starts[i],
                    moved(p.a(), &dt.a),
                    moved(p.b(), &dt.b),
                    moved(p.c(), &dt.c),
                    moved(p.d(), &dt.d),
                )
                .with_jump(moved(&p.jump_matrix(), &dt.jump))
            })
            .collect();
        PiecewiseLti::new(self.period(), starts[0], pieces)
    }
}
