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

/// Eigenvector matrices with a condition number above this send a piece to
/// the block-exponential method: modal errors grow like `cond * eps`.
const MAX_MODAL_CONDITION: f64 = 1e8;
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
}

#[derive(Debug, Clone)]
struct Modal {
    pieces: Vec<ModalPiece>,
    /// Row-major `prod_i transfer_i diag(e_lambda_h_i)`: the monodromy from
    /// `tau_0+` in modal coordinates of piece 0 (without the `exp(-sT)`).
    monodromy: Vec<Complex64>,
}

/// Exponentials of one piece that depend on the harmonic `k` only.
#[derive(Debug, Clone, Copy)]
struct HarmonicFactors {
    /// `exp(b)` with `b = -j k wp h`.
    e_b: Complex64,
    /// `phi1(b)`.
    phi1_b: Complex64,
    /// `exp(-j k wp tau)`.
    rotation: Complex64,
}

/// Per-call buffers, allocated once per `g`/`grid` call.
#[derive(Debug)]
struct Scratch {
    /// `exp((lambda_j - s) h_i)`, piece-major.
    e: Vec<Complex64>,
    /// `phi1((lambda_j - s) h_i)`, piece-major.
    phi: Vec<Complex64>,
    /// Modal (or plain) state after each piece's start jump, piece-major.
    zeta: Vec<Complex64>,
    v: Vec<Complex64>,
    u: Vec<Complex64>,
    mat: Vec<Complex64>,
    /// Block-exponential path: `exp((A - s) h)` and `int exp((A - s) r) dr B`.
    prop: Vec<(DMatrix<Complex64>, DVector<Complex64>)>,
}

impl Scratch {
    fn new(n: usize, n_pieces: usize) -> Self {
        Self {
            e: vec![ZERO; n * n_pieces],
            phi: vec![ZERO; n * n_pieces],
            zeta: vec![ZERO; n * n_pieces],
            v: vec![ZERO; n],
            u: vec![ZERO; n],
            mat: vec![ZERO; n * n],
            prop: Vec::new(),
        }
    }
}

/// The exact HTF of a SISO [`PiecewiseLti`], jumps included.
///
/// `g(n, w)` is `G_n(jw)` in the estimation convention; it is NaN when
/// `exp(j (w - n wp) T)` is a Floquet multiplier (no periodic steady state).
#[derive(Debug, Clone)]
pub struct ExactHtf {
    period: f64,
    wp: f64,
    n: usize,
    pieces: Vec<PieceData>,
    modal: Option<Modal>,
    multipliers: Vec<Complex64>,
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
        let mut scratch = Scratch::new(self.n, self.pieces.len());
        let e_s: Vec<Complex64> = self
            .pieces
            .iter()
            .map(|p| Complex64::from_polar(1.0, -(w_in * p.h).rem_euclid(TAU)))
            .collect();
        let mut factors = vec![self.harmonic_factors_for(0, &self.pieces[0]); self.pieces.len()];
        if !self.solve_state(w_in, &e_s, &mut scratch) {
            return vec![Complex64::new(f64::NAN, f64::NAN); harmonics.len()];
        }
        harmonics
            .iter()
            .map(|&k| {
                for (f, p) in factors.iter_mut().zip(&self.pieces) {
                    *f = self.harmonic_factors_for(k, p);
                }
                self.output(w_in, k, &factors, &mut scratch)
            })
            .collect()
    }

    fn harmonic_factors_for(&self, k: i32, p: &PieceData) -> HarmonicFactors {
        let theta = f64::from(k) * self.wp;
        let b = Complex64::new(0.0, -theta * p.h);
        HarmonicFactors {
            e_b: Complex64::from_polar(1.0, -(theta * p.h).rem_euclid(TAU)),
            phi1_b: phi1_direct(b),
            rotation: Complex64::from_polar(1.0, -(theta * p.tau).rem_euclid(TAU)),
        }
    }

    /// Solves for the periodic state at input frequency `w_in`, given
    /// `e_s[i] = exp(-j w_in h_i)`. Leaves in `scratch.zeta` the (modal)
    /// state after each piece's start jump. Returns `false` if `I - Phi(s)`
    /// is singular.
    fn solve_state(&self, w_in: f64, e_s: &[Complex64], scratch: &mut Scratch) -> bool {
        match &self.modal {
            Some(modal) => self.solve_state_modal(modal, w_in, e_s, scratch),
            None => self.solve_state_block(w_in, scratch),
        }
    }

    /// `Y_k` after [`Self::solve_state`].
    fn output(
        &self,
        w_in: f64,
        k: i32,
        factors: &[HarmonicFactors],
        scratch: &mut Scratch,
    ) -> Complex64 {
        match &self.modal {
            Some(modal) => self.output_modal(modal, w_in, k, factors, scratch),
            None => self.output_block(w_in, k, factors, scratch),
        }
    }

    fn solve_state_modal(
        &self,
        modal: &Modal,
        w_in: f64,
        e_s: &[Complex64],
        scratch: &mut Scratch,
    ) -> bool {
        let n = self.n;
        let s = Complex64::new(0.0, w_in);
        let mut e_st = ONE;
        for (i, (p, mp)) in self.pieces.iter().zip(&modal.pieces).enumerate() {
            e_st *= e_s[i];
            for j in 0..n {
                let x = (mp.lambda[j] - s) * p.h;
                let e = mp.e_lambda_h[j] * e_s[i];
                scratch.e[i * n + j] = e;
                scratch.phi[i * n + j] = phi1(x, e);
            }
        }
        // psi: one period from the zero state.
        scratch.v.fill(ZERO);
        for (i, (p, mp)) in self.pieces.iter().zip(&modal.pieces).enumerate() {
            self.modal_step(i, p, mp, scratch);
        }
        // (I - exp(-sT) Phi_0) zeta_0 = psi.
        for r in 0..n {
            for c in 0..n {
                let id = if r == c { ONE } else { ZERO };
                scratch.mat[r * n + c] = id - e_st * modal.monodromy[r * n + c];
            }
        }
        if !solve_in_place(&mut scratch.mat, &mut scratch.v, n) {
            return false;
        }
        // March the periodic state through the pieces.
        for (i, (p, mp)) in self.pieces.iter().zip(&modal.pieces).enumerate() {
            scratch.zeta[i * n..(i + 1) * n].copy_from_slice(&scratch.v);
            if i + 1 < self.pieces.len() {
                self.modal_step(i, p, mp, scratch);
            }
        }
        true
    }

    /// `v <- transfer_i (E_i v + h phi_i beta_i)`.
    fn modal_step(&self, i: usize, p: &PieceData, mp: &ModalPiece, scratch: &mut Scratch) {
        let n = self.n;
        for j in 0..n {
            scratch.u[j] =
                scratch.e[i * n + j] * scratch.v[j] + scratch.phi[i * n + j] * mp.beta[j] * p.h;
        }
        for r in 0..n {
            let mut acc = ZERO;
            for c in 0..n {
                acc += mp.transfer[r * n + c] * scratch.u[c];
            }
            scratch.v[r] = acc;
        }
    }

    fn output_modal(
        &self,
        modal: &Modal,
        w_in: f64,
        k: i32,
        factors: &[HarmonicFactors],
        scratch: &Scratch,
    ) -> Complex64 {
        let n = self.n;
        let zero = ZERO;
        let mut y = ZERO;
        for (i, (p, mp)) in self.pieces.iter().zip(&modal.pieces).enumerate() {
            let f = &factors[i];
            let b = Complex64::new(0.0, -f64::from(k) * self.wp * p.h);
            let mut acc = f.phi1_b * (p.d * p.h);
            for j in 0..n {
                // c_j = (lambda_j - s) h + b = (lambda_j - j (w_in + k wp)) h.
                let cj = Complex64::new(mp.lambda[j].re * p.h, (mp.lambda[j].im - w_in) * p.h) + b;
                let ec = scratch.e[i * n + j] * f.e_b;
                let homogeneous = scratch.zeta[i * n + j] * phi1(cj, ec);
                let forced = mp.beta[j] * dd2(zero, ONE, b, f.e_b, cj, ec) * p.h;
                acc += mp.gamma[j] * (homogeneous + forced) * p.h;
            }
            y += f.rotation * acc;
        }
        y / self.period
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
        factors: &[HarmonicFactors],
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
            y += factors[i].rotation * acc;
        }
        y / self.period
    }
}

impl HarmonicTransferFunction for ExactHtf {
    fn pumping_frequency(&self) -> f64 {
        self.wp
    }

    fn g(&self, n: i32, w: f64) -> Complex64 {
        let w_in = w - f64::from(n) * self.wp;
        self.response(w_in, &[n])[0]
    }

    /// Tabulates with cached exponentials: `exp(-j w_in h_i)` is the product
    /// of a per-frequency `exp(-j w h_i)` and a per-harmonic
    /// `exp(j n wp h_i)`, so the inner loop evaluates no transcendental
    /// function on the modal path.
    fn grid(&self, harmonics: &[i32], omegas: &[f64]) -> HtfGrid {
        let n_pieces = self.pieces.len();
        let mut scratch = Scratch::new(self.n, n_pieces);
        let per_harmonic: Vec<HarmonicFactors> = harmonics
            .iter()
            .flat_map(|&k| self.pieces.iter().map(move |p| (k, p)))
            .map(|(k, p)| self.harmonic_factors_for(k, p))
            .collect();
        let shift: Vec<Complex64> = harmonics
            .iter()
            .flat_map(|&k| {
                self.pieces.iter().map(move |p| {
                    Complex64::from_polar(1.0, (f64::from(k) * self.wp * p.h).rem_euclid(TAU))
                })
            })
            .collect();
        let mut e_w = vec![ZERO; n_pieces];
        let mut e_s = vec![ZERO; n_pieces];
        let mut values = Vec::with_capacity(harmonics.len() * omegas.len());
        for &w in omegas {
            for (e, p) in e_w.iter_mut().zip(&self.pieces) {
                *e = Complex64::from_polar(1.0, -(w * p.h).rem_euclid(TAU));
            }
            for (ih, &k) in harmonics.iter().enumerate() {
                let w_in = w - f64::from(k) * self.wp;
                for i in 0..n_pieces {
                    e_s[i] = e_w[i] * shift[ih * n_pieces + i];
                }
                let factors = &per_harmonic[ih * n_pieces..(ih + 1) * n_pieces];
                let value = if self.solve_state(w_in, &e_s, &mut scratch) {
                    self.output(w_in, k, factors, &mut scratch)
                } else {
                    Complex64::new(f64::NAN, f64::NAN)
                };
                values.push(value);
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
