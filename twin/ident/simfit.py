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
from typing import Callable

import numpy as np
from scipy.optimize import least_squares

from ..errors import TwinError
from ..recordings import Prepared
from ..vessel import Vessel, check
from .windows import ModelCache, Window, as_measured, make_windows, measured, predict


@dataclass(frozen=True)
class Parameter:
    """One identifiable number of the vessel description: name, unit, how to read and
    write it, bounds, and a typical size that scales the optimiser's variable."""

    name: str
    unit: str
    get: Callable[[Vessel], float]
    put: Callable[[Vessel, float], Vessel]
    lo: float
    hi: float
    typical: float
    fd_abs: float | None = None  # an absolute finite-difference step (value units) where the cost is stepwise


DAMPING_UNITS = {"Xu": "N s/m", "Xuu": "N s2/m2", "Yv": "N s/m", "Yvv": "N s2/m2", "Yrv": "N s2/m", "Yr": "N s",
                 "Yvr": "N s2/m", "Yrr": "N s2", "Nv": "N s", "Nvv": "N s2", "Nrv": "N s2", "Nr": "N m s",
                 "Nvr": "N s2", "Nrr": "N m s2", "Yuv": "N s2/m2", "Nur": "N m s2/m"}


def _damping(name: str) -> Parameter:
    return Parameter(name, DAMPING_UNITS[name], lambda v: getattr(v.damping, name),
                     lambda v, x: replace(v, damping=replace(v.damping, **{name: x})), -1e4, 0.0, 10.0)


def _added(name: str) -> Parameter:
    pair = {"Yrdot": ("Yrdot", "Nvdot")}.get(name, (name,))
    unit = {"Xudot": "kg", "Yvdot": "kg", "Nrdot": "kg m2", "Yrdot": "kg m"}[name]
    lo = -1e3 if name != "Yrdot" else -1e2
    hi = 0.0 if name != "Yrdot" else 1e2
    return Parameter(name, unit, lambda v: getattr(v.added_mass, name),
                     lambda v, x: replace(v, added_mass=replace(v.added_mass, **{k: x for k in pair})), lo, hi, 1.0)


def _thr(field_name: str, unit: str, lo: float, hi: float, typical: float) -> Parameter:
    return Parameter(field_name, unit, lambda v: getattr(v.thrusters, field_name),
                     lambda v, x: replace(v, thrusters=replace(v.thrusters, **{field_name: x})), lo, hi, typical)


def asymmetry_param() -> Parameter:
    def get(v: Vessel) -> float:
        return v.thrusters.gain_right / v.thrusters.gain_left

    def put(v: Vessel, ratio: float) -> Vessel:
        t = v.thrusters
        mean = 0.5 * (t.gain_left + t.gain_right)
        left = 2 * mean / (1 + ratio)
        return replace(v, thrusters=replace(t, gain_left=left, gain_right=ratio * left))

    return Parameter("asymmetry", "right/left", get, put, 0.2, 5.0, 1.0)


def current_param(axis: int) -> Parameter:
    def get(v: Vessel) -> float:
        return float(v.environment.current_ned[axis])

    def put(v: Vessel, x: float) -> Vessel:
        ned = v.environment.current_ned.copy()
        ned[axis] = x
        env = replace(v.environment, current_speed_m_s=float(np.hypot(*ned)),
                      current_dir_deg=float(np.degrees(np.arctan2(ned[1], ned[0]))))
        return replace(v, environment=env)

    return Parameter(("current_north", "current_east")[axis], "m/s", get, put, -3.0, 3.0, 0.1)


def gain_param() -> Parameter:
    """Both thruster gains scaled together (the mean gain), their ratio kept."""
    def get(v: Vessel) -> float:
        return 0.5 * (v.thrusters.gain_left + v.thrusters.gain_right)

    def put(v: Vessel, g: float) -> Vessel:
        t = v.thrusters
        k = g / get(v)
        return replace(v, thrusters=replace(t, gain_left=t.gain_left * k, gain_right=t.gain_right * k))

    return Parameter("thrust_gain", "×", get, put, 0.05, 20.0, 1.0)


def _reverse_scale(prior: Vessel) -> Parameter:
    """The reverse quadratic of eq. 27 scaled against the prior's (on top of the gains, which
    act on both directions): stored back as coefficients."""
    ref = np.asarray(prior.thrusters.reverse, float)

    def get(v: Vessel) -> float:
        return float(v.thrusters.reverse[0] / ref[0]) if ref[0] else 1.0

    def put(v: Vessel, s: float) -> Vessel:
        return replace(v, thrusters=replace(v.thrusters, reverse=tuple(float(c) for c in ref * s)))

    return Parameter("reverse_scale", "×", get, put, 0.05, 20.0, 1.0)


def parameters(prior: Vessel) -> dict[str, Parameter]:
    """Every parameter `fit` can identify, by name (curve scales relative to `prior`)."""
    out = {n: _damping(n) for n in ("Xu", "Xuu", "Yv", "Yvv", "Yrv", "Yvr", "Yrr", "Nvv", "Nrv", "Nvr",
                                    "Nr", "Nrr")}
    out.update({n: _coupling(n) for n in ("Yr", "Nv")})
    out.update({n: _damping(n) for n in ("Yuv", "Nur")})
    out.update({n: _added(n) for n in ("Xudot", "Yvdot", "Yrdot", "Nrdot")})
    out.update({"thrust_gain": gain_param(), "reverse_scale": _reverse_scale(prior), "asymmetry": asymmetry_param(),
                "lag_s": _thr("lag_s", "s", 0.01, 3.0, 0.2), "delay_s": _thr("delay_s", "s", 0.0, 2.0, 0.1),
                "deadzone_fwd": _thr("deadzone_fwd", "δ̃", 0.0, 0.5, 0.05),
                "current_north": current_param(0), "current_east": current_param(1)})
    return out


def _coupling(name: str) -> Parameter:
    """Linear sway-yaw coupling (either sign is dissipative while Yv·Nr dominates)."""
    return Parameter(name, DAMPING_UNITS[name], lambda v: getattr(v.damping, name),
                     lambda v, x: replace(v, damping=replace(v.damping, **{name: x})), -1e3, 1e3, 1.0)


SETTLE_S = 1.0
START_STEP = np.array([0.01, 0.01, 0.01])  # m/s, m/s, rad/s: finite differences of the initial velocities
DEFAULT = ("Xu", "Xuu", "Yv", "Yvv", "Nr", "Nrr", "Yvdot", "Nrdot", "thrust_gain", "reverse_scale", "lag_s")


# ---------------------------------------------------------------- the fit

@dataclass
class Estimate:
    name: str
    unit: str
    prior: float
    value: float
    sigma: float | None  # 1-σ from the cluster-robust covariance; None when not identifiable
    identifiable: bool
    note: str = ""

    def to_dict(self) -> dict:
        return {"name": self.name, "unit": self.unit, "prior": self.prior, "value": self.value, "sigma": self.sigma,
                "identifiable": self.identifiable, "note": self.note}


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


class Measurements:
    """The recordings as a candidate vessel's sensors see them.

    Fixed prepared recordings (identification), or raw recordings re-prepared for each
    heading-sensor and antenna calibration a candidate carries (diagnosis of sensor
    effects: what is measured changes with the calibration, not only what is predicted).
    The grid does not change with the calibration, so windows stay valid."""

    def __init__(self, preps: list[Prepared], recordings: list | None = None, compiled=None,
                 prepare_kwargs: dict | None = None):
        """preps: the recordings prepared for `compiled.vessel` (or fixed, without recordings)."""
        self.preps, self.recordings, self.compiled = preps, recordings, compiled
        self.kwargs = prepare_kwargs or {}
        self._cache: dict[tuple, list[Prepared]] = {}
        self._key0 = self._key(compiled.vessel) if compiled is not None else None

    @staticmethod
    def _key(vessel: Vessel) -> tuple:
        s = vessel.sensors
        return (s.heading_bias_deg, tuple(s.compass_deviation_deg), tuple(s.antenna_offset_m),
                s.heading_bias_by_log_deg)

    def for_vessel(self, vessel: Vessel) -> list[Prepared]:
        if self.recordings is None or self._key(vessel) == self._key0:
            return self.preps
        key = self._key(vessel)
        if key not in self._cache:
            from ..engine.mjcf import CompiledVessel
            from ..replay import prepare_for

            cv = CompiledVessel(vessel, self.compiled.model, self.compiled.geometry)
            self._cache[key] = [prepare_for(r, cv, **self.kwargs) for r in self.recordings]
            if len(self._cache) > 64:
                self._cache.pop(next(iter(self._cache)))
        return self._cache[key]


class Objective:
    """Free-run residuals of the windows, (ν̂ − ν)/σ_dof for u, v, r (σ_dof the spread of
    the measured ν), as a function of the scaled parameter vector x (value = x·scale);
    Jacobians by forward differences in one batch.

    Velocities, not positions or heading: a free run's position and heading errors are
    mostly the integral of its initial velocity error (the start is a smoothed
    measurement), which would outweigh the dynamics being fitted. For the same reason
    the first settle_s of each window is not compared: a fit that followed the decay of
    a noisy initial state would bend the fast dynamics (yaw and sway inertia) to do it.

    free_start: each window's initial velocities are nuisance parameters, re-estimated for
    every candidate (output-error identification with unknown initial state). A smoothed
    GNSS velocity is off by a few cm/s at any instant; a free run from it carries that
    error, and a least-squares fit answers by changing the dynamics that propagate it
    (errors in variables): on synthetic data with 2 cm GNSS jitter, yaw inertia came out
    60 % high from measured starts and within 3 % from the true ones. The correction is
    linear (three extra runs per candidate give the sensitivities to u₀, v₀, r₀, then a
    3×3 least squares per window), which the few-cm/s start errors allow."""

    def __init__(self, prior: Vessel, params: list[Parameter], preps: list[Prepared] | Measurements,
                 windows: list[Window], cache: ModelCache | None = None, settle_s: float = SETTLE_S,
                 free_start: bool = False):
        self.free_start = free_start
        self.data = preps if isinstance(preps, Measurements) else Measurements(preps)
        self.settle_s = settle_s
        self.prior, self.params, self.preps, self.windows = prior, params, self.data.preps, windows
        self.cache = cache or ModelCache()
        self.scale = np.array([max(abs(p.get(prior)), p.typical) for p in params])
        self.steps = np.array([1e-4 if p.fd_abs is None else p.fd_abs / s for p, s in zip(params, self.scale)])
        self.meas = self._measured(self.preps)
        self.valid = np.isfinite(self.meas)
        h = float(self.preps[0].settings.get("grid_dt", 0.1))
        self.valid[:, : int(round(settle_s / h))] = False
        sd = np.array([np.nanstd(self.meas[..., k]) for k in range(3)])
        self.sigma = np.where(sd > 1e-6, sd, 1.0)
        self.evaluations = 0
        self._last: tuple[np.ndarray, np.ndarray] | None = None

    def _measured(self, preps: list[Prepared]) -> np.ndarray:
        return measured(preps, self.windows)[1][:, 1:]

    def _seen(self, nu: np.ndarray, preps: list[Prepared]) -> np.ndarray:
        """The prediction as the measurement would show it (see windows.as_measured)."""
        return as_measured(nu, preps, self.windows)

    @property
    def x_prior(self) -> np.ndarray:
        return np.array([p.get(self.prior) for p in self.params]) / self.scale

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return (np.array([p.lo for p in self.params]) / self.scale, np.array([p.hi for p in self.params]) / self.scale)

    def vessel(self, x: np.ndarray) -> Vessel:
        v = self.prior
        for p, xi, s in zip(self.params, x, self.scale):
            v = p.put(v, float(xi * s))
        return v

    def _residuals(self, vessels: list[Vessel]) -> list[np.ndarray]:
        """Flat residuals of each vessel on the valid samples; with free_start, the first
        vessel's initial-state sensitivities serve all (the others are its finite-difference
        neighbours, whose sensitivities differ by second-order amounts)."""
        full = self._full(vessels, with_start=self.free_start)
        if not self.free_start:
            return [r if r.ndim == 1 else r[self.valid] for r in full]
        base, sens = full[0], full[1:4]
        if base.ndim == 1:  # the base twin is not physical: nothing to linearise about
            return [r if r.ndim == 1 else r[self.valid] for r in [base] + full[4:]]
        S = np.stack([np.where(self.valid, np.nan_to_num((s - base) / d, nan=0.0, posinf=0.0, neginf=0.0), 0.0)
                      for s, d in zip(sens, START_STEP)], axis=-1)  # (W, n, 3 dof, 3 start)
        return [r if r.ndim == 1 else self._free_started(r, S) for r in [base] + full[4:]]

    def _free_started(self, r: np.ndarray, S: np.ndarray) -> np.ndarray:
        """Residuals with each window's initial velocities re-estimated (linearised about
        the base twin): r + S·Δ with Δ = argmin |r + S·Δ|² per window."""
        r = np.where(self.valid, np.nan_to_num(r, nan=10.0), 0.0)
        W = r.shape[0]
        Sf, rf = S.reshape(W, -1, 3), r.reshape(W, -1)
        G = np.einsum("wki,wkj->wij", Sf, Sf)
        G += (1e-9 * np.trace(G, axis1=1, axis2=2)[:, None, None] + 1e-12) * np.eye(3)
        delta = -np.linalg.solve(G, np.einsum("wki,wk->wi", Sf, rf)[..., None])[..., 0]
        return (rf + np.einsum("wki,wi->wk", Sf, delta)).reshape(r.shape)[self.valid]

    def _full(self, vessels: list[Vessel], with_start: bool) -> list[np.ndarray]:
        """(W, n, 3) scaled residuals per vessel (NaN where the twin diverged), or a flat array
        of 10s for a vessel that is not physical; with_start: after the first vessel, its
        three runs from initial velocities offset by START_STEP."""
        runs = list(vessels[:1]) * (4 if with_start else 1) + list(vessels[1:])
        offsets = ([None] + [np.eye(3)[k] * START_STEP[k] for k in range(3)] if with_start else [None])
        offsets += [None] * (len(runs) - len(offsets))
        ok = []
        for v in runs:
            try:
                check(v)
                ok.append(True)
            except TwinError:
                ok.append(False)
        good = [i for i, g in enumerate(ok) if g]
        seen = [self.data.for_vessel(runs[i]) for i in good]
        preds = predict([runs[i] for i in good], seen, self.windows, self.cache,
                        nu_offsets=[offsets[i] for i in good]) if good else []
        self.evaluations += len(vessels)
        out: list[np.ndarray] = [np.full(int(self.valid.sum()), 10.0)] * len(runs)
        for i, prediction, preps in zip(good, preds, seen):
            meas = self.meas if preps is self.preps else self._measured(preps)
            pred = self._seen(prediction.nu, preps)[:, 1:]
            r = (pred - meas) / self.sigma
            if not with_start or i >= 4:
                r = np.where(np.isfinite(pred), r, 10.0)  # a diverged twin costs a lot, smoothly enough
            out[i] = r
        return out

    def residuals(self, x: np.ndarray) -> np.ndarray:
        if self._last is not None and np.array_equal(self._last[0], x):
            return self._last[1]
        r = self._residuals([self.vessel(x)])[0]
        self._last = (x.copy(), r)
        return r

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        lo, hi = self.bounds()
        steps = np.where(x + self.steps <= hi, self.steps, -self.steps)  # stay inside the bounds
        trial = [x.copy() for _ in x]
        for i in range(len(x)):
            trial[i][i] += steps[i]
        rs = self._residuals([self.vessel(x)] + [self.vessel(t) for t in trial])
        self._last = (x.copy(), rs[0])
        return np.column_stack([(r - rs[0]) / h for r, h in zip(rs[1:], steps)])

    def window_index(self) -> np.ndarray:
        """Window number of each residual (the clusters of the sandwich covariance)."""
        idx = np.broadcast_to(np.arange(len(self.windows))[:, None, None], self.meas.shape)
        return idx[self.valid]


def check_names(prior: Vessel, names, anchor: str) -> list[str]:
    """The parameters to fit, checked: known, and with one absolute anchor (module docstring)."""
    table = parameters(prior)
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
    table = parameters(prior)
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
    estimates = _estimates(obj, sol.x, J, r)
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
        again = _estimates(sub, x1, sub.jacobian(x1), r) if pinned else []
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


def _estimates(obj: Objective, x: np.ndarray, J: np.ndarray, r: np.ndarray) -> list[Estimate]:
    """Values, cluster-robust 1-σ, and whether the data pins each parameter down."""
    norms = np.linalg.norm(J, axis=0)
    cov = _sandwich(J, r, obj.window_index())
    out = []
    for i, p in enumerate(obj.params):
        value, prior = float(x[i] * obj.scale[i]), float(p.get(obj.prior))
        sigma = float(np.sqrt(cov[i, i]) * obj.scale[i]) if cov is not None and cov[i, i] >= 0 else None
        note = ""
        if norms[i] < 1e-6 * max(norms.max(), 1e-12):
            ok, note = False, "no effect on these recordings (the motion that excites it is missing)"
        elif sigma is None or not np.isfinite(sigma):
            ok, note = False, "not separable from the other parameters on these recordings"
        elif sigma > max(abs(value), obj.scale[i] * 0.05):
            ok, note = False, f"uncertainty ±{sigma:.3g} exceeds the value: not pinned down by these recordings"
        else:
            ok = True
        out.append(Estimate(p.name, p.unit, prior, value, sigma if ok else None, ok, note))
    return out


def _sandwich(J: np.ndarray, r: np.ndarray, clusters: np.ndarray) -> np.ndarray | None:
    """(JᵀJ)⁻¹ (Σ_w g_w g_wᵀ) (JᵀJ)⁻¹ with g_w = J_wᵀ r_w summed over the residuals of window w."""
    JtJ = J.T @ J
    if np.linalg.cond(JtJ) > 1e14:
        return None
    A = np.linalg.inv(JtJ)
    g = np.zeros((clusters.max() + 1, J.shape[1]))
    np.add.at(g, clusters, J * r[:, None])
    return A @ (g.T @ g) @ A
