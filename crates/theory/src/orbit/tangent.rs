//! Exact derivatives of the HTFs along the orbit by a system's parameters.
//!
//! For the input `exp(j w t)` the steady response is `dx = exp(j w t) q` (`q` periodic,
//! `q' = (A - j w) q + B`, `q+ = S q-` at the switches). A parameter moves the orbit (its
//! sensitivity `z`, periodic), hence `A(t)`, `B(t)`, `C(t)`, `D(t)` along it
//! ([`OrbitTangents::linearisation_change`]), the switches' times (`d tau`) and their
//! saltation matrices ([`OrbitTangents::saltation_change`]). The derivative `r = dq/dp` at a
//! fixed time then follows
//!
//! ```text
//! r' = (A - j w) r + dA q + dB
//! r+ = S r- + dS q- + d tau (S q'- - q'+)
//! ```
//!
//! (the jump's own change, and the stretch of length `d tau` that a moved switch hands from
//! one side's flow to the other's), periodic through the same `I - exp(-j w T) M` as `q`. The
//! output harmonics `(1/T) int (C q + D) exp(-j k wp t) dt` change by the integral of
//! `dC q + C r + dD` and, at each moved switch, by `d tau` times the output's jump there
//! (`y- - y+`) at its phase. Two integrations per input frequency beside the two of the
//! response: from `r = 0` for the periodic start, then from that start with the integrals.

use std::cell::{Cell, RefCell};

use htfid_hybrid::{simulate, Crossing, HybridError, HybridSystem};
use htfid_ltp::{InputOutput, OrbitTangents};
use htfid_orbit::saltation;
use nalgebra::DVector;
use num_complex::Complex64;

use super::{OrbitHtf, NAN, SAME_FREQUENCY_RTOL};
use crate::error::TheoryError;

impl<S: InputOutput> OrbitHtf<'_, S> {
    /// The derivatives of `G_k(jw)` of every output at `points` (`(k, w)`) along each
    /// direction of `tangents`: entry `[o][j][i]` is the rate of change of output `o`'s value
    /// at `points[i]` along direction `j`, exact up to the integrator's tolerance. Points that
    /// share an input frequency share one set of integrations. NaN at a pole.
    ///
    /// # Errors
    /// [`TheoryError::InvalidFrequency`], [`TheoryError::Integration`],
    /// [`TheoryError::StateDimension`] when `tangents.start()` is not `n x k`, or
    /// [`TheoryError::InputAtCrossing`] when a guard or reset on the orbit reads the input and
    /// `tangents` do not give the change of its jump ([`OrbitTangents::input_jump_change`]).
    pub fn derivatives<D: OrbitTangents<Mode = S::Mode>>(
        &self,
        tangents: &D,
        points: &[(i32, f64)],
    ) -> Result<Vec<Vec<Vec<Complex64>>>, TheoryError> {
        let (n, k, p) = (self.system.dim(), tangents.directions(), self.n_outputs());
        if tangents.start().len() != n * k {
            return Err(TheoryError::StateDimension {
                expected: n * k,
                found: tangents.start().len(),
            });
        }
        let mut out = vec![vec![vec![NAN; points.len()]; k]; p];
        let mut order: Vec<(f64, usize)> = points
            .iter()
            .enumerate()
            .map(|(i, &(h, w))| (w - f64::from(h) * self.wp, i))
            .collect();
        order.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut start = 0;
        while start < order.len() {
            let w_in = order[start].0;
            let tol = SAME_FREQUENCY_RTOL * w_in.abs().max(self.wp);
            let end = start
                + order[start..]
                    .iter()
                    .take_while(|(w, _)| (w - w_in).abs() <= tol)
                    .count();
            let group = &order[start..end];
            let mut ks: Vec<i32> = group.iter().map(|&(_, i)| points[i].0).collect();
            ks.sort_unstable();
            ks.dedup();
            let d = self.response_derivatives(tangents, w_in, &ks)?;
            for &(_, i) in group {
                let h = ks.binary_search(&points[i].0).unwrap_or_default();
                for (o, of_output) in out.iter_mut().enumerate() {
                    for (j, column) in of_output.iter_mut().enumerate() {
                        column[i] = d[(h * p + o) * k + j];
                    }
                }
            }
            start = end;
        }
        Ok(out)
    }

    /// Per harmonic `harmonics[h]`, output `o` and direction `j` (at `(h p + o) k + j`), the
    /// derivative of `Y_{o,k}` for the input `exp(j w_in t)` (as [`OrbitHtf::response`]).
    fn response_derivatives<D: OrbitTangents<Mode = S::Mode>>(
        &self,
        tangents: &D,
        w_in: f64,
        harmonics: &[i32],
    ) -> Result<Vec<Complex64>, TheoryError> {
        let (n, k, p) = (self.system.dim(), tangents.directions(), self.n_outputs());
        let nan = || vec![NAN; harmonics.len() * p * k];
        if !w_in.is_finite() {
            return Err(TheoryError::InvalidFrequency { w: w_in });
        }
        let Some((q0, lu)) = self.periodic_start(w_in)? else {
            return Ok(nan());
        };
        let fail = |e: HybridError| TheoryError::Integration {
            w_in,
            reason: e.to_string(),
        };
        let t_end = self.t0 + self.period;
        // From r = 0, the particular end of every direction; then the periodic starts.
        let aug = Moving::new(self, tangents, w_in, &[]);
        let z0 = aug.initial_state(&q0, &vec![Complex64::new(0.0, 0.0); n * k]);
        let part =
            simulate(&aug, self.mode0, self.t0, &z0, t_end, &[], &self.opts).map_err(fail)?;
        if aug.input_at_crossing.get() {
            return Err(TheoryError::InputAtCrossing);
        }
        let mut r0 = vec![Complex64::new(0.0, 0.0); n * k];
        for j in 0..k {
            let end = DVector::from_fn(n, |i, _| aug.read_r(&part.final_state, i, j));
            let Some(start) = lu.solve(&end) else {
                return Ok(nan());
            };
            for i in 0..n {
                r0[i * k + j] = start[i];
            }
        }
        let aug = Moving::new(self, tangents, w_in, harmonics);
        let z0 = aug.initial_state(&q0, &r0);
        let steady =
            simulate(&aug, self.mode0, self.t0, &z0, t_end, &[], &self.opts).map_err(fail)?;
        let mut out = Vec::with_capacity(harmonics.len() * p * k);
        for (h, &kh) in harmonics.iter().enumerate() {
            // The integrals ran in time relative to t0; rotate to absolute time.
            let rotation = Complex64::from_polar(
                1.0,
                -(f64::from(kh) * self.wp * self.t0).rem_euclid(std::f64::consts::TAU),
            );
            for o in 0..p {
                for j in 0..k {
                    out.push(
                        aug.read_integral(&steady.final_state, (h * p + o) * k + j) * rotation,
                    );
                }
            }
        }
        Ok(out)
    }
}

/// Buffers for one evaluation.
struct Scratch {
    jac: Vec<f64>,
    b: Vec<f64>,
    c: Vec<f64>,
    d: Vec<f64>,
    da: Vec<f64>,
    db: Vec<f64>,
    dc: Vec<f64>,
    dd: Vec<f64>,
    q: Vec<Complex64>,
    r: Vec<Complex64>,
    y: Vec<Complex64>,
}

/// The system with its orbit's sensitivity, the response `q`, its derivatives `r` and their
/// output integrals. State: `[x (n), z (n x k), Re q, Im q (n each), Re r, Im r (n x k each),
/// then per harmonic h, output o and direction j the (Re, Im) of the integral of that output's
/// derivative]`.
struct Moving<'h, 'a, S: InputOutput, D> {
    htf: &'h OrbitHtf<'a, S>,
    tangents: &'h D,
    n: usize,
    k: usize,
    p: usize,
    w_in: f64,
    harmonics: &'h [i32],
    scratch: RefCell<Scratch>,
    /// Set when a crossing's guard or reset reads the input and the tangents do not give the
    /// change of its jump per unit input.
    input_at_crossing: Cell<bool>,
}

impl<'h, 'a, S: InputOutput, D: OrbitTangents<Mode = S::Mode>> Moving<'h, 'a, S, D> {
    fn new(htf: &'h OrbitHtf<'a, S>, tangents: &'h D, w_in: f64, harmonics: &'h [i32]) -> Self {
        let n = htf.system.dim();
        let p = htf.system.num_outputs();
        let k = tangents.directions();
        let zero = Complex64::new(0.0, 0.0);
        Self {
            htf,
            tangents,
            n,
            k,
            p,
            w_in,
            harmonics,
            scratch: RefCell::new(Scratch {
                jac: vec![0.0; n * n],
                b: vec![0.0; n],
                c: vec![0.0; p * n],
                d: vec![0.0; p],
                da: vec![0.0; k * n * n],
                db: vec![0.0; k * n],
                dc: vec![0.0; k * p * n],
                dd: vec![0.0; k * p],
                q: vec![zero; n],
                r: vec![zero; n * k],
                y: vec![zero; p],
            }),
            input_at_crossing: Cell::new(false),
        }
    }

    // Offsets of the blocks of the state.
    fn z_at(&self) -> usize {
        self.n
    }
    fn q_at(&self) -> usize {
        self.n + self.n * self.k
    }
    fn r_at(&self) -> usize {
        3 * self.n + self.n * self.k
    }
    fn integrals_at(&self) -> usize {
        3 * self.n + 3 * self.n * self.k
    }

    fn initial_state(&self, q0: &DVector<Complex64>, r0: &[Complex64]) -> Vec<f64> {
        let (n, k) = (self.n, self.k);
        let mut s = vec![0.0; self.dim()];
        s[..n].copy_from_slice(&self.htf.state0);
        s[self.z_at()..self.q_at()].copy_from_slice(self.tangents.start());
        for i in 0..n {
            s[self.q_at() + i] = q0[i].re;
            s[self.q_at() + n + i] = q0[i].im;
        }
        for (at, v) in r0.iter().enumerate() {
            s[self.r_at() + at] = v.re;
            s[self.r_at() + n * k + at] = v.im;
        }
        s
    }

    /// `r_{i, j}` from a state.
    fn read_r(&self, s: &[f64], i: usize, j: usize) -> Complex64 {
        let at = self.r_at() + i * self.k + j;
        Complex64::new(s[at], s[at + self.n * self.k])
    }

    /// Integral number `at` (`(h p + o) k + j`) from a state.
    fn read_integral(&self, s: &[f64], at: usize) -> Complex64 {
        let at = self.integrals_at() + 2 * at;
        Complex64::new(s[at], s[at + 1])
    }

    /// `q` and `r` from a state into `q` (`n`) and `r` (`n x k`).
    fn read_responses(&self, s: &[f64], q: &mut [Complex64], r: &mut [Complex64]) {
        let (n, nk) = (self.n, self.n * self.k);
        let (q_at, r_at) = (self.q_at(), self.r_at());
        for (i, v) in q.iter_mut().enumerate() {
            *v = Complex64::new(s[q_at + i], s[q_at + n + i]);
        }
        for (at, v) in r.iter_mut().enumerate() {
            *v = Complex64::new(s[r_at + at], s[r_at + nk + at]);
        }
    }

    /// `A` (into `jac`) and `B` (into `b`) at `(mode, t, x)`.
    fn linear(&self, mode: S::Mode, t: f64, x: &[f64], sc: &mut Scratch) {
        let sys = self.htf.system;
        super::state_jacobian(sys, mode, t, x, &mut sc.jac);
        sys.input_gain(mode, t, x, &mut sc.b);
    }

    /// `(A - j w) q + B` with `A`, `B` in `sc`.
    fn flow(&self, sc: &Scratch, q: &[Complex64]) -> Vec<Complex64> {
        let n = self.n;
        let jw = Complex64::new(0.0, self.w_in);
        (0..n)
            .map(|i| {
                let row = &sc.jac[i * n..(i + 1) * n];
                row.iter().zip(q).map(|(a, q)| q * *a).sum::<Complex64>() - jw * q[i] + sc.b[i]
            })
            .collect()
    }

    /// `y = C q + D` of every output at `(mode, t, x)`, into `sc.y` (`C`, `D` into `sc`).
    fn outputs(&self, mode: S::Mode, t: f64, x: &[f64], q: &[Complex64], sc: &mut Scratch) {
        let (sys, n) = (self.htf.system, self.n);
        sys.output_gain(mode, t, x, &mut sc.c);
        sys.feedthrough(mode, t, x, &mut sc.d);
        for o in 0..self.p {
            let row = &sc.c[o * n..(o + 1) * n];
            sc.y[o] = row.iter().zip(q).map(|(c, q)| q * *c).sum::<Complex64>() + sc.d[o];
        }
    }
}

impl<S: InputOutput, D: OrbitTangents<Mode = S::Mode>> HybridSystem for Moving<'_, '_, S, D> {
    type Mode = S::Mode;

    fn dim(&self) -> usize {
        self.integrals_at() + 2 * self.harmonics.len() * self.p * self.k
    }

    fn vector_field(&self, mode: S::Mode, t: f64, s: &[f64], ds: &mut [f64]) {
        let (n, k, p, w) = (self.n, self.k, self.p, self.w_in);
        let sys = self.htf.system;
        let x = &s[..n];
        sys.vector_field(mode, t, x, &mut ds[..n]);
        let (z_at, q_at, r_at) = (self.z_at(), self.q_at(), self.r_at());
        let z = &s[z_at..q_at];
        self.tangents
            .sensitivity_field(mode, t, x, z, &mut ds[z_at..q_at]);
        let mut guard = self.scratch.borrow_mut();
        let sc = &mut *guard;
        self.linear(mode, t, x, sc);
        let (mut q, mut r) = (std::mem::take(&mut sc.q), std::mem::take(&mut sc.r));
        self.read_responses(s, &mut q, &mut r);
        let jw = Complex64::new(0.0, w);
        for i in 0..n {
            let row = &sc.jac[i * n..(i + 1) * n];
            let aq: Complex64 = row.iter().zip(&q).map(|(a, q)| q * *a).sum();
            // (A - j w) q + B.
            let v = aq - jw * q[i] + sc.b[i];
            ds[q_at + i] = v.re;
            ds[q_at + n + i] = v.im;
        }
        let with_integrals = !self.harmonics.is_empty();
        if with_integrals {
            sys.output_gain(mode, t, x, &mut sc.c);
            sys.feedthrough(mode, t, x, &mut sc.d);
        }
        {
            let Scratch { da, db, dc, dd, .. } = &mut *sc;
            self.tangents
                .linearisation_change(mode, t, x, z, da, db, dc, dd);
        }
        // r_j' = (A - j w) r_j + dA_j q + dB_j.
        for j in 0..k {
            let (da, db) = (
                &sc.da[j * n * n..(j + 1) * n * n],
                &sc.db[j * n..(j + 1) * n],
            );
            for i in 0..n {
                let row = &sc.jac[i * n..(i + 1) * n];
                let drow = &da[i * n..(i + 1) * n];
                let mut v = Complex64::new(db[i], 0.0) - jw * r[i * k + j];
                for l in 0..n {
                    v += r[l * k + j] * row[l] + q[l] * drow[l];
                }
                let at = r_at + i * k + j;
                ds[at] = v.re;
                ds[at + n * k] = v.im;
            }
        }
        if with_integrals {
            // (dC_j q + C r_j + dD_j) / T, rotated to each harmonic.
            let inv_t = 1.0 / self.htf.period;
            let base = Complex64::from_polar(1.0, -self.htf.wp * (t - self.htf.t0));
            let rotations: Vec<Complex64> =
                self.harmonics.iter().map(|&kh| base.powi(kh)).collect();
            for o in 0..p {
                let crow = &sc.c[o * n..(o + 1) * n];
                for j in 0..k {
                    let dc = &sc.dc[(j * p + o) * n..(j * p + o + 1) * n];
                    let mut dy = Complex64::new(sc.dd[j * p + o], 0.0);
                    for l in 0..n {
                        dy += q[l] * dc[l] + r[l * k + j] * crow[l];
                    }
                    let dy = dy * inv_t;
                    for (h, rotation) in rotations.iter().enumerate() {
                        let v = dy * rotation;
                        let at = self.integrals_at() + 2 * ((h * p + o) * k + j);
                        ds[at] = v.re;
                        ds[at + 1] = v.im;
                    }
                }
            }
        }
        sc.q = q;
        sc.r = r;
    }

    fn num_guards(&self, mode: S::Mode) -> usize {
        self.htf.system.num_guards(mode)
    }

    fn guard(&self, mode: S::Mode, index: usize, t: f64, s: &[f64]) -> f64 {
        self.htf.system.guard(mode, index, t, &s[..self.n])
    }

    fn guard_direction(&self, mode: S::Mode, index: usize) -> Crossing {
        self.htf.system.guard_direction(mode, index)
    }

    fn transition(&self, mode: S::Mode, index: usize, t: f64, s: &mut [f64]) -> S::Mode {
        let (n, k, p) = (self.n, self.k, self.p);
        let sys = self.htf.system;
        let (z_at, q_at, r_at) = (self.z_at(), self.q_at(), self.r_at());
        let x_minus = s[..n].to_vec();
        let z_minus = s[z_at..q_at].to_vec();
        let zero = Complex64::new(0.0, 0.0);
        let (mut q_minus, mut r_minus) = (vec![zero; n], vec![zero; n * k]);
        self.read_responses(s, &mut q_minus, &mut r_minus);
        let (salt, to) = saltation(sys, mode, index, t, &x_minus);
        let input_jump = super::input_jump(sys, mode, index, t, &x_minus);
        let mut f_minus = vec![0.0; n];
        sys.vector_field(mode, t, &x_minus, &mut f_minus);
        let mut guard = self.scratch.borrow_mut();
        let sc = &mut *guard;
        let with_integrals = !self.harmonics.is_empty();
        // q' and the outputs on either side of the crossing.
        self.linear(mode, t, &x_minus, sc);
        let qdot_minus = self.flow(sc, &q_minus);
        if with_integrals {
            self.outputs(mode, t, &x_minus, &q_minus, sc);
        }
        let y_minus = sc.y.clone();
        // The state, its sensitivity and the response through the crossing.
        let to_check = sys.transition(mode, index, t, &mut s[..n]);
        debug_assert_eq!(to_check, to, "transition must be deterministic");
        let x_plus = s[..n].to_vec();
        let mut dtau = vec![0.0; k];
        self.tangents
            .sensitivity_jump(mode, index, t, &x_minus, &mut s[z_at..q_at], &mut dtau);
        let q_plus: Vec<Complex64> = (0..n)
            .map(|i| {
                let own = input_jump.as_ref().map_or(0.0, |e| e[i]);
                (0..n).map(|l| q_minus[l] * salt[(i, l)]).sum::<Complex64>() + own
            })
            .collect();
        for i in 0..n {
            s[q_at + i] = q_plus[i].re;
            s[q_at + n + i] = q_plus[i].im;
        }
        self.linear(to, t, &x_plus, sc);
        let qdot_plus = self.flow(sc, &q_plus);
        if with_integrals {
            self.outputs(to, t, &x_plus, &q_plus, sc);
        }
        // The stretch a moved crossing hands over: S q'- - q'+.
        let handed: Vec<Complex64> = (0..n)
            .map(|i| {
                (0..n)
                    .map(|l| qdot_minus[l] * salt[(i, l)])
                    .sum::<Complex64>()
                    - qdot_plus[i]
            })
            .collect();
        let base = Complex64::from_polar(1.0, -self.htf.wp * (t - self.htf.t0));
        let mut ds = vec![0.0; n * n];
        let mut de = vec![0.0; n];
        let mut dx = vec![0.0; n];
        for j in 0..k {
            for l in 0..n {
                dx[l] = z_minus[l * k + j] + f_minus[l] * dtau[j];
            }
            self.tangents
                .saltation_change(mode, index, t, &x_minus, j, &dx, dtau[j], &mut ds);
            // The change of the input's own jump, where the crossing reads the input.
            de.fill(0.0);
            if input_jump.is_some()
                && !self
                    .tangents
                    .input_jump_change(mode, index, t, &x_minus, j, &dx, dtau[j], &mut de)
            {
                self.input_at_crossing.set(true);
            }
            for i in 0..n {
                let mut v = handed[i] * dtau[j] + de[i];
                for l in 0..n {
                    v += r_minus[l * k + j] * salt[(i, l)] + q_minus[l] * ds[i * n + l];
                }
                let at = r_at + i * k + j;
                s[at] = v.re;
                s[at + n * k] = v.im;
            }
            if with_integrals {
                // The output's jump, for the stretch by which the crossing moved.
                for o in 0..p {
                    let jump = (y_minus[o] - sc.y[o]) * (dtau[j] / self.htf.period);
                    for (h, &kh) in self.harmonics.iter().enumerate() {
                        let v = jump * base.powi(kh);
                        let at = self.integrals_at() + 2 * ((h * p + o) * k + j);
                        s[at] += v.re;
                        s[at + 1] += v.im;
                    }
                }
            }
        }
        to
    }
}
