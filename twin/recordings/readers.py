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
  alt                m (optional, with lat/lon)
  heading_deg        deg from north to east    -- or --   psi           rad
  pwm_left, pwm_right   µs, forward thrust = higher PWM, neutral 1500 µs (optional)
  yaw_rate           rad/s, gyro (optional)
  voltage            V, battery (optional)
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
from .recording import Recording, clean_stream, with_common_origin

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
    if not path.is_file():
        raise TwinError(f"{path}: no such file")
    head = _head(path)
    if not head:
        raise TwinError(f"{path.name}: empty file")
    kind = sniff(head, path.suffix.lower())
    if kind == "mcap":
        return read_mcap(path)
    if kind == "dataflash":
        return read_dataflash(path, channels)
    if kind == "tlog":
        return read_tlog(path, channels)
    if kind == "csv":
        return read_csv(path, channels)
    raise TwinError(f"{path.name}: not a recognised recording (expected .tlog, DataFlash .bin, .csv or .mcap)")


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
    else:
        gnss = None
        rec.notes.append("no GNSS: no lat/lon or north/east columns")
    if gnss is not None:
        rec.gnss = _stream("gnss", t, gnss, rec.dropped)
    psi = np.radians(c["heading_deg"]) if "heading_deg" in c else c.get("psi")
    if psi is not None:
        rec.heading = _stream("heading", t, {"psi_rad": psi}, rec.dropped)
    else:
        rec.notes.append("no heading: no heading_deg or psi column")
    if {"pwm_left", "pwm_right"} <= set(header):
        _csv_pwm(rec, t, c["pwm_left"], c["pwm_right"], (1500.0, 1500.0), {"left": False, "right": False}, channels)
    if "yaw_rate" in c:
        rec.imu = _stream("imu", t, {"yaw_rate_rads": c["yaw_rate"]}, rec.dropped)
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
    its messages' log times. Otherwise a simulated run: /vessel/state gives the
    positions (north/east of the body origin: no lever arm) and heading,
    /vessel/inputs the PWM (absent when the run was driven by thrust)."""
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
    if not any(len(s) for s in rec.streams().values()):
        raise TwinError(f"{path.name}: the MCAP /sensors/ topics hold no usable samples")
    return with_common_origin(rec)


def _mcap_run(path: Path) -> Recording:
    from ..viz.mcap_io import read_run_mcap

    run = read_run_mcap(path)
    rec = Recording(source=str(path), kind="mcap")
    t = run.t
    rec.gnss = clean_stream("gnss", t, {"north_m": run.eta[:, 0], "east_m": run.eta[:, 1]}, rec.dropped)
    rec.heading = clean_stream("heading", t, {"psi_rad": run.eta[:, 2]}, rec.dropped)
    rec.imu = clean_stream("imu", t, {"yaw_rate_rads": run.nu[:, 2]}, rec.dropped)
    if np.any(np.isfinite(run.pwm_us)):
        rec.pwm = clean_stream("pwm", t, {"left_us": run.pwm_us[:, 0], "right_us": run.pwm_us[:, 1]}, rec.dropped)
    else:
        rec.notes.append("no PWM: the run was driven by thrust")
    rec.notes.append("positions are the body origin (simulated): prepare with lever_arm_OP_m=None")
    rec.meta.update(run.meta)
    if not len(rec.gnss) and not len(rec.heading):
        raise TwinError(f"{path.name}: the MCAP run has no finite states")
    return with_common_origin(rec)
