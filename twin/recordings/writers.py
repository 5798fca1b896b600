"""write_recording(rec, path): a Recording → a file that read_recording reads back
to the same streams, so that synthetic sensor logs (own sample times, noise,
clock offsets, gaps) go through exactly the path real logs take.

The format follows the extension:
  .csv   the generic CSV layout of readers.py: header
           t[,lat,lon[,alt] | ,north,east][,heading_deg][,pwm_left,pwm_right[,pwm_neutral_left,
           pwm_neutral_right]][,yaw_rate][,voltage]
         with the columns of the streams that have samples, one row per distinct sample
         time (µs) of any stream, an empty cell where a stream has no sample at that time.
         t %.6f s, lat/lon %.10f deg, alt %.4f m, north/east %.6f m, heading_deg %.7f
         in [0, 360), pwm %.10g µs (integers stay integers), yaw_rate %.9f rad/s, voltage %.4f V.
         The PWM neutral columns are written on the PWM rows only when it is not 1500 µs.
  .tlog  MAVLink telemetry (twin.viz.tlog_io): the recording's parameters, GPS_RAW_INT,
         ATTITUDE, SERVO_OUTPUT_RAW on the channels of SERVO1/3_FUNCTION = 73/74 with
         SERVOn_TRIM = the PWM neutral, SYS_STATUS for the battery, HEARTBEAT every second.
  .bin   ArduPilot DataFlash (twin.viz.dataflash_io): PARM (the recording's parameters and
         the same thruster mapping), GPS, ATT, RCOU, IMU (GyrZ), BAT.
  .mcap  /sensors/gnss (foxglove.LocationFix), /sensors/heading, /sensors/pwm,
         /sensors/imu, /sensors/battery (twin.viz.mcap_io), the parameters in its metadata.

What a round trip keeps (sample times / values):
  .csv   1 µs / lat, lon 1e-10 deg, heading 1e-7 deg, PWM as written; no parameters
  .tlog  GNSS and PWM 1 µs, heading 1 ms / lat, lon 1e-7 deg, alt 1 mm, heading float32
         (~1e-7 rad), PWM integer µs (rounded), voltage 1 mV, parameters float32; the imu
         stream comes back at the heading times (ATTITUDE carries both) and, without one,
         as zeros
  .bin   1 µs / lat, lon 1e-7 deg, alt 1 cm, heading 0.01 deg, PWM integer µs (rounded),
         yaw rate and voltage float32, parameters float32
  .mcap  1 ns / every value exactly (JSON), plus the origin, PWM neutral and parameters

Times: a stream's t (s from the recording's origin) is written as it is, unless some
sample is before the origin: then every stream is shifted by the same amount so that
the earliest sample is at 0 (MCAP and MAVLink times cannot be negative); offsets
between streams are always kept. The readers put the earliest sample at t = 0.

Positions: a gnss stream in north_m/east_m stays local in .csv; .tlog and .mcap store
latitude/longitude, converted around `origin` (lat, lon deg; default
twin.viz.telemetry.DEFAULT_ORIGIN), so they read back as lat_deg/lon_deg.

Every file is written atomically (temporary name in the same folder, then rename);
an unknown extension, a missing folder or a malformed recording is a one-line TwinError
and leaves no file behind.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Callable

import numpy as np

from ..errors import TwinError
from ..geodesy import geodetic_from_ned
from .recording import Recording, Stream

CSV_NEUTRAL_US = 1500.0
COLUMNS = {"heading": ("psi_rad",), "pwm": ("left_us", "right_us"), "imu": ("yaw_rate_rads",),
           "battery": ("voltage_v",)}


def write_recording(rec: Recording, path, *, origin: tuple[float, float] | None = None) -> None:
    """Write `rec` as .csv, .tlog, .bin or .mcap (by the extension of `path`); see the
    module docstring for the layouts. origin: (lat, lon) deg of the local frame of
    a gnss stream in north_m/east_m, for the formats that store latitude/longitude."""
    path = Path(path)
    writer = WRITERS.get(path.suffix.lower())
    if writer is None:
        raise TwinError(f"output '{path}': unknown recording format '{path.suffix}' (use .csv, .tlog, .bin or .mcap)")
    if not path.parent.is_dir():
        raise TwinError(f"output '{path}': folder '{path.parent}' does not exist")
    check_recording(rec)
    try:
        writer(rec, path, origin)
    except OSError as exc:
        raise TwinError(f"output '{path}': cannot write ({exc.strerror or exc})") from None


# ---------------------------------------------------------------- checks and file times

def check_recording(rec: Recording) -> None:
    """TwinError unless every stream with samples has finite, strictly increasing
    times and finite values of its columns, one per time."""
    streams = {name: s for name, s in rec.streams().items() if len(s)}
    if not streams:
        raise TwinError("the recording has no samples to write")
    for name, s in streams.items():
        t = np.asarray(s.t, dtype=float)
        if t.ndim != 1 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
            raise TwinError(f"{name}: sample times must be finite and strictly increasing")
        for col in _columns(name, s):
            values = np.asarray(s[col], dtype=float)
            if values.shape != t.shape:
                raise TwinError(f"{name}.{col}: {values.shape[0] if values.ndim else 1} values for {len(t)} times")
            if not np.all(np.isfinite(values)):
                raise TwinError(f"{name}.{col}: {int(np.sum(~np.isfinite(values)))} values are NaN or infinite")


def _columns(name: str, s: Stream) -> tuple[str, ...]:
    if name != "gnss":
        missing = [c for c in COLUMNS[name] if c not in s.columns]
        if missing:
            raise TwinError(f"{name}: no column {', '.join(missing)}")
        return COLUMNS[name]
    if s.has("lat_deg", "lon_deg"):
        return ("lat_deg", "lon_deg") + (("alt_m",) if "alt_m" in s.columns else ())
    if s.has("north_m", "east_m"):
        return ("north_m", "east_m")
    raise TwinError("gnss: neither lat_deg/lon_deg nor north_m/east_m")


def file_ready(rec: Recording, origin: tuple[float, float] | None, geodetic: bool) -> Recording:
    """A copy with the times a file stores (none before 0), psi wrapped to (−π, π]
    and, if `geodetic`, the gnss stream in lat_deg/lon_deg."""
    firsts = [s.t[0] for s in rec.streams().values() if len(s)]
    shift_s = min(0.0, float(min(firsts)))
    streams = {name: Stream(np.asarray(s.t, dtype=float) - shift_s,
                            {k: np.asarray(v, dtype=float) for k, v in s.columns.items()})
               for name, s in rec.streams().items()}
    heading = streams["heading"]
    if len(heading):
        heading.columns["psi_rad"] = np.angle(np.exp(1j * heading["psi_rad"]))
    gnss = streams["gnss"]
    if geodetic and len(gnss) and not gnss.has("lat_deg", "lon_deg"):
        lat0, lon0 = _origin(origin)
        lat, lon = geodetic_from_ned(gnss["north_m"], gnss["east_m"], lat0, lon0)
        streams["gnss"] = Stream(gnss.t, {"lat_deg": lat, "lon_deg": lon})
    return dataclasses.replace(rec, origin_s=rec.origin_s + shift_s, **streams)


def _origin(origin: tuple[float, float] | None) -> tuple[float, float]:
    if origin is None:
        from ..viz.telemetry import DEFAULT_ORIGIN

        return DEFAULT_ORIGIN
    try:
        lat0, lon0 = (float(x) for x in origin)
    except (TypeError, ValueError):
        raise TwinError(f"origin must be (lat, lon) in degrees, got {origin!r}") from None
    if not (abs(lat0) < 90 and abs(lon0) <= 180):
        raise TwinError(f"origin ({lat0}, {lon0}) is not a latitude in (−90, 90) and a longitude in [−180, 180]")
    return lat0, lon0


# ---------------------------------------------------------------- formats

def _write_csv(rec: Recording, path: Path, origin) -> None:
    from ..viz.telemetry import write_bytes_atomic

    write_bytes_atomic(path, csv_text(file_ready(rec, origin, geodetic=False)).encode())


def _write_tlog(rec: Recording, path: Path, origin) -> None:
    from ..viz.tlog_io import write_recording_tlog

    write_recording_tlog(file_ready(rec, origin, geodetic=True), path)


def _write_bin(rec: Recording, path: Path, origin) -> None:
    from ..viz.dataflash_io import write_recording_bin

    write_recording_bin(file_ready(rec, origin, geodetic=True), path)


def _write_mcap(rec: Recording, path: Path, origin) -> None:
    from ..viz.mcap_io import write_recording_mcap

    write_recording_mcap(file_ready(rec, origin, geodetic=True), path)


WRITERS: dict[str, Callable[[Recording, Path, tuple[float, float] | None], None]] = {
    ".csv": _write_csv, ".tlog": _write_tlog, ".bin": _write_bin, ".mcap": _write_mcap}


# ---------------------------------------------------------------- CSV

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
        out += [("north", "gnss", _fmt("%.6f", g["north_m"])), ("east", "gnss", _fmt("%.6f", g["east_m"]))]
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
    return out


def _fmt(spec: str, values: np.ndarray) -> np.ndarray:
    return np.char.mod(spec, np.asarray(values, dtype=float)).astype(object)
