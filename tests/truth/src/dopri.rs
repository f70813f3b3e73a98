//! Dormand-Prince 5(4) with its 4th-order dense output (Hairer, Norsett & Wanner, Solving ODEs
//! I, section II.6; the `contd5` coefficients of their `dopri5`). Written for a fixed-size
//! state and any right-hand side `f(t, y)`.

use crate::plant::{State, NX};

const C2: f64 = 1.0 / 5.0;
const C3: f64 = 3.0 / 10.0;
const C4: f64 = 4.0 / 5.0;
const C5: f64 = 8.0 / 9.0;

const A21: f64 = 1.0 / 5.0;
const A31: f64 = 3.0 / 40.0;
const A32: f64 = 9.0 / 40.0;
const A41: f64 = 44.0 / 45.0;
const A42: f64 = -56.0 / 15.0;
const A43: f64 = 32.0 / 9.0;
const A51: f64 = 19372.0 / 6561.0;
const A52: f64 = -25360.0 / 2187.0;
const A53: f64 = 64448.0 / 6561.0;
const A54: f64 = -212.0 / 729.0;
const A61: f64 = 9017.0 / 3168.0;
const A62: f64 = -355.0 / 33.0;
const A63: f64 = 46732.0 / 5247.0;
const A64: f64 = 49.0 / 176.0;
const A65: f64 = -5103.0 / 18656.0;
const A71: f64 = 35.0 / 384.0;
const A73: f64 = 500.0 / 1113.0;
const A74: f64 = 125.0 / 192.0;
const A75: f64 = -2187.0 / 6784.0;
const A76: f64 = 11.0 / 84.0;

const E1: f64 = 71.0 / 57600.0;
const E3: f64 = -71.0 / 16695.0;
const E4: f64 = 71.0 / 1920.0;
const E5: f64 = -17253.0 / 339200.0;
const E6: f64 = 22.0 / 525.0;
const E7: f64 = -1.0 / 40.0;

const D1: f64 = -12715105075.0 / 11282082432.0;
const D3: f64 = 87487479700.0 / 32700410799.0;
const D4: f64 = -10690763975.0 / 1880347072.0;
const D5: f64 = 701980252875.0 / 199316789632.0;
const D6: f64 = -1453857185.0 / 822651844.0;
const D7: f64 = 69997945.0 / 29380423.0;

/// One Dormand-Prince step: the new state, the error estimate, the last stage (first stage of
/// the next step) and the dense-output coefficients.
#[derive(Clone, Debug)]
pub(crate) struct Step {
    pub(crate) y1: State,
    pub(crate) err: State,
    pub(crate) k7: State,
    rcont: [State; 5],
}

fn axpy(y: &State, h: f64, terms: &[(f64, &State)]) -> State {
    let mut out = *y;
    for i in 0..NX {
        let s: f64 = terms.iter().map(|(a, k)| a * k[i]).sum();
        out[i] += h * s;
    }
    out
}

/// Take one step of size `h` from `(t, y)` with `k1 = f(t, y)`.
pub(crate) fn step(
    f: &impl Fn(f64, &State) -> State,
    t: f64,
    y: &State,
    k1: &State,
    h: f64,
) -> Step {
    let k2 = f(t + C2 * h, &axpy(y, h, &[(A21, k1)]));
    let k3 = f(t + C3 * h, &axpy(y, h, &[(A31, k1), (A32, &k2)]));
    let k4 = f(
        t + C4 * h,
        &axpy(y, h, &[(A41, k1), (A42, &k2), (A43, &k3)]),
    );
    let k5 = f(
        t + C5 * h,
        &axpy(y, h, &[(A51, k1), (A52, &k2), (A53, &k3), (A54, &k4)]),
    );
    let k6 = f(
        t + h,
        &axpy(
            y,
            h,
            &[(A61, k1), (A62, &k2), (A63, &k3), (A64, &k4), (A65, &k5)],
        ),
    );
    let y1 = axpy(
        y,
        h,
        &[(A71, k1), (A73, &k3), (A74, &k4), (A75, &k5), (A76, &k6)],
    );
    let k7 = f(t + h, &y1);
    let mut err = [0.0; NX];
    let mut rcont = [[0.0; NX]; 5];
    for i in 0..NX {
        err[i] = h * (E1 * k1[i] + E3 * k3[i] + E4 * k4[i] + E5 * k5[i] + E6 * k6[i] + E7 * k7[i]);
        let ydiff = y1[i] - y[i];
        let bspl = h * k1[i] - ydiff;
        rcont[0][i] = y[i];
        rcont[1][i] = ydiff;
        rcont[2][i] = bspl;
        rcont[3][i] = ydiff - h * k7[i] - bspl;
        rcont[4][i] =
            h * (D1 * k1[i] + D3 * k3[i] + D4 * k4[i] + D5 * k5[i] + D6 * k6[i] + D7 * k7[i]);
    }
    Step { y1, err, k7, rcont }
}

impl Step {
    /// Dense output at fraction `theta` in [0, 1] of the step.
    pub(crate) fn interpolate(&self, theta: f64) -> State {
        let t1 = 1.0 - theta;
        let r = &self.rcont;
        let mut out = [0.0; NX];
        for i in 0..NX {
            out[i] =
                r[0][i] + theta * (r[1][i] + t1 * (r[2][i] + theta * (r[3][i] + t1 * r[4][i])));
        }
        out
    }

    /// Weighted RMS error norm: component `i` may err by `tol * scale[i] * (1 + |y_i|)`.
    pub(crate) fn error_norm(&self, y0: &State, tol: f64, scale: &State) -> f64 {
        let s: f64 = (0..NX)
            .map(|i| {
                let sc = tol * scale[i] * (1.0 + y0[i].abs().max(self.y1[i].abs()));
                (self.err[i] / sc).powi(2)
            })
            .sum();
        (s / NX as f64).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// y' = (y1, -y0) (harmonic oscillator, omega = 1): the step is 5th order, the dense
    /// output 4th order, so halving h divides their errors by about 64 and 32.
    #[test]
    fn orders_on_harmonic_oscillator() {
        let f = |_t: f64, y: &State| {
            let mut d = [0.0; NX];
            d[0] = y[1];
            d[1] = -y[0];
            d
        };
        let mut y0 = [0.0; NX];
        y0[0] = 1.0;
        let errs = |h: f64| {
            let s = step(&f, 0.0, &y0, &f(0.0, &y0), h);
            let e_step = (s.y1[0] - h.cos()).abs();
            let e_dense = (s.interpolate(0.37)[0] - (0.37 * h).cos()).abs();
            (e_step, e_dense)
        };
        let (a1, b1) = errs(0.2);
        let (a2, b2) = errs(0.1);
        let order_step = (a1 / a2).log2();
        let order_dense = (b1 / b2).log2();
        assert!(order_step > 5.7 && order_step < 6.3, "{order_step}");
        // At least 4th order (local error O(h^5)); on this linear problem it does better.
        assert!(order_dense > 4.7, "{order_dense}");
        assert!(b1 < 1e-7, "{b1}");
    }
}
