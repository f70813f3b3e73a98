use htfid_hybrid::{simulate, EventKind, Options};
use htfid_orbit::{find_limit_cycle, LimitCycle, ShootingOptions};

use crate::{Hopper, HopperMode, ModelError};

/// The hopper's limit cycle, with the phase origin at the forcing's phase 0 (`t = 0 mod T`).
#[derive(Debug, Clone)]
pub struct HopperOrbit {
    /// The generic periodic-orbit data (state at phase 0, monodromy, multipliers, residual).
    pub cycle: LimitCycle<HopperMode>,
    /// Phase in `[0, T)` of the upward zero crossing of `x' - v_th` (damper turns on), s.
    pub t_on: f64,
    /// Phase in `[0, T)` of the downward crossing (damper turns off), s.
    pub t_off: f64,
    /// Fraction of the period with the damper on.
    pub duty: f64,
}

impl HopperOrbit {
    /// The hopper's orbit data of a limit cycle found by `htfid-orbit` (for example by a fit
    /// that changed the hopper's parameters): the damper's switching phases and duty cycle.
    ///
    /// # Errors
    /// [`ModelError::UnexpectedSwitching`] when the orbit does not switch exactly twice per
    /// period (or never).
    pub fn from_cycle(cycle: LimitCycle<HopperMode>) -> Result<Self, ModelError> {
        let period = cycle.period;
        let transitions = || {
            cycle.events.iter().filter(|e| {
                e.kind == EventKind::Transition || (e.kind == EventKind::SlideEnd && e.to != e.from)
            })
        };
        let ons: Vec<f64> = transitions()
            .filter(|e| e.to == HopperMode::Damped)
            .map(|e| e.time.rem_euclid(period))
            .collect();
        let offs: Vec<f64> = transitions()
            .filter(|e| e.to == HopperMode::Free)
            .map(|e| e.time.rem_euclid(period))
            .collect();
        let (t_on, t_off, duty) = match (ons.as_slice(), offs.as_slice()) {
            ([on], [off]) => (*on, *off, (off - on).rem_euclid(period) / period),
            ([], []) => {
                // One chart only (damper always on): the damper is on all the time.
                (
                    0.0,
                    0.0,
                    if cycle.mode0 == HopperMode::Damped {
                        1.0
                    } else {
                        0.0
                    },
                )
            }
            _ => {
                return Err(ModelError::UnexpectedSwitching {
                    on: ons.len(),
                    off: offs.len(),
                })
            }
        };
        Ok(HopperOrbit {
            cycle,
            t_on,
            t_off,
            duty,
        })
    }

    /// The intervals of the period (times from the phase origin, s) during which the mass
    /// sticks: it slides along `x' = v_th` (with `v_th = 0`, `x' = 0` held by Coulomb
    /// friction). Empty when it never sticks.
    pub fn stick_intervals(&self) -> Vec<(f64, f64)> {
        self.cycle
            .sliding
            .iter()
            .map(|s| (s.start - self.cycle.t0, s.end - self.cycle.t0))
            .collect()
    }
}

/// One sample of the orbit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrbitSample {
    /// Phase in `[0, T)`, s.
    pub phase: f64,
    /// Position, m.
    pub x: f64,
    /// Velocity, m/s.
    pub xd: f64,
    /// Damping switch `s` (1 = damper on). While the mass sticks, the chart it arrived in.
    pub s: f64,
    /// Whether the mass sticks at this phase (slides along the switching surface).
    pub stick: bool,
}

impl Hopper {
    /// Settles onto the forced periodic orbit (input switched off) and refines it by Newton
    /// shooting. Errors when there is no asymptotically stable period-T orbit (for example
    /// `c = 0`) or the orbit does not switch exactly twice per period. A switch is a chart
    /// change, through a crossing or at the end of a stick interval.
    pub fn limit_cycle(
        &self,
        shooting: &ShootingOptions,
        opts: &Options,
    ) -> Result<HopperOrbit, ModelError> {
        self.limit_cycle_from(&self.initial_guess(), shooting, opts)
    }

    /// As [`Hopper::limit_cycle`], starting from `x0` (for example the orbit of a nearby
    /// parameter set, so that little settling is needed).
    pub fn limit_cycle_from(
        &self,
        x0: &[f64],
        shooting: &ShootingOptions,
        opts: &Options,
    ) -> Result<HopperOrbit, ModelError> {
        let unforced = self.with_input(None);
        let mode0 = unforced.mode_of(x0[1]);
        let period = self.params().period;
        let cycle = find_limit_cycle(&unforced, mode0, 0.0, x0, period, shooting, opts)?;
        HopperOrbit::from_cycle(cycle)
    }

    /// Samples the orbit at `samples` equally spaced phases in `[0, T)`.
    pub fn sample_orbit(
        &self,
        orbit: &HopperOrbit,
        samples: usize,
        opts: &Options,
    ) -> Result<Vec<OrbitSample>, ModelError> {
        let period = orbit.cycle.period;
        let grid: Vec<f64> = (0..samples)
            .map(|i| period * i as f64 / samples as f64)
            .collect();
        let unforced = self.with_input(None);
        let traj = simulate(
            &unforced,
            orbit.cycle.mode0,
            0.0,
            &orbit.cycle.state0,
            period,
            &grid,
            opts,
        )?;
        Ok(grid
            .iter()
            .enumerate()
            .map(|(i, &phase)| {
                let s = traj.state(i);
                OrbitSample {
                    phase,
                    x: s[0],
                    xd: s[1],
                    s: traj.modes[i].switch(),
                    stick: traj.sliding_at(phase).is_some(),
                }
            })
            .collect())
    }
}
