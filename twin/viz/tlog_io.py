"""Simulated runs and sensor recordings as MAVLink telemetry logs (.tlog), so that
ArduPilot ground stations (Mission Planner, QGroundControl, UAVLogViewer) and
this project's reader (twin.recordings.ardupilot) open them.

A .tlog is a sequence of [8-byte big-endian µs Unix time][MAVLink 2 packet].
One packet builder (`telemetry_packets`) serves both sources:
  HEARTBEAT          every second from 0 to the last sample, MAV_TYPE_SURFACE_BOAT
  PARAM_VALUE        at 0: SERVO1_FUNCTION = 73 (throttle left), SERVO3_FUNCTION = 74
                     (throttle right), SERVOn_REVERSED = 0, as an ArduRover skid-steer
                     boat; a recording adds its own parameters and SERVOn_TRIM = its PWM
                     neutral (telemetry.log_parameters)
  GPS_RAW_INT        3-D fix, lat/lon 1e-7 deg, alt mm, time_usec = log time (µs)
  ATTITUDE           yaw (rad, float32), yawspeed, time_boot_ms = log time (ms)
  SERVO_OUTPUT_RAW   port 0, PWM (integer µs) on channels 1 and 3, time_usec (32-bit µs)
  SYS_STATUS         battery voltage (mV), only where the source has a battery stream
Every message is stamped with its own sample time; the Unix stamp is a fixed start
plus that time, so the log's boot clock and receive clock agree.

A run is sampled at the rates of seed 004 §3 (twin.viz.telemetry.sample): GNSS at
the antenna every 200 ms, AHRS heading every 20 ms, PWM every 100 ms.
"""
from __future__ import annotations

import struct
from typing import TYPE_CHECKING, Callable

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from ..errors import TwinError
from ..run import Run
from .telemetry import (DEFAULT_ORIGIN, LEFT_CHANNEL, RIGHT_CHANNEL, THRUSTER_PARAMS, Telemetry, log_parameters,
                        sample, write_bytes_atomic)

if TYPE_CHECKING:
    from ..recordings.recording import Recording

START_UNIX_S = 1.7e9  # a fixed wall-clock start keeps the files reproducible
UNKNOWN_U16 = 65535  # MAVLink's "unknown" for GPS speed and course
MAX_BOOT_MS = 2**32 - 1  # ATTITUDE.time_boot_ms is a 32-bit ms counter

Add = Callable[[float, object], None]


def tlog_packets(run: Run, antenna_body_m=(0.0, 0.0), origin=DEFAULT_ORIGIN, start_unix_s: float = START_UNIX_S,
                 **rates) -> list[tuple[int, bytes]]:
    """(unix time µs, MAVLink packet) of a simulated run, in time order."""
    tel = sample(run, antenna_body_m, origin, **rates)
    return telemetry_packets(tel, float(run.t[-1]), THRUSTER_PARAMS, start_unix_s)


def write_run_tlog(run: Run, path, **kwargs) -> None:
    """Write the run as a .tlog ([8-byte big-endian µs][packet]...) atomically."""
    write_bytes_atomic(path, tlog_bytes(tlog_packets(run, **kwargs)))


def write_recording_tlog(rec: Recording, path, start_unix_s: float = START_UNIX_S) -> None:
    """Write a recording whose times are ≥ 0, whose gnss stream has lat_deg/lon_deg
    and whose psi_rad is wrapped (twin.recordings.writers prepares it) atomically."""
    tel = recording_telemetry(rec)
    ends = [s.t[-1] for s in rec.streams().values() if len(s)]
    params = log_parameters(rec.parameters, rec.pwm_neutral_us, with_pwm=len(rec.pwm) > 0)
    write_bytes_atomic(path, tlog_bytes(telemetry_packets(tel, float(max(ends)), params, start_unix_s)))


def tlog_bytes(packets: list[tuple[int, bytes]]) -> bytes:
    return b"".join(struct.pack(">Q", stamp) + data for stamp, data in packets)


# ---------------------------------------------------------------- the shared packet builder

def telemetry_packets(tel: Telemetry, end_s: float, params: dict[str, float],
                      start_unix_s: float = START_UNIX_S) -> list[tuple[int, bytes]]:
    """(unix time µs, MAVLink packet) in time order; see the module docstring."""
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    start_us = int(round(start_unix_s * 1e6))
    out: list[tuple[int, bytes]] = []

    def add(t_s: float, msg) -> None:
        out.append((start_us + _us(t_s), msg.pack(mav)))

    _heartbeats(mav, end_s, add)
    _params(mav, params, add)
    _gnss(mav, tel, add)
    _attitude(mav, tel, add)
    _servo(mav, tel, add)
    _battery(mav, tel, add)
    out.sort(key=lambda item: item[0])  # stable: packets of one instant keep the order above
    return out


def _us(t_s: float) -> int:
    # rounded, not truncated: 4.35 s * 1e6 is 4349999.999…
    return int(round(t_s * 1e6))


def _heartbeats(mav, end_s: float, add: Add) -> None:
    for t in range(int(end_s) + 1):
        add(t, mav.heartbeat_encode(mavlink.MAV_TYPE_SURFACE_BOAT, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 4))


def _params(mav, params: dict[str, float], add: Add) -> None:
    for i, (name, value) in enumerate(params.items()):
        add(0.0, mav.param_value_encode(name.encode(), float(value), mavlink.MAV_PARAM_TYPE_REAL32, len(params), i))


def _gnss(mav, tel: Telemetry, add: Add) -> None:
    alt = tel.alt_m if tel.alt_m is not None else np.zeros(len(tel.gnss_t))
    for t, la, lo, h, v in zip(tel.gnss_t, tel.lat_deg, tel.lon_deg, alt, tel.speed_m_s):
        vel = int(v * 100) if np.isfinite(v) else UNKNOWN_U16  # cm/s, truncated as the writer always did
        add(t, mav.gps_raw_int_encode(_us(t), 3, int(round(la * 1e7)), int(round(lo * 1e7)), int(round(h * 1e3)),
                                      50, 80, vel, UNKNOWN_U16, 12))


def _attitude(mav, tel: Telemetry, add: Add) -> None:
    for t, p, r in zip(tel.heading_t, tel.psi_rad, tel.r_rad_s):
        add(t, mav.attitude_encode(int(round(t * 1e3)), 0.0, 0.0, float(p), 0.0, 0.0, float(r)))


def _servo(mav, tel: Telemetry, add: Add) -> None:
    for t, (left, right) in zip(tel.pwm_t, tel.pwm_us):
        servo = [0] * 8
        servo[LEFT_CHANNEL - 1], servo[RIGHT_CHANNEL - 1] = int(round(left)), int(round(right))
        add(t, mav.servo_output_raw_encode(_us(t) & 0xFFFFFFFF, 0, *servo))


def _battery(mav, tel: Telemetry, add: Add) -> None:
    for t, volts in zip(tel.battery_t, tel.voltage_v):
        # SYS_STATUS has no time field: the reader takes the receive time
        add(t, mav.sys_status_encode(0, 0, 0, 0, int(round(volts * 1e3)), -1, -1, 0, 0, 0, 0, 0, 0))


# ---------------------------------------------------------------- recording → Telemetry

def recording_telemetry(rec: Recording) -> Telemetry:
    """The recording's samples as Telemetry; TwinError where a value does not fit
    its MAVLink field. ATTITUDE carries heading and yaw rate together, so the imu
    stream is interpolated at the heading times (0 without an imu stream)."""
    g, h, p, imu, bat = rec.gnss, rec.heading, rec.pwm, rec.imu, rec.battery
    r = np.interp(h.t, imu.t, imu["yaw_rate_rads"]) if len(imu) else np.zeros(len(h))
    pwm = np.column_stack([p["left_us"], p["right_us"]]) if len(p) else np.zeros((0, 2))
    _check_range("heading time (ms)", np.round(h.t * 1e3), 0, MAX_BOOT_MS)
    _check_range("PWM (µs)", np.round(pwm), 1, 65535)
    _check_range("battery voltage (mV)", np.round(bat["voltage_v"] * 1e3) if len(bat) else np.zeros(0), 1, 65534)
    return Telemetry(g.t, g["lat_deg"] if len(g) else np.zeros(0), g["lon_deg"] if len(g) else np.zeros(0),
                     np.full(len(g), np.nan), h.t, h["psi_rad"] if len(h) else np.zeros(0), r, p.t, pwm,
                     alt_m=g["alt_m"] if g.has("alt_m") else None,
                     battery_t=bat.t, voltage_v=bat["voltage_v"] if len(bat) else np.zeros(0))


def _check_range(what: str, values: np.ndarray, lo: float, hi: float) -> None:
    bad = (values < lo) | (values > hi)
    if np.any(bad):
        raise TwinError(f"tlog: {what} {values[bad][0]:g} does not fit MAVLink's range {lo:g}..{hi:g}")
