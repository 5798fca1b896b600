"""Runs and recordings as ArduPilot DataFlash logs (.bin), the format the
vehicle writes, so that log viewers and this project's readers open them.

A DataFlash log is a sequence of messages [0xA3 0x95 type][payload]; the
first messages are FMT records that describe every type, FMT included.
Written here: PARM (thruster functions 73/74, as ArduRover), GPS at the
antenna (5 Hz, with the lever arm), ATT (heading, 50 Hz), RCOU (10 Hz).
"""
from __future__ import annotations

import os
import struct
from pathlib import Path

import numpy as np

from ..errors import TwinError
from ..geodesy import geodetic_from_ned
from ..run import Run
from .tlog_io import DEFAULT_ORIGIN, LEFT_CHANNEL, RIGHT_CHANNEL, _antenna_ned

HEAD = b"\xa3\x95"
SIZES = {"B": 1, "H": 2, "I": 4, "Q": 8, "c": 2, "C": 2, "L": 4, "e": 4, "f": 4, "n": 4, "N": 16, "Z": 64}
PACK = {"B": "B", "H": "H", "I": "I", "Q": "Q", "c": "h", "C": "H", "L": "i", "e": "i", "f": "f", "n": "4s",
        "N": "16s", "Z": "64s"}
FORMATS = {  # type id, name, format, columns (ArduPilot's layouts, trimmed to what is written)
    "FMT": (128, "BBnNZ", "Type,Length,Name,Format,Columns"),
    "PARM": (64, "QNf", "TimeUS,Name,Value"),
    "GPS": (65, "QBBIHBcLLeff", "TimeUS,I,Status,GMS,GWk,NSats,HDop,Lat,Lng,Alt,Spd,GCrs"),
    "ATT": (66, "QccccCCCC", "TimeUS,DesRoll,Roll,DesPitch,Pitch,DesYaw,Yaw,ErrRP,ErrYaw"),
    "RCOU": (67, "Q" + "H" * 14, "TimeUS," + ",".join(f"C{i}" for i in range(1, 15))),
}
GPS_EPOCH_UNIX_S = 315964800.0
LEAP_S = 18.0


def _message(name: str, *values) -> bytes:
    type_id, fmt, _ = FORMATS[name]
    return HEAD + bytes([type_id]) + struct.pack("<" + "".join(PACK[c] for c in fmt), *values)


def _fmt_record(name: str) -> bytes:
    type_id, fmt, cols = FORMATS[name]
    length = 3 + sum(SIZES[c] for c in fmt)
    return _message("FMT", type_id, length, name.encode(), fmt.encode(), cols.encode())


def dataflash_bytes(run: Run, antenna_body_m=(0.0, 0.0), origin=DEFAULT_ORIGIN, start_unix_s: float = 1.7e9,
                    gnss_dt: float = 0.2, heading_dt: float = 0.02, pwm_dt: float = 0.1) -> bytes:
    out = [_fmt_record(n) for n in FORMATS]
    timed = []
    for name, value in {"SERVO1_FUNCTION": 73, "SERVO3_FUNCTION": 74, "SERVO1_REVERSED": 0,
                        "SERVO3_REVERSED": 0}.items():
        timed.append((0, _message("PARM", 0, name.encode(), float(value))))
    t_end = float(run.t[-1])
    north, east = _antenna_ned(run, antenna_body_m)
    tg = np.arange(0.0, t_end + 1e-9, gnss_dt)
    lat, lon = geodetic_from_ned(np.interp(tg, run.t, north), np.interp(tg, run.t, east), *origin)
    for t, la, lo in zip(tg, lat, lon):
        gps_s = start_unix_s + t - GPS_EPOCH_UNIX_S + LEAP_S
        week, ms = int(gps_s // 604800), int(round((gps_s % 604800) * 1000))
        us = int(round(t * 1e6))
        timed.append((us, _message("GPS", us, 0, 3, ms, week, 12, 80, int(round(la * 1e7)), int(round(lo * 1e7)),
                                   0, 0.0, 0.0)))
    th = np.arange(0.0, t_end + 1e-9, heading_dt)
    psi_deg = np.degrees(np.interp(th, run.t, np.unwrap(run.eta[:, 2]))) % 360.0
    for t, yaw in zip(th, psi_deg):
        us = int(round(t * 1e6))
        timed.append((us, _message("ATT", us, 0, 0, 0, 0, 0, int(round(yaw * 100)) % 36000, 0, 0)))
    if np.all(np.isfinite(run.pwm_us)):
        tp = np.arange(0.0, t_end + 1e-9, pwm_dt)
        idx = np.clip(np.searchsorted(run.t, tp + 1e-9, side="right") - 1, 0, len(run.t) - 1)
        for t, (left, right) in zip(tp, run.pwm_us[idx]):
            ch = [0] * 14
            ch[LEFT_CHANNEL - 1], ch[RIGHT_CHANNEL - 1] = int(round(left)), int(round(right))
            us = int(round(t * 1e6))
            timed.append((us, _message("RCOU", us, *ch)))
    timed.sort(key=lambda item: item[0])
    return b"".join(out + [m for _, m in timed])


def write_run_bin(run: Run, path, **kwargs) -> None:
    """Write the run as a DataFlash .bin atomically (temporary name, then rename)."""
    path = Path(path)
    if len(run.t) < 2:
        raise TwinError("a .bin log needs at least two samples")
    data = dataflash_bytes(run, **kwargs)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
