"""ArduPilot logs → Recording: telemetry logs (.tlog) and DataFlash logs (.bin).

tlog: a sequence of [8-byte big-endian receive time, µs since 1970][MAVLink 1 or 2
packet]. Packets are framed here and decoded with pymavlink's ardupilotmega
dialect (MAVLink.decode); pymavlink's own file reader is not used for tlogs
because it loses the framing for good on non-MAVLink records (the SITL log starts
with some) and then spends seconds scanning for timestamps, and because it
switches the wire protocol through a process-wide environment variable. Every
packet's CRC is checked (bad packets are counted, then the reader re-synchronises
on the next marker byte); only the wanted messages are decoded:
  GPS_RAW_INT (fix_type ≥ 3 only; GLOBAL_POSITION_INT if the log has no usable
  GPS_RAW_INT), ATTITUDE (yaw, yawspeed), SERVO_OUTPUT_RAW, PARAM_VALUE, SYS_STATUS.
Sample times are the vehicle's boot clock (time_boot_ms / time_usec) where it agrees
with the receive clock within 1 s, else the receive time mapped onto the boot clock:
the link's latency jitter would otherwise show up in the velocities.

DataFlash: read with pymavlink's DFReader_binary (current TimeUS and legacy TimeMS
layouts; its per-message `_timestamp` is one clock for all messages):
GPS (Status ≥ 3, instance 0), ATT (Yaw in degrees), RCOU (C1..C14 or legacy
Ch1..Ch12), PARM, BAT (instance 0) or legacy CURR, IMU (GyrZ, instance 0).

Thrusters: SERVOn_FUNCTION 73 (throttle left) and 74 (throttle right), reversal
from SERVOn_REVERSED (older: RCn_REVERSED 0/1, RCn_REV −1), trim from SERVOn_TRIM /
RCn_TRIM (default 1500 µs); or an explicit mapping
  channels={"left": 1, "right": 3, "reversed": {"left": True, "right": False},
            "trim": {"left": 1500, "right": 1500}}   ("reversed"/"trim" optional).
A reversed channel is mirrored around its trim (pwm' = 2·trim − pwm), so the
Recording always holds "forward thrust = higher PWM". A PWM of 0 (output off) is
treated as missing.
"""
from __future__ import annotations

import contextlib
import io
import os
import re
import sys
import tempfile
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np

from ..errors import TwinError
from .recording import Recording, clean_stream, with_common_origin

FUNCTION_LEFT, FUNCTION_RIGHT = 73, 74  # ArduPilot SERVOn_FUNCTION: ThrottleLeft, ThrottleRight
TLOG_WANTED = ("GPS_RAW_INT", "GLOBAL_POSITION_INT", "ATTITUDE", "SERVO_OUTPUT_RAW", "PARAM_VALUE", "SYS_STATUS")
DF_WANTED = ["GPS", "ATT", "RCOU", "PARM", "BAT", "CURR", "IMU"]
_MARKER = re.compile(b"[\xfd\xfe]")
_MAX_JUMP_US = 3 * 24 * 3600 * 1_000_000  # a receive time further than this from the last good one is garbage
_CLOCK_TOLERANCE_S = 1.0


# ---------------------------------------------------------------- tlog framing

def iter_tlog(data: bytes, wanted: tuple[str, ...], counts: Counter):
    """Yield (receive time s, decoded message) for the wanted message names.

    `counts` receives "packets" (good ones), "bad_crc" (packets at a packet boundary whose CRC fails),
    "skipped_bytes" (bytes outside any valid record) and "truncated" (1 if the
    file ends inside a packet)."""
    from pymavlink.dialects.v20 import ardupilotmega as mavlink2

    mav = mavlink2.MAVLink(None)
    wanted_ids = {mid for mid, cls in mavlink2.mavlink_map.items() if cls.msgname in wanted}
    pos, n, last_us, synced = 0, len(data), None, True
    while pos + 16 <= n:
        size = _frame_size(data, pos + 8, n)
        ts = int.from_bytes(data[pos:pos + 8], "big")
        if size and pos + 8 + size > n and synced:
            counts["truncated"] += 1
            break
        if size and pos + 8 + size <= n and (last_us is None or abs(ts - last_us) < _MAX_JUMP_US):
            status, msg = _check_frame(mav, mavlink2, data[pos + 8:pos + 8 + size], wanted_ids)
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
    from pymavlink.generator.mavcrc import x25crc

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


# ---------------------------------------------------------------- tlog → Recording

def read_tlog(path: Path, channels: dict | None) -> Recording:
    """Read a MAVLink telemetry log; see the module docstring."""
    data = _read_bytes(path)
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
    rec.parameters = {_text(m.param_id): float(m.param_value) for _, m in msgs["PARAM_VALUE"]}
    _tlog_gnss(rec, msgs, clock)
    att = msgs["ATTITUDE"]
    t_att = clock.stamp(att, [m.time_boot_ms * 1e-3 for _, m in att])
    rec.heading = clean_stream("heading", t_att, {"psi_rad": [m.yaw for _, m in att]}, rec.dropped)
    rec.imu = clean_stream("imu", t_att, {"yaw_rate_rads": [m.yawspeed for _, m in att]}, rec.dropped)
    _tlog_pwm(rec, msgs, clock, channels)
    _tlog_battery(rec, msgs, clock)
    rec.meta["clock"] = "vehicle boot time" if len(clock.recv) else "tlog receive time"
    return _finish(rec)


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


def _tlog_gnss(rec: Recording, msgs: dict[str, list], clock: _BootClock) -> None:
    raw = msgs["GPS_RAW_INT"]
    fixed = [(t, m) for t, m in raw if m.fix_type >= 3 and (m.lat or m.lon)]
    if raw and len(fixed) < len(raw):
        rec.dropped.append(("gnss: GPS_RAW_INT without a 3-D fix", len(raw) - len(fixed)))
    if fixed:
        t = clock.stamp(fixed, [m.time_usec * 1e-6 for _, m in fixed])
        cols = {"lat_deg": [m.lat * 1e-7 for _, m in fixed], "lon_deg": [m.lon * 1e-7 for _, m in fixed],
                "alt_m": [m.alt * 1e-3 for _, m in fixed]}
        rec.gnss = clean_stream("gnss", t, cols, rec.dropped)
        return
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


def _tlog_pwm(rec: Recording, msgs: dict[str, list], clock: _BootClock, channels: dict | None) -> None:
    servo = [(t, m) for t, m in msgs["SERVO_OUTPUT_RAW"] if m.port == 0]
    mapping = thruster_mapping(rec.parameters, channels, rec.notes)
    if mapping is None or not servo:
        if mapping is not None:
            rec.notes.append("no SERVO_OUTPUT_RAW messages: no thruster PWM")
        return
    t = clock.stamp(servo, [(m.time_usec % 2**32) * 1e-6 for _, m in servo])
    raw = {ch: [getattr(m, f"servo{ch}_raw", 0) for _, m in servo] for ch in (mapping["left"], mapping["right"])}
    _set_pwm(rec, t, raw, mapping)


def _tlog_battery(rec: Recording, msgs: dict[str, list], clock: _BootClock) -> None:
    status = [(t, m) for t, m in msgs["SYS_STATUS"] if 0 < m.voltage_battery < 65535]  # mV; 0/65535: unknown
    missing = len(msgs["SYS_STATUS"]) - len(status)
    if missing:
        rec.dropped.append(("battery: SYS_STATUS without a voltage (0 or unknown)", missing))
    if status:  # SYS_STATUS has no time field of its own: the mapped receive time
        volts = [m.voltage_battery * 1e-3 for _, m in status]
        rec.battery = clean_stream("battery", clock.stamp(status), {"voltage_v": volts}, rec.dropped)


# ---------------------------------------------------------------- DataFlash → Recording

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
    imu = [m for m in rows["IMU"] if _instance(m) == 0 and hasattr(m, "GyrZ")]
    rec.imu = clean_stream("imu", [m._timestamp for m in imu], {"yaw_rate_rads": [m.GyrZ for m in imu]}, rec.dropped)
    _df_pwm(rec, rows["RCOU"], channels)
    _df_battery(rec, rows)
    return _finish(rec)


def _df_messages(path: Path) -> tuple[dict[str, list], list[tuple[str, int]]]:
    """The wanted messages by type, and what DFReader complained about. It prints
    its complaints (bad headers, skipped bytes; its Cython indexer straight to
    file descriptor 2): they are captured and counted instead."""
    from pymavlink import DFReader

    rows: dict[str, list] = defaultdict(list)
    stopped = 0
    with _captured_output() as out:
        try:
            log = DFReader.DFReader_binary(str(path), zero_time_base=False)
        except Exception as exc:  # empty, truncated header, not DataFlash: pymavlink raises anything
            raise TwinError(f"{path.name}: not a readable DataFlash log ({type(exc).__name__})") from None
        while True:
            try:
                m = log.recv_match(type=DF_WANTED)
            except Exception:
                stopped = 1
                break
            if m is None:
                break
            rows[m.get_type()].append(m)
    text = out.getvalue()
    dropped = [(reason, n) for reason, n in (
        ("dataflash: bad message headers skipped", text.count("bad header")),
        ("dataflash: unparseable messages", text.count("Failed to parse") + text.count("bad msg")),
        ("dataflash: unreadable rest of the log", stopped),
        ("dataflash: last message cut short (the log is truncated)", int(_ends_inside_a_message(log)))) if n]
    return rows, dropped


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
    mapping = thruster_mapping(rec.parameters, channels, rec.notes)
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
    _set_pwm(rec, [m._timestamp for m in rcou], raw, mapping)


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


# ---------------------------------------------------------------- thrusters

def thruster_mapping(params: dict[str, float], channels: dict | None, notes: list[str]) -> dict | None:
    """{"left", "right" (1-based output channels), "reversed": {...}, "trim": {...},
    "from"} from an explicit `channels` dict or the SERVOn_FUNCTION parameters
    (73 = throttle left, 74 = throttle right); None (with a note) if neither."""
    if channels is not None:
        mapping = _explicit(channels)
    else:
        found = {side: n for n in range(1, 33) for side, fn in (("left", FUNCTION_LEFT), ("right", FUNCTION_RIGHT))
                 if params.get(f"SERVO{n}_FUNCTION") == fn}
        if len(found) < 2:
            notes.append("no thruster channels: the parameters have no SERVOn_FUNCTION = 73 and 74 "
                         "(throttle left/right); pass --channels LEFT,RIGHT (Python: channels={'left': n, 'right': m})")
            return None
        mapping = {"left": found["left"], "right": found["right"], "reversed": {}, "trim": {},
                   "from": "SERVOn_FUNCTION"}
    for side in ("left", "right"):
        n = mapping[side]
        mapping["reversed"].setdefault(side, _reversed(params, n))
        mapping["trim"].setdefault(side, params.get(f"SERVO{n}_TRIM", params.get(f"RC{n}_TRIM", 1500.0)))
    return mapping


def _explicit(channels: dict) -> dict:
    if not isinstance(channels, dict) or set(channels) - {"left", "right", "reversed", "trim"}:
        raise TwinError("channels must be a dict with keys left, right and optionally reversed, trim")
    try:
        left, right = int(channels["left"]), int(channels["right"])
    except (KeyError, TypeError, ValueError):
        raise TwinError("channels needs integer output channel numbers for 'left' and 'right'") from None
    if not (1 <= left <= 32 and 1 <= right <= 32) or left == right:
        raise TwinError(f"channels: left={left}, right={right} must be two different channels in 1..32")
    rev = dict(channels.get("reversed") or {})
    trim = {k: float(v) for k, v in dict(channels.get("trim") or {}).items()}
    return {"left": left, "right": right, "reversed": {k: bool(v) for k, v in rev.items()}, "trim": trim,
            "from": "explicit"}


def _reversed(params: dict[str, float], n: int) -> bool:
    if f"SERVO{n}_REVERSED" in params:
        return params[f"SERVO{n}_REVERSED"] == 1
    if f"RC{n}_REVERSED" in params:
        return params[f"RC{n}_REVERSED"] == 1
    return params.get(f"RC{n}_REV", 1.0) == -1  # before 3.x: RCn_REV = −1 means reversed


def _set_pwm(rec: Recording, t, raw: dict[int, list], mapping: dict) -> None:
    """Store the thruster PWM, mirrored around the trim where reversed."""
    t = np.asarray(t, dtype=float)
    raw_lr = {side: np.array(raw[mapping[side]], dtype=float) for side in ("left", "right")}
    on = (raw_lr["left"] > 0) & (raw_lr["right"] > 0)  # 0 µs: output off or channel unused
    if not np.all(on):
        rec.dropped.append(("pwm: samples with the output off (0 µs)", int(np.sum(~on))))
    cols = {}
    for side, pwm in raw_lr.items():
        trim = float(mapping["trim"][side])
        cols[f"{side}_us"] = (2 * trim - pwm if mapping["reversed"][side] else pwm)[on]
    rec.pwm = clean_stream("pwm", t[on], cols, rec.dropped)
    rec.pwm_neutral_us = (float(mapping["trim"]["left"]), float(mapping["trim"]["right"]))
    rec.channels = mapping


# ---------------------------------------------------------------- helpers

def _read_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError as exc:
        raise TwinError(f"{path.name}: cannot read ({exc.strerror or exc})") from None


def _text(x) -> str:
    return x.decode("ascii", "replace").rstrip("\x00") if isinstance(x, (bytes, bytearray)) else str(x)


def _finish(rec: Recording) -> Recording:
    """Common origin; raise if no sample at all is left (read_recording then asks for two in a stream)."""
    if not any(len(s) for s in rec.streams().values()):
        why = "; ".join(f"{reason}: {n}" for reason, n in rec.dropped[:3])
        raise TwinError(f"{Path(rec.source).name}: no usable samples (no GNSS fix, heading, PWM, IMU or battery)"
                        + (f"; dropped {why}" if why else ""))
    return with_common_origin(rec)
