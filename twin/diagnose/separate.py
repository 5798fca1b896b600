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

A propeller-and-rudder ship is driven by shaft speed and rudder, not PWM: its trials are not in
this library, and its rivals get the family's advice alone (report.py).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..drive import InputSeries
from ..engine.batch import simulate_many
from ..engine.mjcf import compile_vessel
from ..synth.manoeuvres import TRIALS, trial
from ..vessel import Vessel
from .search import BLOCK_WINDOWS

EVERY_S = 2.0  # a window starts this often along a trial (overlapping, as the trial is short)
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


def _window_differences(first, second, series: InputSeries, window_s: float) -> np.ndarray | None:
    """(windows, 3) RMS difference of u, v, r between the two compiled readings' free runs, each window
    started from the first reading's state along the trial; None when the first diverges."""
    duration = float(series.t[-1]) + 0.1
    whole = simulate_many(first, [series], [duration], sample_dt_s=0.1)[0]
    if whole is None:
        return None
    starts = np.arange(0.0, duration - window_s + 1e-9, EVERY_S)
    rows = [int(np.argmin(np.abs(whole.t - t0))) for t0 in starts]
    pieces = [_from(series, t0) for t0 in starts]
    kwargs = dict(eta0=[tuple(whole.eta[i]) for i in rows], nu0=[tuple(whole.nu[i]) for i in rows],
                  start_s=list(starts), sample_dt_s=0.1)
    a = simulate_many(first, pieces, [window_s] * len(pieces), **kwargs)
    b = simulate_many(second, pieces, [window_s] * len(pieces), **kwargs)
    out = [np.sqrt(np.mean((rb.nu - ra.nu) ** 2, axis=0)) for ra, rb in zip(a, b) if ra is not None and rb is not None]
    return np.array(out) if out else None


def separations(first: Vessel, second: Vessel, yardstick: dict[str, float], window_s: float = 10.0) -> list[Separation]:
    """Each PWM trial's separation of two readings (module docstring), the most telling first.

    Args:
        first, second: the two readings, each a twin with its effect fitted.
        yardstick: per velocity ("u", "v", "r"; m/s, rad/s), what the twin still misses on the log.
        window_s: the diagnosis's window length (s).

    Returns:
        Separations sorted by `ratio`, largest first; empty for a vessel not driven by PWM."""
    if first.thrusters.input_kind != "pwm" or second.thrusters.input_kind != "pwm":
        return []
    scale = np.array([max(float(yardstick[k]), 1e-9) for k in DOFS])
    a, b = compile_vessel(first), compile_vessel(second)
    out = []
    for name in TRIALS:
        diffs = _window_differences(a, b, trial(name), window_s)
        if diffs is None:
            continue
        ratios = diffs / scale
        k = int(np.argmax(np.median(ratios, axis=0)))
        share = float(np.mean(np.max(ratios, axis=1) > 1.0))
        minutes = SETTLE_BLOCKS * BLOCK_WINDOWS * window_s / share / 60.0 if share > 0 else None
        out.append(Separation(name, DOFS[k], float(np.median(diffs[:, k])), float(np.median(ratios[:, k])), share,
                              minutes))
    return sorted(out, key=lambda s: -s.ratio)
