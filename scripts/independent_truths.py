"""Effect truths written by a simulator of this script's own, fed to `twin diagnose` as recordings.

    git show a6f6976:twin/model/blueboat.json > /tmp/blueboat_a6f6976.json
    python scripts/independent_truths.py [--set first|...|twelfth] [--stage before|after] --prior /tmp/blueboat_a6f6976.json
                                         [--only CASE,...] [--work /tmp/independent_truths]
    python scripts/independent_truths.py --set SET --truth-given --prior /tmp/blueboat_a6f6976.json

Every set's stages start from that BlueBoat file (--prior), whose numbers this simulator reproduces:
the shipped BlueBoat (the default) is another hull, so the nulls themselves would carry its form
error.

The simulator here shares no physics with the package: its own three-degree-of-freedom equations
(rigid and added mass, Coriolis and Munk terms, linear and quadratic damping, integrated by RK4),
its own thrust map and its own sensors, written from the BlueBoat's nominal numbers (mass, inertia,
added mass, damping coefficients, the thrust curve's coefficients and the thrusters' positions,
read from the shipped vessel file as numbers, nothing else). The effects it can conceal have forms
the effect library does not have:

- a dead zone on ONE thruster only, soft-edged: that thruster gives nothing within ±EDGE µs of its
  neutral and its full thrust from EDGE + SOFT µs on, rising smoothly in between;
- a thrust loss growing with the square of the speed through the water: T·(1 − k·u²) (the
  library's is T0 − c·√|T0|·u_a);
- a thrust that sags over the run (the library's linear decay, written here afresh): truths beside
  which a heading bias has been drawn although none was there;
- a wind whose load has another shape than the library's: X ∝ −cos γ·(1 − 0.3 sin²γ),
  Y ∝ sin γ·|sin γ|, N ∝ −sin γ (its centre of pressure aft of midships on either side);
- nulls.

Each recording is written as the generic CSV (lat/lon at 5 Hz logged at 10 Hz, heading 10 Hz,
PWM 10 Hz; the rows' times are floating-point multiples of 0.1 s, and where one falls a hair short of a
fix's time the fix reaches the log one row late, about one fix in twenty, as a logger's jitter) and diagnosed from the untuned BlueBoat prior, as a user would feed a log. A case is
exact when the truth is named in the library's terms with its values within 30 % (30° for a
direction) and nothing else is named; a heading bias the compass calibration applies is not an
effect named. The library's terms of a form it does not have: the one-thruster dead zone's edge is
the soft edge's middle; the u² loss's `thrust_speed_loss` coefficient is the least-squares match
over the recording's own samples of k·T·u² by c·√|T|·u.

With --truth-given, each truth in the library's terms is put into the prior at its own values,
nothing fitted, and judged by the rule the diagnosis names an effect by on the blocks a diagnosis of
that recording judges on (diagnose.doctor.given_evidence, `twin diagnose --given`): whether the
recording can prove it at all. The page gains that column beside the stages already run.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import twin.vessel as vessel_mod  # noqa: E402
from twin.diagnose.doctor import diagnose, given_evidence  # noqa: E402
from twin.engine.mjcf import compile_vessel  # noqa: E402
from twin.formats import read_recording  # noqa: E402
from twin.viz.pages import ResultPage, ResultTable, checkout_commit, given_cell, given_record, staged  # noqa: E402

DT_S = 0.02
RHO_AIR = 1.225
NEUTRAL_US = 1511.0
ORIGIN = (63.4, 10.3)
TOLERANCE, TOLERANCE_DEG = 0.30, 30.0


@dataclass(frozen=True)
class Case:
    name: str
    kind: str  # null, one_dead_zone, speed_loss_u2, decay, wind_shape
    values: tuple = ()
    seed: int = 0


CASES = [
    Case("null-1", "null", (), 11), Case("null-2", "null", (), 12),
    Case("one_dead_zone-left", "one_dead_zone", ("left", 60.0, 30.0), 13),
    Case("one_dead_zone-right", "one_dead_zone", ("right", 80.0, 30.0), 14),
    Case("speed_loss_u2-0.10", "speed_loss_u2", (0.10,), 15), Case("speed_loss_u2-0.18", "speed_loss_u2", (0.18,), 16),
    Case("decay-0.02", "decay", (0.02,), 17), Case("decay-0.04", "decay", (0.04,), 18),
    Case("wind_shape-5-60", "wind_shape", (5.0, 60.0), 19), Case("wind_shape-6-250", "wind_shape", (6.0, 250.0), 20),
]
CASES_SECOND = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-3", "null", (), 21), Case("null-4", "null", (), 22),
    Case("one_dead_zone-right-70-40", "one_dead_zone", ("right", 70.0, 40.0), 23),
    Case("one_dead_zone-left-90-20", "one_dead_zone", ("left", 90.0, 20.0), 24),
    Case("speed_loss_u2-0.14", "speed_loss_u2", (0.14,), 25), Case("speed_loss_u2-0.22", "speed_loss_u2", (0.22,), 26),
    Case("decay-0.03", "decay", (0.03,), 27), Case("decay-0.05", "decay", (0.05,), 28),
    Case("wind_shape-5.5-140", "wind_shape", (5.5, 140.0), 29),
    Case("wind_shape-6.5-320", "wind_shape", (6.5, 320.0), 30),
]
CASES_THIRD = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-5", "null", (), 31), Case("null-6", "null", (), 32),
    Case("one_dead_zone-left-75-35", "one_dead_zone", ("left", 75.0, 35.0), 33),
    Case("one_dead_zone-right-85-25", "one_dead_zone", ("right", 85.0, 25.0), 34),
    Case("speed_loss_u2-0.12", "speed_loss_u2", (0.12,), 35), Case("speed_loss_u2-0.20", "speed_loss_u2", (0.20,), 36),
    Case("decay-0.025", "decay", (0.025,), 37), Case("decay-0.045", "decay", (0.045,), 38),
    Case("wind_shape-5-200", "wind_shape", (5.0, 200.0), 39),
    Case("wind_shape-6-30", "wind_shape", (6.0, 30.0), 40),
]
CASES_FOURTH = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-7", "null", (), 41), Case("null-8", "null", (), 42),
    Case("one_dead_zone-left-65-40", "one_dead_zone", ("left", 65.0, 40.0), 43),
    Case("one_dead_zone-right-95-30", "one_dead_zone", ("right", 95.0, 30.0), 44),
    Case("speed_loss_u2-0.16", "speed_loss_u2", (0.16,), 45), Case("speed_loss_u2-0.24", "speed_loss_u2", (0.24,), 46),
    Case("decay-0.035", "decay", (0.035,), 47), Case("decay-0.055", "decay", (0.055,), 48),
    Case("wind_shape-4.5-100", "wind_shape", (4.5, 100.0), 49),
    Case("wind_shape-7-280", "wind_shape", (7.0, 280.0), 50),
]
CASES_FIFTH = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-9", "null", (), 51), Case("null-10", "null", (), 52),
    Case("one_dead_zone-right-70-45", "one_dead_zone", ("right", 70.0, 45.0), 53),
    Case("one_dead_zone-left-85-35", "one_dead_zone", ("left", 85.0, 35.0), 54),
    Case("speed_loss_u2-0.2", "speed_loss_u2", (0.2,), 55), Case("speed_loss_u2-0.28", "speed_loss_u2", (0.28,), 56),
    Case("decay-0.04", "decay", (0.04,), 57), Case("decay-0.06", "decay", (0.06,), 58),
    Case("wind_shape-5-200", "wind_shape", (5.0, 200.0), 59),
    Case("wind_shape-6-20", "wind_shape", (6.0, 20.0), 60),
]
CASES_SIXTH = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-11", "null", (), 61), Case("null-12", "null", (), 62),
    Case("one_dead_zone-left-75-40", "one_dead_zone", ("left", 75.0, 40.0), 63),
    Case("one_dead_zone-right-90-30", "one_dead_zone", ("right", 90.0, 30.0), 64),
    Case("speed_loss_u2-0.15", "speed_loss_u2", (0.15,), 65), Case("speed_loss_u2-0.26", "speed_loss_u2", (0.26,), 66),
    Case("decay-0.045", "decay", (0.045,), 67), Case("decay-0.065", "decay", (0.065,), 68),
    Case("wind_shape-5.5-250", "wind_shape", (5.5, 250.0), 69),
    Case("wind_shape-6.5-140", "wind_shape", (6.5, 140.0), 70),
]
CASES_SEVENTH = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-13", "null", (), 71), Case("null-14", "null", (), 72),
    Case("one_dead_zone-right-80-35", "one_dead_zone", ("right", 80.0, 35.0), 73),
    Case("one_dead_zone-left-70-45", "one_dead_zone", ("left", 70.0, 45.0), 74),
    Case("speed_loss_u2-0.18", "speed_loss_u2", (0.18,), 75), Case("speed_loss_u2-0.24", "speed_loss_u2", (0.24,), 76),
    Case("decay-0.03", "decay", (0.03,), 77), Case("decay-0.055", "decay", (0.055,), 78),
    Case("wind_shape-6-320", "wind_shape", (6.0, 320.0), 79),
    Case("wind_shape-5-80", "wind_shape", (5.0, 80.0), 80),
]
CASES_EIGHTH = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-15", "null", (), 81), Case("null-16", "null", (), 82),
    Case("one_dead_zone-left-85-40", "one_dead_zone", ("left", 85.0, 40.0), 83),
    Case("one_dead_zone-right-75-30", "one_dead_zone", ("right", 75.0, 30.0), 84),
    Case("speed_loss_u2-0.14", "speed_loss_u2", (0.14,), 85), Case("speed_loss_u2-0.22", "speed_loss_u2", (0.22,), 86),
    Case("decay-0.04", "decay", (0.04,), 87), Case("decay-0.06", "decay", (0.06,), 88),
    Case("wind_shape-5.5-190", "wind_shape", (5.5, 190.0), 89),
    Case("wind_shape-6.5-350", "wind_shape", (6.5, 350.0), 90),
]
CASES_NINTH = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-17", "null", (), 91), Case("null-18", "null", (), 92),
    Case("one_dead_zone-right-85-35", "one_dead_zone", ("right", 85.0, 35.0), 93),
    Case("one_dead_zone-left-80-30", "one_dead_zone", ("left", 80.0, 30.0), 94),
    Case("speed_loss_u2-0.16", "speed_loss_u2", (0.16,), 95), Case("speed_loss_u2-0.2", "speed_loss_u2", (0.20,), 96),
    Case("decay-0.035", "decay", (0.035,), 97), Case("decay-0.05", "decay", (0.05,), 98),
    Case("wind_shape-6-100", "wind_shape", (6.0, 100.0), 99),
    Case("wind_shape-5-260", "wind_shape", (5.0, 260.0), 100),
]
CASES_TENTH = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-19", "null", (), 101), Case("null-20", "null", (), 102),
    Case("one_dead_zone-left-90-35", "one_dead_zone", ("left", 90.0, 35.0), 103),
    Case("one_dead_zone-right-70-40", "one_dead_zone", ("right", 70.0, 40.0), 104),
    Case("speed_loss_u2-0.17", "speed_loss_u2", (0.17,), 105), Case("speed_loss_u2-0.25", "speed_loss_u2", (0.25,), 106),
    Case("decay-0.045", "decay", (0.045,), 107), Case("decay-0.06", "decay", (0.06,), 108),
    Case("wind_shape-6.5-40", "wind_shape", (6.5, 40.0), 109),
    Case("wind_shape-5.5-200", "wind_shape", (5.5, 200.0), 110),
]
CASES_ELEVENTH = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-21", "null", (), 111), Case("null-22", "null", (), 112),
    Case("one_dead_zone-right-80-45", "one_dead_zone", ("right", 80.0, 45.0), 113),
    Case("one_dead_zone-left-75-35", "one_dead_zone", ("left", 75.0, 35.0), 114),
    Case("speed_loss_u2-0.15", "speed_loss_u2", (0.15,), 115), Case("speed_loss_u2-0.23", "speed_loss_u2", (0.23,), 116),
    Case("decay-0.04", "decay", (0.04,), 117), Case("decay-0.055", "decay", (0.055,), 118),
    Case("wind_shape-6-300", "wind_shape", (6.0, 300.0), 119),
    Case("wind_shape-5-150", "wind_shape", (5.0, 150.0), 120),
]
CASES_TWELFTH = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-23", "null", (), 121), Case("null-24", "null", (), 122),
    Case("one_dead_zone-left-85-40", "one_dead_zone", ("left", 85.0, 40.0), 123),
    Case("one_dead_zone-right-70-30", "one_dead_zone", ("right", 70.0, 30.0), 124),
    Case("speed_loss_u2-0.19", "speed_loss_u2", (0.19,), 125), Case("speed_loss_u2-0.26", "speed_loss_u2", (0.26,), 126),
    Case("decay-0.045", "decay", (0.045,), 127), Case("decay-0.06", "decay", (0.06,), 128),
    Case("wind_shape-5.5-60", "wind_shape", (5.5, 60.0), 129),
    Case("wind_shape-6.5-220", "wind_shape", (6.5, 220.0), 130),
]
SETS = {"first": CASES, "second": CASES_SECOND, "third": CASES_THIRD, "fourth": CASES_FOURTH, "fifth": CASES_FIFTH,
        "sixth": CASES_SIXTH, "seventh": CASES_SEVENTH,
        "eighth": CASES_EIGHTH, "ninth": CASES_NINTH, "tenth": CASES_TENTH, "eleventh": CASES_ELEVENTH,
        "twelfth": CASES_TWELFTH}
PAGES = {"first": "independent_truths", "second": "independent_truths_second", "third": "independent_truths_third",
         "fourth": "independent_truths_fourth", "fifth": "independent_truths_fifth", "sixth": "independent_truths_sixth",
         "seventh": "independent_truths_seventh", "eighth": "independent_truths_eighth",
         "ninth": "independent_truths_ninth", "tenth": "independent_truths_tenth", "eleventh": "independent_truths_eleventh",
         "twelfth": "independent_truths_twelfth"}
# what a stage of a set ran, where its stages differ in the diagnosis
STAGE_METHODS = {("twelfth", "before"): "the diagnosis as it was when the set was fixed",
                 ("eleventh", "before"): "the diagnosis as it was when the set was fixed",
                 ("tenth", "before"): "the diagnosis as it was when the set was fixed",
                 ("tenth", "after"): "one ESC's PWM span (pwm_span_left, pwm_span_right) offered as an effect",
                 ("ninth", "before"): "the diagnosis as it was when the set was fixed",
                 ("ninth", "after"): "a wind's side-force coefficient per lateral area fitted between none and a two-dimensional flat plate's 2.0, both ends unphysical edges",
                 ("eighth", "before"): "the diagnosis as it was when the set was fixed",
                 ("eighth", "after"): "each candidate screened by two Gauss-Newton steps (each with its line search), "
                                      "not one, on held-out windows spread within each log; a thrust scale kept for its "
                                      "fewer quantities checked for a loss with speed",
                 ("seventh", "before"): "the diagnosis as it was when the set was fixed",
                 ("seventh", "after"): "screening ranked on windows its one step did not fit; of rivals the blocks "
                                       "lean to neither way (|z| < 1.5) that earn their place, the one with the fewest "
                                       "quantities kept",
                 ("sixth", "after"): "the diagnosis as it was when the set was fixed (no change judged on it)",
                 ("fifth", "before"): "the diagnosis as it was when the set was fixed",
                 ("fifth", "after"): "each fold's scanned candidates (time shifts, dead zones) scanned afresh on that "
                                     "fold's training windows, not refined from a screening that saw its held-out blocks",
                 ("fourth", "before"): "the diagnosis as it was when the set was fixed",
                 ("fourth", "after"): "a timing shift named only where it exceeds the floor by half a step of the grid it is read on (fit/kinematic.py)",
                 ("third", "before"): "the diagnosis as it was when the set was fixed",
                 ("third", "fewer numbers among rivals (not kept)"): "of the rivals the blocks cannot tell from the winner (z ≤ 3) that earn their place themselves, the one with fewer fitted numbers kept; full_thrust, like thrust_gain, tested as a stand-in for a thrust loss with speed",
                 ("second", "before"): "a GNSS fixes' latency searched in the dynamics as well as read from the kinematics",
                 ("second", "after"): "a GNSS fixes' latency read from the kinematics alone (diagnose/doctor.py "
                                      "KINEMATIC_ONLY)"}
# the stages' names as the page shows them
STAGE_LABELS = {"after, main's new prior": "after, from the shipped first-principles prior"}


# ---------------------------------------------------------------- the simulator

class Hull:
    """The BlueBoat's numbers and this script's own equations."""

    def __init__(self, vessel):
        compiled = compile_vessel(vessel)
        rigid = compiled.geometry.rigid
        am, d = vessel.added_mass, vessel.damping
        self.m = np.array([rigid.mass_kg - am.Xudot, rigid.mass_kg - am.Yvdot, rigid.Iz_kgm2 - am.Nrdot])
        self.lin = np.array([d.Xu, d.Yv, d.Nr])
        self.quad = np.array([d.Xuu, d.Yvv, d.Nrr])
        self.y = np.array(compiled.geometry.thruster_y_m)
        th = vessel.thrusters
        self.fwd, self.rev = np.array(th.forward), np.array(th.reverse)
        self.edge_fwd, self.edge_rev = th.deadzone_fwd, th.deadzone_rev
        self.scale, self.offset = th.pwm_scale_us, th.pwm_offset
        self.gain = np.array([th.gain_left, th.gain_right])
        self.advance = th.advance_loss
        load = vessel.wind_load
        self.area_f, self.area_l, self.length = load.frontal_area_m2, load.lateral_area_m2, load.length_m

    def thrust(self, pwm: np.ndarray, case: Case) -> np.ndarray:
        """Static thrust (N) of each thruster for the PWM pair, with the case's dead zone."""
        x = np.clip(pwm, 1100.0, 1900.0) / self.scale - self.offset
        t = np.where(x >= self.edge_fwd, np.polyval(self.fwd, x), np.where(x <= self.edge_rev, np.polyval(self.rev, x), 0))
        t = t * self.gain
        if case.kind == "one_dead_zone":
            side, edge, soft = case.values
            k = 0 if side == "left" else 1
            off = abs(pwm[k] - NEUTRAL_US)
            s = np.clip((off - edge) / soft, 0.0, 1.0)
            t[k] *= s * s * (3 - 2 * s)
        return t

    def forces(self, nu: np.ndarray, psi: float, pwm: np.ndarray, t_s: float, case: Case) -> np.ndarray:
        u, v, r = nu
        static = self.thrust(pwm, case)
        if case.kind == "decay":
            static = static * max(0.0, 1.0 - case.values[0] * t_s / 60.0)
        ua = u - r * self.y
        delivered = static - self.advance * np.sqrt(np.abs(static)) * ua
        if case.kind == "speed_loss_u2":
            delivered = delivered * (1.0 - case.values[0] * u * u)
        tau = np.array([delivered.sum(), 0.0, -(self.y * delivered).sum()])
        tau += self.lin * nu + self.quad * nu * np.abs(nu)
        m11, m22, m33 = self.m
        tau += np.array([m22 * v * r, -m11 * u * r, -(m22 - m11) * u * v])
        if case.kind == "wind_shape":
            speed, frm = case.values
            wn, we = -speed * math.cos(math.radians(frm)), -speed * math.sin(math.radians(frm))
            c, s = math.cos(psi), math.sin(psi)
            urw, vrw = u - (c * wn + s * we), v - (-s * wn + c * we)
            q = 0.5 * RHO_AIR * (urw * urw + vrw * vrw)
            g = -math.atan2(vrw, urw)
            tau += q * np.array([-0.7 * math.cos(g) * (1 - 0.3 * math.sin(g) ** 2) * self.area_f,
                                 0.9 * math.sin(g) * abs(math.sin(g)) * self.area_l,
                                 -0.08 * math.sin(g) * self.area_l * self.length])
        return tau / self.m

    def run(self, pwm_t: np.ndarray, pwm: np.ndarray, case: Case) -> tuple[np.ndarray, np.ndarray]:
        t = np.arange(0.0, pwm_t[-1], DT_S)
        state = np.zeros(6)  # north, east, psi, u, v, r
        out = np.empty((len(t), 6))
        idx = np.clip(np.searchsorted(pwm_t, t, side="right") - 1, 0, len(pwm_t) - 1)

        def f(x, p, ts):
            c, s = math.cos(x[2]), math.sin(x[2])
            return np.r_[c * x[3] - s * x[4], s * x[3] + c * x[4], x[5], self.forces(x[3:], x[2], p, ts, case)]
        for i, ts in enumerate(t):
            out[i] = state
            p = pwm[idx[i]]
            k1 = f(state, p, ts)
            k2 = f(state + 0.5 * DT_S * k1, p, ts)
            k3 = f(state + 0.5 * DT_S * k2, p, ts)
            k4 = f(state + DT_S * k3, p, ts)
            state = state + DT_S / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return t, out


def inputs(rng: np.random.Generator, duration_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Sticks held for 2-7 s: straight runs at several throttles (slow ones near the thrusters' dead
    zones among them), turns, spins both ways, now and then astern; PWM every 0.1 s, short ramps
    between holds."""
    t, mean, diff = [], [], []
    now, m, d = 0.0, 0.0, 0.0
    while now < duration_s:
        kind = rng.choice(["straight", "slow", "turn", "spin", "astern", "idle"], p=[0.3, 0.2, 0.2, 0.15, 0.08, 0.07])
        target = {"straight": (rng.uniform(0.25, 0.9), 0.0), "slow": (rng.uniform(0.1, 0.3), rng.uniform(-0.2, 0.2)),
                  "turn": (rng.uniform(0.3, 0.8), rng.uniform(-0.4, 0.4)),
                  "spin": (0.0, rng.choice([-1, 1]) * rng.uniform(0.5, 0.9)), "astern": (rng.uniform(-0.4, -0.15), 0.0),
                  "idle": (0.0, 0.0)}[kind]
        hold = rng.uniform(2.0, 7.0) if kind not in ("straight", "slow") else rng.uniform(5.0, 10.0)
        ramp = rng.uniform(0.1, 0.6)
        for s in np.arange(0.0, hold + ramp, 0.1):
            a = min(1.0, s / ramp)
            t.append(now + s)
            mean.append(m + a * (target[0] - m))
            diff.append(d + a * (target[1] - d))
        now += hold + ramp
        m, d = target
    t, mean, diff = np.array(t), np.array(mean), np.array(diff)
    pwm = NEUTRAL_US + 400.0 * np.column_stack([mean + diff / 2, mean - diff / 2])
    return t, np.round(np.clip(pwm, 1100.0, 1900.0))


def recording_csv(case: Case, hull: Hull, path: Path, duration_s: float = 420.0) -> dict:
    """Simulate the case and write the log; returns what the truth's library terms need."""
    rng = np.random.default_rng(case.seed)
    pwm_t, pwm = inputs(rng, duration_s)
    t, x = hull.run(pwm_t, pwm, case)
    log_t = np.arange(0.0, t[-1], 0.1)
    at = lambda col: np.interp(log_t, t, x[:, col])  # noqa: E731
    fix_t = np.floor(log_t / 0.2) * 0.2  # a 5-Hz receiver's fix, logged on every row (module docstring: jitter)
    north = np.interp(fix_t, t, x[:, 0]) + rng.normal(0, 0.02, len(log_t))[(fix_t / 0.2).astype(int) % len(log_t)]
    east = np.interp(fix_t, t, x[:, 1]) + rng.normal(0, 0.02, len(log_t))[(fix_t / 0.2).astype(int) % len(log_t)]
    lat = ORIGIN[0] + np.degrees(north / 6_371_000.0)
    lon = ORIGIN[1] + np.degrees(east / (6_371_000.0 * math.cos(math.radians(ORIGIN[0]))))
    heading = np.degrees(at(2) + np.radians(0.3) * rng.standard_normal(len(log_t))) % 360.0
    k = np.clip(np.searchsorted(pwm_t, log_t, side="right") - 1, 0, len(pwm_t) - 1)
    rows = ["t,lat,lon,heading_deg,pwm_left,pwm_right,pwm_neutral_left,pwm_neutral_right"]
    rows += [f"{a:.3f},{b:.10f},{c:.10f},{h:.5f},{int(p[0])},{int(p[1])},{NEUTRAL_US:g},{NEUTRAL_US:g}"
             for a, b, c, h, p in zip(log_t, lat, lon, heading, pwm[k])]
    path.write_text("\n".join(rows) + "\n")
    u = at(3)
    static = np.array([hull.thrust(p, Case("", "null")) for p in pwm[k]])
    return {"u": u, "static": static}


def truth_of(case: Case, sim: dict, hull: Hull) -> tuple[str | None, dict]:
    if case.kind == "null":
        return None, {}
    if case.kind == "one_dead_zone":
        side, edge, soft = case.values
        width = (edge + soft / 2) / hull.scale  # the soft edge's middle, in normalised PWM
        return f"dead_zone_{side}", {"fwd": width, "rev": width}
    if case.kind == "speed_loss_u2":
        k = case.values[0]
        u, t0 = sim["u"], sim["static"]
        ahead = (u[:, None] > 0.1) & (t0 > 0.5)
        lost = k * t0 * (u * u)[:, None]  # what the u² form takes off, per thruster
        shape = np.sqrt(np.abs(t0)) * u[:, None]
        c = float(np.sum((lost * shape)[ahead]) / np.sum((shape * shape)[ahead]))
        return "thrust_speed_loss", {"advance_loss": hull.advance + c}
    if case.kind == "decay":
        return "thrust_decay", {"decay_per_min": case.values[0]}
    if case.kind == "wind_shape":
        return "wind", {"speed_m_s": case.values[0], "dir_deg": case.values[1]}
    raise ValueError(case.kind)


def within(name: str, truth: dict, found: dict) -> bool:
    if name == "wind":
        dang = abs((found["dir_deg"] - truth["dir_deg"] + 180.0) % 360.0 - 180.0)
        return abs(found["speed_m_s"] - truth["speed_m_s"]) <= TOLERANCE * truth["speed_m_s"] and dang <= TOLERANCE_DEG
    return all(abs(found[k] - v) <= TOLERANCE * abs(v) for k, v in truth.items() if k in found)


# the library's names an effect of another form may be named by and still be the truth
SAME = {"wind": ("wind", "wind_shape"), "thrust_decay": ("thrust_decay",), "thrust_speed_loss": ("thrust_speed_loss",)}


def run_case(case: Case, prior, hull: Hull, folder: Path) -> dict:
    path = folder / f"{case.name}.csv"
    sim = recording_csv(case, hull, path)
    truth_name, truth = truth_of(case, sim, hull)
    rec = read_recording(path)
    started = time.time()
    d = diagnose([rec], prior)
    seconds = time.time() - started
    named = [{"name": e["name"], "parameters": dict(e["parameters"])} for e in d.effects]
    accepted = SAME.get(truth_name, (truth_name,))
    hit = next((e for e in named if e["name"] in accepted), None)
    others = [e["name"] for e in named if e is not hit]
    close = bool(hit is not None and within(truth_name, truth, hit["parameters"]))
    return {"case": case.name, "kind": case.kind, "values": list(case.values), "seed": case.seed, "truth": truth_name,
            "truth_values": truth, "named": named, "hit": hit is not None, "within": close, "others": others,
            "exact": (not named) if truth_name is None else (close and not others),
            "calibrations": [c.to_dict() for c in d.calibrations], "notes": list(d.notes), "seconds": round(seconds, 1)}


def judge_truth(case: Case, prior, hull: Hull, folder: Path, commit: str) -> dict | None:
    """The case's truth in the library's terms at its own values, nothing fitted, judged on the recording
    written again from its seed (the simulator is deterministic); None for a null."""
    path = folder / f"{case.name}.csv"
    truth_name, truth = truth_of(case, recording_csv(case, hull, path), hull)
    if truth_name is None:
        return None
    text = f"{truth_name}=" + ",".join(f"{v:.4g}" for v in truth.values())
    return given_record(text, given_evidence([read_recording(path)], prior, [text]), commit)


def given_summary(given: dict, stages: dict) -> str:
    """One sentence: of the truths judged as given, how many the recordings prove, the commit, and how
    many of those each stage named exactly."""
    judged = {k: g for k, g in given.items() if g is not None}
    if not judged:
        return ""
    provable = {k for k, g in judged.items() if g["earns_its_place"]}
    commits = ", ".join(sorted({g["commit"] for g in judged.values()}))
    named = "; ".join(f"of those '{key}' named {sum(r['exact'] for r in res['rows'] if r['case'] in provable)} exactly"
                      for key, res in stages.items())
    return (f" The truth itself, given at its own values in the library's terms and judged by the diagnosis's rule "
            f"on the same blocks (commit {commits}): the recording can prove it in {len(provable)} of {len(judged)}"
            + (f"; {named}." if provable else "."))


def summary_of(rows: list[dict]) -> dict:
    effects = [r for r in rows if r["truth"] is not None]
    nulls = [r for r in rows if r["truth"] is None]
    return {"effects": len(effects), "named": sum(r["hit"] for r in effects), "exact": sum(r["exact"] for r in effects),
            "false_discoveries": sum(len(r["others"]) for r in effects) + sum(len(r["named"]) for r in nulls),
            "nulls": len(nulls), "nulls_clean": sum(not r["named"] for r in nulls)}


def _text(values: dict) -> str:
    return ", ".join(f"{k} {v:.3g}" for k, v in values.items())


def write_page(stages: dict, out: Path, proof_set: str = "first", given: dict | None = None) -> Path:
    tables, lines, given = [], [], given or {}
    cases = SETS[proof_set]
    seeds = [c.seed for c in cases]
    for key, res in stages.items():
        stage = STAGE_LABELS.get(key, key)
        s = summary_of(res["rows"])
        lines.append(f"{stage} (commit {res['commit']}): {s['exact']} of {s['effects']} exact, {s['named']} named; "
                     f"{s['false_discoveries']} false {'discovery' if s['false_discoveries'] == 1 else 'discoveries'}; nulls clean {s['nulls_clean']} of {s['nulls']}")
        tables.append(ResultTable(f"{stage}: each truth (commit {res['commit']})",
                                  ["case", "truth", "named (values)", "exact", "else named",
                                   *(["truth as given"] if given else []), "s"],
                                  [[r["case"], "nothing" if r["truth"] is None else
                                    f"{r['truth']} ({_text(r['truth_values'])})",
                                    "; ".join(f"{e['name']} ({_text(e['parameters'])})" for e in r["named"]) or "nothing",
                                    "yes" if r["exact"] else "no", ", ".join(r["others"]) or "-",
                                    *([given_cell(given.get(r["case"]))] if given else []), r["seconds"]]
                                   for r in res["rows"]]))
    page = ResultPage(
        PAGES[proof_set], "Effect truths from a simulator the library does not share"
        + ("" if proof_set == "first" else f" (proof set: {proof_set})"),
        "python scripts/independent_truths.py" + ("" if proof_set == "first" else f" --set {proof_set}")
        + " --stage STAGE --prior PRIOR",
        f"Ten logs of about 7 minutes written by scripts/independent_truths.py's own three-degree-of-freedom "
        f"simulator from the BlueBoat's nominal numbers, one truth each (seeds {min(seeds)}-{max(seeds)}), diagnosed "
        "from the untuned BlueBoat prior the simulator reads its numbers from.",
        "Effects in forms the effect library does not have: a soft dead zone on one thruster only, a thrust loss "
        "growing with u², a thrust decay and a wind of another load shape; and nulls. Exact: the truth named "
        "with its values within 30 % (30° for a direction) and nothing else. " + " ".join(f"{x}." for x in lines)
        + given_summary(given, stages),
        tables, ["The prior: the stages start from twin/model/blueboat.json of commit a6f6976 (`git show "
                 "a6f6976:twin/model/blueboat.json`, given with --prior), whose numbers this simulator reproduces"
                 + ("; the stage 'from the shipped first-principles prior' from the BlueBoat shipped at that stage's "
                    "commit, whose "
                    "sway-yaw coupling and speed-dependent damping this simulator does not have, so its nulls carry "
                    "that form error" if any(k in STAGE_LABELS for k in stages) else "") + ".",
                 *[f"Stage '{k}': {STAGE_METHODS[(proof_set, k)]}." for k in stages if (proof_set, k) in STAGE_METHODS],
                 "A one-thruster dead zone's truth in the library's terms: its soft edge's middle as a hard edge of "
                 "that thruster (forward and astern alike); the u² loss's: the thrust_speed_loss coefficient that "
                 "matches it over the log's own samples, added to the prior's.",
                 *(["Truth as given: the truth column put into the prior at its values, nothing fitted, judged by the "
                    "rule the diagnosis names an effect by (z ≥ 3 of the held-out blocks' votes and 5 % of the "
                    "held-out misfit above the noise): whether the recording can prove it in the library's form at "
                    "all. A miss where it cannot is the data's or the form's; a fitted form may still do better than "
                    "the given one."] if given else [])],
        {"stages": stages, "cases": [c.__dict__ for c in cases], "given": given})
    return page.write(out)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--set", default="first", choices=list(SETS), help="the proof set (each fixed before it was run)")
    ap.add_argument("--stage", default="after")
    ap.add_argument("--only", default="")
    ap.add_argument("--work", type=Path, default=Path("/tmp/independent_truths"))
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "results")
    ap.add_argument("--page-only", action="store_true", help="rewrite the page from the raw figures there are")
    ap.add_argument("--prior", default="blueboat", help="the vessel file the simulator reads its numbers from and the "
                    "diagnosis starts from (default: the shipped BlueBoat)")
    ap.add_argument("--truth-given", action="store_true",
                    help="judge each case's truth as given (twin diagnose --given) beside the stages already run, "
                         "and rewrite the page")
    args = ap.parse_args()
    raw_path = args.out / "data" / f"{PAGES[args.set]}.json"
    if args.page_only:
        raw = json.loads(raw_path.read_text())
        print(write_page(raw["stages"], args.out, args.set, raw.get("given")))
        return 0
    prior = vessel_mod.load(args.prior)
    hull = Hull(prior)
    if args.truth_given:
        raw = json.loads(raw_path.read_text())
        given, commit = raw.get("given") or {}, checkout_commit(ROOT)
        with tempfile.TemporaryDirectory() as tmp:
            for c in SETS[args.set]:
                given[c.name] = judge_truth(c, prior, hull, Path(tmp), commit)
                print(f"{c.name}: truth as given {given_cell(given[c.name])}", flush=True)
        print(write_page(raw["stages"], args.out, args.set, given))
        return 0
    only = {x for x in args.only.split(",") if x}
    cases = SETS[args.set]
    stage_dir = args.work / args.set / args.stage
    stage_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        for c in cases:
            if only and c.name not in only:
                continue
            row = run_case(c, prior, hull, Path(tmp))
            (stage_dir / f"{c.name}.json").write_text(json.dumps(row, indent=1, default=float))
            print(f"{c.name}: named {', '.join(e['name'] for e in row['named']) or 'nothing'}; exact {row['exact']} "
                  f"({row['seconds']} s)", flush=True)
    stages = staged(args.out / "data" / f"{PAGES[args.set]}.json", args.stage, stage_dir, [c.name for c in cases],
                    summary_of, checkout_commit(ROOT))
    print(write_page(stages, args.out, args.set, json.loads(raw_path.read_text()).get("given") if raw_path.is_file()
                     else None))
    return 0


if __name__ == "__main__":
    sys.exit(main())
