"""The sway equation alone, driven by the motion that was measured: how much of a recording's sway
any sway equation of a given form predicts, when the surge, the yaw rate and the thrust are not
predicted but known.

A twin's sway prediction carries its errors in surge and yaw besides the sway equation's own. Here
the sway acceleration is a sum of terms in the measured u, r, ṙ and the differential thrust ΔT, and
in the predicted v itself,

    v̇ = −θ_v·v − θ_|v|v·|v|v − θ_|u|v·|u|v + θ_ur·u·r + θ_r·r + θ_ṙ·ṙ + θ_ΔT·ΔT,

integrated over free runs from each window's measured v (the damping terms implicitly, so a stiff
fit stays stable on the recordings' grid). The coefficients θ are fitted by least squares on the
free runs' residuals. Fitted on the runs themselves, the score bounds what a twin of that sway form
could reach on them; fitted on other runs, it is that form's extrapolation with u and r given.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ..errors import TwinError
from .metrics import r2_score

# each term: (its value from v and the drivers, whether it damps: a damping coefficient is ≥ 0)
TERMS = ("v", "|v|v", "|u|v", "ur", "r", "rdot", "dT")
DAMPING_TERMS = ("v", "|v|v", "|u|v")


@dataclass(frozen=True)
class SwayDrivers:
    """One recording on its grid: u, v (m/s), r (rad/s), the differential thrust dT (N, left less
    right; zeros where not known), the segment of each sample and the grid step h_s (s)."""

    u: np.ndarray
    v: np.ndarray
    r: np.ndarray
    dT: np.ndarray
    segment: np.ndarray
    h_s: float

    @property
    def rdot(self) -> np.ndarray:
        """The yaw acceleration (rad/s²) over each grid step, forward difference (0 at the end)."""
        return np.append(np.diff(self.r) / self.h_s, 0.0)


@dataclass(frozen=True)
class SwayAloneFit:
    """The coefficients θ (per term, units of v̇ per unit of the term) and the 10-s free-run R² of v
    on the windows they were fitted on."""

    terms: tuple[str, ...]
    coefficients: dict[str, float]
    r2: float
    windows: int


def _windows(drivers: list[SwayDrivers], horizon_s: float, stride_s: float) -> list[tuple[int, int, int]]:
    """(recording, start, steps) of every free run inside one segment with every sample finite."""
    out = []
    for i, d in enumerate(drivers):
        n, every = int(round(horizon_s / d.h_s)), max(1, int(round(stride_s / d.h_s)))
        ok = np.isfinite(d.u) & np.isfinite(d.v) & np.isfinite(d.r) & np.isfinite(d.dT)
        for k in range(0, len(d.u) - n, every):
            sl = slice(k, k + n + 1)
            if ok[sl].all() and np.all(d.segment[sl] == d.segment[k]):
                out.append((i, k, n))
    return out


def _stack(drivers: list[SwayDrivers], windows: list[tuple[int, int, int]]) -> dict[str, np.ndarray]:
    """Each driver as (windows, steps + 1), and the grid step of each window."""
    cols = {name: [] for name in ("u", "v", "r", "rdot", "dT")}
    for i, k, n in windows:
        d = drivers[i]
        rdot = d.rdot
        for name, series in (("u", d.u), ("v", d.v), ("r", d.r), ("rdot", rdot), ("dT", d.dT)):
            cols[name].append(series[k: k + n + 1])
    out = {name: np.array(rows) for name, rows in cols.items()}
    out["h"] = np.array([drivers[i].h_s for i, _, _ in windows])[:, None]
    return out


def free_runs(theta: dict[str, float], stacked: dict[str, np.ndarray]) -> np.ndarray:
    """The predicted v (windows, steps + 1) of every window from its measured start."""
    u, r, rdot, dT, h = stacked["u"], stacked["r"], stacked["rdot"], stacked["dT"], stacked["h"][:, 0]
    v = np.empty_like(stacked["v"])
    v[:, 0] = stacked["v"][:, 0]
    for j in range(v.shape[1] - 1):
        vj, uj = v[:, j], u[:, j]
        drive = (theta.get("ur", 0.0) * uj * r[:, j] + theta.get("r", 0.0) * r[:, j]
                 + theta.get("rdot", 0.0) * rdot[:, j] + theta.get("dT", 0.0) * dT[:, j])
        damping = theta.get("v", 0.0) + theta.get("|v|v", 0.0) * np.abs(vj) + theta.get("|u|v", 0.0) * np.abs(uj)
        v[:, j + 1] = (vj + h * drive) / (1.0 + h * damping)
    return v


def fit(drivers: list[SwayDrivers], terms: tuple[str, ...], horizon_s: float = 10.0, stride_s: float = 2.0,
        max_evaluations: int = 400, start: dict[str, float] | None = None) -> SwayAloneFit:
    """θ of `terms` (a subset of TERMS) by least squares on the free runs' v residuals.

    Args:
        drivers: the recordings to fit on.
        terms: which terms the sway equation has.
        horizon_s, stride_s: each free run's length and the spacing of their starts (s).
        max_evaluations: the solver's budget of residual evaluations.
        start: coefficients to start from (a term not given starts at 0, θ_v at 1 unless given): a
            smaller form's fit, so that a larger one fits its own windows at least as well (the free
            runs make the cost non-convex, and from the plain start a larger form can stop worse).

    Returns:
        SwayAloneFit, its R² on the same windows.

    Raises:
        TwinError: an unknown term, or no window of `horizon_s` with every sample known.
    """
    unknown = sorted(set(terms) - set(TERMS))
    if unknown or not terms:
        raise TwinError(f"sway terms must be some of {', '.join(TERMS)}, got {list(terms)}")
    windows = _windows(drivers, horizon_s, stride_s)
    if not windows:
        raise TwinError(f"no free run of {horizon_s:g} s with every sample known")
    stacked = _stack(drivers, windows)
    measured = stacked["v"][:, 1:]

    def residuals(x):
        return (free_runs(dict(zip(terms, x)), stacked)[:, 1:] - measured).ravel()

    lower = [0.0 if t in DAMPING_TERMS else -np.inf for t in terms]
    first = {"v": 1.0, **(start or {})}
    x0 = [max(first.get(t, 0.0), lo) for t, lo in zip(terms, lower)]
    # the terms differ in size by orders (ΔT in N, r in rad/s): each coefficient scaled by its column
    sol = least_squares(residuals, x0, bounds=(lower, np.inf), x_scale="jac", max_nfev=max_evaluations)
    coefficients = dict(zip(terms, map(float, sol.x)))
    return SwayAloneFit(tuple(terms), coefficients, score(coefficients, drivers, horizon_s, stride_s), len(windows))


def score(coefficients: dict[str, float], drivers: list[SwayDrivers], horizon_s: float = 10.0,
          stride_s: float = 2.0) -> float:
    """R² of v over every sample of the free runs of these recordings (pooled, the start excluded)."""
    windows = _windows(drivers, horizon_s, stride_s)
    if not windows:
        raise TwinError(f"no free run of {horizon_s:g} s with every sample known")
    stacked = _stack(drivers, windows)
    return r2_score(stacked["v"][:, 1:].ravel(), free_runs(coefficients, stacked)[:, 1:].ravel())
