"""The effect library: each physical effect declared once, by the name datasets inject it with
and a diagnosis names it by, with its values (units, ranges), what it does to the vessel
description (apply) and how a diagnosis fits it (fit: Quantities, starts, scans).

Every apply is a pure function `apply(vessel, **values) -> Vessel` on the one vessel
description, so the engine simulates it, the analytic model can check it and an amended vessel
file carries it. Set effects replace a value; scale effects (the KEY:S ones, thrust_gain,
thruster_asymmetry) multiply what is there, so effects compose in the given order.

Every fit is relative to the twin being diagnosed (the prior): a current or a heading bias
starts at zero, a damping or added-mass coefficient as a scale of the prior's own value (a
coefficient the prior does not have cannot be scaled, and is not offered), a thrust lag at a
typical value. Time shifts (input delay, clock offset) change which logged PWM sample drives
each engine step, so their cost is a staircase in the shift: they are scanned on a grid, not
followed down a gradient. A dead zone is a staircase too, and a flat one near the prior:
widening it changes the thrust only where the PWM sits between the old and the new edge, so the
gradient at the prior says nothing about a dead zone twice as wide. It is scanned along equal
widths, then each edge on its own. A heading's or a GNSS fix's latency is fitted late only (from
zero up): a filter or a receiver delays a sample, it cannot stamp it before it was taken, and a
negative latency fitted to a recording stands in for something else (as the kinematic step, which
names them late only, fit/kinematic.py). A PWM clock offset is fitted both ways: two clocks can
differ either way. Families group effects that can imitate each other in a recording: the
diagnosis checks them against each other before it names one.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..errors import TwinError
from ..physics.environment import MAX_CURRENT_M_S, MAX_WIND_M_S
from ..vessel import Vessel
from .coefficients import (ADDED_MASS, ADDED_MASS_UNITS, DAMPING_UNITS, LINEAR_DAMPING, QUADRATIC_DAMPING,
                           SURGE_RESISTANCE, mmg_sway_added_mass)
from .quantity import (Quantity, dead_zone_edge, gain_mean, gain_ratio, log_heading_bias, log_wind, member,
                       ned_component, reverse_scale, scale_of, side_dead_zone_edge, start_edge)
from .spec import ALL, PER_KEY_SEP, Candidate, Effect, EffectSpec, Value, checked

_SCALE = ("scale", "×", 0.0, 100.0, True)
_DEG = ("deg", -180.0, 180.0)


def _v(name, unit, lo=-math.inf, hi=math.inf, lo_open=False, default=None) -> Value:
    return Value(name, unit, lo, hi, lo_open, default)


def _grid(lo: float, hi: float, step: float) -> tuple[tuple[float], ...]:
    """One-value scan points lo, lo + step, ..., hi."""
    return tuple((float(x),) for x in np.round(np.arange(lo, hi + step / 2, step), 4))


def _thrusters(vessel: Vessel, **values) -> Vessel:
    return replace(vessel, thrusters=replace(vessel.thrusters, **values))


def _sensors(vessel: Vessel, **values) -> Vessel:
    return replace(vessel, sensors=replace(vessel.sensors, **values))


def _scaled(obj, keys: tuple[str, ...], scales: dict, pairs: dict | None = None):
    values = {k: getattr(obj, k) * scales.get(k, scales.get(ALL, 1.0)) for k in keys}
    for k, twin_key in (pairs or {}).items():
        values[twin_key] = values[k]  # a symmetric pair is scaled together
    return replace(obj, **values)


def _single(name: str, quantity, starts, family: str, **scan) -> "callable":
    """The fit of an effect whose one value is one field of the description (same name)."""
    def fit(prior: Vessel, logs) -> Candidate:
        return Candidate(name, (quantity,), starts, lambda p: effect(name, **p), family, **scan)
    return fit


def _relative(name: str, quantity, family: str) -> "callable":
    """The fit of an effect whose one value multiplies the prior's own (quantity(prior)), from 1."""
    def fit(prior: Vessel, logs) -> Candidate:
        return Candidate(name, (quantity(prior),), ((1.0,),), lambda p: effect(name, **p), family)
    return fit


# ---------------------------------------------------------------- environment

def current(vessel: Vessel, speed_m_s: float, dir_deg: float) -> Vessel:
    """Earth-fixed water current (m/s) flowing towards dir_deg (cw from north)."""
    env = replace(vessel.environment, current_speed_m_s=speed_m_s, current_dir_deg=dir_deg)
    return replace(vessel, environment=env)


def _current_fit(prior: Vessel, logs) -> Candidate:
    def to_effect(p: dict) -> Effect:
        return effect("current", speed_m_s=float(np.hypot(p["current_north"], p["current_east"])),
                      dir_deg=float(np.degrees(np.arctan2(p["current_east"], p["current_north"]))))
    return Candidate("current", (ned_component("current", 0, -3.0, 3.0, 0.1), ned_component("current", 1, -3.0, 3.0, 0.1)),
                     ((0.0, 0.0),), to_effect, "drift")


def wind(vessel: Vessel, speed_m_s: float, dir_deg: float) -> Vessel:
    """Wind (m/s) blowing from dir_deg (cw from north) on the vessel's wind load model (its
    wind_load areas, or its wind_regression, e.g. Fujiwara's)."""
    if speed_m_s > 0 and not vessel.feels_wind():
        raise TwinError(f"effect 'wind': vessel '{vessel.name}' has no wind load model (wind_load areas or "
                        "wind_regression), so wind would do nothing")
    env = replace(vessel.environment, wind_speed_m_s=speed_m_s, wind_dir_deg=dir_deg)
    return replace(vessel, environment=env)


def _wind_fit(prior: Vessel, logs) -> Candidate | None:
    if not prior.feels_wind():
        return None

    def to_effect(p: dict) -> Effect:
        return effect("wind", speed_m_s=float(np.hypot(p["wind_north"], p["wind_east"])),
                      dir_deg=float(np.degrees(np.arctan2(-p["wind_east"], -p["wind_north"]))))
    starts = tuple((5 * np.cos(a), 5 * np.sin(a)) for a in np.radians([0, 90, 180, 270]))
    return Candidate("wind", (ned_component("wind", 0, -25.0, 25.0, 1.0), ned_component("wind", 1, -25.0, 25.0, 1.0)),
                     starts, to_effect, "drift")


def wind_per_log(vessel: Vessel, wind_by_log: dict[str, tuple[float, float]]) -> Vessel:
    """Each named log's own wind (speed m/s, from deg), in place of the constant wind for that log:
    a wind that changed between outings, or between the tests of one day; set."""
    if any(speed > 0 for speed, _ in wind_by_log.values()) and not vessel.feels_wind():
        raise TwinError(f"effect 'wind_per_log': vessel '{vessel.name}' has no wind load model (wind_load areas or "
                        "wind_regression), so wind would do nothing")
    entries = tuple(sorted((n, float(s), float(d)) for n, (s, d) in wind_by_log.items()))
    return replace(vessel, environment=replace(vessel.environment, wind_by_log=entries))


def _wind_per_log_fit(prior: Vessel, logs) -> Candidate | None:
    """Two numbers per log (its air velocity north, east), each log started from the calm or uniform wind
    its own windows like best; one log's wind is `wind`."""
    logs = list(dict.fromkeys(logs))
    if len(logs) < 2 or not prior.feels_wind():
        return None
    params = tuple(log_wind(n, axis) for n in logs for axis in (0, 1))

    def to_effect(p: dict) -> Effect:
        winds = {}
        for n in logs:
            north, east = p[f"{n}@wind_north"], p[f"{n}@wind_east"]
            winds[n] = (float(np.hypot(north, east)), float(np.degrees(np.arctan2(-east, -north))))
        return effect("wind_per_log", **winds)
    # calm, and a wind of 1, 2 or 5 m/s from each of eight directions: each log takes the start its own
    # windows like best (a log's wind acts on no other log), and the screening's Gauss-Newton steps move every
    # log's wind from there (from calm alone the step barely moves: the load grows with the square of
    # the relative wind)
    starts = ((0.0,) * len(params),) + tuple((speed * np.cos(a), speed * np.sin(a)) * len(logs)
                                              for speed in (1.0, 2.0, 5.0) for a in np.radians(np.arange(0, 360, 45)))
    # every log of the diagnosis has its own wind: a constant one (with or without its shape) acts
    # on none, and only the superstructure's load shape is left to fit (wind_load_shape)
    return Candidate("wind_per_log", params, starts, to_effect, "drift",
                     log_of_param=tuple(n for n in logs for _ in (0, 1)), supersedes=("wind", "wind_shape"))


def wind_load_shape(vessel: Vessel, cy: float, cn: float) -> Vessel:
    """The wind load's sway and yaw coefficients set (c_x stays the vessel's, as in `wind_shape`),
    for whatever wind acts (each log's own, a constant one, or a measured one): the shape of a
    superstructure the vessel file does not describe, apart from the wind itself."""
    if vessel.wind_load.cx == 0.0 or not vessel.feels_wind() or vessel.wind_regression is not None:
        raise TwinError(f"effect 'wind_load_shape': vessel '{vessel.name}' has no wind load model with "
                        "coefficients (wind_load areas and c_x, and no wind_regression in their place), so its "
                        "shape would do nothing")
    return replace(vessel, wind_load=replace(vessel.wind_load, cy=cy, cn=cn))


def _wind_load_shape_fit(prior: Vessel, logs) -> Candidate | None:
    """Offered beside winds of each log's own (several logs): a single log's wind and its shape are
    `wind_shape`."""
    if len(set(logs)) < 2 or not prior.feels_wind() or prior.wind_load.cx == 0.0 or prior.wind_regression is not None:
        return None
    shape = _load_coefficients(prior)
    return Candidate("wind_load_shape", shape, ((prior.wind_load.cy, prior.wind_load.cn),),
                     lambda p: effect("wind_load_shape", cy=p["cy"], cn=p["cn"]), "drift")


CY_MAX = 2.0  # a two-dimensional flat plate's broadside drag coefficient [Hoerner-1965]; a superstructure, finite and rounded, has less


def _load_coefficients(prior: Vessel) -> tuple:
    """The wind load's c_y and c_n as fitted quantities, scaled by the prior's. c_y is a side force per
    lateral area: between none and a two-dimensional flat plate's broadside (CY_MAX, or the vessel
    file's own where that is more; the shipped vessels' 0.8). Both ends are unphysical edges: a fit
    that ends on one (a current's drift read as a light wind on a superstructure pushing twice as hard
    as a flat plate) says the form is off, not that the superstructure is so (diagnose/search.py:
    at_unphysical_edge). The fitted wind's speed sets the load's scale through the file's c_x and
    frontal area, so c_y is read against those: a file whose lateral area is half the boat's reads a
    real wind's c_y twice as large."""
    hi = max(CY_MAX, prior.wind_load.cy)
    cy = replace(member("wind_load", "cy", "-", 0.0, hi, max(abs(prior.wind_load.cy), 0.1)), edges_unphysical=True)
    return (cy, member("wind_load", "cn", "-", -2.0, 2.0, max(abs(prior.wind_load.cn), 0.05)))


def wind_shape(vessel: Vessel, speed_m_s: float, dir_deg: float, cy: float, cn: float) -> Vessel:
    """Wind (m/s, from dir_deg) with the sway and yaw load coefficients set (the surge one, c_x, stays
    the vessel's: it sets the scale, since speed² and a coefficient trade off): a superstructure
    whose shape the vessel file does not describe."""
    vessel = wind(vessel, speed_m_s, dir_deg)
    return replace(vessel, wind_load=replace(vessel.wind_load, cy=cy, cn=cn))


def _wind_shape_fit(prior: Vessel, logs) -> Candidate | None:
    base = _wind_fit(prior, logs)
    if base is None or prior.wind_load.cx == 0.0:
        return None
    cy, cn = _load_coefficients(prior)

    def to_effect(p: dict) -> Effect:
        w = base.to_effect(p)
        return effect("wind_shape", cy=p["cy"], cn=p["cn"], **w.params)
    starts = tuple(s + (prior.wind_load.cy, prior.wind_load.cn) for s in base.starts)
    # its c_y and c_n are wind_load_shape's: once kept, that one would fit the same two numbers again
    return Candidate("wind_shape", base.params + (cy, cn), starts, to_effect, "drift",
                     supersedes=("wind_load_shape",))


# ---------------------------------------------------------------- thrusters

def thruster_lag(vessel: Vessel, lag_s: float) -> Vessel:
    """First-order thrust lag time constant (s), [Morel-2024 eq. 15]; 0 = none."""
    return _thrusters(vessel, lag_s=lag_s)


def thrust_ramp(vessel: Vessel, ramp_s: float) -> Vessel:
    """A slew limit on the thrust command: s to change by the full forward thrust (an ESC's or the
    autopilot's ramp, physics/thrusters.py); 0 = none."""
    return _thrusters(vessel, ramp_s=ramp_s)


def input_delay(vessel: Vessel, delay_s: float) -> Vessel:
    """The thrusters act on the PWM logged delay_s (s) earlier."""
    return _thrusters(vessel, delay_s=delay_s)


def thruster_asymmetry(vessel: Vessel, ratio: float) -> Vessel:
    """Right gain / left gain multiplied by `ratio`, the mean of both gains kept,
    so the surge thrust at equal PWM stays and the vessel turns."""
    t = vessel.thrusters
    mean = 0.5 * (t.gain_left + t.gain_right)
    right_over_left = ratio * t.gain_right / t.gain_left
    left = 2 * mean / (1 + right_over_left)
    return _thrusters(vessel, gain_left=left, gain_right=right_over_left * left)


def thrust_gain(vessel: Vessel, scale: float) -> Vessel:
    """Both thruster gains multiplied by `scale` (e.g. a higher supply voltage than the map's 10 V)."""
    t = vessel.thrusters
    return _thrusters(vessel, gain_left=t.gain_left * scale, gain_right=t.gain_right * scale)


def thruster_gain_left(vessel: Vessel, scale: float) -> Vessel:
    """The left thruster alone delivers `scale` times what it did (fouled, damaged, a weaker motor)."""
    return _thrusters(vessel, gain_left=vessel.thrusters.gain_left * scale)


def thruster_gain_right(vessel: Vessel, scale: float) -> Vessel:
    """The right thruster alone delivers `scale` times what it did."""
    return _thrusters(vessel, gain_right=vessel.thrusters.gain_right * scale)


def _one_gain_fit(side: str):
    """One thruster's gain as a scale of the prior's."""
    def fit(prior: Vessel, logs) -> Candidate:
        q = scale_of(prior, "thrusters", f"gain_{side}", "gain")
        q = q.renamed("scale", lo=0.2, hi=3.0)
        return Candidate(f"thruster_gain_{side}", (q,), ((1.0,),), lambda p: effect(f"thruster_gain_{side}",
                                                                                      scale=p["scale"]), "thrust")
    return fit


def pwm_span_left(vessel: Vessel, span: float) -> Vessel:
    """The left thruster's ESC answers `span` times the logged PWM's deviation from neutral (its
    calibrated range differs from the autopilot's output range): a pulse scale, not a thrust scale."""
    return _thrusters(vessel, pwm_span_left=vessel.thrusters.pwm_span_left * span)


def pwm_span_right(vessel: Vessel, span: float) -> Vessel:
    """The right thruster's ESC answers `span` times the logged PWM's deviation from neutral."""
    return _thrusters(vessel, pwm_span_right=vessel.thrusters.pwm_span_right * span)


def _pwm_span_fit(side: str):
    """One ESC's PWM span as a multiple of the prior's, for thrusters driven by PWM."""
    def fit(prior: Vessel, logs) -> Candidate | None:
        if prior.thrusters.kind != "t200":
            return None
        q = scale_of(prior, "thrusters", f"pwm_span_{side}", "span").renamed("span", lo=0.4, hi=2.5)
        return Candidate(f"pwm_span_{side}", (q,), ((1.0,),), lambda p: effect(f"pwm_span_{side}", span=p["span"]),
                         "thrust")
    return fit


def reverse_thrust(vessel: Vessel, scale: float) -> Vessel:
    """The reverse branch of the thrust map × scale: a propeller astern pushes its wash against the
    hull (or through a guard) and delivers less than the datasheet's bollard curve."""
    t = vessel.thrusters
    return _thrusters(vessel, reverse=tuple(float(c) * scale for c in t.reverse))


def _reverse_fit(prior: Vessel, logs) -> Candidate | None:
    if prior.thrusters.kind != "t200":
        return None
    q = reverse_scale(prior).renamed("scale", lo=0.2, hi=2.0)
    return Candidate("reverse_thrust", (q,), ((1.0,),), lambda p: effect("reverse_thrust", scale=p["scale"]), "thrust")


def full_thrust(vessel: Vessel, share: float) -> Vessel:
    """The forward curve saturating to `share` × the map's thrust at full PWM, the low end held
    (ventilation under heavy load, a worn propeller, an ESC's current limit; physics/thrusters.py)."""
    return _thrusters(vessel, full_share=vessel.thrusters.full_share * share)


def _full_thrust_fit(prior: Vessel, logs) -> Candidate | None:
    if prior.thrusters.kind != "t200":
        return None
    q = member("thrusters", "full_share", "×", 0.3, 2.0, 1.0).renamed("share")
    return Candidate("full_thrust", (replace(q, edges_unphysical=True),), ((prior.thrusters.full_share,),),
                     lambda p: effect("full_thrust", share=p["share"] / prior.thrusters.full_share), "thrust")


def dead_zone(vessel: Vessel, fwd: float, rev: float) -> Vessel:
    """Dead-zone widths (≥ 0) in normalised PWM δ̃ = PWM/400 − offset [Yellowfish-TR eq. 27]:
    no thrust for −rev < δ̃ < fwd. 0.0775 = 31 µs."""
    return _thrusters(vessel, deadzone_fwd=fwd, deadzone_rev=-rev)


def _dead_zone_fit(prior: Vessel, logs) -> Candidate:
    t = prior.thrusters
    now = (t.deadzone_fwd, -t.deadzone_rev)
    return Candidate("dead_zone", (dead_zone_edge("fwd"), dead_zone_edge("rev")), (now,),
                     lambda p: effect("dead_zone", fwd=p["fwd"], rev=p["rev"]), "thrust",
                     scan=_dead_zone_scan(now), scan_step=(0.0125, 0.0125))


def _dead_zone_scan(now: tuple[float, float]) -> tuple[tuple[float, float], ...]:
    """Both edges together, then each alone from the prior's: a dead zone need not be symmetric
    (an ESC's reverse band may be wider than its forward one), and one edge moved alone is only
    half-found on a symmetric scan. Screening ranks by the best point of all three."""
    both = tuple((w, w) for w, in _grid(0.0, 0.3, 0.025))
    fwd = tuple((w, now[1]) for w, in _grid(0.0, 0.3, 0.05))
    rev = tuple((now[0], w) for w, in _grid(0.0, 0.3, 0.05))
    return (now,) + both + fwd + rev


def dead_zone_left(vessel: Vessel, fwd: float, rev: float) -> Vessel:
    """The left thruster's own dead-zone widths (≥ 0, δ̃ as dead_zone's), the right keeping the shared:
    an ESC of its own, or a motor that needs more current to turn."""
    return _thrusters(vessel, deadzone_left=(float(fwd), -float(rev)))


def dead_zone_right(vessel: Vessel, fwd: float, rev: float) -> Vessel:
    """The right thruster's own dead-zone widths (≥ 0, δ̃), the left keeping the shared."""
    return _thrusters(vessel, deadzone_right=(float(fwd), -float(rev)))


def _side_dead_zone_fit(side: str):
    """Scanned as dead_zone is, one thruster's edges from where they are (the shared ones): a dead zone
    of one thruster turns the boat where the PWM sits between its edge and the other's."""
    def fit(prior: Vessel, logs) -> Candidate | None:
        t = prior.thrusters
        if t.kind != "t200":
            return None
        edges = t.edges_of(0 if side == "left" else 1)
        now = (edges[0], -edges[1])
        name = f"dead_zone_{side}"
        return Candidate(name, (side_dead_zone_edge(side, "fwd"), side_dead_zone_edge(side, "rev")), (now,),
                         lambda p: effect(name, fwd=p["fwd"], rev=p["rev"]), "thrust",
                         scan=_dead_zone_scan(now), scan_step=(0.0125, 0.0125))
    return fit


def motor_start(vessel: Vessel, fwd: float, rev: float) -> Vessel:
    """Start edges (widths ≥ 0 in δ̃, as dead_zone's) of a motor with start/stop hysteresis: a
    stopped motor starts only beyond them, a running one stops inside the dead zone (physics/thrusters.py);
    an edge inside the dead zone is the dead-zone edge (no hysteresis on that side)."""
    return _thrusters(vessel, start_fwd=fwd, start_rev=-rev)


def _motor_start_fit(prior: Vessel, logs) -> Candidate | None:
    """Scanned like the dead zone (a staircase in the edges), from the dead-zone edges: both edges
    out together, then each alone. The stop edges stay the prior's dead zone."""
    t = prior.thrusters
    if t.kind != "t200":
        return None
    dz = (t.deadzone_fwd, -t.deadzone_rev)
    now = (t.start_edges[0], -t.start_edges[1])
    out = np.round(np.arange(0.025, 0.2 + 1e-9, 0.025), 4)
    scan = ((now,) + tuple((dz[0] + w, dz[1] + w) for w in out) + tuple((dz[0] + w, now[1]) for w in out[1::2])
            + tuple((now[0], dz[1] + w) for w in out[1::2]))
    return Candidate("motor_start", (start_edge("fwd"), start_edge("rev")), (now,),
                     lambda p: effect("motor_start", fwd=p["fwd"], rev=p["rev"]), "thrust",
                     scan=scan, scan_step=(0.0125, 0.0125))


def thrust_decay(vessel: Vessel, decay_per_min: float) -> Vessel:
    """Thrust × (1 − decay_per_min·t/60 s), t from the start of the recording (battery sag)."""
    return _thrusters(vessel, decay_per_min=decay_per_min)


def supply_voltage(vessel: Vessel, exponent: float, ref_v: float = 0.0) -> Vessel:
    """Thrust × (V/V_ref)^exponent with V the battery voltage the recording logs (physics/thrusters.py);
    ref_v: V_ref (V), the voltage the thrust map holds at (0: the vessel's own supply_ref_v)."""
    ref = ref_v or vessel.thrusters.supply_ref_v
    if exponent and not ref:
        raise TwinError(f"supply_voltage: vessel '{vessel.name}' has no reference voltage of its own: give it, "
                        f"supply_voltage={exponent:g},REF_V (the volts its thrust map holds at)")
    return _thrusters(vessel, supply_exponent=exponent, supply_ref_v=ref)


def _supply_fit(prior: Vessel, logs) -> Candidate | None:
    """Offered where the diagnosis knows a reference voltage (every log has a battery stream:
    `candidates(..., supply_ref_v=)`, or the prior follows the supply already). The exponent is fitted
    with the reference held, so a kept effect writes both."""
    ref = prior.thrusters.supply_ref_v
    if ref is None or prior.thrusters.kind == "propeller_rudder":
        return None

    def put(v: Vessel, k: float) -> Vessel:
        return _thrusters(v, supply_exponent=k, supply_ref_v=ref)

    k = Quantity("exponent", "-", lambda v: float(v.thrusters.supply_exponent), put, 0.0, 4.0, 0.5)
    return Candidate("supply_voltage", (k,), ((1.5,),), lambda p: effect("supply_voltage", exponent=p["exponent"],
                                                                          ref_v=ref), "thrust")


def thrust_speed_loss(vessel: Vessel, advance_loss: float) -> Vessel:
    """Each propeller's thrust less advance_loss·√|T0|·its advance speed (√N·s/m, physics/thrusters.py)."""
    return _thrusters(vessel, advance_loss=advance_loss)


# ---------------------------------------------------------------- hull

def quadratic_damping(vessel: Vessel, **scales: float) -> Vessel:
    """Quadratic damping coefficients multiplied by scales ({"Xuu": 1.3}, or all=S)."""
    return replace(vessel, damping=_scaled(vessel.damping, QUADRATIC_DAMPING, scales))


def linear_damping(vessel: Vessel, **scales: float) -> Vessel:
    """Linear damping coefficients multiplied by scales ({"Xu": 0.8}, or all=S)."""
    return replace(vessel, damping=_scaled(vessel.damping, LINEAR_DAMPING, scales))


def surge_resistance(vessel: Vessel, **scales: float) -> Vessel:
    """The hull's surge resistance curve of another shape: Xu and Xuu multiplied by their own scales
    (a fouled hull or wave making: resistance growing faster with speed than the model's, which
    the two together follow over the speeds driven; one alone bends the whole curve)."""
    return replace(vessel, damping=_scaled(vessel.damping, SURGE_RESISTANCE, scales))


def added_mass(vessel: Vessel, **scales: float) -> Vessel:
    """Added-mass derivatives multiplied by scales; Yrdot scales Nvdot too (M_A stays symmetric). On a
    propeller-and-rudder ship a scaled Yvdot moves X'_vr back, as identification's does: surge feels
    only m_y + X'_vr (coefficients.mmg_sway_added_mass, MMG eq. 4 and 7)."""
    scaled = _scaled(vessel.added_mass, ADDED_MASS, scales, {"Yrdot": "Nvdot"})
    if vessel.mmg is None:
        return replace(vessel, added_mass=scaled)
    return replace(mmg_sway_added_mass().put(vessel, scaled.Yvdot), added_mass=scaled)


def _scales_fit(name: str, group: str, keys: tuple[str, ...]):
    """A scale effect fitted as scales of the prior's non-zero coefficients (none: not offered)."""
    def fit(prior: Vessel, logs) -> Candidate | None:
        present = [k for k in keys if getattr(getattr(prior, group), k) != 0.0]
        if name == "linear_damping":
            present = [k for k in present if k not in ("Yr", "Nv")]  # coupling_damping's
        if not present:
            return None
        units = {k: DAMPING_UNITS.get(k) or ADDED_MASS_UNITS[k] for k in present}
        params = tuple(scale_of(prior, group, k, units[k], ("Nvdot",) if k == "Yrdot" else ()) for k in present)
        family = "inertia" if group == "added_mass" else "drag"
        return Candidate(name, params, (tuple(1.0 for _ in present),),
                         lambda p: effect(name, **{k[: -len("_scale")]: v for k, v in p.items()}), family,
                         separable=True)
    return fit


def coupling_damping(vessel: Vessel, Yr: float, Nv: float) -> Vessel:
    """Linear sway-yaw coupling damping Yr (N s), Nv (N s), Fossen's signs, set."""
    return replace(vessel, damping=replace(vessel.damping, Yr=Yr, Nv=Nv))


def speed_damping(vessel: Vessel, Yuv: float, Nur: float) -> Vessel:
    """Sway and yaw damping proportional to the forward speed, Y_|u|v and N_|u|r (Fossen's signs), set."""
    return replace(vessel, damping=replace(vessel.damping, Yuv=Yuv, Nur=Nur))


def speed_coupling(vessel: Vessel, Yur: float, Nuv: float) -> Vessel:
    """Sway-yaw coupling proportional to the signed forward speed, Y_ur and N_uv (N s²/m), set: the
    lift of a hull in a turn (physics.damping)."""
    return replace(vessel, damping=replace(vessel.damping, Yur=Yur, Nuv=Nuv))


def astern_resistance(vessel: Vessel, excess: float) -> Vessel:
    """Going astern the surge drag curve is (1 + excess) times the one ahead (physics.damping): a hull
    drawn to go ahead meets the water with its transom when it backs."""
    return replace(vessel, damping=replace(vessel.damping, astern_excess=excess))


def cg_offset(vessel: Vessel, dx_m: float, dy_m: float) -> Vessel:
    """The whole mass distribution moved by (dx, dy) m, body FRD, from where the MJCF puts it."""
    return replace(vessel, cg_offset_m=(dx_m, dy_m))


def _pair_fit(name: str, group: str, attrs: tuple[str, str], unit: str, lo: float, hi: float, typical: float,
              family: str, index: bool = False, start_from_prior: bool = False):
    """An effect of two set values: two fields (or the two items of one tuple field) of a group."""
    def fit(prior: Vessel, logs) -> Candidate:
        spec_values = [v.name for v in spec(name).values]
        if index:
            qs = tuple(member(group, attrs[0], unit, lo, hi, typical, name=spec_values[i], index=i) for i in range(2))
        else:
            qs = tuple(member(group, a, unit, lo, hi, typical, name=n) for a, n in zip(attrs, spec_values))
        start = tuple(q.get(prior) for q in qs) if start_from_prior else (0.0, 0.0)
        return Candidate(name, qs, (start,), lambda p: effect(name, **p), family)
    return fit


# ---------------------------------------------------------------- sensors

def clock_offset(vessel: Vessel, pwm_clock_offset_s: float) -> Vessel:
    """The PWM log's stamps are pwm_clock_offset_s late against GNSS and heading (either sign)."""
    return _sensors(vessel, pwm_clock_offset_s=pwm_clock_offset_s)


def gnss_latency(vessel: Vessel, gnss_latency_s: float) -> Vessel:
    """The GNSS fixes are stamped gnss_latency_s after they were taken (heading and PWM on time)."""
    return _sensors(vessel, gnss_latency_s=gnss_latency_s)


def heading_latency(vessel: Vessel, heading_latency_s: float) -> Vessel:
    """The heading samples are stamped heading_latency_s after they were taken (GNSS and PWM on
    time): an AHRS or compass filter."""
    return _sensors(vessel, heading_latency_s=heading_latency_s)


def heading_bias(vessel: Vessel, heading_bias_deg: float) -> Vessel:
    """A constant heading error (deg) of every log."""
    return _sensors(vessel, heading_bias_deg=heading_bias_deg)


def heading_bias_per_log(vessel: Vessel, bias_deg_by_log: dict[str, float]) -> Vessel:
    """Each named log's own heading bias (deg), on top of the common one; set."""
    return _sensors(vessel, heading_bias_by_log_deg=tuple(sorted(bias_deg_by_log.items())))


def _per_log_fit(prior: Vessel, logs) -> Candidate | None:
    logs = list(dict.fromkeys(logs))
    if len(logs) < 2:  # one log's bias is heading_bias
        return None
    return Candidate("heading_bias_per_log", tuple(log_heading_bias(n) for n in logs), (tuple(0.0 for _ in logs),),
                     lambda p: effect("heading_bias_per_log", **p), "drift")


def compass_deviation(vessel: Vessel, b_deg: float, c_deg: float, d_deg: float = 0.0, e_deg: float = 0.0) -> Vessel:
    """Heading error B sin ψ + C cos ψ + D sin 2ψ + E cos 2ψ (deg)."""
    return _sensors(vessel, compass_deviation_deg=(b_deg, c_deg, d_deg, e_deg))


def _compass_fit(prior: Vessel, logs) -> Candidate:
    qs = tuple(member("sensors", "compass_deviation_deg", "deg", -30.0, 30.0, 1.0, name=n, index=i)
               for i, n in enumerate(("b_deg", "c_deg")))
    return Candidate("compass_deviation", qs, ((0.0, 0.0),),
                     lambda p: effect("compass_deviation", b_deg=p["b_deg"], c_deg=p["c_deg"]), "drift")


def compass_motor(vessel: Vessel, b_deg: float, c_deg: float) -> Vessel:
    """Heading error τ·(B sin ψ + C cos ψ) (deg at full throttle τ = 1): the motors' currents' field at the
    compass (physics.sensors; ArduPilot's COMPASS_MOT by throttle)."""
    return _sensors(vessel, compass_motor_deg=(b_deg, c_deg))


def _compass_motor_fit(prior: Vessel, logs) -> Candidate | None:
    if prior.thrusters.kind != "t200":  # the throttle is read from the logged PWM
        return None
    qs = tuple(member("sensors", "compass_motor_deg", "deg", -30.0, 30.0, 1.0, name=n, index=i)
               for i, n in enumerate(("b_deg", "c_deg")))
    return Candidate("compass_motor", qs, ((0.0, 0.0),), lambda p: effect("compass_motor", **p), "compass")


def gnss_lever_arm(vessel: Vessel, dx_m: float, dy_m: float) -> Vessel:
    """The antenna sits (dx, dy) m, body FRD, off the MJCF gnss site."""
    return _sensors(vessel, antenna_offset_m=(dx_m, dy_m))


# ---------------------------------------------------------------- the registry

_SPECS = [
    EffectSpec("current", "environment", (_v("speed_m_s", "m/s", 0, MAX_CURRENT_M_S), _v("dir_deg", "deg", -360, 360)), current,
               "water current towards dir_deg", _current_fit),
    EffectSpec("wind", "environment", (_v("speed_m_s", "m/s", 0, MAX_WIND_M_S), _v("dir_deg", "deg", -360, 360)), wind,
               "wind from dir_deg", _wind_fit),
    EffectSpec("wind_per_log", "environment", (_v("speed_m_s", "m/s", 0, MAX_WIND_M_S), _v("dir_deg", "deg", -360, 360)),
               wind_per_log, "each log's own wind (file name), from dir_deg: a wind that changed between logs",
               _wind_per_log_fit, per_key="LOG"),
    EffectSpec("wind_load_shape", "environment", (_v("cy", "-", 0, 5), _v("cn", "-", -2, 2)), wind_load_shape,
               "the wind load's sway and yaw coefficients, for whatever wind acts (beside each log's own wind)",
               _wind_load_shape_fit),
    EffectSpec("wind_shape", "environment", (_v("speed_m_s", "m/s", 0, 40), _v("dir_deg", "deg", -360, 360),
                                              _v("cy", "-", 0, 5), _v("cn", "-", -2, 2)), wind_shape,
               "wind from dir_deg with its sway and yaw load coefficients fitted (another superstructure)",
               _wind_shape_fit),
    EffectSpec("thruster_lag", "thrusters", (_v("lag_s", "s", 0, 10),), thruster_lag, "first-order thrust lag",
               _single("thruster_lag", member("thrusters", "lag_s", "s", 0.02, 3.0, 0.2), ((0.15,), (0.6,)),
                       "timing")),
    EffectSpec("thrust_ramp", "thrusters", (_v("ramp_s", "s", 0, 20),), thrust_ramp,
               "thrust slew limit (ESC or autopilot ramp): s to change by the full forward thrust",
               _single("thrust_ramp", member("thrusters", "ramp_s", "s", 0.05, 10.0, 0.5), ((0.5,), (2.0,)),
                       "timing")),
    EffectSpec("input_delay", "thrusters", (_v("delay_s", "s", 0, 5),), input_delay, "thrust acts on older PWM",
               _single("input_delay", member("thrusters", "delay_s", "s", 0.0, 1.5, 0.1), ((0.0,),), "timing",
                       scan=_grid(0.0, 1.2, 0.12), scan_step=(0.01,), time_shift=True)),
    EffectSpec("thruster_asymmetry", "thrusters", (_v("ratio", "×", 0, 10, True),), thruster_asymmetry,
               "right/left thrust gain ratio, their mean kept",
               _relative("thruster_asymmetry", lambda prior: gain_ratio("ratio", 0.3, 3.0, prior), "turning")),
    EffectSpec("thrust_gain", "thrusters", (_v(*_SCALE),), thrust_gain, "overall thrust scale",
               _relative("thrust_gain", lambda prior: gain_mean("scale", 0.2, 5.0, prior), "thrust")),
    EffectSpec("thruster_gain_left", "thrusters", (_v(*_SCALE),), thruster_gain_left,
               "the left thruster alone weaker or stronger", _one_gain_fit("left")),
    EffectSpec("thruster_gain_right", "thrusters", (_v(*_SCALE),), thruster_gain_right,
               "the right thruster alone weaker or stronger", _one_gain_fit("right")),
    EffectSpec("pwm_span_left", "thrusters", (_v("span", "×", 0, 10, True),), pwm_span_left,
               "the left ESC answers span × the logged PWM's deviation from neutral (another calibrated range)",
               _pwm_span_fit("left")),
    EffectSpec("pwm_span_right", "thrusters", (_v("span", "×", 0, 10, True),), pwm_span_right,
               "the right ESC answers span × the logged PWM's deviation from neutral (another calibrated range)",
               _pwm_span_fit("right")),
    EffectSpec("reverse_thrust", "thrusters", (_v(*_SCALE),), reverse_thrust,
               "thrust astern weaker or stronger than the map's", _reverse_fit),
    EffectSpec("full_thrust", "thrusters", (_v("share", "×", 0, 10, True),), full_thrust,
               "forward thrust at full PWM × share, the low end held (ventilation, a worn propeller)",
               _full_thrust_fit),
    EffectSpec("dead_zone", "thrusters", (_v("fwd", "δ̃", 0, 0.9), _v("rev", "δ̃", 0, 0.9)), dead_zone,
               "dead-zone widths in normalised PWM", _dead_zone_fit),
    EffectSpec("dead_zone_left", "thrusters", (_v("fwd", "δ̃", 0, 0.9), _v("rev", "δ̃", 0, 0.9)), dead_zone_left,
               "the left thruster's own dead-zone widths in normalised PWM (one ESC or motor)",
               _side_dead_zone_fit("left")),
    EffectSpec("dead_zone_right", "thrusters", (_v("fwd", "δ̃", 0, 0.9), _v("rev", "δ̃", 0, 0.9)), dead_zone_right,
               "the right thruster's own dead-zone widths in normalised PWM (one ESC or motor)",
               _side_dead_zone_fit("right")),
    EffectSpec("motor_start", "thrusters", (_v("fwd", "δ̃", 0, 0.9), _v("rev", "δ̃", 0, 0.9)), motor_start,
               "start edges of a motor with start/stop hysteresis (a stopped motor starts late)", _motor_start_fit),
    EffectSpec("thrust_decay", "thrusters", (_v("decay_per_min", "1/min", 0, 0.99),), thrust_decay,
               "thrust sag over time",
               _single("thrust_decay", member("thrusters", "decay_per_min", "1/min", 0.0, 0.6, 0.05), ((0.02,),),
                       "thrust")),
    EffectSpec("supply_voltage", "thrusters", (_v("exponent", "-", 0, 10), _v("ref_v", "V", 0, 1000, default=0.0)),
               supply_voltage, "thrust following the logged battery voltage, × (V/V_ref)^exponent (a pack that sags)",
               _supply_fit),
    EffectSpec("thrust_speed_loss", "thrusters", (_v("advance_loss", "√N s/m", 0, 20),), thrust_speed_loss,
               "propeller thrust loss with advance speed (T0 − c·√|T0|·u_a)",
               _single("thrust_speed_loss", member("thrusters", "advance_loss", "√N s/m", 0.0, 8.0, 0.5),
                       ((0.5,),), "drag")),
    EffectSpec("quadratic_damping", "hull", (), quadratic_damping, "quadratic damping scales",
               _scales_fit("quadratic_damping", "damping", QUADRATIC_DAMPING), keys=QUADRATIC_DAMPING),
    EffectSpec("linear_damping", "hull", (), linear_damping, "linear damping scales",
               _scales_fit("linear_damping", "damping", LINEAR_DAMPING), keys=LINEAR_DAMPING),
    EffectSpec("surge_resistance", "hull", (), surge_resistance, "surge resistance curve of another shape",
               _scales_fit("surge_resistance", "damping", SURGE_RESISTANCE), keys=SURGE_RESISTANCE),
    EffectSpec("coupling_damping", "hull", (_v("Yr", "N s"), _v("Nv", "N s")), coupling_damping,
               "sway-yaw linear coupling damping",
               _pair_fit("coupling_damping", "damping", ("Yr", "Nv"), "N s", -60.0, 60.0, 1.0, "turning",
                         start_from_prior=True)),
    EffectSpec("speed_damping", "hull", (_v("Yuv", "N s2/m2", -500, 0), _v("Nur", "N m s2/m", -500, 0)),
               speed_damping, "sway and yaw damping growing with forward speed",
               _pair_fit("speed_damping", "damping", ("Yuv", "Nur"), "N s2/m2", -300.0, 0.0, 5.0, "drag",
                         start_from_prior=True)),
    EffectSpec("speed_coupling", "hull", (_v("Yur", "N s2/m", -500, 500), _v("Nuv", "N s2/m", -500, 500)),
               speed_coupling, "sway-yaw coupling growing with forward speed (a hull's lift in a turn)",
               _pair_fit("speed_coupling", "damping", ("Yur", "Nuv"), "N s2/m", -300.0, 300.0, 5.0, "turning",
                         start_from_prior=True)),
    EffectSpec("astern_resistance", "hull", (_v("excess", "-", -1, 20, True),), astern_resistance,
               "surge drag astern (1 + excess) times the drag ahead (a transom meeting the water)",
               _single("astern_resistance", member("damping", "astern_excess", "-", -0.5, 4.0, 0.2, name="excess"),
                       ((0.5,),), "drag")),
    EffectSpec("added_mass", "hull", (), added_mass, "added-mass scales",
               _scales_fit("added_mass", "added_mass", ADDED_MASS), keys=ADDED_MASS),
    EffectSpec("cg_offset", "hull", (_v("dx_m", "m", -1, 1), _v("dy_m", "m", -1, 1)), cg_offset,
               "mass distribution moved from the MJCF",
               _pair_fit("cg_offset", "vessel", ("cg_offset_m",), "m", -0.4, 0.4, 0.05, "inertia", index=True)),
    EffectSpec("clock_offset", "sensors", (_v("pwm_clock_offset_s", "s", -5, 5),), clock_offset,
               "PWM log stamps late",
               _single("clock_offset", member("sensors", "pwm_clock_offset_s", "s", -1.5, 1.5, 0.1), ((0.0,),),
                       "timing", scan=_grid(-0.96, 0.96, 0.12), scan_step=(0.01,), time_shift=True)),
    EffectSpec("gnss_latency", "sensors", (_v("gnss_latency_s", "s", -2, 5),), gnss_latency,
               "GNSS fixes stamped late",
               _single("gnss_latency", member("sensors", "gnss_latency_s", "s", 0.0, 1.5, 0.1), ((0.0,),),
                       "timing", scan=_grid(0.0, 1.2, 0.1), scan_step=(0.02,))),
    EffectSpec("heading_latency", "sensors", (_v("heading_latency_s", "s", -2, 5),), heading_latency,
               "heading samples stamped late (an AHRS filter)",
               _single("heading_latency", member("sensors", "heading_latency_s", "s", 0.0, 1.5, 0.1), ((0.0,),),
                       "timing", scan=_grid(0.0, 1.0, 0.1), scan_step=(0.02,))),
    EffectSpec("heading_bias", "sensors", (_v("heading_bias_deg", *_DEG),), heading_bias, "constant heading error",
               _single("heading_bias", member("sensors", "heading_bias_deg", "deg", -30.0, 30.0, 1.0), ((0.0,),),
                       "drift")),
    EffectSpec("heading_bias_per_log", "sensors", (_v("bias_deg", *_DEG),), heading_bias_per_log,
               "constant heading error of each log (file name), e.g. a compass calibrated before every outing",
               _per_log_fit, per_key="LOG"),
    EffectSpec("compass_deviation", "sensors",
               (_v("b_deg", "deg", -45, 45), _v("c_deg", "deg", -45, 45),
                _v("d_deg", "deg", -45, 45, default=0.0), _v("e_deg", "deg", -45, 45, default=0.0)),
               compass_deviation, "heading error varying with heading", _compass_fit),
    EffectSpec("compass_motor", "sensors", (_v("b_deg", "deg", -45, 45), _v("c_deg", "deg", -45, 45)),
               compass_motor, "heading error varying with heading, growing with the throttle (the motors' field, "
               "deg at full throttle)", _compass_motor_fit),
    EffectSpec("gnss_lever_arm", "sensors", (_v("dx_m", "m", -5, 5), _v("dy_m", "m", -5, 5)), gnss_lever_arm,
               "antenna displaced from the MJCF site",
               _pair_fit("gnss_lever_arm", "sensors", ("antenna_offset_m",), "m", -2.0, 2.0, 0.1, "turning",
                         index=True)),
]
EFFECTS: dict[str, EffectSpec] = {s.name: s for s in _SPECS}


def spec(name: str) -> EffectSpec:
    if name not in EFFECTS:
        raise TwinError(f"unknown effect '{name}' (known: {', '.join(EFFECTS)})")
    return EFFECTS[name]


def effect(name: str, **params) -> Effect:
    """A checked Effect: values as floats in range, defaults filled in; TwinError (one line) if not."""
    return checked(spec(name), params)


# what a diagnosis may change of a vessel whose model is not the PWM twin's: a propeller-and-rudder
# ship has no PWM map (lag, dead zone, gains: thrusters) and its hull is the MMG standard's, not the
# [Morel-2024] damping those effects scale
_ACTS_ON = {"propeller_rudder": ("environment", "sensors")}


def candidates(prior: Vessel, logs: list[str] = (), supply_ref_v: float | None = None) -> dict[str, Candidate]:
    """What a diagnosis can fit for this prior and the names of the logs diagnosed together;
    supply_ref_v: the reference voltage (V) of logs that all log their battery, for a prior that has
    none (only then is `supply_voltage` offered)."""
    if supply_ref_v is not None and prior.thrusters.supply_ref_v is None:
        prior = _thrusters(prior, supply_ref_v=float(supply_ref_v))
    out = {}
    for s in _SPECS:
        if s.acts_on not in _ACTS_ON.get(prior.thrusters.kind, (s.acts_on,)):
            continue
        cand = s.fit(prior, tuple(logs)) if s.fit is not None else None
        if cand is not None:
            out[s.name] = cand
    return out


def describe() -> str:
    """One line per effect: NAME=values (units) and what it does (for CLI help)."""
    lines = []
    for s in _SPECS:
        vals = ",".join(f"{p.name}" + ("?" if p.default is not None else "") for p in s.values)
        if s.per_key:
            vals = f"{s.per_key}:{PER_KEY_SEP.join(v.name for v in s.values)},..."
        vals = vals or f"S|KEY:S,... (KEY in {' '.join(s.keys)})"
        lines.append(f"{s.name}={vals}  [{s.acts_on}] {s.doc}")
    return "\n".join(lines)
