"""One identifiable number of the vessel description, and the ways it is reached.

A Quantity reads and writes one number of a Vessel (get/put), with the bounds a fit keeps it
in and a typical size that scales the optimiser's variable. Identification fits hull and
thruster coefficients as Quantities (coefficients.py); every effect of the library says which
Quantities fit it (library.py). The factories here are the only places that know where a
number lives in the description.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from ..vessel import Vessel


@dataclass(frozen=True)
class Quantity:
    """name, unit, get(vessel) → float, put(vessel, value) → vessel, bounds [lo, hi], typical
    size; fd_abs: an absolute finite-difference step (value units) where the cost is a staircase;
    edges_unphysical: the bounds are not physical limits but the end of any plausible value (a
    coefficient ×20 or ×0.05 of a first-principles prior; a wind's side-force coefficient at none or
    beyond a flat plate's), so a fit that ends on one says the form is
    off, not that the number is that large (diagnose/search.py)."""

    name: str
    unit: str
    get: Callable[[Vessel], float]
    put: Callable[[Vessel, float], Vessel]
    lo: float
    hi: float
    typical: float
    fd_abs: float | None = None
    edges_unphysical: bool = False

    def renamed(self, name: str, lo: float | None = None, hi: float | None = None) -> "Quantity":
        return replace(self, name=name, lo=self.lo if lo is None else lo, hi=self.hi if hi is None else hi)


def member(group: str, attr: str, unit: str, lo: float, hi: float, typical: float, *, name: str | None = None,
           index: int | None = None, also: tuple[str, ...] = (), fd_abs: float | None = None) -> Quantity:
    """vessel.<group>.<attr> (group "vessel": the vessel's own field), item `index` of a tuple
    field; `also`: fields of the group that always take the same value (a symmetric pair)."""

    def holder(v: Vessel):
        return v if group == "vessel" else getattr(v, group)

    def get(v: Vessel) -> float:
        x = getattr(holder(v), attr)
        return float(x[index] if index is not None else x)

    def put(v: Vessel, x: float) -> Vessel:
        old = getattr(holder(v), attr)
        new = tuple(x if i == index else c for i, c in enumerate(old)) if index is not None else x
        values = {attr: new, **{a: new for a in also}}
        if group == "vessel":
            return replace(v, **values)
        return replace(v, **{group: replace(holder(v), **values)})

    return Quantity(name or attr, unit, get, put, lo, hi, typical, fd_abs)


def scale_of(prior: Vessel, group: str, attr: str, unit: str, also: tuple[str, ...] = ()) -> Quantity:
    """A coefficient as a multiple of the prior's own value (the coefficient must be non-zero)."""
    base = getattr(getattr(prior, group), attr)

    def get(v: Vessel) -> float:
        return getattr(getattr(v, group), attr) / base

    def put(v: Vessel, s: float) -> Vessel:
        values = {attr: base * s, **{a: base * s for a in also}}
        return replace(v, **{group: replace(getattr(v, group), **values)})

    return Quantity(f"{attr}_scale", f"× {unit}", get, put, 0.05, 20.0, 1.0, edges_unphysical=True)


def ned_component(kind: str, axis: int, lo: float, hi: float, typical: float) -> Quantity:
    """The current (water velocity, towards) or wind (air velocity, towards) north (axis 0) or east
    (axis 1), m/s: a fit moves along components, the description keeps speed and direction."""
    name = f"{kind}_{('north', 'east')[axis]}"

    def get(v: Vessel) -> float:
        env = v.environment
        return float((env.current_ned if kind == "current" else env.wind_ned)[axis])

    def put(v: Vessel, x: float) -> Vessel:
        env = v.environment
        ned = (env.current_ned if kind == "current" else env.wind_ned).copy()
        ned[axis] = x
        speed = float(np.hypot(*ned))
        if kind == "current":
            env = replace(env, current_speed_m_s=speed, current_dir_deg=float(np.degrees(np.arctan2(ned[1], ned[0]))))
        else:  # the description holds where the wind comes from
            env = replace(env, wind_speed_m_s=speed, wind_dir_deg=float(np.degrees(np.arctan2(-ned[1], -ned[0]))))
        return replace(v, environment=env)

    return Quantity(name, "m/s", get, put, lo, hi, typical)


def _ratio(v: Vessel) -> float:
    return v.thrusters.gain_right / v.thrusters.gain_left


def _mean_gain(v: Vessel) -> float:
    return 0.5 * (v.thrusters.gain_left + v.thrusters.gain_right)


def gain_ratio(name: str = "asymmetry", lo: float = 0.2, hi: float = 5.0, prior: Vessel | None = None) -> Quantity:
    """Right/left thrust gain, their mean kept (so the surge thrust at equal PWM stays); with `prior`,
    as a multiple of the prior's own ratio (an effect's value: thruster_asymmetry multiplies it)."""
    ref = 1.0 if prior is None else _ratio(prior)

    def get(v: Vessel) -> float:
        return _ratio(v) / ref

    def put(v: Vessel, ratio: float) -> Vessel:
        t = v.thrusters
        left = 2 * _mean_gain(v) / (1 + ratio * ref)
        return replace(v, thrusters=replace(t, gain_left=left, gain_right=ratio * ref * left))

    return Quantity(name, "right/left", get, put, lo, hi, 1.0, edges_unphysical=True)


def gain_mean(name: str = "thrust_gain", lo: float = 0.05, hi: float = 20.0, prior: Vessel | None = None) -> Quantity:
    """Both thruster gains scaled together (their mean), their ratio kept; with `prior`, as a multiple
    of the prior's own mean gain (an effect's value: thrust_gain multiplies the gains)."""
    ref = 1.0 if prior is None else _mean_gain(prior)

    def get(v: Vessel) -> float:
        return _mean_gain(v) / ref

    def put(v: Vessel, g: float) -> Vessel:
        t = v.thrusters
        k = g * ref / _mean_gain(v)
        return replace(v, thrusters=replace(t, gain_left=t.gain_left * k, gain_right=t.gain_right * k))

    return Quantity(name, "×", get, put, lo, hi, 1.0, edges_unphysical=True)


def reverse_scale(prior: Vessel) -> Quantity:
    """The reverse quadratic of the thrust map scaled against the prior's (on top of the gains,
    which act on both directions), stored back as coefficients."""
    ref = np.asarray(prior.thrusters.reverse, float)

    def get(v: Vessel) -> float:
        return float(v.thrusters.reverse[0] / ref[0]) if ref[0] else 1.0

    def put(v: Vessel, s: float) -> Vessel:
        return replace(v, thrusters=replace(v.thrusters, reverse=tuple(float(c) for c in ref * s)))

    return Quantity("reverse_scale", "×", get, put, 0.05, 20.0, 1.0, edges_unphysical=True)


def dead_zone_edge(which: str) -> Quantity:
    """A dead-zone edge as a width ≥ 0 in normalised PWM δ̃ (the reverse edge is stored negative)."""
    key = "deadzone_fwd" if which == "fwd" else "deadzone_rev"
    sign = 1.0 if which == "fwd" else -1.0

    def get(v: Vessel) -> float:
        return sign * getattr(v.thrusters, key)

    def put(v: Vessel, x: float) -> Vessel:
        return replace(v, thrusters=replace(v.thrusters, **{key: sign * x}))

    return Quantity(which, "δ̃", get, put, 0.0, 0.3, 0.05, fd_abs=0.005)


def side_dead_zone_edge(side: str, which: str) -> Quantity:
    """One thruster's own dead-zone edge as a width ≥ 0 in δ̃ (`ThrusterModel.deadzone_left` or
    `_right`): read from the shared edges until the thruster has its own."""
    key = f"deadzone_{side}"
    k = 0 if which == "fwd" else 1
    sign = 1.0 if which == "fwd" else -1.0

    def get(v: Vessel) -> float:
        return sign * v.thrusters.edges_of(0 if side == "left" else 1)[k]

    def put(v: Vessel, x: float) -> Vessel:
        edges = list(v.thrusters.edges_of(0 if side == "left" else 1))
        edges[k] = sign * x
        return replace(v, thrusters=replace(v.thrusters, **{key: (float(edges[0]), float(edges[1]))}))

    return Quantity(which, "δ̃", get, put, 0.0, 0.3, 0.05, fd_abs=0.005)


def start_edge(which: str) -> Quantity:
    """Where a stopped motor starts, as a width ≥ 0 in normalised PWM δ̃ (never inside the dead zone:
    ThrusterModel.start_edges)."""
    key = "start_fwd" if which == "fwd" else "start_rev"
    sign = 1.0 if which == "fwd" else -1.0

    def get(v: Vessel) -> float:
        return sign * v.thrusters.start_edges[0 if which == "fwd" else 1]

    def put(v: Vessel, x: float) -> Vessel:
        return replace(v, thrusters=replace(v.thrusters, **{key: sign * x}))

    return Quantity(which, "δ̃", get, put, 0.0, 0.4, 0.05, fd_abs=0.005)


def log_heading_bias(log: str) -> Quantity:
    """One log's own heading bias (deg), in sensors.heading_bias_by_log_deg."""
    def get(v: Vessel) -> float:
        return float(dict(v.sensors.heading_bias_by_log_deg).get(log, 0.0))

    def put(v: Vessel, x: float) -> Vessel:
        table = dict(v.sensors.heading_bias_by_log_deg) | {log: x}
        return replace(v, sensors=replace(v.sensors, heading_bias_by_log_deg=tuple(sorted(table.items()))))

    return Quantity(log, "deg", get, put, -30.0, 30.0, 1.0)


def log_wind(log: str, axis: int) -> Quantity:
    """One log's own wind (environment.wind_by_log), as the air's velocity north (axis 0) or east
    (axis 1), m/s, like ned_component's: a log without an entry sees the constant wind."""
    def table(v: Vessel) -> dict[str, np.ndarray]:
        return {n: -speed * np.array([math.cos(math.radians(frm)), math.sin(math.radians(frm))])
                for n, speed, frm in v.environment.wind_by_log}

    def get(v: Vessel) -> float:
        return float(table(v).get(log, v.environment.wind_ned)[axis])

    def put(v: Vessel, x: float) -> Vessel:
        winds = table(v)
        air = winds.get(log, v.environment.wind_ned).copy()
        air[axis] = x
        winds[log] = air
        entries = tuple(sorted((n, float(np.hypot(*a)), float(np.degrees(np.arctan2(-a[1], -a[0]))))
                               for n, a in winds.items()))
        return replace(v, environment=replace(v.environment, wind_by_log=entries))

    return Quantity(f"{log}@wind_{('north', 'east')[axis]}", "m/s", get, put, -25.0, 25.0, 1.0)


def log_magnitude(q: Quantity, prior: Vessel, span: float = math.log(100.0)) -> Quantity:
    """q as ln|value| with the prior's sign fixed: a dissipative coefficient or a positive scale
    stays one, and a log-normal belief about it is a normal one about this coordinate. Bounds:
    the prior's magnitude divided or multiplied by exp(span) (×/÷ 100 by default)."""
    value = q.get(prior)
    if value == 0.0:
        raise ValueError(f"{q.name}: a zero prior has no magnitude to take the logarithm of")
    sign, centre = math.copysign(1.0, value), math.log(abs(value))

    def get(v: Vessel) -> float:
        x = q.get(v)
        return math.log(abs(x)) if x * sign > 0 else centre - span

    def put(v: Vessel, x: float) -> Vessel:
        return q.put(v, sign * math.exp(x))

    return Quantity(q.name, f"ln({q.unit})", get, put, centre - span, centre + span, 1.0)
