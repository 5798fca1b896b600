"""read_recording(path): any supported recording → Recording.

The format is decided by content first, then by extension:
  MCAP (magic "\\x89MCAP")        /sensors/* topics (a recording) or a run written by this
                                 project (twin.viz.mcap_io)
  DataFlash (bytes A3 95)        ArduPilot .bin log            → ardupilot.read_dataflash
  tlog (MAVLink marker at byte 8, or extension .tlog)           → ardupilot.read_tlog
  CSV text                       the BlueBoat layout or the generic layout below

BlueBoat CSV (jankristia/BlueBoatSystemIdentification): columns original_timestamp
(ms since boot), lat, lon, alt, yaw (deg), thr_left, thr_right (µs),
thr_left_pwm_zero_point, thr_right_pwm_zero_point (µs, neutral, about 1511). Its left
channel is reversed (1100 µs drives the left thruster forward), so it is mirrored
around its neutral. The author's surge/sway/yaw_rate estimates are not read.

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
A twin run's u, v (its true velocities) and thrust_left/right are not read: a
Recording holds what sensors log.
`channels={"reversed": {"left": True}, "trim": {"left": 1500, "right": 1500}}` mirrors
a reversed channel and sets the neutral for either CSV layout.
"""
from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from ..errors import TwinError
from .ardupilot import read_dataflash, read_tlog
from .recording import Recording, check_usable, clean_stream, with_common_origin

MCAP_MAGIC = b"\x89MCAP"
DATAFLASH_MAGIC = b"\xa3\x95"
BLUEBOAT_COLUMNS = {"original_timestamp", "lat", "lon", "yaw", "thr_left", "thr_right"}
BLUEBOAT_NEUTRAL_US = 1511.0


def read_recording(path, *, channels: dict | None = None) -> Recording:
    """Read a recording (.tlog, DataFlash .bin, BlueBoat or generic .csv, project
    .mcap) into a Recording; TwinError (one line) if nothing usable is in it.

    channels: thruster output mapping for logs (see twin.recordings.ardupilot), or
    reversal/trim overrides for CSV files."""
    path = Path(path)
    if path.is_dir():
        raise TwinError(f"{path}: is a directory, not a recording file")
    if not path.is_file():
        raise TwinError(f"{path}: no such file")
    head = _head(path)
    if not head:
        raise TwinError(f"{path.name}: empty file")
    reader = READERS.get(sniff(head, path.suffix.lower()))
    if reader is None:
        raise TwinError(f"{path.name}: not a recognised recording (expected .tlog, DataFlash .bin, .csv or .mcap)")
    rec = reader(path, channels)
    check_usable(rec, path.name)
    return rec


def sniff(head: bytes, suffix: str) -> str:
    """"mcap", "dataflash", "tlog", "csv" or "" from the first bytes and the extension."""
    if head.startswith(MCAP_MAGIC):
        return "mcap"
    if head.startswith(DATAFLASH_MAGIC):
        return "dataflash"
    if suffix == ".tlog" or (len(head) > 8 and head[8] in (0xFD, 0xFE)):
        return "tlog"
    if _is_text(head) and b"," in head.split(b"\n", 1)[0]:
        return "csv"
    if suffix in (".bin", ".log"):
        return "dataflash"  # a damaged start: let the DataFlash reader try and say why not
    return ""


def _head(path: Path, n: int = 4096) -> bytes:
    try:
        with open(path, "rb") as fh:
            return fh.read(n)
    except OSError as exc:
        raise TwinError(f"{path.name}: cannot read ({exc.strerror or exc})") from None


def _is_text(head: bytes) -> bool:
    try:
        head.decode("utf-8")
    except UnicodeDecodeError as exc:
        return exc.start > len(head) - 4  # a multi-byte character cut by the 4 kB window
    return b"\x00" not in head


# ---------------------------------------------------------------- CSV

def read_csv(path: Path, channels: dict | None = None) -> Recording:
    """Read a BlueBoat or generic CSV recording (see the module docstring)."""
    header, cols, malformed = _table(path)
    if BLUEBOAT_COLUMNS <= set(header):
        rec = _blueboat(path, cols, channels)
    elif "t" in header:
        rec = _generic(path, header, cols, channels)
    else:
        raise TwinError(f"{path.name}: CSV layout not recognised (need a 't' column or the BlueBoat columns)")
    if malformed:
        rec.dropped.insert(0, ("csv: rows with the wrong number of fields", malformed))
    if not any(len(s) for s in rec.streams().values()):
        raise TwinError(f"{path.name}: no usable rows")
    return with_common_origin(rec)


def _table(path: Path) -> tuple[list[str], dict[str, np.ndarray], int]:
    """Header, float columns (non-numbers → NaN) and the number of malformed rows."""
    try:
        text = path.read_text(encoding="utf-8-sig", errors="replace")  # -sig: a spreadsheet's BOM
    except OSError as exc:
        raise TwinError(f"{path.name}: cannot read ({exc.strerror or exc})") from None
    rows = list(csv.reader(io.StringIO(text)))
    if not rows:
        raise TwinError(f"{path.name}: empty CSV file")
    header = [h.strip() for h in rows[0]]
    good = [r for r in rows[1:] if len(r) == len(header)]
    malformed = sum(1 for r in rows[1:] if r and len(r) != len(header))
    cols = {name: np.array([_float(r[i]) for r in good], dtype=float) for i, name in enumerate(header) if name}
    return header, cols, malformed


def _float(s: str) -> float:
    try:
        return float(s)
    except ValueError:
        return np.nan


def _blueboat(path: Path, c: dict[str, np.ndarray], channels: dict | None) -> Recording:
    rec = Recording(source=str(path), kind="blueboat-csv")
    t = c["original_timestamp"] * 1e-3
    gnss = {"lat_deg": c["lat"], "lon_deg": c["lon"]}
    if "alt" in c:
        gnss["alt_m"] = c["alt"]
    rec.gnss = clean_stream("gnss", t, gnss, rec.dropped)
    rec.heading = clean_stream("heading", t, {"psi_rad": np.radians(c["yaw"])}, rec.dropped)
    neutral = tuple(_neutral(c.get(f"thr_{s}_pwm_zero_point"), BLUEBOAT_NEUTRAL_US) for s in ("right", "left"))
    # The column the dataset calls thr_left is reversed (1100 µs drives its thruster forward) and drives
    # the STARBOARD thruster: with it as port, every run turns the wrong way (more "left" thrust yaws
    # to port in all ten files, while the tracks follow the heading on straight runs). So thr_right is
    # the port (left) thruster and thr_left, mirrored, the starboard (right) one.
    _csv_pwm(rec, t, c["thr_right"], c["thr_left"], neutral, {"left": False, "right": True}, channels)
    rec.notes.append("thrusters: port = column thr_right, starboard = column thr_left mirrored (the dataset's "
                     "labels are swapped: see readers.py)")
    g = rec.gnss
    if len(g) > 1:  # rows at 10 Hz from a slower receiver repeat the fix: say how many
        same = np.mean((np.diff(g["lat_deg"]) == 0) & (np.diff(g["lon_deg"]) == 0))
        rec.notes.append(f"GNSS: {100 * same:.0f}% of the rows repeat the previous fix")
    rec.notes.append("the file's own surge/sway/yaw_rate estimates are not read")
    return rec


def _generic(path: Path, header: list[str], c: dict[str, np.ndarray], channels: dict | None) -> Recording:
    """Multi-rate streams share the rows: a row whose cells of one stream are all empty
    is simply not a sample of it (only partly filled rows count as dropped)."""
    rec = Recording(source=str(path), kind="csv")
    t = c["t"]
    if {"lat", "lon"} <= set(header):
        gnss = {"lat_deg": c["lat"], "lon_deg": c["lon"]} | ({"alt_m": c["alt"]} if "alt" in c else {})
    elif {"north", "east"} <= set(header):
        gnss = {"north_m": c["north"], "east_m": c["east"]}
    elif {"x", "y"} <= set(header):
        gnss = {"north_m": c["x"], "east_m": c["y"]}
        rec.meta["positions"] = "body origin"
        rec.notes.append("positions x, y are north, east of the body origin (a twin run): no lever arm to apply")
    else:
        gnss = None
        rec.notes.append("no GNSS: no lat/lon, north/east or x/y columns")
    if gnss is not None:
        rec.gnss = _stream("gnss", t, gnss, rec.dropped)
    psi = np.radians(c["heading_deg"]) if "heading_deg" in c else c.get("psi")
    if psi is not None:
        rec.heading = _stream("heading", t, {"psi_rad": psi}, rec.dropped)
    else:
        rec.notes.append("no heading: no heading_deg or psi column")
    if {"pwm_left", "pwm_right"} <= set(header):
        neutral = tuple(_neutral(c.get(f"pwm_neutral_{side}"), 1500.0) for side in ("left", "right"))
        _csv_pwm(rec, t, c["pwm_left"], c["pwm_right"], neutral, {"left": False, "right": False}, channels)
    yaw_rate = c.get("yaw_rate", c.get("r"))
    if yaw_rate is not None:
        rec.imu = _stream("imu", t, {"yaw_rate_rads": yaw_rate}, rec.dropped)
    if "voltage" in c:
        rec.battery = _stream("battery", t, {"voltage_v": c["voltage"]}, rec.dropped)
    return rec


def _stream(name: str, t: np.ndarray, cols: dict, dropped: list):
    """clean_stream on the rows that hold at least one cell of this stream."""
    present = np.zeros(len(t), bool)
    for v in cols.values():
        present |= np.isfinite(v)
    return clean_stream(name, t[present], {k: v[present] for k, v in cols.items()}, dropped)


def _neutral(col, default: float) -> float:
    if col is None or not np.any(np.isfinite(col)):
        return default
    return float(np.nanmedian(col))


def _csv_pwm(rec: Recording, t, left, right, neutral, reversed_: dict, channels: dict | None) -> None:
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
    rec.pwm = _stream("pwm", t, cols, rec.dropped)
    rec.pwm_neutral_us = (float(neutral[0]), float(neutral[1]))
    rec.channels = {"reversed": {k: bool(reversed_.get(k)) for k in ("left", "right")},
                    "trim": {"left": neutral[0], "right": neutral[1]}, "from": rec.kind}


# ---------------------------------------------------------------- MCAP

def read_mcap(path: Path) -> Recording:
    """An MCAP file of this project (twin.viz.mcap_io). With /sensors/* topics (a
    sensor recording, written by twin.recordings.writers) each topic is a stream at
    its messages' log times. Otherwise a run: /vessel/state gives the positions
    (north/east: of the body origin for a simulated run, no lever arm; as measured for
    a run written from a recording) and heading, /vessel/inputs the PWM (absent when
    the run was driven by thrust). A file cut short gives its complete messages, with
    a note."""
    from ..viz.mcap_io import read_sensor_mcap

    sensors = read_sensor_mcap(path)
    if sensors is not None:
        return _mcap_sensors(path, *sensors)
    return _mcap_run(path)


def _mcap_sensors(path: Path, streams: dict, meta: dict) -> Recording:
    rec = Recording(source=str(path), kind="mcap", origin_s=meta.get("origin_s", 0.0),
                    pwm_neutral_us=meta.get("pwm_neutral_us", (1500.0, 1500.0)))
    for name, (t, cols) in streams.items():
        setattr(rec, name, clean_stream(name, t, cols, rec.dropped))
    rec.meta.update(meta.get("meta", {}))
    rec.parameters = meta.get("parameters", {})
    if meta.get("damaged"):
        rec.notes.append(meta["damaged"])
    if not any(len(s) for s in rec.streams().values()):
        raise TwinError(f"{path.name}: the MCAP /sensors/ topics hold no usable samples")
    return with_common_origin(rec)


def _mcap_run(path: Path) -> Recording:
    from ..viz.mcap_io import read_run_mcap

    rec = Recording(source=str(path), kind="mcap")
    run = read_run_mcap(path, rec.notes)
    t = run.t
    rec.gnss = clean_stream("gnss", t, {"north_m": run.eta[:, 0], "east_m": run.eta[:, 1]}, rec.dropped)
    rec.heading = clean_stream("heading", t, {"psi_rad": run.eta[:, 2]}, rec.dropped)
    rec.imu = clean_stream("imu", t, {"yaw_rate_rads": run.nu[:, 2]}, rec.dropped)
    if np.any(np.isfinite(run.pwm_us)):
        rec.pwm = clean_stream("pwm", t, {"left_us": run.pwm_us[:, 0], "right_us": run.pwm_us[:, 1]}, rec.dropped)
    else:
        rec.notes.append("no PWM: the run was driven by thrust")
    rec.meta.update(run.meta)
    if run.meta.get("engine") == "recording":  # prepared measurements (an older `twin convert`)
        rec.notes.append("positions are as measured (the GNSS antenna unless a lever arm was applied)")
    else:
        rec.meta["positions"] = "body origin"
        rec.notes.append("positions are the body origin (simulated): prepare with lever_arm_OP_m=None")
    if not len(rec.gnss) and not len(rec.heading):
        raise TwinError(f"{path.name}: the MCAP run has no finite states")
    return with_common_origin(rec)


READERS = {"mcap": lambda path, channels: read_mcap(path), "dataflash": read_dataflash, "tlog": read_tlog,
           "csv": read_csv}
