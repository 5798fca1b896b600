"""Judging a fit's choices on runs left out of it, each predicted by a twin fitted on runs that go
less far than it does.

Every choice identification makes (how strongly to believe the prior, which coefficients to
free) is judged by how a twin fitted WITHOUT a run predicts THAT run, run by run. The runs are
ranked by how far they go (extrapolation.group_order: time under way, time turning), and the twin
that predicts a run is fitted on the runs ranked below it only (`beyond_folds`): a run left out at
random is like the runs fitted and proves interpolation, while a twin is wanted beyond its runs,
so a choice is judged where the twin extrapolates. `each_folds` is plain leave one run out. With fewer
than MIN_RUNS recordings, blocks of consecutive windows (BLOCKS per recording) stand in for runs:
an honest second best, since blocks of one log share its conditions. Refitting
from scratch for every left-out run would cost as many fits as runs; instead each refit is one
Gauss-Newton step from the fit on all runs, using the Jacobian the fit already has (an
approximate jackknife, exact for a model linear in its coordinates): θ₋ₖ = θ̂ + Δ with
Δ = argmin |r₋ₖ + J₋ₖΔ|² (the prior's rows kept). The left-out run is then predicted by real
free runs of the twin θ₋ₖ from its measured states, as `twin evaluate` does: the score is never
linearised.

A run's score: R² and MAE per DOF of 10-s free runs (fit/metrics.py), and its cost, the sum of
squared errors over the DOFs, each divided by the spread of that DOF's measurements in all
the runs (so runs add up and DOFs weigh alike).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..physics.kinematics import wrap_angle
from ..physics.sensors import log_name
from ..prepare import Prepared
from ..vessel import Vessel
from .extrapolation import group_order
from .metrics import DOFS, r2_mae
from .windows import ModelCache, Window, as_measured, make_windows, measured, predict

MIN_RUNS = 3
BLOCKS = 4
# a free run past this speed (m/s, or rad/s of yaw) has run away, though it stays below MuJoCo's
# own divergence bound (1e10): scored as its finite error it would swamp every other run's cost
RUNAWAY = 1e3


def held_out_groups(windows: list[Window], preps: list[Prepared]) -> tuple[np.ndarray, list[str]]:
    """The group each window is left out with, and the groups' names: its recording, or with
    fewer than MIN_RUNS recordings a time block of it (BLOCKS per recording, by the window's
    start time, so that any set of windows of the same recordings gets the same blocks)."""
    recs = np.array([w.rec for w in windows])
    if len(preps) >= MIN_RUNS:
        return recs, [log_name(p.settings.source) for p in preps]
    blocks = np.array([min(BLOCKS - 1, int(BLOCKS * (preps[w.rec].t[w.start] - preps[w.rec].t[0])
                                          / max(preps[w.rec].t[-1] - preps[w.rec].t[0], 1e-9))) for w in windows])
    names = [f"{log_name(p.settings.source)} part {b + 1}" for p in preps for b in range(BLOCKS)]
    return recs * BLOCKS + blocks, names


def beyond_folds(windows: list[Window], preps: list[Prepared], groups: np.ndarray) -> list[np.ndarray]:
    """Per group k, the groups left out of the twin that predicts k: k and every group that goes at
    least as far as k (extrapolation.group_order), so the twin is fitted on the groups below k."""
    order = group_order(preps, windows, groups)
    rank = {g: i for i, g in enumerate(order)}
    n = int(groups.max()) + 1
    return [np.array(sorted(g for g in order if rank[g] >= rank[k])) if k in rank else np.array([k])
            for k in range(n)]


def each_folds(groups: np.ndarray) -> list[np.ndarray]:
    """Per group k, only k left out (leave one run out)."""
    return [np.array([k]) for k in range(int(groups.max()) + 1)]


def reweighted(obj, x: np.ndarray, J: np.ndarray, r: np.ndarray, factor: float
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The fit's linearisation with its beliefs counted `factor` times as much, solved: (x, J, r)
    of the maximum a posteriori solution for that weight, one Gauss-Newton step from the fit."""
    n = obj.n_data
    J2, r2 = J.copy(), r.copy()
    J2[n:] *= np.sqrt(factor)
    r2[n:] *= np.sqrt(factor)
    lo, hi = obj.bounds()
    x2 = np.clip(x + np.linalg.lstsq(J2, -r2, rcond=None)[0], lo, hi)
    return x2, J2, r2 + J2 @ (x2 - x)


@dataclass
class RunScore:
    """How the twin fitted without one run predicts it."""

    log: str
    metrics: dict  # {u, v, r: {r2, mae, n}}
    cost: float

    def to_dict(self) -> dict:
        return {"log": self.log, "cost": self.cost, "metrics": self.metrics}


@dataclass
class CrossValidation:
    """One configuration's leave-one-run-out scores."""

    label: str
    runs: list[RunScore] = field(default_factory=list)
    pooled: dict = field(default_factory=dict)  # {u, v, r: {r2, mae, n}} over every left-out sample together

    @property
    def cost(self) -> float:
        return float(sum(r.cost for r in self.runs))

    def spread(self, dof: str) -> tuple[float, float, float] | None:
        """(median, lowest, highest) R² of one DOF over the runs."""
        values = [r.metrics[dof]["r2"] for r in self.runs if r.metrics[dof]["r2"] is not None]
        if not values:
            return None
        return float(np.median(values)), float(np.min(values)), float(np.max(values))

    def to_dict(self) -> dict:
        return {"label": self.label, "cost": self.cost, "runs": [r.to_dict() for r in self.runs],
                "r2_median_min_max": {d: self.spread(d) for d in DOFS}, "pooled": self.pooled}

    def summary(self) -> str:
        parts = []
        for d in DOFS:
            s = self.spread(d)
            parts.append(f"{d} {s[0]:.2f} ({s[1]:.2f} to {s[2]:.2f})" if s else f"{d} -")
        pooled = ", ".join(f"{d} {self.pooled[d]['r2']:.2f}" for d in DOFS
                           if self.pooled.get(d, {}).get("r2") is not None)
        # fewer recordings than MIN_RUNS: the left-out groups are time blocks of them (held_out_groups)
        unit = "part" if self.runs and all(" part " in r.log for r in self.runs) else "run"
        # a short part's own spread is small, so its R² runs below the pooled one and below a whole log's
        return (f"{self.label}: R² on left-out {unit}s, all together: {pooled}; {unit} by {unit}, median (range): "
                + ", ".join(parts) + f" (each {unit} against its own spread: lower than all together)")


def jackknife_vessels(obj, x: np.ndarray, J: np.ndarray, r: np.ndarray, groups: np.ndarray,
                      fixed: np.ndarray | None = None, at: np.ndarray | None = None,
                      folds: list[np.ndarray] | None = None) -> list[Vessel]:
    """θ₋ₖ for each held-out group k of the objective's windows (module docstring), as vessels:
    fitted without the groups folds[k] (default: k alone), one per fold: a group none of whose windows
    the objective fits (all idle) gets the twin fitted on every window. fixed: coordinates held at `at`
    (default: the prior) instead of refitted; the step then starts by moving them there."""
    n = obj.n_data
    runs = groups[obj.window_index()]
    free = np.ones(len(x), bool) if fixed is None else ~np.asarray(fixed, bool)
    target = obj.x_prior if at is None else at
    base = x.copy()
    base[~free] = target[~free]
    shift = (base - x)
    r0 = r + J @ shift  # linearised residuals with the fixed coordinates moved
    lo, hi = obj.bounds()
    out = []
    folds = folds if folds is not None else each_folds(groups)
    for k in range(len(folds)):
        keep = np.ones(len(r), bool)
        keep[:n] = ~np.isin(runs, folds[k])
        delta = np.zeros(len(x))
        if free.any():
            delta[free] = np.linalg.lstsq(J[keep][:, free], -r0[keep], rcond=None)[0]
        out.append(obj.vessel(np.clip(base + delta, lo, hi)))
    return out


def judge(configurations: dict[str, list[Vessel]], preps: list[Prepared], windows: list[Window],
          groups: np.ndarray, names: list[str], sigma: np.ndarray, cache: ModelCache | None = None,
          wind: str | None = None) -> dict[str, CrossValidation]:
    """Each configuration's twins (one per group, fitted without it) predicting their own group's
    windows by free runs from measured states; every configuration of one group in one batch
    (wind "measured": with each recording's measured wind, windows.predict)."""
    cache = cache or ModelCache()
    out = {label: CrossValidation(label) for label in configurations}
    labels = list(configurations)
    pairs = {label: ([], []) for label in labels}
    for k, name in enumerate(names):
        mine = [w for w, g in zip(windows, groups) if g == k]
        if not mine:
            continue
        predictions = predict([configurations[lb][k] for lb in labels], preps, mine, cache, wind=wind)
        _, meas = measured(preps, mine)
        for label, pred in zip(labels, predictions):
            nu = pred.nu_failed_as_inf()
            out[label].runs.append(score_run(name, nu[:, 1:], meas[:, 1:], sigma))
            pairs[label][0].append(nu[:, 1:].reshape(-1, 3))
            pairs[label][1].append(meas[:, 1:].reshape(-1, 3))
    for label, (pred, meas) in pairs.items():
        if pred:
            out[label].pooled = r2_mae(np.concatenate(pred), np.concatenate(meas))
    return out


def score_run(log: str, pred: np.ndarray, meas: np.ndarray, sigma: np.ndarray) -> RunScore:
    """R²/MAE per DOF and the σ-scaled squared error of one run's free runs (a free run beyond
    RUNAWAY counts as diverged)."""
    pred = np.where(np.abs(pred) > RUNAWAY, np.inf, pred)
    metrics = r2_mae(pred, meas)
    err = (pred - meas) / sigma
    ok = np.isfinite(meas)
    diverged = np.isinf(pred) & ok
    cost = float(np.sum(np.where(ok & ~diverged, err, 0.0) ** 2) + 100.0 * np.sum(diverged))
    return RunScore(log, metrics, cost)


FORM_QUANTITIES = ("north", "east", "psi", "u", "v", "r", "deviation")
FORM_LEVELS = (0.5, 0.68, 0.8, 0.9, 0.95, 0.99)


def form_error(fold_vessels: list[Vessel], preps: list[Prepared], folds_label: str, horizon_s: float = 30.0,
               sample_dt_s: float = 1.0, cache: ModelCache | None = None, wind: str | None = None) -> dict:
    """How far free runs of the twins fitted without each group miss that group: per quantity
    (north, east m; psi rad; u, v m/s; r rad/s; deviation m) and horizon into the run, the
    quantiles FORM_LEVELS of |measured − predicted| over non-overlapping windows of horizon_s, every
    sample_dt_s (velocities through the recording's own smoother, as a band compares them).

    This is the twin's error where it was not fitted, form error and all: what a prediction band
    must add to the spread of its parameters. `fold_vessels[k]` predicts group k (held_out_groups
    of the windows); `folds_label` says how the folds were chosen."""
    windows = make_windows(preps, horizon_s, horizon_s, min_length_s=horizon_s)
    if not windows:
        return {}
    groups, _ = held_out_groups(windows, preps)
    every = max(1, int(round(sample_dt_s / preps[0].settings.grid_dt)))
    cache = cache or ModelCache()
    errors = []
    for k in range(int(groups.max()) + 1):
        mine = [w for w, g in zip(windows, groups) if g == k]
        if not mine or k >= len(fold_vessels):
            continue
        pred = predict(fold_vessels[k], preps, mine, cache, wind=wind)[0]
        eta_m, nu_m = measured(preps, mine)
        nu_p = as_measured(pred.nu, preps, mine)
        d_pos = eta_m[..., :2] - pred.eta[..., :2]
        d_psi = wrap_angle(eta_m[..., 2] - pred.eta[..., 2])
        e = np.concatenate([d_pos, d_psi[..., None], nu_m - nu_p, np.hypot(*np.moveaxis(d_pos, -1, 0))[..., None]],
                           axis=-1)
        for j, _ in pred.diverged:
            e[j] = np.nan
        errors.append(np.abs(e[:, ::every]))
    if not errors:
        return {}
    e = np.concatenate(errors)  # (W, S, 7)
    t = preps[0].settings.grid_dt * every * np.arange(e.shape[1])
    quantiles = {}
    for i, q in enumerate(FORM_QUANTITIES):
        col = e[..., i]
        quantiles[q] = [[float(np.nanquantile(col[:, s], lv)) if np.isfinite(col[:, s]).any() else 0.0
                         for lv in FORM_LEVELS] for s in range(e.shape[1])]
    return {"horizon_s": [float(x) for x in t], "levels": list(FORM_LEVELS), "quantiles": quantiles,
            "windows": int(e.shape[0]), "judged_on": folds_label}


def form_error_at(block: dict, quantity: str, level: float, t_s: np.ndarray) -> np.ndarray:
    """|error| of `quantity` at `level` at horizons t_s (s). The level is raised to the finite-sample
    quantile of split conformal prediction, ⌈(n + 1)·level⌉/n over the block's n windows (a
    quantile of a few windows understates the next window's error), then interpolated between the
    stored levels (at most the highest). Within the stored horizons interpolated; beyond them a
    velocity's holds its last value (a damped twin's velocity error stops growing) and a
    position's or heading's grows on at its last slope (it integrates the velocity error)."""
    n = int(block.get("windows", 0))
    if n > 0:
        level = min(1.0, math.ceil((n + 1) * level) / n)
    levels = np.asarray(block["levels"], float)
    table = np.asarray(block["quantiles"][quantity], float)  # (S, L)
    at_level = np.array([np.interp(level, levels, row) for row in table])
    h = np.asarray(block["horizon_s"], float)
    t = np.asarray(t_s, float)
    out = np.interp(t, h, at_level)
    beyond = t > h[-1]
    if beyond.any() and quantity in ("north", "east", "psi", "deviation") and len(h) > 1:
        slope = (at_level[-1] - at_level[-2]) / (h[-1] - h[-2])
        out[beyond] = at_level[-1] + max(slope, 0.0) * (t[beyond] - h[-1])
    return out
