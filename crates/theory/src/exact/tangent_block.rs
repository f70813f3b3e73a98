//! The derivatives of [`tangent`](super::tangent) for systems on the block-exponential path,
//! whose state matrices need not be diagonalisable (a free flight's `[[0, 1], [0, 0]]`).
//!
//! The same chain, with every integral over a piece read off one matrix exponential (Van
//! Loan's augmented matrices). With the output rotation `rho = exp(nu s)` (`nu = -j k wp`),
//! `P = rho p` and `Z = rho z`, one piece's state, its derivative and both output integrals
//! solve one linear system with constant coefficients:
//!
//! ```text
//! P'   = (A - jw) P + B rho
//! Z'   = (A - jw) Z + dA P + dB rho
//! rho' = nu rho
//! I_p' = C P + D rho                 (the output's integral)
//! I_z' = dC P + C Z + dD rho         (its derivative's)
//! ```
//!
//! so `exp` of its `(2n + 3)`-square matrix times the piece's length maps
//! `[q, z, 1, 0, 0]` at the piece's start to its end, and `p(h) = exp(-nu h) P(h)`. The jumps,
//! the handed-over stretches at moved starts and the periodic solves are those of the modal
//! path.

use htfid_ltp::{expm, PiecewiseTangent};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;

use super::{cis_neg, ExactHtf, ZERO};

/// One piece's exponential along one tangent, split into the blocks the chain reads.
struct Blocks {
    /// `p(h) = e q + f` (the rotation undone).
    e: DMatrix<Complex64>,
    f: DVector<Complex64>,
    /// `z(h) = e z(0) + zp q + zr` (the rotation undone).
    zp: DMatrix<Complex64>,
    zr: DVector<Complex64>,
    /// The derivative's output integral: `iz_p q + iz_z z(0) + iz_r`.
    iz_p: DVector<Complex64>,
    iz_z: DVector<Complex64>,
    iz_r: Complex64,
}

fn complex(m: &DMatrix<f64>) -> DMatrix<Complex64> {
    m.map(|x| Complex64::new(x, 0.0))
}

impl ExactHtf {
    /// [`ExactHtf::derivatives`] on the block-exponential path: one `(2n + 3)`-square complex
    /// exponential per piece, tangent and point.
    pub(super) fn derivatives_block(
        &self,
        tangents: &[PiecewiseTangent],
        points: &[(i32, f64)],
    ) -> Vec<Vec<Complex64>> {
        let mut out = vec![Vec::with_capacity(points.len()); tangents.len()];
        for &(k, w) in points {
            for (column, tangent) in out.iter_mut().zip(tangents) {
                column.push(self.derivative_block(tangent, k, w));
            }
        }
        out
    }

    fn blocks(&self, tangent: &PiecewiseTangent, i: usize, k: i32, w: f64) -> Blocks {
        let n = self.n;
        let (p, d) = (&self.pieces[i], &tangent.pieces()[i]);
        let h = p.h;
        let nu = Complex64::new(0.0, -f64::from(k) * self.wp);
        let jw = Complex64::new(0.0, w);
        let (pp, zz, rho, ip, iz) = (0, n, 2 * n, 2 * n + 1, 2 * n + 2);
        let mut aug = DMatrix::<Complex64>::zeros(2 * n + 3, 2 * n + 3);
        for r in 0..n {
            for c in 0..n {
                aug[(pp + r, pp + c)] = Complex64::new(p.a[(r, c)] * h, 0.0);
                aug[(zz + r, zz + c)] = Complex64::new(p.a[(r, c)] * h, 0.0);
                aug[(zz + r, pp + c)] = Complex64::new(d.a[(r, c)] * h, 0.0);
            }
            aug[(pp + r, pp + r)] -= jw * h;
            aug[(zz + r, zz + r)] -= jw * h;
            aug[(pp + r, rho)] = Complex64::new(p.b[r] * h, 0.0);
            aug[(zz + r, rho)] = Complex64::new(d.b[(r, 0)] * h, 0.0);
            aug[(ip, pp + r)] = Complex64::new(p.c[r] * h, 0.0);
            aug[(iz, pp + r)] = Complex64::new(d.c[(0, r)] * h, 0.0);
            aug[(iz, zz + r)] = Complex64::new(p.c[r] * h, 0.0);
        }
        aug[(rho, rho)] = nu * h;
        aug[(ip, rho)] = Complex64::new(p.d * h, 0.0);
        aug[(iz, rho)] = Complex64::new(d.d[(0, 0)] * h, 0.0);
        let ex = expm(&aug);
        let undo = (-nu * h).exp();
        Blocks {
            e: ex.view((pp, pp), (n, n)) * undo,
            f: ex.view((pp, rho), (n, 1)).column(0) * undo,
            zp: ex.view((zz, pp), (n, n)) * undo,
            zr: ex.view((zz, rho), (n, 1)).column(0) * undo,
            iz_p: ex.view((iz, pp), (1, n)).transpose().column(0).into_owned(),
            iz_z: ex.view((iz, zz), (1, n)).transpose().column(0).into_owned(),
            iz_r: ex[(iz, rho)],
        }
    }

    /// The derivative of `G_k(jw)` along `tangent`; NaN at a pole.
    fn derivative_block(&self, tangent: &PiecewiseTangent, k: i32, w: f64) -> Complex64 {
        let n = self.n;
        let n_pieces = self.pieces.len();
        let next = |i: usize| (i + 1) % n_pieces;
        let nan = Complex64::new(f64::NAN, f64::NAN);
        let blocks: Vec<Blocks> = (0..n_pieces)
            .map(|i| self.blocks(tangent, i, k, w))
            .collect();
        let jump = |i: usize| complex(&self.pieces[i].jump);
        // The periodic response: Phi = J_0 E_{N-1} ... J_1 E_0, psi from the zero state.
        let mut phi = DMatrix::<Complex64>::identity(n, n);
        let mut psi = DVector::<Complex64>::zeros(n);
        for (i, b) in blocks.iter().enumerate() {
            let j = jump(next(i));
            phi = &j * (&b.e * phi);
            psi = &j * (&b.e * psi + &b.f);
        }
        let lu = (DMatrix::<Complex64>::identity(n, n) - phi).lu();
        let Some(mut q) = lu.solve(&psi) else {
            return nan;
        };
        let mut q_start = Vec::with_capacity(n_pieces);
        let mut q_end = Vec::with_capacity(n_pieces);
        for (i, b) in blocks.iter().enumerate() {
            let end = &b.e * &q + &b.f;
            q_start.push(q);
            q = jump(next(i)) * &end;
            q_end.push(end);
        }
        // One period of the derivative from `z0` at piece 0's start; each piece's start.
        let sweep = |z0: DVector<Complex64>| -> (DVector<Complex64>, Vec<DVector<Complex64>>) {
            let mut z = z0;
            let mut starts = Vec::with_capacity(n_pieces);
            for (i, b) in blocks.iter().enumerate() {
                let z_end = &b.e * &z + &b.zp * &q_start[i] + &b.zr;
                starts.push(z);
                let (p, pn) = (&self.pieces[i], &self.pieces[next(i)]);
                let dn = &tangent.pieces()[next(i)];
                let jn = complex(&pn.jump);
                let handed = complex(&(&pn.jump * &p.a - &pn.a * &pn.jump)) * &q_end[i]
                    + (&pn.jump * &p.b - &pn.b).map(|x| Complex64::new(x, 0.0));
                z = &jn * z_end
                    + complex(&dn.jump) * &q_end[i]
                    + handed * Complex64::new(dn.start, 0.0);
            }
            (z, starts)
        };
        let (particular, _) = sweep(DVector::zeros(n));
        let Some(z0) = lu.solve(&particular) else {
            return nan;
        };
        let (_, z_start) = sweep(z0);
        let mut dy = ZERO;
        for (i, (p, b)) in self.pieces.iter().zip(&blocks).enumerate() {
            let d = &tangent.pieces()[i];
            let rotation = cis_neg(f64::from(k) * self.wp * p.tau);
            let mut acc = b.iz_p.dot(&q_start[i]) + b.iz_z.dot(&z_start[i]) + b.iz_r;
            if d.start != 0.0 {
                let before = (i + n_pieces - 1) % n_pieces;
                let pb = &self.pieces[before];
                let y = |c: &DVector<f64>, dd: f64, x: &DVector<Complex64>| {
                    c.iter()
                        .zip(x.iter())
                        .map(|(c, x)| x * *c)
                        .sum::<Complex64>()
                        + Complex64::new(dd, 0.0)
                };
                acc += (y(&pb.c, pb.d, &q_end[before]) - y(&p.c, p.d, &q_start[i])) * d.start;
            }
            dy += rotation * acc;
        }
        dy / self.period
    }
}
