"""Which trial would tell two readings of a log apart.

When a diagnosis keeps an effect beside a rival the recording cannot tell from it (search.py: z < 3
between the two over the held-out blocks), both readings fit the log alike: a weaker thrust and a
thrust that falls with speed give the same top speeds, a drag and a thrust loss the same steady runs.
They part where the log has not been: in a manoeuvre of another kind. Each reading is a twin (the
kept effect and the rival, each fitted on the same training windows), so the twins themselves say
where they part. Each trial of synth.manoeuvres.TRIALS (fixed stick programs from rest) is run whole
by each reading; every EVERY_S along the first reading's run a window of the diagnosis's own length
starts, the first reading's window being its own run there and the second's a free run from the
first's position and velocities with its own thrust-lag state and its own commands (its delay and
ramp carried from the trial's start), as the diagnosis starts a twin's window from the log. A trial
separates the two where their windows differ by more than what the twin still misses on the
recording (its RMS misfit after the amendment, per velocity, never below the noise): a window that
differs by less would not vote for either.

A rival recorded on a trial is refitted to it, so the trial must part the two readings however the
rival's own numbers move: the rival's quantities (those its fit freed) are refitted to the first
reading's windows on the trial, and the trial is judged by what is left, the least discrepancy the
rival can reach (the T-optimal criterion of model discrimination [Atkinson-Fedorov-1975]). Refitted
on the trial alone, the rival may take values the recorded log would refuse, so what is left is a
lower bound of the separation a diagnosis of the log and the trial together would see. Unrefitted,
a weaker thrust and more yaw damping part by 22× a twin's misfit in spins, and the BlueBoat's
diagnosis still could not tell them apart with the spins recorded: the damping's yaw scale took the
spins up alone. Trials are refitted in the order of their unrefitted separation, which a refit
usually narrows (it lowers the summed squares, not always the median of one velocity): up to
REFIT_TRIALS once one settles, all of them while none does. A scanned candidate (a time shift, a dead
zone: a staircase cost) is not refitted.

Only effects that act on the hull or the thrusters are compared: a sensor's effect (a heading bias, a
late GNSS) does not change the velocities a trial runs, an earth-fixed one (a current, a wind) acts
by the heading a trial from rest does not vary, and a per-log one has no log here. Their rivals get
the family's advice alone (report.py), as does a propeller-and-rudder ship, driven by shaft speed and
rudder rather than PWM.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import mujoco
import numpy as np
from scipy.optimize import least_squares

from ..drive import InputSeries
from ..effects import EFFECTS, Candidate
from ..engine import native
from ..engine.batch import initial_state, poses_and_velocities, rollout, thrust_controls_from_inputs
from ..engine.mjcf import compile_vessel
from ..errors import TwinError
from ..synth.manoeuvres import TRIALS, trial
from ..vessel import Vessel
from .search import BLOCK_WINDOWS

EVERY_S = 4.0  # a window starts this often along a trial (overlapping, as the trial is short)
TIMESTEP_S = 0.05  # RK4 step of the trials' runs: the diagnosis's own for its candidates (doctor.SEARCH_TIMESTEP_S)
MIMIC_NFEV = 6  # the rival's refit on a trial: solver steps (a few quantities, a smooth cost)
REFIT_TRIALS = 3  # trials refitted once one of them settles (each refit: a few seconds)
MIMIC_DIFF_STEP = 1e-3  # the refit's finite-difference step, relative
DIVERGED_RESIDUAL = 1e3  # a window the refitted rival diverges in: far off, in yardstick units
SETTLES_RATIO = 1.0  # a trial is proposed where the readings part by at least what the twin still misses
SETTLE_BLOCKS = 10  # blocks with every vote for one reading that z ≥ 3 needs (search.py)
COMPARED = ("hull", "thrusters")  # what an effect acts on for its trials to be compared (module docstring)
DOFS = ("u", "v", "r")


@dataclass(frozen=True)
class Separation:
    """How a trial tells two readings apart. `dof`: the velocity where they differ most; `difference`:
    the median over the trial's windows of their RMS difference there (m/s; rad/s for r); `ratio`: that
    over what the twin still misses in that velocity; `share`: of the windows, those where the two
    differ by more than that in some velocity; `minutes`: recording of the trial that would give
    SETTLE_BLOCKS such blocks (None: no window differs); `refitted`: the rival's quantities refitted
    to the first reading on this trial."""

    trial: str
    dof: str
    difference: float
    ratio: float
    share: float
    minutes: float | None
    refitted: bool = False

    def to_dict(self) -> dict:
        return {k: (round(v, 4) if isinstance(v, float) else v) for k, v in asdict(self).items()}


@dataclass(frozen=True)
class _Reading:
    """One reading run whole on a trial: its model at TIMESTEP_S, its commands (N) per step and its
    full-physics states from the trial's start (the initial state first)."""

    model: mujoco.MjModel
    controls: np.ndarray  # (steps, 2)
    states: np.ndarray  # (steps + 1, nstate)


@dataclass(frozen=True)
class _TrialWindows:
    """A trial cut into windows of `steps` engine steps starting at `starts` (step indices) along the
    first reading's run, and the first reading's velocities (windows, steps, 3) in them."""

    series: InputSeries
    first: _Reading
    starts: np.ndarray
    steps: int
    first_nu: np.ndarray

    def second_nu(self, vessel: Vessel) -> np.ndarray | None:
        """The second reading's velocities in the windows (free runs from the first's position and
        velocities, its own lag state and commands); None where it runs away."""
        reading = _run_whole(vessel, self.series, len(self.first.controls))
        if reading is None:
            return None
        nqv = 1 + reading.model.nq + reading.model.nv
        states0 = reading.states[self.starts].copy()
        states0[:, :nqv] = self.first.states[self.starts][:, :nqv]  # time, position and velocity: the first's
        controls = np.stack([reading.controls[k: k + self.steps] for k in self.starts])
        traj, diverged = rollout(reading.model, states0, controls)
        if diverged:
            return None
        return np.stack([poses_and_velocities(reading.model, t)[1] for t in traj])

    def differences(self, nu: np.ndarray) -> np.ndarray:
        """(windows, 3) RMS difference of u, v, r of `nu` from the first reading's."""
        return np.sqrt(np.mean((nu - self.first_nu) ** 2, axis=1))


def _run_whole(vessel: Vessel, series: InputSeries, steps: int) -> _Reading | None:
    """The vessel run whole on a trial from rest; None where it runs away."""
    model = native.with_native_params(compile_vessel(vessel))
    model.opt.timestep = TIMESTEP_S
    controls = thrust_controls_from_inputs(vessel, series, steps, TIMESTEP_S)
    state0 = initial_state(model)
    traj, diverged = rollout(model, state0[None], controls[None])
    if diverged:
        return None
    return _Reading(model, controls, np.vstack([state0[None], traj[0]]))


def _trial_windows(first: Vessel, name: str, window_s: float) -> _TrialWindows | None:
    """The trial's windows along the first reading's run; None where it runs away or the trial is
    shorter than a window."""
    series = trial(name)
    steps_total = int(round((float(series.t[-1]) + 0.1) / TIMESTEP_S))
    steps = int(round(window_s / TIMESTEP_S))
    starts = np.arange(0, steps_total - steps + 1, int(round(EVERY_S / TIMESTEP_S)))
    reading = _run_whole(first, series, steps_total)
    if reading is None or not len(starts):
        return None
    nu = poses_and_velocities(reading.model, reading.states)[1]
    return _TrialWindows(series, reading, starts, steps, np.stack([nu[k + 1: k + 1 + steps] for k in starts]))


def _mimicked(tw: _TrialWindows, second: Vessel, rival: Candidate, scale: np.ndarray) -> np.ndarray | None:
    """The second reading's windows with the rival's quantities refitted to the first reading's on
    this trial (least squares in units of `scale`); None where the refit fails."""
    params = rival.params
    lo, hi = np.array([p.lo for p in params], float), np.array([p.hi for p in params], float)
    typical = np.array([max(abs(p.typical), 1e-6) for p in params], float)
    x0 = np.clip(np.array([p.get(second) for p in params], float), lo, hi)

    def vessel_at(x: np.ndarray) -> Vessel:
        v = second
        for p, value in zip(params, x):
            v = p.put(v, float(value))
        return v

    def residuals(x: np.ndarray) -> np.ndarray:
        nu = tw.second_nu(vessel_at(x))
        if nu is None:
            return np.full(tw.first_nu.size, DIVERGED_RESIDUAL)
        return ((nu - tw.first_nu) / scale).ravel()

    try:
        sol = least_squares(residuals, x0, bounds=(lo, hi), x_scale=typical, max_nfev=MIMIC_NFEV,
                            diff_step=MIMIC_DIFF_STEP)
        return tw.second_nu(vessel_at(sol.x))
    except (TwinError, ValueError):  # a value the vessel's checks refuse: no refitted figure
        return None


def _separation(name: str, diffs: np.ndarray, scale: np.ndarray, window_s: float, refitted: bool) -> Separation:
    """A trial's separation from its windows' RMS differences (windows, 3) and the yardstick `scale`."""
    ratios = diffs / scale
    k = int(np.argmax(np.median(ratios, axis=0)))
    share = float(np.mean(np.max(ratios, axis=1) > 1.0))
    minutes = SETTLE_BLOCKS * BLOCK_WINDOWS * window_s / share / 60.0 if share > 0 else None
    return Separation(name, DOFS[k], float(np.median(diffs[:, k])), float(np.median(ratios[:, k])), share, minutes,
                      refitted)


def comparable(name: str) -> bool:
    """Whether an effect's trials can be compared (COMPARED; module docstring)."""
    spec = EFFECTS.get(name)
    return spec is not None and spec.acts_on in COMPARED and not spec.per_key


def separations(first: Vessel, second: Vessel, yardstick: dict[str, float], window_s: float = 10.0,
                rival: Candidate | None = None) -> list[Separation]:
    """Each PWM trial's separation of two readings (module docstring), the most telling first.

    Args:
        first, second: the two readings, each a twin with its effect fitted.
        yardstick: per velocity ("u", "v", "r"; m/s, rad/s), what the twin still misses on the log.
        window_s: the diagnosis's window length (s).
        rival: the second reading's effect as the diagnosis fitted it; given (and not scanned), its
            quantities are refitted to the first reading on the trials (module docstring).

    Returns:
        Separations, the refitted ones first, each group by `ratio`, largest first; empty for a vessel
        not driven by PWM."""
    if first.thrusters.input_kind != "pwm" or second.thrusters.input_kind != "pwm":
        return []
    scale = np.array([max(float(yardstick[k]), 1e-9) for k in DOFS])
    as_fitted, windows = {}, {}
    for name in TRIALS:
        tw = _trial_windows(first, name, window_s)
        nu = None if tw is None else tw.second_nu(second)
        if nu is not None:
            windows[name] = tw
            as_fitted[name] = _separation(name, tw.differences(nu), scale, window_s, False)
    if rival is None or rival.scan or not rival.params:
        return sorted(as_fitted.values(), key=lambda s: -s.ratio)
    out, best, refitted = [], 0.0, 0
    for sep in sorted(as_fitted.values(), key=lambda s: -s.ratio):
        if sep.ratio <= best or (refitted >= REFIT_TRIALS and best >= SETTLES_RATIO):
            out.append(sep)
            continue
        nu = _mimicked(windows[sep.trial], second, rival, scale)
        if nu is not None:
            sep = _separation(sep.trial, windows[sep.trial].differences(nu), scale, window_s, True)
            best, refitted = max(best, sep.ratio), refitted + 1
        out.append(sep)
    return sorted(out, key=lambda s: (not s.refitted, -s.ratio))


def settling(seps: list[dict]) -> dict | None:
    """Of one rival's separations (as `Separation.to_dict`, as `separations` orders them), the trial to
    propose: the best that parts the two readings by at least SETTLES_RATIO of what the twin still
    misses, refitted where any was; None when none does (the two readings may be one for these
    trials)."""
    any_refitted = any(s.get("refitted") for s in seps)
    for s in seps:
        if s["ratio"] >= SETTLES_RATIO and s["minutes"] is not None and (s.get("refitted") or not any_refitted):
            return s
    return None
