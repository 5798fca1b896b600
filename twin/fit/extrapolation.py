"""Splits of a vessel's recordings where the judged runs lie beyond the fitted ones.

A run left out at random is like the runs a twin was fitted on, so its score says how well the
twin interpolates. A user needs the twin where no run was recorded: faster, harder turns, another
manoeuvre. These splits put the runs that go further on the judged side:

- `by_activity`: runs ranked by how much of the time they are under way (inputs beyond idle) and
  how much they turn (|r| above the pooled 80th percentile of every run's |r|); the least active
  are fitted, the most active judged. Ranks, not raw shares, so that neither measure's scale
  decides.
- `by_input_level`: runs whose inputs never exceed a level are fitted, the runs that go beyond it
  are judged (a propeller at ≤ 8 rps fitted, at 10 rps judged).
- `by_family`: runs whose file names start with one prefix are fitted, the others judged (random
  manoeuvres against steady turns).
- `low_input_stretches`: the stretches of runs whose inputs stay below a level, to be fitted on
  their own (recording.within) and judged on the runs that go beyond it.
- `by_day`: runs of one family recorded on one day are fitted, the family's runs of other days
  judged (the same manoeuvres a month later: another wind, another water temperature, the model
  ballasted again).

Every function works on prepared recordings and names runs by their log name
(physics.sensors.log_name), so a split can be stated in a report and repeated.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import TwinError
from ..physics.sensors import log_name
from ..prepare import Prepared

TURNING_PERCENTILE = 80.0  # a sample turns when its |r| is above this percentile of all runs' |r|
IDLE_PWM_US = 35.0  # a thruster within this of its neutral is idle (ESC dead band and then some)
IDLE_RPS = 1.0  # a propeller slower than this drives a model ship at a few cm/s at most


@dataclass(frozen=True)
class RunActivity:
    """How far one run goes: the share of its samples under way (inputs beyond idle) and turning
    (|r| above the pooled threshold `turning_rad_s`), and the 95th percentiles of its speed over
    ground (m/s), |r| (rad/s) and input magnitude (µs from neutral, or rps)."""

    log: str
    under_way_share: float
    turning_share: float
    turning_rad_s: float
    speed_p95_m_s: float
    yaw_rate_p95_rad_s: float
    input_p95: float

    def to_dict(self) -> dict:
        return {k: (round(v, 4) if isinstance(v, float) else v) for k, v in self.__dict__.items()}


@dataclass(frozen=True)
class Split:
    """Runs fitted and runs judged, with the rule that chose them."""

    name: str
    rule: str
    fitted: tuple[str, ...]
    judged: tuple[str, ...]

    def __repr__(self) -> str:
        return f"Split({self.name}: fit {', '.join(self.fitted)} | judge {', '.join(self.judged)})"

    def to_dict(self) -> dict:
        return {"name": self.name, "rule": self.rule, "fitted": list(self.fitted), "judged": list(self.judged)}

    def pick(self, items: list, names: list[str]) -> tuple[list, list]:
        """`items` (one per name in `names`) as (fitted, judged), in the split's order."""
        by_name = dict(zip(names, items))
        missing = [n for n in self.fitted + self.judged if n not in by_name]
        if missing:
            raise TwinError(f"split {self.name}: no recording named {', '.join(missing)}")
        return [by_name[n] for n in self.fitted], [by_name[n] for n in self.judged]


def _input_magnitude(prep: Prepared) -> np.ndarray:
    """Per sample, how hard the inputs drive: the larger thruster's |PWM − neutral| (µs), or the
    propeller's |n| (rps) for a propeller-and-rudder ship."""
    if prep.input_kind == "propeller_rudder":
        return np.abs(prep.pwm[:, 0])
    return np.max(np.abs(prep.pwm - np.asarray(prep.pwm_neutral_us)), axis=1)


def _idle_level(prep: Prepared) -> float:
    return IDLE_RPS if prep.input_kind == "propeller_rudder" else IDLE_PWM_US


def activities(preps: list[Prepared]) -> list[RunActivity]:
    """Each run's activity (RunActivity), the turning threshold pooled over all of them."""
    if not preps:
        raise TwinError("no recordings to rank")
    yaw = np.concatenate([np.abs(p.r[np.isfinite(p.r)]) for p in preps])
    if not len(yaw):
        raise TwinError("no yaw rate in the recordings: runs cannot be ranked by how much they turn")
    turning = float(np.percentile(yaw, TURNING_PERCENTILE))
    out = []
    for p in preps:
        drive = _input_magnitude(p)
        speed = np.hypot(p.u, p.v)
        r = np.abs(p.r)
        out.append(RunActivity(log_name(p.settings.source), float(np.mean(drive > _idle_level(p))),
                               float(np.mean(r > turning)), turning, float(np.nanpercentile(speed, 95)),
                               float(np.nanpercentile(r, 95)), float(np.nanpercentile(drive, 95))))
    return out


def _ranks(x: np.ndarray) -> np.ndarray:
    """Ranks 0..n-1 with ties sharing their mean rank."""
    order = np.argsort(x, kind="stable")
    ranks = np.empty(len(x))
    ranks[order] = np.arange(len(x), dtype=float)
    for value in np.unique(x):
        tied = x == value
        ranks[tied] = ranks[tied].mean()
    return ranks


def activity_order(acts: list[RunActivity]) -> list[str]:
    """Log names from the least to the most active: by the mean of the ranks of the share under way
    and the share turning (ties by the turning share, then by name)."""
    under = _ranks(np.array([a.under_way_share for a in acts]))
    turn = _ranks(np.array([a.turning_share for a in acts]))
    score = (under + turn) / 2.0
    keyed = sorted(zip(score, [a.turning_share for a in acts], [a.log for a in acts]))
    return [name for _, _, name in keyed]


def group_order(preps: list[Prepared], windows: list, groups: np.ndarray) -> list[int]:
    """The groups of `windows` (held-out groups: runs or time blocks of runs) from the least to the
    most active, by the samples their windows cover, ranked as `activity_order` ranks runs."""
    yaw = np.concatenate([np.abs(p.r[np.isfinite(p.r)]) for p in preps])
    turning = float(np.percentile(yaw, TURNING_PERCENTILE)) if len(yaw) else np.inf
    ids = sorted({int(g) for g in groups})
    under, turn = [], []
    for g in ids:
        drive, r = [], []
        for w, gw in zip(windows, groups):
            if gw == g:
                p, sl = preps[w.rec], slice(w.start, w.start + w.n + 1)
                drive.append(_input_magnitude(p)[sl] > _idle_level(p))
                r.append(np.abs(p.r[sl]) > turning)
        under.append(float(np.mean(np.concatenate(drive))))
        turn.append(float(np.mean(np.concatenate(r))))
        del drive, r
    score = (_ranks(np.array(under)) + _ranks(np.array(turn))) / 2.0
    return [g for _, _, g in sorted(zip(score, turn, ids))]


def by_activity(preps: list[Prepared], n_fitted: int | None = None) -> Split:
    """The `n_fitted` least active runs fitted (default: half, rounded down), the others judged."""
    if len(preps) < 2:
        raise TwinError("an extrapolation split needs at least two recordings")
    n = len(preps) // 2 if n_fitted is None else int(n_fitted)
    if not 1 <= n < len(preps):
        raise TwinError(f"n_fitted must lie in 1..{len(preps) - 1}, got {n_fitted}")
    order = activity_order(activities(preps))
    return Split("by activity", f"the {n} least active runs (share of time under way, share turning above the "
                 f"pooled {TURNING_PERCENTILE:g}th percentile of |r|) fitted, the {len(preps) - n} most active judged",
                 tuple(order[:n]), tuple(order[n:]))


def by_input_level(preps: list[Prepared], max_fitted: float) -> Split:
    """Runs whose input magnitude never exceeds `max_fitted` (µs from neutral, or rps) fitted, the
    runs that exceed it judged."""
    peak = {log_name(p.settings.source): float(np.nanmax(_input_magnitude(p))) for p in preps}
    fitted = tuple(sorted(n for n, x in peak.items() if x <= max_fitted))
    judged = tuple(sorted(n for n, x in peak.items() if x > max_fitted))
    if not fitted or not judged:
        raise TwinError(f"no split at input level {max_fitted:g}: every run is on one side (peaks "
                        f"{min(peak.values()):g} to {max(peak.values()):g})")
    unit = "rps" if preps[0].input_kind == "propeller_rudder" else "µs from neutral"
    return Split(f"input ≤ {max_fitted:g} {unit.split()[0]}", f"runs whose inputs never exceed {max_fitted:g} {unit} fitted, the runs "
                 "beyond judged", fitted, judged)


def low_input_stretches(prep: Prepared, max_level: float, min_length_s: float) -> list[tuple[float, float]]:
    """The stretches (start, end s on the log's clock) of at least `min_length_s` in which the inputs
    never exceed `max_level` (µs from neutral, or rps) and no sample is missing: the slow parts of
    runs that also go faster, to fit a twin that is then judged at the higher inputs."""
    if not min_length_s > 0:
        raise TwinError(f"a stretch must last more than 0 s, got {min_length_s:g}")
    low = _input_magnitude(prep) <= max_level
    out = []
    for seg in prep.segments:
        t, ok = prep.t[seg.slice], low[seg.slice]
        edges = np.flatnonzero(np.diff(np.r_[0, ok.astype(int), 0]))
        for a, b in zip(edges[::2], edges[1::2]):
            if t[b - 1] - t[a] >= min_length_s:
                out.append((float(t[a]), float(t[b - 1])))
    return out


def by_family(names: list[str], fitted_prefix: str) -> Split:
    """Runs whose log names start with `fitted_prefix` fitted, the others judged."""
    fitted = tuple(sorted(n for n in names if n.startswith(fitted_prefix)))
    judged = tuple(sorted(n for n in names if not n.startswith(fitted_prefix)))
    if not fitted or not judged:
        raise TwinError(f"no split by family '{fitted_prefix}': every run is on one side")
    return Split(f"{fitted_prefix} → other", f"runs named {fitted_prefix}* fitted, the others judged", fitted, judged)


def by_day(names: list[str], fitted_day: str, family: str = "") -> Split:
    """Runs whose log names start with `family` and carry `fitted_day` (a date as the names write
    it, e.g. "14-Sep-2020") fitted, the family's other runs judged; other families left out."""
    among = [n for n in names if n.startswith(family)]
    fitted = tuple(sorted(n for n in among if fitted_day in n))
    judged = tuple(sorted(n for n in among if fitted_day not in n))
    if not fitted or not judged:
        raise TwinError(f"no split by day '{fitted_day}' among runs named {family or ''}*: every such run is on one side")
    what = f"runs named {family}*" if family else "runs"
    return Split(f"{fitted_day} → other days", f"{what} of {fitted_day} fitted, those of other days judged",
                 fitted, judged)
