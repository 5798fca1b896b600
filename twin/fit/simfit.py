"""Identification by simulation: the physical parameters of the vessel description
fitted so that free runs of the twin over short windows (from measured states,
driven by the recorded PWM) match the measured velocities.

The one-step fit of seed 004 is its starting point, not its end: a model that
predicts one step well can still drift in a free run. Here the cost is the free
run itself, the parameters are the physical ones the engine uses (added mass,
damping of seed 004 eq. 7, thrust curve, lag, asymmetry, dead zone, current),
and the constraints are physical: damping coefficients keep Fossen's negative
sign (D(ν) dissipative), added-mass derivatives stay ≤ 0 with M_A symmetric
(M = M_RB + M_A symmetric positive-definite), lag and dead zone ≥ 0.

Scale: GNSS, heading and PWM determine M⁻¹τ and M⁻¹D (seed 004 identifies only
the input gain G = M⁻¹τ, eq. 4): scaling the inertia, the damping and the thrust
together changes no trajectory. One absolute anchor is needed. By default it is
M11 = m − Xu̇: the mass is weighed and a slender hull's surge added mass is a few
per cent of it, so Xu̇ stays at its prior and the thrust curve is identified
(`anchor="mass"`); `anchor="thrust"` keeps the thrust curve and fits Xu̇ instead.

Jacobians are finite differences computed in one batch rollout (all perturbed
twins at once); least squares by scipy's trust-region reflective method within
the bounds; uncertainties from the cluster-robust (sandwich) covariance with the
windows as clusters, because the errors of one free run are correlated.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares

from ..effects import coefficients
from ..effects.coefficients import DEFAULT_FIT as DEFAULT
from ..errors import TwinError
from ..prepare import Prepared
from ..vessel import Vessel
from .objective import SETTLE_S, Estimate, Objective, estimates_of
from .windows import ModelCache, make_windows


@dataclass
class FitResult:
    vessel: Vessel
    estimates: list[Estimate]
    cost_before: float
    cost_after: float
    n_windows: int
    n_evaluations: int
    seconds: float
    message: str = ""
    meta: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"estimates": [e.to_dict() for e in self.estimates], "cost_before": self.cost_before,
                "cost_after": self.cost_after, "windows": self.n_windows, "evaluations": self.n_evaluations,
                "seconds": round(self.seconds, 2), "message": self.message, **self.meta}


def check_names(prior: Vessel, names, anchor: str) -> list[str]:
    """The parameters to fit, checked: known, and with one absolute anchor (module docstring)."""
    table = coefficients(prior)
    names = list(dict.fromkeys(names))
    unknown = [n for n in names if n not in table]
    if unknown:
        raise TwinError(f"unknown parameter(s) {', '.join(unknown)} (known: {', '.join(table)})")
    if anchor not in ("mass", "thrust"):
        raise TwinError(f"anchor must be mass or thrust, got '{anchor}'")
    if anchor == "mass" and "Xudot" in names and "thrust_gain" in names:
        raise TwinError("Xudot and thrust_gain together are not identifiable (the scale needs an anchor): "
                        "drop one, or use --anchor thrust")
    if anchor == "thrust":
        names = [n for n in names if n != "thrust_gain"] + (["Xudot"] if "Xudot" not in names else [])
    return names


def fit(prior: Vessel, preps: list[Prepared], names: tuple[str, ...] = DEFAULT, *, anchor: str = "mass",
        window_s: float = 10.0, stride_s: float = 5.0, max_evaluations: int = 40,
        cache: ModelCache | None = None, settle_s: float = SETTLE_S, free_start: bool = True) -> FitResult:
    """Identify `names` (see `parameters`) by free-run windows of window_s every stride_s s,
    each window's initial velocities estimated with them unless free_start is False."""
    started = time.time()
    table = coefficients(prior)
    names = check_names(prior, names, anchor)
    if prior.thrusters.kind != "t200":
        raise TwinError(f"vessel '{prior.name}' has no PWM thruster model: a recording cannot drive it")
    windows = make_windows(preps, window_s, stride_s, min_length_s=min(window_s, 3.0))
    if not windows:
        raise TwinError(f"no segment of {min(window_s, 3.0):g} s or more to fit on")
    if "lag_s" in names and prior.thrusters.lag_s <= 0:
        prior = replace(prior, thrusters=replace(prior.thrusters, lag_s=0.05))  # the lag state needs a start
    obj = Objective(prior, [table[n] for n in names], preps, windows, cache, min(settle_s, window_s / 2),
                    free_start=free_start)
    x0 = np.clip(obj.x_prior, *obj.bounds())
    cost0 = 0.5 * float(np.sum(obj.residuals(x0) ** 2))
    sol = least_squares(obj.residuals, x0, jac=obj.jacobian, bounds=obj.bounds(), method="trf", x_scale="jac",
                        max_nfev=max_evaluations, xtol=1e-10, ftol=1e-10, gtol=1e-10)
    J = obj.jacobian(sol.x)
    r = obj.residuals(sol.x)
    estimates = estimates_of(obj, sol.x, J, r)
    fitted, evaluations = obj.vessel(sol.x), obj.evaluations
    pinned = [i for i, e in enumerate(estimates) if e.identifiable]
    if len(pinned) < len(estimates):
        # the data cannot say what the others are: they go back to the prior and the rest is fitted
        # again around them, so the returned twin is one that was fitted, not a mix of two
        sub = Objective(prior, [obj.params[i] for i in pinned], preps, windows, obj.cache, obj.settle_s,
                        free_start=free_start)
        x1 = np.clip(np.array([estimates[i].value for i in pinned]) / sub.scale, *sub.bounds())
        if pinned:
            sol = least_squares(sub.residuals, x1, jac=sub.jacobian, bounds=sub.bounds(), method="trf",
                                x_scale="jac", max_nfev=max(5, max_evaluations // 2), xtol=1e-8, ftol=1e-8)
            x1 = sol.x
        r = sub.residuals(x1)
        again = estimates_of(sub, x1, sub.jacobian(x1), r) if pinned else []
        for i, e in zip(pinned, again):
            estimates[i] = e
        for i, e in enumerate(estimates):
            if i not in pinned:
                e.value = e.prior
        fitted, evaluations = sub.vessel(x1), evaluations + sub.evaluations
    return FitResult(fitted, estimates, cost0, 0.5 * float(np.sum(r ** 2)), len(windows), evaluations,
                     time.time() - started, sol.message,
                     {"anchor": anchor, "window_s": window_s, "stride_s": stride_s, "free_start": free_start,
                      "residual_rms": float(np.sqrt(np.mean(r ** 2)))})


