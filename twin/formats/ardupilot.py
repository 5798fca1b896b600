"""What ArduPilot's two log formats share: which servo outputs drive the thrusters.

Thrusters: SERVOn_FUNCTION 73 (throttle left) and 74 (throttle right), reversal
from SERVOn_REVERSED (older: RCn_REVERSED 0/1, RCn_REV −1), trim from SERVOn_TRIM /
RCn_TRIM (default 1500 µs); or an explicit mapping
  channels={"left": 1, "right": 3, "reversed": {"left": True, "right": False},
            "trim": {"left": 1500, "right": 1500}}   ("reversed"/"trim" optional).
A reversed channel is mirrored around its trim (pwm' = 2·trim − pwm), so the
Recording always holds "forward thrust = higher PWM". A PWM of 0 (output off) is
treated as missing.

The gyro: ArduPilot logs it (DataFlash IMU's GyrZ, MAVLink ATTITUDE's yawspeed) after its
two-pole Butterworth low-pass at INS_GYRO_FILTER Hz [ArduPilot-INS]. Well below its cut-off such a
filter passes a signal unchanged but late by its group delay at zero frequency, √2/(2π·f_c):
0.056 s at Rover's default 4 Hz, where a boat turns at well under 1 Hz. A log that states its
filter has its gyro read that much earlier, with a note; writing it back to an ArduPilot format
with the same parameter puts the delay back, so a log converted and read again holds the same
stream. A harmonic notch (INS_HNTCH_ENABLE, INS_HNT2_ENABLE) delays the gyro further, by about
(1 − A²)/(Q·ω) per harmonic ω of its base (notch_delay_s: 1 to 2 ms at 80 Hz): said with its
size, not counted.

The GPS: a DataFlash GPS message and a telemetry GPS_RAW_INT are stamped when the autopilot
received the fix, which the receiver computed earlier. Where the log states how much earlier
(SITL's lag, or the GPS delay the autopilot compensates for: GPS_DELAY below), the fixes are read
at that time, and put back on writing, as the gyro is; a delay the log does not state is not
assumed. (A fused GLOBAL_POSITION_INT, read where a telemetry log has no fix, is left as stamped.)
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import TwinError
from ..recording import MOVED, Recording, clean_stream, with_common_origin

FUNCTION_LEFT, FUNCTION_RIGHT = 73, 74  # ArduPilot SERVOn_FUNCTION: ThrottleLeft, ThrottleRight
GYRO_FILTER = "INS_GYRO_FILTER"  # Hz; 0 turns the low-pass off
MIN_CUTOFF_HZ = 1.0  # lower, the filter would hold a boat's turns back by over 0.2 s: a typo, not a tuning
NOTCHES = ("INS_HNTCH_", "INS_HNT2_")  # the first harmonic notch and the second, each with its own shape
# a harmonic notch's base centre (Hz), bandwidth (Hz), attenuation (dB) and harmonics (a bitmask)
NOTCH_SHAPE = ("FREQ", "BW", "ATT", "HMNCS")
# how long before its stamp a GPS fix was taken, as an ArduPilot log states it, with the largest value
# taken: SITL's own lag (SIM_GPS1_LAG_MS; SIM_GPS_LAG_MS before ArduPilot 4.5), then the delay the
# autopilot compensates for (GPS1_DELAY_MS; GPS_DELAY_MS before 4.5; ArduPilot's range 0-250 ms, and
# 0 leaves it to the receiver's driver, which the log does not state) [ArduPilot-GPS]
SIM_GPS_LAG = (("SIM_GPS1_LAG_MS", 1000.0), ("SIM_GPS_LAG_MS", 1000.0))
GPS_DELAY = (("GPS1_DELAY_MS", 250.0), ("GPS_DELAY_MS", 250.0))
GPS_KIND = ("GPS1_TYPE", "GPS_TYPE")  # listed by every ArduPilot with a GPS
UBLOX_KINDS = (1.0, 2.0)  # auto-detected (a u-blox on most boards) and u-blox


# ---------------------------------------------------------------- the gyro's filter and the GPS's lag

def _valid_cutoff_hz(params: dict[str, float]) -> float | None:
    cutoff = params.get(GYRO_FILTER)
    return cutoff if cutoff is not None and math.isfinite(cutoff) and cutoff >= MIN_CUTOFF_HZ else None


def gyro_filter_delay_s(params: dict[str, float]) -> float:
    """How late the gyro of a log with these parameters is on the turn it measures (s): the group
    delay √2/(2π·f_c) of the two-pole low-pass at f_c = INS_GYRO_FILTER (module docstring); 0 where
    the parameter is missing, turns the filter off or is no cut-off ArduPilot runs (below 1 Hz)."""
    cutoff = _valid_cutoff_hz(params)
    return 0.0 if cutoff is None else math.sqrt(2.0) / (2.0 * math.pi * cutoff)


def notch_delay_s(params: dict[str, float], prefix: str = NOTCHES[0]) -> float | None:
    """How much a harmonic notch (parameters `prefix`FREQ, BW, ATT, HMNCS) adds to a turn's delay (s):
    each notch of ArduPilot's design [ArduPilot-INS] (NotchFilter: A = 10^(−att/40), Q from the centre and
    the bandwidth, the same A and Q at every harmonic) delays slow signals by (1 − A²)/(Q·ω_k), ω_k the
    harmonic's centre (rad/s), summed over the harmonics set. At the base frequency the log states; a
    notch that follows the motors moves up from it and delays less, and a digital notch a little less
    again (1.0 ms against 1.15 at 80 Hz, 40 Hz wide, 40 dB, sampled at 400 Hz). One notch per harmonic: a
    notch per motor (INS_HNTCH_OPTS) delays more. None where the log does not state its shape."""
    names = [prefix + field for field in NOTCH_SHAPE]
    if any(name not in params or not math.isfinite(params[name]) for name in names):
        return None
    f0, bandwidth, attenuation, harmonics = (params[name] for name in names)
    if not (f0 > bandwidth / 2.0 > 0.0 and attenuation >= 0.0 and harmonics >= 1):
        return None
    octaves = 2.0 * math.log2(f0 / (f0 - bandwidth / 2.0))
    q = math.sqrt(2.0 ** octaves) / (2.0 ** octaves - 1.0)
    a_sq = 10.0 ** (-attenuation / 20.0)
    bits = int(harmonics)
    return sum((1.0 - a_sq) / (q * 2.0 * math.pi * f0 * (k + 1)) for k in range(bits.bit_length()) if bits >> k & 1)


def _notch_words(params: dict[str, float]) -> str:
    """The harmonic notches a log runs and the delay their stated shapes add (not counted), or ""."""
    on = [prefix for prefix in NOTCHES if params.get(prefix + "ENABLE", 0.0) > 0.0]
    if not on:
        return ""
    delays = [notch_delay_s(params, prefix) for prefix in on]
    which = " and ".join(f"{prefix}ENABLE 1" for prefix in on)
    if any(d is None for d in delays):
        return (f"; its harmonic notch ({which}) delays it further, by an amount this log's parameters do not give, "
                "not counted")
    base = ", ".join(f"{params[prefix + NOTCH_SHAPE[0]]:g}" for prefix in on)
    return (f"; its harmonic notch ({which}) delays it further, by {1e3 * sum(delays):.1f} ms at its {base}-Hz "
            f"base{'s' if len(on) > 1 else ''} (less where it follows the motors up), not counted")


def read_gyro_on_time(rec: Recording) -> None:
    """Move the imu stream of an ArduPilot log to when the turns it measures happened (earlier by
    gyro_filter_delay_s of its parameters), saying so in the notes; a cut-off that is no filter's
    is warned of and the gyro read as stamped."""
    cutoff = rec.parameters.get(GYRO_FILTER)
    if cutoff is None or cutoff == 0.0 or not len(rec.imu):
        return
    delay = gyro_filter_delay_s(rec.parameters)
    if not delay:
        rec.warnings.append(f"gyro: {GYRO_FILTER} {cutoff:g} is no low-pass ArduPilot runs (0 turns it off, else "
                            f"{MIN_CUTOFF_HZ:g} Hz or more): the gyro is read as stamped")
        return
    rec.imu = rec.imu.shifted(delay)
    notch = _notch_words(rec.parameters)
    rec.notes.append(f"{MOVED[0]} ArduPilot's {cutoff:g}-Hz low-pass ({GYRO_FILTER}), which delays a turn "
                     f"by {delay:.3f} s: read {delay:.3f} s earlier{notch}")


def _out_of_range(params: dict[str, float]) -> list[str]:
    return [f"{name} {params[name]:g} ms" for name, top in SIM_GPS_LAG + GPS_DELAY
            if name in params and not (math.isfinite(params[name]) and 0.0 <= params[name] <= top)]


def gnss_delay_s(params: dict[str, float]) -> tuple[float, str | None]:
    """How long before its stamp a GPS fix of a log with these parameters was taken (s), and the
    parameter that says so: SITL's lag where the log has it (0 included: a simulation's truth),
    else a GPS delay above 0; (0, None) where none says it or one is out of its range."""
    if _out_of_range(params):
        return 0.0, None
    for name, _ in SIM_GPS_LAG:
        if name in params:
            return params[name] * 1e-3, name
    for name, _ in GPS_DELAY:
        if params.get(name, 0.0) > 0.0:
            return params[name] * 1e-3, name
    return 0.0, None


def read_fixes_when_taken(rec: Recording) -> None:
    """The GNSS stream of an ArduPilot log, whose fixes are stamped when the autopilot received
    them, at the times they were taken (gnss_delay_s), said in the notes; a delay out of its range
    is warned of, and an autopilot's log that states none is told so."""
    if not len(rec.gnss):
        return
    params = rec.parameters
    bad = _out_of_range(params)
    if bad:
        rec.warnings.append(f"gnss: {', '.join(bad)} is outside what ArduPilot takes (SITL's lag 0-1000 ms, the GPS "
                            "delay 0-250 ms): the fixes are read when logged")
        return
    delay, name = gnss_delay_s(params)
    if delay:
        rec.gnss = rec.gnss.shifted(delay)
        rec.notes.append(f"{MOVED[1]} {delay:.3f} s before it was logged, as the log's {name} says")
    elif name is None and any(k in params for k in GPS_KIND):
        stated = next((n for n, _ in GPS_DELAY if n in params), None)
        kind = next(params[k] for k in GPS_KIND if k in params)
        ublox = "; ArduPilot's for a u-blox 7 or later is 0.12 s" if kind in UBLOX_KINDS else ""
        rec.notes.append("gnss: fixes read when logged; the receiver took each earlier, by an amount this log does "
                         f"not state ({f'{stated} 0' if stated else 'no GPS delay set'} leaves it to the receiver's "
                         f"driver{ublox}); the vessel's sensors.gnss_latency_s describes it")


# ---------------------------------------------------------------- thrusters

def thruster_mapping(params: dict[str, float], channels: dict | None, notes: list[str],
                     warnings: list[str] | None = None) -> dict | None:
    """{"left", "right" (1-based output channels), "reversed": {...}, "trim": {...},
    "from"} from an explicit `channels` dict or the SERVOn_FUNCTION parameters
    (73 = throttle left, 74 = throttle right); None (with a note) if neither. Explicit channels the
    log's own SERVOn_FUNCTION contradict are used, with a warning (appended to `warnings`): a swapped
    pair turns the twin the other way from the boat."""
    found = {side: n for n in range(1, 33) for side, fn in (("left", FUNCTION_LEFT), ("right", FUNCTION_RIGHT))
             if params.get(f"SERVO{n}_FUNCTION") == fn}
    if channels is not None:
        mapping = _explicit(channels)
        if len(found) == 2 and (found["left"], found["right"]) != (mapping["left"], mapping["right"]) \
                and warnings is not None:
            warnings.append(f"channels {mapping['left']},{mapping['right']} given, where the log's parameters put the "
                            f"left throttle on output {found['left']} and the right on {found['right']} "
                            f"(SERVOn_FUNCTION {FUNCTION_LEFT}, {FUNCTION_RIGHT}): the channels given are read")
    else:
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


def set_pwm(rec: Recording, t, raw: dict[int, list], mapping: dict) -> None:
    """Store the thruster PWM, mirrored around the trim where reversed."""
    t = np.asarray(t, dtype=float)
    raw_lr = {side: np.array(raw[mapping[side]], dtype=float) for side in ("left", "right")}
    on = (raw_lr["left"] > 0) & (raw_lr["right"] > 0)  # 0 µs: output off or channel unused
    if not np.all(on):
        rec.dropped.append(("pwm: samples with the output off (0 µs)", int(np.sum(~on))))
    if len(on) and not on.any():
        off = [mapping[side] for side in ("left", "right") if not np.any(raw_lr[side] > 0)]
        outputs = (f"outputs {off[0]} and {off[1]} are off (0 µs) in every sample" if len(off) == 2 else
                   f"output {off[0]} is off (0 µs) in every sample" if off else
                   f"outputs {mapping['left']} and {mapping['right']} are never on (above 0 µs) at once")
        rec.warnings.append(f"{outputs} ({mapping['from']} channels {mapping['left']},{mapping['right']}): no thruster "
                            "PWM read (check --channels LEFT,RIGHT against the outputs the log drives)")
    cols = {}
    for side, pwm in raw_lr.items():
        trim = float(mapping["trim"][side])
        cols[f"{side}_us"] = (2 * trim - pwm if mapping["reversed"][side] else pwm)[on]
    rec.pwm = clean_stream("pwm", t[on], cols, rec.dropped)
    rec.pwm_neutral_us = (float(mapping["trim"]["left"]), float(mapping["trim"]["right"]))
    rec.channels = mapping


# ---------------------------------------------------------------- helpers

def read_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError as exc:
        raise TwinError(f"{path.name}: cannot read ({exc.strerror or exc})") from None


def text(x) -> str:
    return x.decode("ascii", "replace").rstrip("\x00") if isinstance(x, (bytes, bytearray)) else str(x)


def finish(rec: Recording) -> Recording:
    """Common origin; raise if no sample at all is left (read_recording then asks for two in a stream)."""
    if not any(len(s) for s in rec.streams().values()):
        why = "; ".join(f"{reason}: {n}" for reason, n in rec.dropped[:3])
        raise TwinError(f"{Path(rec.source).name}: no usable samples (no GNSS fix, heading, PWM, IMU or battery)"
                        + (f"; dropped {why}" if why else ""))
    return with_common_origin(rec)
