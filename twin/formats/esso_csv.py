"""The Esso Osaka 3 m model's free-running tests (Osaka University, [ESSO-FRT], 10 Hz
CSV), an adapter onto the generic CSV reader: its columns and conventions into a Recording.

Columns (units in the header): t [s]; x_position_mid, y_position_mid [m] (midship in the pond's
earth-fixed frame O0-x0y0, converted from GNSS by the authors); u_velo, vm_velo [m/s]; psi_hat
[rad]; r_angvelo [rad/s]; n_prop [rps]; delta_rudder [rad]; wind_velo_relative_mid [m/s],
wind_dir_relative_mid [rad]; wind_velo_true [m/s], wind_dir_true [rad].

Units, checked on reading: a propeller speed beyond MODEL_PROPELLER_RPS (rpm) or a rudder angle mostly
beyond ±90° (degrees) refuses the file, naming the column; a heading that looks like degrees
(formats.csv.degrees_as_radians) is said as misread (Recording.misread).

Conventions, each checked on the data (tests/test_esso_data.py):
  * x0, y0 are the twin's north, east without a sign change: ψ turns from x0 towards y0, and the
    body velocities differentiated from the positions with the twin's convention match the file's
    u_velo and vm_velo (v to starboard); r = +dψ/dt. So gnss = (north_m, east_m) = (x0, y0) of
    MIDSHIP, which is this ship's body origin: no antenna site applies (meta "positions" =
    TRACKED_ORIGIN: a measured track, so a tracked point found off midship, the sensors'
    antenna_offset_m, still does).
  * n > 0 drives the ship ahead; δ > 0 turns it to starboard (the MMG sign): every turning test's
    steady yaw rate has the sign of its rudder angle. They become the prop_rudder stream.
  * Both wind angles are directions the wind blows FROM, clockwise: the true one from x0 (the
    twin's north), the relative one from the bow; true = apparent + the midship's velocity (to
    2 mm/s rms). The wind stream holds them in degrees, as measured: identification and diagnosis
    use it only when asked.
  * r_angvelo is read as the yaw-rate stream (imu); u_velo, vm_velo are the authors' estimates
    and are not read (prepare() differentiates the positions, as for any log).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import TwinError
from ..recording import TRACKED_ORIGIN, Recording, clean_stream
from .csv import degrees_as_radians

TIME = "t [s]"
NORTH, EAST = "x_position_mid [m]", "y_position_mid [m]"
HEADING, YAW_RATE = "psi_hat [rad]", "r_angvelo [rad/s]"
PROPELLER, RUDDER = "n_prop [rps]", "delta_rudder [rad]"
WIND_TRUE = ("wind_velo_true [m/s]", "wind_dir_true [rad]")
WIND_RELATIVE = ("wind_velo_relative_mid [m/s]", "wind_dir_relative_mid [rad]")
REQUIRED = {TIME, NORTH, EAST, HEADING, PROPELLER, RUDDER}


# a 3-m model's propeller turns at most a few tens of rps (the shared tests' at 10 rps): 50 rps is 3000 rpm, and
# a propeller speed in rpm is over it from 1 rps
MODEL_PROPELLER_RPS = 50.0
RUDDER_DEGREES_SHARE = 0.05  # of the rudder's samples beyond ±90° (read as radians): the column's unit, not a glitch


def _input_units(n, delta) -> list[str]:
    """Why the propeller speed or rudder angle columns look like another unit (rpm, degrees), one line each."""
    out = []
    n, delta = np.asarray(n, float), np.asarray(delta, float)
    n, delta = np.abs(n[np.isfinite(n)]), np.abs(delta[np.isfinite(delta)])
    if len(n) and np.percentile(n, 99) > MODEL_PROPELLER_RPS:
        out.append(f"{PROPELLER} reaches {np.percentile(n, 99):.4g} (99th percentile), beyond the {MODEL_PROPELLER_RPS:g} "
                   "rps a 3-m model's propeller turns: the column looks like rpm (the layout's n_prop is in rps)")
    beyond = float(np.mean(delta > np.pi / 2)) if len(delta) else 0.0
    if beyond >= RUDDER_DEGREES_SHARE:
        out.append(f"{RUDDER} lies beyond ±90° read as radians in {100 * beyond:.0f} % of its samples (up to "
                   f"{delta.max():.4g}): the column looks like degrees (the layout's delta_rudder is in radians)")
    return out


def matches(header) -> bool:
    """True when a CSV header is this layout's (its time, midship position, heading and inputs)."""
    return REQUIRED <= set(header)


def read(path: Path, header: list[str], c: dict[str, np.ndarray], channels: dict | None) -> Recording:
    """The layout's columns `c` (from the CSV reader) as a Recording (module docstring)."""
    rec = Recording(source=str(path), kind="esso-csv")
    if channels is not None:
        rec.notes.append("--channels does not apply: the file logs the propeller speed and rudder angle")
    t = c[TIME]
    rec.gnss = clean_stream("gnss", t, {"north_m": c[NORTH], "east_m": c[EAST]}, rec.dropped)
    rec.meta["positions"] = TRACKED_ORIGIN
    rec.heading = clean_stream("heading", t, {"psi_rad": c[HEADING]}, rec.dropped)
    if YAW_RATE in c:
        rec.imu = clean_stream("imu", t, {"yaw_rate_rads": c[YAW_RATE]}, rec.dropped)
    looks = degrees_as_radians(HEADING, rec.heading, rec.imu if YAW_RATE in c else None, YAW_RATE,
                               "the layout's psi_hat is in radians", gnss=rec.gnss)
    rec.misread += [looks] if looks else []
    slips = _input_units(c[PROPELLER], c[RUDDER])
    if slips:  # unmistakable (beyond any model's propeller, any rudder's stops): every command refuses the log
        raise TwinError(f"{path.name}: {slips[0]}")
    rec.prop_rudder = clean_stream("prop_rudder", t, {"n_rps": c[PROPELLER], "delta_rad": c[RUDDER]}, rec.dropped)
    if set(WIND_TRUE) <= set(c):
        cols = {"speed_m_s": c[WIND_TRUE[0]], "from_deg": np.degrees(c[WIND_TRUE[1]]) % 360.0}
        if set(WIND_RELATIVE) <= set(c):
            cols |= {"relative_speed_m_s": c[WIND_RELATIVE[0]],
                     "relative_from_deg": np.degrees(c[WIND_RELATIVE[1]]) % 360.0}
        rec.wind = clean_stream("wind", t, cols, rec.dropped)
    else:
        rec.notes.append("no wind: the file has no wind_velo_true / wind_dir_true columns")
    rec.notes += [
        "positions: midship in the pond frame, x0 as north and y0 as east (the body origin of esso_osaka: "
        "no antenna site applies; a point tracked off it is the sensors' antenna offset)",
        "inputs: propeller speed n (rps, > 0 ahead) and rudder angle (> 0 turns to starboard)",
        *(["wind: measured (true: from x0 clockwise; relative: from the bow clockwise, both FROM); "
           "used only when asked"] if len(rec.wind) else []),
        "the file's own u_velo/vm_velo are not read; r_angvelo is the yaw-rate stream",
    ]
    return rec
