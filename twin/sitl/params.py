"""The ArduPilot parameter file a SITL session with the twin needs (`twin sitl --write-params`).

What ArduPilot must agree on with the twin: a boat frame, the two servo outputs the twin
reads as its thrusters, their PWM range and neutral (the vessel file's, so full stick is
full thrust and trim is zero thrust), and a cruise speed/throttle pair that the twin
actually reaches (Rover's speed controller feeds forward from it). Then what a skid-steered
boat needs of its navigation: a waypoint speed it can hold with thrust to spare for steering
(WP_SPEED; Rover's defaults, 3-5 m/s in its SITL parameter files, exceed a 1-m boat's top
speed, and AUTO would then run with both thrusters nearly flat out and nothing left to
turn with), and the turn rate it can reach (ATC_STR_RAT_MAX, which Rover's steering
controller limits its demand to). Each figure is the twin's own, in calm water. The names and
meanings are ArduPilot Rover's [ArduPilot-Rover] (FRAME_CLASS 2 = boat, SERVOn_FUNCTION 73/74 =
throttle left/right, WP_SPEED 0 = CRUISE_SPEED).
"""
from __future__ import annotations

import numpy as np

from ..analytic import course_unstable_from_m_s, straight_run
from ..drive import InputSeries
from ..engine.mjcf import compile_vessel
from ..engine.sim import simulate
from ..errors import TwinError
from ..physics.environment import Environment
from ..vessel import Vessel
from .backend import PwmMap

CRUISE_THROTTLE_PCT = 50
SETTLE_S = 90.0  # a 1-m boat settles to its cruise speed within a few tens of seconds


def _steady(vessel: Vessel, left_pct: float, right_pct: float) -> np.ndarray:
    """Steady (u, v, r) of the twin in calm water with each thruster at a % of its PWM span from
    neutral (+ ahead, − astern), the mean over the last 10 s of SETTLE_S; with both alike on a twin
    that is course-unstable there (it would turn on its own), the straight run Rover's steering holds."""
    calm = vessel.with_environment(Environment())
    m = PwmMap.of(calm.thrusters)

    def pwm(pct):
        end = m.pwm_max_us if pct >= 0 else m.pwm_min_us
        return m.neutral_us + abs(pct) / 100.0 * (end - m.neutral_us)

    pair = [pwm(left_pct), pwm(right_pct)]
    if left_pct == right_pct > 0:
        straight = _straight(calm, m, pair)
        if straight is not None and not straight.stable:
            return np.array([straight.speed_m_s, 0.0, 0.0])
    if m.kind == "pwm":
        drive = InputSeries(np.array([0.0]), np.array([pair]), "pwm")
    else:
        drive = InputSeries(np.array([0.0]), np.array([[m.raw(m.held(p)) for p in pair]]), "thrust")
    run = simulate(compile_vessel(calm), drive, SETTLE_S, sample_dt_s=0.5)
    return np.mean(run.nu[run.t >= SETTLE_S - 10.0], axis=0)


def _straight(vessel: Vessel, m: PwmMap, pair: list[float]):
    """analytic.straight_run of the twin with its two thrusters at these PWMs (µs)."""
    static = vessel.thrusters.gains() * np.array([m.raw(m.held(p), side) for side, p in enumerate(pair)])
    return straight_run(compile_vessel(vessel), static_n=static)


def cruise_speed_m_s(vessel: Vessel, throttle_pct: float = CRUISE_THROTTLE_PCT) -> float:
    """Steady surge speed (m/s) of the twin with both thrusters at `throttle_pct` % of the PWM
    span above neutral, in calm water (the vessel's own current and wind are removed)."""
    return float(_steady(vessel, throttle_pct, throttle_pct)[0])


def pivot_rate_deg_s(vessel: Vessel) -> float:
    """Steady turn rate (°/s) of the twin with full differential thrust (left full ahead, right full
    astern: full steering at zero throttle on a skid-steered boat), calm water."""
    return float(np.degrees(abs(_steady(vessel, 100.0, -100.0)[2])))


def boat_parameters(vessel: Vessel, channels: tuple[int, int] = (1, 3)) -> str:
    """The parameter file's text (ArduPilot's `NAME VALUE  # comment` lines)."""
    if vessel.thrusters.kind == "propeller_rudder":
        raise TwinError(f"vessel '{vessel.name}' is a propeller-and-rudder ship: SITL supports twin-thruster "
                        f"vessels only")
    m = PwmMap.of(vessel.thrusters)
    left, right = channels
    speed = cruise_speed_m_s(vessel)
    top = cruise_speed_m_s(vessel, 100.0)
    turn = pivot_rate_deg_s(vessel)
    unstable_m_s = course_unstable_from_m_s(compile_vessel(vessel.with_environment(Environment())))
    lines = [f"# ArduPilot Rover parameters for a SITL session with the twin of '{vessel.name}'",
             "# written by `twin sitl --write-params`: give it after Rover's own defaults",
             "# (ardurover --defaults rover.parm,rover-skid.parm,THIS, or sim_vehicle.py --add-param-file THIS)",
             "FRAME_CLASS     2      # boat",
             f"SERVO{left}_FUNCTION 73     # throttle left  (twin sitl --channels {left},{right})",
             f"SERVO{right}_FUNCTION 74     # throttle right"]
    for ch in (left, right):
        lines += [f"SERVO{ch}_MIN {m.pwm_min_us:.0f}" + ("        # the vessel file's PWM range and neutral"
                                                         if ch == left else ""),
                  f"SERVO{ch}_TRIM {m.neutral_us:.0f}",
                  f"SERVO{ch}_MAX {m.pwm_max_us:.0f}"]
    if max(channels) > 16:
        lines.append("SERVO_32_ENABLE 1      # outputs beyond 16")
    lines += ["MOT_PWM_TYPE    0      # normal PWM",
              f"CRUISE_SPEED    {speed:.2f}   # the twin's steady speed at {CRUISE_THROTTLE_PCT} % throttle, calm water",
              f"CRUISE_THROTTLE {CRUISE_THROTTLE_PCT}",
              f"WP_SPEED        {speed:.2f}   # AUTO and GUIDED at cruise: its top speed is {top:.2f} m/s at full "
              "throttle, the rest is for steering",
              f"ATC_STR_RAT_MAX {turn:.0f}     # deg/s: the twin's steady turn rate at full differential thrust"]
    if unstable_m_s is not None:
        lines.append(f"# the twin is course-unstable from {unstable_m_s:.2f} m/s (it turns on its own: twin params): "
                     "its speeds above are of the straight runs Rover's steering holds")
    return "\n".join(lines) + "\n"
