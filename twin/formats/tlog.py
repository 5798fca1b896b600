"""Simulated runs and sensor recordings as MAVLink telemetry logs (.tlog), so that
ArduPilot ground stations (Mission Planner, QGroundControl, UAVLogViewer) and
this project's reader (formats.tlog and formats.dataflash) open them.

A .tlog is a sequence of [8-byte big-endian µs Unix time][MAVLink 2 packet].
One packet builder (`telemetry_packets`) serves both sources:
  HEARTBEAT          every second from 0 to the last sample, MAV_TYPE_SURFACE_BOAT
  PARAM_VALUE        at 0: SERVO1_FUNCTION = 73 (throttle left), SERVO3_FUNCTION = 74
                     (throttle right), SERVOn_REVERSED = 0, as an ArduRover skid-steer
                     boat; a recording adds its own parameters and SERVOn_TRIM = its PWM
                     neutral (telemetry.log_parameters)
  GPS_RAW_INT        3-D fix, lat/lon 1e-7 deg, alt mm, time_usec = log time (µs; later by the GPS
                     delay a recording's parameters state, formats.ardupilot), ground speed
                     and course over ground (cog, 65535 when unknown or below 5 cm/s)
  GLOBAL_POSITION_INT  (a simulated run) position, NED velocity and heading at the GNSS times:
                     what ground stations draw the vehicle from
  ATTITUDE           yaw (rad, float32), yawspeed (the gyro as of its filter's delay before, where
                     the parameters state one), time_boot_ms = log time (ms); roll and pitch
                     (rad, float32) of a 6-DOF hull or a recording's attitude stream, else 0
  SERVO_OUTPUT_RAW   port 0, PWM (integer µs) on channels 1 and 3, time_usec (32-bit µs)
  SYS_STATUS         battery voltage (mV), only where the source has a battery stream
  NAMED_VALUE_FLOAT  a recording's propeller speed and rudder angle (PROP_RPS rps, RUDDER_RAD rad)
                     and measured wind (WIND_SPD m/s, WIND_FROM deg; on board, where measured,
                     WIND_RSPD, WIND_RFROM), float32, time_boot_ms:
                     MAVLink has no message of its own for them
Every message is stamped with its own sample time (the GPS fixes and the gyro as ArduPilot
stamps them, formats.ardupilot); the Unix stamp is a fixed start plus that time, so the log's boot
clock and receive clock agree.

A run is sampled at the rates of [Morel-2024 §3] (telemetry.sample): GNSS at
the antenna every 200 ms, AHRS heading every 20 ms, PWM every 100 ms.
"""
from __future__ import annotations

import re
import struct
from collections import Counter, defaultdict
from pathlib import Path
from typing import Callable

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink
from pymavlink.generator.mavcrc import x25crc

from ..errors import TwinError
from ..files import write_bytes_atomic
from ..recording import Recording, Stream, clean_stream
from ..run import Run
from .ardupilot import (finish, gnss_delay_s, gyro_filter_delay_s, read_bytes, read_fixes_when_taken,
                        read_gyro_on_time, set_pwm, text, thruster_mapping)
from .telemetry import (DEFAULT_ORIGIN, LEFT_CHANNEL, RIGHT_CHANNEL, THRUSTER_PARAMS, Telemetry, log_parameters,
                        sample)

START_UNIX_S = 1.7e9  # a fixed wall-clock start keeps the files reproducible
UNKNOWN_U16 = 65535  # MAVLink's "unknown" for GPS speed and course
MAX_BOOT_MS = 2**32 - 1  # ATTITUDE.time_boot_ms is a 32-bit ms counter

Add = Callable[[float, object], None]
# recording stream → (NAMED_VALUE_FLOAT name, column) pairs, written together at the stream's times:
# the first two always, the others (the wind measured on board) where the stream has them
NAMED = {"prop_rudder": (("PROP_RPS", "n_rps"), ("RUDDER_RAD", "delta_rad")),
         "wind": (("WIND_SPD", "speed_m_s"), ("WIND_FROM", "from_deg"),
                  ("WIND_RSPD", "relative_speed_m_s"), ("WIND_RFROM", "relative_from_deg"))}
NAMED_REQUIRED = 2


def tlog_packets(run: Run, antenna_body_m=(0.0, 0.0), origin=DEFAULT_ORIGIN, start_unix_s: float = START_UNIX_S,
                 **rates) -> list[tuple[int, bytes]]:
    """(unix time µs, MAVLink packet) of a simulated run, in time order."""
    tel = sample(run, antenna_body_m, origin, **rates)
    packets = telemetry_packets(tel, float(run.t[-1]), THRUSTER_PARAMS, start_unix_s)
    return _limit_notices(run, start_unix_s) + packets


def _limit_notices(run: Run, start_unix_s: float) -> list[tuple[int, bytes]]:
    """A STATUSTEXT (severity warning) at the time each thruster input bound was first hit
    (run.meta["limits"], twin.engine.limits), so a ground station shows it in the log."""
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    out = []
    for lim in run.meta.get("limits", []):
        text = (f"{lim['thruster']} {lim['quantity']} beyond {lim['bound']:g} {lim['unit']} "
                f"{lim['seconds']:.1f} s")[:50]
        msg = mav.statustext_encode(mavlink.MAV_SEVERITY_WARNING, text.encode())
        out.append((int(round(start_unix_s * 1e6)) + _us(lim["first_s"]), msg.pack(mav)))
    return out


def write_run_tlog(run: Run, path, **kwargs) -> None:
    """Write the run as a .tlog ([8-byte big-endian µs][packet]...) atomically."""
    write_bytes_atomic(path, tlog_bytes(tlog_packets(run, **kwargs)))


def write_recording_tlog(rec: Recording, path, start_unix_s: float = START_UNIX_S) -> None:
    """Write a recording whose times are ≥ 0, whose gnss stream has lat_deg/lon_deg
    and whose psi_rad is wrapped (twin.formats.write_recording prepares it) atomically."""
    tel = recording_telemetry(rec)
    ends = [s.t[-1] for s in rec.streams().values() if len(s)]
    params = log_parameters(rec.parameters, rec.pwm_neutral_us, with_pwm=len(rec.pwm) > 0)
    named = {stream: getattr(rec, stream) for stream in NAMED if len(getattr(rec, stream))}
    for stream in named.values():
        _check_range("time (ms)", np.round(stream.t * 1e3), 0, MAX_BOOT_MS)
    write_bytes_atomic(path, tlog_bytes(telemetry_packets(tel, float(max(ends)), params, start_unix_s, named)))


def tlog_bytes(packets: list[tuple[int, bytes]]) -> bytes:
    return b"".join(struct.pack(">Q", stamp) + data for stamp, data in packets)


# ---------------------------------------------------------------- the shared packet builder

def telemetry_packets(tel: Telemetry, end_s: float, params: dict[str, float],
                      start_unix_s: float = START_UNIX_S, named: dict | None = None) -> list[tuple[int, bytes]]:
    """(unix time µs, MAVLink packet) in time order; see the module docstring. `named`: recording
    streams (a key of NAMED → Stream) written as NAMED_VALUE_FLOAT."""
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
    _named(mav, named or {}, add)
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
    course = tel.course_deg()
    for t, la, lo, h, v, c in zip(tel.gnss_t, tel.lat_deg, tel.lon_deg, alt, tel.speed_m_s, course):
        vel = int(v * 100) if np.isfinite(v) else UNKNOWN_U16  # cm/s, truncated as the writer always did
        cog = int(round(c * 100)) % 36000 if np.isfinite(c) else UNKNOWN_U16
        add(t, mav.gps_raw_int_encode(_us(t), 3, int(round(la * 1e7)), int(round(lo * 1e7)), int(round(h * 1e3)),
                                      50, 80, vel, cog, 12))
    _global_position(mav, tel, alt, add)


def _global_position(mav, tel: Telemetry, alt: np.ndarray, add: Add) -> None:
    """GLOBAL_POSITION_INT, what ground stations draw the vehicle from, where the velocities are
    known (a simulated run): lat/lon 1e-7 deg, alt mm, velocity cm/s NED, hdg the heading
    (cdeg) interpolated at the GNSS times."""
    if tel.velocity_ned_m_s is None or not len(tel.heading_t):
        return
    hdg = np.degrees(np.interp(tel.gnss_t, tel.heading_t, np.unwrap(tel.psi_rad))) % 360.0
    for t, la, lo, h, (vn, ve), yaw in zip(tel.gnss_t, tel.lat_deg, tel.lon_deg, alt, tel.velocity_ned_m_s, hdg):
        add(t, mav.global_position_int_encode(int(round(t * 1e3)) & 0xFFFFFFFF, int(round(la * 1e7)),
                                              int(round(lo * 1e7)), int(round(h * 1e3)), 0, int(round(vn * 100)),
                                              int(round(ve * 100)), 0, int(round(yaw * 100)) % 36000))


def _attitude(mav, tel: Telemetry, add: Add) -> None:
    roll, pitch = tel.attitude()
    for t, p, r, phi, theta in zip(tel.heading_t, tel.psi_rad, tel.r_rad_s, roll, pitch):
        add(t, mav.attitude_encode(int(round(t * 1e3)), float(phi), float(theta), float(p), 0.0, 0.0, float(r)))


def _servo(mav, tel: Telemetry, add: Add) -> None:
    for t, (left, right) in zip(tel.pwm_t, tel.pwm_us):
        servo = [0] * 8
        servo[LEFT_CHANNEL - 1], servo[RIGHT_CHANNEL - 1] = int(round(left)), int(round(right))
        add(t, mav.servo_output_raw_encode(_us(t) & 0xFFFFFFFF, 0, *servo))


def _battery(mav, tel: Telemetry, add: Add) -> None:
    for t, volts in zip(tel.battery_t, tel.voltage_v):
        # SYS_STATUS has no time field: the reader takes the receive time
        add(t, mav.sys_status_encode(0, 0, 0, 0, int(round(volts * 1e3)), -1, -1, 0, 0, 0, 0, 0, 0))


def _named(mav, streams: dict, add: Add) -> None:
    for key, stream in streams.items():
        for name, column in NAMED[key]:
            if not stream.has(column):
                continue
            for t, value in zip(stream.t, stream[column]):
                add(t, mav.named_value_float_encode(int(round(t * 1e3)), name.encode(), float(value)))


# ---------------------------------------------------------------- recording → Telemetry

def recording_telemetry(rec: Recording) -> Telemetry:
    """The recording's samples as Telemetry; TwinError where a value does not fit
    its MAVLink field. ATTITUDE carries heading and yaw rate together, so the imu
    stream is interpolated at the heading times; without an imu stream its yawspeed is NaN, which
    the reader takes as no gyro (a 0 would read back as a gyro that never turns), and so is it at
    heading times the gyro did not cover (before its first sample, after its last, in its gaps):
    a value there would be one it never measured. The attitude stream (roll, pitch) likewise,
    exactly where it shares the heading's times. A gyro without a heading has no ATTITUDE to ride
    on: refused (TwinError), not dropped unsaid."""
    g, h, p, imu, bat = rec.gnss, rec.heading, rec.pwm, rec.imu, rec.battery
    if len(imu) and not len(h):
        raise TwinError(f"{Path(rec.source).name}: a .tlog carries the gyro in ATTITUDE beside the heading, and this "
                        "recording has a gyro but no heading (write a .csv, .bin or .mcap)")
    # ArduPilot's gyro is stamped its filter's delay after the turn (formats.ardupilot): put it back
    late_s = gyro_filter_delay_s(rec.parameters)
    r = _covered(h.t - late_s, imu.t, imu["yaw_rate_rads"]) if len(imu) else np.full(len(h), np.nan)
    att = rec.attitude
    # a log without roll and pitch is not a level one: NaN, which the readers take as not measured
    roll = _covered(h.t, att.t, att["roll_rad"]) if len(att) else np.full(len(h), np.nan)
    pitch = _covered(h.t, att.t, att["pitch_rad"]) if len(att) else np.full(len(h), np.nan)
    pwm = np.column_stack([p["left_us"], p["right_us"]]) if len(p) else np.zeros((0, 2))
    _check_range("heading time (ms)", np.round(h.t * 1e3), 0, MAX_BOOT_MS)
    _check_range("PWM (µs)", np.round(pwm), 1, 65535)
    _check_range("battery voltage (mV)", np.round(bat["voltage_v"] * 1e3) if len(bat) else np.zeros(0), 1, 65534)
    # a fix's GPS_RAW_INT time is when it came in, which a delay the log states puts after it was taken
    gnss_t = g.t + gnss_delay_s(rec.parameters)[0]
    return Telemetry(gnss_t, g["lat_deg"] if len(g) else np.zeros(0), g["lon_deg"] if len(g) else np.zeros(0),
                     np.full(len(g), np.nan), h.t, h["psi_rad"] if len(h) else np.zeros(0), r, p.t, pwm,
                     alt_m=g["alt_m"] if g.has("alt_m") else None,
                     battery_t=bat.t, voltage_v=bat["voltage_v"] if len(bat) else np.zeros(0),
                     roll_rad=roll, pitch_rad=pitch)


def _covered(t: np.ndarray, t_src: np.ndarray, x: np.ndarray) -> np.ndarray:
    """x interpolated at times t where its samples cover them (between two samples no further apart
    than twice their median spacing), NaN elsewhere."""
    t, t_src, x = np.asarray(t, float), np.asarray(t_src, float), np.asarray(x, float)
    out = np.interp(t, t_src, x)
    if len(t_src) < 2:
        return np.where(np.isclose(t, t_src[0]) if len(t_src) else False, out, np.nan)
    steps = np.diff(t_src)
    k = np.clip(np.searchsorted(t_src, t, side="right") - 1, 0, len(steps) - 1)
    inside = (t >= t_src[0] - 1e-9) & (t <= t_src[-1] + 1e-9) & (steps[k] <= 2.0 * float(np.median(steps)))
    return np.where(inside | np.isclose(t, t_src[k]), out, np.nan)


def _check_range(what: str, values: np.ndarray, lo: float, hi: float) -> None:
    bad = (values < lo) | (values > hi)
    if np.any(bad):
        raise TwinError(f"tlog: {what} {values[bad][0]:g} does not fit MAVLink's range {lo:g}..{hi:g}")


# ---------------------------------------------------------------- reading
# A tlog is a sequence of [8-byte big-endian receive time, µs since 1970][MAVLink 1 or 2
# packet]. Packets are framed here and decoded with pymavlink's ardupilotmega dialect
# (MAVLink.decode); pymavlink's own file reader is not used for tlogs because it loses the
# framing for good on non-MAVLink records (the SITL log starts with some) and then spends
# seconds scanning for timestamps, and because it switches the wire protocol through a
# process-wide environment variable. Every packet's CRC is checked (bad packets are counted,
# then the reader re-synchronises on the next marker byte); only the wanted messages are
# decoded: GPS_RAW_INT (fix_type ≥ 3 only; GLOBAL_POSITION_INT if the log has no usable
# GPS_RAW_INT), ATTITUDE (yaw, yawspeed), SERVO_OUTPUT_RAW, PARAM_VALUE, SYS_STATUS, and
# NAMED_VALUE_FLOAT of the names in NAMED (a ship's inputs and a measured wind).
# Sample times are the vehicle's boot clock (time_boot_ms / time_usec) where it agrees with
# the receive clock within 1 s, else the receive time mapped onto the boot clock: the link's
# latency jitter would otherwise show up in the velocities.

TLOG_WANTED = ("GPS_RAW_INT", "GLOBAL_POSITION_INT", "ATTITUDE", "SERVO_OUTPUT_RAW", "PARAM_VALUE", "SYS_STATUS",
               "NAMED_VALUE_FLOAT")
_MARKER = re.compile(b"[\xfd\xfe]")
_MAX_JUMP_US = 3 * 24 * 3600 * 1_000_000  # a receive time further than this from the last good one is garbage
_CLOCK_TOLERANCE_S = 1.0


def iter_tlog(data: bytes, wanted: tuple[str, ...], counts: Counter):
    """Yield (receive time s, decoded message) for the wanted message names.

    `counts` receives "packets" (good ones), "bad_crc" (packets at a packet boundary whose CRC fails),
    "skipped_bytes" (bytes outside any valid record) and "truncated" (1 if the
    file ends inside a packet)."""
    mav = mavlink.MAVLink(None)
    wanted_ids = {mid for mid, cls in mavlink.mavlink_map.items() if cls.msgname in wanted}
    pos, n, last_us, synced = 0, len(data), None, True
    while pos + 16 <= n:
        size = _frame_size(data, pos + 8, n)
        ts = int.from_bytes(data[pos:pos + 8], "big")
        if size and pos + 8 + size > n and synced:
            counts["truncated"] += 1
            break
        if size and pos + 8 + size <= n and (last_us is None or abs(ts - last_us) < _MAX_JUMP_US):
            status, msg = _check_frame(mav, mavlink, data[pos + 8:pos + 8 + size], wanted_ids)
            if status == "ok" or (status == "unknown" and synced):
                counts["packets"] += 1
                if msg is not None:
                    yield ts * 1e-6, msg
                pos, last_us, synced = pos + 8 + size, ts, True
                continue
            if status == "crc" and synced:
                counts["bad_crc"] += 1
        nxt = _MARKER.search(data, pos + 9)  # next candidate: a marker byte after an 8-byte time
        new_pos = nxt.start() - 8 if nxt else n
        counts["skipped_bytes"] += new_pos - pos
        pos, synced = new_pos, False
    if pos < n and not counts["truncated"]:
        counts["truncated"] += 1  # the file ends inside a record


def _frame_size(data: bytes, i: int, n: int) -> int:
    """Length of the MAVLink packet starting at data[i] (0 if no marker there)."""
    if data[i] == 0xFE:
        return 6 + data[i + 1] + 2
    if data[i] == 0xFD and i + 10 <= n:
        signed = 13 if data[i + 2] & 0x01 else 0
        return 10 + data[i + 1] + 2 + signed
    return 0


def _check_frame(mav, dialect, frame: bytes, wanted_ids: set[int]):
    """("ok", msg or None) if the CRC holds, ("crc", None) if not, ("unknown", None)
    for a message id the dialect does not know (its CRC cannot be checked)."""
    v2 = frame[0] == 0xFD
    hdr = 10 if v2 else 6
    mid = (frame[7] | frame[8] << 8 | frame[9] << 16) if v2 else frame[5]
    cls = dialect.mavlink_map.get(mid)
    if cls is None:
        return "unknown", None
    end = hdr + frame[1]
    crc = x25crc(bytes(frame[1:end]) + bytes([cls.crc_extra])).crc
    if crc != int.from_bytes(frame[end:end + 2], "little"):
        return "crc", None
    if mid not in wanted_ids:
        return "ok", None
    try:
        return "ok", mav.decode(bytearray(frame))
    except Exception:  # pymavlink raises MAVError, struct.error, ...: a bad packet, not a crash
        return "crc", None


def read_tlog(path: Path, channels: dict | None) -> Recording:
    """Read a MAVLink telemetry log; see the module docstring."""
    data = read_bytes(path)
    counts: Counter = Counter()
    msgs: dict[str, list] = defaultdict(list)
    for t, msg in iter_tlog(data, TLOG_WANTED, counts):
        msgs[msg.get_type()].append((t, msg))
    if not counts["packets"]:
        raise TwinError(f"{path.name}: no valid MAVLink packets in {len(data)} bytes (not a telemetry log?)")
    if not msgs:
        raise TwinError(f"{path.name}: {counts['packets']} MAVLink packets but none of {', '.join(TLOG_WANTED)}")
    rec = Recording(source=str(path), kind="tlog")
    _tlog_counts(rec, counts)
    msgs = _vehicle_only(msgs)
    clock = _BootClock(msgs)
    rec.parameters = {text(m.param_id): float(m.param_value) for _, m in msgs["PARAM_VALUE"]}
    fixes = _tlog_gnss(rec, msgs, clock)
    att = msgs["ATTITUDE"]
    t_att = clock.stamp(att, [m.time_boot_ms * 1e-3 for _, m in att])
    rec.heading = clean_stream("heading", t_att, {"psi_rad": [m.yaw for _, m in att]}, rec.dropped)
    rec.attitude = clean_stream("attitude", t_att, {"roll_rad": [m.roll for _, m in att],
                                                    "pitch_rad": [m.pitch for _, m in att]}, [])
    rate = np.array([m.yawspeed for _, m in att], float)
    if len(rate) and np.all(np.isnan(rate)):  # written without a gyro (recording_telemetry): none, not dropped
        rec.imu = Stream.empty("yaw_rate_rads")
    else:  # a NaN yawspeed is where recording_telemetry had no gyro sample: not a sample dropped
        sampled = ~np.isnan(rate)
        rec.imu = clean_stream("imu", np.asarray(t_att, float)[sampled], {"yaw_rate_rads": rate[sampled]}, rec.dropped)
    _tlog_pwm(rec, msgs, clock, channels)
    _tlog_battery(rec, msgs, clock)
    _tlog_named(rec, msgs["NAMED_VALUE_FLOAT"], clock)
    rec.meta["clock"] = "vehicle boot time" if len(clock.recv) else "tlog receive time"
    read_gyro_on_time(rec)
    if fixes:  # GPS_RAW_INT's time is when the fix came in, as a DataFlash GPS message's (formats.ardupilot)
        read_fixes_when_taken(rec)
    return finish(rec)


def _tlog_counts(rec: Recording, counts: Counter) -> None:
    for key, reason in (("bad_crc", "tlog: packets with bad CRC"),
                        ("skipped_bytes", "tlog: bytes outside valid MAVLink packets"),
                        ("truncated", "tlog: truncated last packet")):
        if counts[key]:
            rec.dropped.append((reason, counts[key]))


def _vehicle_only(msgs: dict[str, list]) -> dict[str, list]:
    """Keep the messages of the system that sends most ATTITUDE (else most of the
    wanted messages): a tlog also holds the ground station's own packets."""
    votes = Counter(m.get_srcSystem() for _, m in msgs.get("ATTITUDE", []))
    if not votes:
        votes = Counter(m.get_srcSystem() for lst in msgs.values() for _, m in lst)
    sysid = votes.most_common(1)[0][0]
    out: dict[str, list] = defaultdict(list)
    for name, lst in msgs.items():
        out[name] = [(t, m) for t, m in lst if m.get_srcSystem() == sysid]
    return out


class _BootClock:
    """Maps messages onto the vehicle's boot clock (s).

    The (receive time, time_boot_ms) pairs of ATTITUDE and GLOBAL_POSITION_INT give
    the map receive → boot by interpolation (a simulator may run faster than the
    wall clock, so no constant offset will do). A message's own boot time is used
    when it agrees with that map within 1 s; otherwise (wrapped 32-bit µs counter,
    GPS epoch time) and for messages without a time field the mapped receive time
    is used. Without any time_boot_ms the receive clock is the time base."""

    def __init__(self, msgs: dict[str, list]):
        pairs = sorted((t, m.time_boot_ms * 1e-3) for name in ("ATTITUDE", "GLOBAL_POSITION_INT")
                       for t, m in msgs.get(name, []))
        self.recv = np.array([p[0] for p in pairs])
        self.boot = np.array([p[1] for p in pairs])

    def estimate(self, recv: np.ndarray) -> np.ndarray:
        """Boot time (s) of receive times (s); slope 1 beyond the known pairs."""
        if not len(self.recv):
            return recv
        est = np.interp(recv, self.recv, self.boot)
        est = np.where(recv < self.recv[0], self.boot[0] + recv - self.recv[0], est)
        return np.where(recv > self.recv[-1], self.boot[-1] + recv - self.recv[-1], est)

    def stamp(self, items: list, boot_s: list | None = None) -> np.ndarray:
        est = self.estimate(np.array([t for t, _ in items], dtype=float))
        if boot_s is None or not len(est):
            return est
        boot = np.asarray(boot_s, dtype=float)
        return np.where(np.abs(boot - est) <= _CLOCK_TOLERANCE_S, boot, est)


def _tlog_gnss(rec: Recording, msgs: dict[str, list], clock: _BootClock) -> bool:
    """The GNSS stream from GPS_RAW_INT's fixes (True), else from the autopilot's fused position (False)."""
    raw = msgs["GPS_RAW_INT"]
    fixed = [(t, m) for t, m in raw if m.fix_type >= 3 and (m.lat or m.lon)]
    if raw and len(fixed) < len(raw):
        rec.dropped.append(("gnss: GPS_RAW_INT without a 3-D fix", len(raw) - len(fixed)))
    if fixed:
        t = clock.stamp(fixed, [m.time_usec * 1e-6 for _, m in fixed])
        cols = {"lat_deg": [m.lat * 1e-7 for _, m in fixed], "lon_deg": [m.lon * 1e-7 for _, m in fixed],
                "alt_m": [m.alt * 1e-3 for _, m in fixed]}
        rec.gnss = clean_stream("gnss", t, cols, rec.dropped)
        return True
    gpi = [(t, m) for t, m in msgs["GLOBAL_POSITION_INT"] if m.lat or m.lon]
    if gpi:
        t = clock.stamp(gpi, [m.time_boot_ms * 1e-3 for _, m in gpi])
        cols = {"lat_deg": [m.lat * 1e-7 for _, m in gpi], "lon_deg": [m.lon * 1e-7 for _, m in gpi],
                "alt_m": [m.alt * 1e-3 for _, m in gpi]}
        rec.gnss = clean_stream("gnss", t, cols, rec.dropped)
        rec.notes.append("gnss from GLOBAL_POSITION_INT: the autopilot's fused estimate, not raw GNSS fixes")
    else:
        rec.notes.append("no GNSS: no GPS_RAW_INT with a 3-D fix and no GLOBAL_POSITION_INT position"
                         if raw or msgs["GLOBAL_POSITION_INT"] else "no GNSS: the log has no GPS messages")
    return False


def _tlog_pwm(rec: Recording, msgs: dict[str, list], clock: _BootClock, channels: dict | None) -> None:
    servo = [(t, m) for t, m in msgs["SERVO_OUTPUT_RAW"] if m.port == 0]
    mapping = thruster_mapping(rec.parameters, channels, rec.notes, rec.warnings)
    if mapping is None or not servo:
        if mapping is not None:
            rec.notes.append("no SERVO_OUTPUT_RAW messages: no thruster PWM")
        return
    t = clock.stamp(servo, [(m.time_usec % 2**32) * 1e-6 for _, m in servo])
    raw = {ch: [getattr(m, f"servo{ch}_raw", 0) for _, m in servo] for ch in (mapping["left"], mapping["right"])}
    set_pwm(rec, t, raw, mapping)


def _tlog_battery(rec: Recording, msgs: dict[str, list], clock: _BootClock) -> None:
    status = [(t, m) for t, m in msgs["SYS_STATUS"] if 0 < m.voltage_battery < 65535]  # mV; 0/65535: unknown
    missing = len(msgs["SYS_STATUS"]) - len(status)
    if missing:
        rec.dropped.append(("battery: SYS_STATUS without a voltage (0 or unknown)", missing))
    if status:  # SYS_STATUS has no time field of its own: the mapped receive time
        volts = [m.voltage_battery * 1e-3 for _, m in status]
        rec.battery = clean_stream("battery", clock.stamp(status), {"voltage_v": volts}, rec.dropped)


def _tlog_named(rec: Recording, named: list, clock: _BootClock) -> None:
    """The streams of NAMED from NAMED_VALUE_FLOAT: each pair of names read at the times both were
    sent (boot ms); other names are not this project's and are left alone."""
    by_name: dict[str, dict[int, tuple]] = defaultdict(dict)
    for t, m in named:
        by_name[text(m.name)][int(m.time_boot_ms)] = (t, m)
    for stream, pairs in NAMED.items():
        required = pairs[:NAMED_REQUIRED]
        times = sorted(set.intersection(*(set(by_name[name]) for name, _ in required)))
        if not times:
            continue
        items = [by_name[required[0][0]][ms] for ms in times]
        t = clock.stamp(items, [ms * 1e-3 for ms in times])
        sent = required + tuple(p for p in pairs[NAMED_REQUIRED:] if set(times) <= set(by_name[p[0]]))
        cols = {column: [by_name[name][ms][1].value for ms in times] for name, column in sent}
        setattr(rec, stream, clean_stream(stream, t, cols, rec.dropped))
