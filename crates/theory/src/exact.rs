//! Exact (untruncated) HTF of a piecewise-LTI system with jumps.
//!
//! For the input `u = exp(s t)`, `s = j w_in`, the steady state is
//! `x = exp(s t) p(t)` with `p` T-periodic, `p' = (A_i - s I) p + B_i` on
//! piece `i`, `p -> J_i p` at piece starts. Periodicity fixes `p` by one
//! small linear solve; the output harmonics
//! `Y_k = (1/T) int_0^T (C(t) p(t) + D(t)) exp(-j k wp t) dt` are integrated
//! in closed form piece by piece. See the crate docs for the derivation.

use crate::error::TheoryError;
use crate::grid::{HarmonicTransferFunction, HtfGrid};
use crate::kernels::{dd2, phi1, phi1_direct};
use htfid_ltp::{expm, Floquet, PiecewiseLti};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;
use std::f64::consts::TAU;

mod tangent;
mod tangent_block;

/// Eigenvector matrices with a condition number above this send the system
/// to the block-exponential method. Near a defective matrix the eigenvalues
/// themselves are only accurate to `~cond * eps`, and the modal sum cancels
/// terms of size `~cond`, so the HTF error grows like `cond^2 * eps`:
/// measured `~1e-20 cond^2` relative (1.7e-14 at cond 1e3, 9e-11 at 1e5,
/// 7e-7 at 1e7 for a critically damped oscillator perturbed apart). 1e4
/// keeps the modal path at ~1e-12.
const MAX_MODAL_CONDITION: f64 = 1e4;
/// Largest accepted relative residual `||A V - V L|| / ||A||` of a computed
/// eigendecomposition (healthy ones sit near 1e-15; defective matrices give
/// O(1)).
const MAX_MODAL_RESIDUAL: f64 = 1e-9;
/// Eigenvalues closer than this (relative to `max(1, ||A||)`) are treated as
/// one repeated eigenvalue whose eigenvectors span a null space.
const EIGEN_CLUSTER_RTOL: f64 = 1e-8;

const ZERO: Complex64 = Complex64::new(0.0, 0.0);
const ONE: Complex64 = Complex64::new(1.0, 0.0);

/// How [`ExactHtf`] integrates each piece.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum ExactMethod {
    /// Modal when every `A_i` is safely diagonalisable, otherwise block
    /// exponentials.
    Auto,
    /// Eigendecomposition `A_i = V diag(lambda) V^{-1}` computed once; every
    /// frequency then costs scalar exponentials only. Fast.
    Modal,
    /// Van Loan augmented matrix exponentials per frequency and harmonic.
    /// Slow, but needs no diagonalisation (defective `A_i` are fine).
    BlockExponential,
}

#[derive(Debug, Clone)]
struct PieceData {
    h: f64,
    tau: f64,
    a: DMatrix<f64>,
    b: DVector<f64>,
    c: DVector<f64>,
    d: f64,
    /// Jump at the start of this piece.
    jump: DMatrix<f64>,
}

#[derive(Debug, Clone)]
struct ModalPiece {
    lambda: Vec<Complex64>,
    /// `exp(lambda_j h)`.
    e_lambda_h: Vec<Complex64>,
    /// `V^{-1} B`.
    beta: Vec<Complex64>,
    /// `C V`.
    gamma: Vec<Complex64>,
    /// Row-major `V_{i+1}^{-1} J_{i+1} V_i`: modal coordinates at the end of
    /// this piece to modal coordinates after the next piece's jump.
    transfer: Vec<Complex64>,
    /// The eigenvectors `V` and `V^{-1}` (for the derivatives, `tangent`).
    v: DMatrix<Complex64>,
    v_inv: DMatrix<Complex64>,
}

#[derive(Debug, Clone)]
struct Modal {
    pieces: Vec<ModalPiece>,
    /// Row-major `prod_i transfer_i diag(e_lambda_h_i)`: the monodromy from
    /// `tau_0+` in modal coordinates of piece 0 (without the `exp(-sT)`).
    monodromy: Vec<Complex64>,
}

/// Factors of one piece that depend on the harmonic `k` only.
#[derive(Debug, Clone, Copy)]
struct HarmonicFactors {
    /// `b = -j k wp h`.
    b: Complex64,
    /// `exp(b)`.
    e_b: Complex64,
    /// `phi1(b)`.
    phi1_b: Complex64,
    /// `1 / b` (0 for `k = 0`, where it is never used).
    inv_b: Complex64,
    /// `exp(-j k wp tau)`.
    rotation: Complex64,
}

/// Factors of one piece and eigenvalue that depend on the output frequency
/// `w` only: `c = (lambda - j w) h`, the exponent of the output integral.
#[derive(Debug, Clone, Copy)]
struct OmegaFactor {
    c: Complex64,
    e_c: Complex64,
    phi1_c: Complex64,
    /// `1 / c` (0 when `|c|` is below the series radius, where it is unused).
    inv_c: Complex64,
}

const OMEGA_ZERO: OmegaFactor = OmegaFactor {
    c: ZERO,
    e_c: ZERO,
    phi1_c: ZERO,
    inv_c: ZERO,
};

/// Below this modulus a divided difference is evaluated by series, so the
/// quotient formulas below only ever divide by moduli >= 1.
const SERIES_DIAMETER: f64 = 1.0;

/// Per-call buffers, allocated once per `g`/`grid` call.
#[derive(Debug)]
struct Scratch {
    /// `exp(x)` with `x = (lambda_j - s) h_i`, piece-major.
    e: Vec<Complex64>,
    /// `phi1(x)`, piece-major.
    phi: Vec<Complex64>,
    /// `x` and `1 / x` (0 when `|x| < 1`), piece-major.
    x: Vec<Complex64>,
    inv_x: Vec<Complex64>,
    /// Modal (or plain) state after each piece's start jump, piece-major.
    zeta: Vec<Complex64>,
    v: Vec<Complex64>,
    u: Vec<Complex64>,
    mat: Vec<Complex64>,
    /// Output-frequency factors, piece-major, and `exp(-j w h_i)`.
    omega: Vec<OmegaFactor>,
    e_w: Vec<Complex64>,
    /// Block-exponential path: `exp((A - s) h)` and `int exp((A - s) r) dr B`.
    prop: Vec<(DMatrix<Complex64>, DVector<Complex64>)>,
}

impl Scratch {
    fn new(n: usize, n_pieces: usize) -> Self {
        Self {
            e: vec![ZERO; n * n_pieces],
            phi: vec![ZERO; n * n_pieces],
            x: vec![ZERO; n * n_pieces],
            inv_x: vec![ZERO; n * n_pieces],
            zeta: vec![ZERO; n * n_pieces],
            v: vec![ZERO; n],
            u: vec![ZERO; n],
            mat: vec![ZERO; n * n],
            omega: vec![OMEGA_ZERO; n * n_pieces],
            e_w: vec![ZERO; n_pieces],
            prop: Vec::new(),
        }
    }
}

/// `exp(-j theta)` with the phase reduced first, so large arguments keep
/// their digits.
fn cis_neg(theta: f64) -> Complex64 {
    Complex64::from_polar(1.0, -theta.rem_euclid(TAU))
}

/// `1 / z` when `|z| >= SERIES_DIAMETER`, else 0 (the caller then uses a
/// series and never reads it).
fn safe_inverse(z: Complex64) -> Complex64 {
    if z.norm_sqr() >= SERIES_DIAMETER * SERIES_DIAMETER {
        ONE / z
    } else {
        ZERO
    }
}

/// The exact HTF of a SISO [`PiecewiseLti`], jumps included.
///
/// `g(n, w)` is `G_n(jw)` in the estimation convention. It has a pole where
/// `exp(j (w - n wp) T)` is a Floquet multiplier (no periodic steady state);
/// there it is huge, or NaN if the periodicity solve meets an exactly zero
/// pivot.
#[derive(Debug, Clone)]
pub struct ExactHtf {
    period: f64,
    wp: f64,
    n: usize,
    pieces: Vec<PieceData>,
    modal: Option<Modal>,
    multipliers: Vec<Complex64>,
    /// The system itself (what a tangent of [`ExactHtf::derivatives`] must fit).
    lti: PiecewiseLti,
}

impl ExactHtf {
    /// The exact HTF with [`ExactMethod::Auto`].
    pub fn new(lti: &PiecewiseLti) -> Result<Self, TheoryError> {
        Self::with_method(lti, ExactMethod::Auto)
    }

    /// The exact HTF with a chosen integration method. Fails with
    /// [`TheoryError::NotSiso`] for MIMO systems (select a channel with
    /// `PiecewiseLti::channel`) and, for [`ExactMethod::Modal`], with
    /// [`TheoryError::NotDiagonalisable`].
    pub fn with_method(lti: &PiecewiseLti, method: ExactMethod) -> Result<Self, TheoryError> {
        if lti.n_inputs() != 1 || lti.n_outputs() != 1 {
            return Err(TheoryError::NotSiso {
                inputs: lti.n_inputs(),
                outputs: lti.n_outputs(),
            });
        }
        let n = lti.n_states();
        let pieces: Vec<PieceData> = lti
            .pieces()
            .iter()
            .enumerate()
            .map(|(i, p)| PieceData {
                h: p.duration(),
                tau: lti.piece_start(i),
                a: p.a().clone(),
                b: p.b().column(0).into_owned(),
                c: p.c().row(0).transpose(),
                d: p.d()[(0, 0)],
                jump: p.jump_matrix(),
            })
            .collect();
        let modal = match method {
            ExactMethod::BlockExponential => None,
            ExactMethod::Modal => Some(build_modal(&pieces, n)?),
            ExactMethod::Auto => build_modal(&pieces, n).ok(),
        };
        Ok(Self {
            period: lti.period(),
            wp: lti.pumping_frequency(),
            n,
            pieces,
            modal,
            multipliers: Floquet::new(lti).multipliers().to_vec(),
            lti: lti.clone(),
        })
    }

    /// The method in use ([`ExactMethod::Modal`] or
    /// [`ExactMethod::BlockExponential`]).
    pub fn method(&self) -> ExactMethod {
        if self.modal.is_some() {
            ExactMethod::Modal
        } else {
            ExactMethod::BlockExponential
        }
    }

    /// Floquet multipliers of the system; the HTF has poles where
    /// `exp(s T)` equals one of them.
    pub fn floquet_multipliers(&self) -> &[Complex64] {
        &self.multipliers
    }

    /// Steady-state output harmonics for the input `exp(j w_in t)`:
    /// entry `i` is `Y_k` with `k = harmonics[i]`, so that
    /// `y(t) = sum_k Y_k exp(j (w_in + k wp) t)`; equivalently
    /// `Y_k = G_k(j (w_in + k wp))` (a column of Wereley's HTF).
    pub fn response(&self, w_in: f64, harmonics: &[i32]) -> Vec<Complex64> {
        harmonics
            .iter()
            .map(|&k| self.g(k, w_in + f64::from(k) * self.wp))
            .collect()
    }

    fn harmonic_factors(&self, k: i32) -> Vec<HarmonicFactors> {
        let theta = f64::from(k) * self.wp;
        self.pieces
            .iter()
            .map(|p| {
                let b = Complex64::new(0.0, -theta * p.h);
                HarmonicFactors {
                    b,
                    e_b: cis_neg(theta * p.h),
                    phi1_b: phi1_direct(b),
                    inv_b: if k == 0 { ZERO } else { ONE / b },
                    rotation: cis_neg(theta * p.tau),
                }
            })
            .collect()
    }

    /// Fills `scratch.omega` and `scratch.e_w` for output frequency `w`.
    fn omega_factors(&self, modal: &Modal, w: f64, scratch: &mut Scratch) {
        let n = self.n;
        for (i, (p, mp)) in self.pieces.iter().zip(&modal.pieces).enumerate() {
            let e_w = cis_neg(w * p.h);
            scratch.e_w[i] = e_w;
            for j in 0..n {
                let c = Complex64::new(mp.lambda[j].re * p.h, (mp.lambda[j].im - w) * p.h);
                let e_c = mp.e_lambda_h[j] * e_w;
                scratch.omega[i * n + j] = OmegaFactor {
                    c,
                    e_c,
                    phi1_c: phi1(c, e_c),
                    inv_c: safe_inverse(c),
                };
            }
        }
    }

    /// `G_k(jw)` on the modal path, after [`Self::omega_factors`] for `w`;
    /// `hf` are the factors of harmonic `k`. The input frequency is
    /// `w - k wp`, so `x = (lambda - s) h = c - b`.
    fn modal_value(
        &self,
        modal: &Modal,
        hf: &[HarmonicFactors],
        scratch: &mut Scratch,
    ) -> Complex64 {
        let n = self.n;
        // exp(-sT) = prod_i exp(-j w h_i) exp(+j k wp h_i).
        let mut e_st = ONE;
        for (i, f) in hf.iter().enumerate() {
            e_st *= scratch.e_w[i] * f.e_b.conj();
            for j in 0..n {
                let idx = i * n + j;
                let of = scratch.omega[idx];
                let x = of.c - f.b;
                // exp(x) = exp(c) / exp(b), and |exp(b)| = 1.
                let e = of.e_c * f.e_b.conj();
                let inv_x = safe_inverse(x);
                scratch.x[idx] = x;
                scratch.inv_x[idx] = inv_x;
                scratch.e[idx] = e;
                scratch.phi[idx] = if x.norm_sqr() < SERIES_DIAMETER * SERIES_DIAMETER {
                    phi1(x, e)
                } else {
                    (e - ONE) * inv_x
                };
            }
        }
        // psi: one period from the zero state.
        scratch.v.fill(ZERO);
        for (i, (p, mp)) in self.pieces.iter().zip(&modal.pieces).enumerate() {
            modal_step(n, i, p.h, mp, scratch);
        }
        // (I - exp(-sT) Phi_0) zeta_0 = psi.
        for r in 0..n {
            for c in 0..n {
                let id = if r == c { ONE } else { ZERO };
                scratch.mat[r * n + c] = id - e_st * modal.monodromy[r * n + c];
            }
        }
        if !solve_in_place(&mut scratch.mat, &mut scratch.v, n) {
            return Complex64::new(f64::NAN, f64::NAN);
        }
        let mut y = ZERO;
        let n_pieces = self.pieces.len();
        for (i, (p, mp)) in self.pieces.iter().zip(&modal.pieces).enumerate() {
            let f = &hf[i];
            let mut acc = f.phi1_b * p.d;
            for j in 0..n {
                let idx = i * n + j;
                let of = scratch.omega[idx];
                let homogeneous = scratch.v[j] * of.phi1_c;
                let forced = mp.beta[j] * self.dd2_0bc(f, &of, scratch, idx) * p.h;
                acc += mp.gamma[j] * (homogeneous + forced);
            }
            y += f.rotation * acc * p.h;
            if i + 1 < n_pieces {
                modal_step(n, i, p.h, mp, scratch);
            }
        }
        y / self.period
    }

    /// `exp[0, b, c]` from the cached pieces: with `x = c - b`,
    /// `exp[b, c] = e^b phi1(x)`, `exp[0, c] = phi1(c)`, `exp[0, b] = phi1(b)`,
    /// divided by the widest pair's difference (>= 1), or by series for a
    /// tight cluster.
    #[inline]
    fn dd2_0bc(
        &self,
        f: &HarmonicFactors,
        of: &OmegaFactor,
        scratch: &Scratch,
        idx: usize,
    ) -> Complex64 {
        let nb = f.b.norm_sqr();
        let nc = of.c.norm_sqr();
        let nx = scratch.x[idx].norm_sqr();
        let widest = nb.max(nc).max(nx);
        if widest < SERIES_DIAMETER * SERIES_DIAMETER {
            return dd2(ZERO, ONE, f.b, f.e_b, of.c, of.e_c);
        }
        let e_bc = f.e_b * scratch.phi[idx];
        if widest <= nc {
            (e_bc - f.phi1_b) * of.inv_c
        } else if widest <= nb {
            (e_bc - of.phi1_c) * f.inv_b
        } else {
            (of.phi1_c - f.phi1_b) * scratch.inv_x[idx]
        }
    }

    /// `G_k(jw)` on the block-exponential path.
    fn block_value(
        &self,
        w: f64,
        k: i32,
        hf: &[HarmonicFactors],
        scratch: &mut Scratch,
    ) -> Complex64 {
        let w_in = w - f64::from(k) * self.wp;
        if self.solve_state_block(w_in, scratch) {
            self.output_block(w_in, k, hf, scratch)
        } else {
            Complex64::new(f64::NAN, f64::NAN)
        }
    }

    fn solve_state_block(&self, w_in: f64, scratch: &mut Scratch) -> bool {
        let n = self.n;
        let s = Complex64::new(0.0, w_in);
        scratch.prop.clear();
        for p in &self.pieces {
            // exp([[A - sI, B], [0, 0]] h) = [[E, F], [0, 1]].
            let mut aug = DMatrix::<Complex64>::zeros(n + 1, n + 1);
            for r in 0..n {
                for c in 0..n {
                    aug[(r, c)] = Complex64::new(p.a[(r, c)] * p.h, 0.0);
                }
                aug[(r, r)] -= s * p.h;
                aug[(r, n)] = Complex64::new(p.b[r] * p.h, 0.0);
            }
            let ex = expm(&aug);
            let e = ex.view((0, 0), (n, n)).into_owned();
            let f = ex.view((0, n), (n, 1)).column(0).into_owned();
            scratch.prop.push((e, f));
        }
        let n_pieces = self.pieces.len();
        let jump_after = |i: usize| &self.pieces[(i + 1) % n_pieces].jump;
        // Phi = J_0 E_{N-1} J_{N-1} ... J_1 E_0 and psi from the zero state.
        let mut phi = DMatrix::<Complex64>::identity(n, n);
        let mut psi = DVector::<Complex64>::zeros(n);
        for (i, (e, f)) in scratch.prop.iter().enumerate() {
            let j = jump_after(i).map(|v| Complex64::new(v, 0.0));
            phi = &j * (e * phi);
            psi = &j * (e * psi + f);
        }
        let lhs = DMatrix::<Complex64>::identity(n, n) - phi;
        let Some(mut zeta) = lhs.lu().solve(&psi) else {
            return false;
        };
        for i in 0..n_pieces {
            scratch.zeta[i * n..(i + 1) * n].copy_from_slice(zeta.as_slice());
            let (e, f) = &scratch.prop[i];
            let j = jump_after(i).map(|v| Complex64::new(v, 0.0));
            zeta = &j * (e * zeta + f);
        }
        true
    }

    fn output_block(
        &self,
        w_in: f64,
        k: i32,
        hf: &[HarmonicFactors],
        scratch: &Scratch,
    ) -> Complex64 {
        let n = self.n;
        let s = Complex64::new(0.0, w_in);
        let nu = Complex64::new(0.0, -f64::from(k) * self.wp);
        let mut y = ZERO;
        for (i, p) in self.pieces.iter().enumerate() {
            // With q = p exp(nu r), v = exp(nu r), acc' = C q + D v:
            // exp([[A - s + nu, B, 0], [0, nu, 0], [C, D, 0]] h) [p0; 1; 0]
            // ends with acc = int_0^h exp(nu r) (C p(r) + D) dr.
            let mut aug = DMatrix::<Complex64>::zeros(n + 2, n + 2);
            for r in 0..n {
                for c in 0..n {
                    aug[(r, c)] = Complex64::new(p.a[(r, c)] * p.h, 0.0);
                }
                aug[(r, r)] += (nu - s) * p.h;
                aug[(r, n)] = Complex64::new(p.b[r] * p.h, 0.0);
                aug[(n + 1, r)] = Complex64::new(p.c[r] * p.h, 0.0);
            }
            aug[(n, n)] = nu * p.h;
            aug[(n + 1, n)] = Complex64::new(p.d * p.h, 0.0);
            let ex = expm(&aug);
            let mut acc = ex[(n + 1, n)];
            for r in 0..n {
                acc += ex[(n + 1, r)] * scratch.zeta[i * n + r];
            }
            y += hf[i].rotation * acc;
        }
        y / self.period
    }
}

/// `v <- transfer_i (E_i v + h phi_i beta_i)`: one piece in modal
/// coordinates, then the next piece's jump and change of basis.
#[inline]
fn modal_step(n: usize, i: usize, h: f64, mp: &ModalPiece, scratch: &mut Scratch) {
    for j in 0..n {
        scratch.u[j] =
            scratch.e[i * n + j] * scratch.v[j] + scratch.phi[i * n + j] * mp.beta[j] * h;
    }
    for r in 0..n {
        let mut acc = ZERO;
        for c in 0..n {
            acc += mp.transfer[r * n + c] * scratch.u[c];
        }
        scratch.v[r] = acc;
    }
}

impl HarmonicTransferFunction for ExactHtf {
    fn pumping_frequency(&self) -> f64 {
        self.wp
    }

    fn g(&self, n: i32, w: f64) -> Complex64 {
        let mut scratch = Scratch::new(self.n, self.pieces.len());
        let hf = self.harmonic_factors(n);
        match &self.modal {
            Some(modal) => {
                self.omega_factors(modal, w, &mut scratch);
                self.modal_value(modal, &hf, &mut scratch)
            }
            None => self.block_value(w, n, &hf, &mut scratch),
        }
    }

    /// Shares the factors of each harmonic among its points and those of each output
    /// frequency among the points at that frequency (visited in order of frequency); every
    /// value is computed as [`g`](Self::g) computes it.
    fn values(&self, points: &[(i32, f64)]) -> Vec<Complex64> {
        let mut scratch = Scratch::new(self.n, self.pieces.len());
        let mut per_harmonic: Vec<(i32, Vec<HarmonicFactors>)> = Vec::new();
        for &(n, _) in points {
            if !per_harmonic.iter().any(|(k, _)| *k == n) {
                per_harmonic.push((n, self.harmonic_factors(n)));
            }
        }
        let mut order: Vec<usize> = (0..points.len()).collect();
        order.sort_by(|&a, &b| points[a].1.total_cmp(&points[b].1));
        let mut out = vec![ZERO; points.len()];
        let mut factors_of: Option<u64> = None;
        for i in order {
            let (n, w) = points[i];
            let hf = &per_harmonic
                .iter()
                .find(|(k, _)| *k == n)
                .expect("every harmonic's factors were computed above")
                .1;
            out[i] = match &self.modal {
                Some(modal) => {
                    if factors_of != Some(w.to_bits()) {
                        self.omega_factors(modal, w, &mut scratch);
                        factors_of = Some(w.to_bits());
                    }
                    self.modal_value(modal, hf, &mut scratch)
                }
                None => self.block_value(w, n, hf, &mut scratch),
            };
        }
        out
    }

    /// Tabulates with cached factors: those of each output frequency
    /// (`exp((lambda - j w) h)`, its `phi1`) are shared by all harmonics and
    /// those of each harmonic by all frequencies, so on the modal path a
    /// grid point costs a few multiplications and one division per state
    /// and piece, with no transcendental function.
    fn grid(&self, harmonics: &[i32], omegas: &[f64]) -> HtfGrid {
        let mut scratch = Scratch::new(self.n, self.pieces.len());
        let per_harmonic: Vec<Vec<HarmonicFactors>> = harmonics
            .iter()
            .map(|&k| self.harmonic_factors(k))
            .collect();
        let mut values = Vec::with_capacity(harmonics.len() * omegas.len());
        for &w in omegas {
            match &self.modal {
                Some(modal) => {
                    self.omega_factors(modal, w, &mut scratch);
                    for hf in &per_harmonic {
                        values.push(self.modal_value(modal, hf, &mut scratch));
                    }
                }
                None => {
                    for (hf, &k) in per_harmonic.iter().zip(harmonics) {
                        values.push(self.block_value(w, k, hf, &mut scratch));
                    }
                }
            }
        }
        HtfGrid {
            omegas: omegas.to_vec(),
            harmonics: harmonics.to_vec(),
            values,
        }
    }
}

/// Diagonalises every piece and chains the modal transfers.
fn build_modal(pieces: &[PieceData], n: usize) -> Result<Modal, TheoryError> {
    let mut decomps = Vec::with_capacity(pieces.len());
    for (i, p) in pieces.iter().enumerate() {
        let d =
            diagonalise(&p.a).map_err(|(condition, residual)| TheoryError::NotDiagonalisable {
                piece: i,
                condition,
                residual,
            })?;
        decomps.push(d);
    }
    let n_pieces = pieces.len();
    let mut modal_pieces = Vec::with_capacity(n_pieces);
    for (i, (p, (lambda, v, w))) in pieces.iter().zip(&decomps).enumerate() {
        let next = (i + 1) % n_pieces;
        let (_, _, w_next) = &decomps[next];
        let jump = pieces[next].jump.map(|x| Complex64::new(x, 0.0));
        let transfer = w_next * jump * v;
        let b = p.b.map(|x| Complex64::new(x, 0.0));
        let c = p.c.map(|x| Complex64::new(x, 0.0));
        let beta = w * b;
        let gamma = v.transpose() * c;
        modal_pieces.push(ModalPiece {
            lambda: lambda.clone(),
            e_lambda_h: lambda.iter().map(|l| (l * p.h).exp()).collect(),
            beta: beta.iter().copied().collect(),
            gamma: gamma.iter().copied().collect(),
            transfer: row_major(&transfer),
            v: v.clone(),
            v_inv: w.clone(),
        });
    }
    let mut monodromy = DMatrix::<Complex64>::identity(n, n);
    for mp in &modal_pieces {
        let diag = DMatrix::from_diagonal(&DVector::from_column_slice(&mp.e_lambda_h));
        let transfer = DMatrix::from_row_slice(n, n, &mp.transfer);
        monodromy = transfer * diag * monodromy;
    }
    Ok(Modal {
        pieces: modal_pieces,
        monodromy: row_major(&monodromy),
    })
}

fn row_major(m: &DMatrix<Complex64>) -> Vec<Complex64> {
    m.transpose().as_slice().to_vec()
}

type Decomposition = (Vec<Complex64>, DMatrix<Complex64>, DMatrix<Complex64>);

/// `A = V diag(lambda) V^{-1}` with unit eigenvectors from the null spaces
/// of `A - lambda I`; `Err((condition, residual))` when `V` is too ill
/// conditioned or the decomposition does not reproduce `A` (defective `A`).
fn diagonalise(a: &DMatrix<f64>) -> Result<Decomposition, (f64, f64)> {
    let n = a.nrows();
    let raw = a.complex_eigenvalues();
    let scale = a.norm().max(1.0);
    let ac = a.map(|x| Complex64::new(x, 0.0));
    let mut lambda = vec![ZERO; n];
    let mut v = DMatrix::<Complex64>::zeros(n, n);
    let mut done = vec![false; n];
    for i in 0..n {
        if done[i] {
            continue;
        }
        let members: Vec<usize> = (i..n)
            .filter(|&j| !done[j] && (raw[j] - raw[i]).norm() <= EIGEN_CLUSTER_RTOL * scale)
            .collect();
        let mean = members.iter().map(|&j| raw[j]).sum::<Complex64>() / members.len() as f64;
        let shifted = &ac - DMatrix::<Complex64>::identity(n, n) * mean;
        let svd = shifted.svd(false, true);
        let Some(v_t) = svd.v_t else {
            return Err((f64::INFINITY, f64::INFINITY));
        };
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&x, &y| svd.singular_values[x].total_cmp(&svd.singular_values[y]));
        for (slot, &j) in members.iter().enumerate() {
            let row = order[slot];
            for r in 0..n {
                v[(r, j)] = v_t[(row, r)].conj();
            }
            lambda[j] = mean;
            done[j] = true;
        }
    }
    let sv = v.singular_values();
    let (smax, smin) = sv.iter().fold((0.0_f64, f64::INFINITY), |(hi, lo), &x| {
        (hi.max(x), lo.min(x))
    });
    let condition = if smin > 0.0 {
        smax / smin
    } else {
        f64::INFINITY
    };
    let lambda_diag = DMatrix::from_diagonal(&DVector::from_column_slice(&lambda));
    let residual = (&ac * &v - &v * lambda_diag).norm() / a.norm().max(f64::MIN_POSITIVE);
    if !(condition <= MAX_MODAL_CONDITION && residual <= MAX_MODAL_RESIDUAL) {
        return Err((condition, residual));
    }
    let w = v.clone().try_inverse().ok_or((condition, residual))?;
    Ok((lambda, v, w))
}

/// Solves `M x = b` in place by Gaussian elimination with partial pivoting
/// (`m` row-major `n x n`, destroyed; `b` becomes `x`). `false` on a zero or
/// non-finite pivot.
fn solve_in_place(m: &mut [Complex64], b: &mut [Complex64], n: usize) -> bool {
    for col in 0..n {
        let mut pivot = col;
        let mut best = m[col * n + col].norm_sqr();
        for r in col + 1..n {
            let v = m[r * n + col].norm_sqr();
            if v > best {
                best = v;
                pivot = r;
            }
        }
        if !(best > 0.0 && best.is_finite()) {
            return false;
        }
        if pivot != col {
            for c in 0..n {
                m.swap(col * n + c, pivot * n + c);
            }
            b.swap(col, pivot);
        }
        let inv = ONE / m[col * n + col];
        for r in col + 1..n {
            let factor = m[r * n + col] * inv;
            for c in col..n {
                let sub = factor * m[col * n + c];
                m[r * n + c] -= sub;
            }
            let sub = factor * b[col];
            b[r] -= sub;
        }
    }
    for r in (0..n).rev() {
        let mut acc = b[r];
        for c in r + 1..n {
            acc -= m[r * n + c] * b[c];
        }
        b[r] = acc / m[r * n + r];
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solve_in_place_matches_nalgebra() {
        // A fixed, non-symmetric complex 3x3 system; compare with nalgebra's
        // LU (independent implementation) to rounding level.
        let vals = [
            (0.0, 1.0),
            (2.0, -1.0),
            (0.5, 0.0),
            (1.0, 1.0),
            (-3.0, 0.2),
            (0.0, 0.0),
            (4.0, 0.0),
            (0.1, 0.1),
            (1.0, -2.0),
        ];
        let m: Vec<Complex64> = vals.iter().map(|&(r, i)| Complex64::new(r, i)).collect();
        let b = vec![ONE, Complex64::new(0.0, 2.0), Complex64::new(-1.0, 0.5)];
        let mut mm = m.clone();
        let mut x = b.clone();
        assert!(solve_in_place(&mut mm, &mut x, 3));
        let want = DMatrix::from_row_slice(3, 3, &m)
            .lu()
            .solve(&DVector::from_vec(b))
            .expect("nonsingular");
        for i in 0..3 {
            assert!((x[i] - want[i]).norm() < 1e-14);
        }
        let mut singular = vec![ONE, ONE, ONE, ONE];
        let mut rhs = vec![ONE, ONE];
        assert!(!solve_in_place(&mut singular, &mut rhs, 2));
    }

    #[test]
    fn diagonalise_rejects_defective_and_accepts_repeated_diagonalisable() {
        // A Jordan block has one eigenvector: must be refused.
        let jordan = DMatrix::from_row_slice(2, 2, &[-1.0, 1.0, 0.0, -1.0]);
        assert!(diagonalise(&jordan).is_err());
        // -2 I has a two-dimensional eigenspace: must be accepted and exact.
        let scalar = DMatrix::from_row_slice(2, 2, &[-2.0, 0.0, 0.0, -2.0]);
        let (lambda, v, w) = diagonalise(&scalar).expect("diagonalisable");
        for l in &lambda {
            assert!((l - Complex64::new(-2.0, 0.0)).norm() < 1e-14);
        }
        let id = &v * &w;
        assert!((id - DMatrix::<Complex64>::identity(2, 2)).norm() < 1e-14);
        // Complex pair: A V = V diag(lambda) to rounding.
        let osc = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -200.0, -2.0]);
        let (lambda, v, _) = diagonalise(&osc).expect("diagonalisable");
        let ac = osc.map(|x| Complex64::new(x, 0.0));
        let resid = &ac * &v - &v * DMatrix::from_diagonal(&DVector::from_vec(lambda));
        assert!(resid.norm() < 1e-12 * 200.0);
    }
}
