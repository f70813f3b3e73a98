//! Scalar searches on the dense output: a bracketing root finder (Illinois regula falsi with a
//! bisection safeguard) and Brent's local minimiser with an early exit.

use crate::HybridError;

/// `sqrt(f64::EPSILON)`: the relative resolution of a minimum of a smooth function.
pub(crate) const SQRT_EPS: f64 = 1.490_116_119_384_765_6e-8;

/// Golden-section starting abscissa of a minimisation on `[0, 1]`.
pub(crate) const GOLDEN_START: f64 = 0.381_966_011_250_105_1;

/// Whether `g` lies on the far side of zero from `g_before` (or on zero).
#[inline]
fn crossed(g_before: f64, g: f64) -> bool {
    if g_before > 0.0 {
        g <= 0.0
    } else {
        g >= 0.0
    }
}

/// Shrinks the bracket `[a, b]` with `g(a) = ga != 0` and `g(b) = gb` on the other side of (or
/// on) zero until it is narrower than `tol`, and returns its right end, where the guard has
/// already crossed. Returning the post-crossing end is what keeps the guard from re-firing at
/// the restart.
pub(crate) fn locate_root<F>(
    g: &mut F,
    mut a: f64,
    mut ga: f64,
    mut b: f64,
    mut gb: f64,
    tol: f64,
) -> Result<f64, HybridError>
where
    F: FnMut(f64) -> Result<f64, HybridError>,
{
    let tol = tol.max(4.0 * f64::EPSILON * a.abs().max(b.abs()));
    // Which end moved last: the Illinois rule halves the stale end's value when the same end
    // moves twice, which restores superlinear convergence where plain regula falsi stalls.
    let mut last = 0i8;
    let mut width_before = b - a;
    for iter in 0..200 {
        if gb == 0.0 || b - a <= tol {
            return Ok(b);
        }
        // Bisect if two iterations did not halve the bracket.
        let bisect = iter % 2 == 0 && iter > 0 && b - a > 0.5 * width_before;
        if iter % 2 == 0 {
            width_before = b - a;
        }
        let mut c = b - gb * (b - a) / (gb - ga);
        if bisect || !(c > a && c < b) {
            c = 0.5 * (a + b);
        }
        let gc = g(c)?;
        if crossed(ga, gc) {
            b = c;
            gb = gc;
            if last == 1 {
                ga *= 0.5;
            }
            last = 1;
        } else {
            a = c;
            ga = gc;
            if last == -1 {
                gb *= 0.5;
            }
            last = -1;
        }
    }
    if b - a <= tol {
        Ok(b)
    } else {
        Err(HybridError::EventLocationFailed { time: b })
    }
}

#[inline]
fn same(x: f64, y: f64) -> bool {
    x.to_bits() == y.to_bits()
}

/// Outcome of [`minimize`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct Minimum {
    /// Abscissa in `[0, 1]`.
    pub x: f64,
    /// Function value there.
    pub fx: f64,
    /// The search stopped because a value `<= stop` was seen (at `x`).
    pub stopped: bool,
}

/// Brent's local minimiser (golden section with parabolic interpolation) of `f` on `[0, 1]`,
/// started at `x0` (with its value `fx0` if already known). Returns as soon as a value `<= stop`
/// appears. The location is resolved to about `SQRT_EPS * x + tol`: near a smooth minimum `f`
/// is flat to second order, so finer resolution is not available in floating point.
pub(crate) fn minimize<F>(
    f: &mut F,
    x0: f64,
    fx0: Option<f64>,
    tol: f64,
    stop: f64,
) -> Result<Minimum, HybridError>
where
    F: FnMut(f64) -> Result<f64, HybridError>,
{
    const GOLDEN: f64 = GOLDEN_START; // (3 - sqrt 5) / 2
    let (mut a, mut b) = (0.0f64, 1.0f64);
    let mut x = x0.clamp(0.0, 1.0);
    let mut fx = match fx0 {
        Some(v) => v,
        None => f(x)?,
    };
    if fx <= stop {
        return Ok(Minimum {
            x,
            fx,
            stopped: true,
        });
    }
    let (mut w, mut v) = (x, x);
    let (mut fw, mut fv) = (fx, fx);
    let (mut d, mut e) = (0.0f64, 0.0f64);
    for _ in 0..100 {
        let m = 0.5 * (a + b);
        let tol1 = SQRT_EPS * x.abs() + tol / 3.0;
        let tol2 = 2.0 * tol1;
        if (x - m).abs() <= tol2 - 0.5 * (b - a) {
            break;
        }
        let mut golden = true;
        if e.abs() > tol1 {
            let r = (x - w) * (fx - fv);
            let mut q = (x - v) * (fx - fw);
            let mut p = (x - v) * q - (x - w) * r;
            q = 2.0 * (q - r);
            if q > 0.0 {
                p = -p;
            } else {
                q = -q;
            }
            let e_old = e;
            e = d;
            if p.abs() < (0.5 * q * e_old).abs() && p > q * (a - x) && p < q * (b - x) {
                d = p / q;
                let u = x + d;
                if u - a < tol2 || b - u < tol2 {
                    d = if x < m { tol1 } else { -tol1 };
                }
                golden = false;
            }
        }
        if golden {
            e = if x < m { b - x } else { a - x };
            d = GOLDEN * e;
        }
        let u = if d.abs() >= tol1 {
            x + d
        } else if d > 0.0 {
            x + tol1
        } else {
            x - tol1
        };
        let fu = f(u)?;
        if fu <= stop {
            return Ok(Minimum {
                x: u,
                fx: fu,
                stopped: true,
            });
        }
        if fu <= fx {
            if u < x {
                b = x;
            } else {
                a = x;
            }
            (v, fv) = (w, fw);
            (w, fw) = (x, fx);
            (x, fx) = (u, fu);
        } else {
            if u < x {
                a = u;
            } else {
                b = u;
            }
            if fu <= fw || same(w, x) {
                (v, fv) = (w, fw);
                (w, fw) = (u, fu);
            } else if fu <= fv || same(v, x) || same(v, w) {
                (v, fv) = (u, fu);
            }
        }
    }
    Ok(Minimum {
        x,
        fx,
        stopped: false,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    #[test]
    fn illinois_finds_root_of_cubic_to_tolerance() {
        // x^3 - 2 on [1, 2]: root 2^(1/3); the bracket must end narrower than 1e-13 with the
        // returned end on the positive (post-crossing) side.
        let mut evals = 0;
        let mut g = |x: f64| {
            evals += 1;
            Ok(x * x * x - 2.0)
        };
        let r = locate_root(&mut g, 1.0, -1.0, 2.0, 6.0, 1e-13).unwrap();
        assert_abs_diff_eq!(r, 2f64.cbrt(), epsilon = 1e-13);
        assert!(r * r * r - 2.0 >= 0.0);
        assert!(
            evals < 20,
            "Illinois should converge superlinearly, took {evals}"
        );
    }

    #[test]
    fn illinois_survives_a_flat_step_function_by_bisection() {
        // Regula falsi stalls on a guard that is flat on one side; bisection must take over.
        let mut g = |x: f64| {
            Ok(if x < 0.3 {
                -1.0
            } else {
                1e-9 * (x - 0.3) + 1e-300
            })
        };
        let r = locate_root(&mut g, 0.0, -1.0, 1.0, 1.0, 1e-12).unwrap();
        assert_abs_diff_eq!(r, 0.3, epsilon = 1e-12);
    }

    #[test]
    fn brent_locates_smooth_minimum() {
        // (x - 0.3)^2 + 1: minimum at 0.3, located to ~sqrt(eps) as documented.
        let mut f = |x: f64| Ok((x - 0.3) * (x - 0.3) + 1.0);
        let m = minimize(&mut f, 0.5, None, 1e-12, f64::NEG_INFINITY).unwrap();
        assert_abs_diff_eq!(m.x, 0.3, epsilon = 1e-7);
        assert_abs_diff_eq!(m.fx, 1.0, epsilon = 1e-14);
        assert!(!m.stopped);
    }

    #[test]
    fn brent_stops_early_below_threshold() {
        let mut f = |x: f64| Ok((x - 0.7) * (x - 0.7) - 0.01);
        let m = minimize(&mut f, 0.5, None, 1e-12, 0.0).unwrap();
        assert!(m.stopped);
        assert!(m.fx <= 0.0);
        assert!((m.x - 0.7).abs() <= 0.1);
    }
}
