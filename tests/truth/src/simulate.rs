//! The event-driven integration loop.
//!
//! Each accepted Dormand-Prince step is checked for guard sign changes at four points of its
//! dense output. The earliest root is located by Brent's method on the dense output to
//! 1e-14 s, the step is then redone exactly to the root (a full 5th-order step, not the
//! interpolant), and the modes are re-resolved there. Steps are clipped so that every sample
//! instant and every excitation breakpoint is landed on exactly.

use crate::dopri::{self, Step};
use crate::error::Error;
use crate::plant::{Modes, Plant, State, X};

/// Integration settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimOptions {
    /// Absolute and relative tolerance of each step (default 1e-12).
    pub tol: f64,
    /// Largest step, s (default 2e-3; also bounds how far apart guard checks are).
    pub h_max: f64,
}

impl Default for SimOptions {
    fn default() -> Self {
        SimOptions {
            tol: 1e-12,
            h_max: 2e-3,
        }
    }
}

/// A discrete transition and when it happened.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Event {
    /// Time, s.
    pub t: f64,
    /// Modes before.
    pub from: Modes,
    /// Modes after.
    pub to: Modes,
}

/// Work counters of one simulation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// Accepted steps.
    pub accepted: usize,
    /// Rejected steps.
    pub rejected: usize,
    /// Events located.
    pub events: usize,
}

/// States at the requested instants, the transitions, and the work done.
#[derive(Clone, Debug)]
pub struct Trajectory {
    /// The sample instants, s.
    pub t: Vec<f64>,
    /// The full continuous state at each instant.
    pub states: Vec<State>,
    /// Every discrete transition, in time order.
    pub events: Vec<Event>,
    /// Work counters.
    pub stats: Stats,
}

/// Root finding stops when the bracket is this short, s.
const ROOT_TOL: f64 = 1e-14;
/// Smallest step before giving up, s.
const H_MIN: f64 = 1e-13;
/// Events at one instant before declaring an event storm.
const MAX_EVENTS_AT_ONE_INSTANT: usize = 20;
/// Per-component error scale. Forces (N) are weighted as the displacement they cause
/// through the spring (1 N ~ 5 mm): an error of 100 N-units counts like 1 m. Everything else
/// is in m or m/s.
const ERROR_SCALE: State = [1.0, 1.0, 100.0, 1.0, 1.0, 1.0, 100.0];
/// A position beyond this many metres means the true system itself diverged.
const DIVERGED: f64 = 1e3;
/// Guard checkpoints within each step (fractions of the step).
const CHECKPOINTS: [f64; 4] = [0.25, 0.5, 0.75, 1.0];

impl Plant {
    /// Integrate from `(t0, y0)` and return the state at each of `sample_times` (sorted,
    /// all `>= t0`). Modes are resolved from the state at `t0`.
    ///
    /// # Errors
    /// [`Error::StepSizeTooSmall`], [`Error::NoConsistentMode`], [`Error::EventStorm`].
    pub fn simulate(
        &self,
        t0: f64,
        y0: State,
        sample_times: &[f64],
        opts: &SimOptions,
    ) -> Result<Trajectory, Error> {
        let breaks = self.breaks();
        let mut out = Trajectory {
            t: sample_times.to_vec(),
            states: Vec::with_capacity(sample_times.len()),
            events: Vec::new(),
            stats: Stats::default(),
        };
        let mut t = t0;
        let mut seg = self.segment(t);
        let (mut modes, mut y) = self.resolve(t, seg, seg, &y0, self.initial_modes())?;
        let rhs =
            |modes: Modes, seg: usize| move |tt: f64, yy: &State| self.deriv(tt, seg, yy, modes);
        let mut k1 = rhs(modes, seg)(t, &y);
        let mut h = opts.h_max.min(1e-4);
        let mut next_sample = 0;
        let mut storm = (t, 0usize);

        while next_sample < sample_times.len() && sample_times[next_sample] <= t {
            out.states.push(y);
            next_sample += 1;
        }
        while next_sample < sample_times.len() {
            let next_break = breaks.get(seg).copied().unwrap_or(f64::INFINITY);
            let target = sample_times[next_sample].min(next_break);
            let h_try = h.min(opts.h_max);
            let (h_step, clipped) = if t + 1.01 * h_try >= target {
                (target - t, true)
            } else {
                (h_try, false)
            };
            let f = rhs(modes, seg);
            let s = dopri::step(&f, t, &y, &k1, h_step);
            let err = s.error_norm(&y, opts.tol, &ERROR_SCALE);
            if !err.is_finite() || s.y1[X].abs() > DIVERGED {
                return Err(Error::Diverged { time: t });
            }
            let factor = if err == 0.0 {
                5.0
            } else {
                (0.9 * err.powf(-0.2)).clamp(0.2, 5.0)
            };
            if err > 1.0 {
                out.stats.rejected += 1;
                h = h_step * factor;
                if h < H_MIN {
                    return Err(Error::StepSizeTooSmall { time: t, step: h });
                }
                continue;
            }
            out.stats.accepted += 1;

            if let Some(theta) = self.first_root(t, seg, &y, modes, &s, h_step) {
                let t_event = t + theta * h_step;
                if theta > 0.0 {
                    y = dopri::step(&f, t, &y, &k1, theta * h_step).y1;
                }
                storm = if t_event - storm.0 <= ROOT_TOL {
                    (storm.0, storm.1 + 1)
                } else {
                    (t_event, 1)
                };
                if storm.1 > MAX_EVENTS_AT_ONE_INSTANT {
                    return Err(Error::EventStorm {
                        time: t_event,
                        count: storm.1,
                    });
                }
                t = t_event;
                let (new_modes, z) = self.resolve(t, seg, seg, &y, modes)?;
                if new_modes != modes {
                    out.events.push(Event {
                        t,
                        from: modes,
                        to: new_modes,
                    });
                }
                out.stats.events += 1;
                modes = new_modes;
                y = z;
                k1 = rhs(modes, seg)(t, &y);
                continue;
            }

            t = if clipped { target } else { t + h_step };
            y = s.y1;
            k1 = s.k7;
            if !clipped || h_step >= h {
                h = h_step * factor;
            }
            if clipped && target >= next_break {
                let prev_seg = seg;
                seg = self.segment(t);
                let (new_modes, z) = self.resolve(t, seg, prev_seg, &y, modes)?;
                if new_modes != modes {
                    out.events.push(Event {
                        t,
                        from: modes,
                        to: new_modes,
                    });
                }
                modes = new_modes;
                y = z;
                k1 = rhs(modes, seg)(t, &y);
            }
            while next_sample < sample_times.len() && sample_times[next_sample] <= t {
                out.states.push(y);
                next_sample += 1;
            }
        }
        Ok(out)
    }

    /// Earliest guard zero within the step, as a fraction of the step, if any guard goes
    /// negative.
    fn first_root(
        &self,
        t: f64,
        seg: usize,
        y: &State,
        modes: Modes,
        s: &Step,
        h: f64,
    ) -> Option<f64> {
        let g_at = |theta: f64, i: usize| {
            let z = if theta >= 1.0 {
                s.y1
            } else {
                s.interpolate(theta)
            };
            self.guards(t + theta * h, seg, &z, modes).values()[i]
        };
        let g0 = self.guards(t, seg, y, modes);
        let mut prev: Vec<(f64, f64)> = g0.values().iter().map(|&g| (0.0, g)).collect();
        for &theta in &CHECKPOINTS {
            let z = if theta >= 1.0 {
                s.y1
            } else {
                s.interpolate(theta)
            };
            let g = self.guards(t + theta * h, seg, &z, modes);
            let mut best: Option<f64> = None;
            for (i, &gi) in g.values().iter().enumerate() {
                let (ta, ga) = prev[i];
                if gi < 0.0 {
                    let root = if ga < 0.0 {
                        // Already (barely) past the surface at the start: event now.
                        ta
                    } else {
                        brent(|th| g_at(th, i), ta, theta, ga, gi, ROOT_TOL / h)
                    };
                    best = Some(best.map_or(root, |b: f64| b.min(root)));
                }
                prev[i] = (theta, gi);
            }
            if best.is_some() {
                return best;
            }
        }
        None
    }
}

/// Brent's root finder on `[a, b]` with `f(a) >= 0 > f(b)`; returns a point within `tol` of
/// the root, on the side where `f <= 0` or at a zero, so that the event is never reported
/// before the guard has crossed.
fn brent(f: impl Fn(f64) -> f64, a: f64, b: f64, fa: f64, fb: f64, tol: f64) -> f64 {
    let (mut a, mut b, mut fa, mut fb) = (a, b, fa, fb);
    if fa == 0.0 {
        return a;
    }
    let mut c = a;
    let mut fc = fa;
    let mut d = b - a;
    let mut e = d;
    for _ in 0..200 {
        if (fb > 0.0) == (fc > 0.0) && fb != 0.0 {
            c = a;
            fc = fa;
            d = b - a;
            e = d;
        }
        if fc.abs() < fb.abs() {
            a = b;
            b = c;
            c = a;
            fa = fb;
            fb = fc;
            fc = fa;
        }
        let tol1 = 2.0 * f64::EPSILON * b.abs() + 0.5 * tol;
        let xm = 0.5 * (c - b);
        if xm.abs() <= tol1 || fb == 0.0 {
            break;
        }
        if e.abs() >= tol1 && fa.abs() > fb.abs() {
            let s = fb / fa;
            let (mut p, mut q);
            // Identity, not closeness: c was copied from a, so only two points are known.
            if a.to_bits() == c.to_bits() {
                p = 2.0 * xm * s;
                q = 1.0 - s;
            } else {
                let qq = fa / fc;
                let r = fb / fc;
                p = s * (2.0 * xm * qq * (qq - r) - (b - a) * (r - 1.0));
                q = (qq - 1.0) * (r - 1.0) * (s - 1.0);
            }
            if p > 0.0 {
                q = -q;
            }
            p = p.abs();
            if 2.0 * p < (3.0 * xm * q - (tol1 * q).abs()).min((e * q).abs()) {
                e = d;
                d = p / q;
            } else {
                d = xm;
                e = d;
            }
        } else {
            d = xm;
            e = d;
        }
        a = b;
        fa = fb;
        b += if d.abs() > tol1 {
            d
        } else {
            tol1 * xm.signum()
        };
        fb = f(b);
    }
    // b and c bracket the root; report the end where the guard is not positive.
    if fb <= 0.0 {
        b
    } else {
        c
    }
}

/// Readable names of the components that changed between two mode sets.
pub fn describe(e: &Event) -> String {
    let mut parts = Vec::new();
    if e.from.damper != e.to.damper {
        parts.push(format!("damper {:?}->{:?}", e.from.damper, e.to.damper));
    }
    if e.from.friction != e.to.friction {
        parts.push(format!(
            "friction {:?}->{:?}",
            e.from.friction, e.to.friction
        ));
    }
    if e.from.stop != e.to.stop {
        parts.push(format!("stop {:?}->{:?}", e.from.stop, e.to.stop));
    }
    if e.from.lash != e.to.lash {
        parts.push(format!("backlash {:?}->{:?}", e.from.lash, e.to.lash));
    }
    format!("t = {}: {}", e.t, parts.join(", "))
}
