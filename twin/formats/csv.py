"""The generic CSV layout, read and written, and the twin's own run CSV.

Generic CSV (one header line, comma separated, empty or "nan" cells are missing):
  t                  s, any origin, increasing
  lat, lon           deg (WGS-84, antenna)     -- or --   north, east   m (local NED)
                                               -- or --   x, y          m, north, east of the body
                                                          origin (`twin simulate --out run.csv`)
  alt                m (optional, with lat/lon)
  heading_deg        deg from north to east    -- or --   psi           rad
  pwm_left, pwm_right   µs, forward thrust = higher PWM (optional)
  pwm_neutral_left, pwm_neutral_right   µs, the PWM of zero thrust (optional, default 1500)
  yaw_rate           rad/s, gyro (optional; a twin run's r is read as one)
  voltage            V, battery (optional)
  prop_rps, rudder_deg   a propeller-and-rudder ship's inputs: rps (> 0 ahead), degrees (> 0 turns to
                     starboard) (optional, the prop_rudder stream)
  wind_speed, wind_from_deg   true wind over ground, m/s and degrees FROM, clockwise from north
  wind_rel_speed, wind_rel_from_deg   apparent wind on board, m/s and degrees FROM, clockwise from the bow
                     (optional, the wind stream; the relative pair only with the true one)
The columns of a pair (lat, lon; north, east; x, y; pwm_left, pwm_right; prop_rps, rudder_deg; each wind
pair) are read together: a file with one of a pair is refused, naming the other.
A twin run's u, v (its true velocities) and thrust_left/right are not read: a
Recording holds what sensors log. Streams at different rates share the rows.
`channels={"reversed": {"left": True}, "trim": {"left": 1500, "right": 1500}}` mirrors
a reversed channel and sets the neutral.

Written: the columns of the streams that have samples, one row per distinct sample
time (µs) of any stream, an empty cell where a stream has no sample at that time.
t %.6f s, lat/lon %.10f deg, alt %.4f m, north/east %.6f m, heading_deg %.7f in
[0, 360), pwm %.10g µs (integers stay integers), yaw_rate %.9f rad/s, voltage %.4f V,
prop_rps %.10g, rudder_deg %.10g, wind speeds %.6f m/s, wind directions %.6f deg.
The PWM neutral columns are written on the PWM rows only when it is not 1500 µs.
"""
from __future__ import annotations

import csv
import re
from pathlib import Path
from typing import Callable

import numpy as np

from ..errors import TwinError
from ..files import check_unique_columns, write_bytes_atomic, write_stream_atomic
from ..geodesy import ned_from_geodetic
from ..recording import EXACT_ORIGIN, Recording, Stream, clean_stream, with_common_origin

CSV_NEUTRAL_US = 1500.0


Layout = Callable[[Path, list[str], dict[str, np.ndarray], dict | None], Recording]
# the generic layout's columns read only together: a file with one of them would lose its stream unsaid
PAIRS = (("lat", "lon"), ("north", "east"), ("x", "y"), ("pwm_left", "pwm_right"), ("prop_rps", "rudder_deg"),
         ("wind_speed", "wind_from_deg"), ("wind_rel_speed", "wind_rel_from_deg"))
# every column the generic layout reads (a twin run's u, v, thrust_left/right are known and left)
GENERIC_COLUMNS = frozenset({"t", "alt", "heading_deg", "psi", "pwm_neutral_left", "pwm_neutral_right", "yaw_rate", "r",
                             "voltage", "u", "v", "thrust_left", "thrust_right"} | {c for pair in PAIRS for c in pair})
# where a generic CSV gives the streams prepare() needs: what to say of a file without them
NEEDED_COLUMNS = {"GNSS": "GNSS in columns lat,lon or north,east", "heading": "the heading in a column heading_deg or psi"}


def read_csv(path: Path, channels: dict | None = None, adapters: tuple[tuple[Callable, Layout], ...] = (),
             known: tuple[tuple[str, frozenset], ...] = ()) -> Recording:
    """Read a CSV recording: the first adapter whose `matches(header)` holds reads the columns
    (a dataset's own layout, e.g. blueboat_csv), else the generic layout (module docstring).
    `known`: (name, columns it needs) of each dataset layout, so that a file that holds most of one's
    columns is told which it lacks."""
    header, cols, defects = table(path)
    reader = next((read for matches, read in adapters if matches(header)), None)
    if reader is not None:
        rec = reader(path, header, cols, channels)
    elif "t" in header:
        rec = _generic(path, header, cols, channels)
    else:
        raise TwinError(f"{path.name}: {_unrecognised(header, known)}")
    rec.dropped[:0] = [(what, n) for what, n in defects if n]
    if not any(len(s) for s in rec.streams().values()):
        raise TwinError(f"{path.name}: no usable rows")
    return with_common_origin(rec)


def _unrecognised(header: list[str], known: tuple[tuple[str, frozenset], ...]) -> str:
    """Why no layout reads a header: the known layout it comes nearest (half its columns or more),
    and what it lacks; else what a layout needs."""
    have = set(header)
    near = [(len(cols - have), name, cols - have) for name, cols in known if len(cols & have) >= len(cols) / 2]
    if near:
        _, name, missing = min(near, key=lambda x: x[0])
        plural = "s" if len(missing) > 1 else ""
        return f"looks like {name} layout but lacks the column{plural} {', '.join(sorted(missing))}"
    return "CSV layout not recognised (need a 't' column or a known dataset's columns)"


def table(path: Path) -> tuple[list[str], dict[str, np.ndarray], list[tuple[str, int]]]:
    """Header, float columns (a cell that is not a finite number → NaN) and what was read as missing
    though the file had something there: (what, count) for the recording's `dropped`."""
    try:
        text = path.read_text(encoding="utf-8-sig", errors="replace")  # -sig: a spreadsheet's BOM
    except OSError as exc:
        raise TwinError(f"{path.name}: cannot read ({exc.strerror or exc})") from None
    rows, quoted = _rows(text)
    if not rows:
        raise TwinError(f"{path.name}: empty CSV file")
    if rows[0] is None:
        raise TwinError(f"{path.name}: the header line cannot be read as CSV (a quote character that does not "
                        f"close on it, or a field over {csv.field_size_limit() // 1024} kB)")
    header = [h.strip() for h in rows[0]]
    check_unique_columns(header, path.name)
    good = [r for r in rows[1:] if r is not None and len(r) == len(header)]
    malformed = sum(1 for r in rows[1:] if r and len(r) != len(header))
    named = [i for i, name in enumerate(header) if name]
    cells = np.array([[_float(r[i]) for i in named] for r in good], dtype=float).reshape(len(good), len(named))
    # a blank cell or a written NaN is a logger's "no sample": not something misread
    blank = np.array([[r[i].strip().lower() in ("", "nan") for i in named] for r in good], bool).reshape(cells.shape)
    text_cells = int(np.sum(np.isnan(cells) & ~blank))
    infinite = int(np.sum(np.isinf(cells)))
    empty_rows = int(np.sum(blank.all(axis=1))) if len(named) else 0
    cells[np.isinf(cells)] = np.nan
    cols = {header[i]: cells[:, j] for j, i in enumerate(named)}
    return header, cols, [*quoted, ("csv: rows with the wrong number of fields", malformed),
                          ("csv: rows with no value in any column", empty_rows),
                          ("csv: cells that are not numbers (text), read as missing", text_cells),
                          ("csv: infinite cells, read as missing", infinite)]


LINE_END = re.compile(r"\r\n|\r|\n")  # where the csv module ends a row


def _rows(text: str) -> tuple[list[list[str] | None], list[tuple[str, int]]]:
    """The rows of a CSV text, one per line ([] for a blank line, None for a line the csv module cannot
    read), and (what, count) of those unread lines. A row never runs on past its line: a stray quote
    (a logger's cut line, a damaged byte) would otherwise take every row after it into one field, which
    these logs never hold. A line with a quote is read by the csv module on its own (quoted fields are
    unquoted); one whose quote does not close on it, or whose field is over the module's limit (128 kB),
    is left out and counted."""
    lines = LINE_END.split(text)
    if lines and lines[-1] == "":  # the last line's own end
        lines.pop()
    rows: list[list[str] | None] = []
    unclosed = oversized = 0
    for line in lines:
        if '"' not in line:
            rows.append(line.split(",") if line else [])
            continue
        try:
            rows.append(next(csv.reader([line], strict=True), []))
        except csv.Error as exc:
            rows.append(None)
            if "field larger" in str(exc):
                oversized += 1
            else:
                unclosed += 1
    return rows, [("csv: rows with a stray quote character (one that does not close a field on its line), left out", unclosed),
                  (f"csv: rows with a quoted field over {csv.field_size_limit() // 1024} kB, left out", oversized)]


HELD_SHARE = 0.10  # a receiver's fixes differ by its noise even at rest: this many exact repeats are held ones


def held_fix_note(gnss: Stream) -> str:
    """A note when many rows repeat the previous fix exactly (a slower receiver's fixes held on a
    faster grid, as `twin convert --grid-dt` writes them), else ""."""
    names = [n for n in ("lat_deg", "lon_deg", "north_m", "east_m") if n in gnss.columns]
    if len(gnss) < 3 or not names:
        return ""
    same = float(np.mean(np.all([np.diff(np.asarray(gnss[n], float)) == 0 for n in names], axis=0)))
    return f"GNSS: {100 * same:.0f}% of the rows repeat the previous fix (a slower receiver held on the rows)" \
        if same >= HELD_SHARE else ""


def _float(s: str) -> float:
    try:
        return float(s)
    except ValueError:
        return np.nan


def _generic(path: Path, header: list[str], c: dict[str, np.ndarray], channels: dict | None) -> Recording:
    """Multi-rate streams share the rows: a row whose cells of one stream are all empty
    is simply not a sample of it (only partly filled rows count as dropped)."""
    for first, second in PAIRS:
        if (first in c) != (second in c):
            has, lacks = (first, second) if first in c else (second, first)
            raise TwinError(f"{path.name}: has {has} but no {lacks} column")
    rec = Recording(source=str(path), kind="csv")
    t = c["t"]
    if {"lat", "lon"} <= set(header):
        gnss = {"lat_deg": c["lat"], "lon_deg": c["lon"]} | ({"alt_m": c["alt"]} if "alt" in c else {})
    elif {"north", "east"} <= set(header):
        gnss = {"north_m": c["north"], "east_m": c["east"]}
    elif {"x", "y"} <= set(header):
        gnss = {"north_m": c["x"], "east_m": c["y"]}
        rec.meta["positions"] = EXACT_ORIGIN
        rec.notes.append("positions x, y are north, east of the body origin (a twin run): no lever arm to apply")
        states = [c for c in ("u", "v", "thrust_left", "thrust_right") if c in header]
        if states:  # what a recording's sensors would not give: a copy of the run as a log leaves them out
            rec.notes.append(f"the run's own {', '.join(states)} (the twin's states and thrusts, which no sensor "
                             "logs) are not read")
    else:
        gnss = None
        rec.notes.append("no GNSS: no lat/lon, north/east or x/y columns")
    if gnss is not None:
        rec.gnss = stream("gnss", t, gnss, rec.dropped)
        if rec.meta.get("positions") != EXACT_ORIGIN:  # a receiver's, not a twin run's exact track
            held = held_fix_note(rec.gnss)
            if held:
                rec.notes.append(held)
    by_lower = {n.lower(): n for n in GENERIC_COLUMNS}
    cased = [f"{h} (read as {by_lower[h.lower()]} only when named so)" for h in header
             if h not in GENERIC_COLUMNS and h.lower() in by_lower and by_lower[h.lower()] not in header]
    if cased:  # a column name differing only in case is not read: say so, or a missing stream looks unexplained
        rec.notes.append(f"columns not read, names being case-sensitive: {', '.join(cased)}")
    psi = np.radians(c["heading_deg"]) if "heading_deg" in c else c.get("psi")
    if psi is not None:
        rec.heading = stream("heading", t, {"psi_rad": psi}, rec.dropped)
    else:
        rec.notes.append("no heading: no heading_deg or psi column")
    for used, also in (("lat, lon", "north, east" if {"north", "east"} <= set(header) else "x, y"),
                       ("north, east", "x, y"), ("heading_deg", "psi")):
        first = set(used.split(", "))
        if first <= set(header) and set(also.split(", ")) <= set(header):
            rec.warnings.append(f"both {used} and {also} columns: {used} read, {also} not")
    steps = np.diff(np.unique(t[np.isfinite(t)]))
    if len(steps) >= 100 and np.median(steps) > 5.0:
        rec.misread.append(f"t steps by {np.median(steps):g} s (median): the generic CSV's t is in seconds; "
                           "milliseconds would read as this")
    if "heading_deg" in c and len(rec.heading) and len(rec.gnss):
        rate_column = "yaw_rate" if "yaw_rate" in c else ("r" if "r" in c else None)
        looks = radians_as_degrees(np.degrees(rec.heading["psi_rad"]), rec.gnss, t=rec.heading.t,
                                   yaw_rate=(t, c[rate_column], f"the yaw rate column {rate_column}") if rate_column
                                   else None)
        if looks:
            rec.misread.append(looks)
    if {"pwm_left", "pwm_right"} <= set(header):
        neutral_us = tuple(neutral(c.get(f"pwm_neutral_{side}"), 1500.0, f"{path.name}: column pwm_neutral_{side}")
                           for side in ("left", "right"))
        csv_pwm(rec, t, c["pwm_left"], c["pwm_right"], neutral_us, {"left": False, "right": False}, channels)
    yaw_rate = c.get("yaw_rate", c.get("r"))
    if yaw_rate is not None:
        rec.imu = stream("imu", t, {"yaw_rate_rads": yaw_rate}, rec.dropped)
    if "psi" in c and "heading_deg" not in c:
        looks = degrees_as_radians("psi", rec.heading, rec.imu,
                                   f"the yaw rate column {'yaw_rate' if 'yaw_rate' in c else 'r'}", gnss=rec.gnss)
        if looks:
            rec.misread.append(looks)
    if "voltage" in c:
        rec.battery = stream("battery", t, {"voltage_v": c["voltage"]}, rec.dropped)
    if {"prop_rps", "rudder_deg"} <= set(header):
        rec.prop_rudder = stream("prop_rudder", t, {"n_rps": c["prop_rps"], "delta_rad": np.radians(c["rudder_deg"])},
                                 rec.dropped)
    if {"wind_speed", "wind_from_deg"} <= set(header):
        cols = {"speed_m_s": c["wind_speed"], "from_deg": c["wind_from_deg"]}
        if {"wind_rel_speed", "wind_rel_from_deg"} <= set(header):
            cols |= {"relative_speed_m_s": c["wind_rel_speed"], "relative_from_deg": c["wind_rel_from_deg"]}
        rec.wind = stream("wind", t, cols, rec.dropped)
    return rec


RADIANS_SPAN = 7.0  # a heading in radians spans at most 2π (6.28), in [0, 2π) or in ±π
TRACK_TURN_DEG = 90.0  # a track turning through more than this shows a turning vessel, beyond its noise
TRACK_STEP_M = 2.0  # course over ground from fixes this far apart: closer ones are the receiver's noise


def radians_as_degrees(heading_deg: np.ndarray, gnss, column: str = "heading_deg",
                       advice: str = "name it psi for radians, or give degrees", t=None,
                       yaw_rate: tuple[np.ndarray, np.ndarray, str] | None = None) -> str | None:
    """A warning when a heading column in degrees (`column`) looks like radians: its values span less than
    RADIANS_SPAN while the GNSS track turns through more than TRACK_TURN_DEG (a heading in degrees that
    turns with it spans as much), or (with the sample times `t`) while they step by 2π where they wrap, or
    a yaw rate the log holds (`yaw_rate`: its times s, its rad/s and its column's name; a gyro or an
    estimate, read for this check only) turns GYRO_RATIO times as fast as the heading, or the course over
    ground follows them read as radians and not as degrees (course_misfit_deg); None when nothing
    suggests it."""
    heading_deg = np.asarray(heading_deg, float)
    span = float(np.ptp(heading_deg)) if len(heading_deg) else 0.0
    if span >= RADIANS_SPAN:
        return None
    looks = f": the column looks like radians ({advice})"
    turned = track_turn_deg(gnss)
    if turned > TRACK_TURN_DEG:
        return f"{column} spans only {span:.2f} while the GNSS track turns through {turned:.0f}°{looks}"
    if t is None:
        return None
    step = np.diff(heading_deg)
    wrap = (np.abs(step) >= RADIAN_WRAP[0]) & (np.abs(step) <= RADIAN_WRAP[1])
    back = np.zeros(len(step), bool)  # a spike out and back is not a wrap: a wrap goes on from the other end
    back[:-1] = wrap[:-1] & wrap[1:] & (np.sign(step[1:]) != np.sign(step[:-1]))
    back[1:] |= back[:-1] & wrap[1:]
    wraps = int(np.sum(wrap & ~back))
    if wraps:
        return f"{column} spans only {span:.2f} and steps by about 2π where it wraps ({wraps} time{'s' * (wraps != 1)}){looks}"
    if yaw_rate is not None:
        ratio = _turn_ratio(np.radians(heading_deg), np.asarray(t, float), *yaw_rate[:2])
        if ratio is not None and ratio < 1.0 / GYRO_RATIO:
            return (f"{yaw_rate[2]} turns {1.0 / max(ratio, 1e-9):.0f} times as fast as {column} read as degrees "
                    f"(spanning only {span:.2f}){looks}")
    as_read, as_radians = (course_misfit_deg(np.radians(heading_deg) * k, t, gnss) for k in (1.0, np.degrees(1.0)))
    if as_read > COURSE_MISFIT_DEG[1] and as_radians < COURSE_MISFIT_DEG[0]:
        return (f"the course over ground lies {as_read:.0f}° from {column} (median) and {as_radians:.0f}° from it read as "
                f"radians{looks}")
    return None


RADIAN_WRAP = (5.5, 7.0)  # a heading in radians read as degrees wraps by 2π "degrees", where one in degrees wraps by 360
# the course over ground lies within a few degrees of a hull's heading under way (the shared logs: 1-9°, median):
# a heading that lies further than the second from it as read, and within the first in another unit, is in that unit
COURSE_MISFIT_DEG = (30.0, 60.0)
COURSE_SPEED_M_S = 0.2  # under way: slower fixes' course is the receiver's noise or a drift
COURSE_SAMPLES = 10


def course_misfit_deg(psi_rad: np.ndarray, t: np.ndarray, gnss) -> float:
    """The median angle (deg) between the course over ground (fixes TRACK_STEP_M apart, under way at over
    COURSE_SPEED_M_S) and the heading `psi_rad` at times `t` between them; NaN with fewer than
    COURSE_SAMPLES such courses."""
    if len(gnss) < 3 or len(t) < 2:
        return float("nan")
    if gnss.has("lat_deg", "lon_deg"):
        north, east = ned_from_geodetic(gnss["lat_deg"], gnss["lon_deg"], float(gnss["lat_deg"][0]),
                                        float(gnss["lon_deg"][0]))
    elif gnss.has("north_m", "east_m"):
        north, east = gnss["north_m"], gnss["east_m"]
    else:
        return float("nan")
    keep = [0]
    for k in range(1, len(north)):
        if np.hypot(north[k] - north[keep[-1]], east[k] - east[keep[-1]]) >= TRACK_STEP_M:
            keep.append(k)
    if len(keep) < COURSE_SAMPLES + 1:
        return float("nan")
    at = np.asarray(gnss.t, float)[keep]
    dn, de, dt = np.diff(np.asarray(north)[keep]), np.diff(np.asarray(east)[keep]), np.diff(at)
    moving = np.hypot(dn, de) / dt > COURSE_SPEED_M_S
    mid = ((at[1:] + at[:-1]) / 2)[moving]
    inside = (mid >= t[0]) & (mid <= t[-1])
    if inside.sum() < COURSE_SAMPLES:
        return float("nan")
    heading = np.interp(mid[inside], t, np.unwrap(np.asarray(psi_rad, float)))
    return float(np.degrees(np.median(np.abs(np.angle(np.exp(1j * (np.arctan2(de, dn)[moving][inside] - heading)))))))


# a heading in degrees read as radians: it wraps by 360 (a heading in radians never steps by hundreds of
# radians, unwrapped or not), turns 57 times as fast as it does, faster than any hull turns
DEGREE_WRAP = (300.0, 420.0)
FASTEST_TURN_RAD_S = 4 * np.pi  # 2 rev/s: no vessel's heading turns so fast (the shared logs' reach 1.5 rad/s)
GYRO_RATIO = 15.0  # the heading's turn over the gyro's: about 1 in radians (at most 4 in the shared logs), 57 in degrees
GYRO_TURNING_RADS = 0.005  # the gyro's rms rate that shows some turning to compare with (0.3 °/s)
GYRO_SAMPLES = 20


def degrees_as_radians(column: str, heading: Stream, imu: Stream | None = None, imu_column: str = "the gyro",
                       advice: str = "name it heading_deg for degrees, or give radians", gnss=None) -> str | None:
    """Why a heading column in radians (`column`, read into `heading`) looks like degrees, or None: it steps
    by about 360 where it wraps; it turns (its 99th-percentile rate, its steps taken within ±π) faster than
    FASTEST_TURN_RAD_S; it turns GYRO_RATIO times as fast as the yaw rate `imu` measures; or the course over
    ground follows it read as degrees and not as radians (course_misfit_deg)."""
    psi, t = np.asarray(heading["psi_rad"], float) if len(heading) else np.zeros(0), np.asarray(heading.t, float)
    if len(psi) < 3:
        return None
    looks = f": the column looks like degrees ({advice})"
    step = np.diff(psi)
    wraps = int(np.sum((np.abs(step) >= DEGREE_WRAP[0]) & (np.abs(step) <= DEGREE_WRAP[1])))
    if wraps and np.ptp(psi) <= DEGREE_WRAP[1]:
        return f"{column} steps by about 360 where it wraps ({wraps} time{'s' if wraps != 1 else ''}){looks}"
    rate = np.angle(np.exp(1j * step)) / np.diff(t)  # a heading in radians wrapping at 2π: no turn
    fastest = float(np.percentile(np.abs(rate), 99))
    if fastest > FASTEST_TURN_RAD_S:
        return (f"{column} read as radians turns at {np.degrees(fastest):.0f}°/s (99th percentile of its rate), "
                f"faster than any vessel{looks}")
    if imu is not None:
        ratio = _turn_ratio(psi, t, imu.t, imu["yaw_rate_rads"])
        if ratio is not None and ratio > GYRO_RATIO:
            return f"{column} read as radians turns {ratio:.0f} times as fast as {imu_column} measures{looks}"
    if gnss is not None:
        as_read, as_degrees = (course_misfit_deg(psi * k, t, gnss) for k in (1.0, np.radians(1.0)))
        if as_read > COURSE_MISFIT_DEG[1] and as_degrees < COURSE_MISFIT_DEG[0]:
            return (f"the course over ground lies {as_read:.0f}° from {column} (median) and {as_degrees:.0f}° from it "
                    f"read as degrees{looks}")
    return None


def _turn_ratio(psi_rad: np.ndarray, t_s: np.ndarray, rate_t_s, rate_rad_s) -> float | None:
    """How fast the heading psi_rad (at t_s) turns against a yaw rate (rad/s at rate_t_s), least squares over
    the heading's steps taken within ±π (about 1 in matching units); None where the rate shows too little
    turning or too few samples to compare with."""
    rate_t_s, rate_rad_s = np.asarray(rate_t_s, float), np.asarray(rate_rad_s, float)
    ok = np.isfinite(rate_t_s) & np.isfinite(rate_rad_s)
    rate_t_s, rate_rad_s = rate_t_s[ok], rate_rad_s[ok]
    if len(rate_t_s) < GYRO_SAMPLES or len(t_s) < 3:
        return None
    turn = np.angle(np.exp(1j * np.diff(psi_rad))) / np.diff(t_s)
    mid = (t_s[1:] + t_s[:-1]) / 2
    inside = (mid >= rate_t_s[0]) & (mid <= rate_t_s[-1]) & np.isfinite(turn)
    gyro = np.interp(mid[inside], rate_t_s, rate_rad_s)
    if inside.sum() < GYRO_SAMPLES or np.sqrt(np.mean(gyro ** 2)) < GYRO_TURNING_RADS:
        return None
    return float(np.sum(turn[inside] * gyro) / np.sum(gyro ** 2))


def track_turn_deg(gnss) -> float:
    """How far (deg) the course over ground turns, end to end of its unwrapped range, from fixes at
    least TRACK_STEP_M apart."""
    if gnss.has("lat_deg", "lon_deg"):
        north, east = ned_from_geodetic(gnss["lat_deg"], gnss["lon_deg"], float(gnss["lat_deg"][0]),
                                        float(gnss["lon_deg"][0]))
    else:
        north, east = gnss["north_m"], gnss["east_m"]
    keep = [0]
    for k in range(1, len(north)):  # thin the fixes to steps longer than the receiver's noise
        if np.hypot(north[k] - north[keep[-1]], east[k] - east[keep[-1]]) >= TRACK_STEP_M:
            keep.append(k)
    if len(keep) < 3:
        return 0.0
    course = np.unwrap(np.arctan2(np.diff(east[keep]), np.diff(north[keep])))
    return float(np.degrees(np.ptp(course)))


def stream(name: str, t: np.ndarray, cols: dict, dropped: list):
    """clean_stream on the rows that hold at least one cell of this stream."""
    present = np.zeros(len(t), bool)
    for v in cols.values():
        present |= np.isfinite(v)
    return clean_stream(name, t[present], {k: v[present] for k, v in cols.items()}, dropped)


NEUTRAL_RANGE_US = (1000.0, 2000.0)  # where an RC/ESC pulse of zero thrust lies (servo pulses run 1000-2000 µs)


def neutral(col, default: float, name: str = "column pwm_neutral") -> float:
    """A PWM neutral column's value (its median), the default without one; a column that holds no
    number, or a neutral outside NEUTRAL_RANGE_US (a unit slip, a typo), is refused: it mirrors a
    reversed channel and tells idle from driven."""
    if col is None:
        return default
    if not np.any(np.isfinite(col)):
        raise TwinError(f"{name} holds no number: give the PWM of zero thrust in µs, or leave the column out "
                        f"({default:g} µs)")
    value = float(np.nanmedian(col))
    if not NEUTRAL_RANGE_US[0] <= value <= NEUTRAL_RANGE_US[1]:
        raise TwinError(f"{name} is {value:g} µs: a PWM of zero thrust lies between {NEUTRAL_RANGE_US[0]:g} and "
                        f"{NEUTRAL_RANGE_US[1]:g} µs")
    return value


def csv_pwm(rec: Recording, t, left, right, neutral, reversed_: dict, channels: dict | None) -> None:
    """PWM stream, mirrored around the neutral where the channel is reversed."""
    if channels is not None:
        if not isinstance(channels, dict) or set(channels) - {"reversed", "trim"}:
            raise TwinError("for a CSV recording, channels may only hold 'reversed' and 'trim'")
        reversed_ = reversed_ | {k: bool(v) for k, v in dict(channels.get("reversed") or {}).items()}
        trim = dict(channels.get("trim") or {})
        neutral = (float(trim.get("left", neutral[0])), float(trim.get("right", neutral[1])))
    cols = {}
    for side, pwm, n in (("left", left, neutral[0]), ("right", right, neutral[1])):
        cols[f"{side}_us"] = 2 * n - pwm if reversed_.get(side) else pwm
    rec.pwm = stream("pwm", t, cols, rec.dropped)
    rec.pwm_neutral_us = (float(neutral[0]), float(neutral[1]))
    rec.channels = {"reversed": {k: bool(reversed_.get(k)) for k in ("left", "right")},
                    "trim": {"left": neutral[0], "right": neutral[1]}, "from": rec.kind}


def csv_text(rec: Recording) -> str:
    """The generic CSV layout of a file-ready recording (times ≥ 0)."""
    cells = _csv_cells(rec)
    micros = {name: _micros(name, s.t) for name, s in rec.streams().items() if len(s)}
    rows_us = np.unique(np.concatenate(list(micros.values())))
    table = np.full((len(rows_us), len(cells) + 1), "", dtype=object)
    table[:, 0] = [f"{us // 1_000_000}.{us % 1_000_000:06d}" for us in rows_us.tolist()]
    for j, (_, name, text) in enumerate(cells, start=1):
        table[np.searchsorted(rows_us, micros[name]), j] = text
    lines = [",".join(["t"] + [header for header, _, _ in cells])]
    lines += [",".join(row) for row in table.tolist()]
    return "\n".join(lines) + "\n"


def _micros(name: str, t: np.ndarray) -> np.ndarray:
    us = np.round(t * 1e6).astype(np.int64)
    if np.any(np.diff(us) <= 0):
        raise TwinError(f"csv: two {name} samples less than 1 µs apart (the layout's time resolution)")
    return us


def _csv_cells(rec: Recording) -> list[tuple[str, str, np.ndarray]]:
    """(header, stream, formatted values) of every column, in the layout's order."""
    g, h, p, imu, bat = rec.gnss, rec.heading, rec.pwm, rec.imu, rec.battery
    out = []
    if len(g) and g.has("lat_deg", "lon_deg"):
        out += [("lat", "gnss", _fmt("%.10f", g["lat_deg"])), ("lon", "gnss", _fmt("%.10f", g["lon_deg"]))]
        if "alt_m" in g.columns:
            out.append(("alt", "gnss", _fmt("%.4f", g["alt_m"])))
    elif len(g):
        # a run's exact track of the body origin keeps the run layout's x, y, which say so when read back
        exact = rec.meta.get("positions") == EXACT_ORIGIN
        out += [("x" if exact else "north", "gnss", _fmt("%.6f", g["north_m"])),
                ("y" if exact else "east", "gnss", _fmt("%.6f", g["east_m"]))]
    if len(h):
        out.append(("heading_deg", "heading", _fmt("%.7f", np.degrees(h["psi_rad"]) % 360.0)))
    if len(p):
        out += [("pwm_left", "pwm", _fmt("%.10g", p["left_us"])), ("pwm_right", "pwm", _fmt("%.10g", p["right_us"]))]
        if any(n != CSV_NEUTRAL_US for n in rec.pwm_neutral_us):  # the layout's default neutral needs no column
            out += [(f"pwm_neutral_{side}", "pwm", _fmt("%.10g", np.full(len(p), n)))
                    for side, n in zip(("left", "right"), rec.pwm_neutral_us)]
    if len(imu):
        out.append(("yaw_rate", "imu", _fmt("%.9f", imu["yaw_rate_rads"])))
    if len(bat):
        out.append(("voltage", "battery", _fmt("%.4f", bat["voltage_v"])))
    pr, w = rec.prop_rudder, rec.wind
    if len(pr):
        out += [("prop_rps", "prop_rudder", _fmt("%.10g", pr["n_rps"])),
                ("rudder_deg", "prop_rudder", _fmt("%.10g", np.degrees(pr["delta_rad"])))]
    if len(w):
        out += [("wind_speed", "wind", _fmt("%.6f", w["speed_m_s"])),
                ("wind_from_deg", "wind", _fmt("%.6f", w["from_deg"]))]
        if w.has("relative_speed_m_s", "relative_from_deg"):
            out += [("wind_rel_speed", "wind", _fmt("%.6f", w["relative_speed_m_s"])),
                    ("wind_rel_from_deg", "wind", _fmt("%.6f", w["relative_from_deg"]))]
    return out


def _fmt(spec: str, values: np.ndarray) -> np.ndarray:
    return np.char.mod(spec, np.asarray(values, dtype=float)).astype(object)


def write_recording_csv(rec: Recording, path: Path) -> None:
    """A file-ready recording (times ≥ 0) in the generic layout, atomically."""
    write_bytes_atomic(path, csv_text(rec).encode())


def write_run_csv(run, path: Path) -> None:
    """A twin run (twin.run.Run) in the run layout t,x,y,psi,u,v,r,pwm_*,thrust_*, atomically."""
    def fill(fh) -> None:
        for block in run.csv_blocks():
            fh.write(block.encode())
    write_stream_atomic(path, fill)
