"""Multi-step predictions: the twin started from measured states and driven by the
recorded PWM over short windows, many windows and many candidate vessels at once
on the batch engine (`engine.batch.rollout`, native callbacks, all cores).

A window starts at a grid sample of a prepared recording and predicts `n` grid
steps ahead without looking at the measurements again: the free run that
identification by simulation, `twin evaluate` and `twin diagnose` judge a model by.
A whole segment is one long window.

What the recording's clock means for the thrusters (vessel.thrusters, vessel.sensors):
the thrust at recording time t answers the PWM logged at t − delay_s + pwm_clock_offset_s
(a late-stamped PWM log makes the thrust seem to come first), decayed by t and, for thrusters
that follow the supply voltage, scaled by the battery voltage logged at t (Prepared.supply_v).
The engine holds a command over its step: the step's mean of the input so held, so a shift that
is not a whole number of steps mixes the two logged values around it by the share of the step
each covers, and a fitted delay moves the cost however little it changes.

The recorded inputs are the prepared recording's two input channels (`Prepared.pwm`) of its
`input_kind`: PWM for thrusters, or a propeller-and-rudder ship's (n rps, δ rad), which
`ThrusterModel.command` passes on as the engine's controls; a recording of the other kind
cannot drive the vessel.

Measured wind (`predict(..., wind="measured")`): the recording's wind stream, held on the grid
(Prepared.wind_ned), is held over each engine step as the model's controls 2 and 3 (a model
compiled with wind inputs) in place of the vessel environment's constant wind: a known input,
not a fitted one. Without it (the default) nothing of the measured wind is used.
"""
from __future__ import annotations

import copy
import hashlib
import math
import threading
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable

import mujoco
import numpy as np
from scipy.ndimage import correlate1d

from ..engine import batch, native
from ..engine.callbacks import _joint_indices
from ..engine.mjcf import CompiledVessel, compile_vessel
from ..drive import inputs_mismatch
from ..errors import TwinError
from ..physics.hydrodynamics import acceleration
from ..physics.thrusters import ThrusterModel
from ..prepare import Prepared
from ..prepare.prepared import hold
from ..threads import BoundedStore
from ..vessel import Vessel


@dataclass(frozen=True)
class Window:
    """Grid samples start..start+n of prepared recording `rec`, inside one segment."""

    rec: int
    start: int
    n: int


def make_windows(preps: list[Prepared], length_s: float | None, stride_s: float | None = None,
                 min_length_s: float = 2.0) -> list[Window]:
    """Windows of length_s every stride_s (default: length_s) inside every segment;
    length_s None = each whole segment. The last, shorter stretch of a segment is
    kept when it is at least min_length_s long."""
    out = []
    for i, prep in enumerate(preps):
        h = prep.settings.grid_dt
        for seg in prep.segments:
            last = seg.stop - 1
            if length_s is None:
                if (last - seg.start) * h >= min_length_s:
                    out.append(Window(i, seg.start, last - seg.start))
                continue
            n = int(round(length_s / h))
            stride = max(1, int(round((stride_s or length_s) / h)))
            for start in range(seg.start, last, stride):
                steps = min(n, last - start)
                if steps * h >= min(min_length_s, length_s) - 1e-9:
                    out.append(Window(i, start, steps))
    return out


# ---------------------------------------------------------------- models

# a segment's lag states per lag tried: a few tens of kB each, as many as a diagnosis's candidate
# lags over one outing's segments need
SEGMENT_LAGS_KEPT = 512
ROLLOUTS_KEPT_BYTES = 128 * 2 ** 20  # of windows' runs at their samples: tens of thousands of windows
KEPT = 20000  # windows' inputs and initial states: a diagnosis's outing of windows times its lags and offsets


def _structure_key(vessel: Vessel, wind: bool = False) -> tuple:
    """What needs a recompilation: everything else is set on a copy of a compiled model."""
    t = vessel.thrusters
    key = (str(vessel.mjcf), vessel.case, tuple(vessel.cg_offset_m), t.lag_s > 0,
           t.bounded)
    return key + (t.kind, True) if wind else key


class ModelCache:
    """Compiled native models by structure; per vessel a cheap copy with its own
    hydrodynamic parameters, thruster gains, advance loss, lag and range. Every model replays
    recordings, so a propeller and rudder's inputs are taken as logged (Vessel.as_logged).

    timestep_s overrides the MJCF's time step (a coarser RK4 step for the many
    candidate runs of a diagnosis; it must divide the recordings' grid). keep_runs: free runs are
    kept and not rolled out again (rolled_out). One cache may serve fits running in several threads
    (its stores are twin.threads.BoundedStore)."""

    def __init__(self, timestep_s: float | None = None, keep_runs: bool = False) -> None:
        self._compiled: BoundedStore[tuple[CompiledVessel, mujoco.MjModel]] = BoundedStore()
        self.timestep_s = timestep_s
        self._inputs: BoundedStore[np.ndarray] = BoundedStore(KEPT)
        self._lagged: BoundedStore[np.ndarray] = BoundedStore(KEPT)
        self._command_keys: dict[tuple, int] = {}
        self._keys_lock = threading.Lock()
        self._states: BoundedStore[np.ndarray] = BoundedStore(KEPT)
        self._thrust_bounds: BoundedStore[tuple[float, float]] = BoundedStore()
        self._segment_lag: BoundedStore[np.ndarray] = BoundedStore(SEGMENT_LAGS_KEPT)
        # free runs kept only where they are asked for again (a diagnosis's, an identification's fits):
        # a Monte Carlo draw's twin runs once
        self._rollouts: BoundedStore[np.ndarray] | None = BoundedStore(max_bytes=ROLLOUTS_KEPT_BYTES) if keep_runs else None

    def initial_state(self, model: mujoco.MjModel, data: Callable[[], mujoco.MjData], layout: tuple, prep: Prepared,
                      window: Window, nu_offset: tuple) -> np.ndarray:
        """A window's full-physics initial state (_initial_state), made once for every vessel of one
        state layout: it depends on nothing else than the measured state at the window's start and
        the offset (a Jacobian's vessels and a round's candidates share them; a lag's state is the
        inputs', lagged_thrust). data: gives the work MjData, called only for a state not yet kept."""
        k = window.start
        key = (layout, prep.t[k], prep.north[k], prep.east[k], prep.psi[k], prep.u[k], prep.v[k], prep.r[k], nu_offset)
        return self._states.get(key, lambda: _initial_state(model, data(), prep, window, nu_offset))

    def command_key(self, vessel: Vessel) -> int:
        """A small integer for what a vessel's commands depend on (command_thrusters, the PWM clock),
        the same for every vessel that shares them: hashed once per vessel, not once per window."""
        key = (command_thrusters(vessel.thrusters), vessel.sensors.pwm_clock_offset_s)
        with self._keys_lock:  # two threads' new keys must not both take the next number
            return self._command_keys.setdefault(key, len(self._command_keys))

    def inputs(self, vessel: Vessel, prep: Prepared, window: Window, timestep_s: float,
               command_key: int | None = None) -> np.ndarray:
        """(steps, 2) thrust (N, before the gains) over each engine step of a window: the commands,
        through the thrust lag where the vessel has one (lagged_thrust). The commands are the same
        for every candidate that leaves the thrusters and the PWM clock alone, so computed once. (A
        propeller and rudder's commands are its controls (n, δ).) command_key: command_key(vessel),
        when the caller has it (one vessel's many windows)."""
        # the PWM a window sees does not depend on the sensors' heading or antenna calibration, so
        # what the recording logged (logged_key) and the window identify it; nor do the commands depend
        # on the gains, lag or advance loss, so a lag's or a gain's trials share them
        command_key = self.command_key(vessel) if command_key is None else command_key
        recording = logged_key(prep)
        key = recording + (window.start, window.n, timestep_s, command_key)
        cmd = self._inputs.get(key, lambda: thrust_commands(vessel, prep, window, timestep_s))
        if not lag_outside_engine(vessel):
            return cmd
        lag_s = vessel.thrusters.lag_s
        return self._lagged.get(key + (lag_s,),
                          lambda: lagged_thrust(np.clip(cmd, *self._bounds(vessel, command_key)),
                                                self._lag_state(vessel, prep, window, timestep_s, command_key,
                                                                recording),
                                                lag_s, timestep_s))

    def _bounds(self, vessel: Vessel, command_key: int) -> tuple[float, float]:
        """The thrusters' bounds (N), which depend on their map alone (the command key's)."""
        return self._thrust_bounds.get(command_key, vessel.thrusters.bounds)

    def _lag_state(self, vessel: Vessel, prep: Prepared, window: Window, timestep_s: float, command_key: int,
                   recording: tuple) -> np.ndarray:
        """lagged_thrust_at_start, from the segment's commands filtered once per lag: a causal filter's
        value after k steps is the same whether the steps after k are filtered or not."""
        seg = prep.segments[int(prep.segment[window.start])]
        if window.start == seg.start:
            return lagged_thrust_at_start(vessel, prep, window, timestep_s)
        key = recording + (seg.start, timestep_s, command_key, vessel.thrusters.lag_s)
        filtered = self._segment_lag.get(key, lambda: _filtered_segment(vessel, prep, seg, window.rec, timestep_s,
                                                                        self._bounds(vessel, command_key)))
        return filtered[(window.start - seg.start) * _substeps(prep.settings.grid_dt, timestep_s) - 1]

    def compiled(self, vessel: Vessel) -> CompiledVessel:
        return self._base(vessel)[0]

    def _base(self, vessel: Vessel, wind: bool = False) -> tuple[CompiledVessel, mujoco.MjModel]:
        def compiled() -> tuple[CompiledVessel, mujoco.MjModel]:
            cv = compile_vessel(vessel.as_logged())
            model = native.with_native_params(cv, wind_inputs=wind, lean=True)
            if self.timestep_s is not None:
                model.opt.timestep = self.timestep_s
            return cv, model
        return self._compiled.get(_structure_key(vessel, wind), compiled)

    def model(self, vessel: Vessel, wind: bool = False) -> mujoco.MjModel:
        """A native-parameterised model of `vessel` (same dynamics as compiling it afresh);
        `wind`: with the measured wind as controls 2 and 3."""
        return self.keyed_model(vessel, wind)[0]

    def keyed_model(self, vessel: Vessel, wind: bool = False) -> tuple[mujoco.MjModel, tuple]:
        """model(), and a key that is the same for two models exactly when their dynamics are: the
        compiled structure (the base model copied), its time step, and what is set on the copy."""
        m = self._model(vessel, wind)
        key = (_structure_key(vessel, wind), m.opt.timestep, m.numeric_data.tobytes(),
               m.actuator_ctrlrange.tobytes(), m.actuator_gainprm.tobytes(), m.actuator_dynprm.tobytes())
        return m, key

    def rolled_out(self, key: tuple) -> np.ndarray | None:
        """A window's run at its samples (_rollout) kept by `key` (the model's, the sampling's, the
        initial state's and the controls'), or None: a diagnosis's fits roll out the same twin over the same window again and again (every
        candidate starts from the prior; a search's Jacobian repeats a point), 28 % of its steps."""
        return None if self._rollouts is None else self._rollouts.peek(key)

    def keep_rolled_out(self, key: tuple, run: np.ndarray) -> np.ndarray:
        """Keep a window's run at its samples (read-only: every later caller shares it) under `key`,
        where this cache keeps runs."""
        if self._rollouts is None:
            return run
        run.setflags(write=False)
        return self._rollouts.get(key, lambda: run)

    def _model(self, vessel: Vessel, wind: bool) -> mujoco.MjModel:
        cv, base = self._base(vessel, wind)
        m = copy.copy(base)
        native.set_params(m, CompiledVessel(vessel.as_logged(), cv.model, cv.geometry).hydro())
        t = vessel.thrusters
        if t.kind == "propeller_rudder":  # its actuators carry (n, δ) and exert no force: nothing to set
            return m
        if t.bounded:
            m.actuator_ctrlrange[:2] = t.bounds()
        for i, gain in enumerate(t.gains()):
            m.actuator_gainprm[i, 0] = gain
            if t.lag_s > 0:
                m.actuator_dynprm[i, 0] = t.lag_s
        return m


# ---------------------------------------------------------------- inputs

def logged_key(prep: Prepared) -> tuple:
    """What a window's commands read of a prepared recording, by content: its grid, inputs and
    supply voltage. A recording prepared again for another heading or antenna calibration has the
    same (its windows' commands are computed once), and two recordings of one name and span do not.
    Worked out once per Prepared and kept on it (it lives and goes with the recording it describes)."""
    key = prep.__dict__.get("_logged_key")
    if key is None:
        h = hashlib.blake2b(digest_size=16)
        for a in (prep.t, prep.pwm, prep.supply_v):
            if a is not None:
                a = np.ascontiguousarray(a, dtype=float)
                h.update(repr(a.shape).encode())
                h.update(a.tobytes())
            h.update(b"|")
        key = prep.__dict__["_logged_key"] = (prep.input_kind, h.hexdigest())
    return key


def thrust_commands(vessel: Vessel, prep: Prepared, window: Window, timestep_s: float) -> np.ndarray:
    """(steps, 2) thrust commands (N) for the engine steps of one window. A thrust ramp (slew limit)
    stands where the commands since its segment began have brought it (settled at the first)."""
    t = vessel.thrusters
    if t.ramping:
        seg = prep.segments[int(prep.segment[window.start])]
        sub = _substeps(prep.settings.grid_dt, timestep_s)
        k = (window.start - seg.start) * sub
        return _segment_commands(vessel, prep, seg, window.rec, timestep_s)[k:k + window.n * sub]
    return _commands(vessel, prep, window, timestep_s)


def command_thrusters(thrusters: ThrusterModel) -> ThrusterModel:
    """The thrusters as far as their commands go: the gains, the lag and the advance loss act
    later, in the engine (ThrusterModel.command), so they are left at neutral values."""
    return replace(thrusters, lag_s=0.0, gain_left=1.0, gain_right=1.0, advance_loss=0.0)


_SEGMENTS: BoundedStore[tuple[np.ndarray, np.ndarray]] = BoundedStore(64)  # a segment's commands, by recording and thrusters


def _segment_commands(vessel: Vessel, prep: Prepared, seg, rec: int, timestep_s: float) -> np.ndarray:
    """The commands over a whole segment (each engine step's mean; through the ramp where there is
    one), computed once per recording, segment and command_thrusters: a ramp's windows, and every
    lag's state at a window's start (its history from the segment's start), slice them. The key
    holds the id of the recording's PWM array and the entry the array itself, so the id cannot be
    reused by another recording while the entry lives."""
    key = (id(prep.pwm), seg.start, command_thrusters(vessel.thrusters), vessel.sensors.pwm_clock_offset_s,
           timestep_s)
    def commands() -> tuple[np.ndarray, np.ndarray]:
        since = _commands(vessel, prep, Window(rec, seg.start, seg.stop - seg.start), timestep_s)
        return prep.pwm, vessel.thrusters.slewed(since, timestep_s)[0] if vessel.thrusters.ramping else since
    return _SEGMENTS.get(key, commands)[1]


def _commands(vessel: Vessel, prep: Prepared, window: Window, timestep_s: float) -> np.ndarray:
    h = prep.settings.grid_dt
    sub = _substeps(h, timestep_s)
    t0 = prep.t[window.start]
    times = t0 + timestep_s * np.arange(window.n * sub)
    seg = prep.segments[int(prep.segment[window.start])]
    look = times - vessel.thrusters.delay_s + vessel.sensors.pwm_clock_offset_s
    look = np.clip(look, prep.t[seg.start], prep.t[seg.stop - 1])  # nothing is known outside the segment
    sl = seg.slice
    logged = prep.pwm[sl]
    if prep.input_kind == "pwm" and vessel.thrusters.hysteretic:
        # a motor's state follows the PWM since the segment began; nothing later matters
        end = min(int(np.searchsorted(prep.t[sl], look[-1] + timestep_s, side="right")) + 1, len(logged))
        logged = vessel.thrusters.as_driven(logged[:end])
        sl = slice(sl.start, sl.start + end)
    ts = prep.t[sl][: len(logged)]
    supply = supply_steps(vessel, prep, times)
    i = np.clip(np.searchsorted(ts, look + _EPS_S, side="right") - 1, 0, len(ts) - 1)
    now = vessel.thrusters.command(prep.input_kind, logged[i], times, supply)
    # the engine holds a command over its step: the step's mean of the input held from the log, so a
    # shift that is not a whole number of steps moves the cost (held at the step's start, every shift
    # within a step would cost the same and a fitted delay would sit on a plateau a step wide)
    after = np.where(i + 1 < len(ts), (look + timestep_s - ts[np.minimum(i + 1, len(ts) - 1)]) / timestep_s, 0.0)
    after = np.where(after > 1e-9, np.minimum(after, 1.0), 0.0)
    if not after.any():
        return now
    later = vessel.thrusters.command(prep.input_kind, logged[np.minimum(i + 1, len(ts) - 1)], times, supply)
    return now + after[:, None] * (later - now)


_EPS_S = 1e-6  # as prepare.prepared: a time within this of a sample time counts as "at" the sample


def supply_steps(vessel: Vessel, prep: Prepared, times: np.ndarray) -> np.ndarray | None:
    """The battery voltage (V) held at `times` (recording clock, within the recording) for thrusters
    that follow it; None where they do not or the recording logs none (the map acts as at V_ref)."""
    if not vessel.thrusters.follows_supply or prep.supply_v is None:
        return None
    return hold(prep.t, prep.supply_v, np.clip(times, prep.t[0], prep.t[-1]))


def wind_steps(prep: Prepared, window: Window, timestep_s: float) -> np.ndarray:
    """(steps, 2) measured wind (the air's NED velocity, m/s) held over the engine steps of a window,
    within its segment; TwinError where the recording has none."""
    name = Path(prep.settings.source or "the recording").name
    if prep.wind_ned is None:
        raise TwinError(f"{name}: no measured wind (the recording has no wind stream)")
    sub = _substeps(prep.settings.grid_dt, timestep_s)
    t0 = prep.t[window.start]
    times = t0 + timestep_s * np.arange(window.n * sub)
    seg = prep.segments[int(prep.segment[window.start])]
    sl = seg.slice
    look = np.clip(times, prep.t[seg.start], prep.t[seg.stop - 1])
    air = np.column_stack([hold(prep.t[sl], prep.wind_ned[sl, j], look) for j in range(2)])
    if not np.all(np.isfinite(air)):
        raise TwinError(f"{name}: no measured wind yet at t = {float(times[~np.isfinite(air).all(axis=1)][0]):.1f} s "
                        "of a window")
    return air


def _substeps(grid_dt: float, timestep_s: float) -> int:
    sub = int(round(grid_dt / timestep_s))
    if sub < 1 or abs(sub * timestep_s - grid_dt) > 1e-9:
        raise TwinError(f"the recording's grid {grid_dt} s is not a multiple of the model time step {timestep_s} s")
    return sub


def lag_outside_engine(vessel: Vessel) -> bool:
    """Whether the candidate runs filter this vessel's thrust lag ahead of the engine (lagged_thrust)
    instead of integrating it as actuator state: every lagged thruster that takes thrust commands."""
    return vessel.thrusters.lag_s > 0 and vessel.thrusters.kind != "propeller_rudder"


def without_lag(vessel: Vessel) -> Vessel:
    """The vessel the engine runs when its lag is filtered ahead of it (lag_outside_engine)."""
    return replace(vessel, thrusters=replace(vessel.thrusters, lag_s=0.0))


def lagged_thrust(commands_n: np.ndarray, start_n: np.ndarray, lag_s: float, timestep_s: float) -> np.ndarray:
    """Each engine step's mean thrust (N) of a first-order lag driven by commands held over the step,
    from start_n, integrated exactly: stable and exact at any step for any lag, where RK4 integrating
    the lag as state runs away once the step passes 2.8 lags (so a fit of the lag at a coarse step
    stops at that edge, not at the recordings' lag).

    Args:
        commands_n: (steps, 2) commanded thrust, held over each step.
        start_n: (2,) lagged thrust at the first step's start.
        lag_s: time constant τ (s), > 0.
        timestep_s: engine step h (s).
    Returns:
        (steps, 2): c + (y₀ − c)·τ/h·(1 − e^(−h/τ)) per step, y₀ the lagged thrust at its start."""
    # late: scipy.signal (0.25 s) only for a thrust lag; `twin view`, `twin montecarlo` load this module too
    from scipy.signal import lfilter

    a = math.exp(-timestep_s / lag_s)
    ends, _ = lfilter([1 - a], [1, -a], commands_n, axis=0, zi=(a * np.asarray(start_n, float))[None, :])
    starts = np.vstack([np.asarray(start_n, float)[None, :], ends[:-1]])
    return commands_n + (starts - commands_n) * (lag_s / timestep_s) * (1 - a)


def lagged_thrust_at_start(vessel: Vessel, prep: Prepared, window: Window, timestep_s: float) -> np.ndarray:
    """The first-order lag's state (N) at the window start: the recorded commands since
    the segment began, filtered (exact discretisation), so a window does not start from
    a thrust the thrusters never had."""
    seg = prep.segments[int(prep.segment[window.start])]
    history = Window(window.rec, seg.start, window.start - seg.start)
    if history.n == 0:
        return np.clip(thrust_commands(vessel, prep, Window(window.rec, window.start, 1), timestep_s)[0],
                       *vessel.thrusters.bounds())
    # the history's commands are the head of the segment's: the same look-ups from the same start
    sub = _substeps(prep.settings.grid_dt, timestep_s)
    cmd = np.clip(_segment_commands(vessel, prep, seg, window.rec, timestep_s)[: history.n * sub],
                  *vessel.thrusters.bounds())
    # late: scipy.signal (0.25 s) only for a thrust lag; `twin view`, `twin montecarlo` load this module too
    from scipy.signal import lfilter

    a = np.exp(-timestep_s / vessel.thrusters.lag_s)
    filtered, _ = lfilter([1 - a], [1, -a], cmd, axis=0, zi=(a * cmd[0])[None, :])
    return filtered[-1]


def _filtered_segment(vessel: Vessel, prep: Prepared, seg, rec: int, timestep_s: float,
                      bounds: tuple[float, float]) -> np.ndarray:
    """The lag's state (N) at the end of every engine step of a segment, as lagged_thrust_at_start
    filters a window's history (from the segment's first command)."""
    # late: scipy.signal (0.25 s) only for a thrust lag; `twin view`, `twin montecarlo` load this module too
    from scipy.signal import lfilter

    cmd = np.clip(_segment_commands(vessel, prep, seg, rec, timestep_s), *bounds)
    a = np.exp(-timestep_s / vessel.thrusters.lag_s)
    return lfilter([1 - a], [1, -a], cmd, axis=0, zi=(a * cmd[0])[None, :])[0]


def _initial_state(model: mujoco.MjModel, data: mujoco.MjData, prep: Prepared, w: Window,
                   nu_offset=(0.0, 0.0, 0.0)) -> np.ndarray:
    k = w.start
    du, dv, dr = nu_offset
    batch._set_initial_state(model, data, (prep.north[k], prep.east[k], prep.psi[k]),
                             (prep.u[k] + du, prep.v[k] + dv, prep.r[k] + dr))
    data.time = prep.t[k]
    state = np.empty(batch.state_size(model))
    mujoco.mj_getState(model, data, state, batch.FULL)
    return state


# ---------------------------------------------------------------- prediction

@dataclass
class Prediction:
    """States at each window's grid samples: index 0 is the measured start, NaN past
    the window's end or after a divergence. eta (W, n+1, 3) = north, east (m), ψ (rad);
    nu (W, n+1, 3) = u, v (m/s), r (rad/s)."""

    windows: list[Window]
    eta: np.ndarray
    nu: np.ndarray
    diverged: list[tuple[int, float]]

    def nu_failed_as_inf(self) -> np.ndarray:
        """nu with a diverged window's lost samples (NaN within its length) as inf: a twin that blew up
        is a failure to score (metrics.r2_mae counts it), not a gap to skip."""
        nu = self.nu.copy()
        for j, _ in self.diverged:
            n = self.windows[j].n + 1
            nu[j, :n] = np.where(np.isnan(nu[j, :n]), np.inf, nu[j, :n])
        return nu


def predict(vessels: Vessel | list[Vessel], preps: list[Prepared], windows: list[Window],
            cache: ModelCache | None = None, nthread: int | None = None,
            nu_offsets: list | None = None, wind: str | None = None) -> list[Prediction]:
    """Free runs of every vessel over every window in one batch; one Prediction per vessel.

    `preps` are the recordings as each vessel's sensors see them: either one list
    shared by all vessels or, for candidates with different sensor calibrations,
    a list of lists (one per vessel). nu_offsets: per vessel, None or a (u, v, r)
    added to every window's measured initial velocities (initial-state sensitivities).
    wind: None (the vessel environment's constant wind) or "measured" (each recording's
    wind stream as a known input over every window, module docstring)."""
    if wind not in (None, "measured"):
        raise TwinError(f"wind must be None or 'measured', got {wind!r}")
    vessels = [vessels] if isinstance(vessels, Vessel) else list(vessels)
    per_vessel = preps if preps and isinstance(preps[0], list) else [preps] * len(vessels)
    if not windows:
        raise TwinError("no window to predict: the recording has no segment long enough")
    cache = cache or ModelCache()
    n_max = max(w.n for w in windows)
    models, states, controls, owners, keys, picks = [], [], [], [], [], []
    offsets = nu_offsets or [None] * len(vessels)
    for iv, (vessel, vpreps) in enumerate(zip(vessels, per_vessel)):
        offset = (0.0, 0.0, 0.0) if offsets[iv] is None else tuple(offsets[iv])
        if vessel.thrusters.kind not in ("t200", "propeller_rudder"):
            raise TwinError(f"vessel '{vessel.name}' has no PWM thruster model: a recording cannot drive it")
        kinds = {vpreps[w.rec].input_kind for w in windows}
        if kinds != {vessel.thrusters.input_kind}:
            other = sorted(kinds - {vessel.thrusters.input_kind})
            raise TwinError(inputs_mismatch(vessel.name, vessel.thrusters.input_kind, ", ".join(other) or None))
        engine_vessel = without_lag(vessel) if lag_outside_engine(vessel) else vessel
        model, model_key = cache.keyed_model(engine_vessel, wind=wind is not None)
        h = model.opt.timestep
        data = _WorkData(model)
        model_of_log = (_per_log_models(engine_vessel, (model, model_key), cache) if wind is None else
                        (lambda source, m=(model, model_key): m))
        command_key = cache.command_key(vessel)
        layouts: dict[int, tuple] = {}
        for w in windows:
            prep = vpreps[w.rec]
            model, model_key = model_of_log(prep.settings.source)
            layout = layouts.get(id(model))
            if layout is None:  # what fixes a state vector besides the window: sizes, joints, unset qpos
                layout = layouts[id(model)] = (batch._signature(model), _joint_columns(model), model.qpos0.tobytes())
            cmd = cache.inputs(vessel, prep, w, h, command_key)
            sub = _substeps(prep.settings.grid_dt, h)
            steps = sub * n_max
            padded = np.zeros((steps, model.nu))
            padded[: len(cmd), :2] = cmd
            if wind is not None:
                air = wind_steps(prep, w, h)
                padded[: len(air), 2:4] = air
                padded[len(air):, 2:4] = air[-1]
            models.append(model)
            states.append(cache.initial_state(model, data, layout, prep, w, offset))
            controls.append(padded)
            owners.append(iv)
            keys.append(model_key)
            picks.append((sub, layout[1]))
    traj, diverged = _rollout(models, states, controls, nthread, cache, keys, picks)
    return [_collect([i for i, o in enumerate(owners) if o == iv], traj, diverged, windows, per_vessel[iv])
            for iv in range(len(vessels))]


class _WorkData:
    """An MjData of `model`, made on the first call: nearly every window's initial state is kept
    from an earlier call, and a new MjData zeroes its 13 MB arena (0.4 ms; identify made about a
    thousand of them)."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self._model, self._data = model, None

    def __call__(self) -> mujoco.MjData:
        if self._data is None:
            self._data = mujoco.MjData(self._model)
        return self._data


def _per_log_models(vessel: Vessel, own: tuple[mujoco.MjModel, tuple], cache: ModelCache):
    """source → (model, key) of that log's environment (its own wind where `wind_by_log` names it),
    each made once; `own`: the vessel's, for every log without an entry."""
    if not vessel.environment.wind_by_log:
        return lambda source: own
    models: dict = {}

    def model_of(source: str) -> tuple[mujoco.MjModel, tuple]:
        env = vessel.environment.for_log(source)
        if env not in models:
            models[env] = cache.keyed_model(replace(vessel, environment=env))
        return models[env]
    return model_of


def _rollout(models, states, controls, nthread, cache: ModelCache, model_keys: list[tuple],
             picks: list[tuple[int, tuple]]) -> tuple[list[np.ndarray], list[tuple[int, float]]]:
    """Each window's (n_max, 6) positions and velocities (qpos, qvel of the planar joints) at the
    recording's samples, `picks` (substeps a sample, joint columns) choosing them from the engine's
    steps: those kept from an earlier rollout of the same model, initial state, controls and
    sampling as they were (each run is rolled out on its own: the same numbers), the others in one
    rollout per state size (a lagged twin carries actuator states, a plain one does not). A run that
    diverged is not kept; a window asked twice in one batch is rolled out once."""
    keys = [(mk, pick[0], s.tobytes(), hashlib.blake2b(c, digest_size=16).digest())
            for mk, pick, s, c in zip(model_keys, picks, states, controls)]
    traj: list[np.ndarray | None] = [cache.rolled_out(k) for k in keys]
    first: dict[tuple, int] = {}
    for i, k in enumerate(keys):
        if traj[i] is None:
            first.setdefault(k, i)
    sizes: dict[int, list[int]] = {}
    for i in first.values():
        sizes.setdefault(len(states[i]), []).append(i)
    failed: dict[int, float] = {}
    for rows in sizes.values():
        out, bad = batch.rollout([models[i] for i in rows], np.array([states[i] for i in rows]),
                                 np.array([controls[i] for i in rows]), nthread=nthread)
        failed.update((rows[j], t) for j, t in bad)
        for j, i in enumerate(rows):
            model, (sub, (qpos, dof)) = models[i], picks[i]
            columns = [1 + q for q in qpos] + [1 + model.nq + d for d in dof]
            sampled = out[j][sub - 1::sub][:, columns]  # a copy: the batch's array is not held
            traj[i] = sampled if i in failed else cache.keep_rolled_out(keys[i], sampled)
    diverged = []
    for i, k in enumerate(keys):
        if traj[i] is None:  # the batch's first of its key ran it
            traj[i] = traj[first[k]]
        if k in first and first[k] in failed:
            diverged.append((i, failed[first[k]]))
    return traj, diverged


def _collect(rows, traj, diverged, windows, preps) -> Prediction:
    """One vessel's Prediction from its rows' sampled runs (_rollout)."""
    n_max = max(w.n for w in windows)
    eta = np.full((len(windows), n_max + 1, 3), np.nan)
    nu = np.full_like(eta, np.nan)
    bad = {i: t for i, t in diverged}
    lost = [(j, bad[row]) for j, row in enumerate(rows) if row in bad]
    groups: dict[int, list[int]] = {}  # windows of one length: sliced all at once
    recs = np.array([w.rec for w in windows])
    starts = np.array([w.start for w in windows])
    lengths = np.array([w.n for w in windows])
    for rec in np.unique(recs):
        js = np.flatnonzero(recs == rec)
        prep, k = preps[rec], starts[js]
        eta[js, 0] = np.column_stack([prep.north[k], prep.east[k], prep.psi[k]])
        nu[js, 0] = np.column_stack([prep.u[k], prep.v[k], prep.r[k]])
        for n in np.unique(lengths[js]):
            groups.setdefault(int(n), []).extend(js[lengths[js] == n].tolist())
    for n, js in groups.items():
        picks = np.stack([traj[rows[j]][:n] for j in js])  # (G, n, 6)
        e, qv = picks[..., :3], picks[..., 3:]
        c, s = np.cos(e[..., 2]), np.sin(e[..., 2])
        eta[js, 1: n + 1] = e
        nu[js, 1: n + 1] = np.stack([c * qv[..., 0] + s * qv[..., 1], -s * qv[..., 0] + c * qv[..., 1], qv[..., 2]],
                                    axis=-1)
    return Prediction(list(windows), eta, nu, lost)


def _joint_columns(model: mujoco.MjModel) -> tuple[tuple[int, ...], tuple[int, ...]]:
    return _joint_indices(model)


def measured(preps: list[Prepared], windows: list[Window]) -> tuple[np.ndarray, np.ndarray]:
    """The measurements on the windows' samples, shaped like a Prediction's eta and nu."""
    n_max = max(w.n for w in windows)
    eta = np.full((len(windows), n_max + 1, 3), np.nan)
    nu = np.full_like(eta, np.nan)
    for j, w in enumerate(windows):
        p, sl = preps[w.rec], slice(w.start, w.start + w.n + 1)
        eta[j, : w.n + 1] = np.column_stack([p.north[sl], p.east[sl], p.psi[sl]])
        nu[j, : w.n + 1] = np.column_stack([p.u[sl], p.v[sl], p.r[sl]])
    return eta, nu


def measured_side(preps: list[Prepared], windows: list[Window], n1: int) -> tuple:
    """What as_measured takes from the recordings, the same for every prediction of these windows
    (n1 samples each, the start included): the measured r before each window (heading window), u, v
    before it and the heading over it (GNSS window); None where a window of the estimator is empty."""
    settings = preps[0].settings
    h = settings.grid_dt
    gnss_half = int(np.floor(settings.window_s / 2 / h + 1e-9))
    heading_half = int(np.floor(settings.yaw_rate_window_s / 2 / h + 1e-9))
    r_past = _past(preps, windows, heading_half)[..., 2:]
    if gnss_half < 1:
        return r_past, None, None
    return r_past, _past(preps, windows, gnss_half)[..., :2], _headings(preps, windows, gnss_half, n1)


def as_measured(nu_pred: np.ndarray, preps: list[Prepared], windows: list[Window],
                side: tuple | None = None) -> np.ndarray:
    """Predicted velocities seen through the measurement's own velocity estimator.

    A Savitzky-Golay slope over ±L = window_s/2 (any polyorder ≤ 2: the quadratic term
    does not move the centre slope) of a position is the velocity averaged with the
    Epanechnikov kernel 3(L² − s²)/(4L³). So the measured ν is a smoothed ν, and a
    fit that compares it with the raw prediction mistakes the smoothing for physics
    (more lag, less added mass). Smoothing the prediction the same way removes that
    bias; before the window's start the measured velocities stand in for the prediction,
    past its end a straight line through its last two samples. r uses the heading window of the
    preparation (none where r was read from a rate gyro). u, v use the GNSS window and are smoothed where the estimator smooths them:
    over ground (north, east), then turned into the body by the heading at the sample
    (prepare's eqs. 35-36). Smoothed in the body frame instead, a turning hull's velocity would
    keep a sway that the ground track's smoothing turns away (u·r over the window): the fit then
    reads it as sway physics (on a simulated BlueBoat run, Yuv −91 for −48). The turn uses the
    measured heading, as the estimator does; the antenna's arm is left out of the smoothing (its
    part, r·arm averaged over the window, is of second order). side: measured_side(preps, windows,
    nu_pred.shape[1]), when the caller keeps it for many predictions of the same windows."""
    settings = preps[0].settings
    if settings.smoother != "savgol":
        return nu_pred
    h = settings.grid_dt
    r_past, uv_past, psi = measured_side(preps, windows, nu_pred.shape[1]) if side is None else side
    r = _smoothed(nu_pred[..., 2:], r_past, settings.yaw_rate_window_s, h)
    # a rate gyro measures r itself: where a recording's r was read from one, nothing smooths it
    gyro = np.array([preps[w.rec].settings.yaw_rate_source == "gyro" for w in windows], bool)
    if gyro.any():
        r = np.where(gyro[:, None, None], nu_pred[..., 2:], r)
    if uv_past is None:
        return np.concatenate([nu_pred[..., :2], r], axis=-1)
    gnss_half = uv_past.shape[1]
    c, s = np.cos(psi), np.sin(psi)
    body = np.concatenate([uv_past, nu_pred[..., :2]], axis=1)
    ground = np.stack([c * body[..., 0] - s * body[..., 1], s * body[..., 0] + c * body[..., 1]], axis=-1)
    g = _smoothed(ground[:, gnss_half:], ground[:, :gnss_half], settings.window_s, h)
    c, s = c[:, gnss_half:], s[:, gnss_half:]
    uv = np.stack([c * g[..., 0] + s * g[..., 1], -s * g[..., 0] + c * g[..., 1]], axis=-1)
    return np.concatenate([uv, r], axis=-1)


def _smoothed(series: np.ndarray, past: np.ndarray, window_s: float, h: float) -> np.ndarray:
    """All windows at once: [measured past | series | its last slope] convolved with the kernel,
    missing samples left out of both the weighted sum and the weights. series (W, n1, k), past
    (W, half, k) with half the kernel's half-width in samples."""
    half = past.shape[1]
    if half < 1:
        return series
    s = np.arange(-half, half + 1) * h
    kernel = np.maximum(0.0, (window_s / 2) ** 2 - s ** 2)
    W, n1, k = series.shape
    padded = np.full((W, half + n1 + half, k), np.nan)
    padded[:, half: half + n1] = series
    padded[:, :half] = past
    # past each row's last sample the estimator saw the hull go on; a straight line through the
    # last two samples stands in for it (a kernel cut off there would lag by a third of its width)
    last = n1 - 1 - np.argmax(np.isfinite(series[..., 0])[:, ::-1], axis=1)
    rows = np.flatnonzero(last >= 1)
    end = series[rows, last[rows]]
    slope = end - series[rows, last[rows] - 1]
    steps = np.arange(1, half + 1)
    cols = half + last[rows, None] + steps
    padded[rows[:, None], cols] = end[:, None] + steps[None, :, None] * slope[:, None]
    ok = np.isfinite(padded)
    num = correlate1d(np.where(ok, padded, 0.0), kernel, axis=1, mode="constant")
    den = correlate1d(ok.astype(float), kernel, axis=1, mode="constant")
    out = num[:, half: half + n1] / np.where(den[:, half: half + n1] > 0, den[:, half: half + n1], np.nan)
    return np.where(np.isfinite(series), out, np.nan)


def _rows_before(preps: list[Prepared], windows: list[Window], half: int, n_after: int):
    """Per recording: (rows of `windows`, the prepared recording, grid indices (rows, half + n_after)
    from `half` samples before each window's start, and whether each lies in the window's segment
    and recording)."""
    recs = np.array([w.rec for w in windows])
    starts = np.array([w.start for w in windows])
    for rec in np.unique(recs):  # the windows of one recording at once
        p, rows = preps[rec], np.flatnonzero(recs == rec)
        first = np.array([s.start for s in p.segments])[p.segment[starts[rows]].astype(int)]
        idx = starts[rows, None] + np.arange(-half, n_after)
        keep = (idx >= first[:, None]) & (idx < len(p.t))
        yield rows, p, np.where(keep, idx, 0), keep


def _past(preps: list[Prepared], windows: list[Window], half: int) -> np.ndarray:
    """(W, half, 3) measured ν of the `half` samples before each window (NaN outside its segment)."""
    out = np.full((len(windows), half, 3), np.nan)
    for rows, p, idx, keep in _rows_before(preps, windows, half, 0):
        past = np.stack([p.u[idx], p.v[idx], p.r[idx]], axis=-1)
        out[rows] = np.where(keep[..., None], past, np.nan)
    return out


def _headings(preps: list[Prepared], windows: list[Window], half: int, n1: int) -> np.ndarray:
    """(W, half + n1) measured heading (rad) from `half` samples before each window's start to n1
    samples into it; where none was measured (outside the segment) the nearest one stands in, so
    a turn by it is a turn by the heading the hull had."""
    out = np.zeros((len(windows), half + n1))
    for rows, p, idx, keep in _rows_before(preps, windows, half, n1):
        psi = np.where(keep, p.psi[idx], np.nan)
        first = np.argmax(keep, axis=1)
        lead = np.take_along_axis(psi, first[:, None], axis=1)
        psi = np.where(np.arange(psi.shape[1]) < first[:, None], lead, psi)
        out[rows] = _fill_forward(psi)
    return out


def _fill_forward(x: np.ndarray) -> np.ndarray:
    """Each row's NaN replaced by the last finite value before it."""
    ok = np.isfinite(x)
    last = np.maximum.accumulate(np.where(ok, np.arange(x.shape[1]), 0), axis=1)
    return np.take_along_axis(x, last, axis=1)


def comfortable_timestep(compiled, preps: list[Prepared], h_lambda: float, fallback_s: float) -> float:
    """The recordings' grid step if RK4 is comfortable at it for this vessel (|hλ| ≤ h_lambda;
    RK4's stability limit is 2.8), else fallback_s, divided as often as it takes to be comfortable.
    The fastest rate: the largest eigenvalue of ∂ν̇/∂ν at a brisk state (2 m/s, 0.5 m/s, 1 rad/s,
    where quadratic damping is strong). A thrust lag does not count: predict filters it ahead of
    the engine, exactly at any step (lagged_thrust)."""
    hydro, nu, h = compiled.hydro(), np.array([2.0, 0.5, 1.0]), 1e-5
    base = acceleration(hydro, 0.0, nu, np.zeros(3))
    J = np.column_stack([(acceleration(hydro, 0.0, nu + h * e, np.zeros(3)) - base) / h for e in np.eye(3)])
    rate = float(np.max(np.abs(np.linalg.eigvals(J))))
    grid = preps[0].settings.grid_dt
    uniform = all(abs(p.settings.grid_dt - grid) <= 1e-9 for p in preps)
    if uniform and grid > fallback_s and grid * rate <= h_lambda:
        return grid
    # a fallback too coarse for this hull is divided until RK4 is comfortable: past |hλ| 2.8 it runs away
    return fallback_s / math.ceil(fallback_s * rate / h_lambda - 1e-9)
