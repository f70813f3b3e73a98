//! Linearisation of a hybrid system about its limit cycle: `A(t)`, `B(t)`, `C(t)`, `D(t)` along
//! the orbit, the saltation matrix at every switch, and the piecewise-LTI approximation of the
//! paper (one constant matrix set per chart, the average over the chart's time interval).

use htfid_hybrid::{simulate, EventKind, HybridError, HybridSystem, Options};
use htfid_orbit::{saltation, vector_field_jacobian, LimitCycle};
use nalgebra::{DMatrix, DVector};

use crate::{LtpError, Piece, PiecewiseLti};

/// A hybrid system with one scalar input entering its vector field and `p` outputs, as needed
/// for its harmonic transfer functions. Required: the input gain `B` and the output gain `C`;
/// one output and no feedthrough by default.
pub trait InputOutput: HybridSystem {
    /// `B(t) = df/du` at `(mode, t, x)` with the input at zero, into `b` (length `dim`).
    fn input_gain(&self, mode: Self::Mode, t: f64, x: &[f64], b: &mut [f64]);
    /// Number of outputs `p` (default 1).
    fn num_outputs(&self) -> usize {
        1
    }
    /// `C = dy/dx`, row-major `p x dim`, into `c`.
    fn output_gain(&self, mode: Self::Mode, t: f64, x: &[f64], c: &mut [f64]);
    /// `D = dy/du`, length `p`, into `d`; zeros by default.
    fn feedthrough(&self, _mode: Self::Mode, _t: f64, _x: &[f64], d: &mut [f64]) {
        d.iter_mut().for_each(|v| *v = 0.0)
    }
    /// Whether guard `index` of `mode` or its reset reads the input, and if so, at `(t, x)`
    /// (the state before the crossing, the input at zero), `dh/du` into `h_u` and `dR/du` into
    /// `r_u` (length `dim`). A perturbation of the input then moves the crossing and the reset
    /// directly, and the linearised state jumps by `(dR/du + jump dh/du / speed) du` on top of
    /// the saltation matrix's `S dx` (`htfid_theory::OrbitHtf` applies it). `false` (the
    /// default) when neither reads it.
    fn crossing_input(
        &self,
        _mode: Self::Mode,
        _index: usize,
        _t: f64,
        _x: &[f64],
        _h_u: &mut f64,
        _r_u: &mut [f64],
    ) -> bool {
        false
    }
    /// Whether `A, B, C, D` are constant within every mode along any orbit, so that the
    /// chart-averaged piecewise-LTI model of [`linearise`] is exact. `false` by default: only
    /// a system that knows it (for instance from symbolic Jacobians) says `true`, and never
    /// one whose guards or resets read the input ([`InputOutput::crossing_input`]: the
    /// piecewise-LTI model has no input at its jumps).
    fn is_piecewise_constant(&self) -> bool {
        false
    }
}

/// A transition on the orbit with its saltation matrix.
#[derive(Debug, Clone)]
pub struct Switch<M> {
    /// Absolute time of the switch within `[t0, t0 + T)`.
    pub time: f64,
    /// Chart before.
    pub from: M,
    /// Chart after.
    pub to: M,
    /// `S = DR + (f+ - DR f-) grad(h)^T / (grad(h) . f- + dh/dt)`.
    pub saltation: DMatrix<f64>,
}

/// The linearised system at one time on the orbit.
#[derive(Debug, Clone)]
pub struct LinearSample<M> {
    /// Absolute time.
    pub t: f64,
    /// Chart.
    pub mode: M,
    /// Orbit state.
    pub state: Vec<f64>,
    /// `df/dx`.
    pub a: DMatrix<f64>,
    /// `df/du`.
    pub b: DVector<f64>,
    /// `dy/dx`, `p x dim`.
    pub c: DMatrix<f64>,
    /// `dy/du`, length `p`.
    pub d: DVector<f64>,
}

/// The LTP model of a hybrid system about its limit cycle.
#[derive(Debug, Clone)]
pub struct Linearisation<M> {
    /// Period.
    pub period: f64,
    /// Phase origin (absolute time of the orbit's phase 0).
    pub t0: f64,
    /// Transitions over one period, in time order, with their saltation matrices.
    pub switches: Vec<Switch<M>>,
    /// The linearisation sampled at `t0 + i T / samples`.
    pub samples: Vec<LinearSample<M>>,
    /// The piecewise-LTI approximation: one piece per chart interval, starting at the first
    /// switch, each carrying the saltation of the switch that opens it as its jump.
    pub piecewise: PiecewiseLti,
}

/// Gauss-Legendre nodes and weights on [-1, 1] (8 points): exact for polynomials of degree 15,
/// so chart averages of smooth `A(t)` are accurate far beyond the model's other errors.
const GL_NODES: [f64; 8] = [
    -0.960_289_856_497_536_2,
    -0.796_666_477_413_626_7,
    -0.525_532_409_916_329,
    -0.183_434_642_495_649_8,
    0.183_434_642_495_649_8,
    0.525_532_409_916_329,
    0.796_666_477_413_626_7,
    0.960_289_856_497_536_2,
];
const GL_WEIGHTS: [f64; 8] = [
    0.101_228_536_290_376_3,
    0.222_381_034_453_374_5,
    0.313_706_645_877_887_3,
    0.362_683_783_378_362,
    0.362_683_783_378_362,
    0.313_706_645_877_887_3,
    0.222_381_034_453_374_5,
    0.101_228_536_290_376_3,
];

fn sample_at<S: InputOutput>(sys: &S, mode: S::Mode, t: f64, x: &[f64]) -> LinearSample<S::Mode> {
    let (n, p) = (sys.dim(), sys.num_outputs());
    let a = vector_field_jacobian(sys, mode, t, x);
    let mut b = vec![0.0; n];
    let mut c = vec![0.0; p * n];
    let mut d = vec![0.0; p];
    sys.input_gain(mode, t, x, &mut b);
    sys.output_gain(mode, t, x, &mut c);
    sys.feedthrough(mode, t, x, &mut d);
    LinearSample {
        t,
        mode,
        state: x.to_vec(),
        a,
        b: DVector::from_vec(b),
        c: DMatrix::from_row_slice(p, n, &c),
        d: DVector::from_vec(d),
    }
}

/// [`LtpError::GrazingOrbit`] when `cycle` touches a guard without crossing it: no linear
/// model holds there.
pub fn refuse_grazes<M>(cycle: &LimitCycle<M>) -> Result<(), LtpError> {
    match cycle.events.iter().find(|e| e.kind == EventKind::Grazing) {
        Some(e) => Err(LtpError::GrazingOrbit {
            guard: e.guard,
            time: e.time,
        }),
        None => Ok(()),
    }
}

/// Linearises `sys` about `cycle` (which must have been computed with the input off).
///
/// `samples` equally spaced samples of `A(t), B(t), C(t), D(t)` are kept for inspection and
/// FFT-based Fourier analysis; the piecewise-LTI model averages each chart's matrices over its
/// interval with 8-point Gauss-Legendre quadrature. The model has one input and
/// [`InputOutput::num_outputs`] outputs (`C` is `p x n`, `D` is `p x 1`); select a SISO channel
/// with [`PiecewiseLti::channel`].
pub fn linearise<S: InputOutput>(
    sys: &S,
    cycle: &LimitCycle<S::Mode>,
    samples: usize,
    opts: &Options,
) -> Result<Linearisation<S::Mode>, LtpError> {
    if let Some(first) = cycle.sliding.first() {
        return Err(LtpError::SlidingOrbit {
            guard: first.guard,
            start: first.start,
            end: first.end,
            intervals: cycle.sliding.len(),
        });
    }
    refuse_grazes(cycle)?;
    let (t0, period) = (cycle.t0, cycle.period);
    let switches: Vec<Switch<S::Mode>> = cycle
        .events
        .iter()
        .filter(|e| e.kind == EventKind::Transition)
        .map(|e| {
            let (s, to) = saltation(sys, e.from, e.guard, e.time, &e.state);
            Switch {
                time: e.time,
                from: e.from,
                to,
                saltation: s,
            }
        })
        .collect();

    // Piece boundaries: the switch times, or the whole period when the orbit never switches.
    let starts: Vec<f64> = if switches.is_empty() {
        vec![t0]
    } else {
        switches.iter().map(|s| s.time).collect()
    };
    let mut quad_times = Vec::with_capacity(starts.len() * GL_NODES.len());
    for (i, &a) in starts.iter().enumerate() {
        let b = starts.get(i + 1).copied().unwrap_or(starts[0] + period);
        for node in GL_NODES {
            quad_times.push(0.5 * (a + b) + 0.5 * (b - a) * node);
        }
    }
    // Quadrature nodes past t0 + T are taken one period earlier (the orbit is periodic).
    let mut wrapped: Vec<(f64, usize)> = quad_times
        .iter()
        .enumerate()
        .map(|(k, &t)| (if t >= t0 + period { t - period } else { t }, k))
        .collect();
    wrapped.sort_by(|x, y| x.0.total_cmp(&y.0));
    let uniform: Vec<f64> = (0..samples)
        .map(|i| t0 + period * i as f64 / samples as f64)
        .collect();
    let mut grid: Vec<f64> = uniform
        .iter()
        .copied()
        .chain(wrapped.iter().map(|w| w.0))
        .collect();
    grid.sort_by(f64::total_cmp);
    let traj = simulate(
        sys,
        cycle.mode0,
        t0,
        &cycle.state0,
        t0 + period,
        &grid,
        opts,
    )
    .map_err(|e: HybridError| LtpError::Integration(e.to_string()))?;
    let lookup = |t: f64| -> usize { grid.partition_point(|&g| g < t).min(grid.len() - 1) };

    let (n, p) = (sys.dim(), sys.num_outputs());
    let mut pieces = Vec::with_capacity(starts.len());
    for (i, &a_time) in starts.iter().enumerate() {
        let b_time = starts.get(i + 1).copied().unwrap_or(starts[0] + period);
        let half = 0.5 * (b_time - a_time);
        let (mut a, mut b, mut c, mut d) = (
            DMatrix::zeros(n, n),
            DVector::zeros(n),
            DMatrix::zeros(p, n),
            DVector::zeros(p),
        );
        // The chart of the piece: the one the switch opening it enters.
        let mode = switches.get(i).map_or(cycle.mode0, |s| s.to);
        // The tabulated weights sum to 2 only up to rounding; normalising keeps a constant
        // chart matrix exactly constant.
        let weight_sum: f64 = GL_WEIGHTS.iter().sum();
        for (node, weight) in GL_NODES
            .iter()
            .zip(GL_WEIGHTS.map(|w| 2.0 * w / weight_sum))
        {
            let mut t = 0.5 * (a_time + b_time) + half * node;
            if t >= t0 + period {
                t -= period;
            }
            let k = lookup(t);
            let s = sample_at(sys, mode, grid[k], traj.state(k));
            a += s.a * (0.5 * weight);
            b += s.b * (0.5 * weight);
            c += s.c * (0.5 * weight);
            d += s.d * (0.5 * weight);
        }
        let b = DMatrix::from_column_slice(n, 1, b.as_slice());
        let d = DMatrix::from_column_slice(p, 1, d.as_slice());
        let mut piece = Piece::new(b_time - a_time, a, b, c, d);
        if let Some(sw) = switches.get(i) {
            if !sw.saltation.is_identity(1e-14) {
                piece = piece.with_jump(sw.saltation.clone());
            }
        }
        pieces.push(piece);
    }
    let piecewise = PiecewiseLti::new(period, starts[0], pieces)?;

    let samples = uniform
        .iter()
        .map(|&t| {
            let k = lookup(t);
            sample_at(sys, traj.modes[k], grid[k], traj.state(k))
        })
        .collect();
    Ok(Linearisation {
        period,
        t0,
        switches,
        samples,
        piecewise,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use htfid_orbit::{find_limit_cycle, ShootingOptions};

    /// `x' = -(1 + x^2) x + cos t + u`, outputs `y = (x, x^2 + 3 u)`: two outputs, feedthrough on
    /// the second, `A` and `C` varying along the orbit.
    struct TwoOutputs;

    impl HybridSystem for TwoOutputs {
        type Mode = ();
        fn dim(&self) -> usize {
            1
        }
        fn vector_field(&self, _: (), t: f64, x: &[f64], dx: &mut [f64]) {
            dx[0] = -(1.0 + x[0] * x[0]) * x[0] + t.cos();
        }
    }

    impl InputOutput for TwoOutputs {
        fn input_gain(&self, _: (), _t: f64, _x: &[f64], b: &mut [f64]) {
            b[0] = 1.0;
        }
        fn num_outputs(&self) -> usize {
            2
        }
        fn output_gain(&self, _: (), _t: f64, x: &[f64], c: &mut [f64]) {
            c[0] = 1.0;
            c[1] = 2.0 * x[0];
        }
        fn feedthrough(&self, _: (), _t: f64, _x: &[f64], d: &mut [f64]) {
            d[0] = 0.0;
            d[1] = 3.0;
        }
    }

    #[test]
    fn several_outputs_give_a_multi_output_model() {
        let opts = Options::default();
        let cycle = find_limit_cycle(
            &TwoOutputs,
            (),
            0.0,
            &[0.0],
            std::f64::consts::TAU,
            &ShootingOptions::default(),
            &opts,
        )
        .unwrap();
        let lin = linearise(&TwoOutputs, &cycle, 8, &opts).unwrap();
        let lti = &lin.piecewise;
        assert_eq!((lti.n_inputs(), lti.n_outputs()), (1, 2));
        let s = &lin.samples[3];
        assert_eq!((s.c.shape(), s.d.len()), ((2, 1), 2));
        assert!((s.c[(1, 0)] - 2.0 * s.state[0]).abs() < 1e-15);
        assert!((s.a[(0, 0)] + 1.0 + 3.0 * s.state[0] * s.state[0]).abs() < 1e-8);
        let piece = &lti.pieces()[0];
        assert!((piece.d()[(1, 0)] - 3.0).abs() < 1e-14);
        assert!(piece.d()[(0, 0)].abs() < 1e-15);
        // The chart average of C_2 = 2 x over the orbit, by the samples' trapezoid rule.
        let mean_x = lin.samples.iter().map(|s| s.state[0]).sum::<f64>() / 8.0;
        assert!((piece.c()[(1, 0)] - 2.0 * mean_x).abs() < 1e-3);
        let ch = lti.channel(1, 0).unwrap();
        assert_eq!(ch.n_outputs(), 1);
        assert!((ch.pieces()[0].d()[(0, 0)] - 3.0).abs() < 1e-14);
    }
}
