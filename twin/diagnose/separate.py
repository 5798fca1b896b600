"""Which trial would tell two readings of a log apart.

When a diagnosis keeps an effect beside a rival the recording cannot tell from it (search.py: z < 3
between the two over the held-out blocks), both readings fit the log alike: a weaker thrust and a
thrust that falls with speed give the same top speeds, a drag and a thrust loss the same steady runs.
They part where the log has not been: in a manoeuvre of another kind. Each reading is a twin (the
kept effect and the rival, each fitted on the same training windows), so the twins themselves say
where they part: each trial of synth.manoeuvres.TRIALS (fixed stick programs from rest) is run by
the first reading, and from its states every EVERY_S both readings run free for a window of the
diagnosis's own length, as the diagnosis compares a twin with a log. A trial separates the two
where their windows differ by more than what the twin still misses on the recording (its RMS
misfit after the amendment, per velocity, never below the noise): a window that differs by less
would not vote for either. The answer is a prediction of two twins, not a measurement: it says
which trial to record, and roughly how much of it the held-out test needs (ten blocks of three
windows in which the readings differ: search.py's least count for z ≥ 3).

A rival recorded on a trial is refitted to it, so the trial must part the two readings however the
rival's own numbers move: on each trial the rival's quantities are refitted to the first reading's
free runs there, and the trial is judged by what is left (the T-optimal criterion of model
discrimination [Atkinson-Fedorov-1975]: the least discrepancy the rival can reach). Refitted on the
trial alone, the rival may take values the recorded log would refuse, so what is left is a lower
bound of the separation a diagnosis of the log and the trial together would see. Unrefitted, a
weaker thrust and more yaw damping part by 17× a twin's misfit in spins, and the BlueBoat's
diagnosis still could not tell them apart with spins recorded: the damping's yaw scale took the
spins up alone. A candidate that is scanned (a time shift, a dead zone: a staircase cost) is not
refitted.

A propeller-and-rudder ship is driven by shaft speed and rudder, not PWM: its trials are not in
this library, and its rivals get the family's advice alone (report.py).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy.optimize import least_squares

from ..drive import InputSeries
from ..effects import Candidate
from ..engine.batch import simulate_many
from ..engine.mjcf import compile_vessel
from ..errors import TwinError
from ..synth.manoeuvres import TRIALS, trial
from ..vessel import Vessel
from .search import BLOCK_WINDOWS

EVERY_S = 4.0  # a window starts this often along a trial (overlapping, as the trial is short)
TIMESTEP_S = 0.05  # RK4 step of the trials' runs: the diagnosis's own for its candidates (doctor.SEARCH_TIMESTEP_S)
MIMIC_NFEV = 6  # the rival's refit on a trial: solver steps (a few quantities, a smooth cost)
REFIT_TRIALS = 3  # trials whose rival is refitted, the most telling unrefitted first (each refit: a few seconds)
MIMIC_DIFF_STEP = 1e-3  # its finite-difference step, relative
DIVERGED_RESIDUAL = 1e3  # a window the refitted rival diverges in: far off, in yardstick units
SETTLES_RATIO = 1.0  # a trial is proposed where the readings part by at least what the twin still misses
SETTLE_BLOCKS = 10  # blocks with every vote for one reading that z ≥ 3 needs (search.py)
DOFS = ("u", "v", "r")
TRIAL_WORDS = {
    "full_ahead_coast": "full ahead from rest for 25 s, then the thrusters at neutral to coast down",
    "throttle_steps": "throttle steps from rest (a quarter, half, three quarters, full, 8 s each), then neutral",
    "spins": "spins on the spot both ways (12 s each, 0.8 of full on each stick)",
    "turns": "turns both ways at 0.6 throttle, 15 s each",
    "astern_stop": "astern at 0.8 for 15 s, then neutral",
}


@dataclass(frozen=True)
class Separation:
    """How a trial tells two readings apart. `dof`: the velocity where they differ most; `difference`:
    the median over the trial's windows of their RMS difference there (m/s; rad/s for r); `ratio`: that
    over what the twin still misses in that velocity; `share`: of the windows, those where the two
    differ by more than that in some velocity; `minutes`: recording of the trial that would give
    SETTLE_BLOCKS such blocks (None: no window differs)."""

    trial: str
    dof: str
    difference: float
    ratio: float
    share: float
    minutes: float | None
    refitted: bool = False  # the rival's quantities refitted to the first reading on this trial

    @property
    def words(self) -> str:
        return TRIAL_WORDS[self.trial]

    def to_dict(self) -> dict:
        return {k: (round(v, 4) if isinstance(v, float) else v) for k, v in asdict(self).items()}


def _from(series: InputSeries, t0_s: float) -> InputSeries:
    """The series as held from t0_s on, on a clock that starts there."""
    i0 = max(0, int(np.searchsorted(series.t, t0_s + 1e-9, side="right")) - 1)
    t = series.t[i0:] - t0_s
    t[0] = 0.0
    return InputSeries(t, series.values[i0:], series.kind)


@dataclass
class _TrialWindows:
    """A trial cut into free-run windows along the first reading's run: their inputs, where each starts,
    and the first reading's velocities in each (None where it diverged)."""

    pieces: list[InputSeries]
    starts: dict
    first_nu: list[np.ndarray | None]
    window_s: float

    def run(self, compiled) -> list[np.ndarray | None]:
        runs = simulate_many(compiled, self.pieces, [self.window_s] * len(self.pieces), timestep_s=TIMESTEP_S,
                             **self.starts)
        return [None if r is None else r.nu for r in runs]

    def differences(self, second_nu: list[np.ndarray | None]) -> np.ndarray | None:
        """(windows, 3) RMS difference of u, v, r from the first reading (windows where both ran)."""
        out = [np.sqrt(np.mean((b - a) ** 2, axis=0)) for a, b in zip(self.first_nu, second_nu)
               if a is not None and b is not None]
        return np.array(out) if out else None


def _trial_windows(first, series: InputSeries, window_s: float) -> _TrialWindows | None:
    """The trial's windows (_TrialWindows), None when the first reading diverges on it."""
    duration = float(series.t[-1]) + 0.1
    whole = simulate_many(first, [series], [duration], sample_dt_s=0.1, timestep_s=TIMESTEP_S)[0]
    if whole is None:
        return None
    starts = np.arange(0.0, duration - window_s + 1e-9, EVERY_S)
    rows = [int(np.argmin(np.abs(whole.t - t0))) for t0 in starts]
    kwargs = dict(eta0=[tuple(whole.eta[i]) for i in rows], nu0=[tuple(whole.nu[i]) for i in rows],
                  start_s=list(starts), sample_dt_s=0.1)
    tw = _TrialWindows([_from(series, t0) for t0 in starts], kwargs, [], window_s)
    tw.first_nu = tw.run(first)
    return tw


def _mimicked(tw: _TrialWindows, second: Vessel, rival: Candidate, scale: np.ndarray) -> list[np.ndarray | None]:
    """The second reading's windows with the rival's quantities refitted to the first reading's on
    this trial (least squares in units of `scale`, the first reading's windows as the data)."""
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
        nu = tw.run(compile_vessel(vessel_at(x)))
        parts = [((b - a) / scale).ravel() if b is not None else np.full(a.size, DIVERGED_RESIDUAL)
                 for a, b in zip(tw.first_nu, nu) if a is not None]
        return np.concatenate(parts)

    try:
        sol = least_squares(residuals, x0, bounds=(lo, hi), x_scale=typical, max_nfev=MIMIC_NFEV,
                            diff_step=MIMIC_DIFF_STEP)
        x = sol.x
    except (TwinError, ValueError):  # a value the vessel's checks refuse: the rival as fitted on the log
        x = x0
    return tw.run(compile_vessel(vessel_at(x)))


def settling(seps: list[dict]) -> dict | None:
    """Of one rival's separations (as `Separation.to_dict`, best first), the trial to propose: the best
    one that parts the two readings by at least SETTLES_RATIO of what the twin still misses, refitted
    where the rival was; None when no trial does (the two readings may be one for these trials)."""
    for s in seps:
        if s["ratio"] >= SETTLES_RATIO and s["minutes"] is not None and (s.get("refitted") or
                                                                            not any(x.get("refitted") for x in seps)):
            return s
    return None


def _separation(name: str, diffs: np.ndarray, scale: np.ndarray, window_s: float, refitted: bool) -> Separation:
    ratios = diffs / scale
    k = int(np.argmax(np.median(ratios, axis=0)))
    share = float(np.mean(np.max(ratios, axis=1) > 1.0))
    minutes = SETTLE_BLOCKS * BLOCK_WINDOWS * window_s / share / 60.0 if share > 0 else None
    return Separation(name, DOFS[k], float(np.median(diffs[:, k])), float(np.median(ratios[:, k])), share, minutes,
                      refitted)


def separations(first: Vessel, second: Vessel, yardstick: dict[str, float], window_s: float = 10.0,
                rival: Candidate | None = None) -> list[Separation]:
    """Each PWM trial's separation of two readings (module docstring), the most telling first.

    Args:
        first, second: the two readings, each a twin with its effect fitted.
        yardstick: per velocity ("u", "v", "r"; m/s, rad/s), what the twin still misses on the log.
        window_s: the diagnosis's window length (s).
        rival: the second reading's effect as the diagnosis fits it; given (and not scanned), its
            quantities are refitted to the first reading on each trial that could still lead.

    Returns:
        Separations sorted by `ratio`, largest first; empty for a vessel not driven by PWM."""
    if first.thrusters.input_kind != "pwm" or second.thrusters.input_kind != "pwm":
        return []
    scale = np.array([max(float(yardstick[k]), 1e-9) for k in DOFS])
    a, b = compile_vessel(first), compile_vessel(second)
    windows = {name: _trial_windows(a, trial(name), window_s) for name in TRIALS}
    as_fitted = {}
    for name, tw in windows.items():
        diffs = None if tw is None else tw.differences(tw.run(b))
        if diffs is not None:
            as_fitted[name] = _separation(name, diffs, scale, window_s, False)
    if rival is None or rival.scan or not rival.params:
        return sorted(as_fitted.values(), key=lambda s: -s.ratio)
    # a refit only narrows a trial's separation: refit in the order of the unrefitted ones, and stop once
    # the best refitted one is ahead of every trial not yet refitted
    out, best = [], 0.0
    for i, sep in enumerate(sorted(as_fitted.values(), key=lambda s: -s.ratio)):
        if sep.ratio <= best or i >= REFIT_TRIALS:
            out.append(sep)
            continue
        tw = windows[sep.trial]
        diffs = tw.differences(_mimicked(tw, second, rival, scale))
        sep = sep if diffs is None else _separation(sep.trial, diffs, scale, window_s, True)
        best = max(best, sep.ratio if sep.refitted else 0.0)
        out.append(sep)
    return sorted(out, key=lambda s: (not s.refitted, -s.ratio))
