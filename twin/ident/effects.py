"""Physical effects injected by NAME and VALUE: the vocabulary a dataset's truth is
built from and the one a diagnosis names.

Every effect is a pure function `apply(vessel, **values) -> Vessel` on the one
vessel description, so the engine simulates it, the analytic model can check it
and an amended vessel file carries it. Where each lives:

  name                values (CLI order, units)        field of the vessel description
  current             speed_m_s, dir_deg               environment (dir = where the water goes, cw from N)
  wind                speed_m_s, dir_deg               environment (dir = where the wind comes from)
  thruster_lag        tau_s                            thrusters.lag_s (first-order lag, seed 004 eq. 15)
  input_delay         delay_s                          thrusters.delay_s (thrust acts on older PWM)
  thruster_asymmetry  ratio                            thrusters.gain_right / gain_left (mean kept)
  thrust_gain         scale (×)                        both thruster gains
  dead_zone           fwd, rev                         thrusters.deadzone_* widths in δ̃ = PWM/400 − offset
  thrust_decay        per_min (fraction/min)           thrusters.decay_per_min (battery sag)
  thrust_speed_loss   per_m_s (fraction per m/s)       thrusters.speed_loss_per_m_s (propeller advance)
  quadratic_damping   S or KEY:S,...  (×)              damping Xuu Yvv Yrv Yvr Yrr Nvv Nrv Nvr Nrr scaled
  linear_damping      S or KEY:S,...  (×)              damping Xu Yv Yr Nv Nr scaled
  coupling_damping    Yr, Nv (N s, N s)                damping Yr, Nv set (sway-yaw coupling)
  speed_damping       Yuv, Nur (N s²/m², N m s²/m)     damping Y_|u|v, N_|u|r set (derivatives growing with speed)
  added_mass          S or KEY:S,...  (×)              added_mass Xudot Yvdot Yrdot (with Nvdot) Nrdot scaled
  cg_offset           dx_m, dy_m                       cg_offset_m (mass distribution moved)
  clock_offset        offset_s                         sensors.pwm_clock_offset_s (PWM stamps late)
  heading_bias        bias_deg                         sensors.heading_bias_deg
  heading_bias_per_log LOG:bias_deg,...                sensors.heading_bias_by_log_deg (each log its own)
  compass_deviation   b_deg, c_deg[, d_deg, e_deg]     sensors.compass_deviation_deg
  gnss_lever_arm      dx_m, dy_m                       sensors.antenna_offset_m (antenna off the MJCF site)

Set effects replace the value; scale effects (the KEY:S ones, thrust_gain,
thruster_asymmetry) multiply what is there, so effects compose in the given
order. CLI text: `NAME=V1,V2` with the values in the order above, e.g.
`current=0.3,45`, `thruster_lag=0.4`, `quadratic_damping=Xuu:1.3,Nrr:0.8` or
`quadratic_damping=1.3` (every coefficient).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable


from ..errors import TwinError
from ..vessel import Vessel, check

QUADRATIC_DAMPING = ("Xuu", "Yvv", "Yrv", "Yvr", "Yrr", "Nvv", "Nrv", "Nvr", "Nrr")
LINEAR_DAMPING = ("Xu", "Yv", "Yr", "Nv", "Nr")
ADDED_MASS = ("Xudot", "Yvdot", "Yrdot", "Nrdot")
ALL = "all"  # the scale key that stands for every coefficient of a scale effect


@dataclass(frozen=True)
class Param:
    """One value of an effect: name, unit and the allowed range [lo, hi] (lo excluded if lo_open)."""

    name: str
    unit: str
    lo: float = -math.inf
    hi: float = math.inf
    lo_open: bool = False
    default: float | None = None  # None: required

    def check(self, effect: str, value: float) -> str | None:
        low_bad = value <= self.lo if self.lo_open else value < self.lo
        if not math.isfinite(value) or low_bad or value > self.hi:
            lo = f"{'>' if self.lo_open else '≥'} {self.lo:g}" if self.lo > -math.inf else ""
            hi = f"≤ {self.hi:g}" if self.hi < math.inf else ""
            return f"effect '{effect}': {self.name} must be {' and '.join(x for x in (lo, hi) if x) or 'finite'}, got {value:g}"
        return None


@dataclass(frozen=True)
class Spec:
    """A registered effect: what it acts on ("hull", "environment", "thrusters", "sensors"),
    its values and its function. keys: for scale effects, the coefficients that may be
    scaled (plus "all")."""

    name: str
    level: str
    params: tuple[Param, ...]
    apply: Callable
    doc: str
    keys: tuple[str, ...] = ()
    per_key: str = ""  # a free key (e.g. LOG): params maps key → value, each checked against params[0]


@dataclass(frozen=True)
class Effect:
    """An effect with values: params maps value names to floats (scale effects: keys to scales)."""

    name: str
    params: dict

    @property
    def spec(self) -> Spec:
        return spec(self.name)

    @property
    def text(self) -> str:
        """Canonical CLI text; parse_effect(effect.text) == effect."""
        if self.spec.keys or self.spec.per_key:
            p = self.params
            if set(p) == {ALL}:
                return f"{self.name}={p[ALL]:.12g}"
            return f"{self.name}=" + ",".join(f"{k}:{v:.12g}" for k, v in p.items())
        return f"{self.name}=" + ",".join(f"{self.params[q.name]:.12g}" for q in self.spec.params)

    def to_dict(self) -> dict:
        return {"name": self.name, "acts_on": self.spec.level, "params": dict(self.params), "text": self.text}


# ---------------------------------------------------------------- vessel effects

def current(vessel: Vessel, speed_m_s: float, dir_deg: float) -> Vessel:
    """Earth-fixed water current (m/s) flowing towards dir_deg (cw from north)."""
    env = replace(vessel.environment, current_speed_m_s=speed_m_s, current_dir_deg=dir_deg)
    return replace(vessel, environment=env)


def wind(vessel: Vessel, speed_m_s: float, dir_deg: float) -> Vessel:
    """Wind (m/s) blowing from dir_deg (cw from north) on the vessel's wind_load areas."""
    load = vessel.wind_load
    if speed_m_s > 0 and not (load.frontal_area_m2 > 0 or load.lateral_area_m2 > 0):
        raise TwinError(f"effect 'wind': vessel '{vessel.name}' has no wind_load areas, so wind would do nothing")
    env = replace(vessel.environment, wind_speed_m_s=speed_m_s, wind_dir_deg=dir_deg)
    return replace(vessel, environment=env)


def thruster_lag(vessel: Vessel, tau_s: float) -> Vessel:
    """First-order thrust lag time constant (s), seed 004 eq. 15; 0 = none."""
    return replace(vessel, thrusters=replace(vessel.thrusters, lag_s=tau_s))


def thruster_asymmetry(vessel: Vessel, ratio: float) -> Vessel:
    """Right gain / left gain multiplied by `ratio`, the mean of both gains kept,
    so the surge thrust at equal PWM stays and the vessel turns."""
    t = vessel.thrusters
    mean = 0.5 * (t.gain_left + t.gain_right)
    right_over_left = ratio * t.gain_right / t.gain_left
    left = 2 * mean / (1 + right_over_left)
    return replace(vessel, thrusters=replace(t, gain_left=left, gain_right=right_over_left * left))


def dead_zone(vessel: Vessel, fwd: float, rev: float) -> Vessel:
    """Dead-zone widths (≥ 0) in normalised PWM δ̃ = PWM/400 − offset (seed 000 eq. 27):
    no thrust for −rev < δ̃ < fwd. 0.0775 = 31 µs."""
    return replace(vessel, thrusters=replace(vessel.thrusters, deadzone_fwd=fwd, deadzone_rev=-rev))


def _scaled(obj, keys: tuple[str, ...], scales: dict, pairs: dict | None = None):
    values = {k: getattr(obj, k) * scales.get(k, scales.get(ALL, 1.0)) for k in keys}
    for k, twin_key in (pairs or {}).items():
        values[twin_key] = values[k]  # a symmetric pair is scaled together
    return replace(obj, **values)


def quadratic_damping(vessel: Vessel, **scales: float) -> Vessel:
    """Quadratic damping coefficients multiplied by scales ({"Xuu": 1.3}, or all=S)."""
    return replace(vessel, damping=_scaled(vessel.damping, QUADRATIC_DAMPING, scales))


def linear_damping(vessel: Vessel, **scales: float) -> Vessel:
    """Linear damping coefficients multiplied by scales ({"Xu": 0.8}, or all=S)."""
    return replace(vessel, damping=_scaled(vessel.damping, LINEAR_DAMPING, scales))


def added_mass(vessel: Vessel, **scales: float) -> Vessel:
    """Added-mass derivatives multiplied by scales; Yrdot scales Nvdot too (M_A stays symmetric)."""
    return replace(vessel, added_mass=_scaled(vessel.added_mass, ADDED_MASS, scales, {"Yrdot": "Nvdot"}))


def thrust_gain(vessel: Vessel, scale: float) -> Vessel:
    """Both thruster gains multiplied by `scale` (e.g. a higher supply voltage than the map's 10 V)."""
    t = vessel.thrusters
    return replace(vessel, thrusters=replace(t, gain_left=t.gain_left * scale, gain_right=t.gain_right * scale))


def coupling_damping(vessel: Vessel, Yr: float, Nv: float) -> Vessel:
    """Linear sway-yaw coupling damping Yr (N s), Nv (N s), Fossen's signs, set."""
    return replace(vessel, damping=replace(vessel.damping, Yr=Yr, Nv=Nv))


def speed_damping(vessel: Vessel, Yuv: float, Nur: float) -> Vessel:
    """Sway and yaw damping proportional to the forward speed, Y_|u|v and N_|u|r (Fossen's signs), set."""
    return replace(vessel, damping=replace(vessel.damping, Yuv=Yuv, Nur=Nur))


def cg_offset(vessel: Vessel, dx_m: float, dy_m: float) -> Vessel:
    """The whole mass distribution moved by (dx, dy) m, body FRD, from where the MJCF puts it."""
    return replace(vessel, cg_offset_m=(dx_m, dy_m))


def _thrusters(vessel: Vessel, **values) -> Vessel:
    return replace(vessel, thrusters=replace(vessel.thrusters, **values))


def _sensors(vessel: Vessel, **values) -> Vessel:
    return replace(vessel, sensors=replace(vessel.sensors, **values))


def input_delay(vessel: Vessel, delay_s: float) -> Vessel:
    """The thrusters act on the PWM logged delay_s (s) earlier."""
    return _thrusters(vessel, delay_s=delay_s)


def thrust_decay(vessel: Vessel, per_min: float) -> Vessel:
    """Thrust × (1 − per_min·t/60 s), t from the start of the recording (battery sag)."""
    return _thrusters(vessel, decay_per_min=per_min)


def thrust_speed_loss(vessel: Vessel, per_m_s: float) -> Vessel:
    """Thrust × (1 − per_m_s·advance speed of the thruster)."""
    return _thrusters(vessel, speed_loss_per_m_s=per_m_s)


def clock_offset(vessel: Vessel, offset_s: float) -> Vessel:
    """The PWM log's stamps are offset_s late against GNSS and heading (either sign)."""
    return _sensors(vessel, pwm_clock_offset_s=offset_s)


def heading_bias(vessel: Vessel, bias_deg: float) -> Vessel:
    return _sensors(vessel, heading_bias_deg=bias_deg)


def heading_bias_per_log(vessel: Vessel, **bias_deg_by_log: float) -> Vessel:
    """Each named log's own heading bias (deg), on top of the common one; set."""
    return _sensors(vessel, heading_bias_by_log_deg=tuple(sorted(bias_deg_by_log.items())))


def compass_deviation(vessel: Vessel, b_deg: float, c_deg: float, d_deg: float = 0.0, e_deg: float = 0.0) -> Vessel:
    """Heading error B sin ψ + C cos ψ + D sin 2ψ + E cos 2ψ (deg)."""
    return _sensors(vessel, compass_deviation_deg=(b_deg, c_deg, d_deg, e_deg))


def gnss_lever_arm(vessel: Vessel, dx_m: float, dy_m: float) -> Vessel:
    """The antenna sits (dx, dy) m, body FRD, off the MJCF gnss site."""
    return _sensors(vessel, antenna_offset_m=(dx_m, dy_m))


# ---------------------------------------------------------------- registry

def _p(name, unit, lo=-math.inf, hi=math.inf, lo_open=False, default=None) -> Param:
    return Param(name, unit, lo, hi, lo_open, default)


_SCALE = ("scale", "×", 0.0, 100.0, True)
_DEG = ("deg", -180.0, 180.0)
_SPECS = [
    Spec("current", "environment", (_p("speed_m_s", "m/s", 0, 10), _p("dir_deg", "deg", -360, 360)), current,
         "water current towards dir_deg"),
    Spec("wind", "environment", (_p("speed_m_s", "m/s", 0, 40), _p("dir_deg", "deg", -360, 360)), wind,
         "wind from dir_deg"),
    Spec("thruster_lag", "thrusters", (_p("tau_s", "s", 0, 10),), thruster_lag, "first-order thrust lag"),
    Spec("input_delay", "thrusters", (_p("delay_s", "s", 0, 5),), input_delay, "thrust acts on older PWM"),
    Spec("thruster_asymmetry", "thrusters", (_p("ratio", "×", 0, 10, True),), thruster_asymmetry,
         "right/left thrust gain ratio"),
    Spec("thrust_gain", "thrusters", (_p(*_SCALE),), thrust_gain, "overall thrust scale"),
    Spec("dead_zone", "thrusters", (_p("fwd", "δ̃", 0, 0.9), _p("rev", "δ̃", 0, 0.9)), dead_zone,
         "dead-zone widths in normalised PWM"),
    Spec("thrust_decay", "thrusters", (_p("per_min", "1/min", 0, 0.99),), thrust_decay, "thrust sag over time"),
    Spec("thrust_speed_loss", "thrusters", (_p("per_m_s", "s/m", 0, 0.99),), thrust_speed_loss,
         "thrust loss with advance speed"),
    Spec("quadratic_damping", "hull", (), quadratic_damping, "quadratic damping scales", QUADRATIC_DAMPING),
    Spec("linear_damping", "hull", (), linear_damping, "linear damping scales", LINEAR_DAMPING),
    Spec("coupling_damping", "hull", (_p("Yr", "N s"), _p("Nv", "N s")), coupling_damping,
         "sway-yaw linear coupling damping"),
    Spec("speed_damping", "hull", (_p("Yuv", "N s2/m2", -500, 0), _p("Nur", "N m s2/m", -500, 0)), speed_damping,
         "sway and yaw damping growing with forward speed"),
    Spec("added_mass", "hull", (), added_mass, "added-mass scales", ADDED_MASS),
    Spec("cg_offset", "hull", (_p("dx_m", "m", -1, 1), _p("dy_m", "m", -1, 1)), cg_offset,
         "mass distribution moved from the MJCF"),
    Spec("clock_offset", "sensors", (_p("offset_s", "s", -5, 5),), clock_offset, "PWM log stamps late"),
    Spec("heading_bias", "sensors", (_p("bias_deg", *_DEG),), heading_bias, "constant heading error"),
    Spec("heading_bias_per_log", "sensors", (_p("bias_deg", *_DEG),), heading_bias_per_log,
         "constant heading error of each log (file name), e.g. a compass calibrated before every outing",
         per_key="LOG"),
    Spec("compass_deviation", "sensors",
         (_p("b_deg", "deg", -45, 45), _p("c_deg", "deg", -45, 45),
          _p("d_deg", "deg", -45, 45, default=0.0), _p("e_deg", "deg", -45, 45, default=0.0)),
         compass_deviation, "heading error varying with heading"),
    Spec("gnss_lever_arm", "sensors", (_p("dx_m", "m", -5, 5), _p("dy_m", "m", -5, 5)), gnss_lever_arm,
         "antenna displaced from the MJCF site"),
]
EFFECTS: dict[str, Spec] = {s.name: s for s in _SPECS}


def spec(name: str) -> Spec:
    if name not in EFFECTS:
        raise TwinError(f"unknown effect '{name}' (known: {', '.join(EFFECTS)})")
    return EFFECTS[name]


def describe() -> str:
    """One line per effect: NAME=values (units) and what it does (for CLI help)."""
    lines = []
    for s in _SPECS:
        vals = ",".join(f"{p.name}" + ("?" if p.default is not None else "") for p in s.params)
        if s.per_key:
            vals = f"{s.per_key}:{s.params[0].name},..."
        vals = vals or f"S|KEY:S,... (KEY in {' '.join(s.keys)})"
        lines.append(f"{s.name}={vals}  [{s.level}] {s.doc}")
    return "\n".join(lines)


# ---------------------------------------------------------------- building and parsing

def effect(name: str, **params) -> Effect:
    """A checked Effect: values as floats in range, defaults filled in; TwinError (one line) if not."""
    s = spec(name)
    if s.keys:
        return Effect(name, _check_scales(s, params))
    if s.per_key:
        return Effect(name, _check_per_key(s, params))
    known = [p.name for p in s.params]
    unknown = sorted(set(params) - set(known))
    if unknown:
        raise TwinError(f"effect '{name}': unknown value(s) {', '.join(unknown)} (takes {', '.join(known)})")
    out = {}
    for p in s.params:
        if p.name not in params and p.default is None:
            raise TwinError(f"effect '{name}': missing {p.name} ({p.unit}); takes {', '.join(known)}")
        value = _number(name, params.get(p.name, p.default))
        if (msg := p.check(name, value)) is not None:
            raise TwinError(msg)
        out[p.name] = value
    return Effect(name, out)


def _check_scales(s: Spec, params: dict) -> dict:
    if not params:
        raise TwinError(f"effect '{s.name}': give a scale S or KEY:S (KEY in {', '.join(s.keys)})")
    bound = Param("scale", "×", 0.0, 100.0, True)
    out = {}
    for key, value in params.items():
        if key not in s.keys and key != ALL:
            raise TwinError(f"effect '{s.name}': unknown coefficient '{key}' (known: {', '.join(s.keys)}, all)")
        value = _number(s.name, value)
        if (msg := bound.check(s.name, value)) is not None:
            raise TwinError(msg.replace("scale", f"scale of {key}"))
        out[key] = value
    return out


def _check_per_key(s: Spec, params: dict) -> dict:
    if not params:
        raise TwinError(f"effect '{s.name}': give {s.per_key}:{s.params[0].name} pairs")
    out = {}
    for key, value in params.items():
        if not str(key).strip():
            raise TwinError(f"effect '{s.name}': empty {s.per_key} name")
        value = _number(s.name, value)
        if (msg := s.params[0].check(s.name, value)) is not None:
            raise TwinError(msg)
        out[str(key)] = value
    return out


def _number(name: str, value) -> float:
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise TwinError(f"effect '{name}': '{value}' is not a number") from None
    if not math.isfinite(out):
        raise TwinError(f"effect '{name}': '{value}' is not a finite number")
    return out


def parse_effect(text: str) -> Effect:
    """`NAME=V1,V2,...` (values in the documented order) or, for scale effects,
    `NAME=S` / `NAME=KEY:S,KEY:S` → Effect; TwinError with one line on bad input."""
    name, sep, values = str(text).partition("=")
    name, values = name.strip(), values.strip()
    if not sep or not name or not values:
        raise TwinError(f"effect '{text}': expected NAME=VALUES, e.g. current=0.3,45 or thruster_lag=0.4")
    s = spec(name)
    items = [v.strip() for v in values.split(",")]
    if s.keys:
        return effect(name, **_scale_items(name, items))
    if s.per_key:
        return effect(name, **_key_items(name, items, s.per_key))
    required = sum(p.default is None for p in s.params)
    if not required <= len(items) <= len(s.params):
        count = f"{required}" if required == len(s.params) else f"{required} to {len(s.params)}"
        want = ",".join(p.name for p in s.params)
        raise TwinError(f"effect '{name}': expected {count} value(s) {want}, got {len(items)}")
    return effect(name, **{p.name: v for p, v in zip(s.params, items)})


def _scale_items(name: str, items: list[str]) -> dict:
    if len(items) == 1 and ":" not in items[0]:
        return {ALL: items[0]}
    return _key_items(name, items, "KEY", "SCALE")


def _key_items(name: str, items: list[str], what: str, value_name: str = "VALUE") -> dict:
    """KEY:VALUE items whose key may itself hold colons (a log's name): split at the last one."""
    out = {}
    for item in items:
        key, sep, value = item.rpartition(":")
        if not sep or not key.strip():
            raise TwinError(f"effect '{name}': expected {what}:{value_name}, got '{item}'")
        out[key.strip()] = value.strip()
    return out


def as_effect(item) -> Effect:
    """An Effect from an Effect, CLI text, a (name, {params}) pair or a {"name", "params"} dict."""
    if isinstance(item, Effect):
        return effect(item.name, **item.params)
    if isinstance(item, str):
        return parse_effect(item)
    if isinstance(item, dict) and "name" in item:
        return effect(item["name"], **dict(item.get("params") or {}))
    if isinstance(item, (tuple, list)) and len(item) == 2 and isinstance(item[1], dict):
        return effect(item[0], **item[1])
    raise TwinError(f"not an effect: {item!r} (give NAME=VALUES text or (name, params))")


def apply_effects(vessel: Vessel, effects=()) -> Vessel:
    """Apply effects in order to the vessel description; the result is checked
    (dissipative damping, symmetric M_A, positive gains)."""
    for item in effects:
        e = as_effect(item)
        vessel = e.spec.apply(vessel, **e.params)
    try:
        check(vessel)
    except TwinError as exc:
        raise TwinError(f"effects make the vessel unphysical: {exc}") from None
    return vessel
