"""Effects concealed in real logs, exactly and without a model, diagnosed with a twin identified on
other runs of the same vessel.

    python scripts/concealed_effects.py [--set first|...|thirtieth] [--stage before|after] [--only CASE,...]
                                        [--work /tmp/concealed_effects]

Each proof set (PROOFS below) is fixed before the diagnosis is changed: which runs, which effects, at
which magnitudes. The second to fourteenth sets regroup the same active BlueBoat runs into other
outings (C, D; E, F; G, H; I, J; K, L; M, N; O, P; Q, R; S, T; U, V; W, P again: the last pair
left, 216 and 228, is too short to diagnose; A, F again; D, K again) and take other Esso turning tests (T3, T4;
T5, T6; T7, T8; T9, T10; T11, T12; T13, T14; T13, T14 again; T5, T6 again; T7, T8 again; T9, T10 again; T11, T12
again; T1, T2 again; T3, T4 again; then A, P with T11, T12 again, J, O with T3, T4 again,
H, N with T7, T8 again, Q, I with T9, T10 again, G, L with T5, T6 again, B, A with T1, T2
again and C, D with T13, T14 again), with other
magnitudes and directions: a change of method chosen while looking at one set is judged on a set it never saw.

Each effect is put into the logs as a sensor or a clock would have put it there, by rewriting the
logged streams alone:

- current: every GNSS fix moved by c·t (NED), t the time the fix was first logged: the ground
  track drifts with the water;
- antenna: every GNSS fix moved by R(ψ)·Δp, ψ the logged heading when the fix was first logged: the
  antenna sits Δp (body axes, forward and to starboard) from where the twin has it;
- input late: the PWM (or propeller-and-rudder) stamps moved later by d: the log's clock runs d
  behind the GNSS and heading;
- one thruster scaled: one thruster's logged PWM scaled about its neutral by s: the log reports
  s times the command the thruster received;
- heading late: the heading stamps moved later by L;
- null: nothing changed.

A fix repeated by a faster logger is moved as its first row was, so it stays a repeat.

BlueBoat: the twin `twin identify` writes from the five least active runs (218, 221, 222, 223, 226,
by share of time under way and turn rate), each log's per-log compass offset dropped; the
effects are concealed in the five most active runs, diagnosed as two outings (216 + 220 + 228,
224 + 225: `twin diagnose` needs about two minutes). Esso Osaka: the twin identified on the nine
random tests with their measured wind as a known input; the effects are concealed in two turning
tests, each diagnosed alone, the twin given that test's mean measured wind (`wind_per_log`, not
fitted), so that the real wind does not stand in the proof's way; from the eighth set on, each
test's measured wind itself is a known input of every free run (`twin diagnose --wind-measured`),
as the twin was identified with it. The Esso has one propeller: one thruster scaled does not apply.

A case is exact when the concealed effect is named with its parameters within 30 % (a vector's
error within 30 % of its length; a direction within 30°) and nothing else is named; a null is
clean when nothing is named. One thruster's PWM scaled by s is that thruster's ESC span 1/s
(pwm_span_left/right); named as a thrust scale
instead, its truth is the thrust scale of that thruster that best matches, in least squares over
the outing's samples, the thrust the twin's map gives for the true PWM to the one it gives for the
logged PWM.

The recordings (../shared/data) are read in place, never copied; without them the script says so
and exits 0. `--stage before` and `--stage after` keep their results side by side in
docs/results/data/concealed_effects.json (the other sets: concealed_effects_second.json, ..._third.json); the page
shows every stage there is.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import twin.vessel as vessel_mod  # noqa: E402
from twin.diagnose.doctor import diagnose, given_evidence  # noqa: E402
from twin.diagnose.verdict import MIN_UNANIMOUS_BLOCKS as MIN_BLOCKS  # noqa: E402
from twin.effects import apply_effects  # noqa: E402
from twin.geodesy import geodetic_from_ned, ned_from_geodetic  # noqa: E402
from twin.ident.identify import identify, read  # noqa: E402
from twin.physics.sensors import log_name  # noqa: E402
from twin.recording import Recording, Stream  # noqa: E402
from twin.viz.pages import ResultPage, ResultTable, checkout_commit, given_cell, given_record, staged  # noqa: E402

SHARED = ROOT.parent / "shared" / "data"
BLUEBOAT = SHARED / "blueboat"
ESSO = SHARED / "esso"
FIT_BLUEBOAT = (218, 221, 222, 223, 226)
OUTINGS = {"A": (216, 220, 228), "B": (224, 225), "C": (216, 224), "D": (220, 225, 228), "E": (216, 220),
           "F": (224, 225, 228), "G": (216, 225), "H": (220, 224), "I": (224, 228), "J": (220, 225),
           "K": (216, 224, 225), "L": (220, 224, 228), "M": (216, 220, 224), "N": (216, 225, 228),
           "O": (216, 224, 228), "P": (220, 224, 225), "Q": (216, 220, 225), "R": (216, 220, 224, 225, 228),
           "S": (216, 220, 224, 228), "T": (220, 224, 225, 228), "U": (216, 220, 224, 225),
           "V": (216, 224, 225, 228), "W": (216, 220, 225, 228)}
ESSO_TESTS = {"T1": "turn_14-Oct-2020_14_29_49.csv", "T2": "turn_14-Sep-2020_14_50_41.csv",
              "T3": "turn_14-Oct-2020_14_08_51.csv", "T4": "turn_14-Sep-2020_13_51_45.csv",
              "T5": "turn_14-Oct-2020_15_06_53.csv", "T6": "turn_14-Sep-2020_15_47_33.csv",
              "T7": "turn_14-Oct-2020_14_17_39.csv", "T8": "turn_14-Sep-2020_14_16_04.csv",
              "T9": "turn_14-Oct-2020_14_39_54.csv", "T10": "turn_14-Sep-2020_13_39_32.csv",
              "T11": "turn_14-Oct-2020_14_56_07.csv", "T12": "turn_14-Oct-2020_15_21_57.csv",
              "T13": "turn_14-Sep-2020_15_58_08.csv", "T14": "turn_cut_14-Sep-2020_16_09_02.csv"}
ESSO_DUPLICATE = "turn_cut_14-Sep-2020_15_58_08.csv"
TOLERANCE = 0.30  # relative
TOLERANCE_DEG = 30.0


@dataclass(frozen=True)
class Case:
    """One concealed effect: vessel, the outing or test, the concealment and its values."""

    vessel: str  # "blueboat" or "esso"
    where: str  # an outing (A, B) or a test (T1, T2)
    kind: str  # null, current, antenna, input_late, thruster_scaled, heading_late
    values: tuple = ()

    @property
    def name(self) -> str:
        vals = "_".join(f"{v:g}" if isinstance(v, float) else str(v) for v in self.values)
        return f"{self.vessel}-{self.where}-{self.kind}" + (f"-{vals}" if vals else "")

    def magnitude(self) -> str:
        v = self.values
        if self.kind == "current":
            return f"{v[0]:g} m/s towards {v[1]:g}°"
        if self.kind == "antenna":
            return f"Δx {v[0]:+g} m, Δy {v[1]:+g} m"
        if self.kind in ("input_late", "heading_late"):
            return f"{v[0]:g} s"
        if self.kind == "thruster_scaled":
            return f"{v[0]} PWM × {v[1]:g}"
        return "-"


# the proof set: fixed before the method is changed
PROOF = [
    Case("blueboat", "A", "null"), Case("blueboat", "B", "null"),
    Case("blueboat", "A", "current", (0.10, 60.0)), Case("blueboat", "B", "current", (0.20, 210.0)),
    Case("blueboat", "A", "antenna", (0.30, 0.0)), Case("blueboat", "B", "antenna", (-0.20, 0.30)),
    Case("blueboat", "A", "input_late", (0.3,)), Case("blueboat", "B", "input_late", (0.5,)),
    Case("blueboat", "A", "thruster_scaled", ("left", 0.8)), Case("blueboat", "B", "thruster_scaled", ("right", 0.7)),
    Case("blueboat", "A", "heading_late", (0.3,)), Case("blueboat", "B", "heading_late", (0.5,)),
    Case("esso", "T1", "null"), Case("esso", "T2", "null"),
    Case("esso", "T1", "current", (0.05, 30.0)), Case("esso", "T2", "current", (0.10, 250.0)),
    Case("esso", "T1", "antenna", (0.50, 0.0)), Case("esso", "T2", "antenna", (-0.30, 0.30)),
    Case("esso", "T1", "input_late", (0.5,)), Case("esso", "T2", "input_late", (1.0,)),
    Case("esso", "T1", "heading_late", (0.3,)), Case("esso", "T2", "heading_late", (0.6,)),
]
PROOF_SECOND = [
    Case("blueboat", "C", "null"), Case("blueboat", "D", "null"),
    Case("blueboat", "C", "current", (0.15, 300.0)), Case("blueboat", "D", "current", (0.12, 150.0)),
    Case("blueboat", "C", "antenna", (0.25, -0.20)), Case("blueboat", "D", "antenna", (-0.30, 0.0)),
    Case("blueboat", "C", "input_late", (0.4,)), Case("blueboat", "D", "input_late", (0.6,)),
    Case("blueboat", "C", "thruster_scaled", ("left", 0.75)), Case("blueboat", "D", "thruster_scaled", ("right", 0.8)),
    Case("blueboat", "C", "heading_late", (0.4,)), Case("blueboat", "D", "heading_late", (0.25,)),
    Case("esso", "T3", "null"), Case("esso", "T4", "null"),
    Case("esso", "T3", "current", (0.08, 100.0)), Case("esso", "T4", "current", (0.06, 330.0)),
    Case("esso", "T3", "antenna", (0.40, -0.20)), Case("esso", "T4", "antenna", (-0.40, 0.0)),
    Case("esso", "T3", "input_late", (0.7,)), Case("esso", "T4", "input_late", (0.5,)),
    Case("esso", "T3", "heading_late", (0.4,)), Case("esso", "T4", "heading_late", (0.5,)),
]
PROOF_THIRD = [
    Case("blueboat", "E", "null"), Case("blueboat", "F", "null"),
    Case("blueboat", "E", "current", (0.18, 20.0)), Case("blueboat", "F", "current", (0.10, 240.0)),
    Case("blueboat", "E", "antenna", (0.20, 0.25)), Case("blueboat", "F", "antenna", (-0.25, -0.25)),
    Case("blueboat", "E", "input_late", (0.5,)), Case("blueboat", "F", "input_late", (0.35,)),
    Case("blueboat", "E", "thruster_scaled", ("right", 0.7)), Case("blueboat", "F", "thruster_scaled", ("left", 0.85)),
    Case("blueboat", "E", "heading_late", (0.35,)), Case("blueboat", "F", "heading_late", (0.45,)),
    Case("esso", "T5", "null"), Case("esso", "T6", "null"),
    Case("esso", "T5", "current", (0.07, 200.0)), Case("esso", "T6", "current", (0.09, 45.0)),
    Case("esso", "T5", "antenna", (0.30, 0.30)), Case("esso", "T6", "antenna", (-0.50, 0.20)),
    Case("esso", "T5", "input_late", (0.6,)), Case("esso", "T6", "input_late", (0.8,)),
    Case("esso", "T5", "heading_late", (0.35,)), Case("esso", "T6", "heading_late", (0.45,)),
]
PROOF_FOURTH = [
    Case("blueboat", "G", "null"), Case("blueboat", "H", "null"),
    Case("blueboat", "G", "current", (0.14, 80.0)), Case("blueboat", "H", "current", (0.16, 330.0)),
    Case("blueboat", "G", "antenna", (0.30, 0.15)), Case("blueboat", "H", "antenna", (-0.20, -0.30)),
    Case("blueboat", "G", "input_late", (0.45,)), Case("blueboat", "H", "input_late", (0.3,)),
    Case("blueboat", "G", "thruster_scaled", ("left", 0.8)), Case("blueboat", "H", "thruster_scaled", ("right", 0.75)),
    Case("blueboat", "G", "heading_late", (0.3,)), Case("blueboat", "H", "heading_late", (0.55,)),
    Case("esso", "T7", "null"), Case("esso", "T8", "null"),
    Case("esso", "T7", "current", (0.07, 160.0)), Case("esso", "T8", "current", (0.10, 280.0)),
    Case("esso", "T7", "antenna", (0.45, 0.10)), Case("esso", "T8", "antenna", (-0.35, -0.25)),
    Case("esso", "T7", "input_late", (0.9,)), Case("esso", "T8", "input_late", (0.6,)),
    Case("esso", "T7", "heading_late", (0.5,)), Case("esso", "T8", "heading_late", (0.3,)),
]
PROOF_FIFTH = [
    Case("blueboat", "I", "null"), Case("blueboat", "J", "null"),
    Case("blueboat", "I", "current", (0.12, 190.0)), Case("blueboat", "J", "current", (0.17, 45.0)),
    Case("blueboat", "I", "antenna", (-0.25, 0.20)), Case("blueboat", "J", "antenna", (0.35, -0.10)),
    Case("blueboat", "I", "input_late", (0.35,)), Case("blueboat", "J", "input_late", (0.55,)),
    Case("blueboat", "I", "thruster_scaled", ("right", 0.85)), Case("blueboat", "J", "thruster_scaled", ("left", 0.7)),
    Case("blueboat", "I", "heading_late", (0.4,)), Case("blueboat", "J", "heading_late", (0.25,)),
    Case("esso", "T9", "null"), Case("esso", "T10", "null"),
    Case("esso", "T9", "current", (0.08, 20.0)), Case("esso", "T10", "current", (0.11, 230.0)),
    Case("esso", "T9", "antenna", (0.30, -0.30)), Case("esso", "T10", "antenna", (-0.45, 0.15)),
    Case("esso", "T9", "input_late", (0.7,)), Case("esso", "T10", "input_late", (1.0,)),
    Case("esso", "T9", "heading_late", (0.45,)), Case("esso", "T10", "heading_late", (0.35,)),
]
PROOF_SIXTH = [
    Case("blueboat", "K", "null"), Case("blueboat", "L", "null"),
    Case("blueboat", "K", "current", (0.15, 130.0)), Case("blueboat", "L", "current", (0.13, 260.0)),
    Case("blueboat", "K", "antenna", (0.20, -0.25)), Case("blueboat", "L", "antenna", (-0.30, -0.15)),
    Case("blueboat", "K", "input_late", (0.5,)), Case("blueboat", "L", "input_late", (0.4,)),
    Case("blueboat", "K", "thruster_scaled", ("left", 0.75)), Case("blueboat", "L", "thruster_scaled", ("right", 0.8)),
    Case("blueboat", "K", "heading_late", (0.3,)), Case("blueboat", "L", "heading_late", (0.5,)),
    Case("esso", "T11", "null"), Case("esso", "T12", "null"),
    Case("esso", "T11", "current", (0.09, 300.0)), Case("esso", "T12", "current", (0.06, 110.0)),
    Case("esso", "T11", "antenna", (-0.40, -0.20)), Case("esso", "T12", "antenna", (0.35, 0.25)),
    Case("esso", "T11", "input_late", (0.8,)), Case("esso", "T12", "input_late", (0.5,)),
    Case("esso", "T11", "heading_late", (0.4,)), Case("esso", "T12", "heading_late", (0.6,)),
]
# T14 runs 270 s (9 blocks of 30 s, under the 10 the dynamics need): both Esso currents go in T13
PROOF_SEVENTH = [
    Case("blueboat", "M", "null"), Case("blueboat", "N", "null"),
    Case("blueboat", "M", "current", (0.11, 340.0)), Case("blueboat", "N", "current", (0.16, 170.0)),
    Case("blueboat", "M", "antenna", (-0.20, 0.30)), Case("blueboat", "N", "antenna", (0.40, 0.10)),
    Case("blueboat", "M", "input_late", (0.6,)), Case("blueboat", "N", "input_late", (0.3,)),
    Case("blueboat", "M", "thruster_scaled", ("right", 0.75)), Case("blueboat", "N", "thruster_scaled", ("left", 0.85)),
    Case("blueboat", "M", "heading_late", (0.45,)), Case("blueboat", "N", "heading_late", (0.35,)),
    Case("esso", "T13", "null"), Case("esso", "T14", "null"),
    Case("esso", "T13", "current", (0.08, 70.0)), Case("esso", "T13", "current", (0.10, 200.0)),
    Case("esso", "T13", "antenna", (0.40, 0.25)), Case("esso", "T14", "antenna", (-0.30, 0.35)),
    Case("esso", "T13", "input_late", (0.6,)), Case("esso", "T14", "input_late", (0.9,)),
    Case("esso", "T13", "heading_late", (0.5,)), Case("esso", "T14", "heading_late", (0.3,)),
]
# the eighth set takes the last unused BlueBoat outings; no Esso turning test is left unseen, so its Esso
# cases reuse T13 and T14 with other values
PROOF_EIGHTH = [
    Case("blueboat", "O", "null"), Case("blueboat", "P", "null"),
    Case("blueboat", "O", "current", (0.14, 225.0)), Case("blueboat", "P", "current", (0.12, 30.0)),
    Case("blueboat", "O", "antenna", (0.25, 0.25)), Case("blueboat", "P", "antenna", (-0.35, -0.10)),
    Case("blueboat", "O", "input_late", (0.45,)), Case("blueboat", "P", "input_late", (0.35,)),
    Case("blueboat", "O", "thruster_scaled", ("left", 0.7)), Case("blueboat", "P", "thruster_scaled", ("right", 0.85)),
    Case("blueboat", "O", "heading_late", (0.3,)), Case("blueboat", "P", "heading_late", (0.55,)),
    Case("esso", "T13", "null"), Case("esso", "T14", "null"),
    Case("esso", "T13", "current", (0.12, 310.0)), Case("esso", "T13", "current", (0.07, 120.0)),
    Case("esso", "T13", "antenna", (-0.35, -0.30)), Case("esso", "T14", "antenna", (0.45, -0.15)),
    Case("esso", "T13", "input_late", (0.8,)), Case("esso", "T14", "input_late", (0.5,)),
    Case("esso", "T13", "heading_late", (0.35,)), Case("esso", "T14", "heading_late", (0.6,)),
]
# the ninth set takes the last unused grouping of three active BlueBoat runs and all five as one outing;
# its Esso cases reuse T5 and T6 (the third set's tests) with other values
PROOF_NINTH = [
    Case("blueboat", "Q", "null"), Case("blueboat", "R", "null"),
    Case("blueboat", "Q", "current", (0.13, 100.0)), Case("blueboat", "R", "current", (0.15, 285.0)),
    Case("blueboat", "Q", "antenna", (0.30, -0.20)), Case("blueboat", "R", "antenna", (-0.25, 0.30)),
    Case("blueboat", "Q", "input_late", (0.4,)), Case("blueboat", "R", "input_late", (0.55,)),
    Case("blueboat", "Q", "thruster_scaled", ("right", 0.8)), Case("blueboat", "R", "thruster_scaled", ("left", 0.75)),
    Case("blueboat", "Q", "heading_late", (0.5,)), Case("blueboat", "R", "heading_late", (0.35,)),
    Case("esso", "T5", "null"), Case("esso", "T6", "null"),
    Case("esso", "T5", "current", (0.10, 160.0)), Case("esso", "T6", "current", (0.08, 340.0)),
    Case("esso", "T5", "antenna", (0.40, -0.20)), Case("esso", "T6", "antenna", (-0.30, -0.35)),
    Case("esso", "T5", "input_late", (0.7,)), Case("esso", "T6", "input_late", (0.9,)),
    Case("esso", "T5", "heading_late", (0.55,)), Case("esso", "T6", "heading_late", (0.4,)),
]
# the tenth set takes two groupings of four active BlueBoat runs; its Esso cases reuse T7 and T8 (the
# fourth set's tests) with other values
PROOF_TENTH = [
    Case("blueboat", "S", "null"), Case("blueboat", "T", "null"),
    Case("blueboat", "S", "current", (0.11, 200.0)), Case("blueboat", "T", "current", (0.14, 50.0)),
    Case("blueboat", "S", "antenna", (-0.30, -0.20)), Case("blueboat", "T", "antenna", (0.35, 0.15)),
    Case("blueboat", "S", "input_late", (0.5,)), Case("blueboat", "T", "input_late", (0.3,)),
    Case("blueboat", "S", "thruster_scaled", ("left", 0.8)), Case("blueboat", "T", "thruster_scaled", ("right", 0.7)),
    Case("blueboat", "S", "heading_late", (0.4,)), Case("blueboat", "T", "heading_late", (0.6,)),
    Case("esso", "T7", "null"), Case("esso", "T8", "null"),
    Case("esso", "T7", "current", (0.09, 250.0)), Case("esso", "T8", "current", (0.12, 80.0)),
    Case("esso", "T7", "antenna", (-0.40, 0.25)), Case("esso", "T8", "antenna", (0.30, 0.30)),
    Case("esso", "T7", "input_late", (0.6,)), Case("esso", "T8", "input_late", (1.0,)),
    Case("esso", "T7", "heading_late", (0.45,)), Case("esso", "T8", "heading_late", (0.3,)),
]
# the eleventh set takes the two groupings of four active BlueBoat runs the tenth left; its Esso cases
# reuse T9 and T10 (the fifth set's tests) with other values
PROOF_ELEVENTH = [
    Case("blueboat", "U", "null"), Case("blueboat", "V", "null"),
    Case("blueboat", "U", "current", (0.12, 320.0)), Case("blueboat", "V", "current", (0.15, 140.0)),
    Case("blueboat", "U", "antenna", (0.25, -0.30)), Case("blueboat", "V", "antenna", (-0.35, 0.20)),
    Case("blueboat", "U", "input_late", (0.35,)), Case("blueboat", "V", "input_late", (0.6,)),
    Case("blueboat", "U", "thruster_scaled", ("right", 0.75)), Case("blueboat", "V", "thruster_scaled", ("left", 0.7)),
    Case("blueboat", "U", "heading_late", (0.55,)), Case("blueboat", "V", "heading_late", (0.35,)),
    Case("esso", "T9", "null"), Case("esso", "T10", "null"),
    Case("esso", "T9", "current", (0.11, 30.0)), Case("esso", "T10", "current", (0.09, 190.0)),
    Case("esso", "T9", "antenna", (0.35, -0.30)), Case("esso", "T10", "antenna", (-0.40, 0.20)),
    Case("esso", "T9", "input_late", (0.5,)), Case("esso", "T10", "input_late", (0.8,)),
    Case("esso", "T9", "heading_late", (0.6,)), Case("esso", "T10", "heading_late", (0.35,)),
]
PROOF_TWELFTH = [
    Case("blueboat", "W", "null"), Case("blueboat", "P", "null"),
    Case("blueboat", "W", "current", (0.10, 60.0)), Case("blueboat", "P", "current", (0.14, 250.0)),
    Case("blueboat", "W", "antenna", (0.30, 0.20)), Case("blueboat", "P", "antenna", (-0.25, -0.25)),
    Case("blueboat", "W", "input_late", (0.45,)), Case("blueboat", "P", "input_late", (0.7,)),
    Case("blueboat", "W", "thruster_scaled", ("left", 0.8)), Case("blueboat", "P", "thruster_scaled", ("right", 0.7)),
    Case("blueboat", "W", "heading_late", (0.45,)), Case("blueboat", "P", "heading_late", (0.65,)),
    Case("esso", "T11", "null"), Case("esso", "T12", "null"),
    Case("esso", "T11", "current", (0.10, 100.0)), Case("esso", "T12", "current", (0.12, 300.0)),
    Case("esso", "T11", "antenna", (0.40, 0.25)), Case("esso", "T12", "antenna", (-0.30, -0.35)),
    Case("esso", "T11", "input_late", (0.6,)), Case("esso", "T12", "input_late", (0.9,)),
    Case("esso", "T11", "heading_late", (0.5,)), Case("esso", "T12", "heading_late", (0.7,)),
]
# the thirteenth set takes outings A and F (the first and third sets' groupings) and Esso tests T1 and T2
# (the first set's) again, with other values
PROOF_THIRTEENTH = [
    Case("blueboat", "A", "null"), Case("blueboat", "F", "null"),
    Case("blueboat", "A", "current", (0.12, 200.0)), Case("blueboat", "F", "current", (0.09, 30.0)),
    Case("blueboat", "A", "antenna", (-0.30, 0.15)), Case("blueboat", "F", "antenna", (0.35, -0.25)),
    Case("blueboat", "A", "input_late", (0.55,)), Case("blueboat", "F", "input_late", (0.4,)),
    Case("blueboat", "A", "thruster_scaled", ("right", 0.75)), Case("blueboat", "F", "thruster_scaled", ("left", 0.85)),
    Case("blueboat", "A", "heading_late", (0.55,)), Case("blueboat", "F", "heading_late", (0.4,)),
    Case("esso", "T1", "null"), Case("esso", "T2", "null"),
    Case("esso", "T1", "current", (0.11, 220.0)), Case("esso", "T2", "current", (0.09, 20.0)),
    Case("esso", "T1", "antenna", (-0.35, 0.30)), Case("esso", "T2", "antenna", (0.45, -0.20)),
    Case("esso", "T1", "input_late", (0.5,)), Case("esso", "T2", "input_late", (0.8,)),
    Case("esso", "T1", "heading_late", (0.6,)), Case("esso", "T2", "heading_late", (0.45,)),
]
# the fourteenth set takes outings D and K (the second and sixth sets' groupings) and Esso tests T3 and T4
# (the second set's) again, with other values
PROOF_FOURTEENTH = [
    Case("blueboat", "D", "null"), Case("blueboat", "K", "null"),
    Case("blueboat", "D", "current", (0.13, 160.0)), Case("blueboat", "K", "current", (0.10, 320.0)),
    Case("blueboat", "D", "antenna", (0.30, 0.25)), Case("blueboat", "K", "antenna", (-0.35, -0.15)),
    Case("blueboat", "D", "input_late", (0.45,)), Case("blueboat", "K", "input_late", (0.65,)),
    Case("blueboat", "D", "thruster_scaled", ("left", 0.8)), Case("blueboat", "K", "thruster_scaled", ("right", 0.7)),
    Case("blueboat", "D", "heading_late", (0.6,)), Case("blueboat", "K", "heading_late", (0.35,)),
    Case("esso", "T3", "null"), Case("esso", "T4", "null"),
    Case("esso", "T3", "current", (0.12, 250.0)), Case("esso", "T4", "current", (0.10, 70.0)),
    Case("esso", "T3", "antenna", (0.35, 0.25)), Case("esso", "T4", "antenna", (-0.45, -0.20)),
    Case("esso", "T3", "input_late", (0.7,)), Case("esso", "T4", "input_late", (0.55,)),
    Case("esso", "T3", "heading_late", (0.5,)), Case("esso", "T4", "heading_late", (0.65,)),
]
# the fifteenth set takes outings T and U (the tenth and eleventh sets' groupings) and Esso tests T5 and T6
# again, with other values
PROOF_FIFTEENTH = [
    Case("blueboat", "T", "null"), Case("blueboat", "U", "null"),
    Case("blueboat", "T", "current", (0.12, 40.0)), Case("blueboat", "U", "current", (0.11, 200.0)),
    Case("blueboat", "T", "antenna", (0.25, -0.30)), Case("blueboat", "U", "antenna", (-0.30, 0.20)),
    Case("blueboat", "T", "input_late", (0.5,)), Case("blueboat", "U", "input_late", (0.4,)),
    Case("blueboat", "T", "thruster_scaled", ("right", 0.8)), Case("blueboat", "U", "thruster_scaled", ("left", 0.75)),
    Case("blueboat", "T", "heading_late", (0.45,)), Case("blueboat", "U", "heading_late", (0.55,)),
    Case("esso", "T5", "null"), Case("esso", "T6", "null"),
    Case("esso", "T5", "current", (0.11, 300.0)), Case("esso", "T6", "current", (0.09, 150.0)),
    Case("esso", "T5", "antenna", (0.40, -0.25)), Case("esso", "T6", "antenna", (-0.30, 0.35)),
    Case("esso", "T5", "input_late", (0.6,)), Case("esso", "T6", "input_late", (0.75,)),
    Case("esso", "T5", "heading_late", (0.55,)), Case("esso", "T6", "heading_late", (0.7,)),
]
# the sixteenth set takes outings V and W (the eleventh and twelfth sets' groupings) and Esso tests T9 and T10
# again, with other values
PROOF_SIXTEENTH = [
    Case("blueboat", "V", "null"), Case("blueboat", "W", "null"),
    Case("blueboat", "V", "current", (0.14, 100.0)), Case("blueboat", "W", "current", (0.12, 280.0)),
    Case("blueboat", "V", "antenna", (0.30, 0.25)), Case("blueboat", "W", "antenna", (-0.25, -0.30)),
    Case("blueboat", "V", "input_late", (0.55,)), Case("blueboat", "W", "input_late", (0.45,)),
    Case("blueboat", "V", "thruster_scaled", ("right", 0.75)), Case("blueboat", "W", "thruster_scaled", ("left", 0.8)),
    Case("blueboat", "V", "heading_late", (0.5,)), Case("blueboat", "W", "heading_late", (0.4,)),
    Case("esso", "T9", "null"), Case("esso", "T10", "null"),
    Case("esso", "T9", "current", (0.10, 330.0)), Case("esso", "T10", "current", (0.12, 100.0)),
    Case("esso", "T9", "antenna", (0.35, -0.30)), Case("esso", "T10", "antenna", (-0.40, 0.25)),
    Case("esso", "T9", "input_late", (0.65,)), Case("esso", "T10", "input_late", (0.5,)),
    Case("esso", "T9", "heading_late", (0.45,)), Case("esso", "T10", "heading_late", (0.6,)),
]
# the seventeenth set takes outings R and D (the fifth and second sets' groupings) and Esso tests T13 and
# T14 again, with other values
PROOF_SEVENTEENTH = [
    Case("blueboat", "R", "null"), Case("blueboat", "D", "null"),
    Case("blueboat", "R", "current", (0.11, 150.0)), Case("blueboat", "D", "current", (0.13, 20.0)),
    Case("blueboat", "R", "antenna", (-0.30, 0.20)), Case("blueboat", "D", "antenna", (0.25, -0.35)),
    Case("blueboat", "R", "input_late", (0.5,)), Case("blueboat", "D", "input_late", (0.6,)),
    Case("blueboat", "R", "thruster_scaled", ("right", 0.8)), Case("blueboat", "D", "thruster_scaled", ("left", 0.75)),
    Case("blueboat", "R", "heading_late", (0.45,)), Case("blueboat", "D", "heading_late", (0.55,)),
    Case("esso", "T13", "null"), Case("esso", "T14", "null"),
    Case("esso", "T13", "current", (0.10, 40.0)), Case("esso", "T14", "current", (0.11, 230.0)),
    Case("esso", "T13", "antenna", (0.35, 0.30)), Case("esso", "T14", "antenna", (-0.40, -0.20)),
    Case("esso", "T13", "input_late", (0.7,)), Case("esso", "T14", "input_late", (0.55,)),
    Case("esso", "T13", "heading_late", (0.55,)), Case("esso", "T14", "heading_late", (0.65,)),
]
# the eighteenth set takes outings A and P (the first and twelfth sets' groupings) and Esso tests T11 and
# T12 again, with other values
PROOF_EIGHTEENTH = [
    Case("blueboat", "A", "null"), Case("blueboat", "P", "null"),
    Case("blueboat", "A", "current", (0.12, 320.0)), Case("blueboat", "P", "current", (0.10, 200.0)),
    Case("blueboat", "A", "antenna", (0.30, -0.25)), Case("blueboat", "P", "antenna", (-0.35, 0.25)),
    Case("blueboat", "A", "input_late", (0.6,)), Case("blueboat", "P", "input_late", (0.45,)),
    Case("blueboat", "A", "thruster_scaled", ("left", 0.7)), Case("blueboat", "P", "thruster_scaled", ("right", 0.75)),
    Case("blueboat", "A", "heading_late", (0.5,)), Case("blueboat", "P", "heading_late", (0.6,)),
    Case("esso", "T11", "null"), Case("esso", "T12", "null"),
    Case("esso", "T11", "current", (0.12, 60.0)), Case("esso", "T12", "current", (0.10, 250.0)),
    Case("esso", "T11", "antenna", (-0.35, 0.30)), Case("esso", "T12", "antenna", (0.40, -0.25)),
    Case("esso", "T11", "input_late", (0.55,)), Case("esso", "T12", "input_late", (0.75,)),
    Case("esso", "T11", "heading_late", (0.6,)), Case("esso", "T12", "heading_late", (0.5,)),
]
# the nineteenth set takes outings J and O (the fifth and eighth sets' groupings, disjoint runs) and Esso
# tests T3 and T4 again, with other values; its twins are identified with each velocity weighed by its
# own misfit (twin/ident/identify.py), which no earlier set's twins were
PROOF_NINETEENTH = [
    Case("blueboat", "J", "null"), Case("blueboat", "O", "null"),
    Case("blueboat", "J", "current", (0.13, 80.0)), Case("blueboat", "O", "current", (0.11, 300.0)),
    Case("blueboat", "J", "antenna", (0.35, 0.20)), Case("blueboat", "O", "antenna", (-0.30, -0.25)),
    Case("blueboat", "J", "input_late", (0.5,)), Case("blueboat", "O", "input_late", (0.65,)),
    Case("blueboat", "J", "thruster_scaled", ("left", 0.8)), Case("blueboat", "O", "thruster_scaled", ("right", 0.7)),
    Case("blueboat", "J", "heading_late", (0.55,)), Case("blueboat", "O", "heading_late", (0.45,)),
    Case("esso", "T3", "null"), Case("esso", "T4", "null"),
    Case("esso", "T3", "current", (0.11, 160.0)), Case("esso", "T4", "current", (0.12, 340.0)),
    Case("esso", "T3", "antenna", (0.30, 0.25)), Case("esso", "T4", "antenna", (-0.45, 0.20)),
    Case("esso", "T3", "input_late", (0.6,)), Case("esso", "T4", "input_late", (0.7,)),
    Case("esso", "T3", "heading_late", (0.65,)), Case("esso", "T4", "heading_late", (0.55,)),
]
# the twentieth set takes outings H and N (disjoint runs) and Esso tests T7 and T8 again, with other
# values; its Esso twin's hull polynomial continues along its tangents beyond 30° of drift
# (physics/mmg.py), which no earlier set's did
PROOF_TWENTIETH = [
    Case("blueboat", "H", "null"), Case("blueboat", "N", "null"),
    Case("blueboat", "H", "current", (0.12, 230.0)), Case("blueboat", "N", "current", (0.14, 40.0)),
    Case("blueboat", "H", "antenna", (0.30, -0.30)), Case("blueboat", "N", "antenna", (-0.35, 0.20)),
    Case("blueboat", "H", "input_late", (0.55,)), Case("blueboat", "N", "input_late", (0.5,)),
    Case("blueboat", "H", "thruster_scaled", ("right", 0.75)), Case("blueboat", "N", "thruster_scaled", ("left", 0.7)),
    Case("blueboat", "H", "heading_late", (0.5,)), Case("blueboat", "N", "heading_late", (0.6,)),
    Case("esso", "T7", "null"), Case("esso", "T8", "null"),
    Case("esso", "T7", "current", (0.10, 200.0)), Case("esso", "T8", "current", (0.12, 70.0)),
    Case("esso", "T7", "antenna", (0.40, 0.20)), Case("esso", "T8", "antenna", (-0.30, -0.30)),
    Case("esso", "T7", "input_late", (0.65,)), Case("esso", "T8", "input_late", (0.55,)),
    Case("esso", "T7", "heading_late", (0.5,)), Case("esso", "T8", "heading_late", (0.65,)),
]
# the twenty-first set takes outings Q and I (disjoint runs) and Esso tests T9 and T10 again, with other
# values
PROOF_TWENTYFIRST = [
    Case("blueboat", "Q", "null"), Case("blueboat", "I", "null"),
    Case("blueboat", "Q", "current", (0.15, 170.0)), Case("blueboat", "I", "current", (0.12, 300.0)),
    Case("blueboat", "Q", "antenna", (0.30, 0.25)), Case("blueboat", "I", "antenna", (-0.30, -0.20)),
    Case("blueboat", "Q", "input_late", (0.45,)), Case("blueboat", "I", "input_late", (0.6,)),
    Case("blueboat", "Q", "thruster_scaled", ("right", 0.7)), Case("blueboat", "I", "thruster_scaled", ("left", 0.75)),
    Case("blueboat", "Q", "heading_late", (0.55,)), Case("blueboat", "I", "heading_late", (0.4,)),
    Case("esso", "T9", "null"), Case("esso", "T10", "null"),
    Case("esso", "T9", "current", (0.10, 130.0)), Case("esso", "T10", "current", (0.12, 10.0)),
    Case("esso", "T9", "antenna", (0.35, -0.20)), Case("esso", "T10", "antenna", (-0.40, 0.25)),
    Case("esso", "T9", "input_late", (0.6,)), Case("esso", "T10", "input_late", (0.75,)),
    Case("esso", "T9", "heading_late", (0.6,)), Case("esso", "T10", "heading_late", (0.5,)),
]
# the twenty-second set takes outings G and L (disjoint runs) and Esso tests T5 and T6 again, with other
# values
PROOF_TWENTYSECOND = [
    Case("blueboat", "G", "null"), Case("blueboat", "L", "null"),
    Case("blueboat", "G", "current", (0.14, 250.0)), Case("blueboat", "L", "current", (0.13, 20.0)),
    Case("blueboat", "G", "antenna", (0.25, -0.30)), Case("blueboat", "L", "antenna", (-0.35, 0.25)),
    Case("blueboat", "G", "input_late", (0.55,)), Case("blueboat", "L", "input_late", (0.45,)),
    Case("blueboat", "G", "thruster_scaled", ("left", 0.7)), Case("blueboat", "L", "thruster_scaled", ("right", 0.75)),
    Case("blueboat", "G", "heading_late", (0.45,)), Case("blueboat", "L", "heading_late", (0.6,)),
    Case("esso", "T5", "null"), Case("esso", "T6", "null"),
    Case("esso", "T5", "current", (0.11, 100.0)), Case("esso", "T6", "current", (0.10, 330.0)),
    Case("esso", "T5", "antenna", (-0.30, -0.25)), Case("esso", "T6", "antenna", (0.35, 0.30)),
    Case("esso", "T5", "input_late", (0.7,)), Case("esso", "T6", "input_late", (0.55,)),
    Case("esso", "T5", "heading_late", (0.45,)), Case("esso", "T6", "heading_late", (0.65,)),
]
# the twenty-third set takes outings B and A (disjoint runs) and Esso tests T1 and T2 again, with other
# values
PROOF_TWENTYTHIRD = [
    Case("blueboat", "B", "null"), Case("blueboat", "A", "null"),
    Case("blueboat", "B", "current", (0.15, 60.0)), Case("blueboat", "A", "current", (0.12, 200.0)),
    Case("blueboat", "B", "antenna", (0.30, 0.30)), Case("blueboat", "A", "antenna", (-0.25, -0.35)),
    Case("blueboat", "B", "input_late", (0.5,)), Case("blueboat", "A", "input_late", (0.65,)),
    Case("blueboat", "B", "thruster_scaled", ("right", 0.8)), Case("blueboat", "A", "thruster_scaled", ("left", 0.7)),
    Case("blueboat", "B", "heading_late", (0.5,)), Case("blueboat", "A", "heading_late", (0.4,)),
    Case("esso", "T1", "null"), Case("esso", "T2", "null"),
    Case("esso", "T1", "current", (0.12, 160.0)), Case("esso", "T2", "current", (0.09, 280.0)),
    Case("esso", "T1", "antenna", (0.40, -0.25)), Case("esso", "T2", "antenna", (-0.35, 0.35)),
    Case("esso", "T1", "input_late", (0.6,)), Case("esso", "T2", "input_late", (0.8,)),
    Case("esso", "T1", "heading_late", (0.55,)), Case("esso", "T2", "heading_late", (0.4,)),
]
# the twenty-fourth set takes outings C and D (disjoint runs) and Esso tests T13 and T14 again, with
# other values
PROOF_TWENTYFOURTH = [
    Case("blueboat", "C", "null"), Case("blueboat", "D", "null"),
    Case("blueboat", "C", "current", (0.13, 310.0)), Case("blueboat", "D", "current", (0.14, 150.0)),
    Case("blueboat", "C", "antenna", (0.35, -0.20)), Case("blueboat", "D", "antenna", (-0.30, -0.30)),
    Case("blueboat", "C", "input_late", (0.6,)), Case("blueboat", "D", "input_late", (0.45,)),
    Case("blueboat", "C", "thruster_scaled", ("right", 0.75)), Case("blueboat", "D", "thruster_scaled", ("left", 0.8)),
    Case("blueboat", "C", "heading_late", (0.55,)), Case("blueboat", "D", "heading_late", (0.35,)),
    Case("esso", "T13", "null"), Case("esso", "T14", "null"),
    Case("esso", "T13", "current", (0.10, 40.0)), Case("esso", "T14", "current", (0.13, 220.0)),
    Case("esso", "T13", "antenna", (0.30, 0.35)), Case("esso", "T14", "antenna", (-0.40, -0.20)),
    Case("esso", "T13", "input_late", (0.65,)), Case("esso", "T14", "input_late", (0.5,)),
    Case("esso", "T13", "heading_late", (0.6,)), Case("esso", "T14", "heading_late", (0.45,)),
]
# the twenty-fifth set takes outings F and N and Esso tests T3 and T8 again, with other values
PROOF_TWENTYFIFTH = [
    Case("blueboat", "F", "null"), Case("blueboat", "N", "null"),
    Case("blueboat", "F", "current", (0.12, 250.0)), Case("blueboat", "N", "current", (0.15, 20.0)),
    Case("blueboat", "F", "antenna", (-0.35, 0.25)), Case("blueboat", "N", "antenna", (0.25, 0.35)),
    Case("blueboat", "F", "input_late", (0.55,)), Case("blueboat", "N", "input_late", (0.7,)),
    Case("blueboat", "F", "thruster_scaled", ("left", 0.75)), Case("blueboat", "N", "thruster_scaled", ("right", 0.7)),
    Case("blueboat", "F", "heading_late", (0.45,)), Case("blueboat", "N", "heading_late", (0.6,)),
    Case("esso", "T3", "null"), Case("esso", "T8", "null"),
    Case("esso", "T3", "current", (0.11, 300.0)), Case("esso", "T8", "current", (0.12, 130.0)),
    Case("esso", "T3", "antenna", (-0.30, 0.40)), Case("esso", "T8", "antenna", (0.35, -0.30)),
    Case("esso", "T3", "input_late", (0.5,)), Case("esso", "T8", "input_late", (0.75,)),
    Case("esso", "T3", "heading_late", (0.5,)), Case("esso", "T8", "heading_late", (0.6,)),
]
# the twenty-sixth set takes outings L and P and Esso tests T4 and T11 again, with other values
PROOF_TWENTYSIXTH = [
    Case("blueboat", "L", "null"), Case("blueboat", "P", "null"),
    Case("blueboat", "L", "current", (0.14, 80.0)), Case("blueboat", "P", "current", (0.12, 340.0)),
    Case("blueboat", "L", "antenna", (0.30, -0.35)), Case("blueboat", "P", "antenna", (-0.25, 0.30)),
    Case("blueboat", "L", "input_late", (0.65,)), Case("blueboat", "P", "input_late", (0.5,)),
    Case("blueboat", "L", "thruster_scaled", ("right", 0.75)), Case("blueboat", "P", "thruster_scaled", ("left", 0.7)),
    Case("blueboat", "L", "heading_late", (0.5,)), Case("blueboat", "P", "heading_late", (0.4,)),
    Case("esso", "T4", "null"), Case("esso", "T11", "null"),
    Case("esso", "T4", "current", (0.12, 20.0)), Case("esso", "T11", "current", (0.10, 200.0)),
    Case("esso", "T4", "antenna", (0.35, 0.30)), Case("esso", "T11", "antenna", (-0.30, -0.35)),
    Case("esso", "T4", "input_late", (0.6,)), Case("esso", "T11", "input_late", (0.7,)),
    Case("esso", "T4", "heading_late", (0.55,)), Case("esso", "T11", "heading_late", (0.45,)),
]
# the twenty-seventh set takes outings M and S (the least used) and Esso tests T7 and T12, with other values
PROOF_TWENTYSEVENTH = [
    Case("blueboat", "M", "null"), Case("blueboat", "S", "null"),
    Case("blueboat", "M", "current", (0.13, 110.0)), Case("blueboat", "S", "current", (0.11, 290.0)),
    Case("blueboat", "M", "antenna", (-0.30, -0.30)), Case("blueboat", "S", "antenna", (0.35, 0.25)),
    Case("blueboat", "M", "input_late", (0.55,)), Case("blueboat", "S", "input_late", (0.6,)),
    Case("blueboat", "M", "thruster_scaled", ("left", 0.75)), Case("blueboat", "S", "thruster_scaled", ("right", 0.7)),
    Case("blueboat", "M", "heading_late", (0.45,)), Case("blueboat", "S", "heading_late", (0.55,)),
    Case("esso", "T7", "null"), Case("esso", "T12", "null"),
    Case("esso", "T7", "current", (0.11, 250.0)), Case("esso", "T12", "current", (0.12, 70.0)),
    Case("esso", "T7", "antenna", (0.30, -0.35)), Case("esso", "T12", "antenna", (-0.35, 0.30)),
    Case("esso", "T7", "input_late", (0.65,)), Case("esso", "T12", "input_late", (0.55,)),
    Case("esso", "T7", "heading_late", (0.5,)), Case("esso", "T12", "heading_late", (0.6,)),
]
# the twenty-eighth set takes outings E and B (disjoint runs) and Esso tests T1 and T2, with other values
PROOF_TWENTYEIGHTH = [
    Case("blueboat", "E", "null"), Case("blueboat", "B", "null"),
    Case("blueboat", "E", "current", (0.14, 230.0)), Case("blueboat", "B", "current", (0.12, 30.0)),
    Case("blueboat", "E", "antenna", (0.30, 0.35)), Case("blueboat", "B", "antenna", (-0.35, -0.25)),
    Case("blueboat", "E", "input_late", (0.5,)), Case("blueboat", "B", "input_late", (0.65,)),
    Case("blueboat", "E", "thruster_scaled", ("right", 0.8)), Case("blueboat", "B", "thruster_scaled", ("left", 0.7)),
    Case("blueboat", "E", "heading_late", (0.6,)), Case("blueboat", "B", "heading_late", (0.45,)),
    Case("esso", "T1", "null"), Case("esso", "T2", "null"),
    Case("esso", "T1", "current", (0.10, 300.0)), Case("esso", "T2", "current", (0.13, 150.0)),
    Case("esso", "T1", "antenna", (-0.30, 0.35)), Case("esso", "T2", "antenna", (0.35, -0.30)),
    Case("esso", "T1", "input_late", (0.7,)), Case("esso", "T2", "input_late", (0.5,)),
    Case("esso", "T1", "heading_late", (0.45,)), Case("esso", "T2", "heading_late", (0.55,)),
]
# the twenty-ninth set takes outings Q and I (disjoint runs) and Esso tests T5 and T10, with other values
PROOF_TWENTYNINTH = [
    Case("blueboat", "Q", "null"), Case("blueboat", "I", "null"),
    Case("blueboat", "Q", "current", (0.13, 320.0)), Case("blueboat", "I", "current", (0.11, 200.0)),
    Case("blueboat", "Q", "antenna", (0.35, -0.30)), Case("blueboat", "I", "antenna", (-0.30, 0.35)),
    Case("blueboat", "Q", "input_late", (0.6,)), Case("blueboat", "I", "input_late", (0.55,)),
    Case("blueboat", "Q", "thruster_scaled", ("left", 0.75)), Case("blueboat", "I", "thruster_scaled", ("right", 0.7)),
    Case("blueboat", "Q", "heading_late", (0.5,)), Case("blueboat", "I", "heading_late", (0.6,)),
    Case("esso", "T5", "null"), Case("esso", "T10", "null"),
    Case("esso", "T5", "current", (0.12, 20.0)), Case("esso", "T10", "current", (0.10, 230.0)),
    Case("esso", "T5", "antenna", (0.30, 0.30)), Case("esso", "T10", "antenna", (-0.35, -0.30)),
    Case("esso", "T5", "input_late", (0.6,)), Case("esso", "T10", "input_late", (0.7,)),
    Case("esso", "T5", "heading_late", (0.55,)), Case("esso", "T10", "heading_late", (0.5,)),
]
# the thirtieth set takes outings G and L (disjoint runs) and Esso tests T3 and T8, with other values
PROOF_THIRTIETH = [
    Case("blueboat", "G", "null"), Case("blueboat", "L", "null"),
    Case("blueboat", "G", "current", (0.12, 75.0)), Case("blueboat", "L", "current", (0.15, 260.0)),
    Case("blueboat", "G", "antenna", (0.35, 0.25)), Case("blueboat", "L", "antenna", (-0.25, -0.35)),
    Case("blueboat", "G", "input_late", (0.45,)), Case("blueboat", "L", "input_late", (0.6,)),
    Case("blueboat", "G", "thruster_scaled", ("right", 0.75)), Case("blueboat", "L", "thruster_scaled", ("left", 0.8)),
    Case("blueboat", "G", "heading_late", (0.55,)), Case("blueboat", "L", "heading_late", (0.4,)),
    Case("esso", "T3", "null"), Case("esso", "T8", "null"),
    Case("esso", "T3", "current", (0.11, 110.0)), Case("esso", "T8", "current", (0.09, 340.0)),
    Case("esso", "T3", "antenna", (0.35, -0.25)), Case("esso", "T8", "antenna", (-0.30, 0.30)),
    Case("esso", "T3", "input_late", (0.55,)), Case("esso", "T8", "input_late", (0.65,)),
    Case("esso", "T3", "heading_late", (0.6,)), Case("esso", "T8", "heading_late", (0.5,)),
]
PROOFS = {"first": PROOF, "second": PROOF_SECOND, "third": PROOF_THIRD, "fourth": PROOF_FOURTH, "fifth": PROOF_FIFTH,
          "sixth": PROOF_SIXTH, "seventh": PROOF_SEVENTH,
          "eighth": PROOF_EIGHTH, "ninth": PROOF_NINTH, "tenth": PROOF_TENTH,
          "eleventh": PROOF_ELEVENTH, "twelfth": PROOF_TWELFTH,
          "thirteenth": PROOF_THIRTEENTH, "fourteenth": PROOF_FOURTEENTH,
          "fifteenth": PROOF_FIFTEENTH, "sixteenth": PROOF_SIXTEENTH,
          "seventeenth": PROOF_SEVENTEENTH, "eighteenth": PROOF_EIGHTEENTH, "nineteenth": PROOF_NINETEENTH,
          "twentieth": PROOF_TWENTIETH, "twentyfirst": PROOF_TWENTYFIRST,
          "twentysecond": PROOF_TWENTYSECOND, "twentythird": PROOF_TWENTYTHIRD, "twentyfourth": PROOF_TWENTYFOURTH,
          "twentyfifth": PROOF_TWENTYFIFTH, "twentysixth": PROOF_TWENTYSIXTH,
          "twentyseventh": PROOF_TWENTYSEVENTH, "twentyeighth": PROOF_TWENTYEIGHTH,
          "twentyninth": PROOF_TWENTYNINTH, "thirtieth": PROOF_THIRTIETH}
PAGES = {"first": "concealed_effects", "second": "concealed_effects_second", "third": "concealed_effects_third",
         "fourth": "concealed_effects_fourth", "fifth": "concealed_effects_fifth",
         "sixth": "concealed_effects_sixth", "seventh": "concealed_effects_seventh",
         "eighth": "concealed_effects_eighth", "ninth": "concealed_effects_ninth",
         "tenth": "concealed_effects_tenth", "eleventh": "concealed_effects_eleventh",
         "twelfth": "concealed_effects_twelfth", "thirteenth": "concealed_effects_thirteenth",
         "fourteenth": "concealed_effects_fourteenth",
         "fifteenth": "concealed_effects_fifteenth", "sixteenth": "concealed_effects_sixteenth",
         "seventeenth": "concealed_effects_seventeenth",
         "eighteenth": "concealed_effects_eighteenth", "nineteenth": "concealed_effects_nineteenth",
         "twentieth": "concealed_effects_twentieth", "twentyfirst": "concealed_effects_twentyfirst",
         "twentysecond": "concealed_effects_twentysecond", "twentythird": "concealed_effects_twentythird",
         "twentyfourth": "concealed_effects_twentyfourth", "twentyfifth": "concealed_effects_twentyfifth",
         "twentysixth": "concealed_effects_twentysixth",
         "twentyseventh": "concealed_effects_twentyseventh",
         "twentyeighth": "concealed_effects_twentyeighth",
         "twentyninth": "concealed_effects_twentyninth",
         "thirtieth": "concealed_effects_thirtieth"}

# what a stage of the fifth and sixth sets ran (the earlier sets' stages say it on their pages' notes)
STAGE_METHODS = {
    ("thirtieth", "before"): "the diagnosis as it was when the set was fixed",
    ("thirtieth", "half-body prior"): "the diagnosis unchanged, the BlueBoat's cases alone, its twin identified from the "
                                      "prior whose added mass is the half-body's (physics.added_mass.half_body_added_mass: "
                                      "half the whole ellipsoid's the 'before' stage's prior carried)",
    ("twentyninth", "before"): "the diagnosis as it was when the set was fixed",
    ("twentyeighth", "before"): "the diagnosis as it was when the set was fixed",
    ("twentyeighth", "after"): "one ESC's PWM span (pwm_span_left, pwm_span_right: the pulse it answers is neutral + "
                               "span × the logged deviation) offered as an effect",
    ("twentyseventh", "before"): "the diagnosis as it was when the set was fixed",
    ("twentyseventh", "after"): "a wind's side-force coefficient per lateral area fitted between none and a two-dimensional flat plate's 2.0, both ends unphysical edges",
    ("twentysixth", "before"): "the diagnosis as it was when the set was fixed",
    ("twentysixth", "after"): "each candidate screened by two Gauss-Newton steps (each with its line search), not one, "
                               "on held-out windows spread within each log; a thrust scale kept for its fewer "
                               "quantities checked for a loss with speed",
    ("twentyfifth", "before"): "the diagnosis as it was when the set was fixed",
    ("twentyfifth", "after"): "screening ranked on windows its one step did not fit; of rivals the blocks lean to "
                              "neither way (|z| < 1.5) that earn their place, the one with the fewest quantities kept",
    ("twentyfourth", "before"): "the diagnosis as it was when the set was fixed",
    ("twentyfourth", "after"): "each fold's scanned candidates (time shifts, dead zones) scanned afresh on that fold's "
                               "training windows, not refined from a screening that saw its held-out blocks",
    ("twentythird", "before"): "the diagnosis as it was when the set was fixed",
    ("twentythird", "after"): "a timing shift named only where it exceeds the floor by half a step of the grid it is read on (fit/kinematic.py)",
    ("twentysecond", "before"): "the diagnosis as it was when the set was fixed",
    ("twentysecond", "fewer numbers among rivals (not kept)"): "of the rivals the blocks cannot tell from the winner (z ≤ 3) that earn their place themselves, the one with fewer fitted numbers kept; full_thrust, like thrust_gain, tested as a stand-in for a thrust loss with speed",
    ("twentyfirst", "before"): "a GNSS fixes' latency searched in the dynamics as well as read from the kinematics",
    ("twentyfirst", "after"): "a GNSS fixes' latency read from the kinematics alone (diagnose/doctor.py KINEMATIC_ONLY)",
    ("fifth", "before"): "each velocity's residual scaled by the spread of its measured signal",
    ("fifth", "after"): "an identified twin's velocities scaled by its own misfit on the recordings (search.dof_scale)",
    ("sixth", "before"): "each velocity's residual scaled by the spread of its measured signal",
    ("sixth", "weighed by the form error (not kept)"): "an identified twin's velocities scaled by √(noise² + the form "
                                                       "error `twin identify` measured on its own runs)",
    ("sixth", "after"): "an identified twin's velocities scaled by its own misfit on the recordings (search.dof_scale)",
    ("eighth", "before"): "the Esso tests diagnosed with their measured wind a known input of every free run",
    ("ninth", "before"): "the diagnosis as it was when the set was fixed",
    ("tenth", "before"): "the diagnosis as it was when the set was fixed",
    ("eleventh", "before"): "the diagnosis as it was when the set was fixed",
    ("tenth", "after"): "the Esso's yaw rate read from its gyro (sensors.yaw_rate_source), its twin identified so; "
                        "the BlueBoat (no gyro in its logs) as before",
    ("eighth", "mean wind (control)"): "the Esso tests diagnosed with each test's mean wind given as a constant "
                                       "wind_per_log (--esso-mean-wind), as on the pages of the first to seventh sets; the "
                                       "BlueBoat cases as in 'before'",
}

# the sets whose Esso tests are diagnosed with their measured wind stream a known input (`twin diagnose
# --wind-measured`); the earlier ones gave each test's mean wind as a constant wind_per_log
ESSO_WIND_MEASURED = {"eighth", "ninth", "tenth", "eleventh", "twelfth", "thirteenth", "fourteenth", "fifteenth",
                      "sixteenth", "seventeenth", "eighteenth", "nineteenth", "twentieth", "twentyfirst", "twentysecond", "twentythird",
                      "twentyfourth", "twentyfifth", "twentysixth", "twentyseventh", "twentyeighth", "twentyninth",
                      "thirtieth"}

EFFECT_OF = {"current": "current", "antenna": "gnss_lever_arm", "input_late": "clock_offset",
             "heading_late": "heading_latency"}


# ---------------------------------------------------------------- concealing

def _first_rows(gnss: Stream) -> np.ndarray:
    """Index, for every GNSS row, of the row where its fix was first logged (a repeat keeps it)."""
    cols = [gnss[k] for k in ("lat_deg", "lon_deg") if k in gnss.columns] or \
        [gnss[k] for k in ("north_m", "east_m")]
    new = np.r_[True, np.any([np.diff(c) != 0 for c in cols], axis=0)]
    return np.maximum.accumulate(np.where(new, np.arange(len(new)), 0))


def _moved(gnss: Stream, d_north: np.ndarray, d_east: np.ndarray) -> Stream:
    """The GNSS stream with each fix moved by (d_north, d_east) m."""
    cols = dict(gnss.columns)
    if gnss.has("lat_deg", "lon_deg"):
        lat0, lon0 = float(gnss["lat_deg"][0]), float(gnss["lon_deg"][0])
        n, e = ned_from_geodetic(gnss["lat_deg"], gnss["lon_deg"], lat0, lon0)
        cols["lat_deg"], cols["lon_deg"] = geodetic_from_ned(n + d_north, e + d_east, lat0, lon0)[:2]
    else:
        cols["north_m"] = gnss["north_m"] + d_north
        cols["east_m"] = gnss["east_m"] + d_east
    return Stream(gnss.t.copy(), cols)


def conceal(rec: Recording, case: Case) -> Recording:
    """`rec` with the case's effect put into its streams (module docstring)."""
    kind, v = case.kind, case.values
    if kind == "null":
        return rec
    if kind == "current":
        first = _first_rows(rec.gnss)
        t = rec.gnss.t[first] - rec.gnss.t[0]
        a = math.radians(v[1])
        return replace(rec, gnss=_moved(rec.gnss, v[0] * math.cos(a) * t, v[0] * math.sin(a) * t))
    if kind == "antenna":
        first = _first_rows(rec.gnss)
        psi = np.interp(rec.gnss.t[first], rec.heading.t, np.unwrap(rec.heading["psi_rad"]))
        c, s = np.cos(psi), np.sin(psi)
        return replace(rec, gnss=_moved(rec.gnss, c * v[0] - s * v[1], s * v[0] + c * v[1]))
    if kind == "input_late":
        if len(rec.pwm):
            return replace(rec, pwm=Stream(rec.pwm.t + v[0], dict(rec.pwm.columns)))
        return replace(rec, prop_rudder=Stream(rec.prop_rudder.t + v[0], dict(rec.prop_rudder.columns)))
    if kind == "heading_late":
        return replace(rec, heading=Stream(rec.heading.t + v[0], dict(rec.heading.columns)))
    if kind == "thruster_scaled":
        side, scale = v
        k = 0 if side == "left" else 1
        cols = dict(rec.pwm.columns)
        neutral = rec.pwm_neutral_us[k]
        cols[f"{side}_us"] = neutral + scale * (np.asarray(cols[f"{side}_us"], float) - neutral)
        return replace(rec, pwm=Stream(rec.pwm.t.copy(), cols))
    raise ValueError(kind)


def equivalent_gain(twin: vessel_mod.Vessel, recordings: list[Recording], side: str, scale: float) -> float:
    """The thrust scale of one thruster that best matches (least squares over the samples) the thrust
    the twin's map gives for the true PWM to the thrust it gives for the logged PWM (scaled about the
    log's neutral)."""
    k = 0 if side == "left" else 1
    true, logged = [], []
    for rec in recordings:
        neutral = rec.pwm_neutral_us[k]
        pwm = np.asarray(rec.pwm[f"{side}_us"], float)
        true.append(twin.thrusters.thrust_from_pwm(pwm))
        logged.append(twin.thrusters.thrust_from_pwm(neutral + scale * (pwm - neutral)))
    t, lg = np.concatenate(true), np.concatenate(logged)
    return float(np.dot(t, lg) / np.dot(lg, lg))


# ---------------------------------------------------------------- twins

def blueboat_twin(work: Path) -> vessel_mod.Vessel:
    path = work / "blueboat_least_active.vessel.json"
    if not path.is_file():
        recs = read([BLUEBOAT / f"fixed_00000{n}.csv" for n in FIT_BLUEBOAT])
        result = identify(recs, vessel_mod.load("blueboat"))
        work.mkdir(parents=True, exist_ok=True)
        vessel_mod.save(result.vessel, path)
    v = vessel_mod.load(path)
    # a concealed run gets its own compass offset from its own track, not a training log's
    return replace(v, sensors=replace(v.sensors, heading_bias_by_log_deg=()))


def esso_twin(work: Path) -> vessel_mod.Vessel:
    path = work / "esso_random_measured.vessel.json"
    if not path.is_file():
        recs = read(sorted(ESSO.glob("random_*.csv")))
        result = identify(recs, vessel_mod.load("esso_osaka"), prior_weights=(0.01, 0.1), window_s=30.0,
                          max_evaluations=8, wind="measured")
        work.mkdir(parents=True, exist_ok=True)
        vessel_mod.save(result.vessel, path)
    v = vessel_mod.load(path)
    return replace(v, sensors=replace(v.sensors, heading_bias_by_log_deg=()))


def mean_wind(rec: Recording) -> tuple[float, float]:
    """The anemometer's vector-mean true wind over the test: speed (m/s) and the direction it blows from (deg)."""
    a = np.radians(rec.wind["from_deg"])
    north, east = np.mean(rec.wind["speed_m_s"] * np.cos(a)), np.mean(rec.wind["speed_m_s"] * np.sin(a))
    return float(np.hypot(north, east)), float(np.degrees(np.arctan2(east, north)) % 360.0)


# ---------------------------------------------------------------- judging

def truth_of(case: Case, twin: vessel_mod.Vessel, recordings: list[Recording]) -> tuple[str | None, dict]:
    """The effect a diagnosis should name for the case and its values in the library's terms."""
    v = case.values
    if case.kind == "null":
        return None, {}
    if case.kind == "current":
        return "current", {"speed_m_s": v[0], "dir_deg": v[1]}
    if case.kind == "antenna":
        ox, oy = twin.sensors.antenna_offset_m
        return "gnss_lever_arm", {"dx_m": ox + v[0], "dy_m": oy + v[1]}
    if case.kind == "input_late":
        return "clock_offset", {"pwm_clock_offset_s": twin.sensors.pwm_clock_offset_s + v[0]}
    if case.kind == "heading_late":
        return "heading_latency", {"heading_latency_s": twin.sensors.heading_latency_s + v[0]}
    if case.kind == "thruster_scaled":
        return f"thruster_gain_{v[0]}", {"scale": round(equivalent_gain(twin, recordings, *v), 4)}
    raise ValueError(case.kind)


def alternatives_of(case: Case) -> dict[str, dict]:
    """Other names in the library's terms that are the case's truth too, with their values: one
    thruster's PWM scaled by s is that thruster's ESC span 1/s exactly (pwm_span_SIDE)."""
    if case.kind == "thruster_scaled":
        side, scale = case.values
        return {f"pwm_span_{side}": {"span": round(1.0 / scale, 4)}}
    return {}


def within(truth_name: str, truth: dict, found: dict, twin: vessel_mod.Vessel) -> bool:
    """Whether the named values are within the tolerances of the truth (module docstring)."""
    if truth_name == "current":
        a, b = math.radians(truth["dir_deg"]), math.radians(found["dir_deg"])
        dang = abs((found["dir_deg"] - truth["dir_deg"] + 180.0) % 360.0 - 180.0)
        return abs(found["speed_m_s"] - truth["speed_m_s"]) <= TOLERANCE * truth["speed_m_s"] and \
            dang <= TOLERANCE_DEG and bool(np.isfinite(a + b))
    if truth_name == "gnss_lever_arm":
        ox, oy = twin.sensors.antenna_offset_m
        moved = np.array([truth["dx_m"] - ox, truth["dy_m"] - oy])
        err = np.hypot(found["dx_m"] - truth["dx_m"], found["dy_m"] - truth["dy_m"])
        return bool(err <= TOLERANCE * np.hypot(*moved))
    key = next(iter(truth))
    if truth_name.startswith("pwm_span"):  # a span's effect is its departure from 1
        return abs(found[key] - truth[key]) <= TOLERANCE * abs(truth[key] - 1.0)
    if truth_name.startswith("thruster_gain"):
        return abs(found[key] - truth[key]) <= TOLERANCE * abs(truth[key] - 0.0)
    return abs(found[key] - truth[key]) <= TOLERANCE * abs(truth[key])


def recordings_of(case: Case) -> list[Recording]:
    if case.vessel == "blueboat":
        return read([BLUEBOAT / f"fixed_00000{n}.csv" for n in OUTINGS[case.where]])
    return read([ESSO / ESSO_TESTS[case.where]])


def case_setup(case: Case, twins: dict, wind_measured: bool):
    """A case's recordings, the twin that diagnoses them (an Esso test's mean wind given where its
    measured wind is not a known input) and that known wind ("measured" or None)."""
    recs = recordings_of(case)
    twin = twins[case.vessel]
    wind = "measured" if case.vessel == "esso" and wind_measured else None
    if case.vessel == "esso" and wind is None:
        twin = apply_effects(twin, [("wind_per_log", {log_name(r.source): mean_wind(r) for r in recs})])
    return recs, twin, wind


def run_case(case: Case, twins: dict, wind_measured: bool = False) -> dict:
    recs, twin, wind = case_setup(case, twins, wind_measured)
    truth_name, truth = truth_of(case, twin, recs)
    concealed = [conceal(r, case) for r in recs]
    started = time.time()
    d = diagnose(concealed, twin, wind=wind)
    seconds = time.time() - started
    named = [{"name": e["name"] if isinstance(e, dict) else e.name,
              "parameters": dict(e["parameters"] if isinstance(e, dict) else e.parameters)} for e in d.effects]
    accepted = {truth_name: truth, **alternatives_of(case)} if truth_name is not None else {}
    hit = next((e for e in named if e["name"] in accepted), None)
    others = [e for e in named if e is not hit]  # a second name of the truth is one too many
    close = bool(hit is not None and within(hit["name"], accepted[hit["name"]], hit["parameters"], twin))
    return {"case": case.name, "vessel": case.vessel, "where": case.where, "kind": case.kind,
            "magnitude": case.magnitude(), "truth": truth_name, "truth_values": truth, "named": named,
            "hit": hit is not None, "within": close, "others": [e["name"] for e in others],
            "exact": (not named) if truth_name is None else (close and not others),
            "notes": list(d.notes), "seconds": round(seconds, 1), "blocks": d.windows.get("blocks")}


def judge_truth(case: Case, twins: dict, wind_measured: bool, commit: str) -> dict | None:
    """The case's truth at its own values, nothing fitted, judged by the diagnosis's rule on the blocks a
    diagnosis of the concealed logs judges on (doctor.given_evidence, `twin diagnose --given`): whether the
    logs can prove it through this twin at all. None for a null."""
    recs, twin, known = case_setup(case, twins, wind_measured)
    truth_name, truth = truth_of(case, twin, recs)
    if truth_name is None:
        return None
    text = f"{truth_name}=" + ",".join(f"{v:.4g}" for v in truth.values())
    return given_record(text, given_evidence([conceal(r, case) for r in recs], twin, [text], known_wind=known), commit)


# ---------------------------------------------------------------- the page

def limited_by(row: dict) -> str:
    """For a concealed effect not named: what the diagnosis said kept it from naming it (its
    kinematic step's reason for the sensor and timing effects, or too few blocks for the dynamics);
    "-" where it was named or the case is a null."""
    if row["truth"] is None or row["hit"]:
        return "-"
    kinematic = {"gnss_lever_arm": "gnss_lever_arm", "clock_offset": "clock_offset",
                 "heading_latency": "heading_latency"}.get(row["truth"])
    if kinematic:
        note = next((n for n in row["notes"] if n.startswith(f"{kinematic} from kinematics")), "")
        if note:
            return note.split("(", 1)[-1].removesuffix(")").split("; ", 1)[-1]
    if (row.get("blocks") or 0) < MIN_BLOCKS:
        return f"{row.get('blocks')} blocks: the dynamics can name nothing"
    return "did not earn its place in the dynamic search"


def _count(n: int, one: str, many: str) -> str:
    return f"{n} {one if n == 1 else many}"


def _values_text(values: dict) -> str:
    return ", ".join(f"{k} {v:.3g}" for k, v in values.items())


def summary_of(rows: list[dict]) -> dict:
    effects = [r for r in rows if r["truth"] is not None]
    nulls = [r for r in rows if r["truth"] is None]
    return {"cases": len(rows), "effects": len(effects), "named": sum(r["hit"] for r in effects),
            "within": sum(r["within"] for r in effects), "exact": sum(r["exact"] for r in effects),
            "false_discoveries": sum(len(r["others"]) for r in effects) + sum(len(r["named"]) for r in nulls),
            "cases_with_false_discoveries": sum(bool(r["others"]) for r in effects) + sum(bool(r["named"]) for r in nulls),
            "nulls": len(nulls), "nulls_clean": sum(not r["named"] for r in nulls)}


def boat_antenna(work: Path) -> dict:
    """What the kinematics tell of the BlueBoat's antenna against the identified twin's, with nothing
    concealed: from the five least active runs, the five most active and all ten. An antenna is the
    boat's own only if both halves tell the same one."""
    from twin.fit.kinematic import lever_arm

    twin = blueboat_twin(work)
    most = tuple(sorted(set(sum(OUTINGS.values(), ()))))
    out = {}
    halves = (("least active", FIT_BLUEBOAT), ("most active", most), ("all ten", tuple(sorted(FIT_BLUEBOAT + most))))
    for key, runs in halves:
        f = lever_arm(read([BLUEBOAT / f"fixed_00000{n}.csv" for n in runs]), twin)
        out[key] = {"runs": list(runs), "told": f.told, "change": f.change, "sigma": f.sigma, "basis": f.basis,
                    "why": f.why}
    return out


def boat_timing(work: Path) -> list[dict]:
    """What the kinematics tell of the BlueBoat's PWM clock against the identified twin (its thrust map
    and lag), with nothing concealed: each run alone, each outing of the proof sets, and the runs the
    twin was fitted on. The same offset on runs nothing was concealed in is the logs' own timing."""
    from twin.fit.kinematic import input_timing

    twin = blueboat_twin(work)
    groups = [("fitted on", FIT_BLUEBOAT)] + [(f"outing {w}", runs) for w, runs in OUTINGS.items()] + \
        [(f"run {n}", (n,)) for n in sorted(FIT_BLUEBOAT + tuple(set(sum(OUTINGS.values(), ()))))]
    out = []
    for key, runs in groups:
        (f,) = [f for f in input_timing(read([BLUEBOAT / f"fixed_00000{n}.csv" for n in runs]), twin)
                if f.effect == "clock_offset"]
        out.append({"group": key, "runs": list(runs), "told": f.told, "offset_s": f.change.get("pwm_clock_offset_s"),
                    "sigma_s": f.sigma.get("pwm_clock_offset_s"), "basis": f.basis})
    return out


IDLE_AFTER_S = (5.0, 10.0)  # idle this long: little of the hull's own way is left (the two show how little)


def boat_drift(work: Path) -> list[dict]:
    """The BlueBoat's ground velocity while idle, nothing concealed: each run's mean GNSS velocity over the
    samples at which both thrusters have given no thrust (the identified twin's map: inside its dead zone)
    for IDLE_AFTER_S. What the water and the wind do to an idle hull on that day: the background a
    concealed current is added to."""
    th = blueboat_twin(work).thrusters
    out = []
    for n in sorted(FIT_BLUEBOAT + tuple(set(sum(OUTINGS.values(), ())))):
        (rec,) = read([BLUEBOAT / f"fixed_00000{n}.csv"])
        idle = np.all(th.thrust_from_pwm(np.column_stack([rec.pwm["left_us"], rec.pwm["right_us"]])) == 0.0, axis=1)
        t = np.asarray(rec.gnss.t, float)
        north, east = ned_from_geodetic(rec.gnss["lat_deg"], rec.gnss["lon_deg"], rec.gnss["lat_deg"][0],
                                        rec.gnss["lon_deg"][0])[:2]
        idle_at = np.interp(t, np.asarray(rec.pwm.t, float), idle.astype(float)) > 0.999
        since = np.zeros(len(t))
        for i in range(1, len(t)):
            since[i] = since[i - 1] + (t[i] - t[i - 1]) if idle_at[i] else 0.0
        vn, ve = np.gradient(north, t), np.gradient(east, t)
        row = {"run": n, "idle_share": float(np.mean(idle))}
        for after in IDLE_AFTER_S:
            sel = since > after
            key = f"after_{after:g}_s"
            row[key] = {"seconds": float(np.sum(np.diff(t, prepend=t[0])[sel]))}
            if sel.sum() >= 2:
                mn, me = float(np.mean(vn[sel])), float(np.mean(ve[sel]))
                row[key].update({"north_m_s": mn, "east_m_s": me, "speed_m_s": float(np.hypot(mn, me)),
                                 "towards_deg": float(np.degrees(np.arctan2(me, mn)) % 360.0)})
        out.append(row)
    return out


def write_page(stages: dict, out: Path, antenna: dict | None = None, proof_set: str = "first",
               timing: list[dict] | None = None, drift: list[dict] | None = None, given: dict | None = None) -> Path:
    tables, lines = [], []
    given = given or {}
    # an outing's blocks are its windows' alone, whatever the stage: filled in where a stage did not keep them
    blocks = {(r["vessel"], r["where"]): r["blocks"] for res in stages.values() for r in res["rows"] if r.get("blocks")}
    for stage, res in stages.items():
        rows = res["rows"]
        s = summary_of(rows)
        lines.append(f"{stage} (commit {res['commit']}): {s['exact']} of {s['effects']} concealed effects exact, "
                     f"{s['named']} named, {s['within']} within the tolerances; "
                     f"{_count(s['false_discoveries'], 'false discovery', 'false discoveries')} in "
                     f"{_count(s['cases_with_false_discoveries'], 'case', 'cases')}; nulls clean {s['nulls_clean']} of "
                     f"{s['nulls']}")
        tables.append(ResultTable(
            f"{stage}: each case (commit {res['commit']})",
            ["vessel", "where", "blocks", "effect", "magnitude", "truth", "named (values)", "exact", "else named",
             "not named for", *(["truth as given"] if given else []), "s"],
            [[r["vessel"], r["where"], blocks.get((r["vessel"], r["where"]), "-"), r["kind"], r["magnitude"],
              "nothing" if r["truth"] is None else f"{r['truth']} ({_values_text(r['truth_values'])})",
              "; ".join(f"{e['name']} ({_values_text(e['parameters'])})" for e in r["named"]) or "nothing",
              "yes" if r["exact"] else "no", ", ".join(r["others"]) or "-",
              limited_by({**r, "blocks": r.get("blocks") or blocks.get((r["vessel"], r["where"]))}),
              *([given_cell(given.get(r["case"]))] if given else []), r["seconds"]] for r in rows]))
    # the stages in the order they ran: a case's row from the last kept stage that ran it (a stage may run
    # some cases only) is the diagnosis of today for that case
    kept = [st for st in stages if "(not kept)" not in st] or list(stages)[-1:]
    latest = {r["case"]: (st, r) for st in kept for r in stages[st]["rows"]}
    judged = [(g, latest.get(name, (None, None))) for name, g in given.items() if g is not None]
    if judged:
        provable = [(st, r) for g, (st, r) in judged if g["earns_its_place"]]
        named_by = sorted({st for st, r in provable if r is not None}, key=list(stages).index)
        lines.append(
            f"The truth itself, given at its own values and judged by the diagnosis's rule on the same blocks, through "
            f"the twins identified from the same runs at the judging commit "
            f"({', '.join(sorted({g['commit'] for g, _ in judged}))}): the logs can prove "
            f"{len(provable)} of {len(judged)} as given; of those "
            + (" and ".join(f"'{st}'" for st in named_by) or "no stage")
            + f" named {sum(bool(r and r['exact']) for _, r in provable)} exactly")
    proof = PROOFS[proof_set]
    page = ResultPage(
        PAGES[proof_set], "Effects concealed in real logs, found by `twin diagnose` with an identified twin"
        + ("" if proof_set == "first" else f" (proof set: {proof_set})"),
        f"python scripts/concealed_effects.py --set {proof_set} --stage STAGE"
        + (", then --truth-given" if any(g is not None for g in given.values()) else ""),
        f"Proof set: {proof_set}. BlueBoat: twin identified on runs 218, 221, 222, 223, 226 (the least active); "
        "effects concealed in runs " + " and ".join(f"{' + '.join(map(str, OUTINGS[w]))} (outing {w})" for w in
                                                    sorted({c.where for c in proof if c.vessel == 'blueboat'}))
        + ", each outing diagnosed as one. Esso Osaka: twin identified on the nine random tests with their measured "
        "wind; effects concealed in turning tests " + " and ".join(
            f"{ESSO_TESTS[w]} ({w})" for w in sorted({c.where for c in proof if c.vessel == 'esso'}))
        + (", each diagnosed alone with its measured wind a known input of every free run (`--wind-measured`)"
           if proof_set in ESSO_WIND_MEASURED else ", each diagnosed alone with its mean measured wind given")
        + ". Every figure is on runs the twin was not fitted on.",
        "Each effect is put into the logs by rewriting the logged streams (no model): a current moves every GNSS "
        "fix by c·t, an antenna offset by R(ψ)·Δp, an input or heading log late moves that stream's stamps, one "
        "thruster's PWM is scaled about its neutral. Exact: the effect named with its values within 30 % (30° for "
        "a direction) and nothing else named. " + " ".join(f"{x}." for x in lines),
        tables,
        ["One thruster's PWM scaled by s is that thruster's ESC span 1/s (pwm_span_left/right); named as a thrust "
         "scale, its truth is the thrust scale of that thruster that best "
         "matches, over the outing's samples, the twin's thrust for the true PWM to its thrust for the logged one.",
         "Blocks: the 30-s blocks of windows the diagnosis judges on. With fewer than ten, no effect can earn its "
         "place from the dynamics (z 3 needs ten blocks or more, every one for it): there only what the kinematics "
         "tell can be named.",
         *(["Truth as given: the concealed effect at its own values in the library's terms, nothing fitted, judged "
            "by the rule the diagnosis names an effect by (z ≥ 3 of the held-out blocks' votes and 5 % of the misfit "
            "above the noise) on the same blocks, through the twins identified from the same runs at the judging "
            "commit (a stage run at another commit had its own): whether the logs "
            "can prove it from the "
            "dynamics at all. The antenna, the clocks and the heading are named from the kinematics, which this "
            "column does not judge."] if given else []),
         "The Esso has one propeller: one thruster scaled does not apply to it. Its turning tests change the "
         "inputs two or three times, the rudder at about 2.3°/s (a ramp, not a step): an input log late has little "
         "to be seen by.",
         "The Esso's files give midship's positions (the pond's tracking, by the files' own account), not an "
         "antenna's: no antenna site applies to them, and a point tracked off midship is gnss_lever_arm's offset "
         "from it; the kinematics tell it only from spins on the spot, which its tests do not have."],
        {"stages": stages, "proof": [c.name for c in proof], **({"given": given} if given else {}),
         **({"boat_antenna": antenna} if antenna else {}),
         **({"boat_pwm_timing": timing} if timing else {}), **({"boat_idle_drift": drift} if drift else {})})
    page.notes += [f"Stage '{stage}': {STAGE_METHODS[(proof_set, stage)]}." for stage in stages
                   if (proof_set, stage) in STAGE_METHODS]
    if timing:
        page.tables.append(ResultTable(
            "The BlueBoat's PWM clock from the kinematics, nothing concealed (fit/kinematic.input_timing against the "
            "identified twin's thrust map and lag, read against the answers on its own runs where the twin file "
            "keeps them; positive: the PWM log late against heading and GNSS)",
            ["runs", "offset (s)", "σ (s)", "named", "evidence"],
            [[f"{t['group']} ({', '.join(map(str, t['runs']))})" if len(t["runs"]) > 1 else t["group"],
              "-" if t["sigma_s"] is None else t["offset_s"], "-" if t["sigma_s"] is None else t["sigma_s"],
              "yes" if t["told"] else "no", t["basis"]] for t in timing]))
    if drift:
        def cells(d: dict) -> list:
            return ([round(d["speed_m_s"], 3), round(d["towards_deg"]), round(d["seconds"])] if "speed_m_s" in d
                    else ["-", "-", round(d["seconds"])])
        page.tables.append(ResultTable(
            "The BlueBoat's ground velocity while idle, nothing concealed (each run's mean over the GNSS samples at "
            "which both thrusters have given no thrust, by the identified twin's map, for 5 s or for 10 s): the "
            "day's water and wind, which a concealed current adds to",
            ["run", "idle share", "speed after 5 s (m/s)", "towards (°)", "samples (s)", "speed after 10 s (m/s)",
             "towards (°)", "samples (s)"],
            [[d["run"], round(d["idle_share"], 2), *cells(d["after_5_s"]), *cells(d["after_10_s"])] for d in drift]))
        speeds = [d["after_10_s"]["speed_m_s"] for d in drift if "speed_m_s" in d["after_10_s"]]
        currents = [c.values[0] for c in proof if c.vessel == "blueboat" and c.kind == "current"]
        page.notes.append(
            f"Nothing concealed, the idle BlueBoat drifts over ground at {min(speeds):.2f}-{max(speeds):.2f} m/s, in "
            "directions that differ from run to run: the concealed currents "
            f"({min(currents):g}-{max(currents):g} m/s) are added to a background of their own size, which the "
            "proof counts as nothing.")
    if antenna:
        page.notes.append(
            "The BlueBoat's own antenna from the kinematics, nothing concealed, against where the identified twin "
            "has it: " + "; ".join(
                f"{key} ({', '.join(map(str, a['runs']))}): " + ("named" if a["told"] else "not named") + " ("
                + ", ".join(f"{k} {v:+.2f} ± {a['sigma'].get(k) or float('nan'):.2f}" for k, v in a["change"].items())
                + ("; " if a["change"] else "") + f"{a['why']}; {a['basis']})" for key, a in antenna.items()) + ".")
    return page.write(out)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--set", dest="proof_set", choices=sorted(PROOFS), default="first", help="which proof set")
    ap.add_argument("--stage", default="after", help="label of this run's results (before, after)")
    ap.add_argument("--only", default="", help="comma-separated case names (default: the whole proof set)")
    ap.add_argument("--work", type=Path, default=Path("/tmp/concealed_effects"),
                    help="where the identified twins and each case's result are kept")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "results")
    ap.add_argument("--identify-only", action="store_true")
    ap.add_argument("--esso-mean-wind", action="store_true",
                    help="give each Esso test its mean wind as a constant wind_per_log (a control stage)")
    ap.add_argument("--page-only", action="store_true", help="rewrite the page from the raw figures there are")
    ap.add_argument("--truth-given", action="store_true",
                    help="judge each case's truth as given (twin diagnose --given) through the twins in --work, "
                         "beside the stages already run, and rewrite the page")
    args = ap.parse_args()
    raw_path = args.out / "data" / f"{PAGES[args.proof_set]}.json"
    if args.page_only or args.truth_given:
        raw = json.loads(raw_path.read_text())
        given = raw.get("given", {})
        if args.truth_given:
            proof = PROOFS[args.proof_set]
            twins = {"blueboat": blueboat_twin(args.work), "esso": esso_twin(args.work)}
            commit = checkout_commit(ROOT)
            for c in proof:
                given[c.name] = judge_truth(c, twins, args.proof_set in ESSO_WIND_MEASURED, commit)
                print(f"{c.name}: truth as given {given_cell(given[c.name])}", flush=True)
        print(write_page(raw["stages"], args.out, boat_antenna(args.work), args.proof_set,
                         boat_timing(args.work), boat_drift(args.work), given))
        return 0
    proof = PROOFS[args.proof_set]
    needed = [BLUEBOAT / f"fixed_00000{n}.csv" for n in FIT_BLUEBOAT + sum(OUTINGS.values(), ())] + \
        [ESSO / f for f in ESSO_TESTS.values()]
    if any(not p.is_file() for p in needed):
        print(f"the shared recordings are not in {SHARED}: nothing to do")
        return 0
    only = {x for x in args.only.split(",") if x}
    cases = [c for c in proof if not only or c.name in only]
    vessels = {c.vessel for c in cases} if not args.identify_only else {"blueboat", "esso"}
    twins = {}
    if "blueboat" in vessels:
        twins["blueboat"] = blueboat_twin(args.work)
    if "esso" in vessels:
        twins["esso"] = esso_twin(args.work)
    if args.identify_only:
        return 0
    stage_dir = args.work / args.proof_set / args.stage
    stage_dir.mkdir(parents=True, exist_ok=True)
    for c in cases:
        path = stage_dir / f"{c.name}.json"
        if path.is_file() and not only:
            continue
        row = run_case(c, twins, args.proof_set in ESSO_WIND_MEASURED and not args.esso_mean_wind)
        path.write_text(json.dumps(row, indent=1, default=float))
        print(f"{c.name}: named {', '.join(e['name'] for e in row['named']) or 'nothing'}; "
              f"exact {row['exact']} ({row['seconds']} s)", flush=True)
    stages = staged(args.out / "data" / f"{PAGES[args.proof_set]}.json", args.stage, stage_dir,
                    [c.name for c in proof], summary_of, checkout_commit(ROOT))
    given = json.loads(raw_path.read_text()).get("given") if raw_path.is_file() else None
    print(write_page(stages, args.out, boat_antenna(args.work), args.proof_set, boat_timing(args.work),
                     boat_drift(args.work), given))
    return 0


if __name__ == "__main__":
    sys.exit(main())
