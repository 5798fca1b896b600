"""How well a prediction matches a measurement, per DOF [Morel-2024 eqs. 40-41]: R² and the mean
absolute error, over the finite pairs; a diverged (infinite) prediction is a failure, not a gap."""
from __future__ import annotations

import math

import numpy as np

DOFS = ("u", "v", "r")


# what no GNSS or compass resolves (m/s, m/s, rad/s): a velocity whose whole spread (standard
# deviation) is under it has no variance for an R² to explain (a straight run's sway, varying by
# round-off, gave R² −1.6e15), and a misfit under it is the replay's own arithmetic
RESOLUTION = {"u": 1e-3, "v": 1e-3, "r": 1e-4}


def r2_score(truth: np.ndarray, predicted: np.ndarray, no_spread: float = 0.0) -> float:
    """Eq. 40 over the finite pairs; NaN with fewer than two, or where the truth's standard deviation is
    not above `no_spread` (no variance to explain)."""
    ok = np.isfinite(truth) & ~np.isnan(predicted)
    y, p = truth[ok], predicted[ok]
    if len(y) < 2:
        return math.nan
    total = float(np.sum((y - y.mean()) ** 2))
    if total == 0.0 or math.sqrt(total / len(y)) <= no_spread:
        return math.nan
    with np.errstate(over="ignore", invalid="ignore"):
        resid = float(np.sum((y - p) ** 2))
    return 1.0 - resid / total if np.isfinite(resid) else -math.inf


def mae(truth: np.ndarray, predicted: np.ndarray) -> float:
    """Eq. 41 over the finite pairs (a diverged, infinite prediction gives inf)."""
    ok = np.isfinite(truth) & ~np.isnan(predicted)
    return float(np.mean(np.abs(truth[ok] - predicted[ok]))) if ok.any() else math.nan


def scores(truth: np.ndarray, predicted: np.ndarray) -> dict[str, dict[str, float]]:
    """{"u": {"r2", "mae", "n"}, "v": …, "r": …} for (n, 3) arrays."""
    out = {}
    for j, dof in enumerate(DOFS):
        ok = np.isfinite(truth[:, j]) & ~np.isnan(predicted[:, j])
        out[dof] = {"r2": r2_score(truth[:, j], predicted[:, j], RESOLUTION[dof]), "mae": mae(truth[:, j], predicted[:, j]),
                    "n": int(ok.sum())}
    return out


def r2_mae(pred: np.ndarray, meas: np.ndarray) -> dict:
    """{u, v, r} → {r2, mae, n} over every pair with a measurement (the definitions of
    [Morel-2024 eqs. 40-41] in `scores`). A diverged prediction (inf) makes R² and MAE
    unbounded: they are reported as None, with `diverged` counting such samples."""
    p, m = pred.reshape(-1, 3), meas.reshape(-1, 3)
    out = scores(m, p)
    for k, dof in enumerate(DOFS):
        out[dof] = {key: (float(val) if isinstance(val, float) and np.isfinite(val) else
                          (val if isinstance(val, int) else None)) for key, val in out[dof].items()}
        out[dof]["diverged"] = int(np.sum(np.isinf(p[:, k]) & np.isfinite(m[:, k])))
    return out


def ceiling_r2(measured: np.ndarray, reference: np.ndarray) -> float:
    """The R² (eq. 40) a perfect twin would score against `measured` when the truth is `reference`
    (the same signal less its measurement noise, e.g. a derivative over a window much longer than the
    noise but shorter than the dynamics): 1 − Σ(measured − reference)² / Σ(measured − mean)². A
    target above it cannot be met by any twin against this measurement."""
    return r2_score(np.asarray(measured, float), np.asarray(reference, float))
