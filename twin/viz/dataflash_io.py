"""Runs and recordings as ArduPilot DataFlash logs (.bin), the format the
vehicle writes, so that log viewers and this project's readers open them.

A DataFlash log is a sequence of messages [0xA3 0x95 type][payload]; the
first messages are FMT records that describe every type, FMT included.
Written here: PARM (thruster functions 73/74, as ArduRover), GPS at the
antenna (5 Hz, with the lever arm), ATT (heading, 50 Hz), RCOU (10 Hz).
"""
from __future__ import annotations

import struct

import numpy as np

from ..run import Run
from .telemetry import DEFAULT_ORIGIN, LEFT_CHANNEL, RIGHT_CHANNEL, THRUSTER_PARAMS, sample, write_bytes_atomic

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
                    **rates) -> bytes:
    tel = sample(run, antenna_body_m, origin, **rates)
    timed = [(0, _message("PARM", 0, name.encode(), float(value))) for name, value in THRUSTER_PARAMS.items()]
    for t, la, lo, v in zip(tel.gnss_t, tel.lat_deg, tel.lon_deg, tel.speed_m_s):
        gps_s = start_unix_s + t - GPS_EPOCH_UNIX_S + LEAP_S
        us = int(round(t * 1e6))
        timed.append((us, _message("GPS", us, 0, 3, int(round((gps_s % 604800) * 1000)), int(gps_s // 604800), 12,
                                   80, int(round(la * 1e7)), int(round(lo * 1e7)), 0, float(v), 0.0)))
    for t, psi in zip(tel.heading_t, tel.psi_rad):
        us = int(round(t * 1e6))
        timed.append((us, _message("ATT", us, 0, 0, 0, 0, 0, int(round(np.degrees(psi) % 360.0 * 100)) % 36000, 0, 0)))
    for t, (left, right) in zip(tel.pwm_t, tel.pwm_us):
        ch = [0] * 14
        ch[LEFT_CHANNEL - 1], ch[RIGHT_CHANNEL - 1] = int(round(left)), int(round(right))
        us = int(round(t * 1e6))
        timed.append((us, _message("RCOU", us, *ch)))
    timed.sort(key=lambda item: item[0])
    return b"".join([_fmt_record(n) for n in FORMATS] + [m for _, m in timed])


def write_run_bin(run: Run, path, **kwargs) -> None:
    """Write the run as a DataFlash .bin atomically (temporary name, then rename)."""
    write_bytes_atomic(path, dataflash_bytes(run, **kwargs))
