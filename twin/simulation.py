"""Running the engine twin: `twin simulate` and the API's `simulate` / `simulate_run` (re-exported by
twin.api). Kept apart from the rest of the API so that a simulation loads the engine alone, not the
identification and diagnosis libraries (scipy.optimize, scipy.signal, ...): measured, that is about
a second of CPU saved on every `twin simulate`."""
from __future__ import annotations

import inspect
import math
import numbers
import os
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .analytic import straight_speed
from .drive import InputSeries, checked_series, get as get_scenario, read_inputs_csv, to_thruster_inputs
from .engine.limits import Limited, beyond_bounds
from .engine.mjcf import CompiledVessel, compile_vessel
from .engine.sim import simulate as _simulate
from .errors import TwinError
from .files import RUNS, check_new
from .physics.environment import MAX_CURRENT_M_S, MAX_WIND_M_S
from .physics.hydrodynamics import Terms
from .physics.waves import Sea, parse_sea
from .run import Run
from .vessel import Vessel, load as load_vessel


def simulate(vessel: Vessel | str, drive="zigzag", duration_s: float = 120.0, **kwargs) -> Run:
    """Run the engine twin on a scenario, an input series or a controller, and return the run.

    The engine's own call, its keywords passed through as they are; `simulate_run` is
    `twin simulate`, with a current, a wind and where the inputs went beyond the vessel's bounds.
    A propeller-and-rudder ship's scenario starts from its steady straight run (unless `nu0` is
    given), as a ship's manoeuvres start from a steady approach; a small boat's starts at rest.

    Args:
        vessel: a twin.Vessel, a shipped vessel's name or a vessel file's path.
        drive (str | InputSeries | Callable): a scenario's name ("step", "turn", "zigzag", "spin" or
            "random", as `twin simulate --scenario`), an InputSeries, or a controller: a callable (t s,
            η, ν) → (surge, yaw) commands in [−1, 1] (a command beyond is held at ±1, the thrusters'
            saturation, as an autopilot's mixer holds it).
        duration_s: simulated time, s (default 120).
        **kwargs (Any): the keywords of twin.engine.sim.simulate, documented there: among them `nu0`
            and `eta0`, the start (3 numbers each: u, v in m/s and r in rad/s; north, east in m
            and ψ in rad), `sample_dt_s` (the output sample period, s; default 0.1, a multiple of
            the vessel's physics time step), `control_dt_s`, `sea` (a twin.physics.waves.Sea or
            its text 'HS,TP,DIR[,SPREAD]', which runs the 6-DOF hull in waves) and `six_dof`; and
            `seed` (a whole number, default 0), which draws the random scenario and the sea.

    Returns:
        The run: times `t` (s), `eta` (north, east in m, ψ in rad), `nu` (u, v in m/s, r in
        rad/s), the inputs held over each sample (`pwm_us`, `thrust_n`) and `meta` (the inputs
        applied, in `meta["inputs"]`, so that the run can be replayed).

    Raises:
        TwinError: `vessel` is neither a twin.Vessel nor the name of a shipped vessel or a
            readable vessel file; `drive` is none of the three, names an unknown scenario or one
            the vessel's thrusters cannot sail ("spin" for a propeller-and-rudder ship), or is an
            InputSeries the vessel cannot take or one malformed (twin.drive.checked_series); `nu0` or
            `eta0` is not 3 finite numbers; the duration or sample step is not a positive number
            of seconds, the step is longer than the run or not a multiple of the physics time
            step, or the run would hold more than half of the machine's memory; the seed is not a
            whole number; the sea is given wrongly; or a keyword the engine does not take.
    """
    if isinstance(vessel, (str, Path)):
        vessel = load_vessel(str(vessel))
    if not isinstance(vessel, Vessel):
        raise TwinError(f"expected a vessel (a twin.Vessel, a shipped vessel's name or a vessel file), "
                        f"got {type(vessel).__name__}")
    if not (isinstance(drive, (str, InputSeries)) or callable(drive)):
        raise TwinError(f"drive is a scenario name, a twin.InputSeries or a controller (t, eta, nu) -> (surge, yaw), "
                        f"got {drive!r:.60}")
    for name in ("nu0", "eta0"):
        value = kwargs.get(name)
        if value is not None:
            try:
                start = np.asarray(value, float)
            except (TypeError, ValueError):
                start = np.full(0, np.nan)
            if start.shape != (3,) or not np.all(np.isfinite(start)):
                raise TwinError(f"{name} must be 3 finite numbers ({'u, v, r' if name == 'nu0' else 'north, east, ψ'}),"
                                f" got {value!r:.60}")
    # a typo would otherwise be a TypeError from inside the engine, after the compile
    known_options(_simulate, kwargs, "simulate", also=("seed",))
    if "control_dt_s" in kwargs:
        _number(kwargs["control_dt_s"], "the control period")
    if kwargs.get("terms") is not None and not isinstance(kwargs["terms"], Terms):
        raise TwinError(f"terms is a twin.physics.hydrodynamics.Terms (which force terms act) or None, "
                        f"got {kwargs['terms']!r:.60}")
    _check_run(duration_s, kwargs.get("sample_dt_s", 0.1))
    if isinstance(drive, InputSeries):
        drive = checked_series(drive)
        _check_inputs(vessel, drive.kind)
    compiled = compile_vessel(vessel)
    if isinstance(drive, str):
        seed = _seed(kwargs.pop("seed", 0))
        if "nu0" not in kwargs and (nu0 := _approach(compiled, drive, seed)) is not None:
            kwargs["nu0"] = nu0
        drive = get_scenario(drive, seed, vessel.thrusters.kind, vessel.name)
        kwargs["sea"] = _sea(kwargs.get("sea"), seed)
    else:
        kwargs["sea"] = _sea(kwargs.get("sea"), _seed(kwargs.pop("seed", 0)))
    return _simulate(compiled, drive, duration_s, **kwargs)


def _sea(sea, seed: int):
    """A physics.waves.Sea as given, or drawn with `seed` from its text 'HS,TP,DIR[,SPREAD]' /
    'regular,H,T,DIR' (as `twin simulate --sea`); None stays None."""
    if isinstance(sea, str):
        return parse_sea(sea, seed)
    if sea is not None and not isinstance(sea, Sea):
        raise TwinError(f"sea is a twin.physics.waves.Sea or its text 'HS,TP,DIR[,SPREAD]', got {sea!r:.60}")
    return sea


def _approach(compiled: CompiledVessel, scenario: str, seed: int) -> np.ndarray | None:
    """ν₀ of a scenario run by a propeller-and-rudder ship: its steady straight run at the scenario's
    first propeller speed, rudder amidships, as a ship's manoeuvres start from a steady approach
    [IMO-MSC137]; from rest the Esso Osaka model takes 45 s to reach half its speed at 10 rps and two
    minutes at 3 rps, most of a scenario. None for thrusters: a small boat's scenarios start at rest."""
    thrusters = compiled.vessel.thrusters
    if thrusters.kind != "propeller_rudder":
        return None
    first = get_scenario(scenario, seed, thrusters.kind, compiled.vessel.name)  # its own: a scenario keeps state
    surge, _ = first(0.0, np.zeros(3), np.zeros(3))
    n_rps = float(to_thruster_inputs(thrusters, surge, 0.0)[1][0])
    return np.array([straight_speed(compiled, n_rps), 0.0, 0.0])


def _number(value, what: str, finite: bool = True) -> float:
    """A real number given as an argument (not text, not a flag; finite unless not `finite`, for a
    caller that says what range it takes), else TwinError naming it."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TwinError(f"{what} must be a number, got {value!r}")
    if finite and not math.isfinite(value):
        raise TwinError(f"{what} must be a finite number, got {value!r}")
    return float(value)


def _flow(value, what: str) -> tuple[float, float] | None:
    """A current or wind argument: None, or (speed m/s, direction deg)."""
    if value is None:
        return None
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__") or len(value) != 2:
        raise TwinError(f"{what} must be (speed m/s, direction deg), two numbers, got {value!r}")
    speed, direction = _number(value[0], f"{what}'s speed"), _number(value[1], f"{what}'s direction")
    most = MAX_WIND_M_S if what == "wind" else MAX_CURRENT_M_S
    if speed > most:
        raise TwinError(f"{what}'s speed {speed:g} m/s is beyond any a small vessel meets (at most {most:g} m/s)")
    return speed, direction


def _check_inputs(vessel: Vessel, kind: str) -> None:
    """An input series of `kind` ('pwm', 'thrust', 'propeller_rudder') can drive `vessel`, else a
    TwinError naming the columns it takes."""
    ship = vessel.thrusters.kind == "propeller_rudder"
    if ship != (kind == "propeller_rudder") or (kind == "pwm" and vessel.thrusters.kind != "t200"):
        takes = ("prop_rps,rudder_deg (rps; degrees, > 0 turns to starboard)" if ship else
                 "pwm_left,pwm_right (µs) or thrust_left,thrust_right (N)" if vessel.thrusters.kind == "t200" else
                 "thrust_left,thrust_right (N)")
        given = {"pwm": "pwm_left,pwm_right", "thrust": "thrust_left,thrust_right"}.get(kind, "prop_rps,rudder_deg")
        raise TwinError(f"vessel '{vessel.name}' is driven by {takes}, not {given}")


def _seed(seed) -> int:
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral):
        raise TwinError(f"the seed must be a whole number, got {seed!r}")
    return int(seed)


def _check_run(duration_s: float, sample_dt_s: float) -> None:
    """The checks `twin simulate` makes on a run's length and sample step."""
    duration_s, sample_dt_s = _number(duration_s, "the duration", False), _number(sample_dt_s, "the sample step", False)
    if not (duration_s > 0 and np.isfinite(duration_s)):
        raise TwinError(f"the duration must be a positive, finite number of seconds, got {duration_s:g}")
    if not sample_dt_s > 0:
        raise TwinError(f"the sample step must be a positive finite number of seconds, got {sample_dt_s:g}")
    if sample_dt_s > duration_s:
        raise TwinError(f"the sample step ({sample_dt_s:g} s) is longer than the run ({duration_s:g} s): "
                        "give a shorter step or a longer run")
    need, have = BYTES_PER_SAMPLE * duration_s / sample_dt_s, _physical_memory_bytes()
    if have and need > 0.5 * have:
        raise TwinError(f"a run of {duration_s:g} s sampled every {sample_dt_s:g} s holds about {need / 1e9:.3g} GB "
                        f"while it is made, more than half of this machine's {have / 1e9:.3g} GB: give a shorter "
                        "duration or a longer sample step")


BYTES_PER_SAMPLE = 1500  # a run's memory per output sample while it is made and written (1.35 kB measured)


def _physical_memory_bytes() -> int:
    """The machine's physical memory (bytes), 0 where the system does not say."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return 0


def _output_path(path) -> None:
    """An output path given as a path: a str or Path, not empty (Path("") is the current folder)."""
    if not isinstance(path, (str, Path)) or not str(path):
        raise TwinError(f"an output is written to a file path (str or Path), got {path!r:.60}")


def known_options(function, options: dict, what: str, also: tuple[str, ...] = ()) -> None:
    """Refuse, in one sentence, an option neither `function` nor its caller (`also`) takes (a typo
    would otherwise surface as a TypeError from deep inside)."""
    known = [n for n, p in inspect.signature(inspect.unwrap(function)).parameters.items()
             if p.kind is p.KEYWORD_ONLY or (p.kind is p.POSITIONAL_OR_KEYWORD and p.default is not p.empty)]
    known += list(also)
    unknown = sorted(set(options) - set(known))
    if unknown:
        raise TwinError(f"{what}: unknown option{'s' if len(unknown) > 1 else ''} {', '.join(unknown)} "
                        f"(known: {', '.join(known)})")
    parameters = inspect.signature(inspect.unwrap(function)).parameters
    check_flags(what, **{n: v for n, v in options.items() if n in parameters
                         and isinstance(parameters[n].default, bool)})


def check_flags(what: str, **flags) -> None:
    """Refuse a yes-or-no option given as anything but True or False: the text "no" or "false" is
    true to Python, and would have turned on what the user meant to turn off."""
    for name, value in flags.items():
        if not isinstance(value, (bool, np.bool_)):
            raise TwinError(f"{what}: {name} must be True or False, got {value!r:.60}")

@dataclass
class Simulation:
    """A run of the twin with what it was run on, and where its inputs went beyond their bounds.

    `limits` lists where the inputs went beyond the vessel file's bounds: empty when they never did.

    Attributes:
        run: the run: times `t` (s), `eta` (north, east in m, ψ in rad), `nu` (u, v in m/s, r in
            rad/s), the inputs (`pwm_us`, `thrust_n`) and `meta` (the scenario, the inputs applied,
            the limits).
        compiled: the compiled vessel it ran on, with the current and wind it was given.
        limits: each thruster input held beyond the vessel file's bound: which bound, for how long
            (s), the largest excess (in the input's unit) and when it began (s from the start).
    """

    run: Run
    compiled: CompiledVessel
    limits: list[Limited] = field(default_factory=list)

    def __repr__(self) -> str:
        r = self.run
        return (f"Simulation({self.compiled.vessel.name}, {r.t[-1] - r.t[0]:.4g} s, final position "
                f"({r.eta[-1, 0]:.2f}, {r.eta[-1, 1]:.2f}) m, {len(self.limits)} input limits hit)")

    def write(self, path, origin: tuple[float, float] | None = None, *, force: bool = False) -> None:
        """Write the run as `twin simulate --out` does: .csv, .mcap, .rrd, .tlog or .bin.

        Args:
            path (str | Path): the file to write; its suffix says the format.
            origin: (lat, lon) in deg of the start, for the map positions of .mcap, .tlog and .bin
                (`--origin`); None: the command's default (37.4136, −5.9786, Seville).
            force: replace a file already at `path`, which is otherwise kept, as `twin simulate`
                keeps it.

        Raises:
            TwinError: `path` is not a file path, a file is already there and `force` is False,
                the file there is data of another kind (a vessel file, a band, someone's table) or a
                recording with a dataset's truth beside it (kept even with `force`, as the command
                keeps them), or the format is unknown.
        """
        from .outputs import write  # late: the run writers, 0.1 s on top of this module, only when a run is written

        _output_path(path)
        check_new([path], force, "path", RUNS, force_name="force=True")
        v = self.compiled.vessel
        write({"twin": self.run}, Path(path), geometry=self.compiled.geometry, vessel_name=v.name, mjcf=v.mjcf,
              origin=origin)


def simulate_run(vessel: Vessel | str, *, scenario: str = "zigzag", inputs=None, duration_s: float = 120.0,
                 seed: int = 0, sample_dt_s: float = 0.1, current: tuple[float, float] | None = None,
                 wind: tuple[float, float] | None = None, sea=None, six_dof: bool = False,
                 start_speed_m_s: float | None = None) -> Simulation:
    """Run the twin as `twin simulate` does: a scenario or recorded inputs, in a current, wind or sea.

    The run comes with where its inputs went beyond the vessel file's bounds.

    Args:
        vessel: a twin.Vessel, a shipped vessel's name or a vessel file's path.
        scenario: "step", "turn", "zigzag", "spin" or "random" (`--scenario`; default "zigzag");
            not used with `inputs`.
        inputs (str | Path | InputSeries | None): an inputs CSV's path or an InputSeries (`--inputs`): a
            `t` column (s) and pwm_left,pwm_right (µs), thrust_left,thrust_right (N) or, for a
            propeller-and-rudder ship, prop_rps,rudder_deg (rps, deg); each row held until the next, the
            last one to the end of the run.
        duration_s: simulated time, s (`--duration`; default 120, with `inputs` too, where the
            command takes the inputs' last time).
        seed: random seed of the "random" scenario and of the sea's components (`--seed`; a whole
            number, default 0).
        sample_dt_s: output sample period, s (`--sample-dt`; default 0.1): a multiple of the
            vessel's physics time step (0.02 s; cybership1 0.01 s).
        current: (speed m/s, direction deg it flows towards) (`--current`); None: the vessel's own.
        wind: (speed m/s, direction deg it blows from) (`--wind`), for a vessel with a wind load
            model; None: the vessel's own.
        sea (Sea | str | None): a twin.physics.waves.Sea, or its text 'HS,TP,DIR[,SPREAD]' (JONSWAP: Hs
            m, Tp s, direction the waves come from in deg, cosine-power spreading) or 'regular,H,T,DIR',
            drawn with `seed` (`--sea`): runs the 6-DOF hull in waves.
        six_dof: the 6-DOF hull (heave, roll, pitch) in calm water (`--six-dof`; implied by `sea`).
        start_speed_m_s: the surge at t = 0, m/s (`--start-speed`); None: at rest, or a ship's
            scenario's steady approach.

    Returns:
        The run (`.run`), the compiled vessel it ran on (`.compiled`) and the inputs held beyond
        the vessel file's bounds (`.limits`); `.write(path)` writes it as the command does.

    Raises:
        TwinError: `vessel` is neither a twin.Vessel nor the name of a shipped vessel or a
            readable vessel file; the duration or sample step is not a positive number of
            seconds, the step is longer than the run or not a multiple of the physics time step,
            or the run would hold more than half of the machine's memory; `current` or `wind` is
            not two numbers, or faster than any a small vessel meets (10 m/s of current, 40 m/s of
            wind); a wind for a vessel with no wind load model; `inputs` neither a path nor an
            InputSeries, an inputs file missing or malformed, or inputs of a kind that cannot drive
            the vessel; an unknown scenario or one the vessel's thrusters cannot sail; a sea given
            wrongly or one the 6-DOF hull cannot run in; the seed is not a whole number or the start
            speed not a number.
    """
    if isinstance(vessel, (str, Path)):
        vessel = load_vessel(str(vessel))
    if not isinstance(vessel, Vessel):
        raise TwinError(f"expected a vessel (a twin.Vessel, a shipped vessel's name or a vessel file), "
                        f"got {type(vessel).__name__}")
    _check_run(duration_s, sample_dt_s)
    check_flags("simulate_run", six_dof=six_dof)
    current, wind, seed = _flow(current, "current"), _flow(wind, "wind"), _seed(seed)
    env = vessel.environment
    if current is not None:
        env = replace(env, current_speed_m_s=current[0], current_dir_deg=current[1])
    if wind is not None:
        if wind[0] > 0 and not vessel.feels_wind():
            raise TwinError(f"vessel '{vessel.name}' has no wind load model (wind_load areas or wind_regression), "
                            "so a wind would do nothing: add wind_load to its vessel file")
        env = replace(env, wind_speed_m_s=wind[0], wind_dir_deg=wind[1])
    vessel = vessel.with_environment(env)
    if inputs is not None and not isinstance(inputs, (str, Path, InputSeries)):
        raise TwinError(f"inputs is an inputs CSV's path or a twin.InputSeries, got {type(inputs).__name__}")
    if inputs is not None:
        inputs = checked_series(inputs) if isinstance(inputs, InputSeries) else read_inputs_csv(inputs)
    drive = inputs if inputs is not None else get_scenario(scenario, seed, vessel.thrusters.kind, vessel.name)
    if isinstance(drive, InputSeries):
        _check_inputs(vessel, drive.kind)
    sea = _sea(sea, seed)
    compiled = compile_vessel(vessel)
    if start_speed_m_s is not None:
        nu0 = np.array([_number(start_speed_m_s, "start speed"), 0.0, 0.0])
    else:
        nu0 = None if inputs is not None else _approach(compiled, scenario, seed)
    run = _simulate(compiled, drive, duration_s, sample_dt_s=sample_dt_s, sea=sea, six_dof=six_dof, nu0=nu0)
    run.meta["scenario"] = "inputs" if inputs is not None else scenario
    # the water and air the run was made in, which an .mcap keeps in its metadata (plain entries)
    for key, value in (("current_speed_m_s", env.current_speed_m_s), ("current_towards_deg", env.current_dir_deg),
                       ("wind_speed_m_s", env.wind_speed_m_s), ("wind_from_deg", env.wind_dir_deg)):
        if (current if key.startswith("current") else wind) is not None:
            run.meta[key] = float(value)
    if nu0 is not None:
        run.meta["approach_speed_m_s"] = float(nu0[0])
    limits = beyond_bounds(vessel, run.meta["inputs"], duration_s)
    run.meta["limits"] = [lim.to_dict() for lim in limits]
    if inputs is not None and len(inputs.t) > 1 and float(inputs.t[-1]) < duration_s:
        # its last row held from there to the end (one row alone is plainly a constant input)
        run.meta["inputs_end_s"] = float(inputs.t[-1])
    return Simulation(run, compiled, limits)
