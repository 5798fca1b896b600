"""What varies from one twin of a job to the next: the identified coefficients drawn from the
vessel file's covariance (`fit.uncertainty.draw`), coefficients and the mass scaled by factors
drawn from ranges, and effects of the library with values drawn from ranges.

CLI text, one item per option:
  factor  NAME=LO..HI          a coefficient of `twin identify --params` (Xu, Nrr, thrust_gain, ...)
                               or `mass` (every mass of the MJCF), multiplied by a factor drawn
                               log-uniformly from [LO, HI] (so 0.5..2 is centred on 1)
  effect  NAME=V1,V2,...       an effect of `twin effects`, each value fixed (0.3) or drawn
                               uniformly from a range (0..0.3); KEY:LO..HI for scale effects,
                               e.g. current=0..0.3,0..360 or quadratic_damping=Xuu:0.7..1.4

Every draw takes its numbers from the generator it is given, in a fixed order (covariance,
factors, effects), so a batch seeded alike draws alike wherever it runs.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path

import mujoco
import numpy as np

from ..effects import Effect, apply_effects, coefficients, parse_effect
from ..engine.mjcf import compile_vessel, mesh_volume_m3
from ..errors import TwinError
from ..fit.uncertainty import draw as draw_from_covariance
from ..physics.hydrostatics import RHO_FRESH_KG_M3
from ..vessel import MassCase, Vessel, check

_RANGE = re.compile(r"^\s*([-+0-9.eE]+)\s*\.\.\s*([-+0-9.eE]+)\s*$")
MASS = "mass"


def _bounds(text: str, what: str) -> tuple[float, float]:
    """'LO..HI' or a single value 'V' (LO = HI = V) as floats, LO ≤ HI."""
    m = _RANGE.match(text)
    try:
        lo, hi = (float(m.group(1)), float(m.group(2))) if m else (float(text), float(text))
    except ValueError:
        raise TwinError(f"{what}: '{text}' is neither a number nor a range LO..HI") from None
    if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi:
        raise TwinError(f"{what}: '{text}' is not a range LO..HI of finite numbers with LO ≤ HI")
    return lo, hi


@dataclass(frozen=True)
class Factor:
    """A coefficient (or the mass) multiplied by a factor drawn log-uniformly from [lo, hi]."""

    name: str
    lo: float
    hi: float

    def draw(self, rng: np.random.Generator) -> float:
        return float(math.exp(rng.uniform(math.log(self.lo), math.log(self.hi)))) if self.hi > self.lo else self.lo

    @property
    def text(self) -> str:
        return f"{self.name}={self.lo:g}..{self.hi:g}"


def parse_factor(text: str, vessel: Vessel) -> Factor:
    """`NAME=LO..HI` for a coefficient `coefficients(vessel)` knows, or mass; factors > 0."""
    name, sep, values = str(text).partition("=")
    name = name.strip()
    if not sep or not name:
        raise TwinError(f"--vary '{text}': expected NAME=LO..HI, e.g. Xu=0.5..2 or mass=0.9..1.2")
    known = coefficients(vessel)
    if name != MASS and name not in known:
        raise TwinError(f"--vary '{text}': unknown coefficient '{name}' (known: mass, {', '.join(known)})")
    lo, hi = _bounds(values, f"--vary {name}")
    if lo <= 0:
        raise TwinError(f"--vary {name}: factors must be > 0, got {values}")
    if name != MASS and known[name].get(vessel) == 0.0:
        raise TwinError(f"--vary {name}: the vessel's {name} is 0, so no factor changes it (use an --effect)")
    if name == MASS:
        _check_mass_floats(vessel, hi)
    return Factor(name, lo, hi)


def _check_mass_floats(vessel: Vessel, factor: float) -> None:
    """Refuse a mass factor under which the hulls, fully submerged, no longer carry the vessel: a
    surface vessel's twin of that mass describes no boat (its 3-DOF run would go on as if it floated)."""
    compiled = compile_vessel(vessel)
    volume_m3 = mesh_volume_m3(compiled.model)
    mass_kg = compiled.geometry.rigid.mass_kg
    rho = RHO_FRESH_KG_M3 if vessel.mmg is None else vessel.mmg.rho_kg_m3
    if volume_m3 > 0 and factor * mass_kg > rho * volume_m3:
        raise TwinError(f"--vary mass: at ×{factor:g} the vessel's {mass_kg:.4g} kg becomes {factor * mass_kg:.4g} kg, "
                        f"more than its hulls displace fully submerged ({rho * volume_m3:.4g} kg): it would sink")


@dataclass(frozen=True)
class EffectRange:
    """An effect with some values drawn uniformly from ranges; items are (key, lo, hi) in the
    order of the CLI text (key "" for a positional value)."""

    name: str
    items: tuple[tuple[str, float, float], ...]

    def draw(self, rng: np.random.Generator) -> Effect:
        values = [(k, rng.uniform(lo, hi) if hi > lo else lo) for k, lo, hi in self.items]
        return parse_effect(f"{self.name}=" + ",".join(f"{k}:{v:.12g}" if k else f"{v:.12g}" for k, v in values))

    @property
    def text(self) -> str:
        return f"{self.name}=" + ",".join((f"{k}:" if k else "") + (f"{lo:g}..{hi:g}" if hi > lo else f"{lo:g}")
                                          for k, lo, hi in self.items)


def parse_effect_range(text: str) -> EffectRange:
    """`NAME=V1,LO..HI,KEY:LO..HI` (see the module docstring); both ends of every range are
    checked against the effect's own limits now, before any work is done."""
    name, sep, values = str(text).partition("=")
    name = name.strip()
    if not sep or not name or not values.strip():
        raise TwinError(f"--effect '{text}': expected NAME=VALUES, e.g. current=0..0.3,0..360")
    items = []
    for part in values.split(","):
        key, colon, value = part.rpartition(":")
        lo, hi = _bounds(value, f"--effect {name}")
        items.append((key.strip() if colon else "", lo, hi))
    out = EffectRange(name, tuple(items))
    for end in (1, 2):  # the lows, then the highs, as the effect library parses them
        try:
            EffectRange(name, tuple((item[0], item[end], item[end]) for item in items)).draw(np.random.default_rng(0))
        except TwinError as exc:  # the effect's own words, about the text given rather than one end of it
            why = str(exc).split(": ", 1)[-1].split(", got")[0]
            raise TwinError(f"--effect '{text}': {why} (each value V or LO..HI)") from None
    return out


@dataclass(frozen=True)
class Variation:
    """How the twins of a job differ from the vessel: covariance draws (the vessel's identified
    uncertainty), factors and effects; `effect_share`: the chance that each effect is present
    in a twin at all (1: always; less for datasets that must show its absence too)."""

    covariance: bool = False
    factors: tuple[Factor, ...] = ()
    effects: tuple[EffectRange, ...] = ()
    effect_share: float = 1.0

    def __post_init__(self):
        if not 0.0 <= self.effect_share <= 1.0:
            raise TwinError(f"effect share must lie in [0, 1], got {self.effect_share}")
        names = [f.name for f in self.factors]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:  # the later range would replace the earlier one, which the index would still list
            raise TwinError(f"--vary {twice[0]} given twice: give each coefficient one range")

    @property
    def varies(self) -> bool:
        return self.covariance or bool(self.factors) or bool(self.effects)

    def to_dict(self) -> dict:
        return {"covariance": self.covariance, "factors": [f.text for f in self.factors],
                "effects": [e.text for e in self.effects], "effect_share": self.effect_share}

    def draw(self, vessel: Vessel, n: int, rng: np.random.Generator) -> tuple[list["Drawn"], int]:
        """n twins of `vessel` and how many covariance draws were rejected as unphysical."""
        if self.covariance:
            base, rejected = draw_from_covariance(vessel, n, rng)
        else:
            base, rejected = [vessel] * n, 0
        return [self._one(vessel, v, rng) for v in base], rejected

    def _one(self, nominal: Vessel, v: Vessel, rng: np.random.Generator) -> "Drawn":
        factors = {f.name: f.draw(rng) for f in self.factors}
        known = coefficients(nominal)
        for name, k in factors.items():
            v = with_mass_scale(v, k) if name == MASS else known[name].put(v, known[name].get(v) * k)
        effects = []
        for e in self.effects:
            present = self.effect_share >= 1.0 or rng.uniform() < self.effect_share
            drawn = e.draw(rng)  # drawn even when absent: the numbers after it do not depend on the share
            if present:
                effects.append(drawn)
        if factors:  # a covariance draw is checked where it is drawn
            try:
                check(v)
            except TwinError as exc:
                raise TwinError(f"a drawn twin is unphysical ({exc}): narrow the --vary ranges") from None
        return Drawn(v, factors, tuple(effects))


@dataclass(frozen=True)
class Drawn:
    """One twin of a job: the vessel before its effects, the factors drawn and the effects."""

    vessel: Vessel
    factors: dict
    effects: tuple[Effect, ...]

    def truth(self) -> Vessel:
        """The vessel with its effects applied (what is simulated)."""
        return apply_effects(self.vessel, self.effects) if self.effects else self.vessel

    def coordinates(self, names: list[dict], known: dict | None = None) -> list[float]:
        """The drawn values of the uncertainty block's coordinates (its own units: ln|θ| where log);
        known: `coefficients` of the vessel drawn from, if at hand."""
        known = known or coefficients(self.vessel)
        out = []
        for c in names:
            x = known[c["name"]].get(self.vessel)
            out.append(math.log(abs(x)) if c.get("log") and x != 0 else x)
        return out


def with_mass_scale(vessel: Vessel, factor: float) -> Vessel:
    """Every mass of the MJCF (in the vessel's mass case) times `factor`, as a mass case of its
    own (named after the factor, so models compiled for another factor are never reused). The
    added mass, damping and thrusters stay: a payload, not a bigger hull."""
    masses = dict(geom_masses(str(vessel.mjcf)))
    base = vessel.cases.get(vessel.case, MassCase()) if vessel.case != "nominal" else MassCase()
    masses.update(base.geom_mass_kg)
    name = f"mass_x{factor:.12g}" + (f"@{vessel.case}" if vessel.case != "nominal" else "")
    case = MassCase({g: m * factor for g, m in masses.items()}, dict(base.body_x_m))
    return replace(vessel, cases={**vessel.cases, name: case}, case=name)


@lru_cache(maxsize=16)
def geom_masses(mjcf: str) -> tuple[tuple[str, float], ...]:
    """(name, kg) of every named geom of the MJCF given an explicit mass."""
    spec = mujoco.MjSpec.from_file(mjcf)
    out = tuple((g.name, float(g.mass)) for g in spec.geoms if g.name and math.isfinite(g.mass) and g.mass > 0)
    if not out:
        raise TwinError(f"{Path(mjcf).name}: no geom has an explicit mass, so --vary mass cannot scale it")
    return out
