"""The effect library, declared once (library.py): the vocabulary a dataset's truth is built
from and the one a diagnosis names; the coefficients identification fits (coefficients.py);
the Quantity that reaches one number of the vessel description (quantity.py).

CLI text: `NAME=V1,V2` with the values in the documented order, e.g. `current=0.3,45`,
`thruster_lag=0.4`, `quadratic_damping=Xuu:1.3,Nrr:0.8` or `quadratic_damping=1.3` (every
coefficient); `twin effects` lists them.
"""
from __future__ import annotations

from ..errors import TwinError
from ..vessel import Vessel, check
from .coefficients import ADDED_MASS, DAMPING_UNITS, LINEAR_DAMPING, QUADRATIC_DAMPING, coefficients
from .library import EFFECTS, candidates, describe, effect, spec
from .quantity import Quantity
from .spec import ALL, Candidate, Effect, EffectSpec, Value, parse

__all__ = ["ADDED_MASS", "ALL", "DAMPING_UNITS", "EFFECTS", "LINEAR_DAMPING", "QUADRATIC_DAMPING", "Candidate",
           "Effect", "EffectSpec", "Quantity", "Value", "apply_effects", "as_effect", "candidates", "coefficients",
           "describe", "effect", "named_twice", "parse_effect", "spec"]


def parse_effect(text: str) -> Effect:
    """`NAME=V1,V2,...` (values in the documented order) or, for scale effects,
    `NAME=S` / `NAME=KEY:S,KEY:S` → Effect; TwinError with one line on bad input."""
    name, sep, values = str(text).partition("=")
    name, values = name.strip(), values.strip()
    if not sep or not name or not values:
        raise TwinError(f"effect '{text}': expected NAME=VALUES, e.g. current=0.3,45 or thruster_lag=0.4")
    return parse(spec(name), text, values)


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


def named_twice(effects) -> list[str]:
    """The effect names given more than once among `effects` (as_effect items), sorted: judged as given,
    the later would act on top of the earlier (two thrust gains multiply) while the verdict names both."""
    names = [as_effect(e).spec.name for e in effects]
    return sorted({n for n in names if names.count(n) > 1})


def apply_effects(vessel: Vessel, effects=()) -> Vessel:
    """Apply effects in order to the vessel description; the result is checked
    (dissipative damping, symmetric M_A, positive gains)."""
    for item in effects:
        e = as_effect(item)
        # a per-key effect takes its table whole: a log may be named anything, "vessel" included
        vessel = e.spec.apply(vessel, e.params) if e.spec.per_key else e.spec.apply(vessel, **e.params)
    try:
        check(vessel)
    except TwinError as exc:
        raise TwinError(f"effects make the vessel unphysical: {exc}") from None
    return vessel
