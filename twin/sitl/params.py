"""The ArduPilot parameter file a SITL session with the twin needs (`twin sitl --write-params`).

What ArduPilot must agree on with the twin: a boat frame, the two servo outputs the twin
reads as its thrusters, their PWM range and neutral (the vessel file's, so full stick is
full thrust and trim is zero thrust), and a cruise speed/throttle pair that the twin
actually reaches (Rover's speed controller feeds forward from it). The names and meanings
are ArduPilot Rover's (FRAME_CLASS 2 = boat, SERVOn_FUNCTION 73/74 = throttle left/right).
"""
from __future__ import annotations

import numpy as np

from ..drive import InputSeries
from ..engine.mjcf import compile_vessel
from ..engine.sim import simulate
from ..errors import TwinError
from ..physics.environment import Environment
from ..vessel import Vessel
from .backend import PwmMap

CRUISE_THROTTLE_PCT = 50
SETTLE_S = 90.0  # a 1-m boat settles to its cruise speed within a few tens of seconds


def cruise_speed_m_s(vessel: Vessel, throttle_pct: float = CRUISE_THROTTLE_PCT) -> float:
    """Steady surge speed (m/s) of the twin with both thrusters at `throttle_pct` % of the PWM
    span above neutral, in calm water (the vessel's own current and wind are removed)."""
    calm = vessel.with_environment(Environment())
    m = PwmMap.of(calm.thrusters)
    pwm = m.neutral_us + throttle_pct / 100.0 * (m.pwm_max_us - m.neutral_us)
    if m.kind == "pwm":
        drive = InputSeries(np.array([0.0]), np.array([[pwm, pwm]]), "pwm")
    else:
        thrust = m.raw(m.held(pwm))
        drive = InputSeries(np.array([0.0]), np.array([[thrust, thrust]]), "thrust")
    run = simulate(compile_vessel(calm), drive, SETTLE_S, sample_dt_s=0.5)
    return float(np.mean(run.nu[run.t >= SETTLE_S - 10.0, 0]))


def boat_parameters(vessel: Vessel, channels: tuple[int, int] = (1, 3)) -> str:
    """The parameter file's text (ArduPilot's `NAME VALUE  # comment` lines)."""
    if vessel.thrusters.kind == "propeller_rudder":
        raise TwinError(f"vessel '{vessel.name}' is a propeller-and-rudder ship: SITL supports twin-thruster "
                        f"vessels only")
    m = PwmMap.of(vessel.thrusters)
    left, right = channels
    speed = cruise_speed_m_s(vessel)
    lines = [f"# ArduPilot Rover parameters for a SITL session with the twin of '{vessel.name}'",
             "# written by `twin sitl --write-params`; load with sim_vehicle.py --add-param-file",
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
              f"CRUISE_THROTTLE {CRUISE_THROTTLE_PCT}"]
    return "\n".join(lines) + "\n"
