"""Judging a model by what it predicts (seed 004 eqs. 40-41, R² and MAE per DOF):

  one_step       ν̂(k+1) from the measured state at k (what seed 004 reports; the
                 persistence model ν(k+1) = ν(k) already scores R² ≈ 0.99 on it)
  free_run_10s   free runs of 10 s from measured states, driven by the recorded PWM
  free_run_30s   the same over 30 s
  full           each whole trajectory segment from its first measured state

Every model is a predictor with `predict_windows(prep, starts, n_steps) -> (W, n+1, 3)`
(ν̂ with index 0 the measured start): the grey-box models of seed 004 implement it,
and `TwinPredictor` wraps a vessel description on the batch engine.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..prepare import Prepared
from ..vessel import Vessel
from .metrics import DOFS, r2_mae
from .windows import ModelCache, Window, make_windows, measured, predict

HORIZONS = {"one_step": None, "free_run_10s": 10.0, "free_run_30s": 30.0, "full": "segment"}


class Predictor(Protocol):
    def predict_windows(self, prep: Prepared, starts: np.ndarray, n_steps: int) -> np.ndarray: ...


@dataclass
class TwinPredictor:
    """A vessel description as a predictor: free runs on the batch engine."""

    vessel: Vessel
    cache: ModelCache | None = None
    wind: str | None = None  # "measured": each recording's wind stream a known input (windows.predict)

    def predict_windows(self, prep: Prepared, starts: np.ndarray, n_steps: int) -> np.ndarray:
        wins = [Window(0, int(s), _steps_in_segment(prep, int(s), n_steps)) for s in starts]
        out = np.full((len(wins), n_steps + 1, 3), np.nan)
        keep = [i for i, w in enumerate(wins) if w.n > 0]
        if keep:
            pred = predict(self.vessel, [prep], [wins[i] for i in keep], self.cache, wind=self.wind)[0]
            nu = pred.nu.copy()
            for j, _ in pred.diverged:  # a twin that blew up is a failure, not a gap
                w = wins[keep[j]]
                nu[j, : w.n + 1] = np.where(np.isnan(nu[j, : w.n + 1]), np.inf, nu[j, : w.n + 1])
            out[keep, : nu.shape[1]] = nu
        return out


def _steps_in_segment(prep: Prepared, start: int, n_steps: int) -> int:
    seg = prep.segments[int(prep.segment[start])]
    return min(n_steps, seg.stop - 1 - start)


def horizon_windows(preps: list[Prepared], horizon, stride_s: float) -> list[Window]:
    if horizon is None:
        return make_windows(preps, 0.1, 0.1, min_length_s=0.1) if preps else []
    if horizon == "segment":
        return make_windows(preps, None)
    return make_windows(preps, float(horizon), stride_s, min_length_s=float(horizon))


def evaluate(model: Predictor | Vessel, preps: list[Prepared], stride_s: float = 2.0,
             horizons: dict | None = None, wind: str | None = None) -> dict:
    """Metrics per horizon (see the module docstring): {horizon: {u, v, r: {r2, mae, n}}}.

    Only the predicted samples count (not the measured start of each window); a free
    run of a given horizon uses full-length windows only, so every horizon is what its
    name says. wind "measured": a vessel's free runs take each recording's measured wind."""
    if isinstance(model, Vessel):
        model = TwinPredictor(model, ModelCache(), wind)
    out = {}
    for name, horizon in (horizons or HORIZONS).items():
        wins = horizon_windows(preps, horizon, stride_s)
        if not wins:
            out[name] = {d: {"r2": None, "mae": None, "n": 0, "diverged": 0} for d in DOFS}
            continue
        pred, meas = _predictions(model, preps, wins)
        out[name] = r2_mae(pred[:, 1:], meas[:, 1:])
    return out


def error_growth(model: Predictor | Vessel, preps: list[Prepared], horizon_s: float, stride_s: float = 2.0,
                 wind: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """How the free-run error grows, window by window: (W, 2) mean inputs of each window (PWM µs, or
    n rps and δ rad) and (W, 3) the change of the prediction's error (predicted − measured) of u, v,
    r from its start to its end. An error that grows the same way whenever some input does the same
    is a force the twin lacks there (a start error decays; a missing force builds). `wind` applies
    to a Vessel given as the model (a Predictor carries its own)."""
    if isinstance(model, Vessel):
        model = TwinPredictor(model, ModelCache(), wind)
    wins = horizon_windows(preps, horizon_s, stride_s)
    if not wins:
        return np.zeros((0, 2)), np.zeros((0, 3))
    pred, meas = _predictions(model, preps, wins)
    err = pred - meas
    inputs = np.array([preps[w.rec].pwm[w.start:w.start + w.n + 1].mean(axis=0) for w in wins])
    growth = np.array([err[j, w.n] - err[j, 0] for j, w in enumerate(wins)])
    return inputs, growth


# what a window's inputs do, for `misfit_by_manoeuvre`
MANOEUVRES = ("idle", "ahead", "turning", "spin", "astern")
POWERED_SHARE = 0.1  # of full thrust (or of the propeller's top speed): below it a thruster idles
TURNING_RUDDER_DEG = 10.0  # a propeller-and-rudder ship turns beyond this rudder angle
TURNING_THRUST_SHARE = 0.5  # twin thrusters turn when one delivers less than half the other's thrust


def manoeuvres(vessel: Vessel, inputs: np.ndarray) -> np.ndarray:
    """What each sample's inputs (PWM µs per thruster, or n rps and δ rad) ask of the vessel: one of
    MANOEUVRES per row, from the thrust map alone (no state): idle (no thruster above POWERED_SHARE
    of full thrust), spin (both, opposite ways), astern (net thrust backwards), turning (one
    thruster below TURNING_THRUST_SHARE of the other; a rudder beyond TURNING_RUDDER_DEG), else
    ahead."""
    x = np.asarray(inputs, float).reshape(-1, 2)
    th = vessel.thrusters
    names = np.array(MANOEUVRES)
    if th.kind == "propeller_rudder":
        top = th.rps_max if th.rps_max else np.nanmax(np.abs(x[:, 0]), initial=0.0)
        idle = np.abs(x[:, 0]) <= POWERED_SHARE * top
        turning = np.abs(np.degrees(x[:, 1])) > TURNING_RUDDER_DEG
        code = np.where(idle, 0, np.where(x[:, 0] < 0.0, 4, np.where(turning, 2, 1)))
        return names[code]
    thrust = th.thrust_from_pwm(x) if th.kind == "t200" else x
    full = max((abs(b) for b in th.bounds() if np.isfinite(b)), default=0.0) or \
        float(np.nanmax(np.abs(thrust), initial=0.0))
    on = np.abs(thrust) > POWERED_SHARE * full
    left, right = thrust[:, 0], thrust[:, 1]
    spin = on.all(axis=1) & (np.sign(left) != np.sign(right))
    weak, strong = np.minimum(np.abs(left), np.abs(right)), np.maximum(np.abs(left), np.abs(right))
    turning = weak < TURNING_THRUST_SHARE * strong
    code = np.where(~on.any(axis=1), 0, np.where(spin, 3, np.where(left + right < 0.0, 4, np.where(turning, 2, 1))))
    return names[code]


def misfit_by_manoeuvre(model: Predictor | Vessel, preps: list[Prepared], vessel: Vessel, horizon_s: float,
                        stride_s: float = 2.0, wind: str | None = None) -> dict:
    """Where a free run's misfit lies: the windows of `horizon_s` grouped by what their inputs do
    (each window's most frequent of `manoeuvres`), and per group the share of the pooled misfit of
    u, v, r: Σ(predicted − measured)² over its predicted samples divided by the pooled Σ(measured −
    mean)² of all windows, so the shares add up to 1 − R² (evaluate's pooled R², finite windows).
    {"windows", "diverged", "groups": {manoeuvre: {"windows", "samples", "share": {u, v, r}}}}; a
    window whose prediction blew up is counted in "diverged" and in no share. `vessel` classifies
    the inputs (for a grey-box predictor, the vessel whose thrusters it is driven by)."""
    if isinstance(model, Vessel):
        model = TwinPredictor(model, ModelCache(), wind)
    wins = horizon_windows(preps, horizon_s, stride_s)
    out: dict = {"windows": len(wins), "diverged": 0, "groups": {}}
    if not wins:
        return out
    pred, meas = _predictions(model, preps, wins)
    pred, meas = pred[:, 1:], meas[:, 1:]
    finite = ~np.any(np.isinf(pred), axis=(1, 2))
    out["diverged"] = int(np.sum(~finite))
    pairs = np.isfinite(meas) & ~np.isnan(pred) & finite[:, None, None]
    y = np.where(pairs, meas, np.nan)
    total = np.nansum((y - np.nanmean(y.reshape(-1, 3), axis=0)) ** 2, axis=(0, 1))
    sq = np.where(pairs, (pred - meas) ** 2, 0.0)
    kind = []
    for w in wins:
        labels, counts = np.unique(manoeuvres(vessel, preps[w.rec].pwm[w.start:w.start + w.n + 1]),
                                   return_counts=True)
        kind.append(max(zip(counts, [-MANOEUVRES.index(lab) for lab in labels]))[1])
    kind = -np.array(kind)
    for i, name in enumerate(MANOEUVRES):
        sel = (kind == i) & finite
        if sel.any():
            sse = sq[sel].sum(axis=(0, 1))
            out["groups"][name] = {"windows": int(sel.sum()), "samples": int(pairs[sel].any(axis=2).sum()),
                                   "share": {d: float(sse[k] / total[k]) if total[k] > 0 else None
                                             for k, d in enumerate(DOFS)}}
    return out


def _predictions(model: Predictor, preps: list[Prepared], wins: list[Window]) -> tuple[np.ndarray, np.ndarray]:
    n_max = max(w.n for w in wins)
    pred = np.full((len(wins), n_max + 1, 3), np.nan)
    by_rec: dict[int, list[int]] = {}
    for j, w in enumerate(wins):
        by_rec.setdefault(w.rec, []).append(j)
    for rec, rows in by_rec.items():
        # windows of one length at a time, so a predictor never runs past what is asked
        for n in sorted({wins[j].n for j in rows}):
            same = [j for j in rows if wins[j].n == n]
            got = model.predict_windows(preps[rec], np.array([wins[j].start for j in same]), n)
            pred[same, : n + 1] = got[:, : n + 1]
    _, meas = measured(preps, wins)
    return pred, meas


def format_by_manoeuvre(split: dict, title: str = "") -> str:
    """misfit_by_manoeuvre's groups as rows: windows and each DOF's share of 1 − R², ≤ 100 columns."""
    head = f"{'manoeuvre':10s}{'windows':>9s}" + "".join(f"{'share ' + d:>10s}" for d in DOFS)
    lines = ([title] if title else []) + [head, "-" * len(head)]
    for name in MANOEUVRES:
        g = split["groups"].get(name)
        if g is not None:
            shares = ["-" if g["share"][d] is None else f"{g['share'][d]:.3f}" for d in DOFS]
            lines.append(f"{name:10s}{g['windows']:9d}" + "".join(f"{x:>10s}" for x in shares))
    if split.get("diverged"):
        lines.append(f"{split['diverged']} windows diverged and are in no group")
    return "\n".join(lines)


def format_metrics(metrics: dict, title: str = "") -> str:
    """Rows per horizon, R² and MAE per DOF, ≤ 100 columns."""
    head = f"{'horizon':14s}" + "".join(f"{'R2 ' + d:>9s}{'MAE ' + d:>10s}" for d in DOFS)
    lines = ([title] if title else []) + [head, "-" * len(head)]
    for name, m in metrics.items():
        cells = []
        for d in DOFS:
            r2, mae = m[d]["r2"], m[d]["mae"]
            cells.append(f"{'-' if r2 is None else f'{r2:.3f}':>9s}{'-' if mae is None else f'{mae:.4f}':>10s}")
        lines.append(f"{name:14s}" + "".join(cells))
    return "\n".join(lines)
