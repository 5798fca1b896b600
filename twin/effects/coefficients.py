"""The coefficients of the vessel description that identification fits one by one, with their
units, the bounds that keep a fit physical and what is believed about each before any data: damping of seed 004 eq. 7 (Fossen's signs,
so ≤ 0 where a term dissipates), added mass ≤ 0 with M_A symmetric, the thrust curve's
scales, lag, delay, dead zone and a steady current."""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..vessel import Vessel
from .quantity import Quantity, gain_mean, gain_ratio, member, ned_component, reverse_scale

DAMPING_UNITS = {"Xu": "N s/m", "Xuu": "N s2/m2", "Yv": "N s/m", "Yvv": "N s2/m2", "Yrv": "N s2/m", "Yr": "N s",
                 "Yvr": "N s2/m", "Yrr": "N s2", "Nv": "N s", "Nvv": "N s2", "Nrv": "N s2", "Nr": "N m s",
                 "Nvr": "N s2", "Nrr": "N m s2", "Yuv": "N s2/m2", "Nur": "N m s2/m"}
ADDED_MASS_UNITS = {"Xudot": "kg", "Yvdot": "kg", "Yrdot": "kg m", "Nrdot": "kg m2"}
QUADRATIC_DAMPING = ("Xuu", "Yvv", "Yrv", "Yvr", "Yrr", "Nvv", "Nrv", "Nvr", "Nrr")
LINEAR_DAMPING = ("Xu", "Yv", "Yr", "Nv", "Nr")
ADDED_MASS = ("Xudot", "Yvdot", "Yrdot", "Nrdot")
# what `twin identify` fits unless told otherwise: seed 004 eq. 7's main damping terms, the yaw and sway
# added mass, the thrust curve and its lag
DEFAULT_FIT = ("Xu", "Xuu", "Yv", "Yvv", "Nr", "Nrr", "Yvdot", "Nrdot", "thrust_gain", "reverse_scale", "lag_s")
# what `twin identify` considers, in groups a choice frees or keeps at the prior together
FIT_GROUPS = {
    "surge": ("thrust_gain", "Xu", "Xuu"),
    "yaw": ("Nr", "Nrr", "Nrdot"),
    "sway": ("Yv", "Yvv", "Yvdot"),
    "thrust curve": ("reverse_scale", "lag_s"),
    "asymmetry": ("asymmetry",),
    "speed damping": ("Yuv", "Nur"),
    "coupling": ("Yr", "Nv"),
}


def damping(name: str) -> Quantity:
    """A damping coefficient, dissipative sign (≤ 0)."""
    return member("damping", name, DAMPING_UNITS[name], -1e4, 0.0, 10.0)


def coupling(name: str) -> Quantity:
    """Linear sway-yaw coupling Yr, Nv: either sign is dissipative while Yv·Nr dominates."""
    return member("damping", name, DAMPING_UNITS[name], -1e3, 1e3, 1.0)


def added_mass(name: str) -> Quantity:
    """An added-mass derivative ≤ 0 (Yrdot either sign, Nvdot kept equal: M_A symmetric)."""
    lo, hi = (-1e2, 1e2) if name == "Yrdot" else (-1e3, 0.0)
    return member("added_mass", name, ADDED_MASS_UNITS[name], lo, hi, 1.0, also=("Nvdot",) if name == "Yrdot" else ())


def coefficients(prior: Vessel) -> dict[str, Quantity]:
    """Every coefficient identification can fit, by name (curve scales relative to `prior`)."""
    out = {n: damping(n) for n in ("Xu", "Xuu", "Yv", "Yvv", "Yrv", "Yvr", "Yrr", "Nvv", "Nrv", "Nvr", "Nr", "Nrr")}
    out.update({n: coupling(n) for n in ("Yr", "Nv")})
    out.update({n: damping(n) for n in ("Yuv", "Nur")})
    out.update({n: added_mass(n) for n in ADDED_MASS})
    out.update({"thrust_gain": gain_mean(), "reverse_scale": reverse_scale(prior), "asymmetry": gain_ratio(),
                "lag_s": member("thrusters", "lag_s", "s", 0.01, 3.0, 0.2),
                "delay_s": member("thrusters", "delay_s", "s", 0.0, 2.0, 0.1),
                "deadzone_fwd": member("thrusters", "deadzone_fwd", "δ̃", 0.0, 0.5, 0.05),
                "current_north": ned_component("current", 0, -3.0, 3.0, 0.1),
                "current_east": ned_component("current", 1, -3.0, 3.0, 0.1)})
    return out


# ---------------------------------------------------------------- beliefs before the data

@dataclass(frozen=True)
class Belief:
    """What is known about one coefficient before identification, from how its prior value was
    obtained: `log`: its magnitude is log-normal, ln|θ| ~ N(ln|θ0|, sigma²), its sign fixed (a
    factor of exp(sigma) either way is one standard deviation); otherwise θ ~ N(θ0, sigma²) in
    the coefficient's units. `why` says where the width comes from."""

    log: bool
    sigma: float
    why: str


FACTOR_3 = math.log(3.0)
FACTOR_2 = math.log(2.0)
TYPICAL_SPEED_M_S = 1.0  # a small ASV's cruising speed: scales the speed-proportional damping's belief


def belief(name: str, prior: Vessel) -> Belief:
    """The prior belief about coefficient `name` of vessel `prior` (see Belief)."""
    d, a = prior.damping, prior.added_mass
    if name in ("Xu", "Yv", "Nr", "Xuu", "Yvv", "Nrr", "Yrv", "Yvr", "Yrr", "Nvv", "Nrv", "Nvr"):
        return Belief(True, FACTOR_3, "hull damping from a first-principles estimate: right within a factor of 3")
    if name in ("Xudot", "Yvdot", "Nrdot"):
        return Belief(True, FACTOR_2, "added mass from slender-body / ellipsoid theory: right within a factor of 2")
    if name in ("Yr", "Nv"):
        return Belief(False, 0.3 * math.sqrt(abs(d.Yv * d.Nr)) or 1.0,
                      "sway-yaw coupling: at most about a third of the direct terms' geometric mean")
    if name == "Yrdot":
        return Belief(False, 0.3 * math.sqrt(abs(a.Yvdot * a.Nrdot)) or 0.1,
                      "added-mass coupling: at most about a third of the direct terms' geometric mean")
    if name == "Yuv":
        return Belief(False, abs(d.Yv) / TYPICAL_SPEED_M_S or 10.0,
                      "speed-proportional sway damping: up to the linear term's size at 1 m/s")
    if name == "Nur":
        return Belief(False, abs(d.Nr) / TYPICAL_SPEED_M_S or 10.0,
                      "speed-proportional yaw damping: up to the linear term's size at 1 m/s")
    if name == "thrust_gain":
        return Belief(True, 0.4, "thrust curve measured at another supply voltage (a T200 gives about 1.6 times "
                                 "the 10 V thrust at 16 V)")
    if name == "reverse_scale":
        return Belief(True, 0.3, "reverse thrust curve: within about 30 % of the datasheet's")
    if name == "asymmetry":
        return Belief(True, 0.15, "two thrusters of one model: within about 15 % of each other")
    if name == "lag_s":
        return Belief(True, 1.0, "thrust lag of a small ESC and propeller: tenths of a second, a factor of e")
    if name == "delay_s":
        return Belief(False, 0.2, "transport delay of a telemetry link: a few tenths of a second")
    if name == "deadzone_fwd":
        return Belief(False, 0.05, "dead-zone edge: within 20 µs of the datasheet's")
    if name in ("current_north", "current_east"):
        return Belief(False, 0.2, "a lake or harbour current: a few tenths of a m/s")
    raise KeyError(name)
