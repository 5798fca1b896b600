"""`twin sitl`: the twin as ArduPilot SITL's JSON physics backend.

No ArduPilot binary here: `Client` plays ArduPilot's side, written from the protocol text
(libraries/SITL/examples/JSON/readme.md, SIM_JSON.h) with struct and json, not with
twin.sitl.protocol, so that the backend's own packing and parsing are checked against an
independent reading. Every session runs the server in a thread on an ephemeral port with
a stop event; references are computed after the server thread has ended (MuJoCo's passive
callback is process-global).
"""
from __future__ import annotations

import contextlib
import json
import math
import os
import re
import signal
import socket
import struct
import threading
import time
from dataclasses import replace

import mujoco
import numpy as np
import pytest

from twin.drive import InputSeries
from twin.engine.mjcf import compile_vessel
from twin.engine.native import installed_native, with_native_params
from twin.engine.sim import _step_in_parts as step_in_parts, delivered_thrust, initial_state, simulate
from twin.errors import TwinError
from twin.formats import read_recording
from twin.physics.hydrodynamics import Terms
from twin.physics.waves import parse_sea
from twin.run import read_csv
from twin.sitl.backend import PwmMap, SitlTwin, delivered_thrust_n, with_environment
from twin.sitl.protocol import (PacketError, Reply, ServoFrame, format_reply, pack_servo_packet,
                                parse_servo_packet)
from twin.sitl.server import run_sitl
import twin_command
from twin.vessel import MODEL_DIR, load

GRAVITY = 9.80665  # ArduPilot's GRAVITY_MSS
NEUTRAL = 1500.0  # yellowfish: pwm_offset·pwm_scale_us


# ---------------------------------------------------------------- ArduPilot's side

class Client:
    """ArduPilot's side of the link: servo packets out (`<HHI16H`, magic 18458, or `<HHI32H`, magic
    29569), one newline-framed JSON object back per frame; the latency of each frame."""

    def __init__(self, port: int):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.settimeout(5.0)
        self.address = ("127.0.0.1", port)
        self.latencies_s: list[float] = []

    def send(self, count: int, pwm, rate: int = 400) -> None:
        magic = 18458 if len(pwm) == 16 else 29569
        self.sock.sendto(struct.pack(f"<HHI{len(pwm)}H", magic, rate, count, *pwm), self.address)

    def raw(self, data: bytes) -> None:
        self.sock.sendto(data, self.address)

    def receive(self) -> bytes:
        data, _ = self.sock.recvfrom(65536)
        return data

    def frame(self, count: int, pwm, rate: int = 400) -> dict:
        start = time.perf_counter()
        self.send(count, pwm, rate)
        data = self.receive()
        self.latencies_s.append(time.perf_counter() - start)
        return decode(data)

    def nothing_pending(self, wait_s: float = 0.2) -> bool:
        self.sock.settimeout(wait_s)
        try:
            self.sock.recvfrom(65536)
        except TimeoutError:
            return True
        finally:
            self.sock.settimeout(5.0)
        return False

    def close(self) -> None:
        self.sock.close()


def decode(data: bytes) -> dict:
    text = data.decode("ascii")
    assert text.startswith("\n") and text.endswith("\n"), "a reply is preceded and followed by a newline"
    return json.loads(text)


@contextlib.contextmanager
def sitl(vessel, **kwargs):
    """run_sitl in a thread on an ephemeral port; yields (client, box); box["summary"] after the block.
    The ESCs arm at once unless a test says otherwise, so that replies compare with offline runs that
    have no ESC."""
    kwargs.setdefault("esc_arm_s", 0.0)
    box: dict = {}
    ready, stop = threading.Event(), threading.Event()

    def on_ready(address):
        box["port"] = address[1]
        ready.set()

    def target():
        try:
            box["summary"] = run_sitl(vessel, port=0, host="127.0.0.1", stop_event=stop, ready=on_ready, **kwargs)
        except BaseException as exc:  # noqa: BLE001  (re-raised in the test's thread)
            box["error"] = exc
            ready.set()

    thread = threading.Thread(target=target, daemon=True)
    thread.start()
    assert ready.wait(120), "the backend did not start"
    if "error" in box:
        raise box["error"]
    client = Client(box["port"])
    try:
        yield client, box
    finally:
        stop.set()
        thread.join(10)
        client.close()
        assert not thread.is_alive(), "the backend did not stop"
        if "error" in box:
            raise box["error"]


def play(vessel, frames, **kwargs) -> tuple[list[dict], dict, list[float]]:
    """One lock-step session: frames = [(count, pwm, rate)]; the replies, the summary, the latencies."""
    with sitl(vessel, **kwargs) as (client, box):
        replies = [client.frame(count, pwm, rate) for count, pwm, rate in frames]
        latencies = client.latencies_s
    return replies, box["summary"], latencies


# ---------------------------------------------------------------- inputs and references

@pytest.fixture(scope="module")
def full_vessel():
    """The yellowfish with every thruster effect and an environment: lag, transport delay (2.5 frames
    at 50 Hz), decay, advance-speed loss, asymmetric gains, current and wind."""
    v = load("yellowfish")
    thrusters = replace(v.thrusters, lag_s=0.15, delay_s=0.05, decay_per_min=0.05, advance_loss=0.8,
                        gain_left=0.95)
    return with_environment(replace(v, thrusters=thrusters), current=(0.3, 40.0), wind=(6.0, 100.0))


@pytest.fixture(scope="module")
def fine_vessel(full_vessel, tmp_path_factory):
    """The same vessel with its MJCF time step at 2.5 ms: the offline reference at SITL's 400 Hz step."""
    folder = tmp_path_factory.mktemp("mjcf")
    text = (MODEL_DIR / "yellowfish.xml").read_text()
    assert 'timestep="0.02"' in text and 'meshdir="../assets"' in text
    text = text.replace('timestep="0.02"', 'timestep="0.0025"')
    text = text.replace('meshdir="../assets"', f'meshdir="{(MODEL_DIR.parent / "assets").resolve()}"')
    path = folder / "yellowfish_fine.xml"
    path.write_text(text)
    return replace(full_vessel, mjcf=path)


def pwm_frames(n: int, seed: int, outputs: int = 16) -> tuple[list[list[int]], np.ndarray]:
    """n frames of servo outputs: channels 1 and 3 held at random levels for random spans, sometimes 0
    (no output) or beyond 1100-1900 µs; every other output random (it must not matter). Also the
    (left, right) PWM the thrusters should see: 0 is the neutral."""
    rng = np.random.default_rng(seed)
    frames, pairs = [], []
    while len(frames) < n:
        hold = int(rng.integers(3, 40))
        level = [0 if rng.random() < 0.1 else int(rng.integers(1000, 2001)) for _ in range(2)]
        for _ in range(hold):
            pwm = [int(x) for x in rng.integers(900, 2100, outputs)]
            pwm[0], pwm[2] = level
            frames.append(pwm)
            pairs.append([x if x else NEUTRAL for x in level])
    return frames[:n], np.array(pairs[:n], float)


def offline(vessel, pairs: np.ndarray, frame_s: float):
    """The twin run offline by engine.sim.simulate on the same PWM (a zero-order hold from each frame's
    start, neutral before the session): samples at every frame boundary."""
    n = len(pairs)
    series = InputSeries(np.concatenate([[-1.0], np.arange(n) * frame_s]),
                         np.vstack([[NEUTRAL, NEUTRAL], pairs]), "pwm")
    return simulate(compile_vessel(vessel), series, n * frame_s, sample_dt_s=frame_s)


def stepped(vessel, segments) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """Reference for frame rate changes, stepped with mj_step: frames of (rate, pairs) segments, each
    frame split into ceil(400 Hz / rate) equal steps; thrust commands from InputSeries (delay, map,
    decay) at each step's start, and a step within which the delayed input changes taken in two parts
    (the input at its start over its share, then the rest's mean: drive.StepPieces, written out).
    (timestamp, qpos, qvel) after each frame."""
    compiled = compile_vessel(vessel)
    model = with_native_params(compiled, Terms())
    data = mujoco.MjData(model)
    initial_state(model, data, None, None)
    starts, values, out = [-1.0], [[NEUTRAL, NEUTRAL]], []
    t_seg = 0.0
    with installed_native():
        for rate, pairs in segments:
            n_sub = math.ceil(400.0 / rate - 1e-9)
            h = (1.0 / rate) / n_sub
            model.opt.timestep = h
            k = 0
            for pair in pairs:
                starts.append(t_seg + k * h)
                values.append(list(pair))
                series = InputSeries(np.array(starts), np.array(values, float), "pwm")
                for _ in range(n_sub):
                    t = t_seg + k * h
                    data.ctrl[:2] = series.commanded_thrust(vessel.thrusters, np.array([t]))[0]
                    _step_in_parts(model, data, vessel.thrusters, series, t, h)
                    k += 1
                out.append((t_seg + k * h, data.qpos.copy(), data.qvel.copy()))
            t_seg = t_seg + k * h
    return out


def _step_in_parts(model, data, thrusters, series: InputSeries, t: float, h: float) -> None:
    """One step from t: whole, or in two parts where the input held delay_s before changes within it
    (a stamp repeating the input held changes nothing; the rest's command is its one input's, or the
    time-weighted mean of several)."""
    start = t - thrusters.delay_s
    end = start + h
    stamps, values = series.t, series.values
    held = values[max(i for i in range(len(stamps)) if stamps[i] <= start + 1e-9)]
    later = [i for i in range(len(stamps)) if start + 1e-9 < stamps[i] <= end - 1e-9]
    while later and np.array_equal(values[later[0]], held):
        later = later[1:]
    runs = [i for n, i in enumerate(later) if n == 0 or not np.array_equal(values[i], values[later[n - 1]])]
    if not runs:
        mujoco.mj_step(model, data)
        return
    f = 1.0 - thrusters.decay_per_min * t / 60.0
    commands = [thrusters.thrust_from_pwm(values[i][None, :])[0] * f for i in runs]
    if all(np.array_equal(c, data.ctrl[:2]) for c in commands):
        mujoco.mj_step(model, data)
        return
    if len(runs) == 1:
        rest = commands[0]
    else:
        total = np.zeros(2)
        for n, (i, c) in enumerate(zip(runs, commands)):
            until = stamps[runs[n + 1]] if n + 1 < len(runs) else end
            total += (until - stamps[i]) * c
        rest = total / (end - stamps[runs[0]])
    share = (stamps[runs[0]] - start) / h
    step_in_parts(model, data, (share, tuple(data.ctrl[:2]), tuple(rest)))


def arrays(replies: list[dict]) -> dict[str, np.ndarray]:
    return {
        "t": np.array([r["timestamp"] for r in replies]),
        "pos": np.array([r["position"] for r in replies]),
        "vel": np.array([r["velocity"] for r in replies]),
        "att": np.array([r["attitude"] for r in replies]),
        "quat": np.array([r["quaternion"] for r in replies]),
        "gyro": np.array([r["imu"]["gyro"] for r in replies]),
        "acc": np.array([r["imu"]["accel_body"] for r in replies]),
    }


def ned_velocity(run) -> np.ndarray:
    c, s = np.cos(run.eta[:, 2]), np.sin(run.eta[:, 2])
    u, v = run.nu[:, 0], run.nu[:, 1]
    return np.column_stack([c * u - s * v, s * u + c * v])


def assert_matches_offline(replies: list[dict], run) -> None:
    """Lock-step replies against the offline run: the same doubles (position, heading, time) and the
    same velocities up to the body↔NED rotation's rounding."""
    a = arrays(replies)
    n = len(replies)
    np.testing.assert_array_equal(a["t"], run.t[1:n + 1])
    np.testing.assert_array_equal(a["pos"][:, :2], run.eta[1:n + 1, :2])
    np.testing.assert_array_equal(a["att"][:, 2], [math.remainder(p, 2 * math.pi) for p in run.eta[1:n + 1, 2]])
    np.testing.assert_allclose(a["vel"][:, :2], ned_velocity(run)[1:n + 1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(a["gyro"][:, 2], run.nu[1:n + 1, 2], rtol=0, atol=1e-12)
    assert np.hypot(*a["pos"][-1, :2]) > 0.2, "the boat must have moved for the comparison to mean anything"


# ---------------------------------------------------------------- protocol

def test_servo_packets_parse_as_sent_and_anything_else_is_refused_with_a_reason():
    pwm16 = list(range(1000, 1016))
    frame = parse_servo_packet(struct.pack("<HHI16H", 18458, 400, 123456, *pwm16))
    assert frame == ServoFrame(400, 123456, tuple(pwm16))
    pwm32 = list(range(1100, 1132))
    assert parse_servo_packet(struct.pack("<HHI32H", 29569, 1200, 7, *pwm32)) == ServoFrame(1200, 7, tuple(pwm32))
    assert pack_servo_packet(400, 123456, pwm16) == struct.pack("<HHI16H", 18458, 400, 123456, *pwm16)
    assert len(pack_servo_packet(50, 1, pwm32)) == 72
    cases = {
        b"": "short packet",
        b"\x1a\x48": "short packet",
        struct.pack("<HHI16H", 18458, 400, 1, *pwm16)[:39]: "short packet",
        struct.pack("<HHI16H", 29569, 400, 1, *pwm16): "short packet",  # 40 bytes for the 72-byte magic
        struct.pack("<HHI32H", 18458, 400, 1, *pwm32): "long packet",
        struct.pack("<HHI16H", 12345, 400, 1, *pwm16): "unknown magic",
        b'{"timestamp":1.0}': "unknown magic",
        struct.pack("<HHI16H", 18458, 0, 1, *pwm16): "zero frame rate",
    }
    for data, reason in cases.items():
        with pytest.raises(PacketError) as err:
            parse_servo_packet(data)
        assert err.value.reason == reason, data


def _ardupilot_parse(text: str) -> dict:
    """SIM_JSON.cpp parse_sensors, transcribed: strstr the section, strstr the key after it, skip
    strlen(key) + 2 characters, then sscanf "[%f, %f, %f]" (a format space matches any whitespace,
    none included) or atof."""
    keys = [("", "timestamp", 1), ("imu", "gyro", 3), ("imu", "accel_body", 3), ("", "position", 3),
            ("", "attitude", 3), ("", "quaternion", 4), ("", "velocity", 3)]
    number = r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)"
    out = {}
    for section, key, n in keys:
        p = text.find(section) + len(section) + 1
        p = text.find(key, p)
        assert p >= 0, key
        p += len(key) + 2
        pattern = number if n == 1 else r"\[" + r"\s*,".join([number] * n) + r"\s*\]"
        m = re.match(pattern, text[p:])
        assert m, f"ArduPilot could not read {key} from {text[p:p + 30]!r}"
        out[key] = [float(g) for g in m.groups()]
    return out


def test_a_reply_is_a_newline_framed_json_object_that_ardupilots_own_parser_reads_exactly():
    rng = np.random.default_rng(5)
    for _ in range(50):
        values = rng.normal(size=10) * 10.0 ** rng.integers(-9, 4, 10)
        r = Reply(*(float(x) for x in values))
        r = r._replace(yaw_rad=math.remainder(r.yaw_rad, 2 * math.pi), timestamp_s=abs(r.timestamp_s))
        line = format_reply(r).decode("ascii")
        data = decode(line.encode())
        assert data["timestamp"] == r.timestamp_s
        assert data["position"] == [r.north_m, r.east_m, 0.0]
        assert data["velocity"] == [r.vn_m_s, r.ve_m_s, 0.0]
        assert data["imu"] == {"gyro": [0.0, 0.0, r.yaw_rate_rad_s], "accel_body": [r.ax_m_s2, r.ay_m_s2, r.az_m_s2]}
        assert data["attitude"] == [0.0, 0.0, r.yaw_rad]
        w, x, y, z = data["quaternion"]
        assert (x, y) == (0.0, 0.0) and w >= 0 and math.isclose(math.atan2(z, w) * 2, r.yaw_rad, abs_tol=1e-12)
        seen = _ardupilot_parse(line)
        assert seen["timestamp"] == [r.timestamp_s] and seen["gyro"][2] == r.yaw_rate_rad_s
        assert seen["accel_body"] == [r.ax_m_s2, r.ay_m_s2, r.az_m_s2] and seen["position"][:2] == [r.north_m, r.east_m]
        assert seen["velocity"][:2] == [r.vn_m_s, r.ve_m_s] and seen["attitude"][2] == r.yaw_rad
        assert r.as_dict() == data


def test_the_t200_pwm_map_gives_the_bits_of_the_thruster_model_and_direct_thrusters_map_linearly():
    thrusters = load("yellowfish").thrusters
    pwm = np.arange(900.0, 2100.5, 0.25)
    m = PwmMap.of(thrusters)
    assert m.neutral_us == 1500.0 and m.raw(m.held(1500.0)) == 0.0
    np.testing.assert_array_equal([m.raw(m.held(float(p))) for p in pwm], thrusters.thrust_from_pwm(pwm))
    saturating = replace(thrusters, full_share=0.7)
    m = PwmMap.of(saturating)
    np.testing.assert_array_equal([m.raw(m.held(float(p))) for p in pwm], saturating.thrust_from_pwm(pwm))
    direct = PwmMap.of(load("cybership1").thrusters)  # a full command is ±2 N, PWM range 1100-1900 µs
    assert direct.kind == "thrust" and direct.neutral_us == 1500.0
    assert [direct.raw(direct.held(p)) for p in (1100.0, 1300.0, 1500.0, 1700.0, 1900.0, 2100.0, 900.0)] == \
        [-2.0, -1.0, 0.0, 1.0, 2.0, 2.0, -2.0]
    twin = SitlTwin(load("cybership1"), esc_arm_s=0.0)
    with twin.active():
        for _ in range(50):
            twin.step([1900, 0, 1700] + [0] * 13, 50)
    np.testing.assert_array_equal(twin.recording().thrust_n[-1], [2.0, 1.0])


def test_recorded_thrust_is_what_the_engine_says_each_thruster_delivers(full_vessel):
    rng = np.random.default_rng(11)
    compiled = compile_vessel(full_vessel)
    command, nu = rng.uniform(-40, 50, (40, 2)), rng.normal(size=(40, 3))
    y = compiled.geometry.thruster_y_m
    np.testing.assert_allclose(delivered_thrust_n(full_vessel.thrusters, y, command, nu),
                               delivered_thrust(full_vessel, y, command, nu), rtol=1e-15, atol=1e-13)


# ---------------------------------------------------------------- lock-step against the offline twin

def test_lock_step_at_400_hz_is_the_offline_twin_with_the_same_pwm(full_vessel, fine_vessel):
    frames, pairs = pwm_frames(1200, seed=1)
    replies, summary, latencies = play(full_vessel, [(k, pwm, 400) for k, pwm in enumerate(frames)])
    assert summary.counters.frames == 1200 and summary.physics_time_s == pytest.approx(3.0)
    assert_matches_offline(replies, offline(fine_vessel, pairs, 1 / 400))
    assert np.median(latencies) < 5e-3, f"median latency {np.median(latencies) * 1e6:.0f} µs per frame"


def test_lock_step_with_motor_hysteresis_is_the_offline_twin(full_vessel, fine_vessel):
    """A motor that starts late answers the PWM as it comes, in SITL as offline (levels near neutral)."""
    hyst = {"start_fwd": 0.16, "start_rev": -0.17}
    full = replace(full_vessel, thrusters=replace(full_vessel.thrusters, **hyst))
    fine = replace(fine_vessel, thrusters=replace(fine_vessel.thrusters, **hyst))
    rng = np.random.default_rng(5)
    levels = rng.choice([1500, 1525, 1545, 1555, 1575, 1610, 1470, 1450, 1440, 1420, 1380], size=(30, 2))
    pairs = np.repeat(levels, 100, axis=0).astype(float)
    frames = [[1500] * 16 for _ in pairs]
    for f, (left, right) in zip(frames, pairs):
        f[0], f[2] = int(left), int(right)
    replies, _, _ = play(full, [(k, pwm, 400) for k, pwm in enumerate(frames)])
    assert_matches_offline(replies, offline(fine, pairs, 1 / 400))
    plain = offline(fine_vessel, pairs, 1 / 400)
    assert np.abs(arrays(replies)["pos"][-1, :2] - plain.eta[len(pairs), :2]).max() > 0.05


def test_lock_step_with_a_thrust_ramp_is_the_offline_twin(full_vessel, fine_vessel):
    """A slew-limited thrust ramps from rest at the session's start, in SITL as offline."""
    full = replace(full_vessel, thrusters=replace(full_vessel.thrusters, ramp_s=2.0))
    fine = replace(fine_vessel, thrusters=replace(fine_vessel.thrusters, ramp_s=2.0))
    frames, pairs = pwm_frames(1200, seed=4)
    replies, _, _ = play(full, [(k, pwm, 400) for k, pwm in enumerate(frames)])
    assert_matches_offline(replies, offline(fine, pairs, 1 / 400))
    plain = offline(fine_vessel, pairs, 1 / 400)
    assert np.abs(arrays(replies)["pos"][-1, :2] - plain.eta[len(pairs), :2]).max() > 0.05


def test_lock_step_with_a_thrust_ramp_and_a_delay_off_the_step_grid_is_the_offline_twin(full_vessel, fine_vessel):
    """A delay of 20.52 steps: each input reaches the ramp within a step, which both take in two parts,
    the ramp heading for the input held over each (guards against a ramp that takes it from the next
    step in one and not the other)."""
    ramped = {"ramp_s": 2.0, "delay_s": 0.0513}
    full = replace(full_vessel, thrusters=replace(full_vessel.thrusters, **ramped))
    fine = replace(fine_vessel, thrusters=replace(fine_vessel.thrusters, **ramped))
    frames, pairs = pwm_frames(1200, seed=6)
    replies, _, _ = play(full, [(k, pwm, 400) for k, pwm in enumerate(frames)])
    assert_matches_offline(replies, offline(fine, pairs, 1 / 400))


@pytest.mark.parametrize("change", [{"pwm_span_left": 0.8, "pwm_span_right": 1.25},
                                    {"pwm_span_right": 1.3, "delay_s": 0.0513, "start_fwd": 0.16, "start_rev": -0.17},
                                    {"deadzone_left": (0.35, -0.35)},
                                    {"deadzone_right": (0.15, -0.3), "delay_s": 0.0513}])
def test_lock_step_with_an_escs_own_range_is_the_offline_twin(full_vessel, fine_vessel, change):
    """Each ESC's own PWM span acts on the pulse it receives, and one thruster's own dead zone on its
    pulses alone, in SITL as offline, on the direct path and the delayed one (with the motors' start
    edges read on the received pulses)."""
    full = replace(full_vessel, thrusters=replace(full_vessel.thrusters, **change))
    fine = replace(fine_vessel, thrusters=replace(fine_vessel.thrusters, **change))
    frames, pairs = pwm_frames(1200, seed=7)
    replies, _, _ = play(full, [(k, pwm, 400) for k, pwm in enumerate(frames)])
    assert_matches_offline(replies, offline(fine, pairs, 1 / 400))
    plain = offline(fine_vessel, pairs, 1 / 400)
    assert np.abs(arrays(replies)["pos"][-1, :2] - plain.eta[len(pairs), :2]).max() > 0.01  # 3 s: centimetres


def test_lock_step_at_50_hz_substeps_the_frame_and_reads_32_output_packets(full_vessel, fine_vessel):
    frames, pairs = pwm_frames(150, seed=2, outputs=32)
    replies, _, _ = play(full_vessel, [(k, pwm, 50) for k, pwm in enumerate(frames)])
    a = arrays(replies)
    np.testing.assert_array_equal(np.diff(a["t"]), np.diff(np.arange(1, 151) * 0.02))
    assert_matches_offline(replies, offline(fine_vessel, pairs, 0.02))  # 8 steps of 2.5 ms per frame


def test_a_frame_rate_change_changes_the_physics_step(full_vessel):
    frames, pairs = pwm_frames(700, seed=3)
    segments = [(400, slice(0, 300)), (200, slice(300, 500)), (1200, slice(500, 640)), (50, slice(640, 700))]
    sent = [(k, frames[k], rate) for rate, part in segments for k in range(part.start, part.stop)]
    replies, summary, _ = play(full_vessel, sent)
    assert summary.counters.rate_changes == 3
    a = arrays(replies)
    steps = np.diff(np.concatenate([[0.0], a["t"]]))
    for rate, part in segments:
        np.testing.assert_allclose(steps[part], 1.0 / rate, rtol=1e-9)
    reference = stepped(full_vessel, [(rate, pairs[part]) for rate, part in segments])
    np.testing.assert_array_equal(a["t"], [t for t, _, _ in reference])
    np.testing.assert_array_equal(a["pos"][:, :2], [q[:2] for _, q, _ in reference])
    np.testing.assert_array_equal(a["vel"][:, :2], [w[:2] for _, _, w in reference])


# ---------------------------------------------------------------- what ArduPilot's side can do

def test_duplicates_are_answered_again_without_stepping_and_missed_frames_are_counted(full_vessel):
    frames, _ = pwm_frames(120, seed=4)
    counts = [k for k in range(120) if not 70 <= k < 73]  # frames 70-72 never arrive
    with sitl(full_vessel) as (client, box):
        replies = []
        for k in counts:
            replies.append(client.frame(k, frames[k]))
            if k in (10, 50):  # the answer was lost: ArduPilot re-sends after about a second
                time.sleep(0.6)
                client.send(k, frames[k])
                assert decode(client.receive()) == replies[-1]
            if k in (20, 60, 90):  # the copy crossed a late answer: one answer only
                client.send(k, frames[k])
                assert client.nothing_pending(0.3), "a copy that crossed the answer must not be answered"
    counters = box["summary"].counters
    assert (counters.frames, counters.duplicates, counters.crossed, counters.missed) == (117, 2, 3, 3)
    clean, _, _ = play(full_vessel, [(i, frames[k], 400) for i, k in enumerate(counts)])
    assert replies == clean  # one step per frame answered, whatever the counter did
    np.testing.assert_allclose(np.diff(arrays(replies)["t"]), 1 / 400, rtol=1e-9)


def test_a_frame_count_going_back_is_an_ardupilot_restart_and_resets_the_twin(full_vessel, tmp_path):
    frames, _ = pwm_frames(200, seed=5)
    session = [(k, pwm, 400) for k, pwm in enumerate(frames)]
    path = tmp_path / "restart.csv"
    replies, summary, _ = play(full_vessel, session + session[:150], record_paths=[path])
    assert summary.counters.restarts == 1
    assert replies[200:] == replies[:150]  # the same PWM from a fresh twin: the same states
    assert replies[200]["timestamp"] == 1 / 400 and replies[199]["timestamp"] == pytest.approx(0.5)
    run = read_csv(path)
    assert len(run.t) == 351 and np.all(np.diff(run.t) > 0)  # the record clock runs on across the restart
    assert run.t[200] == pytest.approx(0.5) and np.all(run.eta[200] == 0.0)  # the reset state
    np.testing.assert_allclose(run.eta[199, :2], replies[198]["position"][:2], rtol=1e-8)
    assert np.hypot(*replies[199]["position"][:2]) > 0.01


def test_a_frame_count_jumping_wildly_ahead_is_a_new_count_not_billions_of_missed_frames():
    """The fuzzer's 0xffffffff after frame 1, then 1 again: one jump and one restart, no frame missed; a
    gap of lost datagrams (here 5) is still counted as missed."""
    frames, _ = pwm_frames(8, seed=8)
    logged: list[str] = []
    counts = [1, 2, 8, 0xFFFFFFFF, 1, 2]
    with sitl(load("yellowfish"), log=logged.append) as (client, box):
        for count, pwm in zip(counts, frames):
            client.frame(count, pwm, 1200)
    c = box["summary"].counters
    assert (c.frames, c.missed, c.count_jumps, c.restarts) == (6, 5, 1, 1)
    assert "5 missed, 1 restarts, 1 frame_count jumps (taken as a new count, not as missed)" in box["summary"].text()
    assert any("frame_count jumped 8 → 4294967295, more than 10 s of frames at 1200 Hz" in line for line in logged)


def test_sitl_refuses_a_physics_rate_beyond_a_tenth_of_a_millisecond_step():
    """--rate 1e9 split each 1200 Hz frame into 833334 steps: 165 times slower than real time."""
    for rate in ("1e9", "10001", "0", "nan"):
        r = twin_command.twin("sitl", "--vessel", "blueboat", "--rate", rate, "--port", "0")
        assert r.returncode == 2 and r.stderr.count("\n") == 1, (rate, r.stderr)
        assert r.stderr.startswith(f"error: --rate {float(rate):g}: the least physics rate is a number of Hz above 0 "
                                   "and at most 10000"), r.stderr
    with pytest.raises(TwinError, match="at most 10000"):
        SitlTwin(load("yellowfish"), min_rate_hz=2e4)
    assert SitlTwin(load("yellowfish"), min_rate_hz=1e4, record=False).min_rate_hz == 1e4


def test_16_and_32_output_packets_mix_and_the_channels_can_be_chosen(full_vessel):
    frames, _ = pwm_frames(200, seed=6, outputs=32)
    mixed = [(k, pwm if k % 3 else pwm[:16], 400) for k, pwm in enumerate(frames)]
    only16 = [(k, pwm[:16], 400) for k, pwm in enumerate(frames)]
    replies_mixed, _, _ = play(full_vessel, mixed)
    replies_16, _, _ = play(full_vessel, only16)
    assert replies_mixed == replies_16
    moved = []
    for k, pwm in enumerate(frames):  # left thruster on output 20, right on 17; outputs 1 and 3 now unused
        out = list(pwm)
        out[19], out[16], out[0], out[2] = pwm[0], pwm[2], 1900, 1100
        moved.append((k, out, 400))
    replies_moved, _, _ = play(full_vessel, moved, channels=(20, 17))
    assert replies_moved == replies_16
    said: list[str] = []
    sixteen_only, _, _ = play(full_vessel, only16[:50], channels=(20, 17), current=(0, 0), wind=(0, 0),
                              log=said.append)
    assert all(r["position"] == [0.0, 0.0, 0.0] for r in sixteen_only)  # outputs 17+ absent: neutral
    assert any(line.startswith("warning: --channels 20,17: ArduPilot sends 16 servo outputs, so outputs 20 and 17 never")
               for line in said), said


def test_garbage_and_short_datagrams_are_counted_and_ignored(full_vessel):
    rng = np.random.default_rng(7)
    frames, _ = pwm_frames(60, seed=7)
    garbage = [b"", b"\x00", b"x" * 7, bytes(rng.integers(0, 256, 39, dtype=np.uint8)),
               struct.pack("<HHI16H", 18458, 400, 3, *frames[3])[:30],
               struct.pack("<HHI16H", 29569, 400, 3, *frames[3]),
               struct.pack("<HHI32H", 18458, 400, 3, *(frames[3] * 2)),
               b'{"timestamp":1.0,"imu":{}}\n', struct.pack("<HHI16H", 18458, 0, 3, *frames[3]),
               bytes(rng.integers(0, 256, 2000, dtype=np.uint8))]
    expected = {"short packet": 5, "long packet": 1, "unknown magic": 3, "zero frame rate": 1}
    assert all(g[:2] not in (struct.pack("<H", 18458), struct.pack("<H", 29569)) for g in garbage[2:4] + garbage[-1:])
    with sitl(full_vessel) as (client, box):
        replies = []
        for k, pwm in enumerate(frames):
            if k % 6 == 3:
                for g in garbage:
                    client.raw(g)
            replies.append(client.frame(k, pwm))  # the next datagram back answers this frame
        assert client.nothing_pending(), "garbage must never be answered"
    counters = box["summary"].counters
    assert counters.ignored == {reason: 10 * n for reason, n in expected.items()}
    assert counters.frames == 60
    clean, _, _ = play(full_vessel, [(k, pwm, 400) for k, pwm in enumerate(frames)])
    assert replies == clean


# ---------------------------------------------------------------- the states are consistent

def test_the_states_sent_are_kinematically_consistent(full_vessel):
    frames, _ = pwm_frames(600, seed=8)
    replies, _, _ = play(full_vessel, [(k, pwm, 400) for k, pwm in enumerate(frames)])
    a = arrays(replies)
    dt = np.diff(a["t"])[:, None]
    # velocity is the derivative of position: the chord slope is the mean of the end velocities to O(dt²)
    np.testing.assert_allclose(np.diff(a["pos"], axis=0) / dt, 0.5 * (a["vel"][1:] + a["vel"][:-1]), atol=2e-5)
    np.testing.assert_allclose(np.diff(np.unwrap(a["att"][:, 2])) / dt[:, 0],
                               0.5 * (a["gyro"][1:, 2] + a["gyro"][:-1, 2]), atol=2e-5)
    # the specific force, rotated to NED with the attitude sent, plus gravity, is the velocity change
    psi = a["att"][1:, 2]
    c, s = np.cos(psi), np.sin(psi)
    ax, ay = a["acc"][1:, 0], a["acc"][1:, 1]
    accel_ned = np.column_stack([c * ax - s * ay, s * ax + c * ay])
    np.testing.assert_allclose(accel_ned, np.diff(a["vel"][:, :2], axis=0) / dt, atol=1e-9)
    np.testing.assert_array_equal(a["acc"][:, 2], -GRAVITY)
    assert np.all(a["gyro"][:, :2] == 0) and np.all(a["att"][:, :2] == 0)
    np.testing.assert_allclose(a["quat"][:, 0], np.cos(a["att"][:, 2] / 2), atol=1e-15)
    np.testing.assert_allclose(a["quat"][:, 3], np.sin(a["att"][:, 2] / 2), atol=1e-15)
    assert np.all(np.abs(a["att"][:, 2]) <= np.pi)


def test_at_rest_the_imu_feels_only_gravity_and_in_a_steady_turn_the_centripetal_force():
    calm = load("yellowfish")
    rest, _, _ = play(calm, [(k, [0] * 16, 50) for k in range(20)], current=(0, 0), wind=(0, 0))
    for r in rest:
        assert r["imu"] == {"gyro": [0.0, 0.0, 0.0], "accel_body": [0.0, 0.0, -GRAVITY]}
        assert r["position"] == [0.0, 0.0, 0.0] and r["velocity"] == [0.0, 0.0, 0.0]
    turn = [1750, 0, 1550] + [0] * 13
    replies, _, _ = play(calm, [(k, turn, 50) for k in range(1500)], rate_hz=50)  # 30 s, steady
    last = replies[-1]
    psi = last["attitude"][2]
    vn, ve = last["velocity"][:2]
    u, v = math.cos(psi) * vn + math.sin(psi) * ve, -math.sin(psi) * vn + math.cos(psi) * ve
    r = last["imu"]["gyro"][2]
    ax, ay, _ = last["imu"]["accel_body"]
    assert r > 0.05 and u > 0.5, "a steady starboard turn"
    assert ay == pytest.approx(r * u, rel=0.02) and ax == pytest.approx(-r * v, abs=2e-3)


# ---------------------------------------------------------------- real time

def test_real_time_paces_the_twin_to_the_wall_clock(full_vessel):
    frames, _ = pwm_frames(400, seed=9)
    with sitl(full_vessel, realtime=True) as (client, _box):
        start = time.perf_counter()
        fast = []
        for k in range(40):  # as fast as answered: the twin may not run ahead of the wall clock
            fast.append((client.frame(k, frames[k])["timestamp"], time.perf_counter() - start))
        slow = []
        for k in range(40, 55):  # 50 Hz arrivals of 400 Hz frames: the twin keeps up with the wall clock
            time.sleep(0.02)
            slow.append((client.frame(k, frames[k])["timestamp"], time.perf_counter() - start))
    for t_s, wall_s in fast + slow:
        assert t_s <= wall_s + 1e-3
    t_end, wall_end = slow[-1]
    assert t_end == pytest.approx(wall_end, abs=0.05)
    assert fast[-1][0] == pytest.approx(fast[-1][1], abs=0.03)
    steps = np.diff([t for t, _ in slow])
    assert np.median(steps) >= 0.015, "several frame periods per frame when frames come slower than real time"


# ---------------------------------------------------------------- recording and bad input

def test_the_session_is_recorded_in_the_project_formats_also_when_ended_by_ctrl_c(full_vessel, tmp_path):
    frames, _ = pwm_frames(300, seed=10)
    paths = [tmp_path / f"sitl{ext}" for ext in (".csv", ".mcap", ".tlog", ".bin", ".rrd")]
    box, replies = {}, []

    def ardupilot():
        # Ctrl-C comes whatever happens here, so that a failure on this side fails the test (the
        # counts below) instead of leaving the backend waiting for frames forever
        try:
            if not box_ready.wait(120):
                return
            client = Client(box["port"])
            try:
                replies.extend(client.frame(k, pwm) for k, pwm in enumerate(frames))
            finally:
                client.close()
                time.sleep(0.05)  # the backend back waiting for a frame, as when a user presses Ctrl-C
        finally:
            os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C: a real SIGINT, which interrupts a blocked receive

    box_ready = threading.Event()
    thread = threading.Thread(target=ardupilot, daemon=True)
    # Python's own handler, as a user's Ctrl-C meets it (run_sitl puts its own in place while it serves)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    thread.start()
    summary = None
    try:
        summary = run_sitl(full_vessel, port=0, host="127.0.0.1", record_paths=paths, origin=(37.41, -5.98),
                           ready=lambda address: (box.__setitem__("port", address[1]), box_ready.set()))
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler, "run_sitl restores the handler"
    except KeyboardInterrupt:  # pragma: no cover - a late interrupt outside the session loop
        pytest.fail("Ctrl-C escaped run_sitl")
    finally:
        signal.signal(signal.SIGINT, previous)
    thread.join(10)
    assert summary.interrupted and summary.signal_name == "SIGINT" and summary.counters.frames == 300
    assert set(summary.written) == set(paths)
    assert all(p.is_file() and p.stat().st_size > 0 for p in paths)
    assert not list(tmp_path.glob(".*.tmp")), "atomic writes leave no temporary file"
    run = read_csv(paths[0])
    a = arrays(replies)
    assert len(run.t) == 301
    np.testing.assert_allclose(run.t[1:], a["t"], rtol=1e-9)
    np.testing.assert_allclose(run.eta[1:, :2], a["pos"][:, :2], rtol=1e-8, atol=1e-9)
    np.testing.assert_allclose(run.pwm_us[:, 0], [p[0] or NEUTRAL for p in frames] + [frames[-1][0] or NEUTRAL])
    for path in paths[1:4]:  # what `twin info` reads
        rec = read_recording(path)
        assert len(rec.gnss) > 3 and len(rec.pwm) > 3 and rec.duration_s() == pytest.approx(0.75, abs=0.11)


def test_bad_input_is_a_one_line_error(tmp_path):
    holder = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    holder.bind(("127.0.0.1", 0))
    port = holder.getsockname()[1]
    try:
        with pytest.raises(TwinError, match=rf"^port {port} is in use \(another SITL backend running\?\): "
                                            r"choose --port$"):
            run_sitl("yellowfish", port=port, host="127.0.0.1", stop_after_frames=0)
    finally:
        holder.close()
    bad = tmp_path / "bad.json"
    bad.write_text('{"name": "x", "mjcf": "nowhere.xml"}')
    with pytest.raises(TwinError, match="MJCF file 'nowhere.xml' not found"):
        run_sitl(str(bad), port=0, stop_after_frames=0)
    with pytest.raises(TwinError, match="unknown format"):
        run_sitl("yellowfish", port=0, record_paths=[tmp_path / "x.txt"], stop_after_frames=0)
    with pytest.raises(TwinError, match="two different servo outputs"):
        run_sitl("yellowfish", port=0, channels=(3, 3), stop_after_frames=0)
    with pytest.raises(TwinError, match=r"^--esc-arm -1: the ESC arming time is a number of seconds ≥ 0"):
        run_sitl("yellowfish", port=0, esc_arm_s=-1, stop_after_frames=0)


def test_the_twin_refuses_to_step_without_its_hydrodynamics():
    twin = SitlTwin(load("yellowfish"))
    with pytest.raises(RuntimeError, match="active"):
        twin.step([1600] * 16, 400)


def test_a_diverging_twin_is_a_one_line_error_not_a_silent_reset():
    twin = SitlTwin(load("yellowfish"), record=False, esc_arm_s=0.0)
    with twin.active():
        for k in range(10):
            twin.step([1700, 0, 1700] + [0] * 13, 400)
        twin.data.qvel[0] = 1e300  # beyond mjMAXVAL: MuJoCo would reset the boat to the origin and go on
        with pytest.raises(TwinError, match=r"^the twin diverged between t = 0\.025 s and 0\.028 s: MuJoCo found "
                                            r"its velocity non-finite"):
            twin.step([1700, 0, 1700] + [0] * 13, 400)


def test_the_parameter_file_gives_ardupilot_the_vessels_pwm_range_and_the_speed_the_twin_cruises_at(tmp_path):
    from twin.sitl.params import boat_parameters, cruise_speed_m_s

    boat = load("blueboat")
    lines = dict(line.split("#")[0].split() for line in boat_parameters(boat, (2, 17)).splitlines()
                 if line.strip() and not line.startswith("#"))
    neutral = boat.thrusters.pwm_offset * boat.thrusters.pwm_scale_us
    assert lines["SERVO2_FUNCTION"] == "73" and lines["SERVO17_FUNCTION"] == "74" and lines["SERVO_32_ENABLE"] == "1"
    assert float(lines["SERVO17_TRIM"]) == pytest.approx(neutral, abs=0.5) and lines["FRAME_CLASS"] == "2"
    # the cruise pair is the twin's own steady state: half throttle both, calm water
    half = neutral + 0.5 * (boat.thrusters.pwm_max_us - neutral)
    run = simulate(compile_vessel(boat), InputSeries(np.array([0.0]), np.array([[half, half]]), "pwm"), 120.0)
    assert float(lines["CRUISE_SPEED"]) == pytest.approx(run.nu[-1, 0], abs=0.01) and lines["CRUISE_THROTTLE"] == "50"
    windy = boat.with_environment(replace(boat.environment, current_speed_m_s=0.5, wind_speed_m_s=8.0))
    assert cruise_speed_m_s(windy) == pytest.approx(float(lines["CRUISE_SPEED"]), abs=0.01)
    with pytest.raises(TwinError, match="propeller-and-rudder"):
        boat_parameters(load("esso_osaka"))
    out = tmp_path / "boat.parm"
    def twin(*args):
        return twin_command.twin("sitl", "--vessel", "yellowfish", *args)

    assert twin("--write-params", out).returncode == 0 and "SERVO3_FUNCTION 74" in out.read_text()
    refused = twin("--write-params", tmp_path / "b.json")
    assert refused.returncode == 2 and "unknown format" in refused.stderr and not (tmp_path / "b.json").exists()


# ---------------------------------------------------------------- ESC arming and a clean stop

def sitl_startup(rate: int = 1200) -> list[list[int]]:
    """ArduPilot Rover SITL's first frames as a real start at 1200 Hz sent them on outputs 1-4 (the others
    taken alike here): 1500 µs for 2240 frames, then 1000 µs on output 1 alone for 24 frames (20 ms) while
    its outputs are set up, then the disarmed outputs: trim on the throttle outputs 1 and 3, 0 elsewhere."""
    return ([[1500] * 16] * 2240 + [[1000] + [0] * 15] * 24 + [[1500, 0, 1500] + [0] * 13] * (3 * rate))


def test_a_disarmed_autopilot_does_not_move_the_boat_the_escs_arm_on_a_stopped_signal():
    calm = load("yellowfish")
    startup = sitl_startup()
    twin = SitlTwin(calm, esc_arm_s=2.0)
    with twin.active():
        replies = [twin.step(pwm, 1200) for pwm in startup]
        assert all(r.north_m == r.east_m == r.yaw_rad == 0.0 for r in replies), "the start-up pulse moved the boat"
        assert twin.escs_armed == (True, True)  # 2 s of neutral after the pulse, within the 3 s of trim
        ahead = [twin.step([1700, 0, 1700] + [0] * 13, 1200) for _ in range(1200)]
    run = twin.recording()
    pulse = (run.t >= 2240 / 1200) & (run.t < 2264 / 1200 - 1e-9)
    assert pulse.sum() == 24 and np.all(run.pwm_us[pulse, 0] == 1000.0) and np.all(run.thrust_n[pulse] == 0.0)
    assert ahead[-1].north_m > 0.3 and abs(ahead[-1].east_m) < 1e-9, "armed, both ahead: straight on"

    # an ESC that needs no stopped signal takes the pulse as full astern on the left thruster
    eager = SitlTwin(calm, esc_arm_s=0.0, record=False)
    with eager.active():
        last = [eager.step(pwm, 1200) for pwm in startup][-1]
    assert math.hypot(last.north_m, last.east_m) > 0.01 and abs(last.yaw_rad) > 1e-3

    # a thrust command before the ESC has seen 2 s of neutral is held back, and starts the count again
    twin = SitlTwin(calm, esc_arm_s=2.0, record=False)
    with twin.active():
        for k in range(int(1.5 * 1200)):
            twin.step([1500, 0, 1500] + [0] * 13, 1200)
        early = [twin.step([1800, 0, 1800] + [0] * 13, 1200) for _ in range(600)]
        assert early[-1].north_m == 0.0 and twin.escs_armed == (False, False)
        for k in range(int(2.0 * 1200)):
            twin.step([1520, 0, 1480] + [0] * 13, 1200)  # within the ESC's ±25 µs: the stopped signal
        moved = [twin.step([1800, 0, 1800] + [0] * 13, 1200) for _ in range(600)]
    assert twin.escs_armed == (True, True) and moved[-1].north_m > 0.1


def test_a_boat_at_rest_in_calm_water_is_stepped_exactly_as_mujoco_would():
    """The twin skips mj_step when nothing can move the boat (at rest, no thrust, calm water): the
    replies are the ones of a twin that always steps."""
    calm = load("yellowfish")
    frames, _ = pwm_frames(900, seed=12)
    sequence = [[0] * 16] * 300 + frames + [[1500] * 16] * 300
    results = []
    for skip in (True, False):
        twin = SitlTwin(calm, esc_arm_s=0.0, record=False)
        twin._calm = skip
        with twin.active():
            results.append([twin.step(pwm, 1200) for pwm in sequence])
    assert results[0] == results[1]
    assert results[0][299].north_m == 0.0 and results[0][1199].north_m != 0.0


def test_sigterm_and_sigint_in_the_background_end_twin_sitl_cleanly_with_its_recording(tmp_path):
    """`twin sitl &` from a script starts with SIGINT ignored; SIGTERM is what `kill` sends. Either way
    the session ends, the recording is written and the summary printed once."""
    import subprocess
    import sys

    for sig in (signal.SIGTERM, signal.SIGINT):
        path = tmp_path / f"{sig.name}.csv"
        proc = subprocess.Popen([sys.executable, "-m", "twin", "sitl", "--vessel", "yellowfish", "--port", "0",
                                 "--host", "127.0.0.1", "--record", str(path)], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True,
                                preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
        try:
            port = int(re.search(r"udp [\d.]+:(\d+)", proc.stderr.readline()).group(1))
            client = Client(port)
            for k in range(50):
                client.frame(k, [1700, 0, 1700] + [0] * 13, 1200)
            client.close()
            proc.send_signal(sig)
            out, err = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
        assert proc.returncode == 0, err
        assert f"{sig.name}: ending the session" in err
        assert out.count("50 frames") == 1 and "frames" not in err.split("ending the session")[-1], (out, err)
        assert len(read_csv(path).t) == 51
    empty = tmp_path / "empty.csv"  # ended before ArduPilot sent a frame: no file, and a script is told
    proc = subprocess.Popen([sys.executable, "-m", "twin", "sitl", "--vessel", "yellowfish", "--port", "0",
                             "--host", "127.0.0.1", "--record", str(empty)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        proc.stderr.readline()
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode != 0 and "error: --record: nothing written" in err and not empty.exists(), err


def test_the_deviation_from_a_mission_is_the_distance_to_the_nearest_leg():
    from twin.sitl.ardupilot import offset_position, path_deviation_m

    path = [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0)]
    points = [(5.0, 1.5), (10.0, 5.0), (12.0, 12.0), (-3.0, -4.0), (9.0, 9.0), (10.0, 0.0)]
    np.testing.assert_allclose(path_deviation_m(points, path), [1.5, 0.0, math.hypot(2, 2), 5.0, 1.0, 0.0])
    with pytest.raises(TwinError, match="two points"):
        path_deviation_m(points, path[:1])
    lat, lon = offset_position(63.4366, 10.3991, 100.0, -50.0)  # back through twin.geodesy: the same metres
    from twin.geodesy import ned_from_geodetic

    north, east = ned_from_geodetic(lat, lon, 63.4366, 10.3991)
    assert north == pytest.approx(100.0, abs=1e-6) and east == pytest.approx(-50.0, abs=1e-6)


def test_mission_set_refuses_what_cannot_be_an_ardupilot_parameter_before_connecting():
    """--set is checked before any connection: a name ArduPilot could not have (17 characters, a digit
    first) and a value that is no finite number; a name it lacks is told with its closest ones."""
    from twin.cli.sitl import param_settings
    from twin.sitl.ardupilot import unknown_params_text

    assert param_settings(["atc_str_rat_ff=0.5", "WP_SPEED = 2"]) == {"ATC_STR_RAT_FF": 0.5, "WP_SPEED": 2.0}
    for item, message in [("ATC_STR_RAT_FF_XX=1", "--set ATC_STR_RAT_FF_XX: not an ArduPilot parameter name"),
                          ("1WP=1", "--set 1WP: not an ArduPilot parameter name"),
                          ("WP_SPEED=nan", "--set expects NAME=VALUE with a finite number, got 'WP_SPEED=nan'"),
                          ("WP_SPEED", "--set expects NAME=VALUE with a finite number, got 'WP_SPEED'")]:
        with pytest.raises(TwinError, match=re.escape(message)):
            param_settings([item])
    known = ["WP_SPEED", "WP_RADIUS", "ATC_STR_RAT_FF", "CRUISE_SPEED", "MAV3_PARAMS"]
    assert unknown_params_text(["WP_SPD", "ZZZ"], known) == ("--set: ArduPilot has no parameter WP_SPD (did you mean "
                                                            "WP_SPEED?); ZZZ: nothing was set")
    assert "did you mean" not in unknown_params_text(["NOT_A_PARAM"], known)  # another family's name is no typo


@contextlib.contextmanager
def closing_console(heartbeat: bool):
    """A TCP server on a free port that accepts each connection and closes it at once, after one
    ArduPilot heartbeat when `heartbeat`: an autopilot whose console goes away. Yields the port."""
    from pymavlink.dialects.v20 import ardupilotmega as mavlink

    packet = mavlink.MAVLink(None, srcSystem=1, srcComponent=1).heartbeat_encode(
        mavlink.MAV_TYPE_GROUND_ROVER, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 0).pack(
        mavlink.MAVLink(None, srcSystem=1, srcComponent=1))
    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    server.bind(("127.0.0.1", 0))
    server.listen(8)
    server.settimeout(0.1)
    stop = threading.Event()

    def serve():
        while not stop.is_set():
            try:
                conn, _ = server.accept()
            except OSError:
                continue
            with conn:
                if heartbeat:
                    conn.sendall(packet)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield server.getsockname()[1]
    finally:
        stop.set()
        thread.join(5)
        server.close()


def test_mission_ends_at_once_with_one_line_when_ardupilot_closes_the_connection():
    """pymavlink prints "EOF on TCP socket" on every read of a closed socket, some 150,000 lines a second
    until --timeout: the closed connection is told once, at once, before a heartbeat or after one."""
    for heartbeat, before in ((False, "before its first heartbeat"), (True, "before an EKF navigating on GPS")):
        with closing_console(heartbeat) as port:
            start = time.monotonic()
            r = twin_command.twin("mission", "--home", "37.4,-5.9", "--waypoints", "10,0", "--port", port,
                                  "--timeout", "20")
            took_s = time.monotonic() - start
        assert r.returncode == 2 and took_s < 10.0, (r, took_s)
        assert "EOF" not in r.stdout + r.stderr and "Traceback" not in r.stderr
        assert r.stderr.strip().splitlines()[-1] == (f"error: ArduPilot closed the MAVLink connection on "
                                                     f"tcp:127.0.0.1:{port} {before}" +
                                                     (" (is ArduPilot's console on that port?)" if not heartbeat
                                                      else "")), r.stderr


def test_a_mission_file_gives_its_waypoints_in_metres_from_home(tmp_path):
    """A QGC WPL 110 file as Mission Planner saves it: the home item and the non-waypoint items left
    out (named), each waypoint (north, east) m from --home; a file of another kind is refused."""
    from twin.geodesy import geodetic_from_ned
    from twin.sitl.ardupilot import read_waypoint_file

    home = (63.4366, 10.3991)
    (lat1, lon1), (lat2, lon2) = [tuple(float(x) for x in geodetic_from_ned(n, e, *home)) for n, e in ((20, 0), (20, 15))]
    rows = ["QGC WPL 110", f"0\t1\t0\t16\t0\t0\t0\t0\t{home[0]}\t{home[1]}\t0\t1",
            f"1\t0\t3\t16\t0\t0\t0\t0\t{lat1:.8f}\t{lon1:.8f}\t0\t1",
            "2\t0\t3\t178\t0\t1.5\t0\t0\t0\t0\t0\t1",  # DO_CHANGE_SPEED
            f"3\t0\t3\t16\t0\t0\t0\t0\t{lat2:.8f}\t{lon2:.8f}\t0\t1", "4\t0\t3\t20\t0\t0\t0\t0\t0\t0\t0\t1"]
    path = tmp_path / "lake.waypoints"
    path.write_text("\n".join(rows) + "\n")
    points, notes = read_waypoint_file(path, home)
    assert np.allclose(points, [(20, 0), (20, 15)], atol=0.01)
    assert notes == ["lake.waypoints: left out, as `twin mission` drives from waypoint to waypoint: item 2 "
                     "(command 178), item 4 (command 20)"]
    path.write_text("\ufeff" + "\n".join(rows) + "\n", encoding="utf-8")  # a BOM before the header
    assert np.allclose(read_waypoint_file(path, home)[0], [(20, 0), (20, 15)], atol=0.01)
    path.write_text("t,lat,lon\n0,1,2\n")
    with pytest.raises(TwinError, match="not a mission file"):
        read_waypoint_file(path, home)


def test_a_wait_whose_autopilot_clock_stood_still_says_the_physics_stopped():
    """ArduPilot's SITL steps in lockstep with its physics: when `twin sitl` stops answering, its clock
    stands still, and a wait that times out says so rather than only that the mission did not come."""
    from twin.sitl.ardupilot import Rover

    rover = object.__new__(Rover)
    rover.boot_s, rover.texts = 12.0, []
    rover.pump = lambda: None
    with pytest.raises(TwinError, match=r"clock stood at 12.0 s all that time: its physics \(twin sitl\) stopped"):
        rover.wait(lambda: False, "the mission", 0.01)

    def ticking():
        rover.boot_s += 0.1

    rover.pump = ticking
    with pytest.raises(TwinError, match=r"the mission not within 0.01 s; last messages"):
        rover.wait(lambda: False, "the mission", 0.01)


# ---------------------------------------------------------------- in a seaway

def rotation(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Rz(yaw) Ry(pitch) Rx(roll): body FRD → NED, as ArduPilot's from_euler."""
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    return (np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]]) @ np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
            @ np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]]))


def quaternion_rotation(w: float, x: float, y: float, z: float) -> np.ndarray:
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def test_in_a_sea_the_6dof_hull_is_the_offline_twin_and_its_states_are_consistent(full_vessel, tmp_path):
    """`twin sitl --sea`: lock-step at 50 Hz frames (the 6-DOF model's own 20 ms step) gives the offline
    `simulate(sea=...)` to the bit, heave, roll and pitch included, and a recording holds them as the
    offline run does; the attitude, quaternion, body rates and specific force sent agree."""
    sea = parse_sea("0.3,3,45", 0)
    frames, pairs = pwm_frames(300, seed=13)
    path = tmp_path / "sea.csv"
    replies, summary, _ = play(full_vessel, [(k, pwm, 50) for k, pwm in enumerate(frames)], rate_hz=50, sea=sea,
                               record_paths=[path])
    assert summary.counters.frames == 300
    n = len(pairs)
    # the frames' stamps as SITL makes them (k steps of 1/50 s): a delayed input that changes within a
    # step acts for its share of it, which the stamps' last bits move
    series = InputSeries(np.concatenate([[-1.0], np.arange(n) * (1 / 50)]), np.vstack([[NEUTRAL, NEUTRAL], pairs]),
                         "pwm")
    run = simulate(compile_vessel(full_vessel), series, n / 50, sample_dt_s=1 / 50, sea=sea)
    a = arrays(replies)
    six = run.meta["six_dof"]
    np.testing.assert_array_equal(a["t"], run.t[1:n + 1])
    np.testing.assert_array_equal(a["pos"][:, :2], run.eta[1:n + 1, :2])
    np.testing.assert_array_equal(a["att"][:, 2], [math.remainder(p, 2 * math.pi) for p in run.eta[1:n + 1, 2]])
    np.testing.assert_allclose(a["vel"][:, :2], ned_velocity(run)[1:n + 1], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(a["pos"][:, 2], six["down_m"][1:n + 1])
    np.testing.assert_array_equal(a["vel"][:, 2], six["down_rate_m_s"][1:n + 1])
    np.testing.assert_array_equal(a["att"][:, 0], six["roll_rad"][1:n + 1])
    np.testing.assert_array_equal(a["att"][:, 1], six["pitch_rad"][1:n + 1])
    assert np.ptp(a["att"][:, 0]) > 0.01 and np.ptp(a["att"][:, 1]) > 0.01 and np.ptp(a["pos"][:, 2]) > 0.01, \
        "the hull must roll, pitch and heave for the comparison to mean anything"
    for r, q in zip(replies, a["quat"]):
        assert q[0] >= 0
        np.testing.assert_allclose(quaternion_rotation(*q), rotation(*r["attitude"]), atol=1e-12)
    # body rates: the Euler angles' rates turned into the body frame, at the frame's end
    phi, theta = six["roll_rad"][1:n + 1], six["pitch_rad"][1:n + 1]
    dphi, dtheta, dpsi = six["roll_rate_rad_s"][1:n + 1], six["pitch_rate_rad_s"][1:n + 1], run.nu[1:n + 1, 2]
    p = dphi - dpsi * np.sin(theta)
    q = dtheta * np.cos(phi) + dpsi * np.cos(theta) * np.sin(phi)
    r = dpsi * np.cos(theta) * np.cos(phi) - dtheta * np.sin(phi)
    np.testing.assert_allclose(a["gyro"], np.column_stack([p, q, r]), atol=1e-12)
    # the specific force, rotated to NED with the attitude sent, plus gravity, is the velocity change
    dt = np.diff(a["t"])
    for k in range(1, n):
        ned = rotation(*a["att"][k]) @ a["acc"][k] + [0.0, 0.0, GRAVITY]
        np.testing.assert_allclose(ned, (a["vel"][k] - a["vel"][k - 1]) / dt[k - 1], atol=1e-9)
    table = np.genfromtxt(path, delimiter=",", names=True)
    assert table.dtype.names[-3:] == ("down", "roll", "pitch") and len(table) == n + 1
    for column, name in (("down", "down_m"), ("roll", "roll_rad"), ("pitch", "pitch_rad")):
        np.testing.assert_allclose(table[column], six[name], rtol=1e-8, atol=1e-12)


def test_a_6dof_reply_is_read_exactly_by_ardupilots_parser():
    rng = np.random.default_rng(6)
    for _ in range(50):
        values = rng.normal(size=16) * 10.0 ** rng.integers(-9, 4, 16)
        r = Reply(*(float(x) for x in values))
        r = r._replace(yaw_rad=math.remainder(r.yaw_rad, 2 * math.pi), roll_rad=math.remainder(r.roll_rad, 2 * math.pi),
                       pitch_rad=math.remainder(r.pitch_rad, math.pi), timestamp_s=abs(r.timestamp_s))
        line = format_reply(r).decode("ascii")
        seen = _ardupilot_parse(line)
        assert seen["timestamp"] == [r.timestamp_s]
        assert seen["position"] == [r.north_m, r.east_m, r.down_m] and seen["velocity"] == [r.vn_m_s, r.ve_m_s, r.vd_m_s]
        assert seen["gyro"] == [r.gyro_x_rad_s, r.gyro_y_rad_s, r.yaw_rate_rad_s]
        assert seen["accel_body"] == [r.ax_m_s2, r.ay_m_s2, r.az_m_s2]
        assert seen["attitude"] == [r.roll_rad, r.pitch_rad, r.yaw_rad]
        w, x, y, z = seen["quaternion"]
        assert w >= 0 and math.isclose(w * w + x * x + y * y + z * z, 1.0, abs_tol=1e-12)
        np.testing.assert_allclose(quaternion_rotation(w, x, y, z), rotation(r.roll_rad, r.pitch_rad, r.yaw_rad),
                                   atol=1e-12)
        assert r.as_dict() == decode(line.encode())


def test_a_long_recording_waits_on_disk_not_in_memory_and_reads_back_row_for_row(tmp_path):
    """Past the rows held in memory, the recording goes to an unnamed file in the spool folder; what
    `recording()` gives is the same run, row for row, as one held whole in memory, and the session's
    memory holds no more than a block of rows."""
    vessel = load("yellowfish")
    rng = np.random.default_rng(5)
    frames = [[int(p) for p in rng.integers(1300, 1700, 2)] for _ in range(700)]
    runs = []
    for spool_at in (None, 64):
        twin = SitlTwin(vessel, esc_arm_s=0.0, spool_dir=tmp_path)
        if spool_at:
            twin._spool_at = spool_at * twin._row
        with twin.active():
            for k, (left, right) in enumerate(frames):
                twin.step([left, 0, right] + [0] * 13, 400)
                assert len(twin._rows) <= (spool_at or len(frames)) * twin._row
                if k == 350:  # read mid-session: the session then goes on recording
                    assert len(twin.recording().t) == 352
        runs.append(twin.recording())
        assert twin.frames_recorded == len(frames) and twin._spooled == (640 if spool_at else 0)
    held, spooled = runs
    assert len(spooled.t) == len(frames) + 1
    for a, b in zip(held.columns().values(), spooled.columns().values()):
        np.testing.assert_array_equal(a, b)
    assert list(tmp_path.iterdir()) == []  # the spool has no name in the folder


def test_a_spool_that_cannot_be_written_is_one_line_and_keeps_the_rows_held(tmp_path):
    twin = SitlTwin(load("yellowfish"), esc_arm_s=0.0, spool_dir=tmp_path / "gone")
    twin._spool_at = 8 * twin._row
    with twin.active(), pytest.raises(TwinError, match=f"cannot hold the recording in '{tmp_path / 'gone'}': "):
        for _ in range(20):
            twin.step([1600, 0, 1600] + [0] * 13, 400)
    run = twin.recording()  # the frames run, and the state after the last of them
    assert twin.frames_recorded == 8 and len(run.t) == 9 and np.all(np.diff(run.t) > 0)
