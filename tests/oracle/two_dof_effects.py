#!/usr/bin/env python3
"""Independent truth generator for the two-dof model with hidden effects.

Writes ``tests/fixtures/two-dof-effects/``:

* one CSV per effect (header ``t,u,x1,x2``, every value printed with ``%.17g``, so each
  number parses back to the exact double that was computed),
* ``truth.json``: per file, the hidden effect, its true parameter values, the noise level
  and seed, and everything else needed to reproduce the record,
* ``README.md``.

With ``--only NAME`` (repeatable) it writes only the named single-effect record(s) into the
existing ``tests/fixtures/two-dof-effects/`` and merges their entries and self-checks into the
existing ``truth.json``; every other file there is left untouched.

With ``--pairs`` it writes ``tests/fixtures/two-dof-pairs/`` instead: records with two of the
effects below at once (list ``PAIRS``), in the same format, with their own ``truth.json``.
With ``--triples`` it writes ``tests/fixtures/two-dof-triples/``: records with three of the
effects at once (list ``TRIPLES``), likewise.

Run from the repository root (or anywhere)::

    python3 tests/oracle/two_dof_effects.py            # single effects, runs the self-checks
    python3 tests/oracle/two_dof_effects.py --only posvel   # just that record, its checks
    python3 tests/oracle/two_dof_effects.py --pairs    # pairs of effects, with their self-checks
    python3 tests/oracle/two_dof_effects.py --triples  # triples of effects, likewise

The generator is written from the model file ``models/two-dof.toml`` alone and shares no code
with htfid.  Dependencies: Python 3, numpy, scipy.

Model (models/two-dof.toml)
---------------------------
states x1, v1, x2, v2; parameters m1 = 1, m2 = 0.5, k1 = 200, k2 = 100, k3 = 5000, c1 = 2,
c2 = 0.5, a = 20, T = 1::

    coupling = -k2 (x1 - x2) - c2 (v1 - v2)      force on mass 1 from mass 2
    spring1  = -k1 x1 - k3 x1^3
    f0(t)    = a cos(2 pi t / T)
    x1' = v1,  x2' = v2,  v2' = -coupling / m2
    mode up   (damper 1 on):  v1' = (spring1 + coupling - c1 v1 + f0 + u) / m1
    mode down (damper 1 off): v1' = (spring1 + coupling + f0 + u) / m1
    up -> down when v1 falls through 0; down -> up when v1 rises through 0
    outputs x1, x2

Integration
-----------
scipy ``solve_ivp`` (DOP853, rtol 1e-10, atol 1e-12, max_step = 0.01 s = the sample interval)
per mode, with terminal events on every switching surface; at each event the integration
restarts in the new mode from the located event state.  The input u(t) and the forcing are
analytic functions of t, so the integrator reads them exactly.  Samples are taken from each
segment's dense output.

The switching surface of damper 1 is handled in the Filippov sense (as docs/models.md
describes for a pair of guards on the same expression): at a crossing, if the flow of the mode
on the far side points back into the surface, the state slides on the surface (v1 held at the
switching value, v1' = 0) until one side's flow leaves it.  In the model as given (surface
v1 = 0) the two flows agree on the surface, so sliding cannot happen there; with the shifted
guard (v1 = 0.05) it can, in principle, for a short while (the flows then differ by c1 * 0.05).
Coulomb friction on mass 2 is handled the same way with an explicit stick mode (see
``friction2`` below).

Every simulation starts at t = -20 s from rest (x1 = x2 = v1 = v2 = 0, lag states 0) in mode
"up", with the same input and forcing defined for t < 0; only t >= 0 is recorded.

Effects (one per file)
----------------------
clean        the model as given
drag         v1' gets -d |v1| v1 in every mode, d = 2.0 1/m
sensor-lag   each recorded output is s with tau_s s' = y - s (tau_s = 0.03 s), s(-20) = y(-20)
input-delay  the model reads u(t - 0.02); the recorded column u is u(t)
guard-shift  both switching surfaces at v1 = 0.05 m/s instead of 0
stiffer-k2   k2 = 110 instead of 100
friction2    an extra force -0.4 sign(v2) N on mass 2 (Coulomb), with sticking: when v2 = 0 and
             |k2 (x1 - x2) + c2 v1| <= 0.4 N mass 2 stays at rest until that force reaches
             0.4 N in magnitude (events at v2 = 0 and at |force| = 0.4)
posvel       an extra force -a x1 v1 (N) on mass 1 in every mode, a = 5.0 N s/m^2: v1' gets
             -a x1 v1 / m1 in both modes up and down.  (This a is the effect's own coefficient,
             not the forcing amplitude a = 20 of the model.)  The term vanishes on the surface
             v1 = 0, so the two modes' flows still agree there and no sliding can occur.

Noise: independent Gaussian, standard deviation 2e-5 m, added to each recorded output after the
sensor effect; seeded, a different seed per file (7100 + i in the order of ``EFFECTS``, so
posvel uses 7107).  The input column carries no noise.

Pairs (``--pairs``, one file each; every effect defined exactly as above)
--------------------------------------------------------------------------
drag+sensor-lag         d = 2.0, and both outputs through the lag tau_s = 0.03 s
guard-shift+stiffer-k2  both switching surfaces at v1 = 0.05, and k2 = 110
drag+input-delay        d = 2.0, and the model reads u(t - 0.02)
input-delay+stiffer-k2  u(t - 0.02), and k2 = 110
input-delay+sensor-lag  u(t - 0.02), and both outputs through the lag tau_s = 0.03 s

In the pairs with drag, the drag is evaluated as -d v1^2 in mode up and +d v1^2 in mode down,
which is -d |v1| v1 on each mode's side of v1 = 0 (the surface when there is drag).  This
keeps the kink of |v1| out of the step that crosses the surface (see ``Effect.smooth_drag``
and self-check (c)).  Noise seeds 7200 + i, in the order of ``PAIRS``.

Triples (``--triples``, one file each; every effect defined exactly as above)
-----------------------------------------------------------------------------
drag+input-delay+stiffer-k2  d = 2.0, the model reads u(t - 0.02), and k2 = 110
drag+sensor-lag+stiffer-k2   d = 2.0, both outputs through the lag tau_s = 0.03 s, and k2 = 110
drag+input-delay+sensor-lag  d = 2.0, the model reads u(t - 0.02), and both outputs through
                             the lag tau_s = 0.03 s

Written to ``tests/fixtures/two-dof-triples/``, in the same format, with their own
``truth.json``.  The drag is evaluated in the same smooth per-mode form as in the pairs.  Noise
seeds 7300 + i, in the order of ``TRIPLES``.  The self-checks are those of the pairs ((a)
convergence at rtol 1e-12, (b) the lag states against the exact lag of the finely sampled
output of the other two effects, (c) the drag as written) plus (d): the record must differ from
each of its constituents simulated alone (the three pairs, each without one of the effects,
and the three singles) by at least 10 noise std RMS on both outputs, so that every effect is
visible; the script exits non-zero if it does not.
"""

import argparse
import copy
import itertools
import json
import math
import os
import sys

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq
from scipy.signal import lfilter

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
OUT = os.path.join(ROOT, "tests", "fixtures", "two-dof-effects")
OUT_PAIRS = os.path.join(ROOT, "tests", "fixtures", "two-dof-pairs")
OUT_TRIPLES = os.path.join(ROOT, "tests", "fixtures", "two-dof-triples")

# --------------------------------------------------------------------------------------------
# Fixed settings
# --------------------------------------------------------------------------------------------

PARAMS = dict(m1=1.0, m2=0.5, k1=200.0, k2=100.0, k3=5000.0, c1=2.0, c2=0.5, a=20.0, T=1.0)

T_START = -20.0          # simulation start (rest, mode "up")
T_END = 60.0             # last sample
FS = 100.0               # sample rate, Hz
N_SAMPLES = 6001         # t = k / 100, k = 0..6000
DT = 1.0 / FS

RTOL = 1e-10
ATOL = 1e-12
MAX_STEP = DT

# input: 12 sines, frequencies log-uniformly spaced (np.geomspace) from 0.3 Hz to 6 Hz,
# equal amplitudes, random phases; amplitude such that the RMS of u (its power average over
# time, sum A^2/2) is 4 N.
INPUT_SEED = 20240617
N_SINES = 12
F_LO, F_HI = 0.3, 6.0
U_RMS = 4.0

NOISE_STD = 2e-5
EPS = np.finfo(float).eps
NOISE_SEED_BASE = 7100   # file i (0-based, order of EFFECTS) uses seed NOISE_SEED_BASE + i
PAIR_SEED_BASE = 7200    # pair file i (0-based, order of PAIRS) uses seed PAIR_SEED_BASE + i
TRIPLE_SEED_BASE = 7300  # triple file i (0-based, order of TRIPLES) uses TRIPLE_SEED_BASE + i

_rng = np.random.default_rng(INPUT_SEED)
U_FREQS = np.geomspace(F_LO, F_HI, N_SINES)
U_PHASES = _rng.uniform(0.0, 2.0 * np.pi, N_SINES)
U_AMP = U_RMS * math.sqrt(2.0 / N_SINES)          # sqrt(N * A^2 / 2) = U_RMS
U_OMEGA = 2.0 * np.pi * U_FREQS
_U_TERMS = list(zip(U_OMEGA.tolist(), U_PHASES.tolist()))


def u_of_t(t):
    """The excitation u(t) = A sum_i sin(2 pi f_i t + phi_i) (scalar t)."""
    s = 0.0
    for w, p in _U_TERMS:
        s += math.sin(w * t + p)
    return U_AMP * s


def u_vec(t):
    t = np.asarray(t, dtype=float)
    return U_AMP * np.sin(np.multiply.outer(t, U_OMEGA) + U_PHASES).sum(axis=-1)


# --------------------------------------------------------------------------------------------
# Effects
# --------------------------------------------------------------------------------------------

class Effect:
    """Parameters of one simulated system (the model plus at most one effect)."""

    def __init__(self, name, description, **kw):
        self.name = name
        self.description = description
        self.params = dict(PARAMS)
        self.params.update(kw.pop("params", {}))
        self.drag = kw.pop("drag", 0.0)             # d in -d |v1| v1
        self.tau_s = kw.pop("tau_s", None)          # sensor lag time constant
        self.delay = kw.pop("delay", 0.0)           # input delay
        self.v_switch = kw.pop("v_switch", 0.0)     # damper-1 switching surface v1 = v_switch
        self.friction2 = kw.pop("friction2", 0.0)   # Coulomb force on mass 2, N
        self.posvel = kw.pop("posvel", 0.0)         # a in the extra force -a x1 v1 on mass 1
        # smooth_drag: evaluate the drag as -d v1^2 in mode up and +d v1^2 in mode down.  On
        # each mode's own side of the surface v1 = 0 this is -d |v1| v1 exactly, but it has no
        # kink inside the integration step that crosses the surface, so DOP853's dense output
        # (and with it the located crossing) keeps its accuracy there.  Used by the pair and
        # triple records only; the single-effect records keep the form as written (their error
        # from the kink, self_checks.a_*: ~1.7e-10 m, is left as it is so that they stay
        # byte-identical).
        self.smooth_drag = kw.pop("smooth_drag", False)
        if self.smooth_drag:
            assert self.v_switch == 0.0 and self.friction2 == 0.0
        self.true_values = kw.pop("true_values", {})
        assert not kw, kw


EFFECTS = [
    Effect("clean", "the model as given", true_values={}),
    Effect("drag", "extra acceleration -d*|v1|*v1 added to v1' in every mode",
           drag=2.0, true_values={"d": 2.0}),
    Effect("sensor-lag", "each recorded output is a first-order lag of the model output, "
           "tau_s*s' = y - s, s(-20) = y(-20) = 0",
           tau_s=0.03, true_values={"tau_s": 0.03}),
    Effect("input-delay", "the model reads u(t - delay) instead of u(t); the recorded u "
           "column is u(t)", delay=0.02, true_values={"delay": 0.02}),
    Effect("guard-shift", "both switching surfaces at v1 = v_switch: up->down when v1 falls "
           "through v_switch, down->up when v1 rises through it",
           v_switch=0.05, true_values={"v_switch": 0.05}),
    Effect("stiffer-k2", "parameter error: k2 = 110 instead of 100",
           params={"k2": 110.0}, true_values={"k2": 110.0}),
    Effect("friction2", "Coulomb friction on mass 2: extra force -F*sign(v2) on mass 2 "
           "(-F/m2*sign(v2) on v2'), with sticking (v2 = 0 held while "
           "|k2*(x1-x2) + c2*v1| <= F)", friction2=0.4, true_values={"F": 0.4}),
    Effect("posvel", "extra force -a*x1*v1 on mass 1 in every mode (v1' gets -a*x1*v1/m1 in "
           "modes up and down); a = 5.0 N s/m^2 is this effect's own coefficient, not the "
           "forcing amplitude a = 20 of the model", posvel=5.0, true_values={"a": 5.0}),
]


def _single(name):
    return next(e for e in EFFECTS if e.name == name)


def _combine(*names):
    """The model with several of the single effects at once, each exactly as in its own record.

    The effects must be disjoint (each extra setting comes from at most one of them).  With
    drag, the drag is evaluated in the smooth per-mode form (``Effect.smooth_drag``)."""
    parts = [_single(n) for n in names]
    kw = {"params": {}}
    for e in parts:
        kw["params"].update({k: v for k, v in e.params.items() if v != PARAMS[k]})
    for attr, default in (("drag", 0.0), ("tau_s", None), ("delay", 0.0),
                          ("v_switch", 0.0), ("friction2", 0.0), ("posvel", 0.0)):
        vals = [getattr(e, attr) for e in parts if getattr(e, attr) != default]
        assert len(vals) <= 1, attr                       # the effects are disjoint
        kw[attr] = vals[0] if vals else default
    kw["smooth_drag"] = kw["drag"] != 0.0
    tv = {}
    for e in parts:
        tv.update(e.true_values)
    descs = ["%s: %s" % (e.name, e.description) for e in parts]
    desc = descs[0] if len(descs) == 1 else "; ".join(descs[:-1]) + "; and " + descs[-1]
    eff = Effect("+".join(names), desc, true_values=tv, **kw)
    eff.parts = tuple(names)
    return eff


# Records with two hidden effects at once (written with --pairs to tests/fixtures/two-dof-pairs)
PAIRS = [
    _combine("drag", "sensor-lag"),
    _combine("guard-shift", "stiffer-k2"),
    _combine("drag", "input-delay"),
    _combine("input-delay", "stiffer-k2"),
    _combine("input-delay", "sensor-lag"),
]

# Records with three hidden effects at once (written with --triples to
# tests/fixtures/two-dof-triples)
TRIPLES = [
    _combine("drag", "input-delay", "stiffer-k2"),
    _combine("drag", "sensor-lag", "stiffer-k2"),
    _combine("drag", "input-delay", "sensor-lag"),
]


# --------------------------------------------------------------------------------------------
# The hybrid simulator
# --------------------------------------------------------------------------------------------
#
# Mode = (m1, m2): m1 in {"up", "down", "slide"} (damper 1), m2 in {"free", "pos", "neg",
# "stick"} (mass 2: "free" without friction; with friction "pos"/"neg" is the sign of v2 while
# it moves and "stick" holds v2 = 0).  State z = [x1, v1, x2, v2] (+ [s1, s2] with a sensor lag).

class Sim:
    def __init__(self, eff):
        self.eff = eff
        p = eff.params
        self.m1, self.m2 = p["m1"], p["m2"]
        self.k1, self.k2, self.k3 = p["k1"], p["k2"], p["k3"]
        self.c1, self.c2 = p["c1"], p["c2"]
        self.a, self.T = p["a"], p["T"]
        self.nstate = 6 if eff.tau_s is not None else 4

    # forces ----------------------------------------------------------------------------
    def accel_v1(self, t, z):
        """(v1' in mode up, v1' in mode down) at (t, z)."""
        x1, v1, x2, v2 = z[0], z[1], z[2], z[3]
        coupling = -self.k2 * (x1 - x2) - self.c2 * (v1 - v2)
        spring1 = -self.k1 * x1 - self.k3 * x1 ** 3
        f0 = self.a * math.cos(2.0 * math.pi * t / self.T)
        u = u_of_t(t - self.eff.delay)
        base = spring1 + coupling + f0 + u
        if self.eff.posvel:                  # (only then, so the other records keep their bits)
            base = base - self.eff.posvel * x1 * v1
        if self.eff.smooth_drag:
            dv = self.eff.drag * v1 * v1
            return (base - self.c1 * v1) / self.m1 - dv, base / self.m1 + dv
        drag = -self.eff.drag * abs(v1) * v1
        a_up = (base - self.c1 * v1) / self.m1 + drag
        a_down = base / self.m1 + drag
        return a_up, a_down

    def force2(self, z):
        """Force on mass 2 from mass 1 (= -coupling), without friction."""
        x1, v1, x2, v2 = z[0], z[1], z[2], z[3]
        return self.k2 * (x1 - x2) + self.c2 * (v1 - v2)

    def rhs(self, t, z, mode):
        m1mode, m2mode = mode
        dz = np.empty(self.nstate)
        a_up, a_down = self.accel_v1(t, z)
        if m1mode == "up":
            dz[1] = a_up
        elif m1mode == "down":
            dz[1] = a_down
        else:                        # sliding on v1 = v_switch
            dz[1] = 0.0
        dz[0] = z[1]
        F2 = self.force2(z)
        fr = self.eff.friction2
        if m2mode == "free":
            dz[2], dz[3] = z[3], F2 / self.m2
        elif m2mode == "pos":
            dz[2], dz[3] = z[3], (F2 - fr) / self.m2
        elif m2mode == "neg":
            dz[2], dz[3] = z[3], (F2 + fr) / self.m2
        else:                        # stuck
            dz[2], dz[3] = 0.0, 0.0
        if self.nstate == 6:
            tau = self.eff.tau_s
            dz[4] = (z[0] - z[4]) / tau
            dz[5] = (z[2] - z[5]) / tau
        return dz

    # events ----------------------------------------------------------------------------
    def events(self, mode):
        """List of (h, direction, tag, state index or None) for the mode.

        The state index k marks a guard h = z[k] - const (a velocity surface), whose time
        derivative along the mode's flow is rhs[k]; it is used when a segment starts exactly
        on that surface (see `_start_safe`)."""
        m1mode, m2mode = mode
        vs = self.eff.v_switch
        evs = []
        if m1mode == "up":
            evs.append((lambda t, z: z[1] - vs, -1, "v1_falling", 1))
        elif m1mode == "down":
            evs.append((lambda t, z: z[1] - vs, +1, "v1_rising", 1))
        else:
            evs.append((lambda t, z: self.accel_v1(t, z)[0], +1, "slide_exit_up", None))
            evs.append((lambda t, z: self.accel_v1(t, z)[1], -1, "slide_exit_down", None))
        fr = self.eff.friction2
        if m2mode == "pos":
            evs.append((lambda t, z: z[3], -1, "v2_falling", 3))
        elif m2mode == "neg":
            evs.append((lambda t, z: z[3], +1, "v2_rising", 3))
        elif m2mode == "stick":
            evs.append((lambda t, z: self.force2(z) - fr, +1, "unstick_pos", None))
            evs.append((lambda t, z: self.force2(z) + fr, -1, "unstick_neg", None))
        return evs

    def _start_safe(self, h, k, ts, zs, mode):
        """An event function with the same roots as h on t > ts, but not at t = ts.

        A segment that starts on a guard's surface (h(ts) = 0, e.g. v2 = 0 right after mass 2
        reverses or unsticks, or v1 = v_switch right after a switch) may leave the surface and
        come back to it within the first integration step; the root finder would then return
        the start itself.  g(t) = h(t) / (t - ts) has exactly the roots of h for t > ts and
        the limit h'(ts) (= rhs[k]) at ts, so the return to the surface is found exactly."""
        if k is None or h(ts, zs) != 0.0:
            return h
        dh0 = float(self.rhs(ts, zs, mode)[k])

        def g(t, z):
            return h(t, z) / (t - ts) if t > ts else dh0
        return g

    def transition(self, tag, t, z, mode):
        """New (mode, state) after the event `tag` at (t, z)."""
        m1mode, m2mode = mode
        z = z.copy()
        vs = self.eff.v_switch
        fr = self.eff.friction2
        if tag in ("v1_falling", "v1_rising"):
            z[1] = vs                               # on the surface (error ~ 1e-16)
            a_up, a_down = self.accel_v1(t, z)
            if tag == "v1_falling":                 # a_up < 0 here
                m1mode = "down" if a_down <= 0.0 else "slide"
            else:                                   # a_down > 0 here
                m1mode = "up" if a_up >= 0.0 else "slide"
        elif tag == "slide_exit_up":
            m1mode = "up"
        elif tag == "slide_exit_down":
            m1mode = "down"
        elif tag in ("v2_falling", "v2_rising"):
            z[3] = 0.0
            F2 = self.force2(z)
            if abs(F2) <= fr:
                m2mode = "stick"
            else:
                m2mode = "pos" if F2 > 0.0 else "neg"
        elif tag == "unstick_pos":
            m2mode = "pos"
        elif tag == "unstick_neg":
            m2mode = "neg"
        else:
            raise ValueError(tag)
        return (m1mode, m2mode), z

    # run -------------------------------------------------------------------------------
    def run(self, t0=T_START, t1=T_END, rtol=RTOL, atol=ATOL, max_step=MAX_STEP):
        z = np.zeros(self.nstate)
        mode = ("up", "stick" if self.eff.friction2 > 0.0 else "free")
        t = t0
        segments = []        # (t_a, t_b, OdeSolution, mode)
        log = []             # (t, tag, new mode)
        stalls = 0
        while t < t1:
            evs = self.events(mode)
            funcs = []
            safe = []
            for h, d, _, k in evs:
                f = self._start_safe(h, k, t, z, mode)
                f.terminal = True
                f.direction = d
                funcs.append(f)
                safe.append(f)
            # Grazing guard: a velocity surface h = z[k] - c can be crossed twice within one
            # step (a short excursion to the far side), which a sign test at the step ends
            # misses.  Between two such crossings h has an extremum on the far side, so the
            # extrema of h (roots of h' = rhs[k], non-terminal) are watched too, and one found
            # on the far side marks a missed crossing inside that step.
            graze = []
            for j, (h, d, _, k) in enumerate(evs):
                if k is None:
                    continue
                g = (lambda tt, zz, k=k, mode=mode: self.rhs(tt, zz, mode)[k])
                g.terminal = False
                g.direction = -d          # minimum for a falling guard, maximum for rising
                funcs.append(g)
                graze.append((len(funcs) - 1, j))
            sol = solve_ivp(lambda tt, zz, mode=mode: self.rhs(tt, zz, mode), (t, t1), z,
                            method="DOP853", rtol=rtol, atol=atol, max_step=max_step,
                            events=funcs, dense_output=True)
            if not sol.success:
                raise RuntimeError(sol.message)
            # earliest terminal event, or earliest missed crossing (whichever comes first)
            best = None
            for i in range(len(evs)):
                te = sol.t_events[i]
                if len(te) and (best is None or te[0] < best[0]):
                    best = (float(te[0]), i, sol.y_events[i][0])
            for gi, j in graze:
                h, d, _, k = evs[j]
                for tm, zm in zip(sol.t_events[gi], sol.y_events[gi]):
                    if d * h(tm, zm) > 0.0:                   # extremum on the far side
                        if best is None or tm < best[0]:
                            # the crossing lies in the step containing tm, between that
                            # step's start (on the near side) and tm
                            ta = float(sol.t[np.searchsorted(sol.t, tm) - 1])
                            fj = safe[j]
                            tc = brentq(lambda tt: fj(tt, sol.sol(tt)), ta, tm,
                                        xtol=4 * EPS, rtol=4 * EPS)
                            best = (tc, j, sol.sol(tc))
                        break
            if best is not None:
                te, i, ze = best
                tag = evs[i][2]
                segments.append((t, te, sol.sol, mode))
                stalls = stalls + 1 if te - t < 1e-12 else 0
                if stalls > 5:
                    raise RuntimeError("event loop stalled at t = %r (%s)" % (te, tag))
                mode, z = self.transition(tag, te, ze, mode)
                log.append((te, tag, mode))
                t = te
            else:
                segments.append((t, float(sol.t[-1]), sol.sol, mode))
                t = float(sol.t[-1])
        return Trajectory(segments, log)


class Trajectory:
    def __init__(self, segments, log):
        self.segments = segments
        self.log = log
        self.starts = np.array([s[0] for s in segments])

    def __call__(self, t):
        """States at the times t (sorted array), shape (nstate, len(t))."""
        t = np.asarray(t, dtype=float)
        idx = np.searchsorted(self.starts, t, side="right") - 1
        idx = np.clip(idx, 0, len(self.segments) - 1)
        out = None
        for k in np.unique(idx):
            sel = idx == k
            ta, tb, sol, mode = self.segments[k]
            assert np.all(t[sel] >= ta - 1e-12) and np.all(t[sel] <= tb + 1e-12)
            y = sol(t[sel])
            if out is None:
                out = np.empty((y.shape[0], len(t)))
            out[:, sel] = y
        return out

    def summary(self):
        tags = {}
        for te, tag, _ in self.log:
            tags[tag] = tags.get(tag, 0) + 1
        slide = _intervals(self.segments, lambda m: m[0] == "slide")
        stick = _intervals(self.segments, lambda m: m[1] == "stick")
        return {"events_from_t_start": tags,
                "sliding_v1_intervals_t_ge_0": _clip_count(slide),
                "stuck_mass2_intervals_t_ge_0": _clip_count(stick)}


def _intervals(segments, pred):
    return [(ta, tb) for ta, tb, _, m in segments if pred(m)]


def _clip_count(iv):
    iv = [(max(a, 0.0), b) for a, b in iv if b > 0.0]
    return {"count": len(iv), "total_duration_s": float(sum(b - a for a, b in iv))}


# --------------------------------------------------------------------------------------------
# Records
# --------------------------------------------------------------------------------------------

def sample_times():
    return np.arange(N_SAMPLES) / FS          # correctly rounded k/100


def outputs(eff, traj, t):
    z = traj(t)
    if eff.tau_s is not None:
        return z[4], z[5]
    return z[0], z[2]


def write_csv(path, t, u, y1, y2):
    with open(path, "w", newline="\n") as f:
        f.write("t,u,x1,x2\n")
        for row in zip(t.tolist(), u.tolist(), y1.tolist(), y2.tolist()):
            f.write("%.17g,%.17g,%.17g,%.17g\n" % row)


def rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


def lag_check(clean_traj, tau, h, t_start=T_START):
    """Sensor-lag check independent of the ODE integration of the lag states.

    The clean noiseless outputs are sampled on a fine grid of step h from t_start (where
    y = s = 0); the lag's exact solution over each step with y linear in between
    (first-order hold) is  s[n] = alpha s[n-1] + beta y[n] + (1 - alpha - beta) y[n-1],
    alpha = exp(-h/tau), beta = 1 - (tau/h)(1 - alpha).  Returns s at the sample times.
    """
    n_per = int(round(DT / h))
    n_tot = int(round((T_END - t_start) / h))
    k = np.arange(n_tot + 1)
    tf = t_start + k * h
    i0 = int(round(-t_start / h))
    # evaluate in chunks to bound memory
    ys = []
    for lo in range(0, len(tf), 400000):
        z = clean_traj(tf[lo:lo + 400000])
        ys.append(np.vstack([z[0], z[2]]))
    y = np.hstack(ys)
    alpha = math.exp(-h / tau)
    beta = 1.0 - (tau / h) * (1.0 - alpha)
    b = [beta, 1.0 - alpha - beta]
    s = lfilter(b, [1.0, -alpha], y, axis=1)     # zero initial state: y = s = 0 at t_start
    return s[:, i0::n_per][:, :N_SAMPLES]


def truth_header(t_start, u, regenerate):
    """The part of truth.json shared by both fixture directories (input, noise, methods)."""
    truth = {
        "generator": "tests/oracle/two_dof_effects.py",
        "regenerate": regenerate,
        "model": "models/two-dof.toml",
        "parameters": PARAMS,
        "sampling": {"t_first": 0.0, "t_last": T_END, "rate_hz": FS, "samples": N_SAMPLES,
                     "t_k": "k/100 (correctly rounded), k = 0..6000"},
        "simulation": {"t_start": t_start, "initial_state": {"x1": 0, "v1": 0, "x2": 0,
                                                             "v2": 0, "lag states": 0},
                       "initial_mode": "up",
                       "integrator": "scipy solve_ivp DOP853, terminal events on every "
                                     "switching surface, restart in the new mode",
                       "rtol": RTOL, "atol": ATOL, "max_step": MAX_STEP,
                       "scipy": __import__("scipy").__version__,
                       "numpy": np.__version__},
        "input": {"formula": "u(t) = A * sum_i sin(2*pi*f_i*t + phi_i)",
                  "A": U_AMP, "f_hz": U_FREQS.tolist(), "phi_rad": U_PHASES.tolist(),
                  "frequency_spacing": "np.geomspace(0.3, 6, 12)",
                  "phase_seed": INPUT_SEED,
                  "phase_rng": "numpy.random.default_rng(seed).uniform(0, 2*pi, 12)",
                  "rms_analytic": U_RMS, "rms_of_samples": rms(u),
                  "noise": "none (u column is exact)"},
        "noise": {"std": NOISE_STD, "distribution": "independent Gaussian on x1 and x2",
                  "rng": "numpy.random.default_rng(seed).normal(0, std, size=(6001, 2)); "
                         "column 0 -> x1, column 1 -> x2",
                  "applied": "after the sensor effect"},
        "methods": {
            "switching": "terminal events on v1 = v_switch (falling in up, rising in down); "
                         "restart in the other mode from the located state; Filippov sliding "
                         "(v1 held, v1' = 0) if the far side's flow points back into the "
                         "surface (never happens in these records)",
            "grazing": "extrema of v1 (and v2 with friction) are located too; one on the far "
                       "side of the surface marks a double crossing inside one step, whose "
                       "first crossing is then found by brentq on the dense output",
            "friction2": "modes pos/neg/stick for mass 2; at v2 = 0: stick if "
                         "|k2 (x1-x2) + c2 v1| <= F, else continue with the new sign; stick "
                         "ends when that force reaches +F (-> pos) or -F (-> neg)",
            "sensor_lag": "lag states s1, s2 integrated with the model (tau_s s' = y - s)",
            "input_delay": "u(t - delay) evaluated analytically (u is defined for all t)",
        },
        "start_transient": "the simulations start from rest at t_start; the transient has "
                           "not fully decayed at t = 0 (see self_checks.d_*: the clean "
                           "record at t in [0,5) differs by up to ~6e-4 m (x1) and ~1.3e-3 "
                           "m (x2) from a run started 40 s earlier, and by less than the "
                           "noise std only from t ~ 15-20 s on). This is part of the true "
                           "trajectory from the stated initial condition.",
    }
    return truth


def single_record(eff, i, t, u, clean_y, out, t_start):
    """Simulate the single-effect record EFFECTS[i] = eff, write its CSV into out, and return
    (file name, truth.json entry, noiseless outputs, trajectory).  clean_y is the clean
    model's noiseless output (None for the clean record itself)."""
    sim = Sim(eff)
    traj = sim.run(t0=t_start)
    y1, y2 = outputs(eff, traj, t)
    if clean_y is None:
        assert eff.name == "clean"
        clean_y = (y1, y2)
    seed = NOISE_SEED_BASE + i
    noise = np.random.default_rng(seed).normal(0.0, NOISE_STD, size=(N_SAMPLES, 2))
    n1 = y1 + noise[:, 0]
    n2 = y2 + noise[:, 1]
    fname = eff.name + ".csv"
    write_csv(os.path.join(out, fname), t, u, n1, n2)
    d1 = y1 - clean_y[0]
    d2 = y2 - clean_y[1]
    eff_rms = {"x1": rms(d1), "x2": rms(d2)}
    rec_rms = {"x1": rms(n1 - clean_y[0]), "x2": rms(n2 - clean_y[1])}
    extra = {"drag_d": eff.drag, "tau_s": eff.tau_s, "input_delay": eff.delay,
             "v_switch": eff.v_switch, "friction2_F": eff.friction2}
    if eff.posvel:                       # (only then, so the other entries stay as they were)
        extra["posvel_a"] = eff.posvel
    entry = {
        "effect": eff.name,
        "description": eff.description,
        "true_values": eff.true_values,
        "parameters": eff.params,
        "extra": extra,
    }
    if eff.posvel:
        z = traj(t)
        fx = eff.posvel * z[0] * z[1]
        entry["extra_force"] = {
            "term": "force -a*x1*v1 on mass 1",
            "in_v1_dot": "-a*x1*v1/m1, added in both modes up and down",
            "a": eff.posvel,
            "a_unit": "N s/m^2",
            "note": "a here is the effect's own coefficient (true_values.a), not the "
                    "model's forcing amplitude parameters.a = 20",
            "rms_of_a_x1_v1_over_record_N": rms(fx),
            "max_abs_of_a_x1_v1_over_record_N": float(np.max(np.abs(fx))),
            "evaluated_on": "the noiseless states x1, v1 at the 6001 sample times t = 0..60 s",
        }
    entry.update({
        "noise_std": NOISE_STD,
        "noise_seed": seed,
        "rms_noiseless_minus_clean_noiseless": eff_rms,
        "rms_record_minus_clean_noiseless": rec_rms,
        "effect_rms_over_noise_std": {k: v / NOISE_STD for k, v in eff_rms.items()},
        "hybrid_summary": traj.summary(),
    })
    print("%-16s effect RMS x1 %.3e (%.2f sd)  x2 %.3e (%.2f sd)  %s" % (
        fname, eff_rms["x1"], eff_rms["x1"] / NOISE_STD, eff_rms["x2"],
        eff_rms["x2"] / NOISE_STD, traj.summary()), flush=True)
    return fname, entry, (y1, y2), traj


def convergence_check(eff, y, t, t_start):
    """Self-check (a'): the record's noiseless outputs y again at rtol 1e-12, atol 1e-14."""
    tr = Sim(eff).run(t0=t_start, rtol=1e-12, atol=1e-14)
    f1, f2 = outputs(eff, tr, t)
    res = {"x1": float(np.max(np.abs(f1 - y[0]))), "x2": float(np.max(np.abs(f2 - y[1])))}
    print("(a') %-12s rtol 1e-12 vs 1e-10: max |dx1| %.3e  max |dx2| %.3e" % (
        eff.name, res["x1"], res["x2"]), flush=True)
    return res


def posvel_check(eff, y, conv, t, t_start):
    """Self-check (f) for the posvel record (noiseless outputs y, its (a') result conv).

    (f1) the (a') convergence numbers relative to the RMS of each output;
    (f2) an event-free integration written directly from the formulas (no Sim, no modes):
         v1' = (-k1 x1 - k3 x1^3 - k2 (x1 - x2) - c2 (v1 - v2) - c1 max(v1, 0)
                + a_f cos(2 pi t / T) + u(t) - a x1 v1) / m1,
         which is the hybrid model whenever nothing slides (mode up <=> v1 > 0; the two
         modes agree at v1 = 0); DOP853 at rtol 1e-12, atol 1e-14, max_step 0.01 s.  Its error
         comes from the kink of max(v1, 0) inside the steps that cross v1 = 0.
    (f3) the same with the posvel term left out, against the clean model (shows that the
         effect is what differs; recorded as the RMS of the difference over the noise std)."""
    p = eff.params
    m1, m2, k1, k2, k3 = p["m1"], p["m2"], p["k1"], p["k2"], p["k3"]
    c1, c2, af, T = p["c1"], p["c2"], p["a"], p["T"]
    out_rms = {"x1": rms(y[0]), "x2": rms(y[1])}
    res = {"output_rms_m": out_rms,
           "a_rtol1e-12_max_abs_diff_over_output_rms": {k: conv[k] / out_rms[k]
                                                        for k in ("x1", "x2")}}

    def free(coef):
        def f(tt, z):
            x1, v1, x2, v2 = z
            fc = -k2 * (x1 - x2) - c2 * (v1 - v2)
            a1 = (-k1 * x1 - k3 * x1 ** 3 + fc - c1 * max(v1, 0.0)
                  + af * math.cos(2.0 * math.pi * tt / T) + u_of_t(tt) - coef * x1 * v1) / m1
            return [v1, a1, v2, -fc / m2]
        sol = solve_ivp(f, (t_start, T_END), [0.0, 0.0, 0.0, 0.0], method="DOP853",
                        rtol=1e-12, atol=1e-14, max_step=MAX_STEP, t_eval=t)
        if not sol.success:
            raise RuntimeError(sol.message)
        return sol.y[0], sol.y[2]

    g1, g2 = free(eff.posvel)
    d = {"x1": float(np.max(np.abs(g1 - y[0]))), "x2": float(np.max(np.abs(g2 - y[1])))}
    res["event_free_max_abs_diff"] = d
    res["event_free_max_abs_diff_over_output_rms"] = {k: d[k] / out_rms[k] for k in d}
    print("(f) posvel output RMS: x1 %.6e  x2 %.6e" % (out_rms["x1"], out_rms["x2"]),
          flush=True)
    print("(f) posvel rtol 1e-12 vs 1e-10, max |d| / RMS: x1 %.3e  x2 %.3e" % (
        res["a_rtol1e-12_max_abs_diff_over_output_rms"]["x1"],
        res["a_rtol1e-12_max_abs_diff_over_output_rms"]["x2"]), flush=True)
    print("(f) posvel vs event-free integration from the formulas: max |dx1| %.3e (%.3e of "
          "RMS)  max |dx2| %.3e (%.3e of RMS)" % (
              d["x1"], d["x1"] / out_rms["x1"], d["x2"], d["x2"] / out_rms["x2"]), flush=True)
    return res


def main_only(args):
    """Write only the named single-effect records into args.out and merge their entries and
    self-checks into the truth.json that is already there; nothing else is touched."""
    t_start = args.t_start
    path = os.path.join(args.out, "truth.json")
    with open(path) as f:
        truth = json.load(f)
    if truth["simulation"]["t_start"] != t_start:
        raise SystemExit("%s was made with t_start = %r, not %r" % (
            path, truth["simulation"]["t_start"], t_start))
    for lib, ver in (("scipy", __import__("scipy").__version__), ("numpy", np.__version__)):
        if truth["simulation"][lib] != ver:
            print("warning: %s was made with %s %s, this is %s" % (
                path, lib, truth["simulation"][lib], ver), file=sys.stderr)
    names = [e.name for e in EFFECTS]
    for n in args.only:
        if n not in names:
            raise SystemExit("--only: unknown effect %r (one of %s)" % (n, ", ".join(names)))
    t = sample_times()
    u = u_vec(t)
    clean_eff = EFFECTS[0]
    clean_traj = Sim(clean_eff).run(t0=t_start)
    clean_y = outputs(clean_eff, clean_traj, t)       # the clean record is not rewritten
    checks = truth.setdefault("self_checks", {})
    for n in args.only:
        i = names.index(n)
        eff = EFFECTS[i]
        fname, entry, y, traj = single_record(eff, i, t, u, None if n == "clean" else clean_y,
                                              args.out, t_start)
        truth["files"][fname] = entry
        conv = convergence_check(eff, y, t, t_start)
        if n == "clean":
            checks["a_clean_rtol1e-12_max_abs_diff"] = conv
        else:
            checks.setdefault("a_other_effects_rtol1e-12_max_abs_diff", {})[n] = conv
        if eff.posvel:
            checks["f_posvel"] = posvel_check(eff, y, conv, t, t_start)
        if n in ("sensor-lag", "friction2"):
            print("note: self-check %s for %s runs only without --only" % (
                "(b)" if n == "sensor-lag" else "(e)", n), file=sys.stderr)
    with open(path, "w") as f:
        json.dump(truth, f, indent=2)
        f.write("\n")
    return 0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=None,
                    help="output directory (default: %s, %s with --pairs, %s with --triples)"
                    % (os.path.relpath(OUT, ROOT), os.path.relpath(OUT_PAIRS, ROOT),
                       os.path.relpath(OUT_TRIPLES, ROOT)))
    ap.add_argument("--t-start", type=float, default=T_START,
                    help="simulation start time, s (default: %(default)s)")
    group = ap.add_mutually_exclusive_group()
    group.add_argument("--pairs", action="store_true",
                       help="write the records with two effects at once (PAIRS) instead of "
                            "the single-effect records")
    group.add_argument("--triples", action="store_true",
                       help="write the records with three effects at once (TRIPLES) instead "
                            "of the single-effect records")
    ap.add_argument("--only", action="append", metavar="NAME", default=None,
                    help="write only this single-effect record (repeatable) and merge it into "
                         "the existing truth.json; the other files are left as they are")
    args = ap.parse_args()
    if args.only and (args.pairs or args.triples):
        ap.error("--only is for the single-effect records")
    if args.triples:
        if args.out is None:
            args.out = OUT_TRIPLES
        return main_triples(args)
    if args.pairs:
        if args.out is None:
            args.out = OUT_PAIRS
        return main_pairs(args)
    if args.out is None:
        args.out = OUT
    if args.only:
        return main_only(args)
    t_start = args.t_start
    os.makedirs(args.out, exist_ok=True)

    t = sample_times()
    u = u_vec(t)
    checks = {}
    truth = truth_header(t_start, u, "python3 tests/oracle/two_dof_effects.py")
    truth["files"] = {}

    clean_traj = None
    clean_y = None
    noiseless = {}
    for i, eff in enumerate(EFFECTS):
        fname, entry, (y1, y2), traj = single_record(eff, i, t, u, clean_y, args.out,
                                                     t_start)
        noiseless[eff.name] = (y1, y2)
        if eff.name == "clean":
            clean_traj, clean_y = traj, (y1, y2)
        truth["files"][fname] = entry

    # ---- self-checks --------------------------------------------------------------------
    # (a) convergence of the clean record
    fine = Sim(EFFECTS[0]).run(t0=t_start, rtol=1e-12, atol=1e-14)
    z = fine(t)
    checks["a_clean_rtol1e-12_max_abs_diff"] = {
        "x1": float(np.max(np.abs(z[0] - clean_y[0]))),
        "x2": float(np.max(np.abs(z[2] - clean_y[1])))}
    print("(a) clean, rtol 1e-12 vs 1e-10: max |dx1| %.3e  max |dx2| %.3e" % (
        checks["a_clean_rtol1e-12_max_abs_diff"]["x1"],
        checks["a_clean_rtol1e-12_max_abs_diff"]["x2"]), flush=True)

    # (a') the same convergence test for every effect
    conv = {}
    for eff in EFFECTS[1:]:
        conv[eff.name] = convergence_check(eff, noiseless[eff.name], t, t_start)
    checks["a_other_effects_rtol1e-12_max_abs_diff"] = conv

    # (b) sensor lag against the exact first-order-hold solution of the lag on the clean
    # output sampled finely (two grids, to show the check's own O(h^2) error, and their
    # Richardson extrapolation (4 s_{h/2} - s_h) / 3)
    lag_y = noiseless["sensor-lag"]
    lag_eff = EFFECTS[2]
    bchk = {}
    s_h = {}
    for h in (1e-4, 5e-5):
        s_h[h] = lag_check(clean_traj, lag_eff.tau_s, h, t_start)
        bchk["h=%g" % h] = {"x1": float(np.max(np.abs(s_h[h][0] - lag_y[0]))),
                            "x2": float(np.max(np.abs(s_h[h][1] - lag_y[1])))}
    s_r = (4.0 * s_h[5e-5] - s_h[1e-4]) / 3.0
    bchk["richardson"] = {"x1": float(np.max(np.abs(s_r[0] - lag_y[0]))),
                          "x2": float(np.max(np.abs(s_r[1] - lag_y[1])))}
    for k, v in bchk.items():
        print("(b) sensor lag vs exact FOH lag of the finely sampled clean output, %s: "
              "max |ds1| %.3e  max |ds2| %.3e" % (k, v["x1"], v["x2"]), flush=True)
    checks["b_sensor_lag_vs_discrete_exact_lag_max_abs_diff"] = bchk

    # (d) settling: how far the record at t >= 0 still is from the motion that forgets its
    # start (a run started at t_start - 40 s), per 5 s window
    early = Sim(EFFECTS[0]).run(t0=t_start - 40.0)
    z = early(t)
    dchk = {}
    for w0 in range(0, 60, 5):
        sel = (t >= w0) & (t < w0 + 5)
        dchk["t in [%d,%d)" % (w0, w0 + 5)] = {
            "x1": float(np.max(np.abs(z[0] - clean_y[0])[sel])),
            "x2": float(np.max(np.abs(z[2] - clean_y[1])[sel]))}
    checks["d_start_transient_max_abs_diff_vs_start_%g" % (t_start - 40.0)] = dchk
    for k, v in dchk.items():
        print("(d) clean started at %g vs %g, %s: max |dx1| %.3e  max |dx2| %.3e" % (
            t_start - 40.0, t_start, k, v["x1"], v["x2"]), flush=True)

    # (e) friction2: the event-based stick-slip solution against smooth friction
    # -F tanh(v2/eps) integrated without events (LSODA); the gap should shrink ~ eps
    f_eff = EFFECTS[6]
    f_sim = Sim(f_eff)
    f_y = noiseless["friction2"]
    echk = {}
    for eps in (1e-4, 1e-5):
        def smooth_rhs(tt, z, eps=eps):
            a_up, a_down = f_sim.accel_v1(tt, z)
            a1 = a_up if z[1] > f_eff.v_switch else a_down
            F2 = f_sim.force2(z)
            return [z[1], a1, z[3],
                    (F2 - f_eff.friction2 * math.tanh(z[3] / eps)) / f_eff.params["m2"]]
        sol = solve_ivp(smooth_rhs, (t_start, T_END), [0.0, 0.0, 0.0, 0.0], method="LSODA",
                        rtol=1e-9, atol=1e-12, t_eval=t, max_step=MAX_STEP)
        echk["eps=%g" % eps] = {"x1": float(np.max(np.abs(sol.y[0] - f_y[0]))),
                                "x2": float(np.max(np.abs(sol.y[2] - f_y[1])))}
        print("(e) friction2 vs smooth friction tanh(v2/%g): max |dx1| %.3e  max |dx2| %.3e"
              % (eps, echk["eps=%g" % eps]["x1"], echk["eps=%g" % eps]["x2"]), flush=True)
    checks["e_friction2_vs_tanh_regularised_max_abs_diff"] = echk

    # (f) posvel: convergence relative to the output RMS, and an event-free integration written
    # directly from the formulas
    pv = _single("posvel")
    checks["f_posvel"] = posvel_check(pv, noiseless["posvel"], conv["posvel"], t, t_start)

    truth["self_checks"] = checks
    with open(os.path.join(args.out, "truth.json"), "w") as f:
        json.dump(truth, f, indent=2)
        f.write("\n")
    total = sum(os.path.getsize(os.path.join(args.out, n)) for n in os.listdir(args.out))
    print("fixtures total size: %d bytes" % total)


# Threshold of the triples' visibility self-check (d): the record without each effect (the
# constituent pair or single simulated alone) must differ from the triple's noiseless output
# by at least this many noise std (RMS over the 6001 samples), on both outputs.
VISIBLE_MIN_SD = 10.0


def _sub_label(names):
    """Label of a constituent (a proper sub-combination) in the rms_over_noise_std keys."""
    return names[0] + "_alone" if len(names) == 1 else "+".join(names) + "_pair"


def _sub_effect(names):
    """The constituent simulated alone: a single effect as in its own record, or a pair."""
    return _single(names[0]) if len(names) == 1 else _combine(*names)


def main_combos(args, combos, seed_base, label, regenerate, references):
    """Write records with several effects at once (PAIRS or TRIPLES), their truth.json, and run
    their self-checks.  label is "pair" or "triple"; references are extra truth.json entries
    pointing to the records of the constituents."""
    t_start = args.t_start
    os.makedirs(args.out, exist_ok=True)
    t = sample_times()
    u = u_vec(t)
    truth = truth_header(t_start, u, regenerate)
    truth["start_transient"] = (
        "the simulations start from rest at t_start; the transient has not fully decayed at "
        "t = 0 (for the clean model: up to ~6e-4 m (x1) and ~1.3e-3 m (x2) at t in [0,5) "
        "against a run started 40 s earlier, below the noise std only from t ~ 15-20 s on; "
        "see self_checks.d_* in ../two-dof-effects/truth.json). This is part of the true "
        "trajectory from the stated initial condition.")
    truth.update(references)
    truth["files"] = {}
    checks = {}

    # the proper non-empty sub-combinations of each record, smallest first, each in the
    # record's order of effects (for a pair: its two single effects)
    subsets = {eff.name: [c for r in range(1, len(eff.parts))
                          for c in itertools.combinations(eff.parts, r)]
               for eff in combos}

    # noiseless outputs of the clean model and of every constituent (single effects as in their
    # own records, pairs as in PAIRS), each simulated alone
    order = [e.name for e in EFFECTS]
    needed = [("clean",)] + sorted({c for eff in combos for c in subsets[eff.name]},
                                   key=lambda c: (len(c), [order.index(n) for n in c]))
    alone = {}
    for names in needed:
        eff = _sub_effect(names)
        tr = Sim(eff).run(t0=t_start)
        alone[names] = np.vstack(outputs(eff, tr, t))
    clean = alone[("clean",)]

    def sz(d):
        return {"x1": rms(d[0]), "x2": rms(d[1])}

    def sd(d):
        return {k: v / NOISE_STD for k, v in sz(d).items()}

    noiseless = {}
    sizes = {}
    for i, eff in enumerate(combos):
        traj = Sim(eff).run(t0=t_start)
        y = np.vstack(outputs(eff, traj, t))
        noiseless[eff.name] = (y, traj)
        seed = seed_base + i
        noise = np.random.default_rng(seed).normal(0.0, NOISE_STD, size=(N_SAMPLES, 2))
        n1 = y[0] + noise[:, 0]
        n2 = y[1] + noise[:, 1]
        fname = eff.name + ".csv"
        write_csv(os.path.join(args.out, fname), t, u, n1, n2)

        subs = subsets[eff.name]
        size = {label + "_minus_clean": sd(y - clean)}
        for c in subs:
            size[_sub_label(c) + "_minus_clean"] = sd(alone[c] - clean)
        for c in subs:
            size[label + "_minus_" + _sub_label(c)] = sd(y - alone[c])
        # the part that is not additive: the alternating sum over all sub-combinations
        # (pair: y - A - B + clean; triple: y - AB - AC - BC + A + B + C - clean)
        inter = y
        n = len(eff.parts)
        for r in range(n - 1, -1, -1):
            for c in (itertools.combinations(eff.parts, r) if r else [("clean",)]):
                inter = inter - alone[c] if (n - r) % 2 else inter + alone[c]
        size[{"pair": "interaction_pair_minus_both_alone_plus_clean",
              "triple": "interaction_triple_minus_pairs_plus_singles_minus_clean"}[label]] = \
            sd(inter)
        sizes[fname] = size
        entry = {
            "effects": list(eff.parts),
            "description": eff.description,
            "true_values": eff.true_values,
            "parameters": eff.params,
            "extra": {"drag_d": eff.drag, "tau_s": eff.tau_s, "input_delay": eff.delay,
                      "v_switch": eff.v_switch, "friction2_F": eff.friction2},
            "drag_evaluation": ("-d*v1^2 in mode up, +d*v1^2 in mode down (= -d*|v1|*v1 on "
                                "each mode's side of v1 = 0)" if eff.smooth_drag else None),
            "noise_std": NOISE_STD,
            "noise_seed": seed,
            "rms_noiseless_minus_clean_noiseless": sz(y - clean),
            "rms_record_minus_clean_noiseless": {"x1": rms(n1 - clean[0]),
                                                 "x2": rms(n2 - clean[1])},
            "rms_over_noise_std": size,
            "hybrid_summary": traj.summary(),
        }
        truth["files"][fname] = entry
        print("%s  %s" % (fname, traj.summary()), flush=True)
        for k, v in size.items():
            print("    RMS/noise %-58s x1 %9.2f  x2 %9.2f" % (k, v["x1"], v["x2"]), flush=True)
    checks["rms_over_noise_std"] = sizes

    # (a) convergence: every record again at rtol 1e-12, atol 1e-14
    conv = {}
    for eff in combos:
        tr = Sim(eff).run(t0=t_start, rtol=1e-12, atol=1e-14)
        f = np.vstack(outputs(eff, tr, t))
        y = noiseless[eff.name][0]
        conv[eff.name] = {"x1": float(np.max(np.abs(f[0] - y[0]))),
                          "x2": float(np.max(np.abs(f[1] - y[1])))}
        print("(a) %-30s rtol 1e-12 vs 1e-10: max |dx1| %.3e  max |dx2| %.3e" % (
            eff.name, conv[eff.name]["x1"], conv[eff.name]["x2"]), flush=True)
    checks["a_rtol1e-12_max_abs_diff"] = conv

    # (b) the records with a sensor lag: their lag states against the exact first-order-hold
    # lag of the other effects' finely sampled output (h and h/2, and their Richardson
    # extrapolation), as for sensor-lag.csv
    bchk = {}
    for eff in combos:
        if eff.tau_s is None:
            continue
        others = [n for n in eff.parts if _single(n).tau_s is None]
        ref_eff = _combine(*others)          # with drag: the same smooth form as the record
        ref = Sim(ref_eff).run(t0=t_start, rtol=1e-12, atol=1e-14)
        y = noiseless[eff.name][0]
        s_h = {}
        res = {}
        for h in (1e-4, 5e-5):
            s_h[h] = lag_check(ref, eff.tau_s, h, t_start)
            res["h=%g" % h] = {"x1": float(np.max(np.abs(s_h[h][0] - y[0]))),
                               "x2": float(np.max(np.abs(s_h[h][1] - y[1])))}
        s_r = (4.0 * s_h[5e-5] - s_h[1e-4]) / 3.0
        res["richardson"] = {"x1": float(np.max(np.abs(s_r[0] - y[0]))),
                             "x2": float(np.max(np.abs(s_r[1] - y[1])))}
        for k, v in res.items():
            print("(b) %s lag states vs exact FOH lag of the finely sampled %s output, %s: "
                  "max |ds1| %.3e  max |ds2| %.3e" % (eff.name, ref_eff.name, k, v["x1"],
                                                      v["x2"]), flush=True)
        bchk[eff.name] = res
    checks["b_sensor_lag_vs_discrete_exact_lag_max_abs_diff"] = bchk

    # (c) the records with drag, with the drag evaluated as written, -d |v1| v1 (kink inside
    # the step that crosses v1 = 0), at rtol 1e-12: the same records up to that form's
    # integration error
    cchk = {}
    for eff in combos:
        if not eff.smooth_drag:
            continue
        kinked = copy.copy(eff)
        kinked.smooth_drag = False
        tr = Sim(kinked).run(t0=t_start, rtol=1e-12, atol=1e-14)
        f = np.vstack(outputs(kinked, tr, t))
        y = noiseless[eff.name][0]
        cchk[eff.name] = {"x1": float(np.max(np.abs(f[0] - y[0]))),
                          "x2": float(np.max(np.abs(f[1] - y[1])))}
        print("(c) %-30s drag as -d|v1|v1 at rtol 1e-12 vs record: max |dx1| %.3e  "
              "max |dx2| %.3e" % (eff.name, cchk[eff.name]["x1"], cchk[eff.name]["x2"]),
              flush=True)
    checks["c_drag_as_written_rtol1e-12_max_abs_diff"] = cchk

    # (d) triples only: every effect is visible, i.e. the record differs from each of its
    # constituents simulated alone (the pair without one effect, the single without two) by
    # clearly more than the noise
    if label == "triple":
        dchk = {"threshold_rms_over_noise_std": VISIBLE_MIN_SD, "files": {}}
        ok_all = True
        for eff in combos:
            size = sizes[eff.name + ".csv"]
            res = {}
            for c in sorted(subsets[eff.name], key=len, reverse=True):
                v = size[label + "_minus_" + _sub_label(c)]
                m = min(v["x1"], v["x2"])
                missing = [n for n in eff.parts if n not in c]
                res[_sub_label(c)] = {"missing_effects": missing, "min_over_outputs": m,
                                      "pass": bool(m >= VISIBLE_MIN_SD)}
                ok_all = ok_all and m >= VISIBLE_MIN_SD
                print("(d) %-30s minus %-28s (without %s): min RMS/noise %9.2f  %s" % (
                    eff.name, _sub_label(c), "+".join(missing), m,
                    "ok" if m >= VISIBLE_MIN_SD else "FAIL"), flush=True)
            dchk["files"][eff.name] = res
        dchk["all_pass"] = bool(ok_all)
        print("(d) every effect visible (>= %g noise std RMS on both outputs): %s" % (
            VISIBLE_MIN_SD, "yes" if ok_all else "NO"), flush=True)
        checks["d_every_effect_visible"] = dchk

    truth["self_checks"] = checks
    with open(os.path.join(args.out, "truth.json"), "w") as f:
        json.dump(truth, f, indent=2)
        f.write("\n")
    total = sum(os.path.getsize(os.path.join(args.out, n)) for n in os.listdir(args.out))
    print("fixtures total size: %d bytes" % total)
    if label == "triple" and not checks["d_every_effect_visible"]["all_pass"]:
        return 1
    return 0


def main_pairs(args):
    """Write the two-effect records, their truth.json, and run their self-checks."""
    return main_combos(args, PAIRS, PAIR_SEED_BASE, "pair",
                       "python3 tests/oracle/two_dof_effects.py --pairs",
                       {"single_effect_records": "../two-dof-effects/ (same input, same "
                                                 "definitions)"})


def main_triples(args):
    """Write the three-effect records, their truth.json, and run their self-checks."""
    return main_combos(args, TRIPLES, TRIPLE_SEED_BASE, "triple",
                       "python3 tests/oracle/two_dof_effects.py --triples",
                       {"single_effect_records": "../two-dof-effects/ (same input, same "
                                                 "definitions)",
                        "pair_records": "../two-dof-pairs/ (same input, same definitions; "
                                        "the constituent pairs drag+input-delay, "
                                        "input-delay+stiffer-k2, drag+sensor-lag and "
                                        "input-delay+sensor-lag are records there, "
                                        "drag+stiffer-k2 and sensor-lag+stiffer-k2 are "
                                        "not)"})


if __name__ == "__main__":
    sys.exit(main())
