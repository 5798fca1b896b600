"""Many twins at once: `mujoco.rollout` on native threads with the native callback.

Each twin is one model carrying its own parameters (`native.with_native_params`,
or a copy re-parameterised with `native.set_params`), an initial full-physics
state and an open-loop sequence of thrust commands (a propeller and rudder's (n, δ); a model
with wind inputs takes the air's NED velocity as two more controls per step). Because the hydrodynamics
run as a C function pointer, rollout's threads never take the GIL, and the
results are bit-identical to stepping each twin alone with `mj_step`.

A twin that blows up does not spoil the batch: MuJoCo flags it (non-finite or
larger than mjMAXVAL), resets it and stops stepping it; here it is reported as
(index, time) and its samples from then on are NaN (`rollout`), or its run is
left out (`simulate_many`). MuJoCo's own warning log stays off meanwhile
(engine/divergence.py).
"""
from __future__ import annotations

import contextlib
import copy
import os
import threading
from typing import Iterator, Sequence, Union

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from ..errors import TwinError
from ..drive import InputSeries
from ..physics.hydrodynamics import HydroModel
from ..run import Run
from ..vessel import Vessel
from . import native
from .callbacks import _joint_indices
from .divergence import quiet_log
from .mjcf import CompiledVessel
from .sim import delivered_forces, initial_state as _set_initial_state

FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS
Twin = Union[CompiledVessel, mujoco.MjModel]
_thread_limit: list[int] = []  # innermost `thread_limit` last


@contextlib.contextmanager
def thread_limit(nthread: int) -> Iterator[None]:
    """Rollouts that are not given `nthread` use at most this many threads meanwhile.

    A worker of a cluster is granted a few CPUs of a node whose os.cpu_count() counts them all;
    code that rolls out deep inside (a diagnosis, a dataset) would otherwise start a thread per
    core of the node in every worker at once."""
    if nthread < 1:
        raise TwinError(f"thread limit must be at least 1, got {nthread}")
    _thread_limit.append(int(nthread))
    try:
        yield
    finally:
        _thread_limit.pop()


def default_threads() -> int:
    """Threads of a rollout not told how many: the innermost `thread_limit`, else every CPU."""
    return _thread_limit[-1] if _thread_limit else (os.cpu_count() or 1)


def state_size(model: mujoco.MjModel) -> int:
    """Length of a full-physics state vector: [time, qpos, qvel, act, ...]."""
    return mujoco.mj_stateSize(model, FULL)


def initial_state(model: mujoco.MjModel, eta0=None, nu0=None, time_s: float = 0.0) -> np.ndarray:
    """Full-physics state at η0 = (N m, E m, ψ rad) moving with ν0 = (u, v m/s, r rad/s); thrust lag at rest."""
    data = mujoco.MjData(model)
    data.time = time_s
    _set_initial_state(model, data, eta0, nu0)
    state = np.empty(state_size(model))
    mujoco.mj_getState(model, data, state, FULL)
    return state


def models_for(compiled: CompiledVessel, hydros: Sequence[HydroModel]) -> list[mujoco.MjModel]:
    """One model per parameter set: compiled once, then copied and re-parameterised (no recompilation)."""
    base = native.with_native_params(compiled)
    out = []
    for hydro in hydros:
        m = copy.copy(base)
        native.set_params(m, hydro)
        out.append(m)
    return out


def thrust_controls_from_inputs(vessel: Vessel, inputs: InputSeries, nstep: int, timestep: float,
                                start_s: float = 0.0) -> np.ndarray:
    """(nstep, 2) thrust commands (N) held over each step: each step's mean (drive.StepPieces).

    Step k runs from k·timestep with the mean over the step of the commands the zero-order-hold
    series gives less the thrusters' delay (PWM converted through the thruster map), decayed by the
    recording time start_s + k·timestep; with a thrust ramp, through its slew limit (each step's
    mean of the ramp, settled at the first command). `sim.simulate` takes a step within which the
    input changes in two parts instead; a batch rollout holds one command over a step, its mean,
    which is the same push where the thrust is linear in the command and differs by the advance
    loss's curvature where it is not (an input changing sign within a step, a thruster without lag).
    """
    return inputs.thrust_on_steps(vessel.thrusters, nstep, timestep, start_s)


def _as_models(twins: Twin | Sequence[Twin], n: int) -> list[mujoco.MjModel]:
    """One native-parameterised model per twin (a single model or vessel is shared by all)."""
    if isinstance(twins, (CompiledVessel, mujoco.MjModel)):
        twins = [twins] * n
    built: dict[int, mujoco.MjModel] = {}
    checked: set[int] = set()
    models = []
    for t in twins:
        if isinstance(t, CompiledVessel):
            t = built.setdefault(id(t), native.with_native_params(t))
        if id(t) not in checked:
            if not native.has_params(t):
                raise TwinError("batch: a model without twin parameters (build it with native.with_native_params)")
            checked.add(id(t))
        models.append(t)
    if len(models) != n:
        raise TwinError(f"batch: {len(models)} models for {n} initial states")
    return models


def _signature(model: mujoco.MjModel) -> tuple:
    """The integer sizes that fix an MjData's layout: twins sharing them can share MjData."""
    return tuple(int(getattr(model, k)) for k in native.size_fields() if hasattr(model, k))


def _groups(models: list[mujoco.MjModel]) -> list[list[int]]:
    """Indices of the twins that rollout may run together (same size signature)."""
    groups: dict[tuple, list[int]] = {}
    known: dict[int, tuple] = {}  # the same model object repeats for many twins: sign it once
    for i, m in enumerate(models):
        sig = known.get(id(m))
        if sig is None:
            sig = known[id(m)] = _signature(m)
        groups.setdefault(sig, []).append(i)
    return list(groups.values())


def _check_inputs(models, states: np.ndarray, controls: np.ndarray) -> None:
    n = len(models)
    if states.ndim != 2 or states.shape[0] != n:
        raise TwinError(f"batch: initial states must be (N, nstate), got {states.shape}")
    if controls.ndim != 3 or controls.shape[0] != n or controls.shape[2] not in (2, 4):
        raise TwinError(f"batch: controls must be (N, nstep, 2) thrust commands (4 with the wind), "
                        f"got {controls.shape}")
    for m in {id(m): m for m in models}.values():
        if m.nu != controls.shape[2] or state_size(m) != states.shape[1]:
            raise TwinError(f"batch: every model needs {controls.shape[2]} controls (2 thrusters"
                            f"{' and the wind' if controls.shape[2] == 4 else ''}) and the initial states' nstate")


def _first_bad(traj: np.ndarray, t0: float) -> int | None:
    """First sample index MuJoCo would call diverged: non-finite, beyond mjMAXVAL, or time reset."""
    time = traj[:, 0]
    previous = np.concatenate(([t0], time[:-1]))
    bad = ~np.all(np.isfinite(traj), axis=1) | np.any(np.abs(traj) > mujoco.mjMAXVAL, axis=1) | (time <= previous)
    return int(np.argmax(bad)) if bad.any() else None


def _suspects(states: np.ndarray, initial: np.ndarray) -> np.ndarray:
    """The twins `_first_bad` may find a bad sample in, found for all at once (a diagnosis rolls
    out thousands of windows a minute, nearly all of them fine)."""
    with np.errstate(invalid="ignore"):
        bad = ~np.isfinite(states).all(axis=2) | (np.abs(states) > mujoco.mjMAXVAL).any(axis=2)
        time = states[:, :, 0]
        bad[:, 0] |= time[:, 0] <= initial[:, 0]
        bad[:, 1:] |= time[:, 1:] <= time[:, :-1]
    return np.flatnonzero(bad.any(axis=1))


def _divergence(models, initial: np.ndarray, states: np.ndarray) -> list[tuple[int, float]]:
    """Report diverged twins as (index, time s of the first bad sample) and blank their samples to NaN."""
    diverged = []
    for i in map(int, _suspects(states, initial)):
        m = models[i]
        k = _first_bad(states[i], initial[i, 0])
        if k is None:
            continue
        t_prev = states[i, k - 1, 0] if k > 0 else initial[i, 0]
        diverged.append((i, float(t_prev + m.opt.timestep)))
        states[i, k:] = np.nan
    return diverged


_kept = threading.local()  # per calling thread: its rollout pools and work MjData (_pool)


def _pool(model: mujoco.MjModel, n: int) -> tuple[mj_rollout.Rollout, list[mujoco.MjData]]:
    """A rollout pool of n threads and n MjData of `model`'s size signature, made once per
    calling thread and kept: a diagnosis rolls out hundreds of times, and making them each time
    cost about 2.5 % of its rollouts' time
    (profiled on the 30-min bench). Reusing an MjData changes nothing: every rollout sets the
    full physics state of each twin, and these models have no constraints whose solver a
    previous run's warm start could steer (test_batch checks it bit for bit)."""
    if not hasattr(_kept, "pools"):
        _kept.pools, _kept.datas = {}, {}
    pool = _kept.pools.get(n)
    if pool is None:
        pool = _kept.pools[n] = mj_rollout.Rollout(nthread=n if n > 1 else 0)
    key = (_signature(model), n)
    datas = _kept.datas.get(key)
    if datas is None:
        if len(_kept.datas) >= 16:
            _kept.datas.pop(next(iter(_kept.datas)))
        datas = _kept.datas[key] = [mujoco.MjData(model) for _ in range(n)]
    return pool, datas


def _run_group(models, initial, controls, nthread: int) -> np.ndarray:
    """One mujoco.rollout call over twins with a common size signature (GIL released)."""
    pool, datas = _pool(models[0], max(1, min(nthread, len(models))))
    states, _ = pool.rollout(models, datas, initial, controls)
    return states


def rollout(twins: Twin | Sequence[Twin], initial_states, controls, nthread: int | None = None
            ) -> tuple[np.ndarray, list[tuple[int, float]]]:
    """Step N twins open-loop with the native hydrodynamics on `nthread` threads (default: all CPUs).

    twins: one CompiledVessel/MjModel for all, or one per twin; models must come
    from `native.with_native_params` (or `models_for`), vessels are converted
    with their default terms. initial_states: (N, nstate) full-physics states
    (`initial_state`). controls: (N, nstep, 2) thrust commands (N) per step.

    Returns states (N, nstep, nstate), the state after each step (time first),
    and the diverged twins as (index, time in s of the first bad sample); their
    samples from there on are NaN, the other twins' are kept.
    """
    initial = np.ascontiguousarray(initial_states, dtype=float)
    controls = np.ascontiguousarray(controls, dtype=float)
    models = _as_models(twins, len(initial))
    _check_inputs(models, initial, controls)
    nthread = nthread or default_threads()
    states = np.empty((len(models), controls.shape[1], initial.shape[1]))
    with native.installed_native(six_dof=any(native.is_six_dof(m) for m in models)), quiet_log():
        for idx in _groups(models):
            states[idx] = _run_group([models[i] for i in idx], initial[idx], controls[idx], nthread)
    return states, _divergence(models, initial, states)


class Runs(list):
    """The runs of `simulate_many` in input order, None in place of a run that diverged;
    `diverged` lists those as (index, time s on that run's clock, start_s included)."""

    def __init__(self, runs, diverged: list[tuple[int, float]]):
        super().__init__(runs)
        self.diverged = diverged

    def describe_divergence(self) -> str:
        """One line naming the diverged runs and when, e.g. for an error message ("" if none)."""
        if not self.diverged:
            return ""
        shown = ", ".join(f"run {i} at t = {t:.2f} s" for i, t in self.diverged[:5])
        more = f" and {len(self.diverged) - 5} more" if len(self.diverged) > 5 else ""
        return f"{len(self.diverged)} of {len(self)} twins diverged: {shown}{more}"


def simulate_many(compiled: CompiledVessel, inputs: Sequence[InputSeries], durations_s: Sequence[float], *,
                  eta0=None, nu0=None, start_s: Sequence[float] | None = None, sample_dt_s: float | None = None,
                  nthread: int | None = None) -> Runs:
    """Open-loop runs of one vessel in one rollout, as `twin.run.Run`s like `sim.simulate` returns.

    inputs[i] drives run i for durations_s[i] from η0[i], ν0[i] (default: at rest at the
    origin), its clock starting at recording time start_s[i] (thrust decay). Samples
    every sample_dt_s (default: every engine step). A run that diverges does not cost
    the others: it is None in the returned list and reported in `.diverged` as
    (index, time s) on its own clock (see `Runs`)."""
    n = len(inputs)
    model = native.with_native_params(compiled)
    h = model.opt.timestep
    steps = [int(round(d / h)) for d in durations_s]
    every = 1 if sample_dt_s is None else int(round(sample_dt_s / h))
    starts = list(start_s) if start_s is not None else [0.0] * n
    eta0 = [None] * n if eta0 is None else eta0
    nu0 = [None] * n if nu0 is None else nu0
    controls = np.zeros((n, max(steps), 2))
    for i, series in enumerate(inputs):
        controls[i, : steps[i]] = thrust_controls_from_inputs(compiled.vessel, series, steps[i], h, starts[i])
    states0 = np.array([initial_state(model, eta0[i], nu0[i]) for i in range(n)])
    traj, diverged = rollout(model, states0, controls, nthread=nthread)
    # a run counts as diverged only if it blew up within its own duration (the rest is padding)
    diverged = [(i, starts[i] + t) for i, t in diverged if t <= steps[i] * h + 1e-9]
    bad = {i for i, _ in diverged}
    runs = [None if i in bad else _run(compiled, model, series, states0[i], traj[i, : steps[i]],
                                       controls[i, : steps[i]], every, starts[i])
            for i, series in enumerate(inputs)]
    return Runs(runs, diverged)


def poses_and_velocities(model: mujoco.MjModel, states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """η (n, 3: N m, E m, ψ rad) and ν (n, 3: u, v m/s, r rad/s) of full-physics states (n, nstate)."""
    qpos, dof = _joint_indices(model)
    eta = states[:, [1 + q for q in qpos]]
    w = states[:, [1 + model.nq + d for d in dof]]
    c, s = np.cos(eta[:, 2]), np.sin(eta[:, 2])
    return eta, np.column_stack([c * w[:, 0] + s * w[:, 1], -s * w[:, 0] + c * w[:, 1], w[:, 2]])


def _run(compiled: CompiledVessel, model: mujoco.MjModel, series: InputSeries, state0: np.ndarray,
         traj: np.ndarray, controls: np.ndarray, every: int, start_s: float):
    """One rollout trajectory (full-physics states after each step) as a Run sampled every `every` steps."""
    h = model.opt.timestep
    full = np.vstack([state0, traj])[::every]
    eta, nu = poses_and_velocities(model, full)
    t_rel = np.arange(len(full)) * every * h
    act = full[:, 1 + model.nq + model.nv: 1 + model.nq + model.nv + model.na] if model.na else None
    cmd = act if act is not None else np.vstack([controls, controls[-1]])[::every]
    return Run(start_s + t_rel, eta, nu, compiled.vessel.thrusters.at_escs(series.pwm_at(t_rel)),
               delivered_forces(compiled, cmd, nu),
               meta={"vessel": compiled.vessel.name, "engine": "mujoco-rollout", "timestep_s": h,
                     "inputs": series, "start_s": start_s})
