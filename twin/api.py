"""The Python API: the same things the `twin` command does."""
from __future__ import annotations

from .crosscheck import crosscheck
from .engine.mjcf import compile_vessel
from .engine.sim import simulate as _simulate
from .inputs import InputSeries
from .params import effective_parameters
from .run import Run
from .scenarios import get as scenario
from .vessel import Vessel, load as load_vessel, save as save_vessel

__all__ = ["Run", "Vessel", "InputSeries", "load_vessel", "save_vessel", "simulate", "crosscheck",
           "effective_parameters", "compile_vessel"]


def simulate(vessel: Vessel | str, drive="zigzag", duration_s: float = 120.0, **kwargs) -> Run:
    """Run the engine twin; `drive` is a scenario name, an InputSeries or a controller."""
    if isinstance(vessel, str):
        vessel = load_vessel(vessel)
    if isinstance(drive, str):
        drive = scenario(drive, kwargs.pop("seed", 0))
    return _simulate(compile_vessel(vessel), drive, duration_s, **kwargs)
