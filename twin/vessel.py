"""The one vessel description: a JSON parameter file next to the MJCF.

The MJCF carries geometry, mass distribution and sites (thrusters, IMU, GNSS
antenna); the JSON carries everything hydrodynamic and actuation-related and
names its MJCF. Identification writes this file, the engine callbacks and the
analytic model read it, diagnosis amends it. Nothing else defines parameters.
"""
from __future__ import annotations

import json
import math
import os
import types
import typing
from importlib import resources
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from .errors import TwinError
from .files import write_text_atomic
from .physics.added_mass import AddedMass
from .physics.damping import Damping, is_dissipative
from .physics.environment import Environment, WindLoad
from .physics.fujiwara import COEFFICIENTS as WIND_COEFFICIENTS
from .physics.fujiwara import FujiwaraWind
from .physics.mmg import MmgHull, MmgModel, MmgPropeller, MmgRudder
from .physics.priors import Design
from .physics.sensors import Sensors
from .physics.thrusters import ThrusterModel

# the vessels ship inside the package (package data), so an installed `twin` finds them from any folder
MODEL_DIR = Path(str(resources.files("twin") / "model"))
PACKAGE_MJCF = "package:"  # "mjcf": "package:blueboat.xml" names an MJCF shipped in twin/model
CASES = ("min", "nominal", "max")
# thrusters.kind: PWM thrusters [Yellowfish-TR eq. 27], thrusts in N, a propeller and rudder (physics/thrusters.py)
THRUSTER_KINDS = ("t200", "direct", "propeller_rudder")


@dataclass(frozen=True)
class MassCase:
    """Changes to the MJCF for one mass case [Yellowfish-TR Tables III-IV]."""

    geom_mass_kg: dict[str, float] = field(default_factory=dict)
    body_x_m: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class Vessel:
    """A vessel as its vessel file describes it: its MJCF (hull meshes, masses, thruster and sensor
    sites), added mass, damping, thrusters (or an MMG propeller and rudder), wind load, environment,
    sensors, mass cases and each figure's source (`sources`); what identification left uncertain
    (`uncertainty`). Frozen: `with_case`, `with_environment` and `dataclasses.replace` make new ones."""

    name: str
    mjcf: Path
    added_mass: AddedMass
    damping: Damping
    thrusters: ThrusterModel
    wind_load: WindLoad = field(default_factory=WindLoad)
    environment: Environment = field(default_factory=Environment)
    sensors: Sensors = field(default_factory=Sensors)
    cg_offset_m: tuple[float, float] = (0.0, 0.0)  # the whole mass distribution moved by (x, y) from the MJCF
    cases: dict[str, MassCase] = field(default_factory=dict)
    case: str = "nominal"
    sources: dict[str, str] = field(default_factory=dict)
    # what identification left uncertain: {"coordinates": [{"name", "log", "sign"}], "mean": [...],
    # "covariance": [[...]]} in the fit's coordinates (ln|θ| where "log"), see twin.fit.uncertainty
    uncertainty: dict = field(default_factory=dict)
    mmg: MmgModel | None = None  # MMG standard method of a propeller-and-rudder ship
    wind_regression: FujiwaraWind | None = None  # Fujiwara wind loads, in place of wind_load
    design: Design | None = None  # what the first-principles estimate needs beyond the MJCF (verify/priors.py)
    path: Path | None = None

    def __repr__(self) -> str:
        made = [w for k, w in (("identification", "identified"), ("diagnosis", "amended by a diagnosis"))
                if k in self.sources]
        # a twin identify or a diagnosis made in memory has no file of its own until it is saved
        where = f" from {self.path.name}" if self.path else " (not saved)" if made else ""
        return f"Vessel({self.name}{', ' + ', '.join(made) if made else ''}{where}, case {self.case}, MJCF {self.mjcf.name})"

    def with_case(self, case: str) -> "Vessel":
        """The same vessel loaded as its mass case `case` ("nominal" or one of `cases`)."""
        if case != "nominal" and case not in self.cases:
            known = ", ".join(sorted({"nominal", *self.cases}))
            raise TwinError(f"vessel '{self.name}' has no mass case '{case}' (known: {known})")
        return replace(self, case=case)

    def with_environment(self, environment: Environment) -> "Vessel":
        """The same vessel in another environment (current, wind, sea)."""
        return replace(self, environment=environment)

    def feels_wind(self) -> bool:
        """A wind load model: projected areas (wind_load) or a published regression (wind_regression)."""
        load = self.wind_load
        return load.frontal_area_m2 > 0 or load.lateral_area_m2 > 0 or self.wind_regression is not None

    def as_logged(self) -> "Vessel":
        """The vessel as a recording's replay drives it (ThrusterModel.as_logged): a logged
        propeller speed or rudder angle is not clipped to the bounds of the twin's own commands."""
        thrusters = self.thrusters.as_logged()
        return self if thrusters is self.thrusters else replace(self, thrusters=thrusters)

    def to_dict(self) -> dict[str, Any]:
        mjcf = self.mjcf
        if Path(self.mjcf).resolve().parent == MODEL_DIR.resolve():
            # a shipped MJCF by its package name: the file stays valid wherever it is moved or installed
            mjcf = Path(PACKAGE_MJCF + Path(self.mjcf).name)
        elif self.path is not None:
            try:
                mjcf = Path(os.path.relpath(self.mjcf, self.path.parent))
            except ValueError:
                pass
        return {
            "name": self.name,
            "mjcf": str(mjcf),
            # the mass case it is in, where not nominal: a dataset simulated in case max, or a twin fitted
            # in it, describes that boat (load() takes it, unless told another case)
            **({"case": self.case} if self.case != "nominal" else {}),
            "added_mass": asdict(self.added_mass),
            "damping": asdict(self.damping),
            "thrusters": _thrusters_to_dict(self.thrusters),
            "wind_load": asdict(self.wind_load),
            "environment": environment_to_dict(self.environment),
            "sensors": _sensors_to_dict(self.sensors),
            "cg_offset_m": list(self.cg_offset_m),
            "cases": {k: asdict(v) for k, v in self.cases.items()},
            "sources": dict(self.sources),
            **({"uncertainty": self.uncertainty} if self.uncertainty else {}),
            **({"mmg": _mmg_to_dict(self.mmg)} if self.mmg is not None else {}),
            **({"wind_regression": _wind_regression_to_dict(self.wind_regression)}
               if self.wind_regression is not None else {}),
            **({"design": asdict(self.design)} if self.design is not None else {}),
        }


def _thrusters_to_dict(t: ThrusterModel) -> dict[str, Any]:
    d = asdict(t)
    d["forward"], d["reverse"] = list(t.forward), list(t.reverse)
    d["reversed_channels"] = list(t.reversed_channels)
    if t.kind != "propeller_rudder":  # fields of a propeller and rudder only: other files stay as they were
        for key in ("rps_max", "rudder_max_deg"):
            d.pop(key)
    for key in ("start_fwd", "start_rev"):  # only where a motor starts late: other files stay as they were
        if d[key] is None:
            d.pop(key)
    for key in ("deadzone_left", "deadzone_right"):  # only where a thruster has a dead zone of its own
        if d[key] is None:
            d.pop(key)
        else:
            d[key] = list(d[key])
    if not d["ramp_s"]:  # only where the thrust is slew-limited
        d.pop("ramp_s")
    if not d["supply_exponent"] and d["supply_ref_v"] is None:  # only where the thrust follows the supply
        d.pop("supply_exponent"), d.pop("supply_ref_v")
    if d["full_share"] == 1.0:  # only where the forward curve saturates
        d.pop("full_share")
    for key in ("pwm_span_left", "pwm_span_right"):  # only where an ESC answers another range
        if d[key] == 1.0:
            d.pop(key)
    return d


def _mmg_to_dict(m) -> dict[str, Any]:
    """The MMG block; the astern side force's coefficients only where some are set (files without
    them stay what they were: dataset fingerprints)."""
    d = asdict(m)
    if not m.friction_factor:  # only where R'_0 follows the friction line
        d.pop("friction_factor"), d.pop("reference_speed_m_s")
    for key in ("astern_side_y", "astern_side_n"):
        if not any(getattr(m.propeller, key)):
            del d["propeller"][key]
        else:
            d["propeller"][key] = list(getattr(m.propeller, key))
    return d


def _wind_regression_to_dict(w: FujiwaraWind) -> dict[str, Any]:
    d = asdict(w)
    d["coefficients"] = None if w.coefficients is None else list(w.coefficients)
    return d


def environment_to_dict(env: Environment) -> dict[str, Any]:
    """The environment's fields; the per-log winds only when there are some (a vessel file, and the
    fingerprint of a dataset made from it, stay what they were before logs had winds of their own)."""
    d = asdict(env)
    if not env.wind_by_log:
        del d["wind_by_log"]
    if not any(env.wave_drift_ned):  # likewise: only a twin given a sea as a known input carries one
        del d["wave_drift_ned"]
    else:
        d["wave_drift_ned"] = list(env.wave_drift_ned)
    if not env.wave_load:
        del d["wave_load"]
    else:
        d["wave_load"] = list(env.wave_load)
    return d


def _sensors_to_dict(s: Sensors) -> dict[str, Any]:
    d = asdict(s)
    if s.heading_rate_window_s is None:  # files without it stay what they were (dataset fingerprints)
        del d["heading_rate_window_s"]
    if s.yaw_rate_source == "heading":  # likewise
        del d["yaw_rate_source"]
    if not s.heading_latency_s:  # likewise
        del d["heading_latency_s"]
    if not s.follows_throttle:  # likewise
        del d["compass_motor_deg"]
    if not any(s.input_answer_s):  # likewise
        del d["input_answer_s"]
    return {k: list(v) if isinstance(v, tuple) else v for k, v in d.items()}


def _build(cls, data: dict | None, what: str, path: Path):
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise TwinError(f"{path.name}: {what} must be an object of named fields")
    known = {f.name for f in fields(cls)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise TwinError(f"{path.name}: unknown {what} field(s) {', '.join(unknown)}")
    hints = typing.get_type_hints(cls)
    # a string where a number belongs would otherwise surface as a TypeError deep in the physics
    data = {k: _typed(v, hints[k], f"{what}.{k}", path) for k, v in data.items()}
    try:
        return cls(**data)
    except TypeError as exc:
        raise TwinError(f"{path.name}: bad {what}: {exc}") from None
    except TwinError as exc:  # a field's own check: said with the file it is in
        raise TwinError(f"{path.name}: {exc}") from None


def _typed(value, hint, where: str, path: Path):
    """`value` checked against the field's annotation (float, str, X | None, tuple[...], dict[str, X]);
    JSON lists become tuples."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if hint is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise TwinError(f"{path.name}: {where} must be a number, got {_shown(value)}")
        if not math.isfinite(value):
            raise TwinError(f"{path.name}: {where} is not a finite number")
        return value
    if hint is str:
        if not isinstance(value, str):
            raise TwinError(f"{path.name}: {where} must be a string, got {_shown(value)}")
        return value
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        return _typed(value, next(a for a in args if a is not type(None)), where, path)
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise TwinError(f"{path.name}: {where} must be a list, got {_shown(value)}")
        if args and args[-1] is not Ellipsis and len(value) != len(args):
            raise TwinError(f"{path.name}: {where} must be a list of {len(args)} values, got {len(value)}")
        item_hints = [args[0]] * len(value) if args[-1:] == (Ellipsis,) else list(args)
        return tuple(_typed(x, h, f"{where}[{i}]", path) for i, (x, h) in enumerate(zip(value, item_hints)))
    if origin is dict:
        if not isinstance(value, dict):
            raise TwinError(f"{path.name}: {where} must be an object, got {_shown(value)}")
        return {k: _typed(x, args[1], f"{where}.{k}", path) for k, x in value.items()}
    return value


def _shown(value) -> str:
    text = json.dumps(value, ensure_ascii=False)
    return text if len(text) <= 40 else text[:37] + "..."


def _pair(value, what: str, path: Path) -> tuple[float, float]:
    return _typed(value, tuple[float, float], what, path)


VESSEL_FILE_KEYS = frozenset({"name", "mjcf", "added_mass", "damping", "thrusters", "wind_load", "environment",
                              "sensors", "cg_offset_m", "cases", "sources", "uncertainty", "mmg", "wind_regression",
                              "design", "case"})
REQUIRED_SECTIONS = ("added_mass", "damping", "thrusters")


def from_dict(data: dict[str, Any], path: Path) -> Vessel:
    if not isinstance(data, dict):
        raise TwinError(f"{path.name}: a vessel file is a JSON object with at least 'name' and 'mjcf'")
    if {"vessel", "effects", "segments"} <= set(data) and isinstance(data["vessel"], dict):
        data = data["vessel"]  # a dataset's truth: its vessel, written against the truth file's own folder
    lacking = [k for k in ("name", "mjcf") if k not in data]
    if lacking:
        raise TwinError(f"{path.name}: a vessel file needs {' and '.join(repr(k) for k in lacking)}")
    _typed(data["name"], str, "name", path)
    _typed(data["mjcf"], str, "mjcf", path)
    shipped = data["mjcf"].startswith(PACKAGE_MJCF)
    mjcf = (MODEL_DIR / data["mjcf"][len(PACKAGE_MJCF):]) if shipped else (path.parent / data["mjcf"]).resolve()
    if not shipped and not mjcf.is_file() and Path(data["mjcf"]).name == data["mjcf"] \
            and (MODEL_DIR / data["mjcf"]).is_file():
        # a shipped vessel file copied elsewhere names its MJCF by a bare file name, as it lies beside it in
        # the package: found there when the copy's own folder has none (an MJCF of that name beside it wins)
        mjcf = MODEL_DIR / data["mjcf"]
    if not mjcf.is_file():
        raise TwinError(f"{path.name}: MJCF file '{data['mjcf']}' not found (looked beside the vessel file; "
                        f"'{PACKAGE_MJCF}NAME.xml' names one shipped with twin)")
    if mjcf.suffix.lower() != ".xml":  # MuJoCo picks its reader by the extension, and warns on stdout without one
        raise TwinError(f"{path.name}: MJCF file '{data['mjcf']}' must be an .xml file")
    unknown = sorted(set(data) - VESSEL_FILE_KEYS)
    if unknown:  # a misspelt section would otherwise load as its defaults: a twin without that physics
        raise TwinError(f"{path.name}: unknown vessel file field(s) {', '.join(unknown)} "
                        f"(known: {', '.join(sorted(VESSEL_FILE_KEYS))})")
    # null is as good as missing, and so is an empty added mass or thrusters section (its defaults are
    # zeros and a generic thruster); an empty damping is an MMG hull's, refused below for any other
    missing = [k for k in REQUIRED_SECTIONS if data.get(k) is None or (k != "damping" and data.get(k) == {})]
    if missing:
        raise TwinError(f"{path.name}: a vessel file needs its {', '.join(missing)} section(s); "
                        "without them the twin would run with zero or default physics")
    for key in ("cases", "sources"):
        if not isinstance(data.get(key) or {}, dict):
            raise TwinError(f"{path.name}: {key} must be an object, got {_shown(data[key])}")
    cases = {}
    for name, c in (data.get("cases") or {}).items():
        cases[name] = _build(MassCase, c, f"cases.{name}", path)
    vessel = Vessel(
        name=str(data["name"]),
        mjcf=mjcf,
        added_mass=_build(AddedMass, data.get("added_mass"), "added_mass", path),
        damping=_build(Damping, data.get("damping"), "damping", path),
        thrusters=_build(ThrusterModel, data.get("thrusters"), "thrusters", path),
        wind_load=_build(WindLoad, data.get("wind_load"), "wind_load", path),
        environment=_build(Environment, data.get("environment"), "environment", path),
        sensors=_build(Sensors, data.get("sensors"), "sensors", path),
        cg_offset_m=_pair(data.get("cg_offset_m", (0.0, 0.0)), "cg_offset_m", path),
        cases=cases,
        sources=dict(data.get("sources") or {}),
        uncertainty=_uncertainty(data.get("uncertainty"), path),
        mmg=_mmg(data.get("mmg"), path),
        wind_regression=_wind_regression(data.get("wind_regression"), path),
        design=_design(data.get("design"), path),
        path=path,
    )
    _fitted_coefficients_given(data, vessel.uncertainty, path)
    case = data.get("case", "nominal")
    if not isinstance(case, str):
        raise TwinError(f"{path.name}: case must be a mass case's name, got {_shown(case)}")
    try:
        vessel = vessel.with_case(case)
        check(vessel)
    except TwinError as exc:  # the file a user gave, not only the vessel's name, so they know what to edit
        raise TwinError(f"{path.name}: {exc}") from None
    _plausible(vessel, path)
    return vessel


# a file's value past these is a unit slip (ms for s, mm for m, percent for a factor), not a small vessel
MOST_GAIN, MOST_LAG_S, MOST_CG_OFFSET_M = 10.0, 10.0, 5.0


def _plausible(vessel: Vessel, path: Path) -> None:
    """Refuse what a vessel file can hold but no small vessel has, naming the field: a file that
    loads runs, and a unit slipped by 1000 would run as another boat (checked at load only: a fit's
    candidates may pass through values a file should not hold)."""
    am, t, load = vessel.added_mass, vessel.thrusters, vessel.wind_load
    for name in ("Xudot", "Yvdot", "Nrdot"):
        if getattr(am, name) > 0:
            raise TwinError(f"{path.name}: added_mass.{name} is {getattr(am, name):g}: a hull's added mass adds to its "
                            "inertia, so the derivative is ≤ 0")
    if vessel.mmg is None and t.kind != "propeller_rudder" and not any(asdict(vessel.damping).values()):
        raise TwinError(f"{path.name}: damping has no coefficient: the twin would never slow down (give its "
                        "coefficients, N s/m and N s²/m², negative)")
    for name in ("gain_left", "gain_right"):
        if getattr(t, name) > MOST_GAIN:
            raise TwinError(f"{path.name}: thrusters.{name} is {getattr(t, name):g}, a factor on the thrust map: "
                            f"beyond {MOST_GAIN:g} it is no thruster's (a percentage?)")
    if t.reversed_channels:
        # the twin maps each thruster's PWM as logged: a reversed channel is mirrored where the log is read
        raise TwinError(f"{path.name}: thrusters.reversed_channels {list(t.reversed_channels)}: a channel wired in "
                        "reverse is mirrored where the log is read (an ArduPilot log's SERVOn_REVERSED does it; in a "
                        "CSV give the column mirrored about its neutral, 2·neutral − pwm), not in the vessel file")
    for name in ("pwm_span_left", "pwm_span_right"):
        if not 0.0 < getattr(t, name) <= MOST_GAIN:
            raise TwinError(f"{path.name}: thrusters.{name} is {getattr(t, name):g}, a factor on the PWM's "
                            f"deviation from neutral: it must be above 0 and at most {MOST_GAIN:g}")
    for name in ("lag_s", "delay_s"):
        if getattr(t, name) > MOST_LAG_S:
            raise TwinError(f"{path.name}: thrusters.{name} is {getattr(t, name):g} s, beyond {MOST_LAG_S:g} s "
                            "(milliseconds given as seconds?)")
    if math.hypot(*vessel.cg_offset_m) > MOST_CG_OFFSET_M:
        raise TwinError(f"{path.name}: cg_offset_m {list(vessel.cg_offset_m)} moves the masses more than "
                        f"{MOST_CG_OFFSET_M:g} m (millimetres given as metres?)")
    for name in ("frontal_area_m2", "lateral_area_m2", "length_m"):
        if getattr(load, name) < 0:
            raise TwinError(f"{path.name}: wind_load.{name} must be ≥ 0, got {getattr(load, name):g}")


def _fitted_coefficients_given(data: dict, uncertainty: dict, path: Path) -> None:
    """A coefficient the identification fitted (named in the uncertainty block) must be in the file:
    left out, it would load as 0, and the twin would run without a term its fit found (a hand edit
    that deleted one line)."""
    for c in uncertainty.get("coordinates", []):
        name = c["name"]
        for section, cls in (("damping", Damping), ("added_mass", AddedMass)):
            if name in {f.name for f in fields(cls)} and name not in (data.get(section) or {}):
                raise TwinError(f"{path.name}: the identification fitted {name} (uncertainty.coordinates), but the "
                                f"{section} section does not give it: it would run as 0 (write its value back)")


LEGACY_DRIFT_DOMAIN_DEG = 90.0  # mmg.drift_domain_deg of a vessel file that does not give it


def _mmg(data, path: Path) -> MmgModel | None:
    """The `mmg` block: top-level particulars plus `hull`, `propeller` and `rudder` objects."""
    if data is None:
        return None
    if not isinstance(data, dict):
        raise TwinError(f"{path.name}: mmg must be an object of named fields")
    parts = {"hull": MmgHull, "propeller": MmgPropeller, "rudder": MmgRudder}
    lacking = [k for k in parts if data.get(k) is None]
    if lacking:  # each would load as zeros: a ship without that physics
        raise TwinError(f"{path.name}: mmg needs its {', '.join(lacking)} object(s)")
    built = {k: _build(cls, data.get(k), f"mmg.{k}", path) for k, cls in parts.items()}
    # a file without it was written (and its hull identified) with the polynomial as it is at every drift
    top = _build(MmgModel, {"drift_domain_deg": LEGACY_DRIFT_DOMAIN_DEG,
                            **{k: v for k, v in data.items() if k not in parts}}, "mmg", path)
    return replace(top, **built)


def _design(data, path: Path) -> Design | None:
    """The `design` block: top speed and the few hardware figures of the first-principles estimate."""
    if data is None:
        return None
    d = _build(Design, data, "design", path)
    if not (d.top_speed_m_s > 0 and d.form_factor >= 1 and d.cross_flow_cd > 0 and d.duct_diameter_m >= 0
            and d.propeller_diameter_m >= 0):
        raise TwinError(f"{path.name}: design needs top_speed_m_s > 0, form_factor ≥ 1, cross_flow_cd > 0 and "
                        "diameters ≥ 0")
    # beyond these a figure is in another unit (km/h, mm), not a small vessel's
    if d.top_speed_m_s > 30 or max(d.duct_diameter_m, d.propeller_diameter_m) > 3 or d.form_factor > 3:
        raise TwinError(f"{path.name}: design top_speed_m_s {d.top_speed_m_s:g} (at most 30 m/s), diameters "
                        f"{d.duct_diameter_m:g}, {d.propeller_diameter_m:g} (at most 3 m) or form_factor "
                        f"{d.form_factor:g} (at most 3) lies beyond any small vessel: is a unit another?")
    return d


def _wind_regression(data, path: Path) -> FujiwaraWind | None:
    if data is None:
        return None
    w = _build(FujiwaraWind, data, "wind_regression", path)
    if w.coefficients is not None and len(w.coefficients) != len(WIND_COEFFICIENTS):
        raise TwinError(f"{path.name}: wind_regression.coefficients must be {len(WIND_COEFFICIENTS)} numbers "
                        f"({', '.join(WIND_COEFFICIENTS)})")
    try:
        return w.resolved()
    except ZeroDivisionError:
        raise TwinError(f"{path.name}: wind_regression: a zero area, length or height leaves the regression "
                        "undefined; give the coefficients") from None


def _uncertainty(data, path: Path) -> dict:
    """The identification's uncertainty block, checked for shape (a covariance of the coordinates)."""
    if not data:
        return {}
    if not isinstance(data, dict) or not {"coordinates", "mean", "covariance"} <= set(data):
        raise TwinError(f"{path.name}: uncertainty needs coordinates, mean and covariance")
    _uncertainty_coordinates(data["coordinates"], path)
    n = len(data["coordinates"])
    cov = data["covariance"]
    if not isinstance(data["mean"], list) or not isinstance(cov, list) or not all(isinstance(r, list) for r in cov):
        raise TwinError(f"{path.name}: uncertainty.mean must be a list of numbers and uncertainty.covariance a "
                        "list of rows")
    if len(data["mean"]) != n or len(cov) != n or any(len(row) != n for row in cov):
        raise TwinError(f"{path.name}: uncertainty: mean and covariance must match the {n} coordinates")
    for i, x in enumerate(data["mean"]):
        _typed(x, float, f"uncertainty.mean[{i}]", path)
    for i, row in enumerate(cov):
        for j, x in enumerate(row):
            _typed(x, float, f"uncertainty.covariance[{i}][{j}]", path)
        if row[i] < 0:  # a variance: the draws take its square root
            raise TwinError(f"{path.name}: uncertainty.covariance[{i}][{i}] is a variance and must be ≥ 0, "
                            f"got {row[i]}")
    return {"coordinates": [dict(c) for c in data["coordinates"]], "mean": [float(x) for x in data["mean"]],
            "covariance": [[float(x) for x in row] for row in cov],
            **({"source": str(data["source"])} if "source" in data else {}),
            **({"fitted_on": _fitted_on(data["fitted_on"], path)} if "fitted_on" in data else {}),
            **({"form_error": _form_error(data["form_error"], path)} if "form_error" in data else {}),
            **({"stand_ins": _stand_ins(data["stand_ins"], path)} if "stand_ins" in data else {})}


def _uncertainty_coordinates(coordinates, path: Path) -> None:
    """The coordinates of the uncertainty block: objects with a 'name' (a coefficient) and 'log'
    (true: the coordinate is ln|θ|, with the coefficient's 'sign'), as twin.fit.uncertainty reads them."""
    if not isinstance(coordinates, list):
        raise TwinError(f"{path.name}: uncertainty.coordinates must be a list of objects with 'name' and 'log', "
                        f"got {_shown(coordinates)}")
    for i, c in enumerate(coordinates):
        where = f"uncertainty.coordinates[{i}]"
        if not isinstance(c, dict) or not {"name", "log"} <= set(c):
            raise TwinError(f"{path.name}: {where} must be an object with 'name' and 'log', got {_shown(c)}")
        _typed(c["name"], str, f"{where}.name", path)
        if not isinstance(c["log"], bool):
            raise TwinError(f"{path.name}: {where}.log must be true or false, got {_shown(c['log'])}")
        if c["log"] and "sign" not in c:
            raise TwinError(f"{path.name}: {where}: a log coordinate needs the coefficient's 'sign' (1 or -1)")
        if "sign" in c:
            _typed(c["sign"], float, f"{where}.sign", path)


def _stand_ins(data, path: Path) -> list[dict]:
    """The coefficients the fit moved beyond what their beliefs allow (twin identify): per entry its name,
    unit, value, prior and how many belief σ it lies from the prior."""
    bad = TwinError(f"{path.name}: uncertainty.stand_ins needs a list of entries, each with name and unit (text), "
                    "value, prior and from_prior_sigmas (numbers)")
    if not isinstance(data, list):
        raise bad
    out = []
    for e in data:
        if not isinstance(e, dict) or not {"name", "unit", "value", "prior", "from_prior_sigmas"} <= set(e):
            raise bad
        if not isinstance(e["name"], str) or not isinstance(e["unit"], str) or not all(
                isinstance(e[k], (int, float)) and not isinstance(e[k], bool) and math.isfinite(e[k])
                for k in ("value", "prior", "from_prior_sigmas")):
            raise bad
        out.append({"name": e["name"], "unit": e["unit"], "value": float(e["value"]), "prior": float(e["prior"]),
                    "from_prior_sigmas": float(e["from_prior_sigmas"])})
    return out


def _form_error(data, path: Path) -> dict:
    """The twin's error on left-out runs (twin.fit.crossval.form_error): horizons, levels, and per
    quantity one row of non-negative quantiles per horizon."""
    bad = TwinError(f"{path.name}: uncertainty.form_error needs horizon_s (increasing), levels (in (0, 1)) and "
                    "quantiles: per quantity one row of numbers ≥ 0 per horizon, one per level")
    if not isinstance(data, dict) or not {"horizon_s", "levels", "quantiles"} <= set(data):
        raise bad
    h, levels, q = data["horizon_s"], data["levels"], data["quantiles"]
    try:
        ok = (len(h) >= 1 and all(b > a for a, b in zip(h, h[1:])) and all(0 < x < 1 for x in levels)
              and isinstance(q, dict) and all(len(rows) == len(h) and all(len(r) == len(levels) and
                                                                       all(x >= 0 for x in r) for r in rows)
                                              for rows in q.values()))
    except TypeError:
        ok = False
    if not ok:
        raise bad
    return dict(data)


def _fitted_on(data, path: Path) -> dict:
    """What the fit saw (twin.fit.coverage.Envelope's dict), kept as read; its use checks its shape."""
    if not isinstance(data, dict):
        raise TwinError(f"{path.name}: uncertainty.fitted_on must be a mapping (ranges, windows, horizon_s, logs)")
    return dict(data)


def check(vessel: Vessel) -> None:
    """Physical consistency that does not need the MJCF (the engine checks M)."""
    if not is_dissipative(vessel.damping):
        raise TwinError(f"vessel '{vessel.name}': damping is not dissipative (νᵀD(ν)ν < 0 somewhere)")
    am = vessel.added_mass
    if abs(am.Yrdot - am.Nvdot) > 1e-9 * max(1.0, abs(am.Yrdot)):
        raise TwinError(f"vessel '{vessel.name}': added mass must be symmetric (Yrdot = Nvdot)")
    t = vessel.thrusters
    _check_thruster_kind_and_pwm(vessel)
    if t.lag_s < 0:
        raise TwinError(f"vessel '{vessel.name}': thrusters.lag_s must be ≥ 0 s, got {t.lag_s:g}")
    for name in ("gain_left", "gain_right"):
        if not getattr(t, name) > 0:
            raise TwinError(f"vessel '{vessel.name}': thrusters.{name} must be > 0, got {getattr(t, name):g}")
    if t.delay_s < 0 or not 0 <= t.decay_per_min < 1 or not t.advance_loss >= 0:
        raise TwinError(f"vessel '{vessel.name}': thruster delay and advance loss must be ≥ 0, decay in [0, 1)")
    if (t.start_fwd is not None and not t.start_fwd >= 0) or (t.start_rev is not None and not t.start_rev <= 0):
        raise TwinError(f"vessel '{vessel.name}': thrusters.start_fwd must be ≥ 0 and start_rev ≤ 0 (δ̃), got "
                        f"{t.start_fwd}, {t.start_rev}")
    if not t.full_share > 0:
        raise TwinError(f"vessel '{vessel.name}': thrusters.full_share must be positive, got {t.full_share}")
    if t.kind == "t200" and not 500 <= t.pwm_min_us < t.pwm_max_us <= 2500:  # not fitted: a file's unit slip
        raise TwinError(f"vessel '{vessel.name}': thrusters.pwm_min_us {t.pwm_min_us:g} and pwm_max_us "
                        f"{t.pwm_max_us:g} must be pulse widths in µs between 500 and 2500 (an ESC's range, 1100-1900 "
                        "for a T200)")
    if t.kind == "t200":
        _check_dead_zones_and_astern(vessel)
        _check_pwm_within_map(vessel)
    if t.kind == "t200" and not t.forward_rises():
        raise TwinError(f"vessel '{vessel.name}': the forward thrust map {list(t.forward)} falls with the PWM "
                        "somewhere between its dead-zone edge and full PWM")
    if not t.ramp_s >= 0:
        raise TwinError(f"vessel '{vessel.name}': thrusters.ramp_s must be ≥ 0 s, got {t.ramp_s}")
    if not 0 <= t.supply_exponent <= 10 or (t.supply_ref_v is not None and not t.supply_ref_v > 0):
        raise TwinError(f"vessel '{vessel.name}': thrusters.supply_exponent must lie in [0, 10] and supply_ref_v be "
                        f"> 0 V, got {t.supply_exponent}, {t.supply_ref_v}")
    if t.supply_exponent > 0 and t.supply_ref_v is None:
        raise TwinError(f"vessel '{vessel.name}': thrusters.supply_exponent > 0 needs supply_ref_v (the voltage "
                        "the thrust map holds at)")
    if t.ramp_s > 0:
        try:
            t.slew_n_per_s
        except ValueError:
            raise TwinError(f"vessel '{vessel.name}': a thrust ramp (thrusters.ramp_s) needs bounded thrusters or "
                            "command_scale_n (the full thrust it ramps across)") from None
    window = vessel.sensors.heading_rate_window_s
    if window is not None and not window > 0:
        raise TwinError(f"vessel '{vessel.name}': sensors.heading_rate_window_s must be positive, got {window}")
    if vessel.sensors.yaw_rate_source not in ("heading", "gyro"):
        raise TwinError(f"vessel '{vessel.name}': sensors.yaw_rate_source must be heading or gyro, got "
                        f"{vessel.sensors.yaw_rate_source!r}")
    if vessel.sensors.follows_throttle and t.kind != "t200":
        raise TwinError(f"vessel '{vessel.name}': sensors.compass_motor_deg follows the PWM throttle; "
                        f"{t.kind} thrusters log none")
    _check_propeller_rudder(vessel)
    for case in vessel.cases.values():
        for geom, mass in case.geom_mass_kg.items():
            if not mass > 0:
                raise TwinError(f"vessel '{vessel.name}': mass of '{geom}' must be positive, got {mass}")


def _check_dead_zones_and_astern(vessel: Vessel) -> None:
    """Dead-zone edges on their sides of neutral (δ̃: forward ≥ 0 ≥ astern, shared and per thruster), and
    an astern branch that pushes astern, harder as the PWM falls: a file's sign slip would drive the boat
    with its sticks centred, or ahead on an astern command."""
    t, name = vessel.thrusters, vessel.name
    for what, edges in (("deadzone_fwd, deadzone_rev", (t.deadzone_fwd, t.deadzone_rev)),
                        ("deadzone_left", t.deadzone_left), ("deadzone_right", t.deadzone_right)):
        if edges is not None and not (edges[0] >= 0 >= edges[1]):
            raise TwinError(f"vessel '{name}': thrusters.{what} ({edges[0]:g}, {edges[1]:g}) must be a forward edge ≥ 0 "
                            "and an astern edge ≤ 0 (δ̃, no thrust between them)")
    fwd_n, rev_n = t.edge_thrusts_n()
    if fwd_n < 0 or rev_n > 0:
        side, value = ("forward", fwd_n) if fwd_n < 0 else ("reverse", rev_n)
        raise TwinError(f"vessel '{name}': the {side} thrust map {list(getattr(t, side))} gives {value:+.3g} N at its "
                        f"dead-zone edge, thrust the other way (a sign slip?)")
    if not t.reverse_falls():
        raise TwinError(f"vessel '{name}': the reverse thrust map {list(t.reverse)} does not push harder astern as the "
                        "PWM falls from its dead-zone edge to full astern")


# the T200 map runs from δ̃ = −1 to 1 (full astern to full ahead, pwm_scale_us from neutral); a PWM range
# this far past its ends reads the curve beyond its data (the BlueBoat's 1100 µs, 411 µs below its 1511 µs
# neutral, is δ̃ −1.03)
MAP_END_SLACK = 0.1


def _check_pwm_within_map(vessel: Vessel) -> None:
    """A PWM range within the thrust map's full-scale ends, δ̃ = ±1 (MAP_END_SLACK past them): a range
    wider than pwm_scale_us from neutral would extrapolate the map past full thrust."""
    t = vessel.thrusters
    for what, pwm_us in (("pwm_min_us", t.pwm_min_us), ("pwm_max_us", t.pwm_max_us)):
        x = float(t.normalised(pwm_us))
        if abs(x) > 1.0 + MAP_END_SLACK:
            raise TwinError(f"vessel '{vessel.name}': thrusters.{what} {pwm_us:g} µs reads the thrust map at δ̃ "
                            f"{x:+.3g}, past its full-thrust end ±1 (pwm_scale_us {t.pwm_scale_us:g} µs from neutral "
                            f"{t.neutral_us:g} µs): set pwm_scale_us to the PWM from neutral your ESC gives full "
                            "thrust at")


def _check_thruster_kind_and_pwm(vessel: Vessel) -> None:
    """A known thruster kind (another would run as thrusts in N unnoticed) and a PWM map that can be
    evaluated: δ̃ = PWM / pwm_scale_us − pwm_offset divides by the scale, and clips to [min, max]."""
    t = vessel.thrusters
    if t.kind not in THRUSTER_KINDS:
        raise TwinError(f"vessel '{vessel.name}': unknown thrusters.kind '{t.kind}' "
                        f"(known: {', '.join(THRUSTER_KINDS)})")
    if not t.pwm_scale_us > 0:
        raise TwinError(f"vessel '{vessel.name}': thrusters.pwm_scale_us must be positive, got {t.pwm_scale_us}")
    if not t.pwm_min_us < t.pwm_max_us:
        raise TwinError(f"vessel '{vessel.name}': thrusters.pwm_min_us must be below pwm_max_us, got "
                        f"{t.pwm_min_us}, {t.pwm_max_us}")


def _check_propeller_rudder(vessel: Vessel) -> None:
    """A propeller-and-rudder ship needs its MMG description, and only it has one: the MMG forces
    read the two controls as (n, δ), which for thrusters would be thrusts."""
    t, m, name = vessel.thrusters, vessel.mmg, vessel.name
    if (t.kind == "propeller_rudder") != (m is not None):
        raise TwinError(f"vessel '{name}': thrusters.kind 'propeller_rudder' and an 'mmg' block go together "
                        f"(kind '{t.kind}', mmg {'given' if m is not None else 'missing'})")
    if m is None:
        return
    if (t.lag_s or t.delay_s < 0 or t.decay_per_min or t.advance_loss or t.gain_left != 1 or t.gain_right != 1
            or t.ramp_s or t.supply_exponent):
        raise TwinError(f"vessel '{name}': a propeller and rudder take no thruster lag, decay, advance loss, ramp, "
                        "supply voltage or gains (the MMG forces model the propeller)")
    for what, x in (("thrusters.rps_max", t.rps_max), ("thrusters.rudder_max_deg", t.rudder_max_deg)):
        if x is not None and not x > 0:
            raise TwinError(f"vessel '{name}': {what} must be positive, got {x}")
    positive = {"mmg.rho_kg_m3": m.rho_kg_m3, "mmg.lpp_m": m.lpp_m, "mmg.draft_m": m.draft_m,
                "mmg.low_speed_m_s": m.low_speed_m_s, "mmg.propeller.diameter_m": m.propeller.diameter_m,
                "mmg.rudder.area_m2": m.rudder.area_m2, "mmg.rudder.aspect_ratio": m.rudder.aspect_ratio}
    for what, x in positive.items():
        if not x > 0:
            raise TwinError(f"vessel '{name}': {what} must be positive, got {x}")
    if not m.hull.R0 > 0:  # a hull that does not resist runs away under any thrust
        raise TwinError(f"vessel '{name}': mmg.hull.R0 (the straight-running resistance R'_0) must be positive, "
                        f"got {m.hull.R0}")
    if not m.friction_factor >= 0:
        raise TwinError(f"vessel '{name}': mmg.friction_factor (1 + k)·S/(L·d) must be positive, or 0 for a constant "
                        f"R'_0, got {m.friction_factor}")
    if m.friction_factor > 0 and not m.reference_speed_m_s > 0:
        raise TwinError(f"vessel '{name}': mmg.reference_speed_m_s (where R'_0 holds on the friction line) must be "
                        f"positive with a friction_factor, got {m.reference_speed_m_s}")
    if not 0 < m.drift_domain_deg <= 90:
        raise TwinError(f"vessel '{name}': mmg.drift_domain_deg must lie in (0, 90] degrees (90: the hull "
                        f"polynomial as it is at every drift angle), got {m.drift_domain_deg}")
    if not 0 <= m.propeller.wP0 < 1 or not 0 <= m.propeller.tP < 1 or not 0 <= m.rudder.tR < 1:
        raise TwinError(f"vessel '{name}': mmg wake fraction w_P0 and deductions t_P, t_R must lie in [0, 1)")


def available() -> list[str]:
    return sorted(p.stem for p in MODEL_DIR.glob("*.json"))


def load(name_or_path: str | os.PathLike, case: str | None = None) -> Vessel:
    """Load a vessel by name (one shipped with the package) or from a parameter file's path.

    A shipped vessel is twin/model/NAME.json; a parameter file is a vessel file such as
    `twin identify --out` writes, or a dataset's truth (`twin dataset --truth`), which loads as the
    truth vessel it holds (what `twin evaluate --model` of a truth scores).

    Args:
        name_or_path: a shipped vessel's name ("blueboat", "cybership1", "esso_osaka",
            "yellowfish": `twin.vessel.available()` lists them) or the path of a vessel file
            (.json), such as `twin identify --out` writes.
        case: the mass case (`--case` of the commands), one the vessel file lists under `cases`;
            None: the file's own ("nominal" unless the file names another, as a vessel written in
            another case does).

    Returns:
        The vessel in mass case `case`.

    Raises:
        TwinError: `name_or_path` is neither a name nor a path, is a folder, names no shipped
            vessel, or its file is missing, not valid JSON or not a vessel file (no "name" or
            "mjcf", a value of the wrong type, ...); or the vessel has no mass case `case`.
    """
    if not isinstance(name_or_path, (str, os.PathLike)):
        raise TwinError(f"a vessel is a shipped vessel's name ({', '.join(available())}) or a vessel file's path, "
                        f"got {name_or_path!r:.60}")
    text = str(name_or_path)
    if not text.strip():  # Path("") is the folder one is in
        raise TwinError(f"a vessel is a shipped vessel's name ({', '.join(available())}) or a vessel file's path, "
                        "got an empty name")
    path = Path(text)
    if path.is_dir():
        raise TwinError(f"'{text}' is a folder: give a vessel file (.json) or a shipped vessel's name")
    if not (text.endswith(".json") or path.is_file()):
        path = MODEL_DIR / f"{text}.json"
        if not path.is_file():
            raise TwinError(f"unknown vessel '{text}' (known: {', '.join(available())})")
    if not path.is_file():
        raise TwinError(f"vessel file '{text}' not found")
    try:
        data = json.loads(path.read_text())
    except RecursionError:  # Python's parser gives up on arrays or objects nested a thousand deep
        raise TwinError(f"{path.name}: not a vessel file: its JSON is nested too deeply to read (a vessel file is "
                        "an object a few levels deep)") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        recording = path.suffix.lower() in (".csv", ".tlog", ".bin", ".mcap")
        mjcf = path.suffix.lower() == ".xml"
        raise TwinError(f"{path.name}: not valid JSON ({exc})"
                        + ("; a vessel file is the JSON `twin identify` writes, and this looks like a recording"
                           if recording else "")
                        + ("; a vessel file is JSON and names its MJCF (.xml) in its \"mjcf\" field "
                           "(docs/reference/vessel-file.md)" if mjcf else "")) from None
    try:
        vessel = from_dict(data, path.resolve())
    except RecursionError:  # nested within the parser's depth but past what reading it takes
        raise TwinError(f"{path.name}: not a vessel file: its JSON is nested too deeply to read (a vessel file is "
                        "an object a few levels deep)") from None
    return vessel if case is None else vessel.with_case(case)


def save(vessel: Vessel, path: str | os.PathLike) -> Path:
    """Write the vessel description atomically (temporary name, then rename)."""
    path = Path(path).resolve()
    data = replace(vessel, path=path).to_dict()
    write_text_atomic(path, json.dumps(data, indent=2) + "\n")
    return path
