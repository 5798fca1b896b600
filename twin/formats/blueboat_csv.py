"""The BlueBoat dataset's CSV layout (jankristia/BlueBoatSystemIdentification), an adapter
onto the generic CSV reader: columns original_timestamp (ms since boot), lat, lon, alt,
yaw (deg), thr_left, thr_right (µs), thr_left_pwm_zero_point, thr_right_pwm_zero_point
(µs, neutral, about 1511). The author's surge/sway/yaw_rate estimates are not read.

Its channel labels are swapped and one channel is reversed: the column the dataset calls
thr_left drives the STARBOARD thruster, reversed (1100 µs drives it forward). With thr_left
as port every one of the ten runs turns the wrong way (more "left" thrust yaws to port),
while the tracks follow the heading on straight runs. So thr_right is the port (left)
thruster and thr_left, mirrored around its neutral, the starboard (right) one.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..recording import Recording, clean_stream
from .csv import csv_pwm, held_fix_note, neutral, radians_as_degrees

COLUMNS = {"original_timestamp", "lat", "lon", "yaw", "thr_left", "thr_right"}
NEUTRAL_US = 1500.0 + 11.0  # the recordings' neutral, about 1511 µs


def matches(header) -> bool:
    """True when a CSV header is this layout's."""
    return COLUMNS <= set(header)


def read(path: Path, header: list[str], c: dict[str, np.ndarray], channels: dict | None) -> Recording:
    """The layout's columns `c` (from the CSV reader) as a Recording, thrusters relabelled."""
    rec = Recording(source=str(path), kind="blueboat-csv")
    t = c["original_timestamp"] * 1e-3
    gnss = {"lat_deg": c["lat"], "lon_deg": c["lon"]}
    if "alt" in c:
        gnss["alt_m"] = c["alt"]
    rec.gnss = clean_stream("gnss", t, gnss, rec.dropped)
    rec.heading = clean_stream("heading", t, {"psi_rad": np.radians(c["yaw"])}, rec.dropped)
    if len(rec.heading) and len(rec.gnss):
        # the author's yaw_rate estimate is not read as data, but it tells the yaw column's unit
        rate = (t, c["yaw_rate"], "the yaw_rate column") if "yaw_rate" in c else None
        looks = radians_as_degrees(np.degrees(rec.heading["psi_rad"]), rec.gnss, "yaw", "the layout's yaw is in degrees",
                                   t=rec.heading.t, yaw_rate=rate)
        rec.misread += [looks] if looks else []
    neutral_us = tuple(neutral(c.get(f"thr_{s}_pwm_zero_point"), NEUTRAL_US, f"{path.name}: column thr_{s}_pwm_zero_point")
                       for s in ("right", "left"))
    csv_pwm(rec, t, c["thr_right"], c["thr_left"], neutral_us, {"left": False, "right": True}, channels)
    rec.notes.append("thrusters: port = column thr_right, starboard = column thr_left mirrored (the dataset's "
                     "labels are swapped, which every run's turning shows)")
    held = held_fix_note(rec.gnss)  # rows at 10 Hz from a slower receiver repeat the fix: say how many
    if held:
        rec.notes.append(held)
    rec.notes.append("the file's own surge/sway/yaw_rate estimates are not read")
    return rec


