"""Validation of [Morel-2024 §6]: R² and MAE per DOF (eqs. 40-41), training/validation
splits by segments or by independent points (Table 3), the tables of mean and SD
over repeated splits (Tables 4, 7) and by training percentage with a fixed
validation share (Tables 5-6, 8-9), and free-run scores from measured states.

A split is a pair of per-recording boolean row masks; row k is the one-step pair
(k, k+1), so a model is trained with `fit(preps, split.train)` and scored on the
predictions ν̂(k+1) of the validation rows. Tables are plain JSON-able dicts
(None where a metric is undefined); `render_*` turn them into text no wider
than 100 columns.
"""
from __future__ import annotations

import math
import textwrap
from dataclasses import dataclass
from typing import Callable, Protocol, Sequence

import numpy as np

from ...errors import TwinError
from ...prepare.prepared import Prepared
from ...fit.metrics import scores
from . import regressors as R

METHODS = ("segments", "points")


class OneStepModel(Protocol):
    def predict_one_step(self, prep: Prepared) -> np.ndarray: ...


class FreeRunModel(Protocol):
    def predict_windows(self, prep: Prepared, starts, n_steps: int) -> np.ndarray: ...


Fit = Callable[[list[Prepared], list[np.ndarray]], OneStepModel]


def one_step_scores(model: OneStepModel, preps: Sequence[Prepared],
                    rows: Sequence[np.ndarray] | None = None) -> dict[str, dict[str, float]]:
    """Scores of ν̂(k+1) against ν(k+1) over the selected rows k of all recordings."""
    truth, predicted = one_step_pairs(model.predict_one_step, preps, rows)
    return scores(truth, predicted)


def one_step_pairs(predict: Callable[[Prepared], np.ndarray], preps: Sequence[Prepared],
                   rows: Sequence[np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Measured and predicted ν(k+1) (m, 3) stacked over the selected rows k."""
    preps = list(preps)
    rows = R.selection(preps, rows)
    truth, predicted = [], []
    for p, m in zip(preps, rows):
        k = np.flatnonzero(m[:-1])
        truth.append(R.velocities(p)[k + 1])
        predicted.append(predict(p)[k + 1])
    return np.vstack(truth), np.vstack(predicted)


# ---------------------------------------------------------------- splits (Table 3)

@dataclass(frozen=True)
class Split:
    """Training and validation row masks, one boolean array per recording."""

    method: str
    train: list[np.ndarray]
    validation: list[np.ndarray]

    @property
    def train_fraction(self) -> float:
        n_train = sum(int(m.sum()) for m in self.train)
        n_all = n_train + sum(int(m.sum()) for m in self.validation)
        return n_train / n_all if n_all else math.nan


def pieces(preps: Sequence[Prepared], piece_s: float | None = None) -> list[tuple[int, np.ndarray]]:
    """The units a split by segments draws: (recording index, row indices) per segment,
    cut into pieces of at most piece_s seconds when given (a recording of a few long
    segments otherwise leaves nothing to draw)."""
    out = []
    for i, p in enumerate(preps):
        pair = R.pair_rows(p)
        h = R.check_time_step([p])
        for seg in p.segments:
            k = np.arange(seg.start, seg.stop)
            k = k[pair[k]]
            if not len(k):
                continue
            size = len(k) if piece_s is None else max(1, int(round(piece_s / h)))
            out.extend((i, k[a:a + size]) for a in range(0, len(k), size))
    return out


def split_rows(preps: Sequence[Prepared], method: str, train: float, rng: np.random.Generator, *,
               validation: float | None = None, piece_s: float | None = None) -> Split:
    """A random split of the one-step rows (Table 3).

    method "segments": whole segments (or pieces, see `pieces`) drawn in random order;
    the cut falls where the share is closest to the target, so it is approximate.
    "points": independent random rows. validation None: the rest of the rows after
    training (train + validation = 1); otherwise a validation share is drawn first
    and training from what is left (Tables 5-6, 8-9: train 0.7, 0.6, 0.5 with 0.3).
    """
    if method not in METHODS:
        raise TwinError(f"split method must be one of {', '.join(METHODS)}, got {method!r}")
    val_share = 1.0 - train if validation is None else validation
    if not (0.0 < train < 1.0 and 0.0 < val_share < 1.0 and train + val_share <= 1.0 + 1e-9):
        raise TwinError(f"training {train:g} and validation {val_share:g} must be in (0, 1) with a sum ≤ 1")
    preps = list(preps)
    units = pieces(preps, piece_s) if method == "segments" else [
        (i, np.array([k])) for i, p in enumerate(preps) for k in np.flatnonzero(R.pair_rows(p))]
    if len(units) < 2:
        raise TwinError(f"cannot split by {method}: {len(units)} unit(s) of one-step pairs")
    order = rng.permutation(len(units))
    sizes = np.array([len(units[u][1]) for u in order])
    total = sizes.sum()
    n_val = _cut(sizes, val_share * total)
    rest = sizes[n_val:]
    n_train = len(rest) if validation is None else _cut(rest, train * total)
    val_units, train_units = order[:n_val], order[n_val:n_val + n_train]
    return Split(method, _masks(preps, units, train_units), _masks(preps, units, val_units))


def _cut(sizes: np.ndarray, target: float) -> int:
    """How many leading units bring the row count closest to target (at least one)."""
    cumulative = np.concatenate([[0], np.cumsum(sizes)])
    return int(max(1, np.argmin(np.abs(cumulative - target))))


def _masks(preps: Sequence[Prepared], units, chosen) -> list[np.ndarray]:
    masks = [np.zeros(len(p.t), bool) for p in preps]
    for u in chosen:
        i, k = units[u]
        masks[i][k] = True
    return masks


# ---------------------------------------------------------------- tables

def split_method_table(fit: Fit, preps: Sequence[Prepared], *, train: float = 0.7, repeats: int = 20,
                       seed: int = 0, methods: Sequence[str] = METHODS, piece_s: float | None = None,
                       model: str = "") -> dict:
    """Tables 4 and 7: validation MAE and R² per DOF, mean and SD over `repeats` random
    splits per method (numpy Generator seeded with `seed`). A split whose training
    rows cannot identify the model (TwinError) is counted in "failed" with its reason."""
    preps = list(preps)
    rng = np.random.default_rng(seed)
    rows = {}
    for method in methods:
        runs, failures, shares = [], [], []
        for _ in range(repeats):
            split = split_rows(preps, method, train, rng, piece_s=piece_s)
            try:
                runs.append(one_step_scores(fit(preps, split.train), preps, split.validation))
                shares.append(split.train_fraction)
            except TwinError as exc:
                failures.append(str(exc))
        rows[method] = {"mae": _mean_sd(runs, "mae"), "r2": _mean_sd(runs, "r2"),
                        "train_fraction": _stat(shares), "ok": len(runs), "failed": len(failures),
                        "first_failure": failures[0] if failures else None}
    return _json_ready({"kind": "split_methods", "model": model, "train": train, "repeats": repeats, "seed": seed,
                        "piece_s": piece_s, "rows": rows})


def training_size_table(fit: Fit, preps: Sequence[Prepared], *, trains: Sequence[float] = (0.7, 0.6, 0.5),
                        validation: float = 0.3, method: str = "points", seed: int = 0,
                        piece_s: float | None = None, model: str = "") -> dict:
    """Tables 5-6 and 8-9: for each training share, with one fixed validation share
    drawn first (same rows for every training share), MAE and R² per DOF on the
    training rows and on the validation rows."""
    preps = list(preps)
    rng = np.random.default_rng(seed)
    first = split_rows(preps, method, max(trains), rng, validation=validation, piece_s=piece_s)
    rows = []
    for share in trains:
        train_rows = _subsample(first, share / max(trains), rng, method, preps, piece_s)
        entry = {"train": share, "validation": validation}
        try:
            model_fit = fit(preps, train_rows)
            entry["train_scores"] = one_step_scores(model_fit, preps, train_rows)
            entry["validation_scores"] = one_step_scores(model_fit, preps, first.validation)
        except TwinError as exc:
            entry["error"] = str(exc)
        entry["n_train"] = int(sum(m.sum() for m in train_rows))
        entry["n_validation"] = int(sum(m.sum() for m in first.validation))
        rows.append(entry)
    return _json_ready({"kind": "training_size", "model": model, "method": method, "seed": seed,
                        "piece_s": piece_s, "rows": rows})


def _json_ready(value):
    """The same structure with NaN and ±inf (undefined or diverged metrics) as None, so
    that json.dumps gives strict JSON."""
    if isinstance(value, dict):
        return {k: _json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_ready(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _subsample(split: Split, keep: float, rng, method: str, preps, piece_s) -> list[np.ndarray]:
    """A share `keep` of split.train, drawn by the split's own unit (point or piece)."""
    if keep >= 1.0 - 1e-12:
        return [m.copy() for m in split.train]
    units = [(i, k) for i, k in (pieces(preps, piece_s) if method == "segments" else
                                 [(i, np.array([k])) for i, m in enumerate(split.train) for k in np.flatnonzero(m)])
             if split.train[i][k].all()]
    order = rng.permutation(len(units))
    n = _cut(np.array([len(units[u][1]) for u in order]), keep * sum(len(k) for _, k in units))
    return _masks(preps, units, order[:n])


def _stat(values: Sequence[float]) -> dict[str, float]:
    v = np.asarray([x for x in values if x is not None], float)
    if not len(v):
        return {"mean": math.nan, "sd": math.nan}
    return {"mean": float(np.mean(v)), "sd": float(np.std(v, ddof=1)) if len(v) > 1 else math.nan}


def _mean_sd(runs: list[dict], metric: str) -> dict[str, dict[str, float]]:
    return {dof: _stat([r[dof][metric] for r in runs]) for dof in R.DOFS}


# ---------------------------------------------------------------- free runs

def window_starts(prep: Prepared, n_steps: int, every: int) -> np.ndarray:
    """Starts every `every` samples from each segment's start whose whole window of
    n_steps stays inside the segment."""
    starts = [np.arange(s.start, s.stop - n_steps, every) for s in prep.segments]
    return np.concatenate(starts).astype(int) if starts else np.zeros(0, int)


def free_run_pairs(model: FreeRunModel, preps: Sequence[Prepared], *, horizon_s: float = 10.0,
                   every_s: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """Measured and free-run ν (m, 3) over all windows' steps 1..n (step 0 is the
    measured start): windows of horizon_s starting every every_s."""
    truth, predicted = [], []
    for p in preps:
        h = R.check_time_step([p])
        n_steps, every = int(round(horizon_s / h)), max(1, int(round(every_s / h)))
        starts = window_starts(p, n_steps, every)
        if not len(starts):
            continue
        runs = model.predict_windows(p, starts, n_steps)[:, 1:]
        idx = starts[:, None] + np.arange(1, n_steps + 1)
        truth.append(R.velocities(p)[idx].reshape(-1, 3))
        predicted.append(runs.reshape(-1, 3))
    if not truth:
        return np.zeros((0, 3)), np.zeros((0, 3))
    return np.vstack(truth), np.vstack(predicted)


def free_run_scores(model: FreeRunModel, preps: Sequence[Prepared], *, horizon_s: float = 10.0,
                    every_s: float = 2.0) -> dict:
    """R², MAE and the number of predicted points per DOF over free-run windows
    (`free_run_pairs`), plus "windows", "diverged" (windows that reached +inf: they
    make R² −inf) and "coverage" (share of window points with a prediction)."""
    truth, predicted = free_run_pairs(model, preps, horizon_s=horizon_s, every_s=every_s)
    out: dict = scores(truth, predicted)
    n_steps = max(1, int(round(horizon_s / R.check_time_step(list(preps)))))
    windows = predicted.reshape(-1, n_steps, 3) if len(predicted) else np.zeros((0, n_steps, 3))
    out["windows"] = int(len(windows))
    out["diverged"] = int(np.sum(np.isinf(windows).any(axis=(1, 2))))
    out["coverage"] = float(np.mean(~np.isnan(predicted).any(axis=1))) if len(predicted) else math.nan
    return out


# ---------------------------------------------------------------- text

def _num(x: float, width: int = 9) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "–".rjust(width)
    if math.isinf(x):
        return ("-inf" if x < 0 else "inf").rjust(width)
    return (f"{x:.6f}" if 1e-3 <= abs(x) < 100 or x == 0 else f"{x:.2e}").rjust(width)


def render_split_table(table: dict) -> str:
    """Text in the layout of Tables 4 and 7 (≤ 100 columns)."""
    title = f"{table.get('model') or 'model'}: validation by split method, train {table['train']:.0%}, " \
            f"{table['repeats']} repeats (seed {table['seed']})"
    lines = [title]
    for metric, label in (("mae", "MAE"), ("r2", "R²")):
        head = "".join(f"{label + dof:>10}{'SD' + dof:>10}" for dof in R.DOFS)
        lines.append(f"{'':<14}{head}")
        for method, row in table["rows"].items():
            cells = "".join(f"{_num(row[metric][d]['mean']):>10}{_num(row[metric][d]['sd'], 9):>10}"
                            for d in R.DOFS)
            lines.append(f"{'By ' + method:<14}{cells}")
    if any("–" in line for line in lines[1:]):
        lines.append("–: no fit of that split method scored that DOF (each failed or left it without a finite score)")
    for method, row in table["rows"].items():
        share = row["train_fraction"]["mean"]
        note = f"{method}: {row['ok']} fits, actual training share {share:.1%}" if row["ok"] else f"{method}: no fit"
        if row["failed"]:
            note += f"; {row['failed']} failed: {row['first_failure']}"
        lines += textwrap.wrap(note, 100, subsequent_indent="  ")  # whole: a cut reason says nothing
    return "\n".join(lines)


def render_training_table(table: dict) -> str:
    """Text in the layout of Tables 5-6 and 8-9 (≤ 100 columns)."""
    lines = [f"{table.get('model') or 'model'}: by training share, split by {table['method']} (seed {table['seed']})"]
    for metric, label in (("mae", "MAE"), ("r2", "R²")):
        head = "".join(f"{label + d:>10}" for d in R.DOFS)
        lines.append(f"{'Train %':>8}{head}  {'Valid. %':>8}{head}")
        for row in table["rows"]:
            if "error" in row:
                wrapped = textwrap.wrap(row["error"], 88)  # whole, in ≤ 100 columns
                lines.append(f"{row['train'] * 100:8.0f}  {wrapped[0]}")
                lines += [f"{'':10}{more}" for more in wrapped[1:]]
                continue
            tr = "".join(f"{_num(row['train_scores'][d][metric]):>10}" for d in R.DOFS)
            va = "".join(f"{_num(row['validation_scores'][d][metric]):>10}" for d in R.DOFS)
            lines.append(f"{row['train'] * 100:8.0f}{tr}  {row['validation'] * 100:8.0f}{va}")
    return "\n".join(lines)
