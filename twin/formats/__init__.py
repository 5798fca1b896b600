"""Recording and run files: one module per format, reader and writer together.

  read_recording(path)        any supported file → Recording (the format is decided by
                              content first, then by extension):
    MCAP (magic "\\x89MCAP")    /sensors/* topics (a recording) or a run written here   mcap.py
    DataFlash (bytes A3 95)     ArduPilot .bin log                                      dataflash.py
    tlog (MAVLink marker at byte 8, or extension .tlog)                                 tlog.py
    CSV text                    the BlueBoat layout (blueboat_csv.py), the Esso Osaka
                                model's tests (esso_csv.py) or the generic layout (csv.py)
  write_recording(rec, path)  a Recording → .csv, .tlog, .bin or .mcap that read_recording
                              reads back to the same streams
  write_run(run, path)        a simulated run → .csv, .mcap, .tlog or .bin

Synthetic sensor logs (own sample times, noise, clock offsets, gaps) written by
write_recording go through exactly the path real logs take.

The format follows the extension:
  .csv   the generic CSV layout (csv.py): header
           t[,lat,lon[,alt] | ,north,east][,heading_deg][,pwm_left,pwm_right[,pwm_neutral_left,
           pwm_neutral_right]][,yaw_rate][,voltage][,prop_rps,rudder_deg]
           [,wind_speed,wind_from_deg[,wind_rel_speed,wind_rel_from_deg]]
         with the columns of the streams that have samples, one row per distinct sample
         time (µs) of any stream, an empty cell where a stream has no sample at that time.
         t %.6f s, lat/lon %.10f deg, alt %.4f m, north/east %.6f m, heading_deg %.7f
         in [0, 360), pwm %.10g µs (integers stay integers), yaw_rate %.9f rad/s, voltage %.4f V.
         The PWM neutral columns are written on the PWM rows only when it is not 1500 µs.
  .tlog  MAVLink telemetry (tlog.py): the recording's parameters, GPS_RAW_INT,
         ATTITUDE, SERVO_OUTPUT_RAW on the channels of SERVO1/3_FUNCTION = 73/74 with
         SERVOn_TRIM = the PWM neutral, SYS_STATUS for the battery, HEARTBEAT every second,
         NAMED_VALUE_FLOAT for a ship's propeller and rudder and a measured wind.
  .bin   ArduPilot DataFlash (dataflash.py): PARM (the recording's parameters and
         the same thruster mapping), GPS, ATT, RCOU, IMU (GyrZ), BAT, and the log's own
         SHIP (propeller and rudder) and WNDM (measured wind).
  .mcap  /sensors/gnss (foxglove.LocationFix), /sensors/heading, /sensors/pwm,
         /sensors/imu, /sensors/battery, /sensors/prop_rudder, /sensors/wind (mcap.py), the
         parameters in its metadata.

What a round trip keeps (sample times / values):
  .csv   1 µs / lat, lon 1e-10 deg, heading 1e-7 deg, PWM as written; no parameters
  .tlog  GNSS and PWM 1 µs, heading 1 ms / lat, lon 1e-7 deg, alt 1 mm, heading float32
         (~1e-7 rad), PWM integer µs (rounded), voltage 1 mV, parameters float32; the imu
         stream comes back at the heading times (ATTITUDE carries both; earlier by the
         gyro filter's delay where the parameters state one) and, without one, as none
  .bin   1 µs / lat, lon 1e-7 deg, alt 1 cm, heading 0.01 deg, PWM integer µs (rounded),
         yaw rate and voltage float32, parameters float32
  .mcap  1 ns / every value exactly (JSON), plus the origin, PWM neutral and parameters
  (prop_rudder and wind: .csv 10 significant digits, 1e-6 m/s and deg; .tlog 1 ms, .bin 1 µs /
  float32)

Times: a stream's t (s from the recording's origin) is written as it is (in .tlog and .bin,
an ArduPilot gyro and GPS fix later by the delays the parameters state, as ArduPilot stamps
them: formats.ardupilot), unless some
sample is before the origin: then every stream is shifted by the same amount so that
the earliest sample is at 0 (MCAP and MAVLink times cannot be negative); offsets
between streams are always kept. The readers put the earliest sample at t = 0.

Positions: a gnss stream in north_m/east_m stays local in .csv; .tlog and .mcap store
latitude/longitude, converted around `origin` (lat, lon deg; default
telemetry.DEFAULT_ORIGIN), so they read back as lat_deg/lon_deg.

Every file is written atomically (temporary name in the same folder, then rename);
an unknown extension, a missing folder or a malformed recording is a one-line TwinError
and leaves no file behind.
"""
from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Callable

import numpy as np

from ..errors import TwinError
from ..geodesy import geodetic_from_ned
from ..recording import Recording, Stream, check_usable
from ..run import Run
from . import csv as csv_format
from . import blueboat_csv, dataflash, esso_csv, mcap, tlog
from .telemetry import DEFAULT_ORIGIN

# datasets with their own CSV layout
CSV_LAYOUTS = ((blueboat_csv.matches, blueboat_csv.read), (esso_csv.matches, esso_csv.read))
CSV_KNOWN = (("the BlueBoat dataset's", frozenset(blueboat_csv.COLUMNS)),
             ("the Esso Osaka dataset's", frozenset(esso_csv.REQUIRED)))
MCAP_MAGIC = b"\x89MCAP"
DATAFLASH_MAGIC = b"\xa3\x95"
COLUMNS = {"heading": ("psi_rad",), "pwm": ("left_us", "right_us"), "imu": ("yaw_rate_rads",),
           "battery": ("voltage_v",), "prop_rudder": ("n_rps", "delta_rad"), "wind": ("speed_m_s", "from_deg")}
OPTIONAL_COLUMNS = {"wind": ("relative_speed_m_s", "relative_from_deg")}  # checked where present


def read_recording(path, *, channels: dict | None = None) -> Recording:
    """Read a recording (.tlog, DataFlash .bin, BlueBoat or generic .csv, project
    .mcap) into a Recording; TwinError (one line) if nothing usable is in it.

    channels: thruster output mapping for logs (see ardupilot.py), or
    reversal/trim overrides for CSV files."""
    if not isinstance(path, (str, os.PathLike)):
        raise TwinError(f"a recording is read from a file path (str or Path), got {type(path).__name__}")
    path = Path(path)
    try:
        return _read(path, channels)
    except TwinError as exc:
        # the readers name the file; a user who gave a folder or a path needs the path to find it
        text = str(exc)
        if text.startswith(f"{path.name}:") and str(path) != path.name:
            raise TwinError(f"{path}{text[len(path.name):]}") from None
        raise


def _read(path: Path, channels: dict | None) -> Recording:
    if path.is_dir():
        raise TwinError(f"{path}: is a directory, not a recording file")
    if not path.is_file():
        raise TwinError(f"{path}: not a regular file (a device, a pipe or a socket): give a recording file"
                        if path.exists() else f"{path}: no such file")
    head = _head(path)
    if not head:
        raise TwinError(f"{path.name}: empty file")
    kind = sniff(head, path.suffix.lower())
    reader = READERS.get(kind)
    if reader is None:
        why = (_not_csv(head) if path.suffix.lower() == ".csv" else
               "not an MCAP file: it does not begin with MCAP's magic bytes" if path.suffix.lower() == ".mcap" else
               f"a rerun recording is shown by rerun itself: `rerun {path.name}`" if path.suffix.lower() == ".rrd"
               else "")
        raise TwinError(f"{path.name}: not a recognised recording ({why or 'expected .tlog, DataFlash .bin, .csv or .mcap'})")
    if kind in ("csv", "mcap") and isinstance(channels, dict) and {"left", "right"} & set(channels):
        raise TwinError(f"{path.name}: --channels LEFT,RIGHT does not apply to a{'n' if kind == 'mcap' else ''} "
                        f"{kind.upper()} recording: it has no servo outputs to choose from (only ArduPilot .tlog "
                        "and .bin logs do)")
    rec = reader(path, channels)
    check_usable(rec, path.name)
    return rec


def sniff(head: bytes, suffix: str) -> str:
    """"mcap", "dataflash", "tlog", "csv" or "" from the first bytes and the extension."""
    if head.startswith(MCAP_MAGIC):
        return "mcap"
    if head.startswith(DATAFLASH_MAGIC):
        return "dataflash"
    if suffix == ".tlog" or (len(head) > 8 and head[8] in (0xFD, 0xFE)) or _stamped_mavlink(head):
        return "tlog"
    if _is_text(head) and b"," in head.split(b"\n", 1)[0]:
        return "csv"
    if suffix in (".bin", ".log"):
        return "dataflash"  # a damaged start: let the DataFlash reader try and say why not
    return ""


def _stamped_mavlink(head: bytes, needed: int = 3) -> bool:
    """A telemetry log whose first record is not a MAVLink packet (a link's noise at its start): its records
    are an 8-byte µs stamp, whose high 4 bytes stay the same for 71 minutes, then a packet's start byte
    (0xFE MAVLink 1, 0xFD MAVLink 2); `needed` such records in the head say so."""
    stamp = head[:4]
    found = 0
    for i in range(8, len(head)):
        if head[i] in (0xFD, 0xFE) and head[i - 8:i - 4] == stamp:
            found += 1
            if found >= needed:
                return True
    return False


def _head(path: Path, n: int = 4096) -> bytes:
    try:
        with open(path, "rb") as fh:
            return fh.read(n)
    except OSError as exc:
        raise TwinError(f"{path.name}: cannot read ({exc.strerror or exc})") from None


def _not_csv(head: bytes) -> str:
    """Why a file named .csv is not read as one (the start of it, `head`), or ""."""
    if head.startswith(b"\x1f\x8b"):
        return "gzip-compressed: uncompress it first"
    try:
        head.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = head[: exc.start].count(b"\n") + 1
        return f"not UTF-8 text: byte 0x{head[exc.start]:02x} on line {line} (save it as UTF-8)"
    if b"\x00" in head:
        return "binary data, not text"
    first = head.split(b"\n", 1)[0]
    if b";" in first or b"\t" in first:
        return "its columns are separated by ';' or tabs: a CSV recording's by commas"
    return "no comma in its first line: the header names the columns, comma-separated"


def _is_text(head: bytes) -> bool:
    try:
        head.decode("utf-8")
    except UnicodeDecodeError as exc:
        return exc.start > len(head) - 4  # a multi-byte character cut by the 4 kB window
    return b"\x00" not in head


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
        return COLUMNS[name] + tuple(c for c in OPTIONAL_COLUMNS.get(name, ()) if c in s.columns)
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
               for name, s in {**rec.streams(), "attitude": rec.attitude}.items()}
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
    csv_format.write_recording_csv(file_ready(rec, origin, geodetic=False), path)


def _write_tlog(rec: Recording, path: Path, origin) -> None:
    tlog.write_recording_tlog(file_ready(rec, origin, geodetic=True), path)


def _write_bin(rec: Recording, path: Path, origin) -> None:
    dataflash.write_recording_bin(file_ready(rec, origin, geodetic=True), path)


def _write_mcap(rec: Recording, path: Path, origin) -> None:
    mcap.write_recording_mcap(file_ready(rec, origin, geodetic=True), path)


WRITERS: dict[str, Callable[[Recording, Path, tuple[float, float] | None], None]] = {
    ".csv": _write_csv, ".tlog": _write_tlog, ".bin": _write_bin, ".mcap": _write_mcap}
READERS = {"mcap": lambda path, channels: mcap.read_mcap(path), "dataflash": dataflash.read_dataflash,
           "tlog": tlog.read_tlog,
           "csv": lambda path, channels: csv_format.read_csv(path, channels, CSV_LAYOUTS, CSV_KNOWN)}
RUN_FORMATS = (".csv", ".mcap", ".tlog", ".bin")


def write_run(run: Run, path, *, antenna_body_m=(0.0, 0.0), vessel_name: str = "",
              origin: tuple[float, float] | None = None) -> None:
    """A simulated run as .csv (the twin's run layout), .mcap, .tlog or .bin (sampled as a
    boat's sensors log it, GNSS at the antenna `antenna_body_m`, body FRD m). origin: (lat, lon)
    deg of the run's local frame for the formats that carry map positions (default
    telemetry.DEFAULT_ORIGIN)."""
    path = Path(path)
    suffix = path.suffix.lower()
    start = _origin(origin)
    if suffix == ".csv":
        csv_format.write_run_csv(run, path)
    elif suffix == ".mcap":
        mcap.write_run_mcap(run, path, vessel_name, origin=start, antenna_body_m=antenna_body_m)
    elif suffix == ".tlog":
        tlog.write_run_tlog(run, path, antenna_body_m=antenna_body_m, origin=start)
    elif suffix == ".bin":
        dataflash.write_run_bin(run, path, antenna_body_m=antenna_body_m, origin=start)
    else:
        raise TwinError(f"output '{path}': unknown run format (use {', '.join(RUN_FORMATS)})")
