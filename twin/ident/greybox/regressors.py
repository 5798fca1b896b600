"""[Morel-2024] regressors: prepared recordings → the columns of eqs. 21, 26-27 (App. A)
and 32-34 (App. B), with the sample masks that keep every one-step pair inside
one segment and inside the operating regions a model is valid for.

Conventions shared by the grey-box models and the baseline:

- δ_i = (pwm_i − neutral_i)/400 per thruster ([Yellowfish-TR §V-B]: δ̃ = PWM/400 − 3.75
  for a 1500 µs neutral), δ̄ = (δL + δR)/2, Δδ = δL − δR [Morel-2024 §5.1].
- Row k of a recording is the one-step pair (k, k+1); it exists only when k+1
  lies in the same segment. The dynamic model's row k also needs k−1 there.
- Dead band: with `deadband_as_zero`, a thruster inside `Prepared.in_deadband`
  gets δ = 0 and counts as forward. Zero thrust is the same on both branches
  of eq. 14, so an idling thruster fits the (f,f) formulas exactly; without
  this, a 1512/1510 µs idle around a 1511 µs neutral reads as (f,r) and every
  coast-down (where surge damping shows) is lost to the surge regression.
- Two input parametrisations ("thrust forms"):
  "paper": the columns of [Morel-2024]. Surge: δ̄² + Δδ²/4 and δ̄, valid in (f,f) only
  (eq. 21). Sway/yaw: s·(δ̄² + Δδ²/4), δ̄Δδ, s·δ̄, Δδ/2 with s = +1 in (f,r),
  −1 in (r,f), 0 in (f,f) (eq. 28), valid in (f,f), (f,r), (r,f). One
  coefficient is shared between (f,f), where it is 2a_f, and (f,r)/(r,f),
  where it is a_f + a_r: exact only for a_f = a_r.
  "thruster": eqs. 13-14 written per thruster, valid in all four regions:
  Σ_i s_i·[δ_i ≥ 0]·(δ_i², δ_i) and Σ_i s_i·[δ_i < 0]·(δ_i², δ_i), with
  s = (+1, +1) for surge and (+1, −1) for sway and yaw. The coefficients are
  h·M⁻¹(j,·)·(a_f, b_f, a_r, b_r) (times d/2 for sway and yaw) in every region.
  It reduces to the paper's surge columns in (f,f) and to an invertible
  recombination of the paper's sway/yaw columns in (f,r) and (r,f).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from ...errors import TwinError
from ...prepare.prepared import Prepared

PWM_HALF_RANGE_US = 400.0
DOFS = ("u", "v", "r")
REGIONS = ("ff", "fr", "rf", "rr")
THRUST_FORMS = ("paper", "thruster")

# Terms of the lumped disturbance σ_j of eq. 12 that survive the P, Q, R patterns,
# in the order of the regressors of [Morel-2024] A_u (eq. 21) and A_v, A_r (Appendix A).
STATE_TERMS: dict[str, tuple[str, ...]] = {
    "u": ("u|u|", "v·r", "r²", "u", "1"),
    "v": ("v|v|", "v|r|", "r|v|", "r|r|", "u·v", "u·r", "v", "r", "1"),
    "r": ("v|v|", "v|r|", "r|v|", "r|r|", "u·v", "u·r", "v", "r", "1"),
}

_TERM: dict[str, Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]] = {
    "u|u|": lambda u, v, r: u * np.abs(u),
    "v·r": lambda u, v, r: v * r,
    "r²": lambda u, v, r: r * r,
    "u": lambda u, v, r: u,
    "v": lambda u, v, r: v,
    "r": lambda u, v, r: r,
    "v|v|": lambda u, v, r: v * np.abs(v),
    "v|r|": lambda u, v, r: v * np.abs(r),
    "r|v|": lambda u, v, r: r * np.abs(v),
    "r|r|": lambda u, v, r: r * np.abs(r),
    "u·v": lambda u, v, r: u * v,
    "u·r": lambda u, v, r: u * r,
    "1": lambda u, v, r: np.ones_like(u),
}

INPUT_TERMS: dict[str, dict[str, tuple[str, ...]]] = {
    "paper": {"u": ("δ̄²+Δδ²/4", "δ̄"),
             "v": ("s(δ̄²+Δδ²/4)", "δ̄Δδ", "sδ̄", "Δδ/2"),
             "r": ("s(δ̄²+Δδ²/4)", "δ̄Δδ", "sδ̄", "Δδ/2")},
    "thruster": {dof: ("Σf δ²", "Σf δ", "Σr δ²", "Σr δ") for dof in DOFS},
}

DEFAULT_REGIONS: dict[str, dict[str, tuple[str, ...]]] = {
    "paper": {"u": ("ff",), "v": ("ff", "fr", "rf"), "r": ("ff", "fr", "rf")},
    "thruster": {dof: REGIONS for dof in DOFS},
}


@dataclass(frozen=True)
class Inputs:
    """Normalised thruster inputs of one recording: δ (n, 2) left/right (NaN without
    PWM) and the operating region per sample ("" where δ is NaN)."""

    delta: np.ndarray
    region: np.ndarray

    @property
    def mean(self) -> np.ndarray:
        return 0.5 * (self.delta[:, 0] + self.delta[:, 1])

    @property
    def difference(self) -> np.ndarray:
        return self.delta[:, 0] - self.delta[:, 1]


def normalised_inputs(prep: Prepared, deadband_as_zero: bool = True) -> Inputs:
    """δ_i = (pwm_i − neutral_i)/400 and the region letters (module docstring)."""
    pwm = np.asarray(prep.pwm, float).reshape(len(prep.t), 2)
    delta = (pwm - np.asarray(prep.pwm_neutral_us, float)) / PWM_HALF_RANGE_US
    if deadband_as_zero:
        delta = np.where(np.asarray(prep.in_deadband, bool) & np.isfinite(delta), 0.0, delta)
        letters = np.where(delta >= 0, "f", "r")
        region = np.char.add(letters[:, 0], letters[:, 1]).astype("<U2")
    else:
        region = np.asarray(prep.region).astype("<U2")
    region = np.where(np.all(np.isfinite(delta), axis=1), region, "")
    return Inputs(delta, region)


def velocities(prep: Prepared) -> np.ndarray:
    """ν = (u, v, r) as an (n, 3) array (m/s, m/s, rad/s)."""
    return np.column_stack([prep.u, prep.v, prep.r]).astype(float)


def state_columns(nu: np.ndarray, dof: str) -> np.ndarray:
    """σ_dof regressors (n, p) at the velocities nu (n, 3), in STATE_TERMS order."""
    u, v, r = nu[..., 0], nu[..., 1], nu[..., 2]
    return np.stack([_TERM[name](u, v, r) for name in STATE_TERMS[dof]], axis=-1)


def input_columns(inputs: Inputs, dof: str, form: str) -> np.ndarray:
    """Input-gain regressors (n, p) in INPUT_TERMS[form][dof] order (module docstring)."""
    if form == "paper":
        return _paper_input_columns(inputs, dof)
    if form == "thruster":
        return _thruster_input_columns(inputs, dof)
    raise TwinError(f"thrust form must be one of {', '.join(THRUST_FORMS)}, got {form!r}")


def _paper_input_columns(inputs: Inputs, dof: str) -> np.ndarray:
    mean, diff = inputs.mean, inputs.difference
    power = mean ** 2 + diff ** 2 / 4  # (δL² + δR²)/2
    if dof == "u":
        return np.column_stack([power, mean])
    # eq. 28: the (a_L − a_R), (b_L − b_R) terms change sign between (f,r) and (r,f), vanish in (f,f)
    s = np.select([inputs.region == "fr", inputs.region == "rf"], [1.0, -1.0], 0.0)
    return np.column_stack([s * power, mean * diff, s * mean, diff / 2])


def _thruster_input_columns(inputs: Inputs, dof: str) -> np.ndarray:
    d = inputs.delta
    side = np.array([1.0, 1.0]) if dof == "u" else np.array([1.0, -1.0])  # τr ∝ T_L − T_R (eq. 13)
    fwd, rev = d >= 0, d < 0
    cols = [np.sum(side * np.where(m, p, 0.0), axis=1) for m in (fwd, rev) for p in (d ** 2, d)]
    return np.column_stack(cols)


def in_regions(inputs: Inputs, regions: Sequence[str]) -> np.ndarray:
    return np.isin(inputs.region, list(regions))


def pair_rows(prep: Prepared) -> np.ndarray:
    """True at k when (k, k+1) is a one-step pair inside one segment with finite ν."""
    n = len(prep.t)
    ok = np.zeros(n, bool)
    if n < 2:
        return ok
    seg = np.asarray(prep.segment)
    finite = np.all(np.isfinite(velocities(prep)), axis=1)
    ok[:-1] = (seg[1:] == seg[:-1]) & finite[1:] & finite[:-1]
    return ok


def history_rows(prep: Prepared) -> np.ndarray:
    """True at k when (k−1, k, k+1) all lie in one segment with finite ν."""
    pair = pair_rows(prep)
    ok = np.zeros_like(pair)
    ok[1:] = pair[1:] & pair[:-1]
    return ok


def check_time_step(preps: Sequence[Prepared]) -> float:
    """The common grid step h (s) of the recordings (their preparation's grid_dt)."""
    steps = []
    for p in preps:
        steps.append(float(p.settings.grid_dt))
    if not steps or not all(np.isfinite(steps)) or min(steps) <= 0:
        raise TwinError("cannot identify: a recording has no valid grid time step")
    if max(steps) - min(steps) > 1e-9 * max(steps):
        raise TwinError(f"cannot identify across grid steps {sorted(set(steps))} s: prepare all recordings "
                        "with the same grid_dt")
    return steps[0]


def as_list(data: Prepared | Sequence[Prepared]) -> list[Prepared]:
    preps = [data] if isinstance(data, Prepared) else list(data)
    if not preps:
        raise TwinError("cannot identify: no recording given")
    return preps


def selection(preps: Sequence[Prepared], rows: Sequence[np.ndarray] | None) -> list[np.ndarray]:
    """Per-recording boolean row selections (all rows when rows is None)."""
    if rows is None:
        return [np.ones(len(p.t), bool) for p in preps]
    rows = list(rows)
    if len(rows) != len(preps) or any(len(m) != len(p.t) for m, p in zip(rows, preps)):
        raise TwinError("rows must hold one boolean array per recording, as long as its samples")
    return [np.asarray(m, bool) for m in rows]


def require_pwm(preps: Sequence[Prepared], inputs: Sequence[Inputs]) -> None:
    if not any(np.any(np.isfinite(i.delta).all(axis=1)) for i in inputs):
        names = ", ".join(str(p.settings.source or "?").rsplit("/", 1)[-1] for p in preps)
        raise TwinError(f"input gains cannot be identified: no PWM sample in {names}")
