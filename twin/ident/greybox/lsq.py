"""Linear least squares that refuses to answer when the data cannot.

Every fit of the grey-box models and the baseline goes through `fit_linear`:
too few rows, a column that is zero on every usable sample, or columns so
nearly collinear that the coefficients are arbitrary all raise a one-line
TwinError naming the coefficients concerned, instead of returning numbers.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ...errors import TwinError

MIN_ROWS_PER_COEF = 2
# Condition number of the column-equilibrated regressor beyond which coefficients are not
# reported. The paper's static regressors stay near 1e2 on twin and BlueBoat data; its dynamic ones
# put ν_j(k) next to ν_j(k−1) and reach 1e5-1e6 on noise-free twin runs, where they are still
# exactly determined. Beyond 1e8, the rounding of float32 log fields (6e-8 relative) alone can
# move a coefficient by its own size: the fit is numerically rank-deficient.
MAX_CONDITION = 1e8


@dataclass(frozen=True)
class LinearFit:
    """θ of b ≈ A·θ with its covariance and standard errors (from the residual variance,
    white-noise assumption: optimistic for smoothed velocities, whose residuals are
    correlated), the condition number of the column-equilibrated A, the rows used
    and the RMS residual."""

    names: tuple[str, ...]
    coef: np.ndarray
    covariance: np.ndarray
    condition: float
    n_rows: int
    rms_residual: float

    @property
    def stderr(self) -> np.ndarray:
        return np.sqrt(np.maximum(np.diag(self.covariance), 0.0))

    def as_dict(self) -> dict[str, float]:
        return {n: float(c) for n, c in zip(self.names, self.coef)}


def fit_linear(A: np.ndarray, b: np.ndarray, names: Sequence[str], what: str,
               max_condition: float = MAX_CONDITION) -> LinearFit:
    """Least squares with the checks of the module docstring. `what` names the
    regression in error messages (e.g. "surge Xu")."""
    names = tuple(names)
    n, p = A.shape
    need = MIN_ROWS_PER_COEF * p
    if n < need:
        raise TwinError(f"{what}: {', '.join(names)} cannot be identified: {n} usable samples for "
                        f"{p} coefficients (need at least {need})")
    norms = np.linalg.norm(A, axis=0)
    dead = norms <= 1e-12 * np.sqrt(n)
    if np.any(dead):
        raise TwinError(f"{what}: {', '.join(np.asarray(names)[dead])} cannot be identified: the regressor is "
                        f"zero on all {n} usable samples (no excitation)")
    scaled = A / norms
    U, s, Vt = np.linalg.svd(scaled, full_matrices=False)
    condition = float(s[0] / s[-1])
    if not condition <= max_condition:
        raise TwinError(f"{what}: {_collinear(Vt[-1], names)} cannot be separated: nearly collinear on the "
                        f"{n} usable samples (condition number {condition:.1e} > {max_condition:.0e})")
    theta_scaled = Vt.T @ ((U.T @ b) / s)
    coef = theta_scaled / norms
    resid = b - A @ coef
    dof = max(n - p, 1)
    variance = float(resid @ resid) / dof
    covariance = variance * ((Vt.T / s ** 2) @ Vt) / np.outer(norms, norms)
    return LinearFit(names, coef, covariance, condition, n, float(np.sqrt(np.mean(resid ** 2))))


def _collinear(direction: np.ndarray, names: Sequence[str]) -> str:
    """The coefficients that make up the near-null direction of the regressor."""
    weight = np.abs(direction)
    involved = [n for n, w in zip(names, weight) if w >= 0.2 * weight.max()]
    return " and ".join([", ".join(involved[:-1]), involved[-1]]) if len(involved) > 1 else involved[0]
