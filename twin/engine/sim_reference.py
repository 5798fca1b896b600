"""The single-run loop written plainly, without the optimisations of `sim.simulate`: the
slow, readable reference the fast loop is tested against (tests/test_sim_speed.py).

Every control tick recomputes the thrust command of the whole remaining run through the
thruster map, so a run costs O(n²) in its length: use it for short runs only. Not used by
the twin itself.
"""
from __future__ import annotations

import math
from typing import Callable

import mujoco
import numpy as np

from ..drive import InputSeries, StepPieces, to_thruster_inputs
from ..errors import TwinError
from ..physics.hydrodynamics import Terms
from ..physics.thrusters import delivered, slew_parts, slew_step, slew_through
from ..run import Run
from . import callbacks, native
from .divergence import clear, flagged, quiet_log, what_diverged
from .mjcf import CompiledVessel
from .sim import SPLIT_EPS, _divergence_in_parts, _event_steps, _step_in_parts, _steps, initial_state  # the loop differs, not its arithmetic

Controller = Callable[[float, np.ndarray, np.ndarray], tuple[float, float]]
FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS


def _state(data: mujoco.MjData, qpos, dof) -> tuple[np.ndarray, np.ndarray]:
    """η = (x, y, ψ) and ν = (u, v, r) from the joint state."""
    eta = data.qpos[list(qpos)].copy()
    c, s = np.cos(eta[2]), np.sin(eta[2])
    w = data.qvel[list(dof)]
    return eta, np.array([c * w[0] + s * w[1], -s * w[0] + c * w[1], w[2]])


def _backend(compiled: CompiledVessel, terms: Terms, backend: str):
    """The model to step and the context that installs its hydrodynamic callback."""
    if backend == "native":
        return native.with_native_params(compiled, terms), native.installed_native(six_dof=False)
    if backend == "python":
        return compiled.model, callbacks.installed(compiled.model, compiled.hydro(terms))
    raise TwinError(f"unknown backend '{backend}' (native or python)")


def _controller_output(vessel, controller, t: float, eta: np.ndarray, nu: np.ndarray) -> tuple[str, np.ndarray]:
    """(kind, held input) from a controller: normalised (surge, yaw) → PWM or thrust by
    `drive.to_thruster_inputs`, or thrusts in N when the controller says `output = "thrust"`."""
    out = controller(t, eta, nu)
    if getattr(controller, "output", "normalised") == "thrust":
        return "thrust", np.asarray(out, float)
    return to_thruster_inputs(vessel.thrusters, *out)


def simulate_reference(
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
) -> Run:
    """`sim.simulate` as it was: same arguments, same Run."""
    if not duration_s > 0:
        raise TwinError("duration must be positive")
    vessel = compiled.vessel
    thrusters = vessel.thrusters
    terms = terms or Terms()
    model, hydrodynamics = _backend(compiled, terms, backend)
    h = model.opt.timestep
    n_steps = int(round(duration_s / h))
    n_control = _steps(control_dt_s, h, "control period")
    n_sample = _steps(sample_dt_s, h, "sample period")
    steps_late = thrusters.delay_s / h
    n_delay = int(math.floor(steps_late + SPLIT_EPS))
    late = steps_late - n_delay if steps_late - n_delay > SPLIT_EPS else 0.0  # the step the delay ends in
    data = mujoco.MjData(model)
    initial_state(model, data, eta0, nu0)
    qpos, dof = callbacks._joint_indices(model)
    step_times = np.arange(n_steps + 1) * h

    series = drive if isinstance(drive, InputSeries) else None
    split: dict[int, tuple] = {}
    several: dict[int, tuple] = {}
    if series is not None:
        # each step's mean input; a step within which it changes is taken in two parts (sim._OpenLoop)
        pieces = StepPieces.of(series, thrusters, n_steps + 1, h, start_s)
        # a ramp heads for the input held over each part of a step (taken in two parts below)
        cmd_steps = pieces.first.copy() if thrusters.ramping else pieces.mean()
        if terms.thrust:
            split = {k: (pieces.share[k], pieces.first[k], pieces.rest[k]) for k in pieces.split if k < n_steps}
            if pieces.several is not None:  # a ramp heads for each input of such a rest in turn
                several = dict(zip(pieces.several.steps.tolist(), zip(pieces.several.held, pieces.several.commands)))
        held_steps = series.at(step_times)
        kind = series.kind
    else:
        # closed loop: the controller's output at step k reaches the thrusters at step k + n_delay
        cmd_steps = np.zeros((n_steps + 1, 2))
        held_steps = np.zeros((n_steps + 1, 2))
        kind = None
    applied_t, applied_v = [], []
    marks = np.arange(0, n_steps + 1, n_control) if series is None else None
    if series is None and (n_delay or late):
        acts = [marks + n_delay] + ([marks + n_delay + 1] if late else [])
        marks = np.unique(np.minimum(np.concatenate([marks, *acts]), n_steps))
    if series is None and thrusters.decay_per_min:
        marks = np.arange(n_steps + 1)  # the decaying command changes at every step
    ramp = thrusters.slew_n_per_s * h if thrusters.ramping else None
    if ramp is not None:
        marks = np.arange(n_steps + 1)  # a ramp's command changes at every step; its state is where it stands
    ramped = None
    if split and ramp is None:
        marks = np.array([m for k in split for m in (k, k + 1)])
    events = _event_steps(n_steps, n_sample, None, cmd_steps if series is not None else None, marks)
    if not terms.thrust:
        cmd_steps = np.zeros_like(cmd_steps)
    rows = {"t": [], "eta": [], "nu": [], "held": [], "cmd": []}
    motors = (0, 0)  # a hysteretic map's motor states
    chunk_start = np.empty(mujoco.mj_stateSize(model, FULL))
    with hydrodynamics, quiet_log():
        for i, k in enumerate(events):
            t = k * h
            eta, nu = _state(data, qpos, dof)
            if series is None and k % n_control == 0:
                kind, held = _controller_output(vessel, drive, t, eta, nu)
                applied_t.append(t)
                applied_v.append(held)
                held_steps[k:] = held
                act_at = k + n_delay
                if kind == "pwm":
                    motors, driven = thrusters.driven_step(motors, held)
                    held = np.asarray(driven)
                arrives = act_at < n_steps or (act_at == n_steps and not late)  # else after the run
                cmd = thrusters.command(kind, held[None, :], start_s + step_times[act_at:]) if arrives else None
                before = cmd_steps[act_at].copy() if arrives else None
                if arrives:
                    cmd_steps[act_at:] = cmd if terms.thrust else 0.0
                if arrives and late and terms.thrust and act_at < n_steps \
                        and not np.array_equal(before, cmd_steps[act_at]):
                    # the delay ends within step act_at: the command before holds for its first `late`
                    new_cmd = cmd_steps[act_at].copy()
                    split[act_at] = (late, before, new_cmd)
                    cmd_steps[act_at] = late * before + (1.0 - late) * new_cmd
            if ramp is None:
                data.ctrl[:2] = cmd_steps[k]
            elif k in split:  # the ramp heads for the first command over its share, then for the rest's
                share, first, rest = split[k]
                first, rest = np.clip(first, *thrusters.bounds()), np.clip(rest, *thrusters.bounds())
                ramped = first if ramped is None else ramped
                if k in several:
                    held, commands = several[k]
                    commands = np.clip(commands, *thrusters.bounds())
                    heads = [slew_step(a, b, ramp * share) for a, b in zip(ramped, first)]
                    tails = [slew_through(e, held, commands[:, j], ramp) for j, (_, e) in enumerate(heads)]
                    parts = [(head[0], tail[0], tail[1]) for head, tail in zip(heads, tails)]
                else:
                    parts = [slew_parts(a, b, share, c, ramp) for a, b, c in zip(ramped, first, rest)]
                first_means, rest_means = np.array([p[0] for p in parts]), np.array([p[1] for p in parts])
                if np.array_equal(first_means, rest_means):  # commands that differ beyond a bound: one step
                    del split[k]
                    data.ctrl[:2] = first_means
                else:
                    split[k] = (share, first_means, rest_means)
                    data.ctrl[:2] = share * first_means + (1.0 - share) * rest_means
                ramped = np.array([p[2] for p in parts])
            else:
                target = np.clip(cmd_steps[k], *thrusters.bounds())
                ramped = target if ramped is None else ramped
                steps = [slew_step(a, b, ramp) for a, b in zip(ramped, target)]
                data.ctrl[:2] = [m for m, _ in steps]
                ramped = np.array([e for _, e in steps])
            applied = data.ctrl[:2].copy()
            if k % n_sample == 0:
                rows["t"].append(start_s + t)
                rows["eta"].append(eta)
                rows["nu"].append(nu)
                rows["held"].append(held_steps[k] if kind == "pwm" else (np.nan, np.nan))
                # what acts at the sample's instant: a split step's first part
                rows["cmd"].append(data.act[:2].copy() if model.na else
                                   np.array(split[k][1], float) if k in split else data.ctrl[:2].copy())
            if k == n_steps:
                break
            mujoco.mj_getState(model, data, chunk_start, FULL)
            if k in split:
                parts = tuple(map(tuple, (np.asarray(x, float).tolist() for x in split[k][1:])))
                parts = (float(split[k][0]), *parts)
                _step_in_parts(model, data, parts)
                if flagged(data) or not np.all(np.isfinite(data.qvel)):
                    raise TwinError(_divergence_in_parts(model, data, chunk_start, parts, start_s))
                continue
            mujoco.mj_step(model, data, nstep=int(events[i + 1] - k))
            if flagged(data) or not np.all(np.isfinite(data.qvel)):
                raise TwinError(_divergence(model, data, chunk_start, applied, int(events[i + 1] - k), start_s))
    if series is None:
        times, values = np.array(applied_t), np.array(applied_v)
        if thrusters.delay_s > 0.0 and len(times):  # nothing acted until the first command came through
            neutral = thrusters.neutral_us if kind == "pwm" else 0.0
            times = np.r_[times[0] - thrusters.delay_s, times]
            values = np.vstack([np.full((1, values.shape[1]), neutral, dtype=values.dtype), values])
        series = InputSeries(times, values, kind)
    nu = np.array(rows["nu"])
    return Run(
        np.array(rows["t"]), np.array(rows["eta"]), nu, vessel.thrusters.at_escs(np.array(rows["held"], dtype=float)),
        delivered_thrust(vessel, compiled.geometry.thruster_y_m, np.array(rows["cmd"]), nu),
        meta={"vessel": vessel.name, "case": vessel.case, "engine": "mujoco", "timestep_s": h,
              "integrator": mujoco.mjtIntegrator(model.opt.integrator).name, "backend": backend,
              "inputs": series, "start_s": start_s},
    )


def _divergence(model: mujoco.MjModel, data: mujoco.MjData, chunk_start: np.ndarray, command_n: np.ndarray,
                nstep: int, start_s: float) -> str:
    """One line naming when the run diverged (the chunk replayed one step at a time)."""
    mujoco.mj_setState(model, data, chunk_start, FULL)
    data.ctrl[:2] = command_n  # the reset zeroed the controls
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
    less its advance loss (row by row)."""
    t_min, t_max = vessel.thrusters.bounds()
    static = np.clip(command_n, t_min, t_max) * vessel.thrusters.gains()
    if not len(nu):
        return static
    c = vessel.thrusters.advance_loss
    return np.array([delivered(c, s, n, thruster_y_m) for s, n in zip(static, nu)])
