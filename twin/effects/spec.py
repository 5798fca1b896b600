"""What an effect of the library is: its values (names, units, ranges), what it does to the
vessel description, and how a diagnosis fits it; an effect with values; and the CLI text
`NAME=V1,V2` both ways."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

from ..errors import TwinError
from ..vessel import Vessel
from .quantity import Quantity

ALL = "all"  # the scale key that stands for every coefficient of a scale effect
PER_KEY_SEP = "@"  # between the values of one key of a per-key effect of several values: LOG:1.5@270


@dataclass(frozen=True)
class Value:
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
            return f"effect '{effect}': {self.name} must be {' and '.join(x for x in (lo, hi) if x) or 'finite'}, " \
                   f"got {value:g}"
        return None


@dataclass(frozen=True)
class Candidate:
    """An effect as a diagnosis fits it: the Quantities it moves, starting values (one tuple per
    start), `to_effect` from fitted values to the effect, the family of effects it can imitate;
    `scan`: points (one value per quantity) for a staircase cost and `scan_step` the finer scan's
    step per quantity; `time_shift`: the engine's step sets its resolution (never screened at a
    coarse step); `log_of_param`: for an effect of each log's own numbers, the log (file name) each
    quantity belongs to, so that each log takes the start its own windows like best; `supersedes`:
    effects that can do nothing more once this one is kept (a constant wind, once every log has
    its own), so a diagnosis stops offering them; `separable`: the quantities are separate
    coefficients (a scale per DOF), each of which may stay at the base's value: a fit frees only
    those its training windows pin (diagnose/search.py)."""

    name: str
    params: tuple[Quantity, ...]
    starts: tuple[tuple[float, ...], ...]
    to_effect: Callable[[dict[str, float]], "Effect"]
    family: str
    scan: tuple[tuple[float, ...], ...] = ()
    scan_step: tuple[float, ...] = ()
    time_shift: bool = False
    log_of_param: tuple[str, ...] = ()
    supersedes: tuple[str, ...] = ()  # effects a diagnosis stops offering once this one is kept
    separable: bool = False

    @property
    def names(self) -> list[str]:
        return [p.name for p in self.params]


FitForm = Callable[[Vessel, tuple[str, ...]], "Candidate | None"]


@dataclass(frozen=True)
class EffectSpec:
    """A registered effect: what it acts on ("hull", "environment", "thrusters", "sensors"), its
    values and `apply(vessel, **values)` (a per-key effect: `apply(vessel, {key: value})`); keys: for scale effects, the coefficients that may be
    scaled (plus "all"); per_key: a free key (a log's name) taking all the values (one number
    per key, or v1@v2 for several); fit(prior, logs): the Candidate a diagnosis fits, None where it cannot act."""

    name: str
    acts_on: str
    values: tuple[Value, ...]
    apply: Callable
    doc: str
    fit: FitForm | None = None
    keys: tuple[str, ...] = ()
    per_key: str = ""


@dataclass(frozen=True)
class Effect:
    """An effect with values: params maps value names to floats (scale effects: keys to scales)."""

    name: str
    params: dict
    spec: EffectSpec = field(compare=False, repr=False)

    @property
    def text(self) -> str:
        """Canonical CLI text; parse_effect(effect.text) == effect."""
        if self.spec.keys or self.spec.per_key:
            p = self.params
            if self.spec.keys and set(p) == {ALL}:
                return f"{self.name}={p[ALL]:.12g}"
            return f"{self.name}=" + ",".join(f"{k}:{_per_key_text(v)}" for k, v in p.items())
        return f"{self.name}=" + ",".join(f"{self.params[q.name]:.12g}" for q in self.spec.values)

    def flat(self) -> dict[str, float]:
        """The values as one number per name: a per-key effect of several values as "KEY value_name"."""
        return flat_params(self.spec, self.params)

    def to_dict(self) -> dict:
        return {"name": self.name, "acts_on": self.spec.acts_on, "params": dict(self.params), "text": self.text}


def checked(s: EffectSpec, params: dict) -> Effect:
    """An Effect of `s` with values as floats in range, defaults filled in; TwinError if not."""
    if s.keys:
        return Effect(s.name, _check_scales(s, params), s)
    if s.per_key:
        return Effect(s.name, _check_per_key(s, params), s)
    known = [p.name for p in s.values]
    unknown = sorted(set(params) - set(known))
    if unknown:
        raise TwinError(f"effect '{s.name}': unknown value(s) {', '.join(unknown)} (takes {', '.join(known)})")
    out = {}
    for p in s.values:
        if p.name not in params and p.default is None:
            raise TwinError(f"effect '{s.name}': missing {p.name} ({p.unit}); takes {', '.join(known)}")
        value = _number(s.name, params.get(p.name, p.default))
        if (msg := p.check(s.name, value)) is not None:
            raise TwinError(msg)
        out[p.name] = value
    return Effect(s.name, out, s)


def _check_scales(s: EffectSpec, params: dict) -> dict:
    if not params:
        raise TwinError(f"effect '{s.name}': give a scale S or KEY:S (KEY in {', '.join(s.keys)})")
    bound = Value("scale", "×", 0.0, 100.0, True)
    out = {}
    for key, value in params.items():
        if key not in s.keys and key != ALL:
            raise TwinError(f"effect '{s.name}': unknown coefficient '{key}' (known: {', '.join(s.keys)}, all)")
        value = _number(s.name, value)
        if (msg := bound.check(s.name, value)) is not None:
            raise TwinError(msg.replace("scale", f"scale of {key}"))
        out[key] = value
    return out


def _check_per_key(s: EffectSpec, params: dict) -> dict:
    """KEY → value (one value per key) or KEY → (v1, v2, ...) in the values' order, given as a
    sequence or as the text `v1@v2`."""
    if not params:
        raise TwinError(f"effect '{s.name}': give {s.per_key}:{PER_KEY_SEP.join(v.name for v in s.values)} pairs")
    out = {}
    for key, value in params.items():
        if not str(key).strip():
            raise TwinError(f"effect '{s.name}': empty {s.per_key} name")
        items = value.split(PER_KEY_SEP) if isinstance(value, str) else value
        items = list(items) if isinstance(items, (list, tuple)) else [items]
        if len(items) != len(s.values):
            raise TwinError(f"effect '{s.name}': {key} takes {PER_KEY_SEP.join(v.name for v in s.values)}, "
                            f"got {PER_KEY_SEP.join(map(str, items))}")
        numbers = []
        for spec_value, item in zip(s.values, items):
            number = _number(s.name, item)
            if (msg := spec_value.check(s.name, number)) is not None:
                raise TwinError(msg)
            numbers.append(number)
        out[str(key)] = numbers[0] if len(numbers) == 1 else tuple(numbers)
    return out


def flat_params(s: EffectSpec, params: dict) -> dict[str, float]:
    out = {}
    for key, value in params.items():
        if isinstance(value, tuple):
            out.update({f"{key} {v.name}": float(x) for v, x in zip(s.values, value)})
        else:
            out[key] = float(value)
    return out


def _per_key_text(value) -> str:
    if isinstance(value, tuple):
        return PER_KEY_SEP.join(f"{v:.12g}" for v in value)
    return f"{value:.12g}"


def _number(name: str, value) -> float:
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise TwinError(f"effect '{name}': '{value}' is not a number") from None
    if not math.isfinite(out):
        raise TwinError(f"effect '{name}': '{value}' is not a finite number")
    return out


def parse(s: EffectSpec, text: str, values: str) -> Effect:
    """The values part of `NAME=V1,V2,...` (documented order) or, for scale effects, `S` or
    `KEY:S,KEY:S`; for a per-key effect `KEY:V,...`."""
    items = [v.strip() for v in values.split(",")]
    if s.keys:
        return checked(s, _scale_items(s.name, items))
    if s.per_key:
        return checked(s, _key_items(s.name, items, s.per_key))
    required = sum(p.default is None for p in s.values)
    if not required <= len(items) <= len(s.values):
        count = f"{required}" if required == len(s.values) else f"{required} to {len(s.values)}"
        want = ",".join(p.name for p in s.values)
        got = f"{len(items)} value{'' if len(items) == 1 else 's'}"
        raise TwinError(f"effect '{text}': expected {s.name}={want} ({count} number{'' if count == '1' else 's'}), "
                        f"got {got} '{values}'")
    return checked(s, {p.name: v for p, v in zip(s.values, items)})


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
