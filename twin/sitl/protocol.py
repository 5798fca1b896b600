"""ArduPilot SITL's JSON physics interface, both directions, as pure functions.

What the bytes are (checked against ArduPilot's source, ArduPilot/ardupilot
[ArduPilot-SITL]: `libraries/SITL/SIM_JSON.h`, `SIM_JSON.cpp` and `libraries/SITL/examples/JSON/readme.md`):

- ArduPilot → physics, one UDP datagram per frame, little-endian: `uint16 magic`,
  `uint16 frame_rate` (Hz, SIM_RATE_HZ), `uint32 frame_count`, then `uint16 pwm[16]`
  (magic 18458, 40 bytes) or, with SERVO_32_ENABLE = 1, `uint16 pwm[32]` (magic 29569,
  72 bytes). PWM in µs; an unused or disabled output is 0. `frame_count` goes up by one
  per frame ArduPilot receives an answer to, starts again when SITL restarts, and is sent
  again unchanged when no answer came within a second (SIM_JSON.cpp recv_fdm).
- physics → ArduPilot, to the address the frame came from: one JSON object preceded and
  followed by "\\n". Required: `timestamp` (s, absolute physics time), `imu.gyro` (rad/s,
  body), `imu.accel_body` (m/s², body, specific force), `position` (m, NED), `velocity`
  (m/s, NED), and `attitude` (roll, pitch, yaw, rad) or `quaternion` (w, x, y, z; wins
  when both are sent).

How the reply is written, and why: ArduPilot's parser is not a JSON parser. For every
key it `strstr`s the section, then the key, skips `strlen(key) + 2` characters (the
closing quote and the colon) and `sscanf`s `[%f, %f, %f]` or `atof`s a number. So the
reply is compact (no space after a colon: one would be read as part of the skip), no key
may contain another key's name, and the arrays are plain numbers. Both `attitude` and
`quaternion` are sent: older ArduPilot versions read only the Euler angles, newer ones
prefer the quaternion; they describe the same rotation. Numbers are written with 17
significant digits (`%.17g`), which give back every double exactly, so a reply holds the
twin's doubles and a lock-step run can be compared bit for bit with an offline one; a
fixed precision formats faster than the shortest round-trip `repr`.
"""
from __future__ import annotations

import json
import math
import struct
from typing import NamedTuple, Sequence

MAGIC_16 = 18458  # servo_packet with pwm[16] (SIM_JSON.h)
MAGIC_32 = 29569  # servo_packet_32 with pwm[32] (readme: SERVO_32_ENABLE = 1)
HEADER = struct.Struct("<HHI")  # magic, frame_rate, frame_count
PACKET_16 = struct.Struct("<HHI16H")
PACKET_32 = struct.Struct("<HHI32H")
PACKETS = {MAGIC_16: PACKET_16, MAGIC_32: PACKET_32}
SIZES = {MAGIC_16: PACKET_16.size, MAGIC_32: PACKET_32.size}  # 40 and 72 bytes

# Reasons a datagram is ignored (the server counts each).
SHORT, LONG, MAGIC, RATE = "short packet", "long packet", "unknown magic", "zero frame rate"
REASONS = (SHORT, LONG, MAGIC, RATE)


class PacketError(ValueError):
    """A datagram that is not a servo packet: `reason` is one of REASONS."""

    def __init__(self, reason: str, detail: str = "") -> None:
        super().__init__(f"{reason}{': ' + detail if detail else ''}")
        self.reason = reason


class ServoFrame(NamedTuple):
    """One servo packet: requested physics rate (Hz), frame counter, PWM per output (µs, 0 = off)."""

    frame_rate_hz: int
    frame_count: int
    pwm_us: tuple[int, ...]


class Reply(NamedTuple):
    """The state the physics sends back, in the units and frames of the protocol.

    The twin is planar (north, east, yaw), so roll, pitch, their rates, the down
    position and down velocity are zero and are not carried here."""

    timestamp_s: float
    north_m: float
    east_m: float
    yaw_rad: float  # in [−π, π]
    vn_m_s: float
    ve_m_s: float
    yaw_rate_rad_s: float
    ax_m_s2: float  # specific force, body FRD
    ay_m_s2: float
    az_m_s2: float

    def as_dict(self) -> dict:
        """The reply as the JSON object it is sent as (nested as ArduPilot reads it)."""
        return json.loads(format_reply(self))


# ---------------------------------------------------------------- ArduPilot → physics

def parse_servo_packet(data: bytes) -> ServoFrame:
    """A servo packet's fields; PacketError (with its reason) for anything else.

    The magic decides the expected length (40 bytes for 16 outputs, 72 for 32): a
    datagram shorter than its magic says is cut short, a longer one is not ArduPilot's.
    A frame rate of 0 is refused because the physics step is its inverse."""
    n = len(data)
    if n < HEADER.size:
        raise PacketError(SHORT, f"{n} bytes")
    magic, rate, count = HEADER.unpack_from(data)
    packet = PACKETS.get(magic)
    if packet is None:
        raise PacketError(MAGIC, f"{magic} (expected {MAGIC_16} or {MAGIC_32})")
    if n != packet.size:
        raise PacketError(SHORT if n < packet.size else LONG, f"{n} bytes for magic {magic} ({packet.size} expected)")
    if rate == 0:
        raise PacketError(RATE)
    fields = packet.unpack(data)
    return ServoFrame(rate, count, fields[3:])


def pack_servo_packet(frame_rate_hz: int, frame_count: int, pwm_us: Sequence[int]) -> bytes:
    """The packet ArduPilot sends (for test clients and benchmarks): 16 outputs or 32."""
    if len(pwm_us) == 16:
        return PACKET_16.pack(MAGIC_16, frame_rate_hz, frame_count, *pwm_us)
    if len(pwm_us) == 32:
        return PACKET_32.pack(MAGIC_32, frame_rate_hz, frame_count, *pwm_us)
    raise ValueError(f"a servo packet carries 16 or 32 outputs, not {len(pwm_us)}")


# ---------------------------------------------------------------- physics → ArduPilot

_TEMPLATE = ('\n{"timestamp":%.17g,"imu":{"gyro":[0.0,0.0,%.17g],"accel_body":[%.17g,%.17g,%.17g]},'
             '"position":[%.17g,%.17g,0.0],"velocity":[%.17g,%.17g,0.0],"attitude":[0.0,0.0,%.17g],'
             '"quaternion":[%.17g,0.0,0.0,%.17g]}\n')


def format_reply(r: Reply) -> bytes:
    """The JSON line ArduPilot reads ("\\n" before and after; see the module docstring).

    A %-template rather than json.dumps: this runs once per frame, over a thousand times a
    second, and a template is several times faster than building and serialising a dict."""
    half = 0.5 * r.yaw_rad
    return (_TEMPLATE % (r.timestamp_s, r.yaw_rate_rad_s, r.ax_m_s2, r.ay_m_s2, r.az_m_s2, r.north_m, r.east_m,
                         r.vn_m_s, r.ve_m_s, r.yaw_rad, math.cos(half), math.sin(half))).encode("ascii")


def parse_reply(data: bytes) -> dict:
    """A reply as a dict (test clients, benchmarks): the framing newlines are required."""
    text = data.decode("ascii")
    if not (text.startswith("\n") and text.endswith("\n")):
        raise ValueError("a reply is framed by newlines")
    return json.loads(text)
