"""The candidate physical effects a diagnosis fits, each as identifiable parameters of
the one vessel description (twin.ident.effects names them; simfit.Parameter reads
and writes them), with where to start looking.

Every candidate is relative to the twin being diagnosed (the prior): a current or a
heading bias starts at zero, a damping or added-mass coefficient as a scale of the
prior's own value (a coefficient the prior does not have cannot be scaled, and is not
offered), a thrust lag at a typical value. Time shifts (input delay, clock offset)
change which logged PWM sample drives each engine step, so their cost is a staircase
in the shift: they are scanned on a grid, not followed down a gradient. A dead zone is
a staircase too, and a flat one near the prior: widening it changes the thrust only
where the PWM sits between the old and the new edge, so the gradient at the prior
says nothing about a dead zone twice as wide. It is scanned along equal widths, then
each edge on its own.

Families group effects that can imitate each other in a recording: the diagnosis
checks them against each other before it names one (search.py).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from ..ident.effects import ADDED_MASS, LINEAR_DAMPING, QUADRATIC_DAMPING, Effect, effect
from ..ident.simfit import DAMPING_UNITS, Parameter, asymmetry_param, current_param, gain_param
from ..vessel import Vessel

ADDED_MASS_UNITS = {"Xudot": "kg", "Yvdot": "kg", "Yrdot": "kg m", "Nrdot": "kg m2"}


@dataclass(frozen=True)
class Candidate:
    """One effect as parameters to fit. `starts`: starting values (one tuple per start);
    `scan`: points (one value per parameter) for a staircase cost, and `scan_step` the
    step of the finer scan around the best point, per parameter; `to_effect` turns
    fitted values into the effect's own parameters (for the report and the CLI text)."""

    name: str
    params: tuple[Parameter, ...]
    starts: tuple[tuple[float, ...], ...]
    to_effect: Callable[[dict[str, float]], Effect]
    family: str
    scan: tuple[tuple[float, ...], ...] = ()
    scan_step: tuple[float, ...] = ()
    time_shift: bool = False  # the engine's step sets its resolution: never screened at a coarse step

    @property
    def names(self) -> list[str]:
        return [p.name for p in self.params]


def _env_wind(axis: int) -> Parameter:
    """The air's velocity (towards) north or east; the effect reports speed and the direction it comes from."""
    def get(v: Vessel) -> float:
        return float(v.environment.wind_ned[axis])

    def put(v: Vessel, x: float) -> Vessel:
        air = v.environment.wind_ned.copy()
        air[axis] = x
        env = replace(v.environment, wind_speed_m_s=float(np.hypot(*air)),
                      wind_dir_deg=float(np.degrees(np.arctan2(-air[1], -air[0]))))
        return replace(v, environment=env)

    return Parameter(("wind_north", "wind_east")[axis], "m/s", get, put, -25.0, 25.0, 1.0)


def _field(group: str, name: str, unit: str, lo: float, hi: float, typical: float, fd_abs=None,
           index: int | None = None, key: str | None = None) -> Parameter:
    """A number of vessel.<group> (thrusters, sensors) or the vessel itself; index for tuple fields."""
    attr = key or name

    def holder(v: Vessel):
        return v if group == "vessel" else getattr(v, group)

    def get(v: Vessel) -> float:
        x = getattr(holder(v), attr)
        return float(x[index] if index is not None else x)

    def put(v: Vessel, x: float) -> Vessel:
        old = getattr(holder(v), attr)
        new = tuple(x if i == index else c for i, c in enumerate(old)) if index is not None else x
        if group == "vessel":
            return replace(v, **{attr: new})
        return replace(v, **{group: replace(holder(v), **{attr: new})})

    return Parameter(name, unit, get, put, lo, hi, typical, fd_abs)


def _scale(prior: Vessel, group: str, key: str, unit: str, pair: str | None = None) -> Parameter:
    """A coefficient of the prior's damping or added mass as a scale of its prior value."""
    base = getattr(getattr(prior, group), key)

    def get(v: Vessel) -> float:
        return getattr(getattr(v, group), key) / base

    def put(v: Vessel, s: float) -> Vessel:
        values = {key: base * s} | ({pair: base * s} if pair else {})
        return replace(v, **{group: replace(getattr(v, group), **values)})

    return Parameter(f"{key}_scale", f"× {unit}", get, put, 0.05, 20.0, 1.0)


def _dead_zone(which: str) -> Parameter:
    key = "deadzone_fwd" if which == "fwd" else "deadzone_rev"
    sign = 1.0 if which == "fwd" else -1.0

    def get(v: Vessel) -> float:
        return sign * getattr(v.thrusters, key)

    def put(v: Vessel, x: float) -> Vessel:
        return replace(v, thrusters=replace(v.thrusters, **{key: sign * x}))

    return Parameter(which, "δ̃", get, put, 0.0, 0.3, 0.05, fd_abs=0.005)


def _grid(lo: float, hi: float, step: float) -> tuple[tuple[float], ...]:
    """One-parameter scan points lo, lo + step, ..., hi."""
    return tuple((float(x),) for x in np.round(np.arange(lo, hi + step / 2, step), 4))


def _log_bias(log: str) -> Parameter:
    """One log's own heading bias (deg), in sensors.heading_bias_by_log_deg."""
    def get(v: Vessel) -> float:
        return float(dict(v.sensors.heading_bias_by_log_deg).get(log, 0.0))

    def put(v: Vessel, x: float) -> Vessel:
        table = dict(v.sensors.heading_bias_by_log_deg) | {log: x}
        return replace(v, sensors=replace(v.sensors, heading_bias_by_log_deg=tuple(sorted(table.items()))))

    return Parameter(log, "deg", get, put, -30.0, 30.0, 1.0)


def _current_effect(p: dict) -> Effect:
    return effect("current", speed_m_s=float(np.hypot(p["current_north"], p["current_east"])),
                  dir_deg=float(np.degrees(np.arctan2(p["current_east"], p["current_north"]))))


def _wind_effect(p: dict) -> Effect:
    return effect("wind", speed_m_s=float(np.hypot(p["wind_north"], p["wind_east"])),
                  dir_deg=float(np.degrees(np.arctan2(-p["wind_east"], -p["wind_north"]))))


def _scales_effect(name: str) -> Callable[[dict], Effect]:
    return lambda p: effect(name, **{k[: -len("_scale")]: v for k, v in p.items()})


def candidates(prior: Vessel, logs: list[str] = ()) -> dict[str, Candidate]:
    """The library, for this prior and the names of the logs diagnosed together (see the
    module docstring); a heading bias per log needs two logs at least."""
    out: list[Candidate] = [
        Candidate("current", (current_param(0), current_param(1)), ((0.0, 0.0),), _current_effect, "drift"),
        Candidate("thruster_lag", (_field("thrusters", "tau_s", "s", 0.02, 3.0, 0.2, key="lag_s"),),
                  ((0.15,), (0.6,)), lambda p: effect("thruster_lag", tau_s=p["tau_s"]), "timing"),
        Candidate("input_delay", (_field("thrusters", "delay_s", "s", 0.0, 1.5, 0.1),), ((0.0,),),
                  lambda p: effect("input_delay", delay_s=p["delay_s"]), "timing",
                  scan=_grid(0.0, 1.2, 0.12), scan_step=(0.01,), time_shift=True),
        Candidate("clock_offset", (_field("sensors", "offset_s", "s", -1.5, 1.5, 0.1, key="pwm_clock_offset_s"),),
                  ((0.0,),), lambda p: effect("clock_offset", offset_s=p["offset_s"]), "timing",
                  scan=_grid(-0.96, 0.96, 0.12), scan_step=(0.01,), time_shift=True),
        Candidate("dead_zone", (_dead_zone("fwd"), _dead_zone("rev")),
                  ((prior.thrusters.deadzone_fwd, -prior.thrusters.deadzone_rev),),
                  lambda p: effect("dead_zone", fwd=p["fwd"], rev=p["rev"]), "thrust",
                  scan=((prior.thrusters.deadzone_fwd, -prior.thrusters.deadzone_rev),)
                  + tuple((w, w) for w, in _grid(0.0, 0.3, 0.025)),
                  scan_step=(0.0125, 0.0125)),
        Candidate("thruster_asymmetry", (replace(asymmetry_param(), name="ratio", lo=0.3, hi=3.0),), ((1.0,),),
                  lambda p: effect("thruster_asymmetry", ratio=p["ratio"]), "turning"),
        Candidate("thrust_gain", (replace(gain_param(), name="scale", lo=0.2, hi=5.0),), ((1.0,),), lambda p: effect("thrust_gain", scale=p["scale"]), "thrust"),
        Candidate("thrust_decay", (_field("thrusters", "per_min", "1/min", 0.0, 0.6, 0.05, key="decay_per_min"),),
                  ((0.02,),), lambda p: effect("thrust_decay", per_min=p["per_min"]), "thrust"),
        Candidate("thrust_speed_loss", (_field("thrusters", "per_m_s", "s/m", 0.0, 0.8, 0.1,
                                               key="speed_loss_per_m_s"),),
                  ((0.05,),), lambda p: effect("thrust_speed_loss", per_m_s=p["per_m_s"]), "drag"),
        Candidate("heading_bias", (_field("sensors", "bias_deg", "deg", -30.0, 30.0, 1.0, key="heading_bias_deg"),),
                  ((0.0,),), lambda p: effect("heading_bias", bias_deg=p["bias_deg"]), "drift"),
        Candidate("compass_deviation", (_field("sensors", "b_deg", "deg", -30.0, 30.0, 1.0, index=0, key="compass_deviation_deg"),
                                        _field("sensors", "c_deg", "deg", -30.0, 30.0, 1.0, index=1, key="compass_deviation_deg")),
                  ((0.0, 0.0),), lambda p: effect("compass_deviation", b_deg=p["b_deg"], c_deg=p["c_deg"]), "drift"),
        Candidate("gnss_lever_arm", (_field("sensors", "dx_m", "m", -2.0, 2.0, 0.1, index=0, key="antenna_offset_m"),
                                     _field("sensors", "dy_m", "m", -2.0, 2.0, 0.1, index=1, key="antenna_offset_m")),
                  ((0.0, 0.0),), lambda p: effect("gnss_lever_arm", dx_m=p["dx_m"], dy_m=p["dy_m"]), "turning"),
        Candidate("coupling_damping", (_field("damping", "Yr", "N s", -60.0, 60.0, 1.0, key="Yr"),
                                       _field("damping", "Nv", "N s", -60.0, 60.0, 1.0, key="Nv")),
                  ((prior.damping.Yr, prior.damping.Nv),),
                  lambda p: effect("coupling_damping", Yr=p["Yr"], Nv=p["Nv"]), "turning"),
        Candidate("speed_damping", (_field("damping", "Yuv", "N s2/m2", -300.0, 0.0, 5.0, key="Yuv"),
                                    _field("damping", "Nur", "N m s2/m", -300.0, 0.0, 5.0, key="Nur")),
                  ((prior.damping.Yuv, prior.damping.Nur),),
                  lambda p: effect("speed_damping", Yuv=p["Yuv"], Nur=p["Nur"]), "drag"),
        Candidate("cg_offset", (_field("vessel", "dx_m", "m", -0.4, 0.4, 0.05, index=0, key="cg_offset_m"),
                                _field("vessel", "dy_m", "m", -0.4, 0.4, 0.05, index=1, key="cg_offset_m")),
                  ((0.0, 0.0),), lambda p: effect("cg_offset", dx_m=p["dx_m"], dy_m=p["dy_m"]), "inertia"),
    ]
    logs = list(dict.fromkeys(logs))
    if len(logs) >= 2:
        out.append(Candidate("heading_bias_per_log", tuple(_log_bias(n) for n in logs), (tuple(0.0 for _ in logs),),
                             lambda p: effect("heading_bias_per_log", **p), "drift"))
    if prior.wind_load.frontal_area_m2 > 0 or prior.wind_load.lateral_area_m2 > 0:
        starts = tuple((5 * np.cos(a), 5 * np.sin(a)) for a in np.radians([0, 90, 180, 270]))
        out.append(Candidate("wind", (_env_wind(0), _env_wind(1)), starts, _wind_effect, "drift"))
    for name, group, keys, family in (("quadratic_damping", "damping", QUADRATIC_DAMPING, "drag"),
                                      ("linear_damping", "damping", LINEAR_DAMPING, "drag"),
                                      ("added_mass", "added_mass", ADDED_MASS, "inertia")):
        present = [k for k in keys if getattr(getattr(prior, group), k) != 0.0]
        if name == "linear_damping":
            present = [k for k in present if k not in ("Yr", "Nv")]  # coupling_damping's
        if not present:
            continue
        units = {k: DAMPING_UNITS.get(k) or ADDED_MASS_UNITS[k] for k in present}
        params = tuple(_scale(prior, group, k, units[k], "Nvdot" if k == "Yrdot" else None) for k in present)
        out.append(Candidate(name, params, (tuple(1.0 for _ in present),), _scales_effect(name), family))
    return {c.name: c for c in out}
