"""[Morel-2024] grey-box identification of the input gain G = h·M⁻¹·τ from GNSS,
heading and PWM: the second-order static thruster model (Props. 1-2, eqs.
19-28) and the first-order dynamic one (Prop. 3, eqs. 29-39), as fit
functions returning models that predict.

Discrete model (eq. 9) per velocity component j ∈ {u, v, r}:

    ν_j(k+1) = ν_j(k) + G_j(k) + h·σ_j(ν(k)),   h·σ_j = φ_j(ν)·θ_j  (eq. 12)

static:   G_j(k) = C_j(k)·γ_j                          (eqs. 23, 28)
dynamic:  G_j(k) = α·G_j(k−1) + C_j(k−1)·γ_j           (eqs. 37-39)

φ_j are the σ regressors (regressors.STATE_TERMS), C_j the input columns of
the chosen thrust form (regressors.INPUT_TERMS). θ and γ include h, as the
paper's X vectors do. Usage, scikit-learn style::

    model = fit_static(preps)                 # or fit_dynamic(preps)
    nu_hat = model.predict_one_step(prep)     # (n, 3), NaN where no prediction
    runs = model.predict_windows(prep, starts, n_steps)  # free runs

`rows` (one boolean array per recording; row k = the pair k → k+1) restricts
the fit to a training selection (see twin.ident.greybox.splits).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
from scipy.optimize import minimize_scalar

from ...errors import TwinError
from ...prepare.prepared import Prepared
from . import regressors as R
from .freerun import free_run
from .lsq import MAX_CONDITION, LinearFit, fit_linear

ALPHA_DOFS = ("u", "r")  # DOFs whose eq. 35 rows set α by default (fit_dynamic)
ALPHA_BOUND = 1.0 - 1e-6  # α this close to 1 is an integrator, not a lag: refused
PAPER_NAMES = {"u": "Xu", "v": "Xv", "r": "Xr"}
DOF_WORD = {"u": "surge", "v": "sway", "r": "yaw"}


@dataclass(frozen=True)
class GreyboxOptions:
    """How the regressions are built (regressors module docstring).

    thrust_form: "paper" (the columns of [Morel-2024], eqs. 21, 28) or "thruster" (eqs. 13-14 per thruster).
    regions: operating regions used per DOF, e.g. {"u": ("ff",)}; missing DOFs
    take the form's default (paper: surge (f,f), sway/yaw (f,f), (f,r), (r,f)).
    deadband_as_zero: δ = 0 for a thruster inside Prepared.in_deadband.
    """

    thrust_form: str = "paper"
    regions: dict[str, tuple[str, ...]] = field(default_factory=dict)
    deadband_as_zero: bool = True
    max_condition: float = MAX_CONDITION

    def regions_for(self, dof: str) -> tuple[str, ...]:
        if self.thrust_form not in R.THRUST_FORMS:
            raise TwinError(f"thrust form must be one of {', '.join(R.THRUST_FORMS)}, got {self.thrust_form!r}")
        regions = tuple(self.regions.get(dof, R.DEFAULT_REGIONS[self.thrust_form][dof]))
        bad = [x for x in regions if x not in R.REGIONS]
        if bad or not regions:
            raise TwinError(f"regions for {dof} must be among {', '.join(R.REGIONS)}, got {regions}")
        return regions


@dataclass(frozen=True)
class DofFit:
    """One velocity component's coefficients: the first n_state belong to φ_j (h·σ_j),
    the rest to C_j (the input gain)."""

    dof: str
    regions: tuple[str, ...]
    fit: LinearFit
    n_state: int

    @property
    def theta(self) -> np.ndarray:
        return self.fit.coef[: self.n_state]

    @property
    def gamma(self) -> np.ndarray:
        return self.fit.coef[self.n_state:]

    def to_dict(self) -> dict:
        return {"regions": list(self.regions), "n_rows": self.fit.n_rows, "condition": self.fit.condition,
                "rms_residual": self.fit.rms_residual,
                "coefficients": {n: {"value": float(c), "stderr": float(s)}
                                 for n, c, s in zip(self.fit.names, self.fit.coef, self.fit.stderr)}}


# ---------------------------------------------------------------- per-recording arrays

@dataclass(frozen=True)
class _Arrays:
    """What every fit and prediction needs from one recording."""

    nu: np.ndarray          # (n, 3)
    inputs: R.Inputs
    columns: dict           # dof → (n, p) input columns
    valid: dict             # dof → (n,) region allowed and δ finite
    pair: np.ndarray        # (n,) k → k+1 inside a segment
    history: np.ndarray     # (n,) k−1 → k → k+1 inside a segment


def _arrays(prep: Prepared, options: GreyboxOptions) -> _Arrays:
    inputs = R.normalised_inputs(prep, options.deadband_as_zero)
    columns, valid = {}, {}
    for dof in R.DOFS:
        columns[dof] = R.input_columns(inputs, dof, options.thrust_form)
        valid[dof] = R.in_regions(inputs, options.regions_for(dof)) & np.all(np.isfinite(columns[dof]), axis=1)
    return _Arrays(R.velocities(prep), inputs, columns, valid, R.pair_rows(prep), R.history_rows(prep))


def _prepare_fit(data, rows, options: GreyboxOptions) -> tuple[float, list[_Arrays], list[np.ndarray]]:
    preps = R.as_list(data)
    h = R.check_time_step(preps)
    arrays = [_arrays(p, options) for p in preps]
    R.require_pwm(preps, [a.inputs for a in arrays])
    return h, arrays, R.selection(preps, rows)


def _region_text(regions: Sequence[str]) -> str:
    return ", ".join(f"({x[0]},{x[1]})" for x in regions)


def _stack(blocks: list[tuple[np.ndarray, np.ndarray]], what: str, regions: Sequence[str]):
    if not blocks or sum(len(b) for _, b in blocks) == 0:
        raise TwinError(f"{what} cannot be identified: no usable sample in region {_region_text(regions)} "
                        "(one-step pairs inside a segment)")
    return np.vstack([a for a, _ in blocks]), np.concatenate([b for _, b in blocks])


# ---------------------------------------------------------------- static model (Props. 1-2)

@dataclass(frozen=True)
class StaticModel:
    """Second-order static thruster model: eqs. 19-28 (or their per-thruster form)."""

    h: float
    options: GreyboxOptions
    dofs: dict[str, DofFit]

    def X(self, dof: str) -> np.ndarray:
        """The paper's X_u (eq. 20), X_v (eq. 26) or X_r (eq. 27), h included."""
        return self.dofs[dof].fit.coef.copy()

    def drift(self, nu: np.ndarray) -> np.ndarray:
        return _drift(self.dofs, nu)

    def input_gain(self, prep: Prepared) -> np.ndarray:
        """G(k) = h·M⁻¹τ(k) (eqs. 23, 28), (n, 3) in m/s and rad/s per step; NaN
        where the region is outside a DOF's model."""
        return _input_terms(self.dofs, _arrays(prep, self.options))

    def predict_one_step(self, prep: Prepared) -> np.ndarray:
        """ν̂(k+1) = ν(k) + G(k) + h·σ(ν(k)) from the measured ν(k), at index k+1."""
        a = _arrays(prep, self.options)
        out = np.full_like(a.nu, np.nan)
        k = np.flatnonzero(a.pair)
        out[k + 1] = a.nu[k] + _input_terms(self.dofs, a)[k] + self.drift(a.nu[k])
        return out

    def predict_windows(self, prep: Prepared, starts, n_steps: int) -> np.ndarray:
        """Free runs: from the measured ν at each start, the model fed back its own
        ν̂ for n_steps; (n_windows, n_steps + 1, 3), index 0 the measured ν. NaN past
        a segment end or once a DOF's region leaves its model; +inf once diverged."""
        a = _arrays(prep, self.options)
        g = _input_terms(self.dofs, a)
        return free_run(a.nu, a.pair, starts, n_steps, lambda nu, k, state: (nu + g[k] + self.drift(nu), state))

    def to_dict(self) -> dict:
        return {"model": "static", "h_s": self.h, "thrust_form": self.options.thrust_form,
                "deadband_as_zero": self.options.deadband_as_zero,
                "dofs": {d: f.to_dict() for d, f in self.dofs.items()}}


def fit_static(data: Prepared | Sequence[Prepared], rows: Sequence[np.ndarray] | None = None, *,
               options: GreyboxOptions = GreyboxOptions()) -> StaticModel:
    """Props. 1-2: one least-squares fit per DOF of Δν_j(k+1) = [φ_j(ν(k)), C_j(k)]·X_j
    over the one-step pairs whose region at k is in the DOF's regions."""
    h, arrays, sel = _prepare_fit(data, rows, options)
    dofs = {}
    for dof in R.DOFS:
        regions = options.regions_for(dof)
        names = R.STATE_TERMS[dof] + R.INPUT_TERMS[options.thrust_form][dof]
        what = f"{DOF_WORD[dof]} {PAPER_NAMES[dof]} (static)"
        blocks = []
        for a, s in zip(arrays, sel):
            k = np.flatnonzero(s & a.pair & a.valid[dof])
            A = np.hstack([R.state_columns(a.nu[k], dof), a.columns[dof][k]])
            blocks.append((A, a.nu[k + 1, R.DOFS.index(dof)] - a.nu[k, R.DOFS.index(dof)]))
        A, b = _stack(blocks, what, regions)
        fit = fit_linear(A, b, names, what, options.max_condition)
        dofs[dof] = DofFit(dof, regions, fit, len(R.STATE_TERMS[dof]))
    return StaticModel(h, options, dofs)


# ---------------------------------------------------------------- dynamic model (Prop. 3)

@dataclass(frozen=True)
class DynamicModel:
    """First-order dynamic thruster model, eqs. 29-39.

    unconstrained: the paper's X_dyn,u/v/r (eqs. 32-34), each DOF with its own
    implicit α (alpha_roots_by_dof: its candidates). alpha: the one α of eq. 35
    (see `shared_alpha`); eq35_rms its residual. dofs: θ_j and
    γ_j re-estimated with that α fixed, so that σ_j has one value (Remark 4
    lets the paper's X_dyn carry two) and eqs. 37-39 can be iterated.
    gain_start: how a free run initialises the input-gain state G(s):
    "history" from the measured ν(s−1), ν(s) (falls back to "steady" at a
    segment start), "steady" the fixed point C(s−1)·γ/(1 − α) of eq. 37 for
    the PWM held at s−1 (a settled thrust).
    """

    h: float
    alpha: float
    options: GreyboxOptions
    unconstrained: dict[str, LinearFit]
    dofs: dict[str, DofFit]
    alpha_roots_by_dof: dict[str, tuple[float, ...]]
    eq35_rms: float
    alpha_dofs: tuple[str, ...] = ALPHA_DOFS
    gain_start: str = "history"

    def X(self, dof: str) -> np.ndarray:
        """The paper's X_dyn (eqs. 32-34) from the unconstrained regression, h included."""
        return self.unconstrained[dof].coef.copy()

    def drift(self, nu: np.ndarray) -> np.ndarray:
        return _drift(self.dofs, nu)

    def predict_one_step(self, prep: Prepared) -> np.ndarray:
        """ν̂(k+1) = ν(k) + α·G(k−1) + C(k−1)·γ + h·σ(ν(k)) with the measured
        G(k−1) = ν(k) − ν(k−1) − h·σ(ν(k−1)): the paper's one-step predictor,
        using the measured ν(k−1) and ν(k); at index k+1."""
        a = _arrays(prep, self.options)
        out = np.full_like(a.nu, np.nan)
        k = np.flatnonzero(a.history)
        w = _input_terms(self.dofs, a)
        gain = self.alpha * self._measured_gain(a, k - 1) + w[k - 1]
        out[k + 1] = a.nu[k] + gain + self.drift(a.nu[k])
        return out

    def predict_windows(self, prep: Prepared, starts, n_steps: int, gain_start: str | None = None) -> np.ndarray:
        """Free runs of eqs. 37-39 with ν from the model itself; see StaticModel.predict_windows.
        gain_start overrides the model's (class docstring)."""
        mode = gain_start or self.gain_start
        if mode not in ("history", "steady"):
            raise TwinError(f"gain_start must be 'history' or 'steady', got {mode!r}")
        a = _arrays(prep, self.options)
        w = _input_terms(self.dofs, a)
        s = np.asarray(starts, int)
        gain0 = self._initial_gain(a, w, s, mode) if len(s) else None

        def step(nu, k, gain):
            return nu + gain + self.drift(nu), self.alpha * gain + w[k]

        return free_run(a.nu, a.pair, s, n_steps, step, gain0)

    def _measured_gain(self, a: _Arrays, k: np.ndarray) -> np.ndarray:
        """G(k) = ν(k+1) − ν(k) − h·σ(ν(k)) from measured velocities."""
        return a.nu[k + 1] - a.nu[k] - self.drift(a.nu[k])

    def _initial_gain(self, a: _Arrays, w: np.ndarray, s: np.ndarray, mode: str) -> np.ndarray:
        prev = np.maximum(s - 1, 0)
        has_prev = (s >= 1) & a.pair[prev]
        held = np.where(has_prev[:, None], w[prev], w[s])
        gain = held / (1.0 - self.alpha)
        if mode == "history":
            measured = self.alpha * self._measured_gain(a, prev) + w[prev]
            gain = np.where(has_prev[:, None], measured, gain)
        return gain

    def to_dict(self) -> dict:
        return {"model": "dynamic", "h_s": self.h, "alpha": self.alpha, "alpha_dofs": list(self.alpha_dofs),
                "alpha_roots_by_dof": {d: list(v) for d, v in self.alpha_roots_by_dof.items()},
                "eq35_rms": self.eq35_rms, "thrust_form": self.options.thrust_form,
                "deadband_as_zero": self.options.deadband_as_zero, "gain_start": self.gain_start,
                "X_dyn": {d: f.as_dict() for d, f in self.unconstrained.items()},
                "dofs": {d: f.to_dict() for d, f in self.dofs.items()}}


def fit_dynamic(data: Prepared | Sequence[Prepared], rows: Sequence[np.ndarray] | None = None, *,
                options: GreyboxOptions = GreyboxOptions(), alpha_dofs: Sequence[str] = ALPHA_DOFS,
                alpha_weighting: str = "equal", alpha: float | None = None,
                gain_start: str = "history") -> DynamicModel:
    """Prop. 3 in three steps: (1) the paper's unconstrained regressions A_dyn,j·X_dyn,j =
    Δν_j(k+1) (eqs. 29-34) per DOF; (2) one α from eq. 35 over alpha_dofs (`shared_alpha`);
    (3) with α fixed, Δν_j(k+1) − α·Δν_j(k) = [φ_j(k) − α·φ_j(k−1), C_j(k−1)]·[θ_j, γ_j],
    which is eq. 9 with eq. 37 after eliminating G(k−1) = Δν(k) − h·σ(k−1), and is
    linear again.

    alpha_dofs: the DOFs whose eq. 35 rows enter α. The default leaves sway out:
    the thrusters reach sway only through M⁻¹(2,3)·τr (M23 = m·x_g − Y_ṙ, small for
    a catamaran), so X_dyn,v(1) and X_dyn,v(8) describe the sway hull pole, not the
    thruster's, and pull α there (on the Yellowfish twin with a 1 s lag at h = 0.1 s,
    α = 0.88 with sway, 0.908 without, truth 0.905). ("u", "v", "r") is the paper's
    literal eq. 35. alpha_weighting: "equal" (the paper's equations as written) or
    "covariance" (generalised least squares, see `shared_alpha`). alpha: a known
    pole (e.g. lag_alpha(τ, h) for a measured spin-up time τ) instead of eq. 35.

    Raises TwinError when eq. 35 puts α at the stability bound 1: no stable lag
    fits, typically because smoothing (Savitzky-Golay over window_s) makes
    successive Δν nearly equal, which eq. 35 reads as α → 1 (the paper's 0.998).
    """
    if not alpha_dofs or set(alpha_dofs) - set(R.DOFS):
        raise TwinError(f"alpha_dofs must be a non-empty subset of u, v, r, got {tuple(alpha_dofs)}")
    if alpha_weighting not in ("equal", "covariance"):
        raise TwinError(f"alpha_weighting must be 'equal' or 'covariance', got {alpha_weighting!r}")
    h, arrays, sel = _prepare_fit(data, rows, options)
    rows_by_dof = {dof: [np.flatnonzero(s & a.history & np.roll(a.valid[dof], 1)) for a, s in zip(arrays, sel)]
                   for dof in R.DOFS}
    unconstrained = {dof: _fit_unconstrained(dof, arrays, rows_by_dof[dof], options) for dof in R.DOFS}
    pick = {dof: [0, _own_lag_index(dof)] for dof in R.DOFS}
    first, last = ({d: unconstrained[d].coef[pick[d][i]] for d in alpha_dofs} for i in (0, 1))
    cov = {d: unconstrained[d].covariance[np.ix_(pick[d], pick[d])] for d in alpha_dofs}
    roots = {d: alpha_roots(unconstrained[d].coef[0], unconstrained[d].coef[pick[d][1]]) for d in R.DOFS}
    if alpha is None:
        alpha, rms = shared_alpha(first, last, cov if alpha_weighting == "covariance" else None)
        _check_alpha(alpha, alpha_dofs, roots)
    elif not 0.0 <= alpha < 1.0:
        raise TwinError(f"a fixed α must lie in [0, 1) (a stable lag, Remark 5), got {alpha}")
    else:
        alpha, rms = float(alpha), math.nan
    dofs = {dof: _fit_with_alpha(dof, arrays, rows_by_dof[dof], alpha, options) for dof in R.DOFS}
    return DynamicModel(h, alpha, options, unconstrained, dofs, roots, rms, tuple(alpha_dofs), gain_start)


def _check_alpha(alpha: float, alpha_dofs: Sequence[str], roots: dict) -> None:
    if alpha < ALPHA_BOUND:
        return
    found = "; ".join(f"{d}: {', '.join(f'{x:.3f}' for x in roots[d]) or 'none in [0, 1)'}" for d in alpha_dofs)
    raise TwinError(f"dynamic model: α cannot be identified: eq. 35 over {', '.join(alpha_dofs)} puts it at the "
                    f"stability bound α → 1 (per-DOF roots {found}); smoothed velocities? try a shorter "
                    "window_s, other alpha_dofs, a known alpha, or the static model")


def _own_lag_index(dof: str) -> int:
    """Position in X_dyn,j of ν_j(k−1): 5 for surge, 8 for sway, 9 for yaw (1-based, eq. 35)."""
    state = [t for t in R.STATE_TERMS[dof] if t != "1"]
    return 1 + state.index(dof)


def _dynamic_columns(dof: str, nu: np.ndarray, k: np.ndarray, inputs: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """The paper's A_dyn,j(k) (Appendix B order): ν_j(k), σ terms at k−1, σ terms at k
    without ν_j(k), 1, input columns at k−1."""
    terms = list(R.STATE_TERMS[dof])
    body = [i for i, t in enumerate(terms) if t != "1"]
    now = [i for i in body if terms[i] != dof]
    phi_now, phi_prev = R.state_columns(nu[k], dof), R.state_columns(nu[k - 1], dof)
    A = np.hstack([nu[k, R.DOFS.index(dof)][:, None], phi_prev[:, body], phi_now[:, now],
                   np.ones((len(k), 1)), inputs[k - 1]])
    names = ([f"{dof}(k)"] + [f"{terms[i]}(k−1)" for i in body] + [f"{terms[i]}(k)" for i in now] + ["1"])
    return A, names


def _fit_unconstrained(dof: str, arrays: list[_Arrays], rows: list[np.ndarray], options: GreyboxOptions) -> LinearFit:
    what = f"{DOF_WORD[dof]} {PAPER_NAMES[dof]},dyn (eq. {29 + R.DOFS.index(dof)})"
    input_names = [f"{n}(k−1)" for n in R.INPUT_TERMS[options.thrust_form][dof]]
    blocks, names = [], None
    j = R.DOFS.index(dof)
    for a, k in zip(arrays, rows):
        A, names = _dynamic_columns(dof, a.nu, k, a.columns[dof])
        blocks.append((A, a.nu[k + 1, j] - a.nu[k, j]))
    A, b = _stack(blocks, what, options.regions_for(dof))
    return fit_linear(A, b, names + input_names, what, options.max_condition)


def _fit_with_alpha(dof: str, arrays: list[_Arrays], rows: list[np.ndarray], alpha: float,
                    options: GreyboxOptions) -> DofFit:
    what = f"{DOF_WORD[dof]} (dynamic, α = {alpha:.3f})"
    j = R.DOFS.index(dof)
    blocks = []
    for a, k in zip(arrays, rows):
        phi = R.state_columns(a.nu[k], dof) - alpha * R.state_columns(a.nu[k - 1], dof)
        y = (a.nu[k + 1, j] - a.nu[k, j]) - alpha * (a.nu[k, j] - a.nu[k - 1, j])
        blocks.append((np.hstack([phi, a.columns[dof][k - 1]]), y))
    A, b = _stack(blocks, what, options.regions_for(dof))
    names = R.STATE_TERMS[dof] + R.INPUT_TERMS[options.thrust_form][dof]
    return DofFit(dof, options.regions_for(dof), fit_linear(A, b, names, what, options.max_condition),
                  len(R.STATE_TERMS[dof]))


def shared_alpha(first: dict[str, float], last: dict[str, float],
                 covariance: dict[str, np.ndarray] | None = None) -> tuple[float, float]:
    """The one α of eq. 35 from the unconstrained X_dyn of the DOFs in `first`.

    For each DOF j, with a_j = h·R_j (R_j the σ_j coefficient of ν_j):
        X_j(1) = α + a_j,   X_j(last) = −α(1 + a_j)          (last = 5, 8, 9)
    two equations per DOF in the unknowns α and a_j: six in four for the three
    DOFs, an overdetermined system solved in the least-squares sense. For a trial
    α each a_j has a closed form (the minimiser of its own pair of squared
    residuals), which leaves a one-dimensional cost J(α). J is scanned on a fine
    grid of α ∈ [0, 1) (eq. 15 is a stable lag only there, Remark 5) and refined
    by a bounded scalar minimisation around the best grid point.

    Why a scan and not Newton from a guess: eliminating a_j gives
    α² − α(1 + X_j(1)) − X_j(last) = 0, whose two roots are α and 1 + h·R_j, the
    thruster pole and the hull's own pole. One DOF alone cannot tell them apart
    (`alpha_roots`), so J has a local minimum near each DOF's hull pole; only the
    global one is shared by the DOFs.

    covariance: per DOF the 2×2 covariance of (X_j(1), X_j(last)) from its
    regression; when given, each pair is weighted by its inverse (generalised
    least squares), which discounts a DOF whose pair is poorly determined. None:
    all six equations weigh the same, as the paper writes them. Returns (α, RMS
    residual of the equations; whitened, ≈ 1 at agreement, when weighted).
    """
    dofs = tuple(first)
    x = {d: np.array([first[d], last[d]], float) for d in dofs}
    weight = {d: _information(None if covariance is None else covariance.get(d)) for d in dofs}

    def residuals(alpha: float) -> np.ndarray:
        mean, slope = np.array([alpha, -alpha]), np.array([1.0, -alpha])
        out = []
        for d in dofs:
            W, e0 = weight[d], x[d] - mean
            a = (slope @ W @ e0) / (slope @ W @ slope)
            e = e0 - a * slope
            out.append(np.linalg.cholesky(W).T @ e)
        return np.concatenate(out)

    def cost(alpha: float) -> float:
        return float(np.sum(residuals(alpha) ** 2))

    grid = np.linspace(0.0, 1.0 - 1e-9, 2001)
    i = int(np.argmin([cost(a) for a in grid]))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
    best = minimize_scalar(cost, bounds=(lo, hi), method="bounded", options={"xatol": 1e-12})
    alpha = float(best.x) if best.fun <= cost(grid[i]) else float(grid[i])
    return alpha, float(np.sqrt(np.mean(residuals(alpha) ** 2)))


def _information(cov: np.ndarray | None) -> np.ndarray:
    """Inverse of a 2×2 covariance, or the identity when it is missing or singular."""
    if cov is None or not np.all(np.isfinite(cov)):
        return np.eye(2)
    try:
        W = np.linalg.inv(cov)
        np.linalg.cholesky(W)
        return W
    except np.linalg.LinAlgError:
        return np.eye(2)


def alpha_roots(x_first: float, x_last: float) -> tuple[float, ...]:
    """The real roots in [0, 1) of α² − α(1 + X(1)) − X(last) = 0: one DOF's candidates
    for α, one of which is its hull pole 1 + h·R_j (see `shared_alpha`)."""
    roots = np.roots([1.0, -(1.0 + x_first), -x_last])
    return tuple(sorted(float(z.real) for z in roots if abs(z.imag) < 1e-12 and 0.0 <= z.real < 1.0))


# ---------------------------------------------------------------- shared arithmetic

def _drift(dofs: dict[str, DofFit], nu: np.ndarray) -> np.ndarray:
    """h·σ(ν) per DOF for any leading shape of nu (…, 3)."""
    return np.stack([R.state_columns(nu, d) @ dofs[d].theta for d in R.DOFS], axis=-1)


def _input_terms(dofs: dict[str, DofFit], a: _Arrays) -> np.ndarray:
    """C_j(k)·γ_j per DOF, (n, 3); NaN where the region is outside the DOF's model."""
    out = np.column_stack([a.columns[d] @ dofs[d].gamma for d in R.DOFS])
    valid = np.column_stack([a.valid[d] for d in R.DOFS])
    return np.where(valid, out, np.nan)
