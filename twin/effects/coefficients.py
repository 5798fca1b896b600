"""The coefficients of the vessel description that identification fits one by one, with their
units and the bounds that keep a fit physical: damping of seed 004 eq. 7 (Fossen's signs,
so ≤ 0 where a term dissipates), added mass ≤ 0 with M_A symmetric, the thrust curve's
scales, lag, delay, dead zone and a steady current."""
from __future__ import annotations

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
