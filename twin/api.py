"""The Python API: the same things the `twin` command does."""
from __future__ import annotations

from .crosscheck import crosscheck
from .engine.mjcf import compile_vessel
from .engine.sim import simulate as _simulate
from .inputs import InputSeries
from .params import effective_parameters
from .run import Run
from .scenarios import get as scenario
from .validate import Validation, validate as _validate
from .vessel import Vessel, load as load_vessel, save as save_vessel

__all__ = ["Run", "Vessel", "InputSeries", "Validation", "load_vessel", "save_vessel", "simulate", "crosscheck",
           "effective_parameters", "compile_vessel", "validate"]


def simulate(vessel: Vessel | str, drive="zigzag", duration_s: float = 120.0, **kwargs) -> Run:
    """Run the engine twin; `drive` is a scenario name, an InputSeries or a controller."""
    if isinstance(vessel, str):
        vessel = load_vessel(vessel)
    if isinstance(drive, str):
        drive = scenario(drive, kwargs.pop("seed", 0))
    return _simulate(compile_vessel(vessel), drive, duration_s, **kwargs)


def validate(vessel: Vessel | str, case: str | None = None) -> Validation:
    """`twin validate`: every quantity of one vessel and mass case side by side (`.quantities`, `.flagged()`)."""
    if isinstance(vessel, str):
        vessel = load_vessel(vessel)
    return _validate(vessel if case is None else vessel.with_case(case))
