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
use nalgebra::DMatrix;
use num_complex::Complex64;

use super::{row_major, solve_in_place, ExactHtf, Modal, ONE, ZERO};
use crate::error::TheoryError;
use crate::kernels::{dd_exp, phi1};

/// `m` as a complex matrix.
fn complex(m: &DMatrix<f64>) -> DMatrix<Complex64> {
    m.map(|x| Complex64::new(x, 0.0))
}

/// `out = m v` for row-major `m` (`n x n`).
#[inline]
fn mul(m: &[Complex64], v: &[Complex64], out: &mut [Complex64]) {
    let n = v.len();
    for (r, o) in out.iter_mut().enumerate() {
        let mut acc = ZERO;
        for c in 0..n {
            acc += m[r * n + c] * v[c];
        }
        *o = acc;
    }
}

/// What does not depend on the point or the direction, per piece `i`: the stretch of flow a
/// moved start of piece `i + 1` hands over, in modal coordinates,
/// `V_{i+1}^{-1} (J A_i - A_{i+1} J) V_i` and `V_{i+1}^{-1} (J B_i - B_{i+1})`.
struct Handover {
    matrix: Vec<Complex64>,
    vector: Vec<Complex64>,
}

/// One piece of one tangent in the piece's eigenvector coordinates.
struct Direction {
    /// `V^{-1} dA V`, row-major.
    m: Vec<Complex64>,
    dbeta: Vec<Complex64>,
    dgamma: Vec<Complex64>,
    dd: f64,
    /// `V_{i+1}^{-1} dJ_{i+1} V_i`, row-major: the next jump's change.
    djump_next: Vec<Complex64>,
    /// The rates of this piece's start and of the next piece's.
    dtau: f64,
    dtau_next: f64,
}

/// Per-point buffers, piece-major; pair tables `[i][j][l]`.
struct Scratch {
    e: Vec<Complex64>,
    e_x0: Vec<Complex64>,
    e_y0: Vec<Complex64>,
    e_yb0: Vec<Complex64>,
    e_xx: Vec<Complex64>,
    e_xx0: Vec<Complex64>,
    e_yy0: Vec<Complex64>,
    e_yyb0: Vec<Complex64>,
    e_b0: Vec<Complex64>,
    rotation: Vec<Complex64>,
    /// The modal state at each piece's start and end (the system's own response).
    q_start: Vec<Complex64>,
    q_end: Vec<Complex64>,
    /// `I - Phi`, row-major, and a copy to solve with.
    periodic: Vec<Complex64>,
    work: Vec<Complex64>,
    /// The derivative at each piece's start, and vectors of length `n`.
    z_start: Vec<Complex64>,
    a: Vec<Complex64>,
    b: Vec<Complex64>,
    c: Vec<Complex64>,
    x: Vec<(Complex64, Complex64)>,
    y: Vec<(Complex64, Complex64)>,
}

impl Scratch {
    fn new(n: usize, pieces: usize) -> Self {
        let v = |len: usize| vec![ZERO; len];
        Self {
            e: v(pieces * n),
            e_x0: v(pieces * n),
            e_y0: v(pieces * n),
            e_yb0: v(pieces * n),
            e_xx: v(pieces * n * n),
            e_xx0: v(pieces * n * n),
            e_yy0: v(pieces * n * n),
            e_yyb0: v(pieces * n * n),
            e_b0: v(pieces),
            rotation: v(pieces),
            q_start: v(pieces * n),
            q_end: v(pieces * n),
            periodic: v(n * n),
            work: v(n * n),
            z_start: v(pieces * n),
            a: v(n),
            b: v(n),
            c: v(n),
            x: vec![(ZERO, ONE); n],
            y: vec![(ZERO, ONE); n],
        }
    }
}

impl ExactHtf {
    /// The derivatives of `G_k(jw)` at `points` (`(k, w)`, as
    /// [`HarmonicTransferFunction::values`](crate::HarmonicTransferFunction::values)) along
    /// each of `tangents`: entry `[t][i]` is the rate of change of the value at `points[i]`
    /// when the system moves along `tangents[t]` ([`htfid_ltp::PiecewiseLti::moved`]), exact
    /// (closed form, no differences). NaN at a pole, as the values. On the modal path in
    /// scalar exponentials and divided differences; on the block-exponential path (state
    /// matrices that are not safely diagonalisable) from one augmented matrix exponential per
    /// piece, tangent and point (`tangent_block.rs`).
    ///
    /// # Errors
    /// A tangent that does not fit the system ([`TheoryError::Ltp`]).
    pub fn derivatives(
        &self,
        tangents: &[PiecewiseTangent],
        points: &[(i32, f64)],
    ) -> Result<Vec<Vec<Complex64>>, TheoryError> {
        for t in tangents {
            t.check(&self.lti)?;
        }
        let Some(modal) = self.modal.as_ref() else {
            return Ok(self.derivatives_block(tangents, points));
        };
        let n_pieces = self.pieces.len();
        let next = |i: usize| (i + 1) % n_pieces;
        let handover: Vec<Handover> = (0..n_pieces)
            .map(|i| {
                let (p, pn) = (&self.pieces[i], &self.pieces[next(i)]);
                let (mp, mpn) = (&modal.pieces[i], &modal.pieces[next(i)]);
                let matrix = &mpn.v_inv * complex(&(&pn.jump * &p.a - &pn.a * &pn.jump)) * &mp.v;
                let vector = &mpn.v_inv * (&pn.jump * &p.b - &pn.b).map(|x| Complex64::new(x, 0.0));
                Handover {
                    matrix: row_major(&matrix),
                    vector: vector.iter().copied().collect(),
                }
            })
            .collect();
        let directions: Vec<Vec<Direction>> = tangents
            .iter()
            .map(|t| {
                let d = t.pieces();
                (0..n_pieces)
                    .map(|i| {
                        let (mp, mpn) = (&modal.pieces[i], &modal.pieces[next(i)]);
                        Direction {
                            m: row_major(&(&mp.v_inv * complex(&d[i].a) * &mp.v)),
                            dbeta: (&mp.v_inv * complex(&d[i].b).column(0))
                                .iter()
                                .copied()
                                .collect(),
                            dgamma: (complex(&d[i].c) * &mp.v).iter().copied().collect(),
                            dd: d[i].d[(0, 0)],
                            djump_next: row_major(
                                &(&mpn.v_inv * complex(&d[next(i)].jump) * &mp.v),
                            ),
                            dtau: d[i].start,
                            dtau_next: d[next(i)].start,
                        }
                    })
                    .collect()
            })
            .collect();
        let mut scratch = Scratch::new(self.n, n_pieces);
        let mut out = vec![Vec::with_capacity(points.len()); tangents.len()];
        for &(k, w) in points {
            let ok = self.point(modal, k, w, &mut scratch);
            for (column, direction) in out.iter_mut().zip(&directions) {
                column.push(if ok {
                    self.along(modal, &handover, direction, &mut scratch)
                } else {
                    Complex64::new(f64::NAN, f64::NAN)
                });
            }
        }
        Ok(out)
    }

    /// Fills `scratch` with the system's periodic response and the divided differences at
    /// `(k, w)`; `false` at a pole (a singular periodicity solve).
    fn point(&self, modal: &Modal, k: i32, w: f64, sc: &mut Scratch) -> bool {
        let n = self.n;
        let theta = f64::from(k) * self.wp;
        let s = Complex64::new(0.0, w - theta);
        let jw = Complex64::new(0.0, w);
        let zero = (ZERO, ONE);
        for (i, (p, mp)) in self.pieces.iter().zip(&modal.pieces).enumerate() {
            let bz = Complex64::new(0.0, -theta * p.h);
            let b = (bz, super::cis_neg(theta * p.h));
            for j in 0..n {
                let x = (mp.lambda[j] - s) * p.h;
                let y = (mp.lambda[j] - jw) * p.h;
                sc.x[j] = (x, x.exp());
                sc.y[j] = (y, y.exp());
            }
            // Each divided difference by the quotient over a pair of nodes at least 1 apart
            // when there is one among the lower-order differences already at hand, else by
            // `dd_exp` (which picks the widest pair or the series).
            let apart = |a: Complex64, b: Complex64| (a - b).norm_sqr() >= 1.0;
            let e_b0 = phi1(b.0, b.1);
            sc.e_b0[i] = e_b0;
            for j in 0..n {
                let at = i * n + j;
                sc.e[at] = sc.x[j].1;
                sc.e_x0[at] = phi1(sc.x[j].0, sc.x[j].1);
                sc.e_y0[at] = phi1(sc.y[j].0, sc.y[j].1);
                sc.e_yb0[at] = if apart(sc.y[j].0, bz) {
                    (e_b0 - sc.e_y0[at]) / (bz - sc.y[j].0)
                } else {
                    dd_exp(&[sc.y[j], b, zero])
                };
            }
            for j in 0..n {
                for l in j..n {
                    let (jl, lj) = (i * n * n + j * n + l, i * n * n + l * n + j);
                    let (xj, xl) = (sc.x[j].0, sc.x[l].0);
                    let (yj, yl) = (sc.y[j].0, sc.y[l].0);
                    let (xx, xx0, yy0, yyb0) =
                        if j == l && apart(xj, ZERO) && apart(yj, ZERO) && apart(yj, bz) {
                            // One node twice: `e[x, x] = e^x`, then the quotients over `(x, 0)`,
                            // `(y, 0)` and `(y, b)`.
                            let at = i * n + j;
                            let yy0 = (sc.y[j].1 - sc.e_y0[at]) / yj;
                            (
                                sc.e[at],
                                (sc.e[at] - sc.e_x0[at]) / xj,
                                yy0,
                                (sc.e_yb0[at] - yy0) / (bz - yj),
                            )
                        } else if apart(xj, xl) {
                            let (a, b) = (i * n + j, i * n + l);
                            (
                                (sc.e[b] - sc.e[a]) / (xl - xj),
                                (sc.e_x0[b] - sc.e_x0[a]) / (xl - xj),
                                (sc.e_y0[b] - sc.e_y0[a]) / (yl - yj),
                                (sc.e_yb0[b] - sc.e_yb0[a]) / (yl - yj),
                            )
                        } else {
                            (
                                dd_exp(&[sc.x[j], sc.x[l]]),
                                dd_exp(&[sc.x[j], sc.x[l], zero]),
                                dd_exp(&[sc.y[j], sc.y[l], zero]),
                                dd_exp(&[sc.y[j], sc.y[l], b, zero]),
                            )
                        };
                    for at in [jl, lj] {
                        sc.e_xx[at] = xx;
                        sc.e_xx0[at] = xx0;
                        sc.e_yy0[at] = yy0;
                        sc.e_yyb0[at] = yyb0;
                    }
                }
            }
            sc.rotation[i] = super::cis_neg(theta * p.tau);
        }
        // Phi over one period from piece 0's start (columns from the unit states), and the
        // response from the zero state; then the periodic start.
        sc.periodic.fill(ZERO);
        for col in 0..n {
            sc.a.fill(ZERO);
            sc.a[col] = ONE;
            for (i, mp) in modal.pieces.iter().enumerate() {
                for j in 0..n {
                    sc.b[j] = sc.e[i * n + j] * sc.a[j];
                }
                mul(&mp.transfer, &sc.b, &mut sc.a);
            }
            for r in 0..n {
                let id = if r == col { ONE } else { ZERO };
                sc.periodic[r * n + col] = id - sc.a[r];
            }
        }
        sc.a.fill(ZERO);
        for (i, (p, mp)) in self.pieces.iter().zip(&modal.pieces).enumerate() {
            for j in 0..n {
                sc.b[j] = sc.e[i * n + j] * sc.a[j] + sc.e_x0[i * n + j] * mp.beta[j] * p.h;
            }
            mul(&mp.transfer, &sc.b, &mut sc.a);
        }
        sc.work.copy_from_slice(&sc.periodic);
        if !solve_in_place(&mut sc.work, &mut sc.a, n) {
            return false;
        }
        for (i, (p, mp)) in self.pieces.iter().zip(&modal.pieces).enumerate() {
            sc.q_start[i * n..(i + 1) * n].copy_from_slice(&sc.a);
            for j in 0..n {
                sc.b[j] = sc.e[i * n + j] * sc.a[j] + sc.e_x0[i * n + j] * mp.beta[j] * p.h;
            }
            sc.q_end[i * n..(i + 1) * n].copy_from_slice(&sc.b);
            mul(&mp.transfer, &sc.b, &mut sc.a);
        }
        true
    }

    /// The state's derivative through one period from `sc.a` at piece 0's start, storing each
    /// piece's start in `sc.z_start` when `store`; ends in `sc.a`.
    fn sweep(
        &self,
        modal: &Modal,
        handover: &[Handover],
        dir: &[Direction],
        sc: &mut Scratch,
        store: bool,
    ) {
        let n = self.n;
        let nn = n * n;
        for (i, (p, mp)) in self.pieces.iter().zip(&modal.pieces).enumerate() {
            let d = &dir[i];
            let h = p.h;
            if store {
                sc.z_start[i * n..(i + 1) * n].copy_from_slice(&sc.a);
            }
            let q = &sc.q_start[i * n..(i + 1) * n];
            for j in 0..n {
                let mut v = sc.e[i * n + j] * sc.a[j] + sc.e_x0[i * n + j] * d.dbeta[j] * h;
                for l in 0..n {
                    v += d.m[j * n + l]
                        * (sc.e_xx[i * nn + j * n + l] * q[l]
                            + sc.e_xx0[i * nn + j * n + l] * mp.beta[l] * h)
                        * h;
                }
                sc.b[j] = v;
            }
            // Into the next piece: its jump, the jump's change, the handed-over stretch.
            let q_end = &sc.q_end[i * n..(i + 1) * n];
            let ho = &handover[i];
            for r in 0..n {
                let mut acc = ho.vector[r] * d.dtau_next;
                for c in 0..n {
                    acc += mp.transfer[r * n + c] * sc.b[c]
                        + (d.djump_next[r * n + c] + ho.matrix[r * n + c] * d.dtau_next) * q_end[c];
                }
                sc.c[r] = acc;
            }
            sc.a.copy_from_slice(&sc.c);
        }
    }

    /// The derivative of the value at the point in `sc` along one direction.
    fn along(
        &self,
        modal: &Modal,
        handover: &[Handover],
        dir: &[Direction],
        sc: &mut Scratch,
    ) -> Complex64 {
        let n = self.n;
        let nn = n * n;
        let n_pieces = self.pieces.len();
        sc.a.fill(ZERO);
        self.sweep(modal, handover, dir, sc, false);
        sc.work.copy_from_slice(&sc.periodic);
        if !solve_in_place(&mut sc.work, &mut sc.a, n) {
            return Complex64::new(f64::NAN, f64::NAN);
        }
        self.sweep(modal, handover, dir, sc, true);
        let mut dy = ZERO;
        for (i, (p, mp)) in self.pieces.iter().zip(&modal.pieces).enumerate() {
            let d = &dir[i];
            let h = p.h;
            let q = &sc.q_start[i * n..(i + 1) * n];
            let z = &sc.z_start[i * n..(i + 1) * n];
            let mut acc = d.dd * sc.e_b0[i] * h;
            for j in 0..n {
                let (e_y0, e_yb0) = (sc.e_y0[i * n + j], sc.e_yb0[i * n + j]);
                // The integrals of exp(b s) q_j and exp(b s) z_j over the piece.
                let int_q = (q[j] * e_y0 + mp.beta[j] * e_yb0 * h) * h;
                let mut int_z = (z[j] * e_y0 + d.dbeta[j] * e_yb0 * h) * h;
                for l in 0..n {
                    int_z += d.m[j * n + l]
                        * (q[l] * sc.e_yy0[i * nn + j * n + l]
                            + mp.beta[l] * sc.e_yyb0[i * nn + j * n + l] * h)
                        * h
                        * h;
                }
                acc += d.dgamma[j] * int_q + mp.gamma[j] * int_z;
            }
            dy += sc.rotation[i] * acc;
            // The moved start: the output's jump there, times its rate.
            if d.dtau != 0.0 {
                let before = (i + n_pieces - 1) % n_pieces;
                let (pb, mpb) = (&self.pieces[before], &modal.pieces[before]);
                let q_end = &sc.q_end[before * n..(before + 1) * n];
                let mut y_minus = Complex64::new(pb.d, 0.0);
                let mut y_plus = Complex64::new(p.d, 0.0);
                for j in 0..n {
                    y_minus += mpb.gamma[j] * q_end[j];
                    y_plus += mp.gamma[j] * q[j];
                }
                dy += sc.rotation[i] * (y_minus - y_plus) * d.dtau;
            }
        }
        dy / self.period
    }
}
