"""Identification by simulation: the physical parameters of the vessel description
fitted so that free runs of the twin over short windows (from measured states,
driven by the recorded PWM) match the measured velocities.

The one-step fit of [Morel-2024] is its starting point, not its end: a model that
predicts one step well can still drift in a free run. Here the cost is the free
run itself, the parameters are the physical ones the engine uses (added mass,
damping of [Morel-2024 eq. 7], thrust curve, lag, asymmetry, dead zone, current),
and the constraints are physical: damping coefficients keep Fossen's negative
sign (D(ν) dissipative), added-mass derivatives stay ≤ 0 with M_A symmetric
(M = M_RB + M_A symmetric positive-definite), lag and dead zone ≥ 0.

Scale: GNSS, heading and PWM determine M⁻¹τ and M⁻¹D ([Morel-2024] identifies only
the input gain G = M⁻¹τ, eq. 4): scaling the inertia, the damping and the thrust
together changes no trajectory. One absolute anchor is needed. By default it is
M11 = m − Xu̇: the mass is weighed and a slender hull's surge added mass is a few
per cent of it, so Xu̇ stays at its prior and the thrust curve is identified
(`anchor="mass"`); `anchor="thrust"` keeps the thrust curve and fits Xu̇ instead.

Jacobians are finite differences computed in one batch rollout (all perturbed
twins at once); least squares by scipy's trust-region reflective method within
the bounds; uncertainties from the cluster-robust (sandwich) covariance with the
windows as clusters, because the errors of one free run are correlated.

A propeller-and-rudder ship (thrusters kind `propeller_rudder`, an MMG block) is driven by its
recorded (n, δ) instead of PWM and fits its MMG coefficients (effects.coefficients.MMG_FIT_GROUPS);
its scale is anchored by the mass and the propeller's K_T, neither of which is fitted. With
wind="measured" every free run takes the recording's measured wind as a known input.

With `prior_weight`, the fit is a maximum a posteriori one: each coefficient's belief
(effects.coefficients.belief: a log-normal magnitude for a damping, an added mass or a
thrust scale, a normal value for a coupling) enters as a residual row, counted as
`prior_weight` windows' worth of data. A log-normal coefficient is fitted as ln|θ|, so its
sign cannot flip. A coefficient whose posterior is not clearly narrower than its belief
(POSTERIOR_RATIO) is not pinned down by the recordings: it goes back to its prior value
exactly, keeps its belief's uncertainty, and the rest is fitted again around it, so what the
report says is kept is what the vessel file holds.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares

from ..effects import Quantity, coefficients
from ..effects.coefficients import PWM_THRUSTER_TERMS, Belief, belief
from ..effects.quantity import log_magnitude
from ..effects.coefficients import DEFAULT_FIT as DEFAULT
from ..errors import TwinError
from ..prepare import Prepared
from ..vessel import Vessel
from .uncertainty import block
from .objective import SETTLE_S, STAND_IN_SIGMAS, Estimate, Objective, cluster_covariance, estimates_of
from .windows import ModelCache, make_windows


STEP_FRACTIONS = (1.0, 0.5, 0.25, 0.0)  # of the step that returns unpinned coordinates to their prior
POSTERIOR_RATIO = 0.7  # a posterior σ above this share of the belief's: the data did not pin it down
# a posterior σ above this multiple of what the belief alone leaves: the cluster-robust σ carries the
# windows' disagreement (their scatter about the fit), which no belief narrows
DISPUTED_RATIO = 1.5
MAP_FTOL = 1e-4  # relative cost change at which a maximum a posteriori fit stops


@dataclass
class FitResult:
    """What a fit returns: the fitted vessel, each coefficient's estimate (prior, value, 1-σ, whether
    the data pin it), the cost before and after (½ Σ residual²), the windows and rollouts it took and
    its time (s); `meta` the settings it ran with; the objective, coordinates, Jacobian and covariance
    at the solution for the callers that continue from it (`start=`) or draw from it."""

    vessel: Vessel
    estimates: list[Estimate]
    cost_before: float
    cost_after: float
    n_windows: int
    n_evaluations: int
    seconds: float
    message: str = ""
    meta: dict = field(default_factory=dict)
    objective: Objective | None = field(default=None, repr=False)  # what was minimised, at the solution:
    x: np.ndarray | None = field(default=None, repr=False)  # its coordinates (see Objective.vessel)
    jacobian: np.ndarray | None = field(default=None, repr=False)  # data rows, then the prior's
    covariance: np.ndarray | None = field(default=None, repr=False)  # of the coordinates' values

    def to_dict(self) -> dict:
        return {"estimates": [e.to_dict() for e in self.estimates], "cost_before": self.cost_before,
                "cost_after": self.cost_after, "windows": self.n_windows, "evaluations": self.n_evaluations,
                "seconds": round(self.seconds, 2), "message": self.message, **self.meta}


def check_names(prior: Vessel, names, anchor: str) -> list[str]:
    """The parameters to fit, checked: known, and with one absolute anchor (module docstring)."""
    table = coefficients(prior)
    names = list(dict.fromkeys(names))
    unknown = [n for n in names if n not in table]
    pwm_only = [n for n in unknown if n in PWM_THRUSTER_TERMS]
    if pwm_only:
        raise TwinError(f"{', '.join(pwm_only)}: a PWM thruster's term{'s' if len(pwm_only) > 1 else ''}, and vessel "
                        f"'{prior.name}' has a propeller and rudder (its MMG coefficients: "
                        f"{', '.join(n for n in table if n.startswith('mmg_'))})")
    if unknown:
        raise TwinError(f"unknown parameter(s) {', '.join(unknown)} (known: {', '.join(table)})")
    if anchor not in ("mass", "thrust"):
        raise TwinError(f"anchor must be mass or thrust, got '{anchor}'")
    if anchor == "mass" and "Xudot" in names and "thrust_gain" in names:
        raise TwinError("Xudot and thrust_gain together are not identifiable (the scale needs an anchor): "
                        "drop one, or use --anchor thrust")
    if prior.mmg is not None and "Yvdot" in names and "mmg_Xvr" in names:
        raise TwinError("Yvdot and mmg_Xvr together: a ship's fitted Yvdot moves X'_vr with it, so that surge feels "
                        "m_y + X'_vr unchanged (effects/coefficients.py mmg_sway_added_mass): fit one of them")
    if anchor == "thrust":
        names = [n for n in names if n != "thrust_gain"] + (["Xudot"] if "Xudot" not in names else [])
    return names


FITTABLE_KINDS = ("t200", "propeller_rudder")  # thrusters a recording's inputs drive


def check_kind(prior: Vessel) -> None:
    """A vessel whose inputs a recording can give (PWM, or a propeller's n and a rudder's δ)."""
    if prior.thrusters.kind not in FITTABLE_KINDS:
        raise TwinError(f"vessel '{prior.name}' has no PWM thruster model: a recording cannot drive it")


def fit(prior: Vessel, preps: list[Prepared], names: tuple[str, ...] = DEFAULT, *, anchor: str = "mass",
        window_s: float = 10.0, stride_s: float = 5.0, max_evaluations: int = 40,
        cache: ModelCache | None = None, settle_s: float = SETTLE_S, free_start: bool = True,
        prior_weight: float | None = None, start: Vessel | list[Vessel] | FitResult | None = None,
        windows: list | None = None,
        wind: str | None = None, dof_sigma: np.ndarray | None = None) -> FitResult:
    """Identify `names` (see `coefficients`) by free-run windows of window_s every stride_s s,
    each window's initial velocities estimated with them unless free_start is False; with
    prior_weight, a maximum a posteriori fit (module docstring) from `start` (default: the prior;
    several candidates: the one the objective finds lowest; a FitResult of the same coefficients on
    the same windows, recordings and scales at another weight: its point, its runs there not repeated),
    on `windows` if given; wind "measured": the recordings' wind a known input. dof_sigma: the
    scale of each velocity's residual in a MAP fit (m/s, m/s, rad/s; default: the spread of each
    measured velocity, Objective)."""
    if prior_weight is not None:
        return _fit_map(prior, preps, names, anchor=anchor, window_s=window_s, stride_s=stride_s,
                        max_evaluations=max_evaluations, cache=cache, settle_s=settle_s, free_start=free_start,
                        prior_weight=prior_weight, start=start, windows=windows, wind=wind, dof_sigma=dof_sigma)
    return _fit_least_squares(prior, preps, names, anchor=anchor, window_s=window_s, stride_s=stride_s,
                              max_evaluations=max_evaluations, cache=cache, settle_s=settle_s, free_start=free_start,
                              wind=wind)


def _fit_least_squares(prior: Vessel, preps: list[Prepared], names: tuple[str, ...] = DEFAULT, *,
                       anchor: str = "mass", window_s: float = 10.0, stride_s: float = 5.0,
                       max_evaluations: int = 40, cache: ModelCache | None = None, settle_s: float = SETTLE_S,
                       free_start: bool = True, wind: str | None = None) -> FitResult:
    """Bounded least squares without a prior (the data alone)."""
    started = time.time()
    table = coefficients(prior)
    names = check_names(prior, names, anchor)
    check_kind(prior)
    windows = make_windows(preps, window_s, stride_s, min_length_s=min(window_s, 3.0))
    if not windows:
        raise TwinError(f"no segment of {min(window_s, 3.0):g} s or more to fit on")
    if "lag_s" in names and prior.thrusters.lag_s <= 0:
        prior = replace(prior, thrusters=replace(prior.thrusters, lag_s=0.05))  # the lag state needs a start
    obj = Objective(prior, [table[n] for n in names], preps, windows, cache, min(settle_s, window_s / 2),
                    free_start=free_start, wind=wind)
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
                        free_start=free_start, wind=wind)
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




# ---------------------------------------------------------------- maximum a posteriori

@dataclass(frozen=True)
class Coordinate:
    """One fitted coordinate: the Quantity the optimiser moves (ln|θ| for a log-normal belief),
    the belief about it, and its prior value in the coordinate's units."""

    name: str
    quantity: Quantity
    belief: Belief
    log: bool
    mean: float
    unit: str
    prior_value: float

    def natural(self, x: float) -> float:
        """The coefficient's value for coordinate value x."""
        return float(np.sign(self.prior_value) * np.exp(x)) if self.log else float(x)


def map_start(prior: Vessel, names) -> Vessel:
    """The prior a maximum a posteriori fit of `names` starts from: a thrust lag of 0.1 s where the
    prior has none (a log-normal belief needs a magnitude, and the lag's state a start), and a
    thrust that follows the pack as V^1 where the prior's does not follow it."""
    if "lag_s" in names and prior.thrusters.lag_s <= 0:
        prior = replace(prior, thrusters=replace(prior.thrusters, lag_s=0.1))
    if "supply_exponent" in names and prior.thrusters.supply_exponent <= 0:
        # k = 0 is the edge of its range, where a finite difference cannot look below: start between a
        # regulated supply (0) and an ideal ESC (2), which is also the belief's centre
        prior = replace(prior, thrusters=replace(prior.thrusters, supply_exponent=1.0))
    return prior


def _map_starts(given: Vessel, start: Vessel) -> dict[str, tuple[float, float]]:
    """The terms map_start may start away from the vessel's own value: (own, start) each."""
    return {"lag_s": (given.thrusters.lag_s, start.thrusters.lag_s),
            "supply_exponent": (given.thrusters.supply_exponent, start.thrusters.supply_exponent)}


def _started_elsewhere(given: Vessel, start: Vessel) -> set[str]:
    """The terms the fit started away from the vessel's own value: their belief centres on the start, so
    no distance from a physical prior is measured for them."""
    return {name for name, (own, began) in _map_starts(given, start).items() if own != began}


def _started(estimates: list[Estimate], given: Vessel, start: Vessel) -> list[Estimate]:
    """The estimates with the vessel's own prior value where the fit started elsewhere (map_start: a
    lag of 0 s started at 0.1 s), and the note saying so: a prior column showing the start would read
    as the vessel's."""
    moved = _map_starts(given, start)
    out = []
    for e in estimates:
        own, began = moved.get(e.name, (None, None))
        if own is not None and own != began:
            e = replace(e, prior=own, note=f"the prior's {own:g} {e.unit} started at {began:g} (a log-normal belief "
                                           f"needs a magnitude); {e.note}")
        out.append(e)
    return out


def coordinates(prior: Vessel, names) -> list[Coordinate]:
    """The coordinates of a maximum a posteriori fit of `names`: log-magnitude where the belief
    is log-normal and the prior value non-zero, the value itself otherwise (a zero prior has no
    magnitude: its belief is taken as normal with the same relative width of its typical size)."""
    table = coefficients(prior)
    out = []
    for n in names:
        q, b = table[n], belief(n, prior)
        value = q.get(prior)
        if b.log and value != 0.0:
            out.append(Coordinate(n, log_magnitude(q, prior), b, True, float(np.log(abs(value))), q.unit, value))
        else:
            sigma = b.sigma if not b.log else b.sigma * max(abs(value), q.typical)
            out.append(Coordinate(n, q, Belief(False, sigma, b.why), False, float(value), q.unit, value))
    return out


def _fit_map(prior: Vessel, preps: list[Prepared], names, *, anchor: str, window_s: float, stride_s: float,
             max_evaluations: int, cache: ModelCache | None, settle_s: float, free_start: bool,
             prior_weight: float, start: Vessel | list[Vessel] | FitResult | None, windows: list | None,
             wind: str | None = None, dof_sigma: np.ndarray | None = None) -> FitResult:
    started = time.time()
    names = check_names(prior, names, anchor)
    check_kind(prior)
    if windows is None:
        windows = make_windows(preps, window_s, stride_s, min_length_s=min(window_s, 3.0))
    if not windows:
        raise TwinError(f"no segment of {min(window_s, 3.0):g} s or more to fit on")
    given = prior
    prior = map_start(prior, names)
    coords = coordinates(prior, names)
    obj = map_objective(prior, coords, preps, windows, cache, min(settle_s, window_s / 2), free_start, prior_weight,
                        wind, dof_sigma)
    cost0 = 0.5 * float(np.sum(obj.residuals(obj.x_prior) ** 2))
    if isinstance(start, FitResult):  # a fit at another belief weight: its point and its data's Jacobian there
        x0 = _continued(obj, coords, start)
    else:
        x0 = obj.x_prior if start is None else _lowest_start(obj, coords, [start] if isinstance(start, Vessel)
                                                             else start)
    # ftol 1e-4: on the BlueBoat's runs the last ten of twenty steps moved the cost by 0.01 % and the
    # coefficients by a fraction of their posterior σ, at half the time of the fit
    sol = least_squares(obj.residuals, x0, jac=obj.jacobian, bounds=obj.bounds(), method="trf", x_scale="jac",
                        max_nfev=max_evaluations, xtol=1e-8, ftol=MAP_FTOL, gtol=1e-8)
    x, J, r, cov = _solution(obj, sol.x, sol.jac)  # trf's last Jacobian is the one at sol.x
    free = _pinned(obj, coords, cov)
    evaluations = obj.evaluations
    for _ in range(3):  # until what is called pinned is pinned at the solution returned
        if all(free):
            break
        # not pinned by the data: back to the prior exactly, and the rest moved toward where that puts
        # their optimum: a Gauss-Newton step on the Jacobian already at hand (the unpinned ones
        # barely move the fit, or the data would have pinned them), shortened where the full step
        # lands in windows that diverge
        reset = np.where(free, x, obj.x_prior)
        r0 = r + J @ (reset - x)
        step = np.zeros(len(x))
        if any(free):
            step[free] = np.linalg.lstsq(J[:, free], -r0, rcond=None)[0]
        moved = _solution(obj, _lowest_on_line(obj, reset, step))
        if moved[3] is None:  # no curvature to say what is pinned there: the set stands, σ from before
            x, J, r = moved[:3]
            break
        x, J, r, cov = moved
        still = free & _pinned(obj, coords, cov)
        if np.array_equal(still, free):
            break
        free = still
    evaluations = obj.evaluations
    estimates = _started(_map_estimates(obj, coords, x, cov, free, _started_elsewhere(given, prior)), given, prior)
    data_r = r[: obj.n_data]
    result = FitResult(obj.vessel(x), estimates, cost0, 0.5 * float(np.sum(r ** 2)), len(windows), evaluations,
                     time.time() - started, sol.message,
                     {"anchor": anchor, "window_s": window_s, "stride_s": stride_s, "free_start": free_start,
                      "prior_weight": prior_weight, "residual_rms": float(np.sqrt(np.mean(data_r ** 2))),
                      **({"wind": wind} if wind else {}),
                      **({"dof_sigma": [float(x) for x in obj.sigma]} if dof_sigma is not None else {})},
                     objective=obj, x=x, jacobian=J, covariance=cov)
    result.vessel = replace(result.vessel, uncertainty=block(result, coords, free))
    return result


def at_prior(fit: FitResult, given: Vessel, why: str) -> FitResult:
    """`fit` put back at the vessel it was given: every coefficient at its prior with its prior's
    uncertainty (`why` says why), the uncertainty block the beliefs' alone. A term the vessel lacks
    that the fit started elsewhere (map_start: a lag of 0 s at 0.1 s) stays out of the block: a draw
    from it would add physics the written twin does not have."""
    names = [e.name for e in fit.estimates]
    table = coefficients(given)
    kept, own = [], []
    for e, c in zip(fit.estimates, coordinates(fit.objective.prior, names)):
        held = table[c.name].get(given) == c.prior_value
        sigma = (abs(c.prior_value) * c.belief.sigma if c.log else c.belief.sigma) if held else None
        kept.append(Estimate(e.name, e.unit, e.prior, e.prior, sigma, False,
                             "kept at its prior with its prior's uncertainty: the prior written (below)"))
        if held:
            own.append(c)
    uncertainty = {"coordinates": [{"name": c.name, "log": c.log, "sign": float(np.sign(c.prior_value) or 1.0)}
                                   for c in own],
                   "mean": [c.mean for c in own],
                   "covariance": [[c.belief.sigma ** 2 if i == j else 0.0 for j in range(len(own))]
                                  for i, c in enumerate(own)]}
    return replace(fit, vessel=replace(given, uncertainty=uncertainty), estimates=kept,
                   meta={**fit.meta, "kept_prior": why})


def _lowest_on_line(obj: Objective, x: np.ndarray, step: np.ndarray) -> np.ndarray:
    """x + a·step for the a in STEP_FRACTIONS the objective finds lowest (a step of 0 included)."""
    lo, hi = obj.bounds()
    xs = [np.clip(x + a * step, lo, hi) for a in STEP_FRACTIONS]
    costs = np.array([float(np.sum(obj.residuals(c) ** 2)) for c in xs])
    return xs[int(np.argmin(np.where(np.isfinite(costs), costs, np.inf)))]


def _continued(obj: Objective, coords: list[Coordinate], start: FitResult) -> np.ndarray:
    """The point of `start`, a fit of the same coordinates on the same windows, recordings, scales,
    start handling, wind and time step at another belief weight, its data's residuals and Jacobian
    given to `obj` there (a data row does not depend on the weight: no run is repeated); otherwise
    its vessel as a start. Only the weight may differ: each velocity's scale also weighs the fitted
    start of every window, so rows at other scales are not these rows rescaled."""
    before = start.objective
    same = (before is not None and start.x is not None and start.jacobian is not None
            and [c.quantity.name for c in coords] == [q.name for q in before.params]
            and before.windows == obj.windows and len(before.preps) == len(obj.preps)
            and all(a is b for a, b in zip(before.preps, obj.preps))
            and before.free_start == obj.free_start and before.wind == obj.wind
            and before.cache.timestep_s == obj.cache.timestep_s
            and np.array_equal(before.sigma, obj.sigma) and np.array_equal(before.scale, obj.scale))
    # the vessel must be the fit's point (a fit put back at its prior keeps its objective and point)
    at_point = same and np.allclose([c.quantity.get(start.vessel) for c in coords], np.asarray(start.x) * obj.scale,
                                    rtol=1e-9, atol=1e-12)
    if not at_point:
        return _lowest_start(obj, coords, [start.vessel])
    x = np.asarray(start.x, float)
    n = obj.n_data
    obj.seed(x, before.residuals(x)[:n], start.jacobian[:n])
    return x


def _lowest_start(obj: Objective, coords: list[Coordinate], starts: list[Vessel]) -> np.ndarray:
    """Of the candidate starts, the one the objective finds lowest: a trust-region fit from a start
    whose windows diverge sees a Jacobian of overflows and never takes a step."""
    xs = [np.clip(np.array([c.quantity.get(v) for c in coords]) / obj.scale, *obj.bounds()) for v in starts]
    if len(xs) == 1:
        return xs[0]
    costs = [float(np.sum(obj.residuals(x) ** 2)) for x in xs]
    return xs[int(np.nanargmin(np.where(np.isfinite(costs), costs, np.nan)))] if np.isfinite(costs).any() else xs[0]


def map_objective(prior: Vessel, coords: list[Coordinate], preps, windows, cache, settle_s: float, free_start: bool,
                  prior_weight: float, wind: str | None = None, dof_sigma: np.ndarray | None = None) -> Objective:
    """The objective of a maximum a posteriori fit: data rows, then one row per coordinate, the
    beliefs counted as prior_weight windows' worth of data samples each; dof_sigma: each velocity's
    residual scale (default: its measured spread)."""
    obj = Objective(prior, [c.quantity for c in coords], preps, windows, cache, settle_s, free_start=free_start,
                    wind=wind)
    if dof_sigma is not None:
        obj.sigma = np.asarray(dof_sigma, float)
    per_window = obj.n_data / max(len(windows), 1)
    obj.believe(np.array([c.mean for c in coords]), np.array([c.belief.sigma for c in coords]),
                prior_weight * per_window)
    return obj


def _solution(obj: Objective, x: np.ndarray, J: np.ndarray | None = None):
    """x, the Jacobian there (computed unless given), the residuals and the coordinates' covariance."""
    J = obj.jacobian(x) if J is None else J
    r = obj.residuals(x)
    n = obj.n_data
    cov = cluster_covariance(J[:n], r[:n], obj.window_index(), J[n:])
    if cov is not None:
        cov = cov * np.outer(obj.scale, obj.scale)  # coordinate value units
    return x, J, r, cov


def _pinned(obj: Objective, coords: list[Coordinate], cov) -> np.ndarray:
    """Which coordinates the data narrowed clearly below their belief (POSTERIOR_RATIO)."""
    if cov is None:
        return np.zeros(len(coords), bool)
    sigma = np.sqrt(np.maximum(np.diag(cov), 0.0))
    return sigma < POSTERIOR_RATIO * np.array([c.belief.sigma for c in coords])


def _near_bound(obj: Objective, x: np.ndarray, cov) -> list[tuple[float, bool] | None]:
    """Per coordinate, the bound of its range it ended on or within its σ of (coordinate units) and
    whether exactly on it (trf keeps iterates just inside); None when clear of both bounds."""
    lo, hi = obj.bounds()
    out = []
    for i in range(len(x)):
        span = hi[i] - lo[i] if np.isfinite(hi[i] - lo[i]) else 1.0
        sx = float(np.sqrt(max(cov[i, i], 0.0))) / obj.scale[i] if cov is not None else 0.0
        near = None
        for bound in (lo[i], hi[i]):
            gap = abs(x[i] - bound)
            if np.isfinite(bound) and gap <= max(1e-6 * span, sx):
                near = (float(bound * obj.scale[i]), gap <= 1e-6 * span)
        out.append(near)
    return out


def _share(ratio: float) -> str:
    """A ratio as a percentage, "< 1%" where it would round to none (a pinned coefficient's posterior
    is not zero wide)."""
    return "< 1%" if 0 <= ratio <= 0.005 else f"{ratio:.0%}"


def _map_estimates(obj: Objective, coords: list[Coordinate], x: np.ndarray, cov, free: np.ndarray,
                   started_elsewhere: set[str] = frozenset()) -> list[Estimate]:
    out = []
    edge = _near_bound(obj, x, cov)
    held = obj.belief_sigma()
    for i, c in enumerate(coords):
        xv = float(x[i] * obj.scale[i])
        value = c.natural(xv)
        sx = float(np.sqrt(max(cov[i, i], 0.0))) if cov is not None else float("nan")
        if free[i]:
            sigma = abs(value) * sx if c.log else sx  # the delta method through exp
            note = f"pinned by the recordings (posterior {_share(sx / c.belief.sigma)} of the belief's σ)"
            alone = held[i] if held is not None else float("inf")  # what the belief alone leaves at its weight
            disputed = sx > DISPUTED_RATIO * alone
            by_belief = not disputed and sx >= POSTERIOR_RATIO * alone  # the belief, as data, did the narrowing
            if by_belief:
                note = (f"held by its belief (posterior {_share(sx / c.belief.sigma)} of the belief's σ, "
                        f"{sx / alone:.0%} of what the belief alone leaves at its weight): the recordings add little")
            elif disputed:
                note = (f"moved by recordings whose windows pull it different ways (posterior {_share(sx / c.belief.sigma)} "
                        f"of the belief's σ, {sx / alone:.1f} times what the belief alone leaves at its weight: the "
                        "σ is their scatter about the fit)")
            if edge[i] is not None:  # a curvature's σ at a wall says nothing of where the data would put it
                bound, on = edge[i]
                note = (f"{'on' if on else 'within its σ of'} the bound {c.natural(bound):g} {c.unit} of its physical "
                        f"range: {'the recordings push it beyond' if on else 'the recordings do not tell it from the bound'}"
                        " (σ from the fit's curvature, which the bound cuts)")
            physical = c.belief.sigma > 0 and c.name not in started_elsewhere
            away = abs(xv - c.mean) / c.belief.sigma if physical else None
            if away is not None and away >= STAND_IN_SIGMAS:  # Estimate.stand_in
                ratio = f", ×{value / c.prior_value:.2g}" if c.log and c.prior_value else ""
                lacks = "it stands in for something the twin's form lacks"
                if by_belief and edge[i] is None:
                    note = (f"pulled {away:.1f} σ of its belief from its prior{ratio}, by recordings that narrow it "
                            f"no more than its belief does (posterior {_share(sx / c.belief.sigma)} of the belief's σ, "
                            f"{sx / alone:.0%} of what the belief alone leaves at its weight): {lacks}")
                else:
                    note += f"; {away:.1f} σ of its belief from its prior{ratio}: {lacks}"
            stands_in = away is not None and away >= STAND_IN_SIGMAS
            out.append(Estimate(c.name, c.unit, c.prior_value, value, sigma, True, note, edge[i] is not None,
                                by_belief and edge[i] is None and not stands_in, disputed and edge[i] is None, away))
        else:
            sigma = abs(value) * c.belief.sigma if c.log else c.belief.sigma
            out.append(Estimate(c.name, c.unit, c.prior_value, c.prior_value, sigma, False,
                                f"kept at its prior with its prior's uncertainty: {c.belief.why}"))
    return out
