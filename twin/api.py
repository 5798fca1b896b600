"""The Python API: what the `twin` command does, as functions returning typed results.

    import twin
    v = twin.load_vessel("yellowfish")
    run = twin.simulate(v, "zigzag", duration_s=120)
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

from .drive import InputSeries, get as get_scenario, read_inputs_csv
from .engine.limits import Limited, beyond_bounds
from .engine.mjcf import CompiledVessel, compile_vessel
from .engine.parameters import effective_parameters
from .engine.sim import simulate as _simulate
from .errors import TwinError
from .run import Run
from .verify.crosscheck import crosscheck
from .verify.validate import Validation, validate as _validate
from .vessel import Vessel, load as load_vessel, save as save_vessel

__all__ = ["Run", "Vessel", "InputSeries", "Validation", "Simulation", "load_vessel", "save_vessel", "simulate",
           "simulate_run", "crosscheck", "effective_parameters", "compile_vessel", "validate"]


def simulate(vessel: Vessel | str, drive="zigzag", duration_s: float = 120.0, **kwargs) -> Run:
    """Run the engine twin; `drive` is a scenario name, an InputSeries or a controller."""
    if isinstance(vessel, str):
        vessel = load_vessel(vessel)
    if isinstance(drive, str):
        drive = get_scenario(drive, kwargs.pop("seed", 0))
    return _simulate(compile_vessel(vessel), drive, duration_s, **kwargs)


@dataclass
class Simulation:
    """A run of the twin with what it was run on, and where its inputs went beyond the vessel
    file's bounds (`limits`: empty when they never did)."""

    run: Run
    compiled: CompiledVessel
    limits: list[Limited] = field(default_factory=list)

    def __repr__(self) -> str:
        r = self.run
        return (f"Simulation({self.compiled.vessel.name}, {r.t[-1] - r.t[0]:g} s, final position "
                f"({r.eta[-1, 0]:.2f}, {r.eta[-1, 1]:.2f}) m, {len(self.limits)} input limits hit)")

    def write(self, path, origin: tuple[float, float] | None = None) -> None:
        """The run as .csv, .mcap, .rrd, .tlog or .bin (map positions around `origin`, lat/lon deg)."""
        from .outputs import write

        v = self.compiled.vessel
        write({"twin": self.run}, Path(path), geometry=self.compiled.geometry, vessel_name=v.name, mjcf=v.mjcf,
              origin=origin)


def simulate_run(vessel: Vessel | str, *, scenario: str = "zigzag", inputs=None, duration_s: float = 120.0,
                 seed: int = 0, sample_dt_s: float = 0.1, current: tuple[float, float] | None = None,
                 wind: tuple[float, float] | None = None) -> Simulation:
    """`twin simulate`: a scenario (or an inputs CSV path / InputSeries) with an optional current
    (speed m/s, direction deg it flows towards) and wind (speed m/s, direction deg it blows from)."""
    if isinstance(vessel, str):
        vessel = load_vessel(vessel)
    env = vessel.environment
    if current is not None:
        env = replace(env, current_speed_m_s=current[0], current_dir_deg=current[1])
    if wind is not None:
        env = replace(env, wind_speed_m_s=wind[0], wind_dir_deg=wind[1])
    vessel = vessel.with_environment(env)
    if inputs is not None and not isinstance(inputs, InputSeries):
        inputs = read_inputs_csv(inputs)
    drive = inputs if inputs is not None else get_scenario(scenario, seed)
    if isinstance(drive, InputSeries) and drive.kind == "pwm" and vessel.thrusters.kind != "t200":
        raise TwinError(f"vessel '{vessel.name}' has no PWM model: give thrust_left,thrust_right in N")
    compiled = compile_vessel(vessel)
    run = _simulate(compiled, drive, duration_s, sample_dt_s=sample_dt_s)
    run.meta["scenario"] = "inputs" if inputs is not None else scenario
    limits = beyond_bounds(vessel, run.meta["inputs"], duration_s)
    run.meta["limits"] = [lim.to_dict() for lim in limits]
    return Simulation(run, compiled, limits)


def validate(vessel: Vessel | str, case: str | None = None) -> Validation:
    """`twin validate`: every quantity of one vessel and mass case side by side (`.quantities`, `.flagged()`)."""
    if isinstance(vessel, str):
        vessel = load_vessel(vessel)
    return _validate(vessel if case is None else vessel.with_case(case))
