"""Runs and recordings as ArduPilot DataFlash logs (.bin), the format the
vehicle writes, so that log viewers and this project's readers open them.

A DataFlash log is a sequence of messages [0xA3 0x95 type][payload]; the
first messages are FMT records that describe every type, FMT included.
Written here: PARM (a recording's own parameters, then the thruster functions
73/74 on channels 1/3 as ArduRover, and their trims), GPS (lat/lon 1e-7 deg,
alt cm), ATT (heading, roll and pitch, centidegrees), RCOU (integer µs), IMU (GyrZ, rad/s),
BAT (Volt), and for a propeller-and-rudder ship and a measured wind the log's own types SHIP
(Prop rps, Rudder rad) and WNDM (Spd m/s, From deg; the wind measured on board, where there is
one, as WNDR at the same times), float32, each message at its own sample time (TimeUS, µs).
A run is sampled as a boat's sensors would log it: GPS at the antenna (5 Hz, with
the lever arm), ATT and IMU 50 Hz, RCOU 10 Hz (telemetry.sample).
Read back, a log that states its gyro's low-pass or its GPS delay has that stream at the times it
measured (formats.ardupilot), and a recording with those parameters is written with the delays put
back.
"""
from __future__ import annotations

import contextlib
import io
import os
import struct
import sys
import tempfile
from collections import defaultdict
from pathlib import Path

import numpy as np

from ..errors import TwinError
from ..files import write_bytes_atomic
from ..recording import Recording, clean_stream
from ..run import Run
from .ardupilot import (finish, gnss_delay_s, gyro_filter_delay_s, read_fixes_when_taken, read_gyro_on_time,
                        set_pwm, thruster_mapping)
from .telemetry import DEFAULT_ORIGIN, LEFT_CHANNEL, RIGHT_CHANNEL, THRUSTER_PARAMS, log_parameters, sample

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
    "IMU": (68, "QBfff", "TimeUS,I,GyrX,GyrY,GyrZ"),
    "BAT": (69, "QBf", "TimeUS,Inst,Volt"),
    # a ship's inputs and a measured wind, which ArduPilot has no message for (a log defines its own types)
    "SHIP": (70, "Qff", "TimeUS,Prop,Rudder"),
    "WNDM": (71, "Qff", "TimeUS,Spd,From"),
    "WNDR": (72, "Qff", "TimeUS,Spd,From"),  # the wind measured on board (relative), at WNDM's times
}
GPS_EPOCH_UNIX_S = 315964800.0
LEAP_S = 18.0
# GPS week 0, time 0 at the log's time 0: a simulated run claims no calendar day (read back, its
# origin is 0, not a date that `twin fleet` would take for the day it was logged)
NO_CALENDAR_UNIX_S = GPS_EPOCH_UNIX_S - LEAP_S
CALENDAR_UNIX_S = (946684800.0, 4102444800.0)  # 2000-2100: an origin in this span is a calendar time


def _message(name: str, *values) -> bytes:
    type_id, fmt, _ = FORMATS[name]
    return HEAD + bytes([type_id]) + struct.pack("<" + "".join(PACK[c] for c in fmt), *values)


def _fmt_record(name: str) -> bytes:
    type_id, fmt, cols = FORMATS[name]
    length = 3 + sum(SIZES[c] for c in fmt)
    return _message("FMT", type_id, length, name.encode(), fmt.encode(), cols.encode())


def dataflash_bytes(run: Run, antenna_body_m=(0.0, 0.0), origin=DEFAULT_ORIGIN,
                    start_unix_s: float = NO_CALENDAR_UNIX_S, **rates) -> bytes:
    tel = sample(run, antenna_body_m, origin, **rates)
    timed = _parameters(THRUSTER_PARAMS)
    timed += _gps(tel.gnss_t, tel.lat_deg, tel.lon_deg, np.zeros(len(tel.gnss_t)), tel.speed_m_s, start_unix_s,
                  tel.course_deg())
    timed += (_attitude(tel.heading_t, tel.psi_rad, *tel.attitude()) + _imu(tel.heading_t, tel.r_rad_s)
              + _rcou(tel.pwm_t, tel.pwm_us))
    return _log_bytes(timed)


def write_run_bin(run: Run, path, **kwargs) -> None:
    """Write the run as a DataFlash .bin atomically (temporary name, then rename)."""
    write_bytes_atomic(path, dataflash_bytes(run, **kwargs))


def recording_bytes(rec: Recording, start_unix_s: float | None = None) -> bytes:
    """A recording whose times are ≥ 0, whose gnss stream has lat_deg/lon_deg and whose psi_rad
    is wrapped (twin.formats.write_recording prepares it) as a DataFlash log; TwinError where a value
    does not fit its field. start_unix_s: the GPS clock (as Unix time) at the log's time 0; None: the
    recording's own origin where it is a calendar time (a converted log keeps its day), else none
    claimed (NO_CALENDAR_UNIX_S)."""
    if start_unix_s is None:
        dated = CALENDAR_UNIX_S[0] <= rec.origin_s <= CALENDAR_UNIX_S[1]
        start_unix_s = rec.origin_s if dated else NO_CALENDAR_UNIX_S
    g, h, p, imu, bat = rec.gnss, rec.heading, rec.pwm, rec.imu, rec.battery
    pwm = np.column_stack([p["left_us"], p["right_us"]]) if len(p) else np.zeros((0, 2))
    _check_range("PWM (µs)", np.round(pwm), 1, 65535)
    timed = _parameters(log_parameters(rec.parameters, rec.pwm_neutral_us, with_pwm=len(p) > 0))
    if len(g):
        alt = g["alt_m"] if g.has("alt_m") else np.zeros(len(g))
        # logged when received (formats.ardupilot): the delay put back
        timed += _gps(g.t + gnss_delay_s(rec.parameters)[0], g["lat_deg"], g["lon_deg"], alt, np.zeros(len(g)),
                      start_unix_s)
    if len(h):
        att = rec.attitude  # roll and pitch where the recording has them, at the heading's times
        unknown = np.full(len(h), np.nan)  # a log without them is not a level one (UNKNOWN_CDEG)
        timed += _attitude(h.t, h["psi_rad"], np.interp(h.t, att.t, att["roll_rad"]) if len(att) else unknown,
                           np.interp(h.t, att.t, att["pitch_rad"]) if len(att) else unknown)
    if len(imu):  # ArduPilot's gyro is stamped its filter's delay after the turn (formats.ardupilot): put it back
        timed += _imu(imu.t + gyro_filter_delay_s(rec.parameters), imu["yaw_rate_rads"])
    if len(bat):
        timed += [(_us(t), _message("BAT", _us(t), 0, float(v))) for t, v in zip(bat.t, bat["voltage_v"])]
    ship, wind = rec.prop_rudder, rec.wind
    if len(ship):
        timed += [(_us(t), _message("SHIP", _us(t), float(n), float(d)))
                  for t, n, d in zip(ship.t, ship["n_rps"], ship["delta_rad"])]
    if len(wind):
        timed += [(_us(t), _message("WNDM", _us(t), float(v), float(f)))
                  for t, v, f in zip(wind.t, wind["speed_m_s"], wind["from_deg"])]
    if len(wind) and wind.has("relative_speed_m_s", "relative_from_deg"):
        timed += [(_us(t), _message("WNDR", _us(t), float(v), float(f)))
                  for t, v, f in zip(wind.t, wind["relative_speed_m_s"], wind["relative_from_deg"])]
    return _log_bytes(timed + _rcou(p.t, pwm))


def write_recording_bin(rec: Recording, path) -> None:
    """Write the recording as a DataFlash .bin atomically (see recording_bytes)."""
    write_bytes_atomic(path, recording_bytes(rec))


# ---------------------------------------------------------------- messages: (TimeUS, bytes)

def _us(t_s: float) -> int:
    return int(round(t_s * 1e6))


def _parameters(params: dict[str, float]) -> list[tuple[int, bytes]]:
    return [(0, _message("PARM", 0, name.encode()[:16], float(value))) for name, value in params.items()]


def _gps(t_s, lat_deg, lon_deg, alt_m, speed_m_s, start_unix_s: float, course_deg=None) -> list[tuple[int, bytes]]:
    out = []
    course_deg = np.zeros(len(t_s)) if course_deg is None else np.nan_to_num(course_deg)
    for t, la, lo, h, v, c in zip(t_s, lat_deg, lon_deg, alt_m, speed_m_s, course_deg):
        gps_s = start_unix_s + t - GPS_EPOCH_UNIX_S + LEAP_S
        us = _us(t)
        out.append((us, _message("GPS", us, 0, 3, int(round((gps_s % 604800) * 1000)), int(gps_s // 604800), 12, 80,
                                 int(round(la * 1e7)), int(round(lo * 1e7)), int(round(h * 100)),
                                 float(v) if np.isfinite(v) else 0.0, float(c))))
    return out


def _attitude(t_s, psi_rad, roll_rad, pitch_rad) -> list[tuple[int, bytes]]:
    return [(_us(t), _message("ATT", _us(t), 0, _cdeg(phi), 0, _cdeg(theta), 0,
                              int(round(np.degrees(psi) % 360.0 * 100)) % 36000, 0, 0))
            for t, psi, phi, theta in zip(t_s, psi_rad, roll_rad, pitch_rad)]


# ATT's int16 centidegrees for a roll or pitch not measured: −327.68°, beyond any attitude, which the
# reader takes as none
UNKNOWN_CDEG = -32768


def _cdeg(angle_rad: float) -> int:
    """An angle in ATT's int16 centidegrees (UNKNOWN_CDEG for NaN: not measured)."""
    return int(round(np.degrees(angle_rad) * 100)) if np.isfinite(angle_rad) else UNKNOWN_CDEG


def _angle_rad(deg: float) -> float:
    """An ATT roll or pitch (deg) in rad; NaN beyond ±180° (UNKNOWN_CDEG: not measured)."""
    return float(np.radians(deg)) if abs(deg) <= 180.0 else float("nan")


def _imu(t_s, yaw_rate_rads) -> list[tuple[int, bytes]]:
    return [(_us(t), _message("IMU", _us(t), 0, 0.0, 0.0, float(r))) for t, r in zip(t_s, yaw_rate_rads)]


def _rcou(t_s, pwm_us) -> list[tuple[int, bytes]]:
    out = []
    for t, (left, right) in zip(t_s, pwm_us):
        ch = [0] * 14
        ch[LEFT_CHANNEL - 1], ch[RIGHT_CHANNEL - 1] = int(round(left)), int(round(right))
        out.append((_us(t), _message("RCOU", _us(t), *ch)))
    return out


def _log_bytes(timed: list[tuple[int, bytes]]) -> bytes:
    timed.sort(key=lambda item: item[0])  # stable: parameters first at 0
    return b"".join([_fmt_record(n) for n in FORMATS] + [m for _, m in timed])


def _check_range(what: str, values: np.ndarray, lo: float, hi: float) -> None:
    bad = (values < lo) | (values > hi)
    if np.any(bad):
        raise TwinError(f"bin: {what} {values[bad][0]:g} does not fit DataFlash's range {lo:g}..{hi:g}")


# ---------------------------------------------------------------- reading
# Read with pymavlink's DFReader_binary (current TimeUS and legacy TimeMS layouts; its
# per-message `_timestamp` is one clock for all messages): GPS (Status ≥ 3, instance 0),
# ATT (Yaw in degrees), RCOU (C1..C14 or legacy Ch1..Ch12), PARM, BAT (instance 0) or
# legacy CURR, IMU (GyrZ, instance 0), SHIP and WNDM (this project's own, above).

DF_WANTED = ["GPS", "ATT", "RCOU", "PARM", "BAT", "CURR", "IMU", "SHIP", "WNDM", "WNDR"]


def read_dataflash(path: Path, channels: dict | None) -> Recording:
    """Read an ArduPilot DataFlash .bin log; see the module docstring."""
    rows, dropped = _df_messages(path)
    if not any(rows.values()):
        raise TwinError(f"{path.name}: no readable DataFlash messages (not a DataFlash log?)")
    rec = Recording(source=str(path), kind="dataflash", dropped=dropped)
    rec.parameters = {str(m.Name): float(m.Value) for m in rows["PARM"]}
    _df_gnss(rec, rows["GPS"])
    att = rows["ATT"]
    rec.heading = clean_stream("heading", [m._timestamp for m in att],
                               {"psi_rad": [np.radians(m.Yaw) for m in att]}, rec.dropped)
    if att and hasattr(att[0], "Roll") and hasattr(att[0], "Pitch"):
        rec.attitude = clean_stream("attitude", [m._timestamp for m in att], {
            "roll_rad": [_angle_rad(m.Roll) for m in att], "pitch_rad": [_angle_rad(m.Pitch) for m in att]}, [])
    imu = [m for m in rows["IMU"] if _instance(m) == 0 and hasattr(m, "GyrZ")]
    rec.imu = clean_stream("imu", [m._timestamp for m in imu], {"yaw_rate_rads": [m.GyrZ for m in imu]}, rec.dropped)
    _df_pwm(rec, rows["RCOU"], channels)
    _df_battery(rec, rows)
    ship, wind = rows["SHIP"], rows["WNDM"]
    if ship:
        rec.prop_rudder = clean_stream("prop_rudder", [m._timestamp for m in ship], {
            "n_rps": [m.Prop for m in ship], "delta_rad": [m.Rudder for m in ship]}, rec.dropped)
    if wind:
        cols = {"speed_m_s": [m.Spd for m in wind], "from_deg": [m.From for m in wind]}
        relative = rows.get("WNDR", [])
        if [m.TimeUS for m in relative] == [m.TimeUS for m in wind]:  # written beside each true wind, or not at all
            cols |= {"relative_speed_m_s": [m.Spd for m in relative], "relative_from_deg": [m.From for m in relative]}
        rec.wind = clean_stream("wind", [m._timestamp for m in wind], cols, rec.dropped)
    read_gyro_on_time(rec)
    read_fixes_when_taken(rec)
    return finish(rec)


def _df_messages(path: Path) -> tuple[dict[str, list], list[tuple[str, int]]]:
    """The wanted messages by type, and what DFReader complained about. It prints
    its complaints (bad headers, skipped bytes; its Cython indexer straight to
    file descriptor 2): they are captured and counted instead."""
    # late: DFReader imports pymavlink.mavutil, which sets MAVLINK_DIALECT in os.environ (twin.sitl.ardupilot)
    from pymavlink import DFReader

    rows: dict[str, list] = defaultdict(list)
    stopped = 0
    with _captured_output() as out, tempfile.TemporaryDirectory() as spare:
        try:
            log = DFReader.DFReader_binary(str(path), zero_time_base=False)
            unread = []
        except Exception as exc:  # empty, truncated header, not DataFlash: pymavlink raises anything
            why = f"{type(exc).__name__}: {exc}".splitlines()[0] if str(exc).strip() else type(exc).__name__
            log, unread = _without_damaged_formats(path, Path(spare), DFReader)
            if log is None:
                raise TwinError(f"{path.name}: not a readable DataFlash log (pymavlink: {why[:120]})") from None
        # DFReader's index stops at the first message of a type no FMT defines (one damaged type byte would
        # cut the log there, silently): such a log is read on from the next valid header past each of them
        # (a log read without its damaged FMT records is read message by message, which steps over them)
        resynced = (0, 0)
        if not unread and _index_stops_early(log, out.getvalue()):
            again, resynced = _resynchronised(path, Path(spare), DFReader)
            if again is not None:
                _close(log)
                log = again
        # DFReader's index of the types stops at a message whose FMT is gone: such a log is read
        # message by message
        wanted = None if unread else DF_WANTED
        while True:
            try:
                m = log.recv_match(type=wanted)
            except Exception:
                stopped = 1
                break
            if m is None:
                break
            if m.get_type() in DF_WANTED:
                rows[m.get_type()].append(m)
    text = out.getvalue()
    try:
        dropped = [(f"dataflash: a damaged FMT record, its {', '.join(unread)} messages left out", len(unread))
                   ] if unread else []
        dropped += [(reason, n) for reason, n in (
            ("dataflash: messages of a type no FMT defines (a damaged byte?) skipped, read on from the next "
             "valid header", resynced[0]),
            ("dataflash: bytes skipped to resynchronise after them", resynced[1]),
            # DFReader says "bad header" at every byte it steps over, those after a skipped message's too
            ("dataflash: bad message headers skipped", max(0, text.count("bad header") - resynced[1])),
            ("dataflash: unparseable messages", text.count("Failed to parse") + text.count("bad msg")),
            ("dataflash: unreadable rest of the log", stopped),
            ("dataflash: last message cut short (the log is truncated)", int(_ends_inside_a_message(log)))) if n]
    finally:
        _close(log)
    return rows, dropped


FMT_HEAD = b"\xa3\x95\x80"  # a FMT record: head, type, length, name[4], format[16], columns[64]
FMT_SIZE = 89
FIELD_TYPES = frozenset(b"abBhHiIfdnNZcCeELMqQ")  # the DataFlash field types a format is written in


def _without_damaged_formats(path: Path, spare: Path, reader) -> tuple[object | None, list[str]]:
    """A log whose FMT records DFReader refuses (a format character no field type has: a damaged
    card's bytes) read without those records, their messages then skipped as unknown: (the reader
    on a copy in `spare`, the names of the types left out); (None, []) where no FMT record is damaged
    so, or the copy cannot be read either."""
    data = bytearray(path.read_bytes())
    unread = []
    at = data.find(FMT_HEAD)
    while 0 <= at <= len(data) - FMT_SIZE:
        fields = bytes(data[at + 9:at + 25]).rstrip(b"\0")
        if not fields or any(c not in FIELD_TYPES for c in fields):
            unread.append(bytes(data[at + 5:at + 9]).rstrip(b"\0").decode("ascii", "replace") or f"type {data[at + 3]}")
            data[at:at + 3] = bytes(3)  # no longer a record: the reader steps over it as junk
        at = data.find(FMT_HEAD, at + 3)
    if not unread:
        return None, []
    copy = spare / path.name
    copy.write_bytes(data)
    try:
        return reader.DFReader_binary(str(copy), zero_time_base=False), unread
    except Exception:  # damaged beyond its formats
        return None, []


TAIL = 528  # DFReader ignores what cannot be read in the last 528 bytes (a card's block padding)


def _index_stops_early(log, said: str) -> bool:
    """True when DFReader's index of the messages ended well before the end of the file: it stops at a
    message of a type no FMT record defines (and says "unknown msg type")."""
    if "unknown msg type" in said:
        return True
    ends = [offsets[-1] + log.formats[mtype].len for mtype, offsets in enumerate(getattr(log, "offsets", None) or [])
            if offsets and mtype in log.formats]
    return bool(ends) and log.data_len - max(ends) >= TAIL


def _undefined_headers(data: bytearray) -> tuple[list[int], int]:
    """Where `data` holds the header of a message whose type no FMT record (up to there) defines, read as
    DFReader indexes a log (a known type steps by its length, anything else byte by byte to the next
    header 0xA3 0x95), and how many bytes lie from each such header to the next valid one; the last
    TAIL bytes aside, as DFReader leaves them."""
    lengths = {FMT_HEAD[2]: FMT_SIZE}
    found, skipped = [], 0
    n, at, since = len(data), 0, None
    while at + 3 <= n:
        if data[at] == HEAD[0] and data[at + 1] == HEAD[1]:
            size = lengths.get(data[at + 2], 0)
            if size >= 3:
                if since is not None:
                    skipped += at - since
                    since = None
                if data[at + 2] == FMT_HEAD[2] and at + 5 <= n:
                    lengths[data[at + 3]] = data[at + 4]
                at += size
                continue
            if n - at < TAIL:
                break
            found.append(at)
            if since is None:
                since = at
        nxt = data.find(HEAD, at + 1)
        if nxt < 0:
            break
        at = nxt
    return found, skipped


def _resynchronised(source: Path, spare: Path, reader) -> tuple[object | None, tuple[int, int]]:
    """A log whose messages of undefined types (_undefined_headers) are made junk bytes, which DFReader
    steps over to the next valid header: (the reader on a copy in `spare`, (messages skipped, bytes
    skipped)); (None, (0, 0)) when there are none or the copy cannot be read."""
    data = bytearray(source.read_bytes())
    found, skipped = _undefined_headers(data)
    if not found:
        return None, (0, 0)
    for at in found:
        data[at:at + 3] = bytes(3)
    copy = spare / f"resynchronised-{source.name}"
    copy.write_bytes(data)
    try:
        return reader.DFReader_binary(str(copy), zero_time_base=False), (len(found), skipped)
    except Exception:  # damaged beyond its types
        return None, (0, 0)


def _close(log) -> None:
    """DFReader keeps its file and its memory map open and has no close: both closed here, so that
    reading a log leaves nothing open."""
    for name in ("data_map", "filehandle"):
        handle = getattr(log, name, None)
        if handle is not None:
            try:
                handle.close()
            except (OSError, ValueError, BufferError):  # already closed, or still viewed: the collector's
                pass


def _ends_inside_a_message(log) -> bool:
    """True when the file ends before the last message it starts (a log cut short: copied
    while written, a full card, a half download). DFReader drops that message silently;
    its index still holds where the message started."""
    starts = [(offsets[-1], mtype) for mtype, offsets in enumerate(getattr(log, "offsets", None) or []) if offsets]
    if not starts:
        return False
    start, mtype = max(starts)
    fmt = log.formats.get(mtype)
    return fmt is not None and start + fmt.len > log.data_len


@contextlib.contextmanager
def _captured_output():
    """Capture sys.stdout/sys.stderr and, briefly, file descriptor 2 (C code)."""
    sink = io.StringIO()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
                yield sink
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            sink.write(tmp.read().decode("utf-8", "replace"))


def _instance(m) -> int:
    for name in ("I", "Instance", "Inst"):
        if name in m.get_fieldnames():
            return int(getattr(m, name))
    return 0


def _df_gnss(rec: Recording, gps: list) -> None:
    first = [m for m in gps if _instance(m) == 0]
    fixed = [m for m in first if m.Status >= 3 and (m.Lat or m.Lng)]
    if len(fixed) < len(first):
        rec.dropped.append(("gnss: GPS without a 3-D fix", len(first) - len(fixed)))
    if not fixed:
        rec.notes.append("no GNSS: no GPS message with a 3-D fix" if first else "no GNSS: the log has no GPS messages")
        return
    cols = {"lat_deg": [m.Lat for m in fixed], "lon_deg": [m.Lng for m in fixed],
            "alt_m": [getattr(m, "Alt", np.nan) for m in fixed]}
    rec.gnss = clean_stream("gnss", [m._timestamp for m in fixed], cols, rec.dropped)


def _df_pwm(rec: Recording, rcou: list, channels: dict | None) -> None:
    mapping = thruster_mapping(rec.parameters, channels, rec.notes, rec.warnings)
    if mapping is None or not rcou:
        if mapping is not None:
            rec.notes.append("no RCOU messages: no thruster PWM")
        return
    fields = rcou[0].get_fieldnames()
    raw = {}
    for ch in (mapping["left"], mapping["right"]):
        name = f"C{ch}" if f"C{ch}" in fields else f"Ch{ch}"  # Ch1..Ch12 in the legacy layout
        if name not in fields:
            raise TwinError(f"{Path(rec.source).name}: RCOU has no output channel {ch}")
        raw[ch] = [getattr(m, name) for m in rcou]
    set_pwm(rec, [m._timestamp for m in rcou], raw, mapping)


def _df_battery(rec: Recording, rows: dict[str, list]) -> None:
    bat = [m for m in rows["BAT"] if _instance(m) == 0]
    t = [m._timestamp for m in bat]
    volt = np.array([m.Volt for m in bat], dtype=float)
    if not bat and rows["CURR"]:
        t = [m._timestamp for m in rows["CURR"]]
        volt = np.array([m.Volt for m in rows["CURR"]], dtype=float)
        if len(volt) and np.median(volt) > 100:  # legacy CURR logged centivolts
            volt = volt / 100
    on = volt > 0  # 0 V: no battery monitor
    if not np.all(on):
        rec.dropped.append(("battery: samples at 0 V (no monitor)", int(np.sum(~on))))
    rec.battery = clean_stream("battery", np.asarray(t, dtype=float)[on], {"voltage_v": volt[on]}, rec.dropped)
