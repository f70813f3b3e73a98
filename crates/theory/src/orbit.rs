//! HTFs of the linearisation of any hybrid system about its limit cycle, integrated along the
//! orbit by the one hybrid integrator (no piecewise-constant approximation of `A(t)`).
//!
//! For the input `u = exp(j w t)` the steady state of the linearisation is
//! `dx(t) = exp(j w t) q(t)` with `q` T-periodic,
//! `q' = (A(t) - j w I) q + B(t)` between switches and `q+ = S q-` at every switch (`S` the
//! saltation matrix). Each frequency costs two integrations over one period of an augmented
//! [`HybridSystem`] whose state is `[x_orbit, Re q, Im q, Fourier integrals]`, whose guards are
//! the model's own guards on `x_orbit` and whose reset applies the model's reset to `x_orbit`
//! and `S` to `q`. See the crate docs, section "HTFs along the orbit".

use std::cell::RefCell;
use std::fmt;

use htfid_hybrid::{simulate, Crossing, HybridSystem, Options};
use htfid_ltp::InputOutput;
use htfid_orbit::{period_map, saltation, transition_jump, vector_field_jacobian, LimitCycle};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;
use std::f64::consts::TAU;

use crate::error::TheoryError;
use crate::grid::{HarmonicTransferFunction, HtfGrid};

/// The cycle must return to its start within this, relative to `max(1, |x|_inf)`, under the
/// HTF's integrator options: far above the error of any sensible tolerance, far below a cycle
/// of a different system or one computed with the input on.
const PERIODICITY_RTOL: f64 = 1e-6;

/// Input frequencies closer than this (relative to `max(|w_in|, wp)`) share one integration in
/// [`OrbitHtf::grids`]. Moving the input frequency by `1e-12 wp` moves `G` by far less than
/// the integrator's error.
const SAME_FREQUENCY_RTOL: f64 = 1e-12;

const NAN: Complex64 = Complex64::new(f64::NAN, f64::NAN);

/// `I - exp(-j w_in T) M`, factorised.
type Periodicity = nalgebra::linalg::LU<Complex64, nalgebra::Dyn, nalgebra::Dyn>;

mod tangent;

/// The harmonic transfer functions of the linearisation of an [`InputOutput`] system about a
/// [`LimitCycle`], exact up to the integrator's tolerance: `A(t)`, `B(t)`, `C(t)`, `D(t)` are
/// evaluated along the orbit as it is integrated (no averaging per chart), and the saltation
/// matrix is applied at every switch. One input, [`InputOutput::num_outputs`] outputs.
///
/// [`OrbitHtf::response`] gives every output and harmonic for one input frequency;
/// [`OrbitHtf::grids`] tabulates every output. The [`HarmonicTransferFunction`] implementation
/// reads one output, [`OrbitHtf::output`] (0 unless chosen with [`OrbitHtf::channel`]); its `g`
/// and `grid` return NaN where an integration fails, [`OrbitHtf::response`] and
/// [`OrbitHtf::grids`] the error.
///
/// Cost: two integrations of `3 n + 2 p H` real states over one period per distinct input
/// frequency (`n` states, `p` outputs, `H` harmonics asked for at that frequency).
pub struct OrbitHtf<'a, S: InputOutput> {
    system: &'a S,
    period: f64,
    wp: f64,
    t0: f64,
    state0: Vec<f64>,
    mode0: S::Mode,
    monodromy: DMatrix<f64>,
    multipliers: Vec<Complex64>,
    opts: Options,
    output: usize,
}

impl<S: InputOutput> fmt::Debug for OrbitHtf<'_, S> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("OrbitHtf")
            .field("period", &self.period)
            .field("t0", &self.t0)
            .field("state0", &self.state0)
            .field("mode0", &self.mode0)
            .field("monodromy", &self.monodromy)
            .field("opts", &self.opts)
            .field("output", &self.output)
            .finish_non_exhaustive()
    }
}

// Derived Clone would demand `S: Clone`; only the reference is copied.
impl<S: InputOutput> Clone for OrbitHtf<'_, S> {
    fn clone(&self) -> Self {
        Self {
            system: self.system,
            period: self.period,
            wp: self.wp,
            t0: self.t0,
            state0: self.state0.clone(),
            mode0: self.mode0,
            monodromy: self.monodromy.clone(),
            multipliers: self.multipliers.clone(),
            opts: self.opts.clone(),
            output: self.output,
        }
    }
}

impl<'a, S: InputOutput> OrbitHtf<'a, S> {
    /// The HTFs of `system` linearised about `cycle`, integrated with `opts` (which set the
    /// accuracy: every value is exact up to the integrator's error).
    ///
    /// The monodromy matrix is recomputed over one period from `cycle.state0` with `opts`
    /// (saltations included), so that it matches the integrations of every frequency.
    ///
    /// # Errors
    /// [`TheoryError::InvalidPeriod`], [`TheoryError::StateDimension`] when `cycle.state0`
    /// does not have [`HybridSystem::dim`] entries, [`TheoryError::NoOutputs`],
    /// [`TheoryError::Orbit`] when the integration over the cycle fails, and
    /// [`TheoryError::NotPeriodic`] when `cycle` does not return to its start within
    /// `1e-6 max(1, |x|_inf)` (a cycle of another system, or computed with the input on).
    pub fn new(
        system: &'a S,
        cycle: &LimitCycle<S::Mode>,
        opts: &Options,
    ) -> Result<Self, TheoryError> {
        let period = cycle.period;
        if !(period.is_finite() && period > 0.0) {
            return Err(TheoryError::InvalidPeriod { period });
        }
        let n = system.dim();
        if cycle.state0.len() != n {
            return Err(TheoryError::StateDimension {
                expected: n,
                found: cycle.state0.len(),
            });
        }
        if system.num_outputs() == 0 {
            return Err(TheoryError::NoOutputs);
        }
        let map = period_map(system, cycle.mode0, cycle.t0, &cycle.state0, period, opts)
            .map_err(|e| TheoryError::Orbit(e.to_string()))?;
        // The responses below integrate the variational equations, which do not hold through
        // sliding (see htfid-orbit's period_map): refuse rather than give a wrong HTF.
        if let Some(first) = map.sliding.first() {
            return Err(TheoryError::Ltp(htfid_ltp::LtpError::SlidingOrbit {
                guard: first.guard,
                start: first.start,
                end: first.end,
                intervals: map.sliding.len(),
            }));
        }
        htfid_ltp::refuse_grazes(cycle)?;
        let residual = map
            .state
            .iter()
            .zip(&cycle.state0)
            .map(|(a, b)| (a - b).abs())
            // Unlike f64::max, keeps a NaN (a state gone non-finite) so that it fails below.
            .fold(0.0, |m: f64, d| if d > m || d.is_nan() { d } else { m });
        let scale = cycle.state0.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
        let tolerance = PERIODICITY_RTOL * scale;
        if residual.is_nan() || residual > tolerance || map.mode != cycle.mode0 {
            return Err(TheoryError::NotPeriodic {
                residual,
                tolerance,
            });
        }
        let mut multipliers: Vec<Complex64> = map
            .jacobian
            .complex_eigenvalues()
            .iter()
            .map(|c| Complex64::new(c.re, c.im))
            .collect();
        multipliers.sort_by(|a, b| b.norm().total_cmp(&a.norm()).then(b.im.total_cmp(&a.im)));
        Ok(Self {
            system,
            period,
            wp: TAU / period,
            t0: cycle.t0,
            state0: cycle.state0.clone(),
            mode0: cycle.mode0,
            monodromy: map.jacobian,
            multipliers,
            opts: opts.clone(),
            output: 0,
        })
    }

    /// The same HTFs with output `output` selected for [`HarmonicTransferFunction`].
    ///
    /// # Errors
    /// [`TheoryError::OutputOutOfRange`].
    pub fn channel(&self, output: usize) -> Result<Self, TheoryError> {
        let n_outputs = self.n_outputs();
        if output >= n_outputs {
            return Err(TheoryError::OutputOutOfRange { output, n_outputs });
        }
        Ok(Self {
            output,
            ..self.clone()
        })
    }

    /// The output read by [`HarmonicTransferFunction`].
    pub fn output(&self) -> usize {
        self.output
    }

    /// Number of outputs `p`.
    pub fn n_outputs(&self) -> usize {
        self.system.num_outputs()
    }

    /// The period `T`.
    pub fn period(&self) -> f64 {
        self.period
    }

    /// The monodromy matrix over one period from the cycle's phase origin, saltations included,
    /// as integrated with this HTF's options.
    pub fn monodromy(&self) -> &DMatrix<f64> {
        &self.monodromy
    }

    /// Floquet multipliers (eigenvalues of [`OrbitHtf::monodromy`]), largest modulus first;
    /// the HTFs have poles where `exp(j w_in T)` equals one of them.
    pub fn floquet_multipliers(&self) -> &[Complex64] {
        &self.multipliers
    }

    /// Steady-state output harmonics for the input `exp(j w_in t)`: entry `(o, i)` is
    /// `Y_{o,k}` with `k = harmonics[i]`, so that output `o` is
    /// `y_o(t) = sum_k Y_{o,k} exp(j (w_in + k wp) t)`; equivalently
    /// `Y_{o,k} = G_k(j (w_in + k wp))` of output `o` in the estimation convention.
    /// Entries are NaN when `exp(j w_in T)` is exactly a Floquet multiplier.
    ///
    /// # Errors
    /// [`TheoryError::InvalidFrequency`] for a non-finite `w_in`, [`TheoryError::Integration`]
    /// when the integrator fails.
    pub fn response(
        &self,
        w_in: f64,
        harmonics: &[i32],
    ) -> Result<DMatrix<Complex64>, TheoryError> {
        if !w_in.is_finite() {
            return Err(TheoryError::InvalidFrequency { w: w_in });
        }
        let n = self.system.dim();
        let p = self.n_outputs();
        let fail = |e: htfid_hybrid::HybridError| TheoryError::Integration {
            w_in,
            reason: e.to_string(),
        };
        let t_end = self.t0 + self.period;
        let Some((q0, _)) = self.periodic_start(w_in)? else {
            return Ok(DMatrix::from_element(p, harmonics.len(), NAN));
        };
        // Pass 2: the periodic response from q0, with the Fourier integrals.
        let aug = Augmented::new(self, w_in, harmonics);
        let z0 = aug.initial_state(&self.state0, &q0);
        let steady =
            simulate(&aug, self.mode0, self.t0, &z0, t_end, &[], &self.opts).map_err(fail)?;
        let fourier = &steady.final_state[3 * n..];
        Ok(DMatrix::from_fn(p, harmonics.len(), |o, h| {
            let idx = 2 * (h * p + o);
            // The integrals ran in time relative to t0; rotate to absolute time.
            let rotation = Complex64::from_polar(
                1.0,
                -(f64::from(harmonics[h]) * self.wp * self.t0).rem_euclid(TAU),
            );
            Complex64::new(fourier[idx], fourier[idx + 1]) * rotation
        }))
    }

    /// The periodic response's start `q(t0)` for the input `exp(j w_in t)`, with the
    /// factorised `I - exp(-j w_in T) M` that gives it (the derivatives solve with it too);
    /// `None` when that matrix is singular (`exp(j w_in T)` a Floquet multiplier).
    fn periodic_start(
        &self,
        w_in: f64,
    ) -> Result<Option<(DVector<Complex64>, Periodicity)>, TheoryError> {
        let n = self.system.dim();
        // The response from q(t0) = 0 over one period.
        let aug = Augmented::new(self, w_in, &[]);
        let z0 = aug.initial_state(&self.state0, &DVector::zeros(n));
        let part = simulate(
            &aug,
            self.mode0,
            self.t0,
            &z0,
            self.t0 + self.period,
            &[],
            &self.opts,
        )
        .map_err(|e| TheoryError::Integration {
            w_in,
            reason: e.to_string(),
        })?;
        let q_part = DVector::from_iterator(
            n,
            (0..n).map(|i| Complex64::new(part.final_state[n + i], part.final_state[2 * n + i])),
        );
        // Periodicity: q(t0 + T) = exp(-j w T) M q0 + q_part(T) = q0.
        let phase = Complex64::from_polar(1.0, -(w_in * self.period).rem_euclid(TAU));
        let lu = (DMatrix::<Complex64>::identity(n, n)
            - self.monodromy.map(|v| Complex64::new(v, 0.0)) * phase)
            .lu();
        Ok(lu.solve(&q_part).map(|q0| (q0, lu)))
    }

    /// `G_n(jw)` of every output on `omegas x harmonics`, one [`HtfGrid`] per output. Grid
    /// points with the same input frequency `w - n wp` (within `1e-12 max(|w_in|, wp)`)
    /// share one pair of integrations.
    ///
    /// # Errors
    /// As [`OrbitHtf::response`].
    pub fn grids(&self, harmonics: &[i32], omegas: &[f64]) -> Result<Vec<HtfGrid>, TheoryError> {
        let nh = harmonics.len();
        let p = self.n_outputs();
        let mut values = vec![vec![NAN; omegas.len() * nh]; p];
        // (w_in, grid index), grouped by input frequency.
        let mut points: Vec<(f64, usize)> = omegas
            .iter()
            .enumerate()
            .flat_map(|(iw, &w)| {
                harmonics
                    .iter()
                    .enumerate()
                    .map(move |(ih, &k)| (w - f64::from(k) * self.wp, iw * nh + ih))
            })
            .collect();
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut start = 0;
        while start < points.len() {
            let w_in = points[start].0;
            let tol = SAME_FREQUENCY_RTOL * w_in.abs().max(self.wp);
            let end = start
                + points[start..]
                    .iter()
                    .take_while(|(w, _)| (w - w_in).abs() <= tol)
                    .count();
            let group = &points[start..end];
            let mut ks: Vec<i32> = group.iter().map(|&(_, idx)| harmonics[idx % nh]).collect();
            ks.sort_unstable();
            ks.dedup();
            let y = self.response(w_in, &ks)?;
            for &(_, idx) in group {
                let col = ks.binary_search(&harmonics[idx % nh]).unwrap_or_default();
                for (o, out) in values.iter_mut().enumerate() {
                    out[idx] = y[(o, col)];
                }
            }
            start = end;
        }
        Ok(values
            .into_iter()
            .map(|values| HtfGrid {
                omegas: omegas.to_vec(),
                harmonics: harmonics.to_vec(),
                values,
            })
            .collect())
    }
}

impl<S: InputOutput> HarmonicTransferFunction for OrbitHtf<'_, S> {
    fn pumping_frequency(&self) -> f64 {
        self.wp
    }

    /// `G_n(jw)` of output [`OrbitHtf::output`]; NaN if the integration fails.
    fn g(&self, n: i32, w: f64) -> Complex64 {
        self.response(w - f64::from(n) * self.wp, &[n])
            .map_or(NAN, |y| y[(self.output, 0)])
    }

    /// One pair of integrations per distinct input frequency; all NaN if one fails.
    fn grid(&self, harmonics: &[i32], omegas: &[f64]) -> HtfGrid {
        match self.grids(harmonics, omegas) {
            Ok(mut grids) => grids.swap_remove(self.output),
            Err(_) => HtfGrid {
                omegas: omegas.to_vec(),
                harmonics: harmonics.to_vec(),
                values: vec![NAN; omegas.len() * harmonics.len()],
            },
        }
    }
}

/// Buffers for one evaluation of the linearisation.
#[derive(Debug)]
struct Scratch {
    jac: Vec<f64>,
    b: Vec<f64>,
    c: Vec<f64>,
    d: Vec<f64>,
    y: Vec<Complex64>,
}

/// The model augmented with the steady-state response `q` and its Fourier integrals. State:
/// `[x (n), Re q (n), Im q (n), (Re, Im) of I_{o,k} for each harmonic k, output o]` with
/// `I_{o,k}(t) = (1/T) int_{t0}^{t} (C_o q + D_o) exp(-j k wp (r - t0)) dr`.
struct Augmented<'h, 'a, S: InputOutput> {
    htf: &'h OrbitHtf<'a, S>,
    n: usize,
    p: usize,
    w_in: f64,
    harmonics: &'h [i32],
    scratch: RefCell<Scratch>,
}

impl<'h, 'a, S: InputOutput> Augmented<'h, 'a, S> {
    fn new(htf: &'h OrbitHtf<'a, S>, w_in: f64, harmonics: &'h [i32]) -> Self {
        let n = htf.system.dim();
        let p = htf.system.num_outputs();
        Self {
            htf,
            n,
            p,
            w_in,
            harmonics,
            scratch: RefCell::new(Scratch {
                jac: vec![0.0; n * n],
                b: vec![0.0; n],
                c: vec![0.0; p * n],
                d: vec![0.0; p],
                y: vec![Complex64::new(0.0, 0.0); p],
            }),
        }
    }

    fn initial_state(&self, x0: &[f64], q0: &DVector<Complex64>) -> Vec<f64> {
        let n = self.n;
        let mut z = vec![0.0; self.dim()];
        z[..n].copy_from_slice(x0);
        for i in 0..n {
            z[n + i] = q0[i].re;
            z[2 * n + i] = q0[i].im;
        }
        z
    }
}

impl<S: InputOutput> HybridSystem for Augmented<'_, '_, S> {
    type Mode = S::Mode;

    fn dim(&self) -> usize {
        3 * self.n + 2 * self.p * self.harmonics.len()
    }

    fn vector_field(&self, mode: S::Mode, t: f64, z: &[f64], dz: &mut [f64]) {
        let (n, p) = (self.n, self.p);
        let sys = self.htf.system;
        let x = &z[..n];
        sys.vector_field(mode, t, x, &mut dz[..n]);
        let mut guard = self.scratch.borrow_mut();
        let s = &mut *guard;
        state_jacobian(sys, mode, t, x, &mut s.jac);
        sys.input_gain(mode, t, x, &mut s.b);
        let (q_re, q_im) = (&z[n..2 * n], &z[2 * n..3 * n]);
        let w = self.w_in;
        for i in 0..n {
            let row = &s.jac[i * n..(i + 1) * n];
            let (mut re, mut im) = (0.0, 0.0);
            for l in 0..n {
                re += row[l] * q_re[l];
                im += row[l] * q_im[l];
            }
            // (A - j w) q + B.
            dz[n + i] = re + w * q_im[i] + s.b[i];
            dz[2 * n + i] = im - w * q_re[i];
        }
        if self.harmonics.is_empty() {
            return;
        }
        sys.output_gain(mode, t, x, &mut s.c);
        sys.feedthrough(mode, t, x, &mut s.d);
        let inv_t = 1.0 / self.htf.period;
        for o in 0..p {
            let row = &s.c[o * n..(o + 1) * n];
            let (mut re, mut im) = (s.d[o], 0.0);
            for l in 0..n {
                re += row[l] * q_re[l];
                im += row[l] * q_im[l];
            }
            s.y[o] = Complex64::new(re * inv_t, im * inv_t);
        }
        // exp(-j wp (t - t0)): t - t0 stays within one period, so the phase keeps its digits.
        let base = Complex64::from_polar(1.0, -self.htf.wp * (t - self.htf.t0));
        for (h, &k) in self.harmonics.iter().enumerate() {
            let e = base.powi(k);
            for o in 0..p {
                let v = s.y[o] * e;
                let idx = 3 * n + 2 * (h * p + o);
                dz[idx] = v.re;
                dz[idx + 1] = v.im;
            }
        }
    }

    fn num_guards(&self, mode: S::Mode) -> usize {
        self.htf.system.num_guards(mode)
    }

    fn guard(&self, mode: S::Mode, index: usize, t: f64, z: &[f64]) -> f64 {
        self.htf.system.guard(mode, index, t, &z[..self.n])
    }

    fn guard_direction(&self, mode: S::Mode, index: usize) -> Crossing {
        self.htf.system.guard_direction(mode, index)
    }

    fn transition(&self, mode: S::Mode, index: usize, t: f64, z: &mut [f64]) -> S::Mode {
        let n = self.n;
        let sys = self.htf.system;
        let (s, to) = saltation(sys, mode, index, t, &z[..n]);
        let x_before = z[..n].to_vec();
        let (x, rest) = z.split_at_mut(n);
        let to_check = sys.transition(mode, index, t, x);
        debug_assert_eq!(to_check, to, "transition must be deterministic");
        let (q_re, rest) = rest.split_at_mut(n);
        let q_im = &mut rest[..n];
        let mut re = &s * DVector::from_column_slice(q_re);
        let im = &s * DVector::from_column_slice(q_im);
        // A guard or reset that reads the input adds the input's own jump; the input is
        // `exp(j w t)`, which is 1 in `q`'s frame.
        if let Some(e) = input_jump(sys, mode, index, t, &x_before) {
            re += e;
        }
        q_re.copy_from_slice(re.as_slice());
        q_im.copy_from_slice(im.as_slice());
        to
    }
}

/// The linearised state's jump per unit input at the crossing of guard `index` of `mode` at
/// `(t, x_minus)`, `dR/du + jump dh/du / speed` ([`InputOutput::crossing_input`]), or `None`
/// when neither the guard nor its reset reads the input.
pub(crate) fn input_jump<S: InputOutput>(
    sys: &S,
    mode: S::Mode,
    index: usize,
    t: f64,
    x_minus: &[f64],
) -> Option<DVector<f64>> {
    let n = sys.dim();
    let (mut h_u, mut r_u) = (0.0, vec![0.0; n]);
    if !sys.crossing_input(mode, index, t, x_minus, &mut h_u, &mut r_u) {
        return None;
    }
    let jump = transition_jump(sys, mode, index, t, x_minus);
    // A grazing crossing (zero speed) is refused before any HTF is formed.
    let moved = if jump.speed != 0.0 {
        h_u / jump.speed
    } else {
        0.0
    };
    Some(DVector::from_vec(r_u) + jump.jump * moved)
}

/// `A = df/dx` at `(mode, t, x)` into `jac` (row-major): the system's own Jacobian, or
/// [`vector_field_jacobian`]'s differences where it gives none.
fn state_jacobian<S: HybridSystem>(sys: &S, mode: S::Mode, t: f64, x: &[f64], jac: &mut [f64]) {
    if !sys.jacobian(mode, t, x, jac) {
        let n = x.len();
        let a = vector_field_jacobian(sys, mode, t, x);
        for i in 0..n {
            for j in 0..n {
                jac[i * n + j] = a[(i, j)];
            }
        }
    }
}
