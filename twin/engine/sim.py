"""Headless runs of the MuJoCo twin: open-loop input series or a closed-loop
scenario controller, recorded at fixed sample times.

The loop returns to Python only at events (samples, controller ticks, command
changes); between them the engine runs `mj_step(nstep=...)` by itself. It runs at
the engine's own speed because an event does little in Python: one `mj_getState`
into a preallocated array (the sample's row, which is also the chunk start that a
divergence replay needs), two writes to ctrl, and at a controller tick the
controller and its thrust command in float arithmetic (engine/tick.py). Open-loop
commands are computed for every step ahead; η, ν, the held inputs and the delivered
thrust come from the stored states afterwards, in whole-array operations. The
results are the bits of the step-by-step reference loop (engine/sim_reference.py,
tests/test_sim_speed.py).

A propeller-and-rudder ship's controls are its inputs (n rps, δ rad) themselves; its run's
thrust_n holds the propeller thrust T and the rudder normal force F_N (N) the MMG forces give.
A measured wind (`wind`, a drive.WindSeries on the run's clock) is held over each step as the
model's controls 2 and 3 (mjcf.add_wind_inputs), in place of the environment's constant wind.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import replace
from typing import Callable

import mujoco
import numpy as np

from ..drive import INPUT_WORDS, InputSeries, StepPieces, SupplySeries, WindSeries
from ..errors import TwinError
from ..physics.hydrodynamics import Terms, mmg_forces
from ..physics import thrusters
from ..run import Run
from . import callbacks, native, sixdof
from .divergence import CHECKS, clear, flagged, quiet_log, what_diverged
from .mjcf import CompiledVessel, compile_vessel
from .sixdof import joint_addresses
from .tick import Pair, TickMap

Controller = Callable[[float, np.ndarray, np.ndarray], tuple[float, float]]
FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS
SPLIT_EPS = 1e-9  # of a step: a delay within this of a whole number of steps is that number
_CHECKED = [int(kind) for kind in CHECKS]  # data.warning indices of MuJoCo's divergence checks


def _steps(interval_s: float, timestep_s: float, what: str) -> int:
    if not (np.isfinite(interval_s) and interval_s > 0):
        raise TwinError(f"{what} must be a positive finite number of seconds, got {interval_s:g}")
    n = int(round(interval_s / timestep_s))
    if n < 1 or abs(n * timestep_s - interval_s) > 1e-9:
        below, above = max(n, 1) * timestep_s, (max(n, 1) + 1) * timestep_s
        raise TwinError(f"{what} {interval_s:g} s is not a multiple of the physics' time step {timestep_s:g} s "
                        f"(e.g. {below:g} or {above:g} s)")
    return n


def initial_state(model: mujoco.MjModel, data: mujoco.MjData, eta0, nu0, qpos0=None) -> None:
    """η0, ν0 on the planar joints (a 6-DOF model's other joints from qpos0, its rest)."""
    if qpos0 is not None:
        data.qpos[:] = qpos0
    eta0 = np.zeros(3) if eta0 is None else np.asarray(eta0, float)
    nu0 = np.zeros(3) if nu0 is None else np.asarray(nu0, float)
    qpos, dof = callbacks._joint_indices(model)
    data.qpos[list(qpos)] = eta0
    c, s = np.cos(eta0[2]), np.sin(eta0[2])
    data.qvel[list(dof)] = [c * nu0[0] - s * nu0[1], s * nu0[0] + c * nu0[1], nu0[2]]
    if model.na:
        data.act[:] = 0.0


def _event_steps(n_steps: int, n_sample: int, n_control: int | None, cmd_steps, extra=None) -> np.ndarray:
    """Steps at which the loop must act: samples, controller ticks, command changes, the end.

    Between them the engine runs `mj_step(nstep=...)` without returning to Python.
    """
    marks = [np.arange(0, n_steps + 1, n_sample), [n_steps]]
    if n_control is not None:
        marks.append(np.arange(0, n_steps + 1, n_control))
    if extra is not None:
        marks.append(extra)
    if cmd_steps is not None:
        changed = np.flatnonzero(np.any(np.diff(cmd_steps, axis=0) != 0, axis=1)) + 1
        marks += [[0], changed[changed <= n_steps]]
    return np.unique(np.concatenate(marks)).astype(int)


def _backend(compiled: CompiledVessel, terms: Terms, backend: str, wind: bool = False):
    """The model to step and the context that installs its hydrodynamic callback (with the wind's
    two controls when `wind`)."""
    if backend == "native":
        return native.with_native_params(compiled, terms, wind_inputs=wind), native.installed_native(six_dof=False)
    if backend == "python":
        if wind and not compiled.wind_inputs:
            compiled = CompiledVessel(compiled.vessel, compile_vessel(compiled.vessel, wind_inputs=True).model,
                                      compiled.geometry)
        return compiled.model, callbacks.installed(compiled.model, compiled.hydro(terms))
    raise TwinError(f"unknown backend '{backend}' (native or python)")


class _Wind:
    """A wind series held over the engine's steps: the air's velocity at every step, the steps where
    it changes (events of the loop) and the value each event sets on the wind's controls."""

    def __init__(self, series: WindSeries, n_steps: int, h: float):
        self.series = series
        self.steps = series.at(np.arange(n_steps + 1) * h)
        changed = np.flatnonzero(np.any(np.diff(self.steps, axis=0) != 0, axis=1)) + 1
        self.changes = np.concatenate([[0], changed])
        self._at = [tuple(row) for row in self.steps.tolist()]

    def __call__(self, k: int) -> tuple[float, float]:
        return self._at[k]


class _Layout:
    """Where η, the joint velocities and the thrust lag sit in a full-physics state vector
    [time, qpos, qvel, act, ...]; slices when contiguous (cheaper than index arrays per tick)."""

    def __init__(self, model: mujoco.MjModel):
        qpos, dof = callbacks._joint_indices(model)
        self.eta = _picker([1 + q for q in qpos])
        self.w = _picker([1 + model.nq + d for d in dof])
        self.act = slice(1 + model.nq + model.nv, 1 + model.nq + model.nv + min(model.na, 2)) if model.na else None

    def eta_nu(self, state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """η = (x, y, ψ) and ν = (u, v, r) of one state, as fresh arrays for a controller."""
        eta = state[self.eta].copy()
        c, s = np.cos(eta[2]), np.sin(eta[2])
        w0, w1, w2 = state[self.w]
        return eta, np.array([c * w0 + s * w1, -s * w0 + c * w1, w2])

    def samples(self, states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """η and ν of every stored state: the same operations as `eta_nu`, element by element."""
        eta = states[:, self.eta].copy()
        c, s = np.cos(eta[:, 2]), np.sin(eta[:, 2])
        w = states[:, self.w]
        return eta, np.column_stack([c * w[:, 0] + s * w[:, 1], -s * w[:, 0] + c * w[:, 1], w[:, 2]])


def _picker(indices: list[int]):
    if indices == list(range(indices[0], indices[0] + len(indices))):
        return slice(indices[0], indices[0] + len(indices))
    return np.array(indices)


class _OpenLoop:
    """An input series: the thrust command of every step computed ahead, events where it changes.
    A step within which the input changes (a delay or stamps off the step grid) is taken in two
    parts, each with the command held over it (`split`: step → (share of the step, first command,
    the rest's)); with a thrust ramp, each part's mean of the ramp heading for that command."""

    def __init__(self, series: InputSeries, thrusters, n_steps: int, n_sample: int, h: float, start_s: float,
                 thrust_on: bool):
        self.series = series
        pieces = StepPieces.of(series, thrusters, n_steps + 1, h, start_s)
        if thrusters.ramping:
            pieces = pieces.through_ramp(thrusters, h)
        cmd_steps = pieces.mean()
        split = pieces.split if thrust_on else np.zeros(0, int)
        split = split[split < n_steps]
        self.events = _event_steps(n_steps, n_sample, None, cmd_steps, np.concatenate([split, split + 1]))
        if not thrust_on:
            cmd_steps = np.zeros_like(cmd_steps)
        self._at = dict(zip(self.events.tolist(), map(tuple, cmd_steps[self.events].tolist())))
        self._steps = cmd_steps  # for events that are not the inputs' own (a wind series' changes)
        self.split = {k: (float(pieces.share[k]), tuple(pieces.first[k].tolist()), tuple(pieces.rest[k].tolist()))
                      for k in split.tolist()}
        self.h = h

    def command(self, k: int, state: np.ndarray) -> Pair:
        at = self._at.get(k)
        return at if at is not None else tuple(self._steps[k].tolist())

    def held(self, steps: np.ndarray) -> np.ndarray:
        """PWM (µs) held at these steps, NaN when the series is in thrust."""
        if self.series.kind != "pwm":
            return np.full((len(steps), 2), np.nan)
        return np.asarray(self.series.at(steps * self.h), dtype=float)

    def inputs(self) -> InputSeries:
        return self.series


_OUTPUT_WORDS = {"thrust": "(left, right) thrusts in N", "propeller_rudder": "(n rps, rudder δ rad)"}


def _two_finite(pair) -> bool:
    """Two finite numbers: a controller's output, or the input it holds (plain floats on the fast path)."""
    if isinstance(pair, (tuple, list)) and len(pair) == 2 and all(isinstance(x, (float, int)) for x in pair):
        return math.isfinite(pair[0]) and math.isfinite(pair[1])
    try:
        values = np.asarray(pair, dtype=float)
    except (TypeError, ValueError):
        return False
    return values.shape == (2,) and bool(np.all(np.isfinite(values)))


class _ClosedLoop:
    """A controller evaluated every n_control steps. Its output at step k reaches the thrusters
    delay_s later, decayed by the recording time of each step: from step min(k + n_delay, n_steps)
    where the delay is a whole number of steps; otherwise within that step, which is taken in two
    parts (`split`, as _OpenLoop's: the share `late` of it under the command before; with a thrust
    ramp, each part's mean of the ramp heading for that command)."""

    def __init__(self, compiled: CompiledVessel, controller: Controller, layout: _Layout, *, n_steps: int,
                 n_sample: int, n_control: int, h: float, start_s: float, thrust_on: bool,
                 supply: SupplySeries | None = None):
        thrusters = compiled.vessel.thrusters
        self.controller, self.layout, self.map = controller, layout, TickMap.of(thrusters)
        self.n_steps, self.n_control, self.h, self.start_s = n_steps, n_control, h, start_s
        steps_late = thrusters.delay_s / h
        self.n_delay = int(math.floor(steps_late + SPLIT_EPS))
        # the share of the step the delay ends in that the command before still holds (0: none)
        self.late = steps_late - self.n_delay if steps_late - self.n_delay > SPLIT_EPS else 0.0
        self.split: dict[int, tuple[float, Pair, Pair]] = {}
        self.thrust_on = thrust_on
        # the supply factor of every step (the voltage as each step starts), where the thrust follows it
        self.supply = supply
        self.supplied = (np.asarray(thrusters.supply_factor(supply.at(np.arange(n_steps + 1) * h)), float)
                         if supply is not None and thrusters.follows_supply and thrust_on else None)
        self.decaying = (bool(thrusters.decay_per_min) or self.supplied is not None) and thrust_on
        # a slew-limited command changes at every step of a ramp; its state is the ramp's value
        self.ramp = thrusters.slew_n_per_s * h if thrusters.ramping and thrust_on else None
        self.ramped: Pair | None = None  # the ramp's value: settled at the first command
        self.bounds = thrusters.bounds()
        self.pending: deque[tuple[int, Pair]] = deque()  # (step it acts from, raw thrust command)
        self.raw: Pair = (0.0, 0.0)  # the command in force before decay: none until the first one acts
        self.motors = (0, 0)  # a hysteretic map's motor states (+1 ahead, −1 astern, 0 stopped)
        self.ticks: list[int] = []
        self.times: list[float] = []
        self.values: list = []
        self.kinds: list[str] = []
        self.events = _event_steps(n_steps, n_sample, None, None, self._marks())

    def _marks(self) -> np.ndarray:
        """Ticks, the steps their delayed commands act from, or every step while the command decays."""
        if self.decaying or self.ramp is not None:
            return np.arange(self.n_steps + 1)
        marks = np.arange(0, self.n_steps + 1, self.n_control)
        if self.n_delay or self.late:
            acts = [marks + self.n_delay] + ([marks + self.n_delay + 1] if self.late else [])
            marks = np.unique(np.minimum(np.concatenate([marks, *acts]), self.n_steps))
        return marks

    def command(self, k: int, state: np.ndarray) -> Pair:
        """The thrust command (N) over step k, after the controller's tick at k if there is one."""
        if k % self.n_control == 0:
            self._tick(k, state)
        pending = self.pending
        before, arrived = self.raw, False
        while pending and pending[0][0] <= k:
            arrived = pending[0][0] == k
            self.raw = pending.popleft()[1]
        command = self.raw
        f = 1.0
        if self.decaying:
            f = self.map.decay(self.start_s + k * self.h)
            if self.supplied is not None:
                f *= float(self.supplied[k])
            command = (self.raw[0] * f, self.raw[1] * f)
        if arrived and self.late and self.raw != before and k < self.n_steps:
            old = (before[0] * f, before[1] * f) if self.decaying else before
            if self.ramp is not None:
                old, command = self._ramped_parts(old, command)
            self.split[k] = (self.late, old, command)
            w = self.late
            return (w * old[0] + (1.0 - w) * command[0], w * old[1] + (1.0 - w) * command[1])
        return command if self.ramp is None else self._ramped(command)

    def _bounded(self, command: Pair) -> Pair:
        lo, hi = self.bounds
        return min(max(command[0], lo), hi), min(max(command[1], lo), hi)

    def _ramped(self, command: Pair) -> Pair:
        """The step's mean thrust command through the slew limit (physics.thrusters.slew_step)."""
        left, right = self._bounded(command)
        if self.ramped is None:
            self.ramped = (left, right)
        (mean_l, end_l), (mean_r, end_r) = (thrusters.slew_step(self.ramped[0], left, self.ramp),
                                            thrusters.slew_step(self.ramped[1], right, self.ramp))
        self.ramped = (end_l, end_r)
        return mean_l, mean_r

    def _ramped_parts(self, old: Pair, command: Pair) -> tuple[Pair, Pair]:
        """A step the delay ends in, through the slew limit: the ramp's mean over the share `late`
        heading for the command before, and over the rest heading for the new one
        (physics.thrusters.slew_parts)."""
        old, command = self._bounded(old), self._bounded(command)
        if self.ramped is None:
            self.ramped = old
        first_l, rest_l, end_l = thrusters.slew_parts(self.ramped[0], old[0], self.late, command[0], self.ramp)
        first_r, rest_r, end_r = thrusters.slew_parts(self.ramped[1], old[1], self.late, command[1], self.ramp)
        self.ramped = (end_l, end_r)
        return (first_l, first_r), (rest_l, rest_r)

    def _tick(self, k: int, state: np.ndarray) -> None:
        t = np.float64(k * self.h)  # the type the controller always got (k·h on numpy steps)
        eta, nu = self.layout.eta_nu(state)
        out = self.controller(t, eta, nu)
        try:
            kind, held = self.map.held(self.controller, out)
        except (TypeError, ValueError, IndexError):
            kind, held = "", None
        if held is None or not _two_finite(out) or not _two_finite(held):
            raise TwinError(f"the controller gave {out!r:.60} at t = {t:.2f} s: it must return two finite numbers, "
                            f"{_OUTPUT_WORDS.get(getattr(self.controller, 'output', ''), '(surge, yaw) from -1 to 1')}")
        self.ticks.append(k)
        self.times.append(t)
        self.values.append(held)
        self.kinds.append(kind)
        if kind == "pwm" and self.map.thrusters.hysteretic:  # the motors answer the PWM as it comes
            self.motors, held = self.map.thrusters.driven_step(self.motors, held)
        if self.thrust_on:
            acts = k + self.n_delay
            if acts < self.n_steps or (acts == self.n_steps and not self.late):  # else it arrives after the run
                self.pending.append((acts, self.map.raw_thrust(kind, held)))

    def held(self, steps: np.ndarray) -> np.ndarray:
        """PWM (µs) held at these steps (the latest tick's), NaN where that tick gave thrust."""
        last = np.searchsorted(np.array(self.ticks), steps, side="right") - 1
        values = np.array(self.values, dtype=float)[last]
        pwm = np.array([kind == "pwm" for kind in self.kinds])[last]
        return np.where(pwm[:, None], values, np.nan)

    def inputs(self) -> InputSeries:
        """The inputs the controller gave, as a series that replays the run (with the supply voltage at
        its ticks where one was given: a replay holds it over each tick, the run had it at every step).
        With a delay, the thrusters' neutral input from −delay_s on comes first: nothing acted until the
        first command came through (a series holds its first input before it)."""
        times, values = np.array(self.times), np.array(self.values)
        delay_s = self.map.thrusters.delay_s
        if delay_s > 0.0 and len(times):
            neutral = self.map.thrusters.neutral_us if self.kinds[-1] == "pwm" else 0.0
            times = np.r_[times[0] - delay_s, times]
            values = np.vstack([np.full((1, values.shape[1]), neutral, dtype=values.dtype), values])
        return InputSeries(times, values, self.kinds[-1], None if self.supply is None else self.supply.at(times))


def simulate(
    compiled: CompiledVessel,
    drive: InputSeries | Controller,
    duration_s: float,
    *,
    control_dt_s: float = 0.1,
    sample_dt_s: float = 0.1,
    eta0=None,
    nu0=None,
    start_s: float = 0.0,
    terms: Terms | None = None,
    backend: str = "native",
    wind: WindSeries | None = None,
    supply: SupplySeries | None = None,
    sea=None,
    six_dof: bool = False,
    sea_terms=None,
) -> Run:
    """Run the engine twin for `duration_s` and return samples every `sample_dt_s`.

    `drive` is an InputSeries (zero-order hold on its own clock, which starts
    with the run) or a controller (t, η, ν) → (surge, yaw) in [−1, 1] (or thrusts
    in N if it has `output = "thrust"`), evaluated every `control_dt_s` (the
    autopilot's PWM rate). The thrusters act on the input of `delay_s` before
    (vessel.thrusters). `start_s` is the recording time at which the run starts:
    sample times are start_s + k·sample_dt_s and the thrust decay counts from 0.
    The inputs actually applied are returned in `run.meta["inputs"]` (times from
    the run's start), so that any run can be replayed.
    `backend`: "native" (compiled callback, the default) or "python" (the
    readable reference callback); both give the same forces to 1e-9.
    `wind`: a measured wind on the run's clock, held over each step (module docstring); it
    replaces the vessel environment's constant wind and is returned in `run.meta["wind"]`.
    `supply`: the battery voltage on the run's clock, for thrusters that follow it (an input series
    may carry its own instead); without either they act as at their reference voltage.
    `sea` (physics.waves.Sea) runs the 6-DOF hull in that sea (engine/sixdof.py), `six_dof` the
    6-DOF hull in calm water; `sea_terms` switches its sea loads. Its heave, roll and pitch (and
    their rates) are returned in `run.meta["six_dof"]`.
    """
    if not duration_s > 0:
        raise TwinError("duration must be positive")
    vessel = compiled.vessel
    terms = terms or Terms()
    six = None
    if sea is not None or six_dof:
        if backend != "native":
            raise TwinError("the 6-DOF hull runs on the native backend only")
        six = sixdof.compile_six(compiled, sea, terms, sea_terms, wind_inputs=wind is not None or compiled.wind_inputs)
        model, hydrodynamics = six.model, native.installed_native()
    else:
        model, hydrodynamics = _backend(compiled, terms, backend, wind is not None)
    h = model.opt.timestep
    n_steps = int(round(duration_s / h))
    n_control = _steps(control_dt_s, h, "control period")
    n_sample = _steps(sample_dt_s, h, "sample period")
    data = mujoco.MjData(model)
    initial_state(model, data, eta0, nu0, None if six is None else six.initial_qpos(eta0))
    layout = _Layout(model)
    # a propeller and rudder's controls are inputs to the MMG forces, which their own terms switch
    inputs_on = terms.thrust or vessel.thrusters.kind == "propeller_rudder"
    if isinstance(drive, InputSeries):
        if (drive.kind == "propeller_rudder") != (vessel.thrusters.kind == "propeller_rudder"):
            raise TwinError(f"vessel '{vessel.name}' is driven by {INPUT_WORDS[vessel.thrusters.input_kind]}, "
                            f"not {INPUT_WORDS.get(drive.kind, drive.kind)}")
        if supply is not None:
            drive = replace(drive, supply_v=supply.at(drive.t))
        loop = _OpenLoop(drive, vessel.thrusters, n_steps, n_sample, h, start_s, inputs_on)
    else:
        loop = _ClosedLoop(compiled, drive, layout, n_steps=n_steps, n_sample=n_sample, n_control=n_control, h=h,
                           start_s=start_s, thrust_on=inputs_on, supply=supply)
    events, air = loop.events, None
    if wind is not None:
        air = _Wind(wind, n_steps, h)
        events = np.unique(np.concatenate([events, air.changes]))
    sample_steps = np.arange(0, n_steps + 1, n_sample)
    states = np.empty((len(sample_steps), mujoco.mj_stateSize(model, FULL)))
    with hydrodynamics, quiet_log():
        commands = _step_events(model, data, events.tolist(), n_sample, states, loop.command, start_s, air,
                                getattr(loop, "split", None))
    eta, nu = layout.samples(states)
    command_n = states[:, layout.act] if layout.act is not None else np.array(commands, dtype=float)
    meta = {"vessel": vessel.name, "case": vessel.case, "engine": "mujoco", "timestep_s": h,
            "integrator": mujoco.mjtIntegrator(model.opt.integrator).name, "backend": backend,
            "inputs": loop.inputs(), "start_s": start_s}
    if wind is not None:
        meta["wind"] = wind
    if six is not None:
        meta["six_dof"] = six_dof_samples(six, states)
    return Run(start_s + sample_steps * h, eta, nu, vessel.thrusters.at_escs(loop.held(sample_steps)),
               delivered_forces(compiled, command_n, nu, terms), meta=meta)


def six_dof_samples(six, states: np.ndarray) -> dict:
    """Heave (down, m), roll and pitch (rad) and their rates at the samples of a 6-DOF run, with the
    hull and the sea it ran in."""
    qpos, dof = joint_addresses(six.model)
    nq = six.model.nq
    col = {name: states[:, 1 + q] for name, q in zip(("down_m", "pitch_rad", "roll_rad"), (qpos[2], qpos[4], qpos[5]))}
    col.update({name: states[:, 1 + nq + d] for name, d in zip(("down_rate_m_s", "pitch_rate_rad_s", "roll_rate_rad_s"),
                                                               (dof[2], dof[4], dof[5]))})
    col["equilibrium"] = six.hull.equilibrium
    col["sea"] = None if six.sea is None else six.sea.to_dict()
    col["components"] = six.components
    return col


def delivered_forces(compiled: CompiledVessel, commands: np.ndarray, nu: np.ndarray,
                     terms: Terms | None = None) -> np.ndarray:
    """(n, 2) per sample: each thruster's delivered thrust (N, `delivered_thrust`) or, for a
    propeller and rudder driven by the controls (n rps, δ rad), the propeller thrust T and the
    rudder normal force F_N (N) of the MMG forces at the sample's velocity."""
    vessel = compiled.vessel
    if vessel.thrusters.kind != "propeller_rudder":
        return delivered_thrust(vessel, compiled.geometry.thruster_y_m, commands, nu)
    hydro = compiled.hydro(terms)
    return np.array([mmg_forces(hydro, v, c)[3:5] for v, c in zip(np.asarray(nu, float), commands)]).reshape(-1, 2)


def _step_events(model: mujoco.MjModel, data: mujoco.MjData, events: list[int], n_sample: int,
                 states: np.ndarray, command: Callable[[int, np.ndarray], Pair], start_s: float,
                 wind: Callable[[int], Pair] | None = None,
                 split: dict[int, tuple[float, Pair, Pair]] | None = None) -> list[Pair]:
    """Step the engine from event to event, the thrust command `command(k, state)` held from
    each (and the air's velocity `wind(k)` on controls 2 and 3); the state at every sample step
    goes to the next row of `states`. Returns the command set at each sample. Raises TwinError
    (naming when) if the twin diverges. `split`: the steps taken in two parts (_OpenLoop), each
    an event followed by one at the next step.

    The hot loop of a run: names are bound to locals and the arrays (ctrl, qvel, the warning
    counters) are views taken once, so an event costs a few microseconds of Python."""
    rows = iter(states)
    scratch = np.empty(states.shape[1])
    ctrl, qvel, warnings = data.ctrl, data.qvel, data.warning.number
    get_state, step = mujoco.mj_getState, mujoco.mj_step
    commands: list[Pair] = []
    last = len(events) - 1
    for i, k in enumerate(events):
        sampled = k % n_sample == 0
        state = next(rows) if sampled else scratch
        get_state(model, data, state, FULL)
        left, right = command(k, state)
        ctrl[0] = left
        ctrl[1] = right
        if wind is not None:
            ctrl[2], ctrl[3] = wind(k)
        parts = split.get(k) if split else None
        if sampled:  # what acts at the sample's instant: a split step's first part
            commands.append((left, right) if parts is None else parts[1])
        if i == last:
            break
        nstep = events[i + 1] - k
        if parts is not None:
            _step_in_parts(model, data, parts)
            if _diverged(warnings, qvel):
                raise TwinError(_divergence_in_parts(model, data, state, parts, start_s))
            if nstep == 1:
                continue
            get_state(model, data, scratch, FULL)
            state, nstep = scratch, nstep - 1
            left, right = parts[2]
        step(model, data, nstep)
        if _diverged(warnings, qvel):
            controls = (left, right) if wind is None else (left, right, *wind(k))
            raise TwinError(_divergence(model, data, state, controls, nstep, start_s))
    return commands


def _divergence_in_parts(model: mujoco.MjModel, data: mujoco.MjData, start: np.ndarray,
                         parts: tuple[float, Pair, Pair], start_s: float) -> str:
    """One line naming when a step taken in two parts diverged: the step replayed from its saved
    start (MuJoCo reset the diverged state) and what MuJoCo found bad."""
    mujoco.mj_setState(model, data, start, FULL)
    clear(data)
    _step_in_parts(model, data, parts)
    return (f"the twin diverged at t = {start_s + float(start[0]):.2f} s: MuJoCo found its {what_diverged(data)} "
            f"non-finite or beyond {mujoco.mjMAXVAL:g} (unstable parameters, inputs or time step)")


def _step_in_parts(model: mujoco.MjModel, data: mujoco.MjData, parts: tuple[float, Pair, Pair]) -> None:
    """One engine step in two: `share` of it under the first command, the rest under the second
    (the model's time step put back after)."""
    share, first, rest = parts
    h = model.opt.timestep
    try:
        data.ctrl[0], data.ctrl[1] = first
        model.opt.timestep = share * h
        mujoco.mj_step(model, data)
        data.ctrl[0], data.ctrl[1] = rest
        model.opt.timestep = h - share * h
        mujoco.mj_step(model, data)
    finally:
        model.opt.timestep = h


def _diverged(warnings: np.ndarray, qvel: np.ndarray) -> bool:
    """divergence.flagged(data) or a non-finite velocity, on views held by the caller."""
    return any(warnings[_CHECKED].tolist()) or not all(map(math.isfinite, qvel.tolist()))


def _divergence(model: mujoco.MjModel, data: mujoco.MjData, chunk_start: np.ndarray, command_n,
                nstep: int, start_s: float) -> str:
    """One line naming when the run diverged: the chunk of nstep steps under the thrust command
    (N) replayed one step at a time from its saved start (MuJoCo reset the diverged state, so
    only the replay knows the step), and what MuJoCo found bad."""
    mujoco.mj_setState(model, data, chunk_start, FULL)
    data.ctrl[:len(command_n)] = command_n  # the reset zeroed the controls
    clear(data)
    t_s = float(data.time)
    for _ in range(nstep):
        t_s = float(data.time)
        mujoco.mj_step(model, data)
        if flagged(data) or not np.all(np.isfinite(data.qvel)):
            break
    return (f"the twin diverged at t = {start_s + t_s:.2f} s: MuJoCo found its {what_diverged(data)} "
            f"non-finite or beyond {mujoco.mjMAXVAL:g} (unstable parameters, inputs or time step)")


def delivered_thrust(vessel, thruster_y_m, command_n: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """Thrust each thruster delivers (N): the (lagged) command within the range, times its gain,
    less its advance loss (`thrusters.delivered`, for all samples at once; at the speed over
    ground ν, which with a current differs from the callback's speed through the water)."""
    t_min, t_max = vessel.thrusters.bounds()
    static = np.clip(command_n, t_min, t_max) * vessel.thrusters.gains()
    if not len(nu) or not vessel.thrusters.advance_loss:
        return static
    return thrusters.delivered(vessel.thrusters.advance_loss, static, np.asarray(nu, float), thruster_y_m)
