"""Free-run (multi-step) simulation of an identified discrete model from measured
states: the test the project judges models by, where one-step predictors that
look excellent can drift or diverge (the static model of [Morel-2024 Table 10] does)."""
from __future__ import annotations

from typing import Any, Callable

import numpy as np

from ...errors import TwinError

DIVERGED = 1e3  # |ν̂| (m/s, rad/s) beyond which a free run is marked diverged (+inf)

Step = Callable[[np.ndarray, np.ndarray, Any], tuple[np.ndarray, Any]]


def free_run(nu: np.ndarray, pair: np.ndarray, starts, n_steps: int, step: Step, state0: Any = None) -> np.ndarray:
    """Windows of ν̂ (n_windows, n_steps + 1, 3) from the measured nu[starts].

    step(ν̂ (w, 3), k (w,), state) → (ν̂ at k+1, state) advances every window by one
    sample. pair[k] is True when k → k+1 stays inside a segment. A window turns NaN
    where its next sample leaves the segment (or the model gives NaN, e.g. a region
    it was not identified for) and +inf once |ν̂| exceeds DIVERGED, so that a diverged
    run scores as a failure, not as a gap.
    """
    starts = np.asarray(starts, int).reshape(-1)
    n = len(nu)
    if n_steps < 0:
        raise TwinError(f"n_steps must be ≥ 0, got {n_steps}")
    if np.any((starts < 0) | (starts >= n)):
        raise TwinError(f"window starts must lie in 0..{n - 1}")
    out = np.full((len(starts), n_steps + 1, 3), np.nan)
    if not len(starts):
        return out
    state = state0
    current = nu[starts].astype(float)
    out[:, 0] = current
    alive = np.ones(len(starts), bool)
    diverged = np.zeros(len(starts), bool)
    with np.errstate(over="ignore", invalid="ignore"):
        for i in range(n_steps):
            k = np.minimum(starts + i, n - 1)
            alive &= (starts + i + 1 < n) & pair[k]
            current, state = step(current, k, state)
            diverged |= alive & np.any(np.abs(current) > DIVERGED, axis=1)
            out[:, i + 1] = np.where(alive[:, None], current, np.nan)
            out[diverged & alive, i + 1] = np.inf
    return out
