"""Engine against analytic model: the same inputs through two integrations of
one physics. Run for the full model and for each force term alone, so that a
term computed but never applied (or applied with a wrong sign or frame)
cannot hide: every term case also reports how far the term moves the vessel
("effect"), which must dwarf the tolerance.

An input delay that is not a whole number of engine steps has a case of its own (the full model,
the inputs of the full run reaching the thrusters CHECK_DELAY_S later): the engine holds an input
that changes within a step over its share of the step, the analytic model switches at the delayed
time itself.

A propeller-and-rudder ship (MMG standard method) has its own cases: the MMG hull, propeller
and rudder forces each alone, its Fujiwara wind load under a constant wind and under a
time-varying (measured-like, gusty) wind series, the added mass's Coriolis terms without the
Munk moment, the current through the hull forces; its zig-zag steers with the rudder at full
propeller speed."""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .. import analytic
from .. import drive as scenarios
from ..drive import WindSeries
from ..engine.mjcf import CompiledVessel, compile_vessel
from ..engine.sim import simulate
from ..errors import TwinError
from ..physics.environment import Environment
from ..physics.hydrodynamics import Terms
from ..physics.kinematics import wrap_angle
from ..run import Run
from ..progress import Progress, steps
from ..vessel import Vessel

POSITION_TOL_M = 0.01
HEADING_TOL_DEG = 0.1
NU0_TERMS = (0.8, 0.2, 0.2)
TERM_ENV = Environment(current_speed_m_s=0.4, current_dir_deg=60.0, wind_speed_m_s=8.0, wind_dir_deg=200.0)
# a 3-m ship model in a pond: its own speeds (m/s, rad/s) and a pond's current and wind
SHIP_NU0_TERMS = (0.3, 0.03, 0.02)
SHIP_TERM_ENV = Environment(current_speed_m_s=0.1, current_dir_deg=60.0, wind_speed_m_s=2.0, wind_dir_deg=200.0)
SHIP_GUST_SEED = 20240516
# an input delay that is not a whole number of engine steps (0.02 s): each input then changes within a step
CHECK_DELAY_S = 0.35


@dataclass(frozen=True)
class Case:
    name: str
    terms: Terms
    environment: Environment
    nu0: tuple[float, float, float]
    baseline: Terms | None  # the case without the term, to measure the term's effect
    wind: WindSeries | None = None  # a time-varying wind on the run's clock (replaces the environment's)
    input_delay_s: float = 0.0  # the thrusters act on inputs this much older (baseline: the same terms without)


def gusty_wind(duration_s: float = 600.0, seed: int = SHIP_GUST_SEED) -> WindSeries:
    """A measured-like wind for the checks: 10 Hz samples of a mean 1.7 m/s from 135° with gusts
    (σ 0.6 m/s, a random walk in direction, σ 3° per s^½), as the Esso tests log [ESSO-FRT]."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration_s, 0.1)
    speed = np.abs(1.7 + 0.6 * np.convolve(rng.standard_normal(len(t)), np.ones(20) / np.sqrt(20), "same"))
    direction = 135.0 + np.cumsum(rng.standard_normal(len(t))) * 3.0 * np.sqrt(0.1)
    return WindSeries.from_speed_direction(t, speed, direction)


def ship_cases() -> list[Case]:
    """The cases of a propeller-and-rudder ship (module docstring)."""
    none = Terms().only()
    env, nu0 = SHIP_TERM_ENV, SHIP_NU0_TERMS
    calm = Environment()
    return [
        Case("full", Terms(), calm, (0.2, 0.0, 0.0), None),
        Case("rigid_body", none, calm, nu0, None),
        Case("added_mass", none.only("added_mass"), calm, nu0, none),
        Case("coriolis", none.only("added_mass_coriolis"), calm, nu0, none),
        Case("mmg_hull", none.only("mmg_hull"), calm, nu0, none),
        Case("propeller", none.only("propeller"), calm, nu0, none),
        Case("rudder", none.only("rudder"), calm, nu0, none),
        Case("current", none.only("mmg_hull", "current"), env, nu0, none.only("mmg_hull")),
        Case("wind", none.only("wind"), env, nu0, none),
        Case("wind_series", none.only("wind"), calm, nu0, none, gusty_wind()),
        Case("full_environment", Terms(), env, (0.2, 0.0, 0.0), Terms(current=False, wind=False)),
        Case("full_wind_series", Terms(), calm, (0.2, 0.0, 0.0), Terms(wind=False), gusty_wind()),
        Case("input_delay", Terms(), calm, (0.2, 0.0, 0.0), Terms(), input_delay_s=CHECK_DELAY_S),
    ]


def cases(vessel: Vessel | None = None) -> list[Case]:
    """The term cases of the vessel's kind (default: a twin-thruster vessel's)."""
    if vessel is not None and vessel.thrusters.kind == "propeller_rudder":
        return ship_cases()
    none = Terms().only()
    env = TERM_ENV
    return [
        Case("full", Terms(), Environment(), (0.0, 0.0, 0.0), None),
        Case("rigid_body", none, Environment(), NU0_TERMS, None),
        Case("added_mass", none.only("added_mass"), Environment(), NU0_TERMS, none),
        Case("coriolis", none.only("added_mass_coriolis"), Environment(), NU0_TERMS, none),
        Case("damping", none.only("damping"), Environment(), NU0_TERMS, none),
        Case("thrust", none.only("thrust"), Environment(), NU0_TERMS, none),
        Case("current", none.only("damping", "current"), env, NU0_TERMS, none.only("damping")),
        Case("wind", none.only("wind"), env, NU0_TERMS, none),
        Case("full_environment", Terms(), env, (0.0, 0.0, 0.0), Terms().only("added_mass", "added_mass_coriolis",
                                                                              "damping", "thrust")),
        Case("input_delay", Terms(), Environment(), (0.0, 0.0, 0.0), Terms(), input_delay_s=CHECK_DELAY_S),
    ]


@dataclass(frozen=True)
class Result:
    case: str
    position_err_m: float
    heading_err_deg: float
    effect_m: float | None
    engine: Run
    analytic: Run

    @property
    def passed(self) -> bool:
        return self.position_err_m < POSITION_TOL_M and self.heading_err_deg < HEADING_TOL_DEG

    @property
    def exercised(self) -> bool:
        """The term moves this vessel at least the position tolerance over the run: a pass where it
        moves less checks nothing (the command says "no effect")."""
        return self.effect_m is None or self.effect_m >= POSITION_TOL_M

    def __repr__(self) -> str:
        verdict = "FAIL" if not self.passed else "pass" if self.exercised else "no effect"
        return f"Result({self.case}: {self.position_err_m:.3g} m, {self.heading_err_deg:.3g}°, {verdict})"

    def to_dict(self) -> dict:
        return {"case": self.case, "position_err_m": self.position_err_m, "heading_err_deg": self.heading_err_deg,
                "effect_m": self.effect_m, "passed": self.passed, "exercised": self.exercised}


def _compare(a: Run, b: Run) -> tuple[float, float]:
    pos = float(np.max(np.hypot(a.eta[:, 0] - b.eta[:, 0], a.eta[:, 1] - b.eta[:, 1])))
    head = float(np.rad2deg(np.max(np.abs(wrap_angle(a.eta[:, 2] - b.eta[:, 2])))))
    return pos, head


def zigzag_for(vessel: Vessel):
    """The check's zig-zag: the scenario's, or for a ship the rudder at half its bound (20°) and the
    propeller at full speed, switched at ±10° of heading."""
    if vessel.thrusters.kind == "propeller_rudder":
        return scenarios.ZigZag(surge=1.0, yaw=0.5, switch_deg=10.0, at_s=5.0)
    return scenarios.get("zigzag")


def run_case(compiled: CompiledVessel, case: Case, duration_s: float, inputs=None) -> Result:
    plain = replace(compiled.vessel, environment=case.environment)
    vessel = replace(plain, thrusters=replace(plain.thrusters, delay_s=plain.thrusters.delay_s + case.input_delay_s))
    cv = CompiledVessel(vessel, compiled.model, compiled.geometry)
    drive = inputs if inputs is not None else zigzag_for(vessel)
    try:
        eng = simulate(cv, drive, duration_s, nu0=case.nu0, terms=case.terms, wind=case.wind)
    except TwinError as exc:  # say which term case blew up: the full model may be fine
        raise TwinError(f"crosscheck case '{case.name}': {exc}") from None
    ana = analytic.simulate(cv.hydro(case.terms), vessel.thrusters, cv.geometry.thruster_y_m,
                            eng.meta["inputs"], eng.t, nu0=np.array(case.nu0), wind=case.wind)
    pos, head = _compare(eng, ana)
    effect = None
    if case.baseline is not None:
        base = analytic.simulate(cv.hydro(case.baseline), plain.thrusters, cv.geometry.thruster_y_m,
                                 eng.meta["inputs"], eng.t, nu0=np.array(case.nu0), wind=case.wind)
        effect = _compare(ana, base)[0]
    return Result(case.name, pos, head, effect, eng, ana)


def six_dof_case(vessel: Vessel, duration_s: float, inputs=None) -> Result:
    """The 6-DOF hull in calm water (engine/sixdof.py) against the analytic 3-DOF model, full physics,
    over the zig-zag. The 3-DOF model is a level hull's: a vessel whose hull meshes float it level
    (the shipped ones do, by construction of their lines) differs from it only by what its heave,
    roll and pitch in the manoeuvre do to its horizontal motion."""
    cv = compile_vessel(vessel)
    drive = inputs if inputs is not None else zigzag_for(vessel)
    try:
        eng = simulate(cv, drive, duration_s, six_dof=True)
    except TwinError as exc:
        raise TwinError(f"crosscheck case 'six_dof_calm': {exc}") from None
    ana = analytic.simulate(cv.hydro(), vessel.thrusters, cv.geometry.thruster_y_m, eng.meta["inputs"], eng.t,
                            nu0=np.zeros(3))
    pos, head = _compare(eng, ana)
    return Result("six_dof_calm", pos, head, None, eng, ana)


def crosscheck(vessel: Vessel, duration_s: float = 120.0, only: list[str] | None = None,
               progress: Progress | None = None, six_dof: bool = False) -> list[Result]:
    """All cases over the same zig-zag inputs (those of the full-physics engine run); `six_dof`: and
    the 6-DOF hull in calm water (`six_dof_case`), for a vessel with hull meshes."""
    compiled = compile_vessel(vessel)
    results: list[Result] = []
    inputs = None
    chosen = [c for c in cases(vessel) if not only or c.name in only or c.name == "full"]
    for k, case in enumerate(chosen):
        steps(progress)(f"case {case.name}", k, len(chosen))
        res = run_case(compiled, case, duration_s, inputs)
        if case.name == "full":
            inputs = res.engine.meta["inputs"]
        results.append(res)
    if six_dof:
        steps(progress)("case six_dof_calm", len(chosen), len(chosen) + 1)
        results.append(six_dof_case(vessel, duration_s, inputs))
    return results
