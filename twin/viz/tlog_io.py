"""Simulated runs as MAVLink telemetry logs (.tlog), so that ArduPilot ground
stations (Mission Planner, QGroundControl, UAVLogViewer) open them.

A .tlog is a sequence of [8-byte big-endian µs Unix time][MAVLink packet].
The sensors are written at the rates of seed 004 §3: GNSS at the antenna
(with the lever arm, seed 000 appendix) every 200 ms, AHRS heading every
20 ms, PWM (SERVO_OUTPUT_RAW) every 100 ms; the thruster channels are
declared with SERVO1_FUNCTION = 73 (throttle left) and SERVO3_FUNCTION = 74
(throttle right), as an ArduRover skid-steer boat does.
"""
from __future__ import annotations

import os
import struct
from pathlib import Path

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from ..errors import TwinError
from ..geodesy import geodetic_from_ned
from ..run import Run

DEFAULT_ORIGIN = (37.4136, -5.9786)  # a lake-free reference point; any origin works
LEFT_CHANNEL, RIGHT_CHANNEL = 1, 3


def _antenna_ned(run: Run, antenna_body_m) -> tuple[np.ndarray, np.ndarray]:
    """Antenna position in NED: CO + R(ψ)·r_antenna (inverse of seed 000 eq. 32)."""
    c, s = np.cos(run.eta[:, 2]), np.sin(run.eta[:, 2])
    ax, ay = antenna_body_m[0], antenna_body_m[1]
    return run.eta[:, 0] + c * ax - s * ay, run.eta[:, 1] + s * ax + c * ay


def _interp(t_new, t, y):
    return np.interp(t_new, t, y)


def tlog_packets(run: Run, antenna_body_m=(0.0, 0.0), origin=DEFAULT_ORIGIN, start_unix_s: float = 1.7e9,
                 gnss_dt: float = 0.2, heading_dt: float = 0.02, pwm_dt: float = 0.1):
    """Yield (unix time µs, packet bytes) in time order."""
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    out = []

    def add(t_s, msg):
        out.append((int(round((start_unix_s + t_s) * 1e6)), msg.pack(mav)))

    t_end = float(run.t[-1])
    for t in np.arange(0.0, t_end + 1e-9, 1.0):
        add(t, mav.heartbeat_encode(mavlink.MAV_TYPE_SURFACE_BOAT, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 4))
    params = {"SERVO1_FUNCTION": 73, "SERVO3_FUNCTION": 74, "SERVO1_REVERSED": 0, "SERVO3_REVERSED": 0}
    for i, (name, value) in enumerate(params.items()):
        add(0.0, mav.param_value_encode(name.encode(), float(value), mavlink.MAV_PARAM_TYPE_REAL32, len(params), i))
    north, east = _antenna_ned(run, antenna_body_m)
    tg = np.arange(0.0, t_end + 1e-9, gnss_dt)
    lat, lon = geodetic_from_ned(_interp(tg, run.t, north), _interp(tg, run.t, east), *origin)
    speed = np.hypot(*np.gradient(np.column_stack([_interp(tg, run.t, north), _interp(tg, run.t, east)]), tg,
                                  axis=0).T) if len(tg) > 1 else np.zeros_like(tg)
    for t, la, lo, v in zip(tg, lat, lon, speed):
        add(t, mav.gps_raw_int_encode(int(t * 1e6), 3, int(round(la * 1e7)), int(round(lo * 1e7)), 0, 50, 80,
                                      int(v * 100), 65535, 12))
    th = np.arange(0.0, t_end + 1e-9, heading_dt)
    psi = np.angle(np.exp(1j * _interp(th, run.t, np.unwrap(run.eta[:, 2]))))
    r = _interp(th, run.t, run.nu[:, 2])
    for t, p, rr in zip(th, psi, r):
        add(t, mav.attitude_encode(int(t * 1e3), 0.0, 0.0, float(p), 0.0, 0.0, float(rr)))
    if np.all(np.isfinite(run.pwm_us)):
        tp = np.arange(0.0, t_end + 1e-9, pwm_dt)
        idx = np.clip(np.searchsorted(run.t, tp + 1e-9, side="right") - 1, 0, len(run.t) - 1)
        for t, (left, right) in zip(tp, run.pwm_us[idx]):
            servo = [0] * 8
            servo[LEFT_CHANNEL - 1], servo[RIGHT_CHANNEL - 1] = int(round(left)), int(round(right))
            add(t, mav.servo_output_raw_encode(int(t * 1e6) & 0xFFFFFFFF, 0, *servo))
    out.sort(key=lambda item: item[0])
    return out


def write_run_tlog(run: Run, path, **kwargs) -> None:
    """Write the run as a .tlog atomically (temporary name, then rename)."""
    path = Path(path)
    if len(run.t) < 2:
        raise TwinError("a .tlog needs at least two samples")
    packets = tlog_packets(run, **kwargs)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as fh:
            for stamp, data in packets:
                fh.write(struct.pack(">Q", stamp))
                fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
