"""The coefficients of the vessel description that identification fits one by one, with their
units, the bounds that keep a fit physical and what is believed about each before any data: damping of [Morel-2024 eq. 7] (Fossen's signs,
so ≤ 0 where a term dissipates), added mass ≤ 0 with M_A symmetric, the thrust curve's
scales, lag, delay, dead zone and a steady current; for a propeller-and-rudder ship (an `mmg`
block), the MMG standard's non-dimensional hull derivatives, wake fraction and rudder inflow
factors instead of the PWM thrusters' (MMG_FIT_GROUPS; `fit_groups` picks the vessel's)."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

from ..vessel import Vessel
from .quantity import Quantity, gain_mean, gain_ratio, member, ned_component, reverse_scale

DAMPING_UNITS = {"Xu": "N s/m", "Xuu": "N s2/m2", "Yv": "N s/m", "Yvv": "N s2/m2", "Yrv": "N s2/m", "Yr": "N s",
                 "Yvr": "N s2/m", "Yrr": "N s2", "Nv": "N s", "Nvv": "N s2", "Nrv": "N s2", "Nr": "N m s",
                 "Nvr": "N s2", "Nrr": "N m s2", "Yuv": "N s2/m2", "Nur": "N m s2/m",
                 "Yur": "N s2/m", "Nuv": "N s2/m", "astern_excess": "-"}
ADDED_MASS_UNITS = {"Xudot": "kg", "Yvdot": "kg", "Yrdot": "kg m", "Nrdot": "kg m2"}
QUADRATIC_DAMPING = ("Xuu", "Yvv", "Yrv", "Yvr", "Yrr", "Nvv", "Nrv", "Nvr", "Nrr")
LINEAR_DAMPING = ("Xu", "Yv", "Yr", "Nv", "Nr")
SURGE_RESISTANCE = ("Xu", "Xuu")  # the surge drag curve R(u) = −Xu·u − Xuu·u|u| [Morel-2024 eq. 7]
ADDED_MASS = ("Xudot", "Yvdot", "Yrdot", "Nrdot")
# what `twin identify` fits unless told otherwise: [Morel-2024 eq. 7]'s main damping terms, the yaw and sway
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
    "speed coupling": ("Yur", "Nuv"),
    "advance loss": ("advance_loss",),
    "astern resistance": ("astern_excess",),
}
# a propeller-and-rudder ship (MMG, physics/mmg.py): the same idea on its own description. Not the
# PWM thrusters' dead zone, gains or lag (it has none), and not X'_vv.., Y'_vvv, N'_vvv, Y'_rrr:
# large drift at low speed is where the recordings are thin and the cubic terms trade off against
# the linear ones. Names carry the `mmg_` prefix: Yv, Nr are already the PWM vessels' dimensional
# damping.
MMG_FIT_GROUPS = {
    "mmg resistance": ("mmg_R0", "mmg_wP0"),
    "mmg sway": ("mmg_Yv", "mmg_Nv"),
    "mmg yaw": ("mmg_Yr", "mmg_Nr"),
    "mmg nonlinear": ("mmg_Yvvr", "mmg_Yvrr", "mmg_Nvvr", "mmg_Nvrr"),
    "mmg rudder": ("mmg_epsilon", "mmg_gamma_plus", "mmg_gamma_minus"),
    "mmg added mass": ("Yvdot", "Nrdot"),
}
MMG_HULL = ("R0", "Xvv", "Xvr", "Xrr", "Xvvvv", "Yv", "Yr", "Yvvv", "Yvvr", "Yvrr", "Yrrr",
            "Nv", "Nr", "Nvvv", "Nvvr", "Nvrr", "Nrrr")
MMG_PROPELLER = ("tP", "wP0", "C1", "C2_plus", "C2_minus")
MMG_RUDDER = ("tR", "aH", "xH", "gamma_minus", "gamma_plus", "lR", "epsilon", "kappa")


def damping(name: str) -> Quantity:
    """A damping coefficient, dissipative sign (≤ 0)."""
    return member("damping", name, DAMPING_UNITS[name], -1e4, 0.0, 10.0)


def coupling(name: str) -> Quantity:
    """Linear sway-yaw coupling Yr, Nv: either sign is dissipative while Yv·Nr dominates."""
    return member("damping", name, DAMPING_UNITS[name], -1e3, 1e3, 1.0)


def speed_coupling(name: str) -> Quantity:
    """Speed-proportional sway-yaw coupling Y_ur, N_uv: either sign (physics.damping)."""
    return member("damping", name, DAMPING_UNITS[name], -1e3, 1e3, 5.0)


def added_mass(name: str) -> Quantity:
    """An added-mass derivative ≤ 0 (Yrdot either sign, Nvdot kept equal: M_A symmetric)."""
    lo, hi = (-1e2, 1e2) if name == "Yrdot" else (-1e3, 0.0)
    return member("added_mass", name, ADDED_MASS_UNITS[name], lo, hi, 1.0, also=("Nvdot",) if name == "Yrdot" else ())


def mmg_sway_added_mass() -> Quantity:
    """Yvdot of a propeller-and-rudder ship (kg, ≤ 0), the surge force of a turn held.

    In MMG eq. 4 the sway added mass m_y acts twice: as inertia in the sway row, (m + m_y)·v̇, and
    in the surge row as −(m + m_y)·v·r, beside the hull's X'_vr·v'·r' (eq. 7), which multiplies the
    same v·r. Only the sum m_y + ½ρL²d·X'_vr acts on surge, and a captive test measures that sum.
    A free run tells m_y from the sway row; moving it alone would also move the ship's speed loss in
    every turn by what the sway transients asked for, which on tests without fast turns nothing
    checks (docs/results/esso_identification.md). So X'_vr moves by −Δm_y/(½ρL²d): the fitted sway inertia
    changes the sway row only, and the surge force of a turn stays the prior's."""
    base = added_mass("Yvdot")

    def put(v: Vessel, x: float) -> Vessel:
        m = v.mmg
        shift_nd = (x - v.added_mass.Yvdot) / (0.5 * m.rho_kg_m3 * m.lpp_m ** 2 * m.draft_m)  # Δ(−m_y) = Δ Yvdot
        held = replace(m, hull=replace(m.hull, Xvr=m.hull.Xvr + shift_nd))
        return base.put(replace(v, mmg=held), x)

    return replace(base, put=put)


# where every recording logs its battery, PWM thrusters' answer to the pack voltage (physics/thrusters.py)
SUPPLY_GROUP = {"pack voltage": ("supply_exponent",)}


def fit_groups(vessel: Vessel, supplied: bool = False) -> dict[str, tuple[str, ...]]:
    """The groups `twin identify` considers for this vessel: its thrusters' kind decides; `supplied`:
    every recording logs its battery voltage, which adds the thrust's answer to it."""
    if vessel.mmg is not None:
        return MMG_FIT_GROUPS
    return {**FIT_GROUPS, **SUPPLY_GROUP} if supplied else FIT_GROUPS


def mmg_member(part: str, attr: str, lo: float, hi: float, typical: float) -> Quantity:
    """vessel.mmg.<part>.<attr>, a non-dimensional MMG coefficient (named mmg_<attr>)."""

    def get(v: Vessel) -> float:
        return float(getattr(getattr(v.mmg, part), attr))

    def put(v: Vessel, x: float) -> Vessel:
        holder = replace(getattr(v.mmg, part), **{attr: x})
        return replace(v, mmg=replace(v.mmg, **{part: holder}))

    return Quantity(f"mmg_{attr}", "-", get, put, lo, hi, typical)


def mmg_coefficients() -> dict[str, Quantity]:
    """The MMG coefficients a fit may move, with bounds that keep them physical: wake fraction and
    deductions in [0, 1), flow-straightening and inflow factors positive; hull derivatives in a
    wide band around any published full-form ship's (|Y'_v| < 2 etc.), either sign."""
    out = {f"mmg_{n}": mmg_member("hull", n, -5.0, 5.0, 0.05) for n in MMG_HULL}
    out["mmg_R0"] = mmg_member("hull", "R0", 0.001, 0.2, 0.02)  # a resistance resists
    out.update({"mmg_tP": mmg_member("propeller", "tP", 0.0, 0.6, 0.2),
                "mmg_wP0": mmg_member("propeller", "wP0", 0.0, 0.8, 0.3),
                "mmg_C1": mmg_member("propeller", "C1", 0.0, 10.0, 1.0),
                "mmg_C2_plus": mmg_member("propeller", "C2_plus", 0.5, 3.0, 1.0),
                "mmg_C2_minus": mmg_member("propeller", "C2_minus", 0.5, 3.0, 1.0)})
    out.update({"mmg_tR": mmg_member("rudder", "tR", 0.0, 0.8, 0.3),
                "mmg_aH": mmg_member("rudder", "aH", 0.0, 1.0, 0.3),
                "mmg_xH": mmg_member("rudder", "xH", -0.8, 0.0, 0.4),
                "mmg_gamma_minus": mmg_member("rudder", "gamma_minus", 0.05, 2.0, 0.4),
                "mmg_gamma_plus": mmg_member("rudder", "gamma_plus", 0.05, 2.0, 0.4),
                "mmg_lR": mmg_member("rudder", "lR", -2.0, 0.0, 0.7),
                "mmg_epsilon": mmg_member("rudder", "epsilon", 0.3, 3.0, 1.0),
                "mmg_kappa": mmg_member("rudder", "kappa", 0.05, 2.0, 0.5)})
    return out


PWM_THRUSTER_TERMS = ("thrust_gain", "reverse_scale", "asymmetry", "lag_s", "advance_loss", "delay_s",
                      "supply_exponent", "full_share", "deadzone_fwd")  # what a propeller and rudder lacks


def coefficients(prior: Vessel) -> dict[str, Quantity]:
    """Every coefficient identification can fit, by name (curve scales relative to `prior`; the
    MMG ones only for a vessel with an `mmg` block)."""
    out = {n: damping(n) for n in ("Xu", "Xuu", "Yv", "Yvv", "Yrv", "Yvr", "Yrr", "Nvv", "Nrv", "Nvr", "Nr", "Nrr")}
    out.update({n: coupling(n) for n in ("Yr", "Nv")})
    out.update({n: damping(n) for n in ("Yuv", "Nur")})
    out.update({n: speed_coupling(n) for n in ("Yur", "Nuv")})
    out.update({n: added_mass(n) for n in ADDED_MASS})
    if prior.thrusters.kind != "propeller_rudder":  # a propeller and rudder has none of a PWM thruster's terms
        out.update({"thrust_gain": gain_mean(), "reverse_scale": reverse_scale(prior), "asymmetry": gain_ratio(),
                    "lag_s": member("thrusters", "lag_s", "s", 0.01, 3.0, 0.2),
                    "advance_loss": member("thrusters", "advance_loss", "√N s/m", 0.0, 8.0, 0.5),
                    "delay_s": member("thrusters", "delay_s", "s", 0.0, 2.0, 0.1),
                    "supply_exponent": member("thrusters", "supply_exponent", "-", 0.0, 4.0, 0.5),
                    "full_share": member("thrusters", "full_share", "×", 0.3, 2.0, 0.2),
                    "deadzone_fwd": member("thrusters", "deadzone_fwd", "δ̃", 0.0, 0.5, 0.05)})
    out.update({"astern_excess": member("damping", "astern_excess", "-", -0.5, 4.0, 0.2),
                "current_north": ned_component("current", 0, -3.0, 3.0, 0.1),
                "current_east": ned_component("current", 1, -3.0, 3.0, 0.1)})
    if prior.mmg is not None:
        out.update(mmg_coefficients())
        out["Yvdot"] = mmg_sway_added_mass()
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
    if prior.mmg is not None and (name.startswith("mmg_") or name in ("Yvdot", "Nrdot", "Xudot")):
        return mmg_belief(name)
    d, a = prior.damping, prior.added_mass
    if name in ("Xu", "Yv", "Nr", "Xuu", "Yvv", "Nrr", "Yrv", "Yvr", "Yrr", "Nvv", "Nrv", "Nvr"):
        return Belief(True, FACTOR_3, "hull damping from a first-principles estimate: right within a factor of 3")
    if name in ("Xudot", "Yvdot", "Nrdot"):
        return Belief(True, FACTOR_2, "added mass from slender-body / ellipsoid theory: right within a factor of 2")
    if prior.design is not None and name in ("Yuv", "Yur", "Nuv", "Nur") and getattr(d, name) != 0:
        return Belief(True, FACTOR_2, "first-principles lift of the hulls [Clarke-1983] and momentum of the "
                                      "thrusters' flow: right within a factor of 2")
    if prior.design is not None and name in ("Yr", "Nv"):
        return Belief(False, abs(getattr(d, name)) or 1.0, "the thrusters' own flow at rest, estimated at half "
                                                           "thrust: zero to twice the estimate")
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
    if name in ("Yur", "Nuv"):
        return Belief(False, math.sqrt(abs(d.Yv * d.Nr)) / TYPICAL_SPEED_M_S or 10.0,
                      "speed-proportional sway-yaw coupling (hull lift in a turn): up to the direct terms' "
                      "geometric mean at 1 m/s")
    if name == "thrust_gain":
        return Belief(True, 0.4, "thrust curve measured at another supply voltage (a T200 gives about 1.6 times "
                                 "the 10 V thrust at 16 V)")
    if name == "reverse_scale":
        return Belief(True, 0.3, "reverse thrust curve: within about 30 % of the datasheet's")
    if name == "asymmetry":
        return Belief(True, 0.15, "two thrusters of one model: within about 15 % of each other")
    if name == "advance_loss":
        return Belief(False, 1.5, "propeller advance loss c = √(ρK_T0)·D/J_0: about 1.5 √N·s/m for a small "
                                  "thruster's propeller (D 76 mm, K_T0 0.4, J_0 1), known to a factor of 2")
    if name == "astern_excess":
        return Belief(False, 0.5, "surge drag astern against ahead at the same speed: a hull drawn to go ahead "
                                  "meets the water with its transom, about 1 to 2 times the drag ahead")
    if name == "full_share":
        return Belief(True, 0.3, "forward thrust at full PWM: within about 30 % of the datasheet's (ventilation, a "
                                 "worn propeller or an ESC's current limit bend the top of the curve)")
    if name == "lag_s":
        return Belief(True, 1.0, "thrust lag of a small ESC and propeller: tenths of a second, a factor of e")
    if name == "supply_exponent":
        return Belief(False, 1.5, "the thrust's answer to the pack voltage, (V/V_ref)^k: between 0 (a regulated "
                                  "supply) and about 2 (a propeller's n² on an ideal ESC); a prior without one "
                                  "starts from 1 (fit/simfit.py map_start)")
    if name == "delay_s":
        return Belief(False, 0.2, "transport delay of a telemetry link: a few tenths of a second")
    if name == "deadzone_fwd":
        return Belief(False, 0.05, "dead-zone edge: within 20 µs of the datasheet's")
    if name in ("current_north", "current_east"):
        return Belief(False, 0.2, "a lake or harbour current: a few tenths of a m/s")
    raise KeyError(name)


# Beliefs about the MMG prior (twin/model/esso_osaka.json, its sources): KVLCC2's captive-model derivatives applied to the
# Esso Osaka 3 m model, a full-form VLCC of similar proportions (C_b 0.83 against 0.81, L/B 6.1
# against 5.5). Widths from how far the published full-form ships' derivatives scatter among
# themselves (KVLCC1/2, Esso Osaka captive set, empirical formulas of [Kijima-1990]): the linear ones
# within about 25 %, the nonlinear ones within a factor of 2 or their own size.
MMG_LOG_BELIEFS = {
    "mmg_R0": (0.3, "resistance from KVLCC2's R'_0 at the Esso model's form: within about 30 % (scale effect, "
                    "laminar flow at model Reynolds numbers)"),
    "mmg_Yv": (0.25, "linear sway derivative of a full-form VLCC: the published sets scatter by about 25 %"),
    "mmg_Nv": (0.25, "linear yaw-sway derivative (Munk moment inside it): about 25 % among full-form ships"),
    "mmg_Nr": (0.3, "yaw damping N'_r: about 30 % among full-form ships (KVLCC2 −0.049, Esso captive −0.048)"),
    "mmg_Yr": (0.5, "Y'_r − (m' + m'_x) is what acts; Y'_r itself scatters by a factor of 1.6"),
    "mmg_epsilon": (0.25, "wake ratio rudder/propeller ε: 1.09 (KVLCC2) to 1.42 (Esso captive): about 25 %"),
    "mmg_gamma_plus": (0.4, "flow straightening γ_R: 0.4-0.65 in published sets, a factor of 1.5"),
    "mmg_gamma_minus": (0.4, "flow straightening γ_R: 0.35-0.45 in published sets, a factor of 1.5"),
    "Yvdot": (0.25, "sway added mass m'_y (KVLCC2 0.223, Esso captive 0.258): about 25 %"),
    "Nrdot": (0.5, "yaw added inertia J'_z, an empirical formula's value: a factor of 1.6"),
    "Xudot": (0.5, "surge added mass m'_x (KVLCC2 0.022, Esso captive 0.047): a factor of 1.6"),
}
MMG_NORMAL_BELIEFS = {  # the nonlinear derivatives change sign between published sets: normal beliefs
    "mmg_wP0": (0.1, "wake fraction w_P0: 0.40 (KVLCC2) to 0.61 (Esso captive); ±0.1"),
    "mmg_Yvvr": (0.4, "Y'_vvr: its own size (0.38)"),
    "mmg_Yvrr": (0.4, "Y'_vrr: its own size (−0.39)"),
    "mmg_Nvvr": (0.3, "N'_vvr: its own size (−0.29)"),
    "mmg_Nvrr": (0.1, "N'_vrr: twice its own size (0.055)"),
}


def mmg_belief(name: str) -> Belief:
    """The belief about one MMG coefficient of the KVLCC2-based prior (tables above); any other
    MMG coefficient: normal with σ 0.1 (hull) or 30 % (factors), wide enough to be told apart."""
    if name in MMG_LOG_BELIEFS:
        sigma, why = MMG_LOG_BELIEFS[name]
        return Belief(True, sigma, why)
    if name in MMG_NORMAL_BELIEFS:
        sigma, why = MMG_NORMAL_BELIEFS[name]
        return Belief(False, sigma, why)
    return Belief(False, 0.1, "an MMG coefficient outside the standard groups: ±0.1")
