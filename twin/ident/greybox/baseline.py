"""The plain baseline the grey-box models must beat: per DOF a linear plus
quadratic damping, one coupling or thrust term, and the vessel's own thruster
map, fitted by least squares on one-step differences (forward Euler):

    u̇ = a_u·u + b_u·u|u| + c_u·(T_L + T_R)
    v̇ = a_v·v + b_v·v|v| + c_v·u·r          (centripetal term of −M_RB/A·C(ν)ν)
    ṙ = a_r·r + b_r·r|r| + c_r·(T_L − T_R)

T_i (N) = vessel.thrusters.thrust_from_pwm(pwm_i): the datasheet curve with its
dead zone, no lag. c_u ≈ 1/M11 and c_r ≈ d/(2·M33) when that curve is right.
with_bias adds a constant per DOF (wind, current, a trimmed thruster).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ...errors import TwinError
from ...physics.thrusters import ThrusterModel
from ...prepare.prepared import Prepared
from ...vessel import Vessel
from . import regressors as R
from .freerun import free_run
from .lsq import MAX_CONDITION, LinearFit, fit_linear

TERMS = {"u": ("u", "u|u|", "T_L+T_R"), "v": ("v", "v|v|", "u·r"), "r": ("r", "r|r|", "T_L−T_R")}


def thrust_n(prep: Prepared, thrusters: ThrusterModel) -> np.ndarray:
    """Per-thruster thrust (n, 2) in N from the recorded PWM; NaN where PWM is missing."""
    if thrusters.kind != "t200":
        raise TwinError("the plain baseline needs a vessel with a PWM→thrust map (thrusters.kind = 't200')")
    pwm = np.asarray(prep.pwm, float).reshape(len(prep.t), 2)
    thrust = thrusters.thrust_from_pwm(np.nan_to_num(pwm, nan=0.5 * (thrusters.pwm_min_us + thrusters.pwm_max_us)))
    return np.where(np.isfinite(pwm), thrust, np.nan)


def _columns(nu: np.ndarray, thrust: np.ndarray, dof: str, with_bias: bool) -> np.ndarray:
    u, v, r = nu[..., 0], nu[..., 1], nu[..., 2]
    cols = {"u": (u, u * np.abs(u), thrust[..., 0] + thrust[..., 1]),
            "v": (v, v * np.abs(v), u * r),
            "r": (r, r * np.abs(r), thrust[..., 0] - thrust[..., 1])}[dof]
    if with_bias:
        cols = cols + (np.ones_like(u),)
    return np.stack(cols, axis=-1)


@dataclass(frozen=True)
class PlainModel:
    """Continuous-time coefficients (per DOF, in TERMS order, then the bias) stepped
    with forward Euler at h."""

    h: float
    thrusters: ThrusterModel
    fits: dict[str, LinearFit]
    with_bias: bool = False

    def rates(self, nu: np.ndarray, thrust: np.ndarray) -> np.ndarray:
        """ν̇ (…, 3) at velocities nu and thrusts (…, 2) in N."""
        return np.stack([_columns(nu, thrust, d, self.with_bias) @ self.fits[d].coef for d in R.DOFS], axis=-1)

    def predict_one_step(self, prep: Prepared) -> np.ndarray:
        nu, pair, thrust = R.velocities(prep), R.pair_rows(prep), thrust_n(prep, self.thrusters)
        out = np.full_like(nu, np.nan)
        k = np.flatnonzero(pair)
        out[k + 1] = nu[k] + self.h * self.rates(nu[k], thrust[k])
        return out

    def predict_windows(self, prep: Prepared, starts, n_steps: int) -> np.ndarray:
        nu, thrust = R.velocities(prep), thrust_n(prep, self.thrusters)
        return free_run(nu, R.pair_rows(prep), starts, n_steps,
                        lambda x, k, s: (x + self.h * self.rates(x, thrust[k]), s))

    def to_dict(self) -> dict:
        return {"model": "plain", "h_s": self.h, "with_bias": self.with_bias,
                "dofs": {d: {n: {"value": float(c), "stderr": float(e)}
                             for n, c, e in zip(f.names, f.coef, f.stderr)} for d, f in self.fits.items()}}


def fit_plain(data: Prepared | Sequence[Prepared], vessel: Vessel, rows: Sequence[np.ndarray] | None = None, *,
              with_bias: bool = False, max_condition: float = MAX_CONDITION) -> PlainModel:
    """Least squares of (ν_j(k+1) − ν_j(k))/h on the terms of the module docstring over
    every one-step pair with PWM, all operating regions."""
    preps = R.as_list(data)
    h = R.check_time_step(preps)
    sel = R.selection(preps, rows)
    thrusts = [thrust_n(p, vessel.thrusters) for p in preps]
    if not any(np.isfinite(t).all(axis=1).any() for t in thrusts):
        raise TwinError("plain baseline: c_u, c_r cannot be identified: no PWM sample in the recordings")
    fits = {}
    for j, dof in enumerate(R.DOFS):
        blocks = []
        for p, s, thrust in zip(preps, sel, thrusts):
            nu = R.velocities(p)
            k = np.flatnonzero(s & R.pair_rows(p) & np.isfinite(thrust).all(axis=1))
            blocks.append((_columns(nu[k], thrust[k], dof, with_bias), (nu[k + 1, j] - nu[k, j]) / h))
        A = np.vstack([b[0] for b in blocks])
        y = np.concatenate([b[1] for b in blocks])
        names = TERMS[dof] + (("1",) if with_bias else ())
        fits[dof] = fit_linear(A, y, names, f"plain baseline {dof}", max_condition)
    return PlainModel(h, vessel.thrusters, fits, with_bias)


def persistence_one_step(prep: Prepared) -> np.ndarray:
    """ν̂(k+1) = ν(k): the no-model reference of one-step prediction."""
    nu, pair = R.velocities(prep), R.pair_rows(prep)
    out = np.full_like(nu, np.nan)
    k = np.flatnonzero(pair)
    out[k + 1] = nu[k]
    return out
