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

import struct

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from ..run import Run
from .telemetry import DEFAULT_ORIGIN, LEFT_CHANNEL, RIGHT_CHANNEL, THRUSTER_PARAMS, sample, write_bytes_atomic


def tlog_packets(run: Run, antenna_body_m=(0.0, 0.0), origin=DEFAULT_ORIGIN, start_unix_s: float = 1.7e9,
                 **rates) -> list[tuple[int, bytes]]:
    """(unix time µs, MAVLink packet) in time order."""
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    tel = sample(run, antenna_body_m, origin, **rates)
    out = []

    def add(t_s, msg):
        out.append((int(round((start_unix_s + t_s) * 1e6)), msg.pack(mav)))

    for t in range(int(run.t[-1]) + 1):
        add(t, mav.heartbeat_encode(mavlink.MAV_TYPE_SURFACE_BOAT, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 4))
    for i, (name, value) in enumerate(THRUSTER_PARAMS.items()):
        add(0.0, mav.param_value_encode(name.encode(), float(value), mavlink.MAV_PARAM_TYPE_REAL32,
                                        len(THRUSTER_PARAMS), i))
    for t, la, lo, v in zip(tel.gnss_t, tel.lat_deg, tel.lon_deg, tel.speed_m_s):
        add(t, mav.gps_raw_int_encode(int(t * 1e6), 3, int(round(la * 1e7)), int(round(lo * 1e7)), 0, 50, 80,
                                      int(v * 100), 65535, 12))
    for t, p, r in zip(tel.heading_t, tel.psi_rad, tel.r_rad_s):
        add(t, mav.attitude_encode(int(t * 1e3), 0.0, 0.0, float(p), 0.0, 0.0, float(r)))
    for t, (left, right) in zip(tel.pwm_t, tel.pwm_us):
        servo = [0] * 8
        servo[LEFT_CHANNEL - 1], servo[RIGHT_CHANNEL - 1] = int(round(left)), int(round(right))
        add(t, mav.servo_output_raw_encode(int(t * 1e6) & 0xFFFFFFFF, 0, *servo))
    out.sort(key=lambda item: item[0])
    return out


def write_run_tlog(run: Run, path, **kwargs) -> None:
    """Write the run as a .tlog ([8-byte big-endian µs][packet]...) atomically."""
    packets = tlog_packets(run, **kwargs)
    write_bytes_atomic(path, b"".join(struct.pack(">Q", stamp) + data for stamp, data in packets))
