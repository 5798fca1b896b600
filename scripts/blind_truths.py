"""Concealed effects written by a simulator of this script's own, diagnosed through `twin diagnose` as a user would.

    python scripts/blind_truths.py [--set first|second|...|seventeenth] [--work DIR] [--only CASE,...] [--page-only] [--truth-given]

Ten recordings of ten minutes of the Yellowfish on a survey mission, each with one concealed effect of a
form the effect library does not have (or none), are written by a three-degree-of-freedom simulator that
shares no code with the package's physics: its own equations about the body origin (rigid body with
its centre of gravity off the origin, diagonal added mass, Coriolis and Munk terms, linear and quadratic
damping), its own RK4 integrator, its own evaluation of the T200 thrust map, its own sensors and its
own survey pilot. From the package it reads numbers only: the mass, CG and yaw inertia
(`compile_vessel(vessel).geometry.rigid`), where the thrusters and the GNSS antenna sit, and the added
mass, damping, thrust-map and wind-area figures of the shipped Yellowfish.

Each recording is written as the generic CSV (GNSS 5 Hz with 2 cm noise, heading 10 Hz with 0.3°
noise, PWM 10 Hz, every sample stamped at its true time) and handed to the CLI:

    twin diagnose LOG.csv --vessel yellowfish --json OUT.json

starting from the shipped, untuned Yellowfish. A case is exact when its truth, put into the library's
terms, is named with its values within 30 % (30° for a direction) and nothing else is named; a null is
exact when nothing is named. A compass offset the calibration applies is not an effect named. The
page docs/results/blind_truths.md and its raw figures docs/results/data/blind_truths.json are
rewritten; the logs, the CLI's JSON and its console output stay in --work.
"""
from __future__ import annotations

import argparse
import json
import math
import shutil
import subprocess
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import twin.vessel as vessel_mod  # noqa: E402
from twin.engine.mjcf import compile_vessel  # noqa: E402
from twin.viz.pages import ResultPage, ResultTable, checkout_commit, given_cell  # noqa: E402

VESSEL = "yellowfish"
DURATION_S = 600.0
STEP_S = 0.02  # RK4 step
TICK_S = 0.1  # the pilot's and the logger's period: PWM and heading at 10 Hz
STEPS_PER_TICK = 5
TICKS_PER_FIX = 2  # GNSS at 5 Hz
GNSS_SIGMA_M = 0.02
HEADING_SIGMA_DEG = 0.3
NEUTRAL_US = 1500.0
PWM_MIN_US, PWM_MAX_US = 1100.0, 1900.0
ORIGIN_DEG = (37.3410, -5.9866)  # lat, lon of the first fix's neighbourhood
WGS84_A_M, WGS84_E2 = 6378137.0, 6.69437999014e-3
RHO_AIR_KG_M3 = 1.225
TOLERANCE, TOLERANCE_DEG = 0.30, 30.0

# the survey pilot: a heading controller acting on the PWM difference
TRACK_GAIN_US_PER_DEG, TRACK_DIFF_MAX_US = 6.0, 150.0
TURN_GAIN_US_PER_DEG, TURN_DIFF_MAX_US, TURN_MEAN_US = 10.0, 320.0, 1580.0
TURN_DONE_DEG, TURN_MAX_S = 5.0, 40.0
MEAN_SLEW_US_PER_S, DIFF_SLEW_US_PER_S = 600.0, 1200.0
LEG_THROTTLES_US = (1650.0, 1750.0, 1850.0)
CROSS_THROTTLE_US, CROSS_LEG_S = 1650.0, 8.0

# the wind load of this script's own (Fossen's cosine/sine form with its own coefficients; the yaw
# moment of the other sign than the shipped load's: the centre of pressure on the other side of midships)
WIND_CX, WIND_CY, WIND_CN = 0.6, 0.8, -0.1


@dataclass(frozen=True)
class Case:
    """One recording's concealed effect. kind: null, dead_zone (one thruster's PWM band of no thrust,
    smoothstep from inner_us to outer_us off neutral; hard where they are equal), speed_loss
    (T·(1 − k·u^power) ahead), sag_exp (T·(1 − k + k·exp(−t/tau_s))), sag_square (T·(1 − k·(t/T_log)²)),
    wind (mean speed from a direction, with first-order gusts of gust_sigma_m_s and gust_tau_s)."""

    name: str
    kind: str
    seed: int
    side: str = ""
    inner_us: float = 0.0
    outer_us: float = 0.0
    k: float = 0.0
    power: int = 1
    tau_s: float = 0.0
    wind_speed_m_s: float = 0.0
    wind_from_deg: float = 0.0
    gust_sigma_m_s: float = 0.0
    gust_tau_s: float = 15.0


FIRST = [
    Case("null-a", "null", 31),
    Case("null-b", "null", 32),
    Case("dead_zone-left-hard-70us", "dead_zone", 33, side="left", inner_us=70.0, outer_us=70.0),
    Case("dead_zone-right-soft-50-90us", "dead_zone", 34, side="right", inner_us=50.0, outer_us=90.0),
    Case("speed_loss-0.12u", "speed_loss", 35, k=0.12, power=1),
    Case("speed_loss-0.15u2", "speed_loss", 36, k=0.15, power=2),
    Case("sag-exp-300s", "sag_exp", 37, k=0.3, tau_s=300.0),
    Case("sag-square-0.25", "sag_square", 38, k=0.25),
    Case("wind-gusty-5-130", "wind", 39, wind_speed_m_s=5.0, wind_from_deg=130.0, gust_sigma_m_s=0.8, gust_tau_s=15.0),
    Case("wind-steady-6.5-300", "wind", 40, wind_speed_m_s=6.5, wind_from_deg=300.0),
]
SECOND = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-c", "null", 41),
    Case("null-d", "null", 42),
    Case("dead_zone-left-soft-40-100us", "dead_zone", 43, side="left", inner_us=40.0, outer_us=100.0),
    Case("dead_zone-right-hard-80us", "dead_zone", 44, side="right", inner_us=80.0, outer_us=80.0),
    Case("speed_loss-0.10u", "speed_loss", 45, k=0.10, power=1),
    Case("speed_loss-0.12u2", "speed_loss", 46, k=0.12, power=2),
    Case("sag-exp-400s", "sag_exp", 47, k=0.25, tau_s=400.0),
    Case("sag-square-0.3", "sag_square", 48, k=0.3),
    Case("wind-gusty-6-40", "wind", 49, wind_speed_m_s=6.0, wind_from_deg=40.0, gust_sigma_m_s=1.0, gust_tau_s=15.0),
    Case("wind-steady-5-220", "wind", 50, wind_speed_m_s=5.0, wind_from_deg=220.0),
]
THIRD = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-e", "null", 51),
    Case("null-f", "null", 52),
    Case("dead_zone-right-soft-50-120us", "dead_zone", 53, side="right", inner_us=50.0, outer_us=120.0),
    Case("dead_zone-left-hard-100us", "dead_zone", 54, side="left", inner_us=100.0, outer_us=100.0),
    Case("speed_loss-0.08u", "speed_loss", 55, k=0.08, power=1),
    Case("speed_loss-0.10u2", "speed_loss", 56, k=0.10, power=2),
    Case("sag-exp-300s", "sag_exp", 57, k=0.3, tau_s=300.0),
    Case("sag-square-0.25", "sag_square", 58, k=0.25),
    Case("wind-gusty-5-130", "wind", 59, wind_speed_m_s=5.0, wind_from_deg=130.0, gust_sigma_m_s=0.8, gust_tau_s=10.0),
    Case("wind-steady-6-300", "wind", 60, wind_speed_m_s=6.0, wind_from_deg=300.0),
]
FOURTH = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-g", "null", 61),
    Case("null-h", "null", 62),
    Case("dead_zone-left-soft-60-110us", "dead_zone", 63, side="left", inner_us=60.0, outer_us=110.0),
    Case("dead_zone-right-hard-90us", "dead_zone", 64, side="right", inner_us=90.0, outer_us=90.0),
    Case("speed_loss-0.14u", "speed_loss", 65, k=0.14, power=1),
    Case("speed_loss-0.08u2", "speed_loss", 66, k=0.08, power=2),
    Case("sag-exp-250s", "sag_exp", 67, k=0.2, tau_s=250.0),
    Case("sag-square-0.2", "sag_square", 68, k=0.2),
    Case("wind-gusty-5.5-200", "wind", 69, wind_speed_m_s=5.5, wind_from_deg=200.0, gust_sigma_m_s=0.9, gust_tau_s=12.0),
    Case("wind-steady-5.5-70", "wind", 70, wind_speed_m_s=5.5, wind_from_deg=70.0),
]
FIFTH = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-i", "null", 71),
    Case("null-j", "null", 72),
    Case("dead_zone-right-soft-45-100us", "dead_zone", 73, side="right", inner_us=45.0, outer_us=100.0),
    Case("dead_zone-left-hard-85us", "dead_zone", 74, side="left", inner_us=85.0, outer_us=85.0),
    Case("speed_loss-0.11u", "speed_loss", 75, k=0.11, power=1),
    Case("speed_loss-0.13u2", "speed_loss", 76, k=0.13, power=2),
    Case("sag-exp-350s", "sag_exp", 77, k=0.25, tau_s=350.0),
    Case("sag-square-0.3", "sag_square", 78, k=0.3),
    Case("wind-gusty-6-320", "wind", 79, wind_speed_m_s=6.0, wind_from_deg=320.0, gust_sigma_m_s=1.0, gust_tau_s=12.0),
    Case("wind-steady-5-150", "wind", 80, wind_speed_m_s=5.0, wind_from_deg=150.0),
]
SIXTH = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-k", "null", 81),
    Case("null-l", "null", 82),
    Case("dead_zone-left-soft-55-95us", "dead_zone", 83, side="left", inner_us=55.0, outer_us=95.0),
    Case("dead_zone-right-hard-75us", "dead_zone", 84, side="right", inner_us=75.0, outer_us=75.0),
    Case("speed_loss-0.09u", "speed_loss", 85, k=0.09, power=1),
    Case("speed_loss-0.11u2", "speed_loss", 86, k=0.11, power=2),
    Case("sag-exp-300s", "sag_exp", 87, k=0.22, tau_s=300.0),
    Case("sag-square-0.25", "sag_square", 88, k=0.25),
    Case("wind-gusty-5-60", "wind", 89, wind_speed_m_s=5.0, wind_from_deg=60.0, gust_sigma_m_s=0.8, gust_tau_s=15.0),
    Case("wind-steady-6-240", "wind", 90, wind_speed_m_s=6.0, wind_from_deg=240.0),
]
SEVENTH = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-m", "null", 91),
    Case("null-n", "null", 92),
    Case("dead_zone-right-soft-50-105us", "dead_zone", 93, side="right", inner_us=50.0, outer_us=105.0),
    Case("dead_zone-left-hard-80us", "dead_zone", 94, side="left", inner_us=80.0, outer_us=80.0),
    Case("speed_loss-0.12u", "speed_loss", 95, k=0.12, power=1),
    Case("speed_loss-0.09u2", "speed_loss", 96, k=0.09, power=2),
    Case("sag-exp-280s", "sag_exp", 97, k=0.25, tau_s=280.0),
    Case("sag-square-0.22", "sag_square", 98, k=0.22),
    Case("wind-gusty-6-100", "wind", 99, wind_speed_m_s=6.0, wind_from_deg=100.0, gust_sigma_m_s=0.9, gust_tau_s=12.0),
    Case("wind-steady-5.5-200", "wind", 100, wind_speed_m_s=5.5, wind_from_deg=200.0),
]
EIGHTH = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-o", "null", 101),
    Case("null-p", "null", 102),
    Case("dead_zone-left-soft-60-110us", "dead_zone", 103, side="left", inner_us=60.0, outer_us=110.0),
    Case("dead_zone-right-hard-75us", "dead_zone", 104, side="right", inner_us=75.0, outer_us=75.0),
    Case("speed_loss-0.13u", "speed_loss", 105, k=0.13, power=1),
    Case("speed_loss-0.10u2", "speed_loss", 106, k=0.10, power=2),
    Case("sag-exp-350s", "sag_exp", 107, k=0.2, tau_s=350.0),
    Case("sag-square-0.18", "sag_square", 108, k=0.18),
    Case("wind-gusty-5-30", "wind", 109, wind_speed_m_s=5.0, wind_from_deg=30.0, gust_sigma_m_s=0.8, gust_tau_s=10.0),
    Case("wind-steady-6.5-250", "wind", 110, wind_speed_m_s=6.5, wind_from_deg=250.0),
]
NINTH = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-q", "null", 111),
    Case("null-r", "null", 112),
    Case("dead_zone-right-soft-40-100us", "dead_zone", 113, side="right", inner_us=40.0, outer_us=100.0),
    Case("dead_zone-left-hard-90us", "dead_zone", 114, side="left", inner_us=90.0, outer_us=90.0),
    Case("speed_loss-0.15u", "speed_loss", 115, k=0.15, power=1),
    Case("speed_loss-0.14u2", "speed_loss", 116, k=0.14, power=2),
    Case("sag-exp-220s", "sag_exp", 117, k=0.3, tau_s=220.0),
    Case("sag-square-0.25", "sag_square", 118, k=0.25),
    Case("wind-gusty-7-160", "wind", 119, wind_speed_m_s=7.0, wind_from_deg=160.0, gust_sigma_m_s=1.0, gust_tau_s=15.0),
    Case("wind-steady-5-330", "wind", 120, wind_speed_m_s=5.0, wind_from_deg=330.0),
]
TENTH = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-s", "null", 121),
    Case("null-t", "null", 122),
    Case("dead_zone-left-soft-50-110us", "dead_zone", 123, side="left", inner_us=50.0, outer_us=110.0),
    Case("dead_zone-right-hard-80us", "dead_zone", 124, side="right", inner_us=80.0, outer_us=80.0),
    Case("speed_loss-0.12u", "speed_loss", 125, k=0.12, power=1),
    Case("speed_loss-0.18u2", "speed_loss", 126, k=0.18, power=2),
    Case("sag-exp-300s", "sag_exp", 127, k=0.25, tau_s=300.0),
    Case("sag-square-0.3", "sag_square", 128, k=0.3),
    Case("wind-gusty-6-40", "wind", 129, wind_speed_m_s=6.0, wind_from_deg=40.0, gust_sigma_m_s=1.2, gust_tau_s=12.0),
    Case("wind-steady-6.5-210", "wind", 130, wind_speed_m_s=6.5, wind_from_deg=210.0),
]
ELEVENTH = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-u", "null", 131),
    Case("null-v", "null", 132),
    Case("dead_zone-right-soft-45-105us", "dead_zone", 133, side="right", inner_us=45.0, outer_us=105.0),
    Case("dead_zone-left-hard-85us", "dead_zone", 134, side="left", inner_us=85.0, outer_us=85.0),
    Case("speed_loss-0.16u", "speed_loss", 135, k=0.16, power=1),
    Case("speed_loss-0.16u2", "speed_loss", 136, k=0.16, power=2),
    Case("sag-exp-260s", "sag_exp", 137, k=0.28, tau_s=260.0),
    Case("sag-square-0.22", "sag_square", 138, k=0.22),
    Case("wind-gusty-5.5-300", "wind", 139, wind_speed_m_s=5.5, wind_from_deg=300.0, gust_sigma_m_s=1.1, gust_tau_s=14.0),
    Case("wind-steady-7-120", "wind", 140, wind_speed_m_s=7.0, wind_from_deg=120.0),
]
TWELFTH = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-w", "null", 141),
    Case("null-x", "null", 142),
    Case("dead_zone-left-soft-50-100us", "dead_zone", 143, side="left", inner_us=50.0, outer_us=100.0),
    Case("dead_zone-right-hard-85us", "dead_zone", 144, side="right", inner_us=85.0, outer_us=85.0),
    Case("speed_loss-0.14u", "speed_loss", 145, k=0.14, power=1),
    Case("speed_loss-0.12u2", "speed_loss", 146, k=0.12, power=2),
    Case("sag-exp-320s", "sag_exp", 147, k=0.24, tau_s=320.0),
    Case("sag-square-0.28", "sag_square", 148, k=0.28),
    Case("wind-gusty-6.5-210", "wind", 149, wind_speed_m_s=6.5, wind_from_deg=210.0, gust_sigma_m_s=1.0, gust_tau_s=13.0),
    Case("wind-steady-5-70", "wind", 150, wind_speed_m_s=5.0, wind_from_deg=70.0),
]
THIRTEENTH = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-y", "null", 151),
    Case("null-z", "null", 152),
    Case("dead_zone-right-soft-55-100us", "dead_zone", 153, side="right", inner_us=55.0, outer_us=100.0),
    Case("dead_zone-left-hard-75us", "dead_zone", 154, side="left", inner_us=75.0, outer_us=75.0),
    Case("speed_loss-0.11u", "speed_loss", 155, k=0.11, power=1),
    Case("speed_loss-0.15u2", "speed_loss", 156, k=0.15, power=2),
    Case("sag-exp-240s", "sag_exp", 157, k=0.26, tau_s=240.0),
    Case("sag-square-0.24", "sag_square", 158, k=0.24),
    Case("wind-gusty-5-280", "wind", 159, wind_speed_m_s=5.0, wind_from_deg=280.0, gust_sigma_m_s=0.9, gust_tau_s=11.0),
    Case("wind-steady-6-160", "wind", 160, wind_speed_m_s=6.0, wind_from_deg=160.0),
]
FOURTEENTH = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-aa", "null", 161),
    Case("null-ab", "null", 162),
    Case("dead_zone-left-soft-60-110us", "dead_zone", 163, side="left", inner_us=60.0, outer_us=110.0),
    Case("dead_zone-right-hard-80us", "dead_zone", 164, side="right", inner_us=80.0, outer_us=80.0),
    Case("speed_loss-0.13u", "speed_loss", 165, k=0.13, power=1),
    Case("speed_loss-0.1u2", "speed_loss", 166, k=0.10, power=2),
    Case("sag-exp-280s", "sag_exp", 167, k=0.22, tau_s=280.0),
    Case("sag-square-0.3", "sag_square", 168, k=0.30),
    Case("wind-gusty-6-30", "wind", 169, wind_speed_m_s=6.0, wind_from_deg=30.0, gust_sigma_m_s=1.2, gust_tau_s=12.0),
    Case("wind-steady-5.5-230", "wind", 170, wind_speed_m_s=5.5, wind_from_deg=230.0),
]
FIFTEENTH = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-ac", "null", 171),
    Case("null-ad", "null", 172),
    Case("dead_zone-right-soft-50-95us", "dead_zone", 173, side="right", inner_us=50.0, outer_us=95.0),
    Case("dead_zone-left-hard-90us", "dead_zone", 174, side="left", inner_us=90.0, outer_us=90.0),
    Case("speed_loss-0.16u", "speed_loss", 175, k=0.16, power=1),
    Case("speed_loss-0.13u2", "speed_loss", 176, k=0.13, power=2),
    Case("sag-exp-360s", "sag_exp", 177, k=0.2, tau_s=360.0),
    Case("sag-square-0.26", "sag_square", 178, k=0.26),
    Case("wind-gusty-5.5-120", "wind", 179, wind_speed_m_s=5.5, wind_from_deg=120.0, gust_sigma_m_s=1.0, gust_tau_s=10.0),
    Case("wind-steady-6.5-320", "wind", 180, wind_speed_m_s=6.5, wind_from_deg=320.0),
]
SIXTEENTH = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-ae", "null", 181),
    Case("null-af", "null", 182),
    Case("dead_zone-left-soft-45-100us", "dead_zone", 183, side="left", inner_us=45.0, outer_us=100.0),
    Case("dead_zone-right-hard-85us", "dead_zone", 184, side="right", inner_us=85.0, outer_us=85.0),
    Case("speed_loss-0.14u", "speed_loss", 185, k=0.14, power=1),
    Case("speed_loss-0.11u2", "speed_loss", 186, k=0.11, power=2),
    Case("sag-exp-420s", "sag_exp", 187, k=0.22, tau_s=420.0),
    Case("sag-square-0.24", "sag_square", 188, k=0.24),
    Case("wind-gusty-6-250", "wind", 189, wind_speed_m_s=6.0, wind_from_deg=250.0, gust_sigma_m_s=1.1, gust_tau_s=11.0),
    Case("wind-steady-5-70", "wind", 190, wind_speed_m_s=5.0, wind_from_deg=70.0),
]
SEVENTEENTH = [  # fixed before it was run: other seeds, magnitudes, sides and directions of the same kinds
    Case("null-ag", "null", 191),
    Case("null-ah", "null", 192),
    Case("dead_zone-right-soft-40-95us", "dead_zone", 193, side="right", inner_us=40.0, outer_us=95.0),
    Case("dead_zone-left-hard-80us", "dead_zone", 194, side="left", inner_us=80.0, outer_us=80.0),
    Case("speed_loss-0.12u", "speed_loss", 195, k=0.12, power=1),
    Case("speed_loss-0.12u2", "speed_loss", 196, k=0.12, power=2),
    Case("sag-exp-380s", "sag_exp", 197, k=0.21, tau_s=380.0),
    Case("sag-square-0.22", "sag_square", 198, k=0.22),
    Case("wind-gusty-5-200", "wind", 199, wind_speed_m_s=5.0, wind_from_deg=200.0, gust_sigma_m_s=1.0, gust_tau_s=12.0),
    Case("wind-steady-6-10", "wind", 200, wind_speed_m_s=6.0, wind_from_deg=10.0),
]
SETS = {"first": FIRST, "second": SECOND, "third": THIRD, "fourth": FOURTH, "fifth": FIFTH, "sixth": SIXTH,
        "seventh": SEVENTH, "eighth": EIGHTH, "ninth": NINTH, "tenth": TENTH, "eleventh": ELEVENTH,
        "twelfth": TWELFTH, "thirteenth": THIRTEENTH, "fourteenth": FOURTEENTH,
        "fifteenth": FIFTEENTH, "sixteenth": SIXTEENTH, "seventeenth": SEVENTEENTH}

# the library's names an effect may be named by and still be the truth
ACCEPTED = {"wind": ("wind", "wind_shape")}


# ---------------------------------------------------------------- the hull's numbers and equations

@dataclass(frozen=True)
class Hull:
    """The Yellowfish's numbers, as plain floats (body frame FRD about the origin CO)."""

    mass_kg: float
    xg_m: float
    yg_m: float
    iz_kgm2: float
    added_kg: tuple[float, float, float]  # −Xu̇, −Yv̇, −Nṙ
    linear: tuple[float, float, float]  # Xu, Yv, Nr (< 0)
    quadratic: tuple[float, float, float]  # X|u|u, Y|v|v, N|r|r (< 0)
    thruster_y_m: tuple[float, float]
    gnss_xy_m: tuple[float, float]
    forward: tuple[float, float, float]  # a, b, c of a·x² + b·x + c in normalised PWM x
    reverse: tuple[float, float, float]
    edge_fwd: float
    edge_rev: float
    pwm_scale_us: float
    pwm_offset: float
    gains: tuple[float, float]
    advance_loss: float
    frontal_area_m2: float
    lateral_area_m2: float
    length_m: float


def hull_of(vessel) -> Hull:
    """Read the numbers; refuse a prior with a term this simulator does not have."""
    geometry = compile_vessel(vessel).geometry
    rigid, am, d, th, load = geometry.rigid, vessel.added_mass, vessel.damping, vessel.thrusters, vessel.wind_load
    absent = {"Yrdot": am.Yrdot, "Nvdot": am.Nvdot, "lag_s": th.lag_s, "delay_s": th.delay_s,
              "decay_per_min": th.decay_per_min, "advance_loss": th.advance_loss, "ramp_s": th.ramp_s,
              **{k: getattr(d, k) for k in ("Yrv", "Yr", "Yvr", "Yrr", "Nv", "Nvv", "Nrv", "Nvr", "Yuv", "Nur", "Yur",
                                            "Nuv", "astern_excess")}}
    present = {k: v for k, v in absent.items() if v}
    if present or th.kind != "t200" or th.full_share != 1.0 or th.deadzone_left or th.deadzone_right:
        raise SystemExit(f"the prior has terms this simulator leaves out: {present or th}")
    return Hull(rigid.mass_kg, rigid.xg_m, rigid.yg_m, rigid.Iz_kgm2, (-am.Xudot, -am.Yvdot, -am.Nrdot),
                (d.Xu, d.Yv, d.Nr), (d.Xuu, d.Yvv, d.Nrr), tuple(geometry.thruster_y_m),
                (float(geometry.gnss_pos_m[0]), float(geometry.gnss_pos_m[1])), tuple(th.forward), tuple(th.reverse),
                th.deadzone_fwd, th.deadzone_rev, th.pwm_scale_us, th.pwm_offset, (th.gain_left, th.gain_right),
                th.advance_loss, load.frontal_area_m2, load.lateral_area_m2, load.length_m)


def inverse_mass(hull: Hull) -> np.ndarray:
    """(M_RB + M_A)⁻¹ about CO."""
    m = hull.mass_kg
    a11, a22, a33 = hull.added_kg
    mass = np.array([[m + a11, 0.0, -m * hull.yg_m],
                     [0.0, m + a22, m * hull.xg_m],
                     [-m * hull.yg_m, m * hull.xg_m, hull.iz_kgm2 + a33]])
    return np.linalg.inv(mass)


def map_thrust_n(hull: Hull, pwm_us: float, side: int) -> float:
    """One thruster's static thrust (N) from its pulse: the T200 quadratics outside the shipped dead zone."""
    x = min(max(pwm_us, PWM_MIN_US), PWM_MAX_US) / hull.pwm_scale_us - hull.pwm_offset
    if x >= hull.edge_fwd:
        a, b, c = hull.forward
    elif x <= hull.edge_rev:
        a, b, c = hull.reverse
    else:
        return 0.0
    return (a * x * x + b * x + c) * hull.gains[side]


def smoothstep(s: float) -> float:
    s = min(max(s, 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


def dead_zone_share(case: Case, pwm_us: float, side: int) -> float:
    """The share of its thrust a thruster gives under the case's dead zone (1 for the other thruster)."""
    if case.kind != "dead_zone" or side != ("left", "right").index(case.side):
        return 1.0
    off_us = abs(pwm_us - NEUTRAL_US)
    if case.outer_us <= case.inner_us:
        return 1.0 if off_us > case.inner_us else 0.0
    return smoothstep((off_us - case.inner_us) / (case.outer_us - case.inner_us))


def sag_share(case: Case, t_s: float) -> float:
    if case.kind == "sag_exp":
        return 1.0 - case.k + case.k * math.exp(-t_s / case.tau_s)
    if case.kind == "sag_square":
        return 1.0 - case.k * (t_s / DURATION_S) ** 2
    return 1.0


def speed_loss_share(case: Case, thrust_n: float, u_m_s: float) -> float:
    """T·(1 − k·u^power) ahead only (thrust and surge speed both positive), never below nothing."""
    if case.kind != "speed_loss" or thrust_n <= 0.0 or u_m_s <= 0.0:
        return 1.0
    return max(0.0, 1.0 - case.k * u_m_s ** case.power)


def wind_load_n(hull: Hull, psi_rad: float, u_m_s: float, v_m_s: float, wind_m_s: float,
                from_deg: float) -> tuple[float, float, float]:
    """This script's wind load (X, Y, N) on the relative wind; γ = 0 is a head wind."""
    if wind_m_s == 0.0:
        return 0.0, 0.0, 0.0
    going = math.radians(from_deg) + math.pi  # where the air goes
    wn, we = wind_m_s * math.cos(going), wind_m_s * math.sin(going)
    c, s = math.cos(psi_rad), math.sin(psi_rad)
    u_rel, v_rel = u_m_s - (c * wn + s * we), v_m_s - (-s * wn + c * we)
    q_pa = 0.5 * RHO_AIR_KG_M3 * (u_rel * u_rel + v_rel * v_rel)
    gamma = -math.atan2(v_rel, u_rel)
    return (-WIND_CX * math.cos(gamma) * hull.frontal_area_m2 * q_pa,
            WIND_CY * math.sin(gamma) * hull.lateral_area_m2 * q_pa,
            WIND_CN * math.sin(2.0 * gamma) * hull.lateral_area_m2 * hull.length_m * q_pa)


def derivative(hull: Hull, m_inv: np.ndarray, x: tuple, thrust_n: tuple[float, float],
               wind: tuple[float, float]) -> tuple:
    """d/dt of (north, east, ψ, u, v, r) for thrusts already delivered and a wind (speed, from)."""
    _, _, psi, u, v, r = x
    m = hull.mass_kg
    a11, a22, _ = hull.added_kg
    lu, lv, lr = hull.linear
    qu, qv, qr = hull.quadratic
    yl, yr = hull.thruster_y_m
    wx, wy, wn = wind_load_n(hull, psi, u, v, *wind)
    # τ − C_RB(ν)ν − C_A(ν)ν − D(ν)ν
    fx = (thrust_n[0] + thrust_n[1] + wx + m * (v * r + hull.xg_m * r * r) + a22 * v * r
          + lu * u + qu * abs(u) * u)
    fy = wy - m * (u * r - hull.yg_m * r * r) - a11 * u * r + lv * v + qv * abs(v) * v
    fn = (-(yl * thrust_n[0] + yr * thrust_n[1]) + wn - m * (hull.xg_m * u * r + hull.yg_m * v * r)
          - (a22 - a11) * u * v + lr * r + qr * abs(r) * r)
    du = m_inv[0, 0] * fx + m_inv[0, 1] * fy + m_inv[0, 2] * fn
    dv = m_inv[1, 0] * fx + m_inv[1, 1] * fy + m_inv[1, 2] * fn
    dr = m_inv[2, 0] * fx + m_inv[2, 1] * fy + m_inv[2, 2] * fn
    c, s = math.cos(psi), math.sin(psi)
    return (c * u - s * v, s * u + c * v, r, du, dv, dr)


def delivered_n(hull: Hull, case: Case, pwm_us: tuple[float, float], t_s: float,
                u_m_s: float) -> tuple[tuple[float, float], tuple[float, float]]:
    """(static thrusts with the case's dead zone and sag, thrusts delivered after its speed loss), N."""
    static = tuple(map_thrust_n(hull, p, i) * dead_zone_share(case, p, i) * sag_share(case, t_s)
                   for i, p in enumerate(pwm_us))
    return static, tuple(t * speed_loss_share(case, t, u_m_s) for t in static)


def rk4_step(hull: Hull, m_inv: np.ndarray, case: Case, x: tuple, pwm_us: tuple[float, float], t_s: float,
             wind: tuple[float, float]) -> tuple:
    def f(state: tuple, at_s: float) -> tuple:
        return derivative(hull, m_inv, state, delivered_n(hull, case, pwm_us, at_s, state[3])[1], wind)

    def plus(state: tuple, k: tuple, h: float) -> tuple:
        return tuple(a + h * b for a, b in zip(state, k))
    k1 = f(x, t_s)
    k2 = f(plus(x, k1, STEP_S / 2), t_s + STEP_S / 2)
    k3 = f(plus(x, k2, STEP_S / 2), t_s + STEP_S / 2)
    k4 = f(plus(x, k3, STEP_S), t_s + STEP_S)
    return tuple(a + STEP_S / 6.0 * (b + 2 * c + 2 * d + e) for a, b, c, d, e in zip(x, k1, k2, k3, k4))


# ---------------------------------------------------------------- the mission and its pilot

@dataclass(frozen=True)
class Segment:
    """kind: sticks (mean and difference held by hand for duration_s), track (a heading held by the
    controller for duration_s), turn (the controller turns to heading_deg; ends there)."""

    kind: str
    mean_us: float
    duration_s: float
    diff_us: float = 0.0
    heading_deg: float = 0.0


def survey_plan(rng: np.random.Generator, first_heading_deg: float) -> list[Segment]:
    """A lawnmower survey: legs up and down an axis at the three throttles in a shuffled order, a short
    cross leg between them with a turn at each end, and manual segments between legs (spins both ways,
    a stop, a short astern). Longer than DURATION_S; the run is cut there."""
    throttles = [float(x) for x in rng.permutation(LEG_THROTTLES_US)]
    step = float(rng.choice([-90.0, 90.0]))  # which side the survey steps over to
    plan = [Segment("sticks", NEUTRAL_US, 4.0)]
    for leg in range(9):
        heading = (first_heading_deg + 180.0 * (leg % 2)) % 360.0
        plan += [Segment("turn", TURN_MEAN_US, TURN_MAX_S, heading_deg=heading),
                 Segment("track", throttles[leg % 3], float(rng.uniform(40.0, 55.0)), heading_deg=heading)]
        if leg in (1, 5):  # spins both ways, the first hand drawn
            hand = float(rng.choice([-1.0, 1.0]))
            for sign in (hand, -hand):
                plan += [Segment("sticks", NEUTRAL_US, float(rng.uniform(6.0, 9.0)), sign * rng.uniform(240.0, 320.0)),
                         Segment("sticks", NEUTRAL_US, 3.0)]
        if leg == 3:  # a stop and a short astern
            plan += [Segment("sticks", NEUTRAL_US, 8.0),
                     Segment("sticks", NEUTRAL_US - float(rng.uniform(100.0, 150.0)), 6.0),
                     Segment("sticks", NEUTRAL_US, 4.0)]
        cross = (heading + step * (1 if leg % 2 == 0 else -1)) % 360.0
        plan += [Segment("turn", TURN_MEAN_US, TURN_MAX_S, heading_deg=cross),
                 Segment("track", CROSS_THROTTLE_US, CROSS_LEG_S, heading_deg=cross)]
    return plan


def heading_error_deg(target_deg: float, measured_deg: float) -> float:
    return (target_deg - measured_deg + 180.0) % 360.0 - 180.0


def slewed(now_us: float, target_us: float, rate_us_per_s: float) -> float:
    limit = rate_us_per_s * TICK_S
    return now_us + min(max(target_us - now_us, -limit), limit)


class Pilot:
    """Walks the plan one tick at a time: (mean, difference) targets from the sticks or the heading
    controller on the measured heading, slewed; PWM left = mean + diff/2, right = mean − diff/2."""

    def __init__(self, plan: list[Segment]):
        self.plan, self.index, self.since_s = plan, 0, 0.0
        self.mean_us, self.diff_us = NEUTRAL_US, 0.0

    def pwm_us(self, measured_deg: float) -> tuple[float, float]:
        seg = self.plan[self.index]
        error = heading_error_deg(seg.heading_deg, measured_deg)
        done = self.since_s >= seg.duration_s or (seg.kind == "turn" and abs(error) < TURN_DONE_DEG)
        if done and self.index + 1 < len(self.plan):
            self.index, self.since_s = self.index + 1, 0.0
            seg = self.plan[self.index]
            error = heading_error_deg(seg.heading_deg, measured_deg)
        if seg.kind == "sticks":
            target_diff = seg.diff_us
        elif seg.kind == "track":
            target_diff = min(max(TRACK_GAIN_US_PER_DEG * error, -TRACK_DIFF_MAX_US), TRACK_DIFF_MAX_US)
        else:
            target_diff = min(max(TURN_GAIN_US_PER_DEG * error, -TURN_DIFF_MAX_US), TURN_DIFF_MAX_US)
        self.mean_us = slewed(self.mean_us, seg.mean_us, MEAN_SLEW_US_PER_S)
        self.diff_us = slewed(self.diff_us, target_diff, DIFF_SLEW_US_PER_S)
        self.since_s += TICK_S
        pair = (self.mean_us + self.diff_us / 2.0, self.mean_us - self.diff_us / 2.0)
        return tuple(float(round(min(max(p, PWM_MIN_US), PWM_MAX_US))) for p in pair)


# ---------------------------------------------------------------- the run and its log

def gust_series_m_s(case: Case, rng: np.random.Generator, n_steps: int) -> np.ndarray:
    """First-order (Gauss-Markov) gusts on the wind speed, one value per RK4 step, stationary from the start."""
    if case.gust_sigma_m_s == 0.0:
        return np.zeros(n_steps)
    a = math.exp(-STEP_S / case.gust_tau_s)
    kick = case.gust_sigma_m_s * math.sqrt(1.0 - a * a) * rng.standard_normal(n_steps)
    out = np.empty(n_steps)
    g = case.gust_sigma_m_s * rng.standard_normal()
    for i in range(n_steps):
        out[i] = g
        g = a * g + kick[i]
    return out


def simulate(case: Case, hull: Hull) -> dict[str, np.ndarray]:
    """The case's ten minutes, one row per tick: true time, state at the tick, the PWM set at it and the
    measurements taken at it (GNSS antenna north/east on every TICKS_PER_FIX-th row, NaN between)."""
    plan_rng, sensor_rng, gust_rng = (np.random.default_rng(s) for s in np.random.SeedSequence(case.seed).spawn(3))
    first_heading_deg = float(plan_rng.uniform(0.0, 360.0))
    pilot = Pilot(survey_plan(plan_rng, first_heading_deg))
    m_inv = inverse_mass(hull)
    n_ticks = int(round(DURATION_S / TICK_S))
    gusts = gust_series_m_s(case, gust_rng, n_ticks * STEPS_PER_TICK)
    x = (0.0, 0.0, math.radians(first_heading_deg), 0.0, 0.0, 0.0)
    names = ("t_s", "north_m", "east_m", "psi_rad", "u_m_s", "v_m_s", "r_rad_s", "pwm_left_us", "pwm_right_us",
             "static_left_n", "static_right_n", "delivered_left_n", "delivered_right_n", "heading_deg",
             "gnss_north_m", "gnss_east_m")
    rows = np.full((n_ticks, len(names)), np.nan)
    for k in range(n_ticks):
        t_s = k * TICK_S
        heading_deg = (math.degrees(x[2]) + HEADING_SIGMA_DEG * sensor_rng.standard_normal()) % 360.0
        pwm = pilot.pwm_us(heading_deg)
        static, delivered = delivered_n(hull, case, pwm, t_s, x[3])
        rows[k, :14] = (t_s, *x, *pwm, *static, *delivered, heading_deg)
        if k % TICKS_PER_FIX == 0:
            c, s = math.cos(x[2]), math.sin(x[2])
            gx, gy = hull.gnss_xy_m
            noise = GNSS_SIGMA_M * sensor_rng.standard_normal(2)
            rows[k, 14:] = (x[0] + c * gx - s * gy + noise[0], x[1] + s * gx + c * gy + noise[1])
        for j in range(STEPS_PER_TICK):
            wind = (case.wind_speed_m_s + gusts[k * STEPS_PER_TICK + j], case.wind_from_deg)
            x = rk4_step(hull, m_inv, case, x, pwm, t_s + j * STEP_S, wind)
    return {n: rows[:, i] for i, n in enumerate(names)}


def lat_lon_deg(north_m: np.ndarray, east_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Local north/east (m) to WGS-84 latitude and longitude by the radii of curvature at the origin."""
    lat0 = math.radians(ORIGIN_DEG[0])
    w = 1.0 - WGS84_E2 * math.sin(lat0) ** 2
    meridian_m = WGS84_A_M * (1.0 - WGS84_E2) / w ** 1.5
    normal_m = WGS84_A_M / math.sqrt(w)
    return (ORIGIN_DEG[0] + np.degrees(north_m / meridian_m),
            ORIGIN_DEG[1] + np.degrees(east_m / (normal_m * math.cos(lat0))))


def write_csv(run: dict[str, np.ndarray], path: Path) -> None:
    """The generic CSV: a fix on every other row, heading and PWM on every row, empty cells between."""
    lat, lon = lat_lon_deg(run["gnss_north_m"], run["gnss_east_m"])
    lines = ["t,lat,lon,heading_deg,pwm_left,pwm_right"]
    for i, t_s in enumerate(run["t_s"]):
        fix = f"{lat[i]:.10f},{lon[i]:.10f}" if np.isfinite(lat[i]) else ","
        lines.append(f"{t_s:.3f},{fix},{run['heading_deg'][i]:.4f},"
                     f"{int(run['pwm_left_us'][i])},{int(run['pwm_right_us'][i])}")
    path.write_text("\n".join(lines) + "\n")


# ---------------------------------------------------------------- the truth in the library's terms

def truth_of(case: Case, run: dict[str, np.ndarray], hull: Hull) -> tuple[str | None, dict]:
    """The library's effect name and values the case's truth is matched by (the page's notes)."""
    if case.kind == "null":
        return None, {}
    if case.kind == "dead_zone":
        edge = 0.5 * (case.inner_us + case.outer_us) / hull.pwm_scale_us
        return f"dead_zone_{case.side}", {"fwd": edge, "rev": edge}
    if case.kind == "speed_loss":
        static = np.column_stack([run["static_left_n"], run["static_right_n"]])
        lost = static - np.column_stack([run["delivered_left_n"], run["delivered_right_n"]])
        u_a = run["u_m_s"][:, None] - run["r_rad_s"][:, None] * np.array(hull.thruster_y_m)[None, :]
        shape = np.sqrt(np.abs(static)) * u_a  # the library's loss is c·√|T0|·u_a
        c = float(np.sum(lost * shape) / np.sum(shape * shape))
        return "thrust_speed_loss", {"advance_loss": hull.advance_loss + c}
    if case.kind in ("sag_exp", "sag_square"):
        minutes = run["t_s"] / 60.0
        lost = 1.0 - np.array([sag_share(case, t) for t in run["t_s"]])
        return "thrust_decay", {"decay_per_min": float(np.sum(lost * minutes) / np.sum(minutes * minutes))}
    if case.kind == "wind":
        return "wind", {"speed_m_s": case.wind_speed_m_s, "dir_deg": case.wind_from_deg}
    raise ValueError(case.kind)


def within(name: str, truth: dict, found: dict) -> bool:
    """Each of the truth's values found within 30 % (a direction within 30°)."""
    if any(k not in found for k in truth):
        return False
    if name == "wind":
        off_deg = abs((found["dir_deg"] - truth["dir_deg"] + 180.0) % 360.0 - 180.0)
        speed_off_m_s = abs(found["speed_m_s"] - truth["speed_m_s"])
        return speed_off_m_s <= TOLERANCE * truth["speed_m_s"] and off_deg <= TOLERANCE_DEG
    return all(abs(found[k] - v) <= TOLERANCE * abs(v) for k, v in truth.items())


# ---------------------------------------------------------------- the diagnosis, as a user runs it

def twin_command() -> str:
    beside = Path(sys.executable).parent / "twin"
    return str(beside) if beside.is_file() else (shutil.which("twin") or "twin")


def diagnose_cli(log_csv: Path, out_json: Path) -> tuple[dict | None, float, list[str]]:
    """`twin diagnose LOG.csv --vessel yellowfish --json OUT.json`: (its JSON or None, wall seconds, argv)."""
    argv = [twin_command(), "diagnose", str(log_csv), "--vessel", VESSEL, "--json", str(out_json)]
    started_s = time.time()
    done = subprocess.run(argv, capture_output=True, text=True, cwd=ROOT)
    seconds = time.time() - started_s
    out_json.with_suffix(".console.txt").write_text(f"$ {' '.join(argv[1:])}\n# exit {done.returncode}\n"
                                                    f"{done.stdout}\n# stderr\n{done.stderr}")
    if done.returncode != 0 or not out_json.is_file():
        return None, seconds, argv
    return json.loads(out_json.read_text()), seconds, argv


def truth_text(name: str, values: dict) -> str:
    """The truth in `twin effects` syntax (NAME=v1,v2 in the effect's own order)."""
    return f"{name}=" + ",".join(f"{v:.4g}" for v in values.values())


def given_cli(log_csv: Path, text: str, out_json: Path) -> dict | None:
    """`twin diagnose LOG.csv --vessel yellowfish --given TEXT --json OUT.json`: the truth at its own values,
    nothing fitted, judged by the diagnosis's rule on the diagnosis's blocks (its JSON, or None)."""
    argv = [twin_command(), "diagnose", str(log_csv), "--vessel", VESSEL, "--given", text, "--json", str(out_json)]
    done = subprocess.run(argv, capture_output=True, text=True, cwd=ROOT)
    out_json.with_suffix(".console.txt").write_text(f"$ {' '.join(argv[1:])}\n# exit {done.returncode}\n"
                                                    f"{done.stdout}\n# stderr\n{done.stderr}")
    if done.returncode != 0 or not out_json.is_file():
        return None
    return json.loads(out_json.read_text())


def judge_truth(case: Case, hull: Hull, row: dict, work: Path, commit: str) -> dict:
    """The row with its truth judged as given (row["given"]); the log written again from its seed when
    --work no longer holds it (the simulator is deterministic)."""
    if row["truth"] is None:
        return row
    log_csv = work / f"{case.name}.csv"
    if not log_csv.is_file():
        write_csv(simulate(case, hull), log_csv)
    text = truth_text(row["truth"], row["truth_values"])
    got = given_cli(log_csv, text, work / f"{case.name}.given.json")
    given = {"effect": text, "commit": commit, "failed": got is None}
    if got is not None:
        given.update({k: got[k] for k in ("earns_its_place", "z", "held_out_gain", "excess_gain", "blocks_for",
                                          "blocks_against", "affected_windows")})
    return {**row, "given": given}


def steady_speeds(run: dict[str, np.ndarray], hull: Hull) -> list[dict]:
    """The simulator against the hand balance: on each survey leg's last 10 s at a steady throttle, the
    mean surge speed and the speed at which 2·T(mean PWM) = −Xu·u − X|u|u·u²."""
    mean_us = 0.5 * (run["pwm_left_us"] + run["pwm_right_us"])
    out = []
    for throttle_us in LEG_THROTTLES_US:
        steady = np.abs(mean_us - throttle_us) <= 1.0
        idx = np.flatnonzero(steady)
        if not len(idx):
            continue
        runs = [r for r in np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1) if len(r) * TICK_S >= 30.0]
        if not runs:  # a gusty wind keeps the heading controller's throttle from ever holding 30 s
            continue
        last = np.concatenate([r[-int(10.0 / TICK_S):] for r in runs])
        thrust_n = sum(map_thrust_n(hull, throttle_us, i) for i in (0, 1))
        xu, xuu = -hull.linear[0], -hull.quadratic[0]
        balance = (-xu + math.sqrt(xu * xu + 4.0 * xuu * thrust_n)) / (2.0 * xuu)
        out.append({"throttle_us": throttle_us, "thrust_n": thrust_n, "u_balance_m_s": balance,
                    "u_sim_m_s": float(np.mean(run["u_m_s"][last])), "samples": int(len(last))})
    return out


def run_case(case: Case, hull: Hull, work: Path) -> dict:
    started_s = time.time()
    run = simulate(case, hull)
    log_csv = work / f"{case.name}.csv"
    write_csv(run, log_csv)
    simulated_s = time.time() - started_s
    truth_name, truth = truth_of(case, run, hull)
    found, seconds, argv = diagnose_cli(log_csv, work / f"{case.name}.diagnosis.json")
    row = {"case": case.name, "kind": case.kind, "seed": case.seed, "spec": asdict(case), "truth": truth_name,
           "truth_values": truth, "seconds": round(seconds, 1), "simulated_s": round(simulated_s, 1),
           "command": " ".join(["twin", *argv[1:]]), "log": {"rows": len(run["t_s"]),
           "fixes": int(np.isfinite(run["gnss_north_m"]).sum()), "u_max_m_s": float(np.max(run["u_m_s"])),
           "r_max_deg_s": float(np.degrees(np.max(np.abs(run["r_rad_s"]))))}, "steady": steady_speeds(run, hull)}
    if found is None:
        return {**row, "failed": True, "named": [], "hit": False, "within": False, "others": [], "exact": False,
                "calibrations": [], "notes": []}
    named = [{"name": e["name"], "parameters": dict(e["parameters"])} for e in found["effects"]]
    accepted = ACCEPTED.get(truth_name, (truth_name,))
    hit = next((e for e in named if e["name"] in accepted), None)
    others = [e["name"] for e in named if e is not hit]
    close = bool(hit is not None and within(truth_name, truth, hit["parameters"]))
    return {**row, "failed": False, "named": named, "hit": hit is not None, "within": close, "others": others,
            "exact": (not named) if truth_name is None else (close and not others),
            "unsettled": unsettled_rivals(found), "calibrations": found.get("calibrations", []),
            "notes": found.get("notes", [])}


def unsettled_rivals(found: dict) -> list[str]:
    """The effects a diagnosis reports in place of one it named, which the recording cannot tell from
    it (its rivals not separable: UNSETTLED in the CLI's answer)."""
    return sorted({r["name"] for e in found.get("effects", []) for r in e.get("rivals", []) if not r["separable"]})


def truth_unsettled(row: dict) -> bool:
    """The truth not named but reported as a rival the recording cannot tell from what was."""
    accepted = ACCEPTED.get(row["truth"], (row["truth"],))
    return bool(row["truth"] is not None and not row["hit"] and set(accepted) & set(row.get("unsettled", [])))


# ---------------------------------------------------------------- the page

def summary_of(rows: list[dict]) -> dict:
    effects = [r for r in rows if r["truth"] is not None]
    nulls = [r for r in rows if r["truth"] is None]
    judged = [r for r in effects if "given" in r and not r["given"]["failed"]]
    provable = [r for r in judged if r["given"]["earns_its_place"]]
    given = {"given_judged": len(judged), "given_provable": len(provable),
             "exact_where_provable": sum(r["exact"] for r in provable),
             "exact_where_not_provable": sum(r["exact"] for r in judged if r not in provable)} if judged else {}
    return {**given, "effects": len(effects), "named": sum(r["hit"] for r in effects), "exact": sum(r["exact"] for r in effects),
            "truth_unsettled": sum(truth_unsettled(r) for r in effects),
            "false_discoveries": sum(len(r["others"]) for r in effects) + sum(len(r["named"]) for r in nulls),
            "nulls": len(nulls), "nulls_clean": sum(r["exact"] for r in nulls),
            "failed": sum(r["failed"] for r in rows), "seconds": round(sum(r["seconds"] for r in rows), 1)}


def _values_text(values: dict) -> str:
    return ", ".join(f"{k} {v:.3g}" for k, v in values.items())


def _calibration_text(calibrations: list[dict]) -> str:
    """Each log's compass offset as the calibration left it: the offset applied, or not applied."""
    return "; ".join("not applied" if c.get("heading_bias_deg") is None else f"{c['heading_bias_deg']:+.2g}° applied"
                     for c in calibrations) or "-"


def case_text(case: Case) -> str:
    """One case's concealed effect in words."""
    if case.kind == "null":
        return "nothing"
    if case.kind == "dead_zone":
        edge = (f"hard at {case.inner_us:g} µs" if case.inner_us == case.outer_us
                else f"soft from {case.inner_us:g} to {case.outer_us:g} µs")
        return f"{case.side} thruster's dead zone, {edge}"
    if case.kind == "speed_loss":
        return f"thrust × (1 − {case.k:g}·u{'²' if case.power == 2 else ''})"
    if case.kind == "sag_exp":
        return f"thrust × ({1 - case.k:g} + {case.k:g}·exp(−t/{case.tau_s:g} s))"
    if case.kind == "sag_square":
        return f"thrust × (1 − {case.k:g}·(t/{DURATION_S:g} s)²)"
    if case.kind == "wind":
        gusts = f", gusts σ {case.gust_sigma_m_s:g} m/s over {case.gust_tau_s:g} s" if case.gust_sigma_m_s else ", steady"
        return f"wind {case.wind_speed_m_s:g} m/s from {case.wind_from_deg:g}°{gusts}"
    raise ValueError(case.kind)


def write_page(rows: list[dict], commit: str, out: Path, proof_set: str = "first", compared: dict | None = None) -> Path:
    """The set's page from its rows; `compared` ({"label", "commit", "rows"}), the same recordings diagnosed
    by another commit's diagnosis, is shown beside them."""
    s = summary_of(rows)
    line = (f"{s['exact']} of {s['effects']} exact, {s['named']} named; {s['false_discoveries']} false {'discovery' if s['false_discoveries'] == 1 else 'discoveries'}; "
            f"nulls clean {s['nulls_clean']} of {s['nulls']}"
            + (f"; {s['failed']} diagnoses failed" if s["failed"] else "")
            + f" (diagnoses {s['seconds']:.0f} s in all)."
            + (f" Of the truths not named, {s['truth_unsettled']} the diagnosis reported as a rival the recording "
               "cannot tell from what it named (UNSETTLED)." if s["truth_unsettled"] else ""))
    if s.get("given_judged"):
        commits = sorted({r["given"]["commit"] for r in rows if "given" in r})
        line += (f" The truth itself, given at its own values in the library's terms and judged by the diagnosis's "
                 f"rule on the same blocks (commit {', '.join(commits)}): the recording can prove it on "
                 f"{s['given_provable']} of {s['given_judged']}; of those the diagnosis named {s['exact_where_provable']} "
                 f"exactly, of the others {s['exact_where_not_provable']}.")
    by_name = {c.name: c for c in SETS[proof_set]}
    cases = ResultTable("Each truth and what the diagnosis named",
                        ["case", "seed", "concealed", "truth (library's terms)", "named (values)", "exact", "else named",
                         "unsettled with", "truth as given", "s"],
                        [[r["case"], r["seed"], case_text(by_name[r["case"]]), "nothing" if r["truth"] is None else
                          f"{r['truth']} ({_values_text(r['truth_values'])})",
                          "diagnosis failed" if r["failed"] else
                          "; ".join(f"{e['name']} ({_values_text(e['parameters'])})" for e in r["named"]) or "nothing",
                          "yes" if r["exact"] else "no", ", ".join(r["others"]) or "-",
                          "not recorded" if "unsettled" not in r else ", ".join(r["unsettled"]) or "-",
                          given_cell(r.get("given")), r["seconds"]]
                         for r in rows])
    logs = ResultTable("The recordings",
                       ["case", "rows", "GNSS fixes", "top surge speed m/s", "top yaw rate °/s", "compass calibration"],
                       [[r["case"], r["log"]["rows"], r["log"]["fixes"], r["log"]["u_max_m_s"], r["log"]["r_max_deg_s"],
                         _calibration_text(r["calibrations"])] for r in rows])
    null = next((r for r in rows if r["truth"] is None), None)
    tables = [cases, logs]
    if compared:
        c = summary_of(compared["rows"])
        line += (f" The same recordings diagnosed at commit {compared['commit']} ({compared['label']}): {c['exact']} of "
                 f"{c['effects']} exact, {c['named']} named; {c['false_discoveries']} false {'discovery' if c['false_discoveries'] == 1 else 'discoveries'}; nulls clean "
                 f"{c['nulls_clean']} of {c['nulls']}.")
        tables.insert(1, ResultTable(f"The same recordings diagnosed at commit {compared['commit']} ({compared['label']})",
                                     ["case", "named (values)", "exact", "else named"],
                                     [[r["case"], "diagnosis failed" if r["failed"] else "; ".join(
                                         f"{e['name']} ({_values_text(e['parameters'])})" for e in r["named"]) or "nothing",
                                       "yes" if r["exact"] else "no", ", ".join(r["others"]) or "-"]
                                      for r in compared["rows"]]))
    if null is not None:
        tables.append(ResultTable(f"The simulator against the hand balance of thrust and surge drag ({null['case']})",
                                  ["throttle µs", "2·T N", "u balance m/s", "u simulated m/s", "samples"],
                                  [[x["throttle_us"], x["thrust_n"], x["u_balance_m_s"], x["u_sim_m_s"], x["samples"]]
                                   for x in null["steady"]], digits=4))
    seeds = [c.seed for c in SETS[proof_set]]
    page = ResultPage(
        page_name(proof_set),
        "Effect truths of forms the library lacks, from a simulator of the study's own, diagnosed by the CLI"
        + ("" if proof_set == "first" else f" (proof set: {proof_set})"),
        "python scripts/blind_truths.py" + ("" if proof_set == "first" else f" --set {proof_set}")
        + (", then the same with --truth-given" if s.get("given_judged") else ""),
        f"Ten recordings of 10 minutes (seeds {min(seeds)}-{max(seeds)}) written by scripts/blind_truths.py's own three-degree-of-freedom "
        "simulator (RK4 at 0.02 s) from the shipped Yellowfish's numbers: a survey mission (legs at 1650, 1750 and "
        "1850 µs held by a heading controller on the PWM difference, 90° turns and a short cross leg at each end, "
        "spins of both hands twice, a stop and a short astern), logged as the generic CSV (GNSS antenna 5 Hz with "
        "2 cm noise, heading 10 Hz with 0.3° noise, PWM 10 Hz, every sample at its true time). Each diagnosed with "
        "`twin diagnose LOG.csv --vessel yellowfish --json OUT.json` from the shipped, untuned Yellowfish "
        f"(commit {commit}).",
        ("" if proof_set == "first" else f"Proof set {proof_set}, fixed before it was run: the same kinds as the "
                                          "first set at other seeds, magnitudes, sides and directions. ")
        + "One concealed effect per recording, in forms the effect library does not have but for the hard dead zone "
        "and the steady wind's load (notes), and two nulls. Exact: the "
        "truth named in the library's terms with its values within 30 % (30° for a direction) and nothing else; a "
        "null is exact when nothing is named; a compass offset the calibration applies is not an effect named. "
        + line,
        tables,
        ["The simulator's terms: M_RB about the body origin with the CG off it (mass, CG and yaw inertia from "
         "compile_vessel(yellowfish).geometry.rigid), diagonal added mass with its Coriolis and Munk terms, linear and "
         "quadratic damping in surge, sway and yaw, the T200 quadratics outside the shipped dead zone (0.0775 / "
         "−0.0925 in normalised PWM), thrust along body x at the thrusters' y, the GNSS antenna at its site; PWM held "
         "over each 0.1 s tick. It refuses a prior with a term it leaves out (cross damping, thrust lag, decay).",
         "Dead zone of one thruster: no thrust within ±inner µs of neutral, the map's thrust from ±outer µs, "
         "smoothstep between (hard where inner = outer), ahead and astern alike. "
         "In the library's terms dead_zone_left / dead_zone_right with fwd = rev = the hard edge or the soft edge's "
         "middle over pwm_scale_us (400 µs). The hard one is the library's own form but for the "
         "edge pulse itself (the library gives thrust at the edge, this simulator none).",
         "Thrust loss with speed: each thruster's static thrust T × (1 − k·u) or × (1 − k·u²), u the hull's "
         "surge speed, only where T > 0 and u > 0. In the library's terms thrust_speed_loss with advance_loss = the "
         "prior's (0) + c, c the least-squares match over every 0.1-s row of the log and both thrusters of the "
         "loss taken off by c·√|T0|·u_a, u_a = u − r·y_i (rows without loss count as zero loss).",
         "Thrust sag: every thrust × (1 − k + k·exp(−t/τ)) or × (1 − k·(t/600 s)²). In the library's terms "
         "thrust_decay with decay_per_min = k, the least-squares line through the start, 1 − k·t/60 s, over every "
         "0.1-s row of the log (Σ(1 − f)·t_min / Σ t_min²).",
         "Wind: from the given direction, its speed steady or with first-order gusts (the correlation time and σ "
         "of the table, drawn at every RK4 step), its load this script's own: X = −0.6·cos γ·A_F·q, Y = 0.8·sin γ·A_L·q, "
         "N = −0.1·sin 2γ·A_L·L·q on the relative wind (γ = 0 a head wind; the shipped load's yaw moment has the "
         "other sign), on the vessel's wind areas. X and Y are the shipped load's form and coefficients, so the "
         "steady wind's load is wind_shape's form with cy 0.8 and cn −0.1; the gusts are no form of the library. "
         "In the library's terms wind or wind_shape with speed_m_s the mean speed and dir_deg the direction it "
         "blows from.",
         "Named: every entry of the CLI's JSON `effects` (kinematic findings among them). False discoveries: every "
         "name but the truth's on an effect case, and every name on a null.",
         "Unsettled with: the rivals the CLI's JSON reports beside what it named that the recording cannot tell "
         "from it (not separable: UNSETTLED in its answer), shown where the named effect is exact too.",
         "Truth as given: `twin diagnose LOG.csv --vessel yellowfish --given TRUTH` (TRUTH the library's terms of "
         "the truth column), nothing fitted, judged by the rule the diagnosis names an effect by (z ≥ 3 of the "
         "held-out blocks' votes and 5 % of the held-out misfit above the noise): whether the recording can prove "
         "the truth in the library's form at all. A miss where it cannot is the data's or the form's; a fitted "
         "form may still do better than the given one."],
        {"commit": commit, "summary": s, "rows": rows, "cases": [asdict(c) for c in SETS[proof_set]],
         **({"compared": compared} if compared else {})})
    return page.write(out)


def with_unsettled(row: dict, work: Path) -> dict:
    """The row with its diagnosis's unsettled rivals, read from the CLI's JSON in `work` where the row
    was written without them and that JSON names what the row does (it is that diagnosis's)."""
    found = work / f"{row['case']}.diagnosis.json"
    if "unsettled" in row or row.get("failed") or not found.is_file():
        return row
    diagnosis = json.loads(found.read_text())
    if [e["name"] for e in diagnosis.get("effects", [])] != [e["name"] for e in row["named"]]:
        return row
    return {**row, "unsettled": unsettled_rivals(diagnosis)}


def page_name(proof_set: str) -> str:
    return "blind_truths" if proof_set == "first" else f"blind_truths_{proof_set}"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--set", default="first", choices=list(SETS), help="the proof set (each fixed before it was run)")
    ap.add_argument("--work", type=Path, default=None, help="logs, the CLI's JSON and console (default "
                                                           "/tmp/blind_truths, /tmp/blind_truths_SET)")
    ap.add_argument("--only", default="", help="these cases only (comma separated); the page is not rewritten")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "results")
    ap.add_argument("--page-only", action="store_true", help="rewrite the page from the rows in --work")
    ap.add_argument("--truth-given", action="store_true",
                    help="judge each case's truth as given (twin diagnose --given) beside the diagnosis already run "
                         "(rows from --work, else from the page's raw figures), and rewrite the page")
    ap.add_argument("--compare", type=Path, default=None,
                    help="the raw figures (data/blind_truths_SET.json) of the same set diagnosed at another commit, "
                         "shown beside this run's")
    ap.add_argument("--compare-label", default="", help="what that commit's diagnosis did otherwise")
    args = ap.parse_args()
    cases = SETS[args.set]
    args.work = args.work or Path("/tmp/blind_truths" + ("" if args.set == "first" else f"_{args.set}"))
    args.work.mkdir(parents=True, exist_ok=True)
    if args.truth_given:
        hull, commit = hull_of(vessel_mod.load(VESSEL)), checkout_commit(ROOT)
        published = args.out / "data" / f"{page_name(args.set)}.json"
        kept = {r["case"]: r for r in json.loads(published.read_text())["rows"]} if published.is_file() else {}
        for case in cases:
            path = args.work / f"{case.name}.row.json"
            row = json.loads(path.read_text()) if path.is_file() else kept[case.name]
            row = judge_truth(case, hull, row, args.work, commit)
            path.write_text(json.dumps(row, indent=1))
            print(f"{case.name}: truth as given {given_cell(row.get('given'))}", flush=True)
        if not (args.work / "commit.txt").is_file() and published.is_file():
            (args.work / "commit.txt").write_text(json.loads(published.read_text())["commit"])
    elif not args.page_only:
        hull = hull_of(vessel_mod.load(VESSEL))
        only = {x for x in args.only.split(",") if x}
        for case in cases:
            if only and case.name not in only:
                continue
            row = run_case(case, hull, args.work)
            (args.work / f"{case.name}.row.json").write_text(json.dumps(row, indent=1))
            print(f"{case.name}: named {', '.join(e['name'] for e in row['named']) or 'nothing'}; exact {row['exact']} "
                  f"({row['seconds']} s)", flush=True)
        if only:
            return 0
        (args.work / "commit.txt").write_text(checkout_commit(ROOT))
    published = args.out / "data" / f"{page_name(args.set)}.json"
    kept = {r["case"]: r for r in json.loads(published.read_text())["rows"]} if published.is_file() else {}
    missing = [c.name for c in cases if not (args.work / f"{c.name}.row.json").is_file() and c.name not in kept]
    if missing:
        print(f"error: no row for {', '.join(missing)} in {args.work} or {published}: run the set first", file=sys.stderr)
        return 2
    # rows from --work, else the page's raw figures (a rewrite of a published set)
    rows = [with_unsettled(json.loads((args.work / f"{c.name}.row.json").read_text()), args.work)
            if (args.work / f"{c.name}.row.json").is_file() else kept[c.name] for c in cases]
    commit_file = args.work / "commit.txt"
    commit = (commit_file.read_text().strip() if commit_file.is_file() else
              json.loads(published.read_text())["commit"] if published.is_file() else checkout_commit(ROOT))
    if args.compare:
        other = json.loads(args.compare.read_text())
        compared = {"label": args.compare_label, "commit": other["commit"], "rows": other["rows"]}
    else:  # a rewrite keeps what the page compared with
        compared = json.loads(published.read_text()).get("compared") if published.is_file() else None
    print(write_page(rows, commit, args.out, args.set, compared))
    return 0


if __name__ == "__main__":
    sys.exit(main())
