//! Exact derivatives of the exact HTF along a direction of change of its system.
//!
//! Along a [`PiecewiseTangent`] every piece's matrices change (`dA`, `dB`, `dC`, `dD`), every
//! jump changes (`dJ`) and every piece start moves (`d tau`), the period fixed. For the input
//! `exp(s t)` the periodic `p` (`x = exp(s t) p`) then changes by `z`, with, on piece `i`,
//!
//! ```text
//! z' = (A - s) z + dA p + dB
//! ```
//!
//! and, where piece `i + 1` starts (its jump `J`), `z+ = J z- + dJ p- + d tau (J (A_i p- + B_i)
//! - A_{i+1} J p- - B_{i+1})`: the jump's own change, and the stretch of length `d tau` that
//! a moved switch hands from one piece's flow to the other's. The output harmonic
//! `Y_k = (1/T) int (C p + D) exp(-j k wp t) dt` changes by the integral of
//! `dC p + C z + dD` plus, at each moved start, `d tau` times the output's jump there
//! (`y- - y+`) rotated to the start's phase.
//!
//! In the eigenvector coordinates of each piece (`A = V diag(lambda) V^{-1}`, `x_j = (lambda_j -
//! s) h`, `M = V^{-1} dA V`) every integral is a divided difference of the exponential, at
//! most over four nodes ([`dd_exp`]): with `q` the modal state at the piece's start and
//! `beta = V^{-1} B`,
//!
//! ```text
//! z_j(h) = e^{x_j} z_j(0) + h e[x_j, 0] dbeta_j
//!        + sum_l M_jl (h e[x_j, x_l] q_l + h^2 e[x_j, x_l, 0] beta_l),
//! ```
//!
//! and, with `y_j = x_j + b`, `b = -j k wp h`, the output integrals are the same with one node
//! `b` more (`int_0^h sigma^m e[a_0 sigma, ...] d sigma = h^{m+1} e[a_0 h, ..., 0]`). The
//! periodic `z` comes from the same solve with `I - Phi` as `p` itself.

use htfid_ltp::PiecewiseTangent;
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;

use super::{ExactHtf, Modal, ZERO};
use crate::error::TheoryError;
use crate::kernels::dd_exp;

/// What every direction shares at one point `(k, w)`: the system's own periodic response and
/// the divided differences of each piece.
struct Point {
    /// Per piece: the modal state at its start (after its jump), in its own coordinates.
    start: Vec<DVector<Complex64>>,
    /// Per piece: `p` at its start and at its end, in the system's coordinates.
    p_start: Vec<DVector<Complex64>>,
    p_end: Vec<DVector<Complex64>>,
    /// Per piece, by state: `e^{x_j}`, `e[x_j, 0]`, `e[y_j, 0]`, `e[y_j, b, 0]`.
    e: Vec<Vec<Complex64>>,
    e_x0: Vec<Vec<Complex64>>,
    e_y0: Vec<Vec<Complex64>>,
    e_yb0: Vec<Vec<Complex64>>,
    /// Per piece, row-major by state pair: `e[x_j, x_l]`, `e[x_j, x_l, 0]`, `e[y_j, y_l, 0]`,
    /// `e[y_j, y_l, b, 0]`.
    e_xx: Vec<Vec<Complex64>>,
    e_xx0: Vec<Vec<Complex64>>,
    e_yy0: Vec<Vec<Complex64>>,
    e_yyb0: Vec<Vec<Complex64>>,
    /// Per piece: `e[b, 0]` and the rotation `exp(-j k wp tau_i)`.
    e_b0: Vec<Complex64>,
    rotation: Vec<Complex64>,
    /// `I - Phi` over one period from piece 0's start, factorised.
    periodic: nalgebra::LU<Complex64, nalgebra::Dyn, nalgebra::Dyn>,
}

fn node(z: Complex64) -> (Complex64, Complex64) {
    (z, z.exp())
}

fn complex(m: &DMatrix<f64>) -> DMatrix<Complex64> {
    m.map(|x| Complex64::new(x, 0.0))
}

impl ExactHtf {
    /// The derivatives of `G_k(jw)` at `points` (`(k, w)`, as
    /// [`HarmonicTransferFunction::values`](crate::HarmonicTransferFunction::values)) along
    /// each of `tangents`: entry `[t][i]` is the rate of change of the value at `points[i]`
    /// when the system moves along `tangents[t]` ([`htfid_ltp::PiecewiseLti::moved`]), exact
    /// (closed form, no differences).
    ///
    /// # Errors
    /// A tangent that does not fit the system ([`TheoryError::Ltp`]), or a system on the
    /// block-exponential path ([`TheoryError::DerivativeNeedsModal`]).
    pub fn derivatives(
        &self,
        tangents: &[PiecewiseTangent],
        points: &[(i32, f64)],
    ) -> Result<Vec<Vec<Complex64>>, TheoryError> {
        for t in tangents {
            t.check(&self.lti)?;
        }
        let modal = self
            .modal
            .as_ref()
            .ok_or(TheoryError::DerivativeNeedsModal)?;
        // Per tangent and piece: M = V^-1 dA V, V^-1 dB, dC V, dD, and the jump's terms.
        let directions: Vec<Vec<Direction>> = tangents
            .iter()
            .map(|t| {
                t.pieces()
                    .iter()
                    .zip(&modal.pieces)
                    .map(|(d, mp)| Direction {
                        m: &mp.v_inv * complex(&d.a) * &mp.v,
                        dbeta: &mp.v_inv * complex(&d.b).column(0),
                        dgamma: (complex(&d.c) * &mp.v).row(0).transpose(),
                        dd: d.d[(0, 0)],
                        djump: complex(&d.jump),
                        dtau: d.start,
                    })
                    .collect()
            })
            .collect();
        let mut out = vec![Vec::with_capacity(points.len()); tangents.len()];
        for &(k, w) in points {
            match self.point(modal, k, w) {
                Some(point) => {
                    for (t, direction) in directions.iter().enumerate() {
                        out[t].push(self.along(modal, &point, direction));
                    }
                }
                None => {
                    for column in &mut out {
                        column.push(Complex64::new(f64::NAN, f64::NAN));
                    }
                }
            }
        }
        Ok(out)
    }

    /// The system's periodic response and the divided differences at `(k, w)`; `None` at a
    /// pole (a singular periodicity solve).
    fn point(&self, modal: &Modal, k: i32, w: f64) -> Option<Point> {
        let n = self.n;
        let theta = f64::from(k) * self.wp;
        let s = Complex64::new(0.0, w - theta);
        let n_pieces = self.pieces.len();
        let mut pt = Point {
            start: Vec::with_capacity(n_pieces),
            p_start: Vec::with_capacity(n_pieces),
            p_end: Vec::with_capacity(n_pieces),
            e: Vec::with_capacity(n_pieces),
            e_x0: Vec::with_capacity(n_pieces),
            e_y0: Vec::with_capacity(n_pieces),
            e_yb0: Vec::with_capacity(n_pieces),
            e_xx: Vec::with_capacity(n_pieces),
            e_xx0: Vec::with_capacity(n_pieces),
            e_yy0: Vec::with_capacity(n_pieces),
            e_yyb0: Vec::with_capacity(n_pieces),
            e_b0: Vec::with_capacity(n_pieces),
            rotation: Vec::with_capacity(n_pieces),
            periodic: DMatrix::<Complex64>::identity(n, n).lu(),
        };
        let zero = node(ZERO);
        for (p, mp) in self.pieces.iter().zip(&modal.pieces) {
            let b = node(Complex64::new(0.0, -theta * p.h));
            let x: Vec<_> = mp.lambda.iter().map(|l| node((l - s) * p.h)).collect();
            let y: Vec<_> = mp
                .lambda
                .iter()
                .map(|l| node((l - Complex64::new(0.0, w)) * p.h))
                .collect();
            pt.e.push(x.iter().map(|x| x.1).collect());
            pt.e_x0
                .push(x.iter().map(|&x| dd_exp(&[x, zero])).collect());
            pt.e_y0
                .push(y.iter().map(|&y| dd_exp(&[y, zero])).collect());
            pt.e_yb0
                .push(y.iter().map(|&y| dd_exp(&[y, b, zero])).collect());
            let mut xx = Vec::with_capacity(n * n);
            let mut xx0 = Vec::with_capacity(n * n);
            let mut yy0 = Vec::with_capacity(n * n);
            let mut yyb0 = Vec::with_capacity(n * n);
            for j in 0..n {
                for l in 0..n {
                    xx.push(dd_exp(&[x[j], x[l]]));
                    xx0.push(dd_exp(&[x[j], x[l], zero]));
                    yy0.push(dd_exp(&[y[j], y[l], zero]));
                    yyb0.push(dd_exp(&[y[j], y[l], b, zero]));
                }
            }
            pt.e_xx.push(xx);
            pt.e_xx0.push(xx0);
            pt.e_yy0.push(yy0);
            pt.e_yyb0.push(yyb0);
            pt.e_b0.push(dd_exp(&[b, zero]));
            pt.rotation.push(super::cis_neg(theta * p.tau));
        }
        // Phi (columns from the unit states) and psi (from the zero state) over one period.
        let mut phi = DMatrix::<Complex64>::identity(n, n);
        let mut psi = DVector::<Complex64>::zeros(n);
        for (i, (p, mp)) in self.pieces.iter().zip(&modal.pieces).enumerate() {
            let transfer = DMatrix::from_row_slice(n, n, &mp.transfer);
            let e = DMatrix::from_diagonal(&DVector::from_column_slice(&pt.e[i]));
            let forced =
                DVector::from_iterator(n, (0..n).map(|j| pt.e_x0[i][j] * mp.beta[j] * p.h));
            phi = &transfer * (&e * phi);
            psi = &transfer * (&e * psi + forced);
        }
        let periodic = (DMatrix::<Complex64>::identity(n, n) - phi).lu();
        let mut q = periodic.solve(&psi)?;
        if q.iter().any(|v| !(v.re.is_finite() && v.im.is_finite())) {
            return None;
        }
        pt.periodic = periodic;
        for (i, (p, mp)) in self.pieces.iter().zip(&modal.pieces).enumerate() {
            pt.p_start.push(&mp.v * &q);
            let end = DVector::from_iterator(
                n,
                (0..n).map(|j| pt.e[i][j] * q[j] + pt.e_x0[i][j] * mp.beta[j] * p.h),
            );
            pt.p_end.push(&mp.v * &end);
            pt.start.push(q);
            q = DMatrix::from_row_slice(n, n, &mp.transfer) * end;
        }
        Some(pt)
    }

    /// The derivative of the value at `point` along one direction.
    fn along(&self, modal: &Modal, pt: &Point, dir: &[Direction]) -> Complex64 {
        let n = self.n;
        let n_pieces = self.pieces.len();
        // The state's derivative at each piece's start, from a given one at piece 0's.
        let sweep = |z0: DVector<Complex64>, starts: &mut Vec<DVector<Complex64>>| {
            starts.clear();
            let mut z = z0;
            for i in 0..n_pieces {
                let (p, mp, d) = (&self.pieces[i], &modal.pieces[i], &dir[i]);
                let h = p.h;
                let q = &pt.start[i];
                let end = DVector::from_iterator(
                    n,
                    (0..n).map(|j| {
                        let mut v = pt.e[i][j] * z[j] + pt.e_x0[i][j] * d.dbeta[j] * h;
                        for l in 0..n {
                            v += d.m[(j, l)]
                                * (pt.e_xx[i][j * n + l] * q[l] * h
                                    + pt.e_xx0[i][j * n + l] * mp.beta[l] * h * h);
                        }
                        v
                    }),
                );
                starts.push(z);
                let next = (i + 1) % n_pieces;
                let (pn, mpn, dn) = (&self.pieces[next], &modal.pieces[next], &dir[next]);
                let jump = complex(&pn.jump);
                let p_minus = &pt.p_end[i];
                let moved = complex(&pn.jump)
                    * (complex(&p.a) * p_minus + p.b.map(|x| Complex64::new(x, 0.0)))
                    - complex(&pn.a) * (&jump * p_minus)
                    - pn.b.map(|x| Complex64::new(x, 0.0));
                let change = &jump * (&mp.v * end)
                    + &dn.djump * p_minus
                    + moved * Complex64::new(dn.dtau, 0.0);
                z = &mpn.v_inv * change;
            }
            z
        };
        let mut starts = Vec::with_capacity(n_pieces);
        let psi = sweep(DVector::zeros(n), &mut starts);
        let Some(z0) = pt.periodic.solve(&psi) else {
            return Complex64::new(f64::NAN, f64::NAN);
        };
        sweep(z0, &mut starts);
        let mut dy = ZERO;
        for i in 0..n_pieces {
            let (p, mp, d) = (&self.pieces[i], &modal.pieces[i], &dir[i]);
            let h = p.h;
            let (q, z) = (&pt.start[i], &starts[i]);
            let mut acc = d.dd * pt.e_b0[i] * h;
            for j in 0..n {
                // int exp(b s) q_j and int exp(b s) z_j over the piece.
                let int_q = q[j] * pt.e_y0[i][j] * h + mp.beta[j] * pt.e_yb0[i][j] * h * h;
                let mut int_z = z[j] * pt.e_y0[i][j] * h + d.dbeta[j] * pt.e_yb0[i][j] * h * h;
                for l in 0..n {
                    int_z += d.m[(j, l)]
                        * (q[l] * pt.e_yy0[i][j * n + l] * h * h
                            + mp.beta[l] * pt.e_yyb0[i][j * n + l] * h * h * h);
                }
                acc += d.dgamma[j] * int_q + mp.gamma[j] * int_z;
            }
            dy += pt.rotation[i] * acc;
            // The moved start: the output's jump there, times its rate.
            let before = (i + n_pieces - 1) % n_pieces;
            let pb = &self.pieces[before];
            let y_minus = pb.c.map(|x| Complex64::new(x, 0.0)).dot(&pt.p_end[before]) + pb.d;
            let y_plus = p.c.map(|x| Complex64::new(x, 0.0)).dot(&pt.p_start[i]) + p.d;
            dy += pt.rotation[i] * (y_minus - y_plus) * d.dtau;
        }
        dy / self.period
    }
}

/// One piece of one tangent in the piece's eigenvector coordinates.
struct Direction {
    m: DMatrix<Complex64>,
    dbeta: DVector<Complex64>,
    dgamma: DVector<Complex64>,
    dd: f64,
    djump: DMatrix<Complex64>,
    dtau: f64,
}
