"""The Esso Osaka 3 m model's free-running tests (Osaka University, [ESSO-FRT], 10 Hz
CSV), an adapter onto the generic CSV reader: its columns and conventions into a Recording.

Columns (units in the header): t [s]; x_position_mid, y_position_mid [m] (midship in the pond's
earth-fixed frame O0-x0y0, converted from GNSS by the authors); u_velo, vm_velo [m/s]; psi_hat
[rad]; r_angvelo [rad/s]; n_prop [rps]; delta_rudder [rad]; wind_velo_relative_mid [m/s],
wind_dir_relative_mid [rad]; wind_velo_true [m/s], wind_dir_true [rad].

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

from ..recording import TRACKED_ORIGIN, Recording, clean_stream

TIME = "t [s]"
NORTH, EAST = "x_position_mid [m]", "y_position_mid [m]"
HEADING, YAW_RATE = "psi_hat [rad]", "r_angvelo [rad/s]"
PROPELLER, RUDDER = "n_prop [rps]", "delta_rudder [rad]"
WIND_TRUE = ("wind_velo_true [m/s]", "wind_dir_true [rad]")
WIND_RELATIVE = ("wind_velo_relative_mid [m/s]", "wind_dir_relative_mid [rad]")
REQUIRED = {TIME, NORTH, EAST, HEADING, PROPELLER, RUDDER}


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
