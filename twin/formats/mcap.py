"""Runs and sensor recordings as MCAP files (JSON messages, jsonschema schemas) that
Foxglove can open.

A simulated run (true states), all topics logged at the run time t (s → ns):
  /vessel/pose    foxglove.PoseInFrame  pose in frame "ned": x north, y east (m), yaw ψ about z (down)
  /vessel/state   twin.VesselState      t (s), x, y (m), psi (rad), u, v (m/s), r (rad/s)
  /vessel/inputs  twin.ThrusterInputs   pwm_left/right (µs), thrust_left/right (N); null where NaN
  /vessel/fix     foxglove.LocationFix  latitude, longitude (deg) of the GNSS antenna, the run's local
                                        frame placed at the origin (lat, lon), so Foxglove's map shows it
Metadata record "twin": {"vessel": name, "meta": JSON of the plain str/int/float run.meta entries,
"origin": JSON [lat, lon] deg}.

A sensor recording, each message logged at its own stream's sample time (s → ns ≥ 0):
  /sensors/gnss     foxglove.LocationFix  latitude, longitude (deg), altitude (m) of the antenna,
                                          frame_id "gnss", position_covariance 9 zeros, type 0 (unknown)
  /sensors/heading  twin.Heading          psi_rad (rad, (−π, π], north to east), heading_deg ([0, 360))
  /sensors/pwm      twin.ThrusterPwm      left_us, right_us (µs, forward thrust = higher)
  /sensors/imu      twin.YawRate          yaw_rate_rads (rad/s, gyro z, body FRD)      (if recorded)
  /sensors/battery  twin.Battery          voltage_v (V)                                (if recorded)
  /sensors/prop_rudder twin.PropellerRudder n_rps (rps, > 0 ahead), delta_rad (rad, > 0 to starboard) (if recorded)
  /sensors/wind     twin.Wind             speed_m_s, from_deg (true wind, FROM, clockwise from north) and
                                          relative_speed_m_s, relative_from_deg (apparent, FROM, clockwise
                                          from the bow; where measured)                (if recorded)
  /sensors/attitude twin.Attitude         roll_rad, pitch_rad (rad; a 6-DOF hull's or a log's)  (if recorded)
Metadata record "twin.recording": origin_s (the recording's origin, s, repr), pwm_neutral_us
(JSON [left, right]), source, kind (of the recording written), meta (JSON, plain entries),
parameters (JSON {name: value}, the autopilot's parameters when the source had them).

Both are written with the metadata first and in small chunks, so that a file cut short
(a full disk, a killed logger) still holds its metadata and all but its last chunk:
the readers fall back to streaming the complete records and say what was lost.
"""
from __future__ import annotations

import json
import math
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Channel, Message, Metadata
from mcap.stream_reader import StreamReader
from mcap.writer import Writer

from ..errors import TwinError
from ..files import write_stream_atomic
from ..geodesy import geodetic_from_ned
from ..physics.sensors import antenna_ned
from ..recording import EXACT_ORIGIN, TRACKED_ORIGIN, Recording, Stream, clean_stream, with_common_origin
from ..run import Run
from .telemetry import DEFAULT_ORIGIN


FRAME_ID = "ned"
TOPIC_POSE, TOPIC_STATE, TOPIC_INPUTS, TOPIC_FIX = "/vessel/pose", "/vessel/state", "/vessel/inputs", "/vessel/fix"
STATE_FIELDS = ("t", "x", "y", "psi", "u", "v", "r")
INPUT_FIELDS = ("pwm_left", "pwm_right", "thrust_left", "thrust_right")
CHUNK_BYTES = 32 * 1024  # uncompressed: a file cut short loses at most this much of its messages

_NUM = {"type": "number"}
_TIME = {"type": "object", "title": "time", "properties": {
    "sec": {"type": "integer", "minimum": 0},
    "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}}
_VEC3 = {"title": "foxglove.Vector3", "type": "object", "properties": {k: _NUM for k in "xyz"}}
_QUAT = {"title": "foxglove.Quaternion", "type": "object", "properties": {k: _NUM for k in "xyzw"}}
# Foxglove's published jsonschema for PoseInFrame (github.com/foxglove/foxglove-sdk, schemas/jsonschema)
POSE_SCHEMA = {
    "title": "foxglove.PoseInFrame",
    "description": "A timestamped pose for an object or reference frame in 3D space",
    "type": "object",
    "properties": {
        "timestamp": _TIME,
        "frame_id": {"type": "string"},
        "pose": {"title": "foxglove.Pose", "type": "object",
                 "properties": {"position": _VEC3, "orientation": _QUAT}},
    },
}
STATE_SCHEMA = {
    "title": "twin.VesselState",
    "description": "NED pose x, y (m), psi (rad) and body velocities u, v (m/s), r (rad/s) at t (s)",
    "type": "object",
    "properties": {k: _NUM for k in STATE_FIELDS},
}
INPUTS_SCHEMA = {
    "title": "twin.ThrusterInputs",
    "description": "Thruster PWM (us) and delivered thrust (N); null where unknown",
    "type": "object",
    "properties": {k: {"type": ["number", "null"]} for k in INPUT_FIELDS},
}


def check_run(run: Run, name: str = "run") -> int:
    """Return the number of samples, or raise TwinError if the arrays disagree in shape."""
    n = len(np.atleast_1d(run.t))
    want = {"t": (n,), "eta": (n, 3), "nu": (n, 3), "pwm_us": (n, 2), "thrust_n": (n, 2)}
    for attr, shape in want.items():
        got = np.shape(getattr(run, attr))
        if got != shape:
            raise TwinError(f"{name}: {attr} has shape {got}, expected {shape} for {n} samples")
    if n and not np.all(np.isfinite(run.t)):
        raise TwinError(f"{name}: sample times must be finite")
    return n


def write_run_mcap(run: Run, path: str | Path, vessel_name: str = "", *, origin: tuple[float, float] = DEFAULT_ORIGIN,
                   antenna_body_m=(0.0, 0.0)) -> None:
    """Write `run` to the MCAP file `path` atomically (temporary file, then rename); the map
    positions (/vessel/fix) are the antenna's at `antenna_body_m` (body FRD, m) around `origin`."""
    check_run(run)
    if len(run.t) and np.min(run.t) < 0:
        raise TwinError("MCAP log times cannot be negative: the run starts at t < 0")
    # a lambda, so that _write is looked up at call time (tests replace it)
    write_stream_atomic(path, lambda fh: _write(fh, run, vessel_name, origin, antenna_body_m))


MESSAGE_BLOCK = 65536  # samples turned into messages at a time


def _write(fh, run: Run, vessel_name: str, origin: tuple[float, float] = DEFAULT_ORIGIN,
           antenna_body_m=(0.0, 0.0)) -> None:
    w = Writer(fh, chunk_size=CHUNK_BYTES)
    w.start(profile="", library="twin")
    w.add_metadata("twin", {"vessel": vessel_name, "meta": json.dumps(_plain(run.meta), sort_keys=True),
                            "origin": json.dumps([float(origin[0]), float(origin[1])]),
                            "limits": json.dumps(run.meta.get("limits", []))})
    channels = {}
    for topic, schema in ((TOPIC_POSE, POSE_SCHEMA), (TOPIC_STATE, STATE_SCHEMA), (TOPIC_INPUTS, INPUTS_SCHEMA),
                          (TOPIC_FIX, LOCATION_FIX_SCHEMA)):
        sid = w.register_schema(schema["title"], "jsonschema", json.dumps(schema).encode())
        channels[topic] = w.register_channel(topic, "json", sid)
    cols = run.columns()
    north, east = antenna_ned(run.eta[:, 0], run.eta[:, 1], run.eta[:, 2], antenna_body_m)
    lat_deg, lon_deg = geodetic_from_ned(north, east, *origin)
    # a block at a time: Python floats (exact repr in JSON) take 32 bytes each, a whole SITL recording's
    # columns as lists several gigabytes
    for first in range(0, len(run.t), MESSAGE_BLOCK):
        block = slice(first, first + MESSAGE_BLOCK)
        rows = {k: v[block].tolist() for k, v in cols.items()}
        lat, lon = lat_deg[block].tolist(), lon_deg[block].tolist()
        for j, t in enumerate(rows["t"]):
            ns = int(round(t * 1e9))
            msgs = {
                TOPIC_POSE: _pose_msg(ns, rows["x"][j], rows["y"][j], rows["psi"][j]),
                TOPIC_STATE: {k: _num(rows[k][j]) for k in STATE_FIELDS},
                TOPIC_INPUTS: {k: _num(rows[k][j]) for k in INPUT_FIELDS},
            }
            if math.isfinite(lat[j]) and math.isfinite(lon[j]):
                msgs[TOPIC_FIX] = _location_fix(ns, lat[j], lon[j], 0.0)
            for topic, msg in msgs.items():
                data = json.dumps(msg, allow_nan=False).encode()
                w.add_message(channels[topic], log_time=ns, data=data, publish_time=ns, sequence=first + j)
    w.finish()


def _pose_msg(ns: int, x: float, y: float, psi: float) -> dict:
    # yaw about NED z (down): q = (0, 0, sin ψ/2, cos ψ/2)
    return {
        "timestamp": {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000},
        "frame_id": FRAME_ID,
        "pose": {"position": {"x": _num(x), "y": _num(y), "z": 0.0},
                 "orientation": {"x": 0.0, "y": 0.0, "z": _num(math.sin(psi / 2)), "w": _num(math.cos(psi / 2))}},
    }


def _num(x: float) -> float | None:
    return x if math.isfinite(x) else None


def _plain(meta: dict) -> dict:
    """The meta entries JSON keeps exactly: str, int and finite float (bool is an int), and a dict of
    them (the sea a log was made in)."""
    def kept(v) -> bool:
        return v is None or isinstance(v, (str, int)) or (isinstance(v, float) and math.isfinite(v))

    return {str(k): v for k, v in meta.items()
            if kept(v) or (isinstance(v, dict) and all(kept(x) for x in v.values()))}


def read_run_mcap(path: str | Path, notes: list[str] | None = None) -> Run:
    """Read a run written by `write_run_mcap`; JSON null becomes NaN. What a damaged file
    lost is appended to `notes` (TwinError when nothing complete is left)."""
    path = Path(path)
    contents = read_contents(path)
    if not contents.messages.get(TOPIC_STATE):
        raise TwinError(f"{path.name}: MCAP file has no {TOPIC_STATE} messages" + contents.lost_clause())
    states, bad = _json_messages(contents.messages[TOPIC_STATE])
    inputs, bad_inputs = _json_messages(contents.messages.get(TOPIC_INPUTS, []))
    if bad or bad_inputs:  # a run's states and inputs pair up one by one: a damaged one breaks the pairs
        raise TwinError(f"{path.name}: damaged: {bad + bad_inputs} of its run's messages are not readable")
    states, inputs = [m for _, m in states], [m for _, m in inputs]
    if contents.damaged:
        inputs = inputs[: len(states)]  # the last sample's topics may straddle the cut
        states = states[: len(inputs)] if inputs else states
        if notes is not None:
            notes.append(contents.damaged)
    meta = _meta_from(contents.metadata["twin"]) if "twin" in contents.metadata else {}
    return _run_from(states, inputs, meta, path.name)


@dataclass
class Contents:
    """The messages of an MCAP file by topic as (log time ns, data) in log-time order (file
    order for a damaged file), its metadata records by name, and `damaged`: "" or one line
    saying what was lost."""

    messages: dict[str, list[tuple[int, bytes]]]
    metadata: dict[str, dict[str, str]]
    damaged: str = ""

    def lost_clause(self) -> str:
        return f" ({self.damaged})" if self.damaged else ""


MCAP_DAMAGE = "MCAP file "  # how the note on what a damaged file lost begins (Contents.damaged)

# what the mcap reader raises on a truncated or foreign file
_MCAP_ERRORS = (McapError, OSError, EOFError, ValueError, KeyError, TypeError, IndexError, struct.error)
# a damaged chunk's bytes also reach the decompressors mcap uses, whose errors are classes of their own
_DECOMPRESSORS = ("zstandard", "lz4")


def _damage(exc: BaseException) -> bool:
    """Whether reading raised `exc` because of the file's bytes (not a lack of memory, not a bug)."""
    return isinstance(exc, _MCAP_ERRORS) or type(exc).__module__.split(".")[0] in _DECOMPRESSORS


def read_contents(path: Path) -> Contents:
    """Every message and metadata record of an MCAP file: through its index when the file is
    whole, else streamed record by record up to where it breaks (TwinError if not MCAP)."""
    try:
        with open(path, "rb") as fh:
            reader = make_reader(fh)
            if reader.get_summary() is None:
                raise McapError("no summary")
            messages: dict[str, list] = {}
            # in file order, then each topic sorted by time (stable: file order breaks ties): what the
            # reader's own time-ordered merge gives per topic, without its heap over every message
            for _, channel, message in reader.iter_messages(log_time_order=False):
                messages.setdefault(channel.topic, []).append((message.log_time, message.data))
            for m in messages.values():
                m.sort(key=lambda item: item[0])
            metadata = {r.name: dict(r.metadata) for r in reader.iter_metadata()}
        return Contents(messages, metadata)
    except Exception as exc:
        if not _damage(exc):
            raise
        return _salvage(path, exc)


def _salvage(path: Path, first_error: Exception) -> Contents:
    """The complete records of a damaged MCAP file, streamed from its start."""
    messages: dict[str, list] = {}
    metadata: dict[str, dict[str, str]] = {}
    topics: dict[int, str] = {}
    complete = True
    try:
        with open(path, "rb") as fh:
            for record in StreamReader(fh).records:
                if isinstance(record, Channel):
                    topics[record.id] = record.topic
                elif isinstance(record, Message) and record.channel_id in topics:
                    messages.setdefault(topics[record.channel_id], []).append((record.log_time, record.data))
                elif isinstance(record, Metadata):
                    metadata[record.name] = dict(record.metadata)
    except Exception as exc:
        if not _damage(exc):
            raise
        complete = False
    n = sum(len(m) for m in messages.values())
    if not n and not metadata:
        raise TwinError(f"{path.name}: not a readable MCAP file ({type(first_error).__name__}: {first_error})")
    last_s = max((t for m in messages.values() for t, _ in m), default=0) / 1e9
    how = "truncated or damaged" if not complete else "without its index (not closed)"
    return Contents(messages, metadata, f"{MCAP_DAMAGE}{how}: read the {n} complete messages up to "
                                        f"t = {last_s:.1f} s, the rest is lost")


def _loaded(text: str, what: str):
    """json.loads of a metadata record's text; TwinError where its bytes were damaged."""
    try:
        return json.loads(text)
    except ValueError:  # JSONDecodeError, and text from undecodable bytes
        raise TwinError(f"damaged: the MCAP {what} metadata does not read as JSON") from None


def _meta_from(record: dict[str, str]) -> dict:
    meta = _loaded(record.get("meta", "{}"), "run's")
    if record.get("vessel"):
        meta.setdefault("vessel", record["vessel"])
    return meta


def _run_from(states: list[dict], inputs: list[dict], meta: dict, name: str) -> Run:
    def table(rows: list[dict], fields: tuple[str, ...]) -> np.ndarray:
        a = [[np.nan if r.get(k) is None else float(r[k]) for k in fields] for r in rows]
        return np.array(a, dtype=float).reshape(len(rows), len(fields))

    if inputs and len(inputs) != len(states):
        raise TwinError(f"{name}: {len(inputs)} {TOPIC_INPUTS} messages for {len(states)} states")
    s = table(states, STATE_FIELDS)
    u = table(inputs, INPUT_FIELDS) if inputs else np.full((len(states), 4), np.nan)
    return Run(s[:, 0], s[:, 1:4], s[:, 4:7], u[:, 0:2], u[:, 2:4], meta=meta)


# ---------------------------------------------------------------- sensor recordings

SENSOR_PREFIX = "/sensors/"
GNSS_FRAME_ID = "gnss"
RECORDING_METADATA = "twin.recording"
# Foxglove's published jsonschema for LocationFix (github.com/foxglove/foxglove-sdk, schemas/jsonschema),
# the fields it requires; its optional heading, velocity, color and metadata are not written
LOCATION_FIX_SCHEMA = {
    "title": "foxglove.LocationFix",
    "description": "A navigation satellite fix for any Global Navigation Satellite System",
    "type": "object",
    "properties": {
        "timestamp": _TIME,
        "frame_id": {"type": "string"},
        "latitude": _NUM,
        "longitude": _NUM,
        "altitude": _NUM,
        "position_covariance": {"type": "array", "items": _NUM, "minItems": 9, "maxItems": 9},
        "position_covariance_type": {"title": "foxglove.PositionCovarianceType", "oneOf": [
            {"title": name, "const": i} for i, name in enumerate(("UNKNOWN", "APPROXIMATED", "DIAGONAL_KNOWN",
                                                                  "KNOWN"))]},
    },
    "required": ["timestamp", "frame_id", "latitude", "longitude", "altitude", "position_covariance",
                 "position_covariance_type"],
}


def _project_schema(title: str, description: str, fields: tuple[str, ...]) -> dict:
    return {"title": title, "description": description, "type": "object",
            "properties": {k: _NUM for k in fields}, "required": list(fields)}


# stream → (topic, schema, {Recording column: message field})
SENSORS = {
    "gnss": ("/sensors/gnss", LOCATION_FIX_SCHEMA,
             {"lat_deg": "latitude", "lon_deg": "longitude", "alt_m": "altitude"}),
    "heading": ("/sensors/heading", _project_schema(
        "twin.Heading", "Heading from north towards east: psi_rad in (-pi, pi], heading_deg in [0, 360)",
        ("psi_rad", "heading_deg")), {"psi_rad": "psi_rad"}),
    "pwm": ("/sensors/pwm", _project_schema(
        "twin.ThrusterPwm", "Thruster PWM (us), forward thrust = higher", ("left_us", "right_us")),
        {"left_us": "left_us", "right_us": "right_us"}),
    "imu": ("/sensors/imu", _project_schema(
        "twin.YawRate", "Gyro z, body FRD (rad/s)", ("yaw_rate_rads",)), {"yaw_rate_rads": "yaw_rate_rads"}),
    "battery": ("/sensors/battery", _project_schema(
        "twin.Battery", "Battery voltage (V)", ("voltage_v",)), {"voltage_v": "voltage_v"}),
    "prop_rudder": ("/sensors/prop_rudder", _project_schema(
        "twin.PropellerRudder", "Propeller speed n_rps (rps, > 0 ahead) and rudder angle delta_rad (rad, > 0 turns "
        "to starboard)", ("n_rps", "delta_rad")), {"n_rps": "n_rps", "delta_rad": "delta_rad"}),
    "wind": ("/sensors/wind", {**_project_schema(
        "twin.Wind", "True wind speed_m_s (m/s) and from_deg (direction it blows FROM, deg clockwise from north); "
        "apparent relative_speed_m_s, relative_from_deg (FROM, deg clockwise from the bow) where measured",
        ("speed_m_s", "from_deg", "relative_speed_m_s", "relative_from_deg")), "required": ["speed_m_s", "from_deg"]},
        {k: k for k in ("speed_m_s", "from_deg", "relative_speed_m_s", "relative_from_deg")}),
    "attitude": ("/sensors/attitude", _project_schema(
        "twin.Attitude", "Roll (starboard down) and pitch (bow up) of the hull (rad)", ("roll_rad", "pitch_rad")),
        {"roll_rad": "roll_rad", "pitch_rad": "pitch_rad"}),
}


def write_recording_mcap(rec: Recording, path: str | Path) -> None:
    """Write a recording whose times are ≥ 0, whose gnss stream has lat_deg/lon_deg
    and whose psi_rad is wrapped (twin.formats.write_recording prepares it) atomically."""
    write_stream_atomic(path, lambda fh: _write_sensors(fh, rec))


def _write_sensors(fh, rec: Recording) -> None:
    w = Writer(fh, chunk_size=CHUNK_BYTES)
    w.start(profile="", library="twin")
    w.add_metadata(RECORDING_METADATA, {
        "origin_s": repr(float(rec.origin_s)), "pwm_neutral_us": json.dumps([float(x) for x in rec.pwm_neutral_us]),
        "source": str(rec.source), "kind": str(rec.kind), "meta": json.dumps(_plain(rec.meta), sort_keys=True),
        "parameters": json.dumps({str(k): float(v) for k, v in rec.parameters.items()}, sort_keys=True)})
    timed = []
    for name, stream in {**rec.streams(), "attitude": rec.attitude}.items():
        if not len(stream):
            continue
        topic, schema, _ = SENSORS[name]
        sid = w.register_schema(schema["title"], "jsonschema", json.dumps(schema).encode())
        cid = w.register_channel(topic, "json", sid)
        timed += [(ns, cid, seq, data) for seq, (ns, data) in enumerate(_sensor_messages(name, stream))]
    # time order across topics, so that a streaming reader replays the sensors as they came
    timed.sort(key=lambda m: m[0])
    for ns, cid, seq, data in timed:
        w.add_message(cid, log_time=ns, data=data, publish_time=ns, sequence=seq)
    w.finish()


def _sensor_messages(name: str, stream: Stream) -> Iterator[tuple[int, bytes]]:
    """(log time ns, JSON message) of every sample of one stream."""
    fields = SENSORS[name][2]
    cols = {col: stream[col].tolist() for col in fields if col in stream.columns}  # Python floats: exact JSON
    for i, ns in enumerate(np.round(stream.t * 1e9).astype(np.int64).tolist()):
        row = {col: values[i] for col, values in cols.items()}
        if name == "gnss":
            msg = _location_fix(ns, row["lat_deg"], row["lon_deg"], row.get("alt_m", 0.0))
        elif name == "heading":
            msg = {"psi_rad": row["psi_rad"], "heading_deg": _compass_deg(row["psi_rad"])}
        else:
            msg = {fields[col]: v for col, v in row.items()}
        yield ns, json.dumps(msg, allow_nan=False).encode()


def _compass_deg(psi_rad: float) -> float:
    deg = math.degrees(psi_rad) % 360.0
    return deg if deg < 360.0 else 0.0  # −1e-17 rad % 360 rounds to 360.0


def _location_fix(ns: int, lat_deg: float, lon_deg: float, alt_m: float) -> dict:
    return {"timestamp": {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}, "frame_id": GNSS_FRAME_ID,
            "latitude": lat_deg, "longitude": lon_deg, "altitude": alt_m,
            "position_covariance": [0.0] * 9, "position_covariance_type": 0}


def read_sensor_mcap(path: str | Path) -> tuple[dict[str, tuple[np.ndarray, dict[str, np.ndarray]]], dict] | None:
    """The /sensors/* topics of an MCAP file as {stream: (t s, {column: values})} at
    the messages' log times, and the "twin.recording" metadata parsed (origin_s,
    pwm_neutral_us, meta, parameters; empty when absent) with "damaged" (what a cut-short
    file lost, "" if whole); None when there is no /sensors/ topic.
    A missing or null field is NaN; an altitude that is never given is left out."""
    contents = read_contents(Path(path))
    wanted = {SENSORS[name][0]: name for name in SENSORS}
    topics = [topic for topic in wanted if contents.messages.get(topic)]  # the Recording's stream order
    if not topics:
        if contents.damaged and RECORDING_METADATA in contents.metadata:  # a recording cut before its first sample
            raise TwinError(f"{Path(path).name}: no complete sensor message{contents.lost_clause()}")
        return None
    rows, unreadable = {}, 0
    for topic in topics:
        rows[wanted[topic]], bad = _json_messages(contents.messages[topic])
        unreadable += bad
    rows = {name: msgs for name, msgs in rows.items() if msgs}
    if not rows:
        raise TwinError(f"{Path(path).name}: no readable sensor message ({unreadable} damaged)")
    meta = _recording_meta(contents.metadata.get(RECORDING_METADATA, {}))
    lost = f"{MCAP_DAMAGE}damaged: {unreadable} messages whose bytes are not JSON left out" if unreadable else ""
    meta["damaged"] = "; ".join(x for x in (contents.damaged, lost) if x)
    return {name: _columns(name, msgs) for name, msgs in rows.items()}, meta


def _json_messages(messages: list[tuple[int, bytes]]) -> tuple[list[tuple[int, dict]], int]:
    """(log time, JSON object) of each message whose bytes read as one, and how many did not (a
    damaged chunk that still decompressed)."""
    out, bad = [], 0
    for ns, data in messages:
        try:
            value = json.loads(data)
        except (UnicodeDecodeError, ValueError):
            bad += 1
            continue
        if isinstance(value, dict):
            out.append((ns, value))
        else:
            bad += 1
    return out, bad


def _columns(name: str, msgs: list[tuple[int, dict]]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    t = np.array([ns for ns, _ in msgs], dtype=np.int64) / 1e9
    cols = {col: np.array([_float(m.get(field)) for _, m in msgs], dtype=float)
            for col, field in SENSORS[name][2].items()}
    for optional in ("alt_m", "relative_speed_m_s", "relative_from_deg"):
        if optional in cols and not np.any(np.isfinite(cols[optional])):
            del cols[optional]  # a fix without altitude, a wind without its apparent pair, must not cost the sample
    return t, cols


def _float(x) -> float:
    return float(x) if isinstance(x, (int, float)) and not isinstance(x, bool) else np.nan


def _recording_meta(record: dict[str, str]) -> dict:
    out: dict = {}
    if "origin_s" in record:
        out["origin_s"] = float(record["origin_s"])
    if "pwm_neutral_us" in record:
        left, right = _loaded(record["pwm_neutral_us"], "recording's")
        out["pwm_neutral_us"] = (float(left), float(right))
    meta = _loaded(record.get("meta", "{}"), "recording's")
    out["meta"] = meta if isinstance(meta, dict) else {}
    if record.get("kind") == "esso-csv" and out["meta"].get("positions") == EXACT_ORIGIN:
        # an older file gives an Esso test's track as "body origin": it is the pond's tracking, measured
        out["meta"]["positions"] = TRACKED_ORIGIN
    params = _loaded(record.get("parameters", "{}"), "recording's")
    out["parameters"] = {str(k): float(v) for k, v in params.items()} if isinstance(params, dict) else {}
    return out


# ---------------------------------------------------------------- reading a recording

def read_mcap(path: Path) -> Recording:
    """An MCAP file of this project. With /sensors/* topics (a sensor recording, written
    by write_recording_mcap) each topic is a stream at
    its messages' log times. Otherwise a run: /vessel/state gives the positions
    (north/east: of the body origin for a simulated run, no lever arm; as measured for
    a run written from a recording) and heading, /vessel/inputs the PWM (absent when
    the run was driven by thrust). A file cut short gives its complete messages, with
    a note."""
    try:
        sensors = read_sensor_mcap(path)
        if sensors is not None:
            return _mcap_sensors(path, *sensors)
        return _mcap_run(path)
    except TwinError as exc:
        if str(exc).startswith("damaged:"):  # said by _loaded, which does not know the file
            raise TwinError(f"{Path(path).name}: {exc}") from None
        raise


def _mcap_sensors(path: Path, streams: dict, meta: dict) -> Recording:
    rec = Recording(source=str(path), kind="mcap", origin_s=meta.get("origin_s", 0.0),
                    pwm_neutral_us=meta.get("pwm_neutral_us", (1500.0, 1500.0)))
    for name, (t, cols) in streams.items():
        setattr(rec, name, clean_stream(name, t, cols, rec.dropped))
    rec.meta.update(meta.get("meta", {}))
    rec.parameters = meta.get("parameters", {})
    if meta.get("damaged"):
        rec.notes.append(meta["damaged"])
    if not any(len(s) for s in rec.streams().values()):
        raise TwinError(f"{path.name}: the MCAP /sensors/ topics hold no usable samples")
    return with_common_origin(rec)


def _mcap_run(path: Path) -> Recording:
    rec = Recording(source=str(path), kind="mcap")
    run = read_run_mcap(path, rec.notes)
    t = run.t
    rec.gnss = clean_stream("gnss", t, {"north_m": run.eta[:, 0], "east_m": run.eta[:, 1]}, rec.dropped)
    rec.heading = clean_stream("heading", t, {"psi_rad": run.eta[:, 2]}, rec.dropped)
    rec.imu = clean_stream("imu", t, {"yaw_rate_rads": run.nu[:, 2]}, rec.dropped)
    if np.any(np.isfinite(run.pwm_us)):
        rec.pwm = clean_stream("pwm", t, {"left_us": run.pwm_us[:, 0], "right_us": run.pwm_us[:, 1]}, rec.dropped)
    else:
        rec.notes.append("no PWM: the run was driven by thrust")
    rec.meta.update(run.meta)
    if run.meta.get("engine") == "recording":  # prepared measurements (an older `twin convert`)
        rec.notes.append("positions are as measured (the GNSS antenna unless a lever arm was applied)")
    else:
        rec.meta["positions"] = EXACT_ORIGIN
        rec.notes.append("positions are the body origin (a simulated run): no GNSS lever arm is applied")
        rec.notes.append("the run's own u, v and thrusts (the twin's states, which no sensor logs) are not read")
    if not len(rec.gnss) and not len(rec.heading):
        raise TwinError(f"{path.name}: the MCAP run has no finite states")
    return with_common_origin(rec)


