"""A run as an MCAP file (JSON messages, jsonschema schemas) that Foxglove can open.

Topics, all logged at the run time t (s → ns):
  /vessel/pose    foxglove.PoseInFrame  pose in frame "ned": x north, y east (m), yaw ψ about z (down)
  /vessel/state   twin.VesselState      t (s), x, y (m), psi (rad), u, v (m/s), r (rad/s)
  /vessel/inputs  twin.ThrusterInputs   pwm_left/right (µs), thrust_left/right (N); null where NaN
Metadata record "twin": {"vessel": name, "meta": JSON of the plain str/int/float run.meta entries}.
"""
from __future__ import annotations

import json
import math
import os
import struct
import uuid
from pathlib import Path

import numpy as np
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.writer import Writer

from ..errors import TwinError
from ..run import Run

FRAME_ID = "ned"
TOPIC_POSE, TOPIC_STATE, TOPIC_INPUTS = "/vessel/pose", "/vessel/state", "/vessel/inputs"
STATE_FIELDS = ("t", "x", "y", "psi", "u", "v", "r")
INPUT_FIELDS = ("pwm_left", "pwm_right", "thrust_left", "thrust_right")

_NUM = {"type": "number"}
_VEC3 = {"title": "foxglove.Vector3", "type": "object", "properties": {k: _NUM for k in "xyz"}}
_QUAT = {"title": "foxglove.Quaternion", "type": "object", "properties": {k: _NUM for k in "xyzw"}}
# Foxglove's published jsonschema for PoseInFrame (github.com/foxglove/foxglove-sdk, schemas/jsonschema)
POSE_SCHEMA = {
    "title": "foxglove.PoseInFrame",
    "description": "A timestamped pose for an object or reference frame in 3D space",
    "type": "object",
    "properties": {
        "timestamp": {"type": "object", "title": "time", "properties": {
            "sec": {"type": "integer", "minimum": 0},
            "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}},
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


def write_run_mcap(run: Run, path: str | Path, vessel_name: str = "") -> None:
    """Write `run` to the MCAP file `path` atomically (temporary file, then rename)."""
    path = Path(path)
    check_run(run)
    if len(run.t) and np.min(run.t) < 0:
        raise TwinError("MCAP log times cannot be negative: the run starts at t < 0")
    tmp = temp_path(path)
    try:
        with open(tmp, "xb") as fh:
            _write(fh, run, vessel_name)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def temp_path(path: Path) -> Path:
    """A fresh hidden name next to `path` (same file system, so os.replace is atomic).

    Unlike mkstemp, the file is created later with the usual permissions (umask)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    return path.with_name(f".{path.name}.{uuid.uuid4().hex[:12]}.tmp")


def _write(fh, run: Run, vessel_name: str) -> None:
    w = Writer(fh)
    w.start(profile="", library="twin")
    channels = {}
    for topic, schema in ((TOPIC_POSE, POSE_SCHEMA), (TOPIC_STATE, STATE_SCHEMA), (TOPIC_INPUTS, INPUTS_SCHEMA)):
        sid = w.register_schema(schema["title"], "jsonschema", json.dumps(schema).encode())
        channels[topic] = w.register_channel(topic, "json", sid)
    cols = run.columns()
    rows = {k: v.tolist() for k, v in cols.items()}  # Python floats: exact repr in JSON
    for i in range(len(run.t)):
        ns = int(round(rows["t"][i] * 1e9))
        msgs = {
            TOPIC_POSE: _pose_msg(ns, rows["x"][i], rows["y"][i], rows["psi"][i]),
            TOPIC_STATE: {k: _num(rows[k][i]) for k in STATE_FIELDS},
            TOPIC_INPUTS: {k: _num(rows[k][i]) for k in INPUT_FIELDS},
        }
        for topic, msg in msgs.items():
            data = json.dumps(msg, allow_nan=False).encode()
            w.add_message(channels[topic], log_time=ns, data=data, publish_time=ns, sequence=i)
    w.add_metadata("twin", {"vessel": vessel_name, "meta": json.dumps(_plain(run.meta), sort_keys=True)})
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
    """The meta entries JSON keeps exactly: str, int and finite float (bool is an int)."""
    return {str(k): v for k, v in meta.items()
            if isinstance(v, (str, int)) or (isinstance(v, float) and math.isfinite(v))}


def read_run_mcap(path: str | Path) -> Run:
    """Read a run written by `write_run_mcap`; JSON null becomes NaN."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            reader = make_reader(fh)
            summary = reader.get_summary()
            topics = {c.topic for c in summary.channels.values()} if summary else set()
            if TOPIC_STATE not in topics:
                raise TwinError(f"{path.name}: MCAP file has no {TOPIC_STATE} topic")
            msgs = {TOPIC_STATE: [], TOPIC_INPUTS: []}
            for _, channel, message in reader.iter_messages(topics=list(msgs)):
                msgs[channel.topic].append(json.loads(message.data))
            meta = {}
            for record in reader.iter_metadata():
                if record.name == "twin":
                    meta = _meta_from(record.metadata)
    except TwinError:
        raise
    # the mcap reader raises any of these on a truncated or foreign file
    except (McapError, OSError, EOFError, ValueError, KeyError, TypeError, struct.error) as exc:
        raise TwinError(f"{path.name}: not a readable MCAP file ({type(exc).__name__}: {exc})") from None
    return _run_from(msgs[TOPIC_STATE], msgs[TOPIC_INPUTS], meta, path.name)


def _meta_from(record: dict[str, str]) -> dict:
    meta = json.loads(record.get("meta", "{}"))
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
