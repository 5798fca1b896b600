"""The twin as a live physics backend: stepped one ArduPilot frame at a time.

`SitlTwin.step(pwm, frame_rate_hz)` applies the servo outputs of one frame and
advances the full twin (MuJoCo rigid body, the native hydrodynamic callback with
added mass, Coriolis, damping, current and wind, the thrusters as actuators with
their lag) by one frame period, and returns what ArduPilot is sent back. The
engine is the one every other command uses; only the driving differs: inputs
arrive one frame at a time instead of as a series known in advance.

Choices, and why:

- **Physics step.** A frame lasts 1/frame_rate. The engine steps at least
  `min_rate_hz` times a second and a whole number of times per frame:
  h = (1/frame_rate) / ceil(min_rate_hz / frame_rate). At Rover SITL's default
  1200 Hz frames (SIM_RATE_HZ) and the default 400 Hz that is one step of 0.833 ms
  per frame; at 400 Hz frames one of 2.5 ms; at 50 Hz frames, eight. A
  frame rate change (SIM_RATE_HZ changed in flight) starts a new segment of
  constant step at the current time, so times stay k·h within a segment: the
  same numbers an offline run at that step computes.
- **Thruster commands** follow `ThrusterModel.command` exactly, step by step as
  `engine.sim.simulate` does: the input held `delay_s` earlier (a zero-order-hold
  history of the frames' inputs, neutral before the session started), through
  the PWM map ([Yellowfish-TR eq. 27] with its dead zone), times the thrust decay at the
  step's time, then a thrust ramp's slew limit (each step's mean of the ramp, from rest at
  the start of the SITL session); a step within which the delayed input changes is taken in two
  parts, each under the input held over it (through the ramp where there is one). The decay counts from the start of the twin's clock, which starts
  again with ArduPilot (a restart is a new session). Gains, lag and the
  advance-speed loss act in MuJoCo as everywhere else. A twin whose thrust follows the
  supply voltage runs at its reference voltage: SITL sends no battery (ArduPilot simulates
  its own), so the factor is 1.
- **ESC arming.** A real ESC does not drive its motor until, after power-up, it has
  seen the stopped signal for a while: the Blue Robotics Basic ESC (BLHeli_S) wants
  "a stopped signal (1500 microseconds) for a few seconds" [BlueRobotics-BasicESC].
  ArduPilot, before its outputs are set up, sends 1000 µs on output 1 alone for about
  20 ms; an ESC that obeyed it would run one thruster full astern before arming. So
  each thruster gives no thrust until its PWM has stayed within ±25 µs (the ESC's
  deadband, same source) of its neutral for `esc_arm_s` (2 s by default, the short end
  of "a few seconds"); a pulse outside that band before then starts the count again.
  A twin reset (ArduPilot restarted) powers the ESCs up again. `esc_arm_s = 0` drives
  the thrusters from the first frame. The recording keeps the PWM ArduPilot sent and
  the thrust the ESCs gave (zero while unarmed).
- **PWM.** Output 0 (ArduPilot's "no output") is the thruster's neutral: for a
  T200 map the PWM of δ̃ = 0, pwm_offset·pwm_scale_us (1500 µs); for a vessel whose
  thrusters are "direct" (thrust in N, no PWM map) the PWM range
  [pwm_min_us, pwm_max_us] (1100-1900 µs by default) maps linearly onto the thrust
  a full normalised command stands for (`ThrusterModel.command_range`: the thrust
  bounds, or ±command_scale_n for thrusters without bounds), its middle to zero
  thrust, as `drive.to_thruster_inputs` maps a normalised command.
- **The states sent** are consistent with each other: position and velocity are
  MuJoCo's joint state (velocity is the derivative of position); the specific
  force is the mean kinematic acceleration over the frame, (v_ned(t1) − v_ned(t0))
  / (t1 − t0), minus gravity, expressed in the body frame of the reply's attitude,
  so that ArduPilot, rotating it back with that attitude and adding gravity, gets
  exactly the velocity change it is told about (the IMU's delta-velocity). It
  holds the centripetal terms of ν̇ + ω×v without differentiating ν. Gravity is
  ArduPilot's own (GRAVITY_MSS, 9.80665 m/s², AP_Math/definitions.h), so at rest the
  IMU reads (0, 0, −9.80665) exactly what ArduPilot subtracts: the planar twin's
  motion does not depend on gravity, its EKF's vertical channel does.
- **In a seaway** (`sea`): the 6-DOF hull of `engine.sixdof` (heave, roll and pitch freed,
  floating on its meshes, the 3-DOF horizontal model unchanged), started at rest on its
  equilibrium. The reply carries the body origin's six degrees of freedom: down position and
  velocity, roll and pitch (zyx Euler angles, R = Rz(ψ) Ry(θ) Rx(φ)), the body rates (p, q, r)
  from the Euler angles' rates, and the specific force as above in all three axes, Rᵀ (Δv/Δt −
  g). SITL places its own IMU and GPS at their offsets from that motion. A floating hull is
  never "at rest" to the bit, so it is always stepped.
- **Sensor calibration** amendments of a vessel file (heading bias, compass
  deviation, antenna offset, log clock offset) describe how a real boat's sensors
  err; SITL simulates its own sensors from the true state, so they are not applied
  here (ArduPilot's SIM_MAG_*, SIM_GPS*_POS_* play that role).
"""
from __future__ import annotations

import contextlib
import math
import tempfile
from array import array
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import IO, Iterator, Sequence

import mujoco
import numpy as np

from twin.engine.divergence import flagged, quiet_log, what_diverged
from twin.engine.mjcf import JOINTS, THRUSTERS, compile_vessel
from twin.engine.native import installed_native, with_native_params
from twin.engine.sim import initial_state
from twin.engine.sixdof import SIX_JOINTS, compile_six
from twin.errors import TwinError
from twin.physics.hydrodynamics import Terms
from twin.physics.sensors import Sensors
from twin.physics.thrusters import ThrusterModel, delivered, saturated, slew_parts, slew_step, slew_through
from twin.physics.waves import Sea
from twin.run import Run
from twin.sitl.protocol import Reply
from twin.vessel import Vessel

DEFAULT_CHANNELS = (1, 3)  # SERVO1_FUNCTION = 73 (throttle left), SERVO3_FUNCTION = 74 (throttle right)
GRAVITY_M_S2 = 9.80665  # ArduPilot's GRAVITY_MSS: the specific force at rest is what its EKF expects
ESC_ARM_S = 2.0  # [BlueRobotics-BasicESC]: "a stopped signal ... for a few seconds" (module docstring)
# the finest physics --rate: a 0.1 ms step, nine steps to a frame at Rover SITL's 1200 Hz (SIM_RATE_HZ), finer
# than any boat's dynamics needs. A step costs about 8 µs here: 1e5 Hz would just keep up with real time, and
# 1e9 Hz (833334 steps a frame) ran 165 times slower than it, with ArduPilot waiting on every frame
MAX_RATE_HZ = 10_000.0
ESC_DEADBAND_US = 25.0  # [BlueRobotics-BasicESC]: signal deadband ±25 µs around the stopped signal
SPOOL_ROWS = 65536  # recorded rows held in memory before they go to the spool file
ROW = 11  # recorded values per frame: t, x, y, ψ, u, v, r, pwm L/R, thrust command L/R
SIX_NAMES = ("down_m", "pitch_rad", "roll_rad", "down_rate_m_s", "pitch_rate_rad_s", "roll_rate_rad_s")  # and in a sea
_TWO_PI = 2.0 * math.pi
# bound once for the frame loop: module globals, not attribute lookups; a Reply from a tuple without
# NamedTuple's Python-level __new__
_new_tuple, _cos, _sin, _remainder, _mj_step = tuple.__new__, math.cos, math.sin, math.remainder, mujoco.mj_step
_ZOH_TOL_S = 1e-9  # as drive.InputSeries.at: an input switching at t holds from t on
# a step in two parts: (share of the step, first command (L, R), the rest's, [(share of the step, L, R)
# of each input held in the rest]), commands in N
StepParts = tuple[float, tuple[float, float], tuple[float, float], list[tuple[float, float, float]]]


@dataclass(frozen=True)
class PwmMap:
    """One thruster's PWM (µs) → its model input and raw thrust (N), on plain floats.

    `held` gives what `ThrusterModel.command` takes as its held input: the PWM itself
    (kind "pwm", T200 map) or the thrust of the linear map (kind "thrust", "direct"
    thrusters). `raw` is `command` before the decay. Plain-float arithmetic in numpy's
    order (clip as max then min, Horner from 0 as np.polyval), so the values are the
    bits the numpy path gives: an offline run and a SITL session agree exactly."""

    kind: str
    neutral_us: float
    pwm_min_us: float
    pwm_max_us: float
    scale_us: float
    offset: float
    forward: tuple[float, ...]
    reverse: tuple[float, ...]
    deadzone_fwd: float
    deadzone_rev: float
    thrust_min_n: float
    thrust_max_n: float
    full_forward_n: float = 0.0
    full_share: float = 1.0
    spans: tuple[float, float] = (1.0, 1.0)  # each ESC's PWM span (ThrusterModel.received)
    # each thruster's (forward, reverse) dead-zone edges where it has its own (ThrusterModel.edges_of)
    edges: tuple[tuple[float, float], tuple[float, float]] | None = None

    @classmethod
    def of(cls, t: ThrusterModel) -> "PwmMap":
        if t.kind == "t200":
            t_min, t_max = t.bounds()
            return cls("pwm", t.pwm_offset * t.pwm_scale_us, t.pwm_min_us, t.pwm_max_us, t.pwm_scale_us,
                       t.pwm_offset, tuple(t.forward), tuple(t.reverse), t.deadzone_fwd, t.deadzone_rev, t_min, t_max,
                       t.full_forward_n, t.full_share, (t.pwm_span_left, t.pwm_span_right),
                       None if t.deadzone_left is None and t.deadzone_right is None else (t.edges_of(0), t.edges_of(1)))
        try:  # full PWM asks what a full normalised command asks: the bounds, or ±command_scale_n
            t_min, t_max = t.command_range()
        except ValueError as exc:
            raise TwinError(f"direct-thrust vessel: PWM cannot be mapped to thrust ({exc})") from None
        mid = 0.5 * (t.pwm_min_us + t.pwm_max_us)
        return cls("thrust", mid, t.pwm_min_us, t.pwm_max_us, 0.5 * (t.pwm_max_us - t.pwm_min_us), 0.0, (), (),
                   0.0, 0.0, t_min, t_max)

    def received(self, pwm_us: float, side: int) -> float:
        """The pulse thruster `side` (0 left, 1 right) answers for a logged one: its ESC's span about
        neutral (ThrusterModel.received, the same operations in the same order)."""
        span = self.spans[side]
        return pwm_us if span == 1.0 else self.neutral_us + span * (pwm_us - self.neutral_us)

    def held(self, pwm_us: float) -> float:
        """The model input the PWM stands for: PWM (µs) itself, or thrust (N) for "direct"."""
        if self.kind == "pwm":
            return pwm_us
        s = (min(max(pwm_us, self.pwm_min_us), self.pwm_max_us) - self.neutral_us) / self.scale_us
        return s * self.thrust_max_n if s >= 0.0 else -s * self.thrust_min_n

    def raw(self, held: float, side: int = 0) -> float:
        """Thrust (N) before the decay: [Yellowfish-TR eq. 27] with thruster `side`'s dead zone (0 left,
        1 right), or the thrust itself."""
        if self.kind != "pwm":
            return held
        x = min(max(held, self.pwm_min_us), self.pwm_max_us) / self.scale_us - self.offset
        edge_fwd, edge_rev = (self.deadzone_fwd, self.deadzone_rev) if self.edges is None else self.edges[side]
        if x >= edge_fwd:
            coefficients = self.forward
        elif x <= edge_rev:
            coefficients = self.reverse
        else:
            return 0.0
        y = 0.0
        for c in coefficients:
            y = y * x + c
        if coefficients is self.forward and self.full_share != 1.0:
            return saturated(y, self.full_forward_n, self.full_share)
        return y


def _index(model: mujoco.MjModel, obj, name: str, field: str) -> int:
    i = mujoco.mj_name2id(model, obj, name)
    return int(getattr(model, field)[i])


class SitlTwin:
    """The vessel's twin advanced frame by frame (module docstring): `reset()`, `step()`, and
    `recording()` of everything it did as a twin Run. Step only inside `with twin.active():`,
    which installs the native hydrodynamic callback (MuJoCo's callback is process-global).
    `sea` (physics.waves.Sea) runs the 6-DOF hull in that sea (module docstring, "In a seaway")."""

    def __init__(self, vessel: Vessel, *, min_rate_hz: float = 400.0,
                 channels: tuple[int, int] = DEFAULT_CHANNELS, heading_deg: float = 0.0, record: bool = True,
                 esc_arm_s: float = ESC_ARM_S, sea: Sea | None = None, spool_dir: str | Path | None = None) -> None:
        check_channels(channels)
        check_rate(min_rate_hz)
        check_esc_arm(esc_arm_s)
        self.esc_arm_s = float(esc_arm_s)
        if not math.isfinite(heading_deg):
            raise TwinError("the initial heading must be a finite number of degrees")
        self.vessel = vessel
        self.compiled = compile_vessel(vessel)
        self.sea = sea
        self._six = None if sea is None else compile_six(self.compiled, sea, Terms())
        self.model = with_native_params(self.compiled, Terms()) if self._six is None else self._six.model
        self.data = mujoco.MjData(self.model)
        self.min_rate_hz = float(min_rate_hz)
        self.channels = (int(channels[0]), int(channels[1]))
        self.heading_rad = math.radians(heading_deg)
        self.record = record
        self.map = PwmMap.of(vessel.thrusters)
        self._neutral_held = self.map.held(self.map.neutral_us)
        self._neutral_us = self.map.neutral_us
        self._outputs = (self.channels[0] - 1, self.channels[1] - 1)  # 0-based indices into the packet
        self._hysteretic = vessel.thrusters.hysteretic
        # per thruster (a dead zone of its own): PWM (µs) → raw thrust (N), ArduPilot's PWM is whole µs
        self._thrust_of: tuple[dict[float, float], dict[float, float]] = ({}, {})
        self._raw_of: tuple[dict[float, float], dict[float, float]] = ({}, {})  # held input → raw thrust (N), delayed path
        self._delay_s = float(vessel.thrusters.delay_s)
        self._decay_per_min = float(vessel.thrusters.decay_per_min)
        t = vessel.thrusters
        # a thrust ramp (slew limit): the most the command changes in one step, set with the step size
        self._slew_n_per_s = t.slew_n_per_s if t.ramping else None
        self._bounds = t.bounds()
        self._plain = self._delay_s == 0.0 and self._decay_per_min == 0.0 and self._slew_n_per_s is None
        env = vessel.environment
        # calm water and no wind: a boat at rest with no thrust feels no force, and stays as it is (a
        # floating hull's buoyancy and weight balance only to round-off: in a sea it is always stepped)
        self._calm = env.current_speed_m_s == 0.0 and env.wind_speed_m_s == 0.0 and sea is None
        m = self.model
        self._qadr = [_index(m, mujoco.mjtObj.mjOBJ_JOINT, j, "jnt_qposadr") for j in JOINTS]
        self._dadr = [_index(m, mujoco.mjtObj.mjOBJ_JOINT, j, "jnt_dofadr") for j in JOINTS]
        if self._six is not None:
            self._qadr_six = [_index(m, mujoco.mjtObj.mjOBJ_JOINT, j, "jnt_qposadr") for j in SIX_JOINTS]
            self._dadr_six = [_index(m, mujoco.mjtObj.mjOBJ_JOINT, j, "jnt_dofadr") for j in SIX_JOINTS]
        self._row = ROW if self._six is None else ROW + len(SIX_NAMES)
        self._act = [_index(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a, "actuator_actadr") if m.na else -1
                     for a in THRUSTERS]
        self._ctrl_ids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a) for a in THRUSTERS]
        self._az = -GRAVITY_M_S2  # the specific force down of a hull that stays level: gravity's reaction
        self._active = False
        self._rows = array("d")
        # rows past SPOOL_ROWS go to an unnamed file in spool_dir (the system's temporary folder if
        # None): the memory held stays the same however long ArduPilot flies
        self._spool_dir = spool_dir
        self._spool: IO[bytes] | None = None
        self._spooled = 0
        self._spool_at = SPOOL_ROWS * self._row
        self._record_offset_s = 0.0
        self.restarts_s: list[float] = []
        self.reset()

    # ------------------------------------------------------------ session

    @contextlib.contextmanager
    def active(self) -> Iterator["SitlTwin"]:
        """The native callback installed and MuJoCo's console/file warnings off while stepping."""
        with installed_native(six_dof=self._six is not None), quiet_log():
            self._active = True
            try:
                yield self
            finally:
                self._active = False
                self._rate_checked = None  # a step after this raises: the callback is gone

    @property
    def time_s(self) -> float:
        """The twin's clock (s since the last reset): the timestamp ArduPilot is sent."""
        return self._seg_t0 + self._seg_k * self._h

    @property
    def step_s(self) -> float:
        """The physics step (s) at the current frame rate (before the first frame: 1/min_rate_hz)."""
        return self._h

    @property
    def substeps(self) -> int:
        return self._nsub

    @property
    def six_dof(self) -> bool:
        """Whether the hull moves in heave, roll and pitch too (a sea was given)."""
        return self._six is not None

    def reset(self) -> None:
        """Back to the start: at the origin, heading `heading_deg`, at rest, thrusters neutral, clock 0.
        What was recorded so far stays; the record clock goes on from where it was, so a
        recording of several ArduPilot sessions keeps increasing times."""
        if getattr(self, "_rate_hz", None) is not None:
            self._record_offset_s += self.time_s
            self.restarts_s.append(self._record_offset_s)
        self._start()

    def warm_up(self) -> None:
        """One step, then back to the start with nothing recorded: the native callback's compilation
        and MuJoCo's first-step work are paid before ArduPilot's first frame, not during it."""
        record, self.record = self.record, False
        try:
            self.step([0] * 16, max(1, int(round(self.min_rate_hz))))
        finally:
            self.record = record
        self._start()

    @property
    def total_time_s(self) -> float:
        """Twin time over every ArduPilot session since the twin was built (the record clock), s."""
        return self._record_offset_s + self.time_s

    def _start(self) -> None:
        mujoco.mj_resetData(self.model, self.data)
        # the arrays' views, made once: each `data.qpos` access builds a new numpy view (about a µs)
        self._qpos, self._qvel, self._ctrl = self.data.qpos, self.data.qvel, self.data.ctrl
        eta0 = (0.0, 0.0, self.heading_rad)
        initial_state(self.model, self.data, eta0, None, None if self._six is None else self._six.initial_qpos(eta0))
        self._rate_hz = self._rate_checked = None
        self._seg_t0, self._seg_k, self._h, self._nsub = 0.0, 0, 1.0 / self.min_rate_hz, 1
        self.model.opt.timestep = self._h
        self._mj_time_s = self.data.time
        self._hist_t = [-math.inf]  # zero-order hold of the inputs: neutral before the session
        self._hist_l = [self._neutral_held]
        self._hist_r = [self._neutral_held]
        self._hist_i = 0
        self._pwm_last = (self.map.neutral_us, self.map.neutral_us)
        self._driven = None  # the thrusters' inputs last written to the controls (none yet)
        self._thrust_off = True  # both controls zero
        self._motors = (0, 0)  # a hysteretic map's motor states (+1 ahead, −1 astern, 0 stopped)
        self._ramped = (0.0, 0.0)  # where a thrust ramp stands: at rest, the inputs neutral before the session
        self._escs_ready = self.esc_arm_s == 0.0
        self._esc_ready = [self._escs_ready, self._escs_ready]
        self._esc_stopped_since_s: list[float | None] = [None, None]
        q, w = self._qpos.tolist(), self._qvel.tolist()
        a, b = self._qadr, self._dadr
        self._state = (q[a[0]], q[a[1]], q[a[2]], w[b[0]], w[b[1]], w[b[2]])
        if self._six is not None:
            a, b = self._qadr_six, self._dadr_six
            self._state_six = (q[a[0]], q[a[1]], q[a[2]], w[b[0]], w[b[1]], w[b[2]])

    def _check_rate(self, frame_rate_hz: int) -> None:
        """The first frame after a start, a reset or a rate change: the callback must be installed, and
        a new frame rate starts a new segment."""
        if not self._active:
            raise RuntimeError("step the twin inside `with twin.active():` (installs the hydrodynamic callback)")
        if frame_rate_hz != self._rate_hz:
            self._set_rate(frame_rate_hz)
        self._rate_checked = frame_rate_hz

    def _set_rate(self, frame_rate_hz: int) -> None:
        """A new constant-step segment from now: h = frame period / ceil(min_rate / frame rate)."""
        t = self.time_s
        frame_s = 1.0 / frame_rate_hz
        self._nsub = max(1, math.ceil(frame_s * self.min_rate_hz - 1e-9))
        self._h = frame_s / self._nsub
        self._seg_t0, self._seg_k = t, 0
        self._rate_hz = frame_rate_hz
        self.model.opt.timestep = self._h

    # ------------------------------------------------------------ stepping

    def step(self, pwm_us: Sequence[int], frame_rate_hz: int, frames: int = 1) -> Reply:
        """Apply one frame's servo outputs (16 or 32, µs) for `frames` frame periods (1 in
        lock-step; more when a real-time session catches up with the wall clock) and return
        the state at the end of the frame. The thrusters' outputs (1-based channels): 0,
        ArduPilot's "no output", or an output beyond the packet's (17+ in a 16-output packet) is
        the thruster's neutral."""
        n_out, (i_left, i_right) = len(pwm_us), self._outputs
        return self.step_pair(pwm_us[i_left] if i_left < n_out else 0, pwm_us[i_right] if i_right < n_out else 0,
                              frame_rate_hz, frames)

    def step_pair(self, pwm_left_us: int, pwm_right_us: int, frame_rate_hz: int, frames: int = 1) -> Reply:
        """`step` given the two thrusters' PWM (µs, 0: no output) instead of the packet's outputs: the
        frame loop's call. It runs over a thousand times a second, so the usual frame (rate known,
        ESCs armed, no hysteresis, no delay or decay) is one function of local arithmetic around
        mj_step; the rare cases branch off."""
        if frame_rate_hz != self._rate_checked:
            self._check_rate(frame_rate_hz)
        neutral = self._neutral_us
        pl = float(pwm_left_us) if pwm_left_us else neutral
        pr = float(pwm_right_us) if pwm_right_us else neutral
        n = frames * self._nsub
        k0, h, seg_t0 = self._seg_k, self._h, self._seg_t0
        t0 = seg_t0 + k0 * h
        driven = (pl, pr) if self._escs_ready else self._esc_gate(t0, pl, pr)
        if self._hysteretic:  # the motors answer the PWM as it comes (ThrusterModel.driven_step); the log keeps it
            self._motors, driven = self.vessel.thrusters.driven_step(self._motors, driven)
        if self._plain:
            # no delay and no decay: one thrust command for the whole frame, n steps inside MuJoCo. The
            # controls are written only when the inputs change (ArduPilot's outputs change at its loop
            # rate, 50 Hz, its frames come at 1200 Hz)
            if driven != self._driven:
                self._drive(driven)
            if self.record:
                self._record(t0, pl, pr)
            if self._calm and self._thrust_off and self._at_rest():
                # what mj_step would compute, exactly (every force and acceleration is zero): only the clock
                # moves. ArduPilot's boot and EKF alignment, tens of seconds of frames, cost almost nothing
                d = self.data
                for _ in range(n):
                    d.time += h
            else:
                _mj_step(self.model, self.data, n)
        else:
            self._advance_delayed(t0, pl, pr, driven, n)
        k1 = self._seg_k = k0 + n
        self._pwm_last = (pl, pr)
        if self._six is not None:
            return self._reply_six(t0, n)
        # the state after the frame, checked for divergence, with the frame's mean specific force
        _, _, _, vx0, vy0, _ = self._state
        q, w = self._qpos.tolist(), self._qvel.tolist()  # plain floats: cheaper than numpy scalars
        a, b = self._qadr, self._dadr
        x, y, psi, vx, vy, r = state = (q[a[0]], q[a[1]], q[a[2]], w[b[0]], w[b[1]], w[b[2]])
        total = x + y + psi + vx + vy + r
        # MuJoCo resets a diverged state (its clock too) and carries on: a clock that did not move on, a
        # NaN in the state (a last step) or, at the first step, MuJoCo's warning counters tell
        now_s, before_s = self.data.time, self._mj_time_s
        if now_s < before_s + 0.5 * n * h or total - total != 0.0 or before_s == 0.0:
            self._check_diverged(t0, now_s, before_s, n, total)
        self._mj_time_s = now_s
        self._state = state
        dt = n * h
        an, ae = (vx - vx0) / dt, (vy - vy0) / dt
        c, s = _cos(psi), _sin(psi)
        return _new_tuple(Reply, (seg_t0 + k1 * h, x, y, _remainder(psi, _TWO_PI), vx, vy, r,
                                  c * an + s * ae, -s * an + c * ae, self._az, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))

    def _reply_six(self, t0_s: float, n: int) -> Reply:
        """step_pair's reply for the 6-DOF hull (module docstring, "In a seaway")."""
        q, w = self._qpos.tolist(), self._qvel.tolist()
        a, b = self._qadr, self._dadr
        x, y, psi, vx, vy, dpsi = planar = (q[a[0]], q[a[1]], q[a[2]], w[b[0]], w[b[1]], w[b[2]])
        a, b = self._qadr_six, self._dadr_six
        z, theta, phi, vz, dtheta, dphi = six = (q[a[0]], q[a[1]], q[a[2]], w[b[0]], w[b[1]], w[b[2]])
        total = sum(planar) + sum(six)
        now_s, before_s = self.data.time, self._mj_time_s
        self._check_diverged(t0_s, now_s, before_s, n, total)
        self._mj_time_s = now_s
        vx0, vy0, vz0 = self._state[3], self._state[4], self._state_six[3]
        self._state, self._state_six = planar, six
        rot, (p, q_rate, r) = attitude(psi, theta, phi, dpsi, dtheta, dphi)
        dt = n * self._h
        # the mean acceleration over the frame minus gravity (NED, down +), in the body frame at its end: Rᵀ f
        fn, fe, fd = (vx - vx0) / dt, (vy - vy0) / dt, (vz - vz0) / dt - GRAVITY_M_S2
        return Reply(self.time_s, x, y, math.remainder(psi, _TWO_PI), vx, vy, r,
                     rot[0] * fn + rot[3] * fe + rot[6] * fd, rot[1] * fn + rot[4] * fe + rot[7] * fd,
                     rot[2] * fn + rot[5] * fe + rot[8] * fd, z, vz, math.remainder(phi, _TWO_PI), theta, p, q_rate)

    def _drive(self, driven: tuple[float, float]) -> None:
        """Write the thrusters' controls for these (ESC-passed) inputs."""
        mp = self.map
        left, right = self._thrust(mp.received(driven[0], 0), 0), self._thrust(mp.received(driven[1], 1), 1)
        ctrl, (il, ir) = self._ctrl, self._ctrl_ids
        ctrl[il] = left
        ctrl[ir] = right
        self._driven = driven
        self._thrust_off = left == 0.0 and right == 0.0

    def _check_diverged(self, t0_s: float, now_s: float, before_s: float, n: int, total: float) -> None:
        """Raise if the frame diverged (step_pair's tests; at the first step MuJoCo's warnings too)."""
        if now_s < before_s + 0.5 * n * self._h or total - total != 0.0 or (before_s == 0.0 and flagged(self.data)):
            raise TwinError(f"the twin diverged between t = {t0_s:.3f} s and {self.time_s:.3f} s: MuJoCo found its "
                            f"{what_diverged(self.data)} non-finite or beyond {mujoco.mjMAXVAL:g} (unstable "
                            f"parameters)")

    def _esc_gate(self, t0_s: float, pl: float, pr: float) -> tuple[float, float]:
        """What the ESCs pass on before they are armed (module docstring): neutral, until a thruster's
        PWM has stayed within the deadband of its neutral for esc_arm_s; from then on the PWM itself."""
        out = [pl, pr]
        for i, p in enumerate(out):
            if self._esc_ready[i]:
                continue
            since = self._esc_stopped_since_s[i]
            if abs(p - self._neutral_us) <= ESC_DEADBAND_US:
                if since is None:
                    self._esc_stopped_since_s[i] = t0_s
                out[i] = self._neutral_us  # the stopped signal: no thrust either way
                continue
            if since is not None and t0_s - since >= self.esc_arm_s - 1e-9:
                self._esc_ready[i] = True
                continue
            self._esc_stopped_since_s[i] = None
            out[i] = self._neutral_us
        self._escs_ready = self._esc_ready[0] and self._esc_ready[1]
        return out[0], out[1]

    @property
    def escs_armed(self) -> tuple[bool, bool]:
        """Whether each thruster's ESC (left, right) has armed and follows its PWM: it has, or it has
        seen the stopped signal for esc_arm_s up to now."""
        now = self.time_s

        def armed(i):
            since = self._esc_stopped_since_s[i]
            return self._esc_ready[i] or (since is not None and now - since >= self.esc_arm_s - 1e-9)

        return armed(0), armed(1)

    def _thrust(self, pwm_us: float, side: int) -> float:
        """Raw thrust (N) of a PWM as thruster `side`'s ESC receives it (PwmMap.received), cached: the
        map's polynomial once per distinct PWM value."""
        thrust = self._thrust_of[side].get(pwm_us)
        if thrust is None:
            mp = self.map
            thrust = self._thrust_of[side][pwm_us] = mp.raw(mp.held(pwm_us), side)
        return thrust

    def _raw(self, held: float, side: int) -> float:
        """PwmMap.raw of a held input, cached like `_thrust` (the delayed path looks it up every step)."""
        thrust = self._raw_of[side].get(held)
        if thrust is None:
            thrust = self._raw_of[side][held] = self.map.raw(held, side)
        return thrust

    def _advance_delayed(self, t0_s: float, pl: float, pr: float, driven: tuple[float, float], n: int) -> None:
        """A transport delay or a decay: the command at each step's start, from the input held
        delay_s before and the decay at that time (ThrusterModel.command, as engine.sim does). Every
        physics step runs this loop, so the hold lookup (a moving index: lookups only go forward in
        time) and the map's cache are inlined."""
        mp, m, d, ctrl, (il, ir) = self.map, self.model, self.data, self._ctrl, self._ctrl_ids
        self._hold(t0_s, mp.held(mp.received(driven[0], 0)), mp.held(mp.received(driven[1], 1)))
        h, t_seg, k0, delay_s = self._h, self._seg_t0, self._seg_k, self._delay_s
        decay_per_min, slew = self._decay_per_min, self._slew_n_per_s is not None
        times, lefts, rights, j = self._hist_t, self._hist_l, self._hist_r, self._hist_i
        last, (raw_left, raw_right), raw = len(times) - 1, self._raw_of, self._raw
        for i in range(n):
            t = t_seg + (k0 + i) * h
            x = t - delay_s + _ZOH_TOL_S  # the last frame that started at or before t − delay (InputSeries.at)
            while j < last and times[j + 1] <= x:
                j += 1
            held_left, held_right = lefts[j], rights[j]
            f = 1.0 - decay_per_min * t / 60.0  # ThrusterModel.decay_factor on a float (same operations, same bits)
            if f < 0.0:
                f = 0.0
            left, right = raw_left.get(held_left), raw_right.get(held_right)
            left = (raw(held_left, 0) if left is None else left) * f
            right = (raw(held_right, 1) if right is None else right) * f
            start = t - delay_s
            end = start + h
            parts = None
            if j < last and times[j + 1] <= end - _ZOH_TOL_S:
                parts = self._pieces(j, start, end, f, left, right)
            if slew:
                if parts is None:
                    left, right = self._ramp(left, right)
                else:
                    parts = self._ramp_parts(parts, left, right)
                    left, right = parts[1]
            ctrl[il] = left
            ctrl[ir] = right
            if i == 0 and self.record:
                self._record(t0_s, pl, pr)
            if parts is None:
                _mj_step(m, d)
            else:
                self._step_in_parts(parts)
        self._hist_i = j

    def _pieces(self, j: int, start: float, end: float, f: float, left: float, right: float) -> StepParts | None:
        """A step within which a delayed input changes, as engine.sim takes it (drive.StepPieces: the
        input held at the step's start over its share, then the rest's: the one input held there, or
        the mean of several), the same operations in the same order: (share, first command, the
        rest's, [(share of the step, left, right) of each input of the rest]); None where nothing
        changes (a stamp repeating the held input, or inputs that command the same thrust)."""
        h = self._h
        times, lefts, rights, last = self._hist_t, self._hist_l, self._hist_r, len(self._hist_t) - 1
        until = end - _ZOH_TOL_S
        k = j + 1
        while k <= last and times[k] <= until and lefts[k] == lefts[j] and rights[k] == rights[j]:
            k += 1
        if k > last or times[k] > until:
            return None
        change = times[k]
        pieces = []
        while k <= last and times[k] <= until:
            n = k + 1
            while n <= last and times[n] <= until and lefts[n] == lefts[k] and rights[n] == rights[k]:
                n += 1
            held_s = (times[n] if n <= last and times[n] <= until else end) - times[k]
            pieces.append((held_s, self._raw(lefts[k], 0) * f, self._raw(rights[k], 1) * f))
            k = n
        if all((p[1], p[2]) == (left, right) for p in pieces):
            return None
        if len(pieces) == 1:
            rest = (pieces[0][1], pieces[0][2])
        else:
            total_l = total_r = 0.0
            for held_s, piece_l, piece_r in pieces:
                total_l += held_s * piece_l
                total_r += held_s * piece_r
            rest = (total_l / (end - change), total_r / (end - change))
        return (change - start) / h, (left, right), rest, [(p[0] / h, p[1], p[2]) for p in pieces]

    def _step_in_parts(self, parts: StepParts) -> None:
        """One step in two (the first part's command already in the controls): the share of it, then
        the rest under its command."""
        m, d, ctrl, (il, ir), h = self.model, self.data, self._ctrl, self._ctrl_ids, self._h
        share, _, (rest_l, rest_r) = parts[:3]
        try:
            m.opt.timestep = share * h
            _mj_step(m, d)
            ctrl[il], ctrl[ir] = rest_l, rest_r
            m.opt.timestep = h - share * h
            _mj_step(m, d)
        finally:
            m.opt.timestep = h

    def _at_rest(self) -> bool:
        """No velocity and (with a thruster lag) no thrust still in the lag."""
        if any(self._qvel.tolist()):
            return False
        if self.model.na:
            act = self.data.act
            return act[self._act[0]] == 0.0 and act[self._act[1]] == 0.0
        return True

    def _hold(self, t_s: float, left: float, right: float) -> None:
        """Append a frame's inputs to the hold history; drop what no delayed lookup can reach."""
        self._hist_t.append(t_s)
        self._hist_l.append(left)
        self._hist_r.append(right)
        i = self._hist_i
        if i > 4096:
            del self._hist_t[:i], self._hist_l[:i], self._hist_r[:i]
            self._hist_i = 0

    def _ramp_parts(self, parts: StepParts, left: float, right: float) -> StepParts:
        """A step taken in two parts through the slew limit (physics.thrusters.slew_parts; heading for
        each input of the rest in turn where it holds several: slew_through): (share, the ramp's mean
        over the first part, over the rest, the rest's inputs)."""
        lo, hi = self._bounds
        share, _, (rest_l, rest_r), pieces = parts
        change = self._slew_n_per_s * self._h
        if len(pieces) > 1:  # frames are at least a step apart, so only after a frame rate change
            held = np.array([p[0] for p in pieces])
            out = []
            for side, (start, first) in enumerate(zip(self._ramped, (left, right))):
                head, middle = slew_step(start, min(max(first, lo), hi), change * share)
                tail, end = slew_through(middle, held, np.clip([p[1 + side] for p in pieces], lo, hi), change)
                out.append((head, tail, end))
            (first_l, mean_l, end_l), (first_r, mean_r, end_r) = out
        else:
            first_l, mean_l, end_l = slew_parts(self._ramped[0], min(max(left, lo), hi), share,
                                                min(max(rest_l, lo), hi), change)
            first_r, mean_r, end_r = slew_parts(self._ramped[1], min(max(right, lo), hi), share,
                                                min(max(rest_r, lo), hi), change)
        self._ramped = (end_l, end_r)
        return share, (first_l, first_r), (mean_l, mean_r), pieces

    def _ramp(self, left: float, right: float) -> tuple[float, float]:
        """The step's mean thrust command through the slew limit (physics.thrusters.slew_step)."""
        lo, hi = self._bounds
        change = self._slew_n_per_s * self._h
        (mean_l, end_l), (mean_r, end_r) = (slew_step(self._ramped[0], min(max(left, lo), hi), change),
                                            slew_step(self._ramped[1], min(max(right, lo), hi), change))
        self._ramped = (end_l, end_r)
        return mean_l, mean_r

    # ------------------------------------------------------------ recording

    def _record(self, t_s: float, pwm_left: float, pwm_right: float) -> None:
        """One row at the frame's start: the state then, the PWM held over the frame and the thrust
        command in force (the lagged thrust when there is a lag), as engine.sim records a sample."""
        if len(self._rows) >= self._spool_at:  # first: a spool that fails leaves no row of a frame not run
            self._flush()
        x, y, psi, vx, vy, r = self._state
        c, s = math.cos(psi), math.sin(psi)
        cl, cr = self._command_now()
        self._rows.extend((self._record_offset_s + t_s, x, y, psi, c * vx + s * vy, -s * vx + c * vy, r,
                           pwm_left, pwm_right, cl, cr))
        if self._six is not None:  # then heave, pitch and roll and their rates
            self._rows.extend(self._state_six)

    def _flush(self) -> None:
        """The rows held in memory to the spool file."""
        try:
            if self._spool is None:
                self._spool = tempfile.TemporaryFile(dir=self._spool_dir, prefix=".twin-sitl-", suffix=".rows")
            # from the end of the rows it holds: a write that failed part way leaves nothing counted
            self._spool.seek(self._spooled * self._row * 8)
            self._spool.truncate()
            self._rows.tofile(self._spool)
        except OSError as exc:
            raise TwinError(f"cannot hold the recording in '{self._spool_dir or tempfile.gettempdir()}': "
                            f"{exc.strerror or exc}") from None
        self._spooled += len(self._rows) // self._row
        del self._rows[:]

    def _command_now(self) -> tuple[float, float]:
        if self.model.na:
            act = self.data.act
            return float(act[self._act[0]]), float(act[self._act[1]])
        ctrl = self.data.ctrl
        return float(ctrl[self._ctrl_ids[0]]), float(ctrl[self._ctrl_ids[1]])

    @property
    def frames_recorded(self) -> int:
        return self._spooled + len(self._rows) // self._row

    def _recorded_rows(self, extra: int) -> np.ndarray:
        """Every recorded row in one array, with `extra` rows more left to fill (the spool read back)."""
        held = len(self._rows) // self._row
        rows = np.empty((self._spooled + held + extra, self._row))
        if self._spooled:
            self._spool.seek(0)
            self._spool.readinto(memoryview(rows[:self._spooled]).cast("B"))
        if held:
            rows[self._spooled:self._spooled + held] = np.frombuffer(self._rows, dtype=float).reshape(held, self._row)
        return rows

    def recording(self, meta: dict | None = None) -> Run:
        """Everything recorded as a twin Run (one row per frame at its start time, and the state
        after the last frame), times on the record clock that runs on across restarts; in a sea the
        heave, pitch, roll and their rates in meta["six_dof"], as engine.sim.simulate gives them."""
        ended = self.frames_recorded > 0 and self.time_s > 0
        rows = self._recorded_rows(1 if ended else 0)  # one copy: hours of frames run to gigabytes
        if ended:
            x, y, psi, vx, vy, r = self._state
            c, s = math.cos(psi), math.sin(psi)
            rows[-1] = [self._record_offset_s + self.time_s, x, y, psi, c * vx + s * vy, -s * vx + c * vy, r,
                        *self._pwm_last, *self._command_now(),
                        *(self._state_six if self._six is not None else ())]
        nu = rows[:, 4:7]
        thrust = delivered_thrust_n(self.vessel.thrusters, self.compiled.geometry.thruster_y_m, rows[:, 9:11], nu)
        info = {"vessel": self.vessel.name, "case": self.vessel.case, "engine": "mujoco", "source": "ardupilot-sitl",
                "backend": "native", "integrator": mujoco.mjtIntegrator(self.model.opt.integrator).name,
                "min_rate_hz": self.min_rate_hz, "channels": f"{self.channels[0]},{self.channels[1]}",
                "restarts_s": ",".join(f"{t:.6f}" for t in self.restarts_s)}
        if self._six is not None:
            info["six_dof"] = {**{name: rows[:, ROW + i] for i, name in enumerate(SIX_NAMES)},
                               "equilibrium": self._six.hull.equilibrium, "sea": self.sea.to_dict(),
                               "components": self._six.components}
        return Run(rows[:, 0], rows[:, 1:4], nu, rows[:, 7:9], thrust, meta={**info, **(meta or {})})


def attitude(psi: float, theta: float, phi: float, dpsi: float, dtheta: float,
             dphi: float) -> tuple[tuple[float, ...], tuple[float, float, float]]:
    """The hull's rotation R = Rz(ψ) Ry(θ) Rx(φ) (body FRD → NED, nine numbers row by row) and its body
    rates (p, q, r) from the Euler angles and their rates [Fossen-2021] (the 6-DOF joints, engine/sixdof.py)."""
    cps, sps, cth, sth, cph, sph = (math.cos(psi), math.sin(psi), math.cos(theta), math.sin(theta),
                                    math.cos(phi), math.sin(phi))
    rot = (cps * cth, cps * sth * sph - sps * cph, cps * sth * cph + sps * sph,
           sps * cth, sps * sth * sph + cps * cph, sps * sth * cph - cps * sph,
           -sth, cth * sph, cth * cph)
    return rot, (dphi - dpsi * sth, dtheta * cph + dpsi * cth * sph, dpsi * cth * cph - dtheta * sph)


def delivered_thrust_n(thrusters: ThrusterModel, thruster_y_m, command_n: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """Thrust each thruster delivers (N): the (lagged) command within the bounds, times its gain, less
    its advance loss −c·√|T0|·(u − r·y_i). engine.sim.delivered_thrust, vectorised over rows: a
    session at 400 Hz records 1.4 million rows an hour."""
    t_min, t_max = thrusters.bounds()
    static = np.clip(command_n, t_min, t_max) * thrusters.gains()
    return delivered(thrusters.advance_loss, static, nu, thruster_y_m) if thrusters.advance_loss else static


def check_rate(rate_hz: float) -> None:
    """A physics rate (Hz) above 0 and at most MAX_RATE_HZ."""
    number = isinstance(rate_hz, (int, float))
    if not (number and math.isfinite(rate_hz) and 0 < rate_hz <= MAX_RATE_HZ):
        shown = f"{rate_hz:g}" if number else repr(rate_hz)
        raise TwinError(f"--rate {shown}: the least physics rate is a number of Hz above 0 and at most "
                        f"{MAX_RATE_HZ:g}, a 0.1 ms step (Rover SITL's frames come at 1200 Hz: the default 400 "
                        "steps once a frame)")


def check_esc_arm(esc_arm_s: float) -> None:
    """A finite, non-negative ESC arming time (s)."""
    if not (isinstance(esc_arm_s, (int, float)) and math.isfinite(esc_arm_s) and esc_arm_s >= 0):
        raise TwinError(f"--esc-arm {esc_arm_s}: the ESC arming time is a number of seconds ≥ 0 (0: no arming)")


def check_channels(channels: tuple[int, int]) -> None:
    """Two different servo outputs in 1..32 (SERVO1..SERVO32)."""
    try:
        left, right = (int(c) for c in channels)
    except (TypeError, ValueError):
        raise TwinError(f"--channels expects two servo output numbers LEFT,RIGHT, got {channels!r}") from None
    if not (1 <= left <= 32 and 1 <= right <= 32) or left == right:
        raise TwinError(f"--channels {left},{right}: two different servo outputs in 1..32 (e.g. 1,3)")


def with_environment(vessel: Vessel, current: tuple[float, float] | None,
                     wind: tuple[float, float] | None) -> Vessel:
    """The vessel with --current SPEED,DIR (m/s, flowing towards DIR°) and --wind SPEED,DIR (m/s,
    blowing from DIR°) in place of its file's environment; None keeps the file's."""
    env = vessel.environment
    if current is not None:
        env = replace(env, current_speed_m_s=float(current[0]), current_dir_deg=float(current[1]))
    if wind is not None:
        env = replace(env, wind_speed_m_s=float(wind[0]), wind_dir_deg=float(wind[1]))
    return vessel.with_environment(env)


def sensor_amendments(vessel: Vessel) -> list[str]:
    """The vessel file's sensor calibration fields that differ from an ideal sensor (not applied: see
    the module docstring), for a note at the start of a session."""
    ideal = Sensors()
    return [f.name for f in fields(Sensors) if getattr(vessel.sensors, f.name) != getattr(ideal, f.name)]
