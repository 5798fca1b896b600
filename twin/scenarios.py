"""Manoeuvres that drive a twin: step, turning circle, zig-zag, spin.

Each scenario is a controller (t, η, ν) → (surge command, yaw command), both
normalised to [−1, 1], evaluated at the autopilot rate. A positive yaw
command speeds the left thruster up and the right one down, which turns the
vessel to starboard (r > 0, seed 000 eq. 26c).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .errors import TwinError
from .physics.thrusters import ThrusterModel

Controller = Callable[[float, np.ndarray, np.ndarray], tuple[float, float]]


def step(surge: float = 0.6, at_s: float = 1.0) -> Controller:
    return lambda t, eta, nu: (surge if t >= at_s else 0.0, 0.0)


def turn(surge: float = 0.6, yaw: float = 0.3, at_s: float = 10.0) -> Controller:
    return lambda t, eta, nu: (surge, yaw if t >= at_s else 0.0)


def spin(yaw: float = 0.5, at_s: float = 1.0) -> Controller:
    return lambda t, eta, nu: (0.0, yaw if t >= at_s else 0.0)


@dataclass
class ZigZag:
    """The classic zig-zag: rudder-equivalent yaw command ±yaw, switched each
    time the heading passes ±switch_deg from the initial heading."""

    surge: float = 0.3
    yaw: float = 0.6
    switch_deg: float = 20.0
    at_s: float = 5.0
    _sign: float = 1.0
    _psi0: float | None = None

    def __call__(self, t: float, eta: np.ndarray, nu: np.ndarray) -> tuple[float, float]:
        if self._psi0 is None:
            self._psi0 = float(eta[2])
        if t < self.at_s:
            return self.surge, 0.0
        heading_deg = np.rad2deg(eta[2] - self._psi0)
        if self._sign > 0 and heading_deg >= self.switch_deg:
            self._sign = -1.0
        elif self._sign < 0 and heading_deg <= -self.switch_deg:
            self._sign = 1.0
        return self.surge, self._sign * self.yaw


def random_rc(seed: int = 0, hold_s: tuple[float, float] = (2.0, 6.0)) -> Controller:
    """RC-like driving: two joysticks (surge, yaw) held at random levels for
    random intervals, as a pilot drives for identification (seed 004 §6.1)."""
    rng = np.random.default_rng(seed)
    state = {"until": -1.0, "cmd": (0.0, 0.0)}

    def controller(t: float, eta: np.ndarray, nu: np.ndarray) -> tuple[float, float]:
        if t >= state["until"]:
            state["until"] = t + rng.uniform(*hold_s)
            state["cmd"] = (float(rng.uniform(0.0, 0.8)), float(rng.uniform(-0.5, 0.5)))
        return state["cmd"]

    return controller


SCENARIOS: dict[str, Callable[..., Controller]] = {
    "step": step, "turn": turn, "zigzag": ZigZag, "spin": spin, "random": random_rc,
}


def get(name: str, seed: int = 0) -> Controller:
    if name not in SCENARIOS:
        raise TwinError(f"unknown scenario '{name}' (known: {', '.join(SCENARIOS)})")
    return SCENARIOS[name](seed=seed) if name == "random" else SCENARIOS[name]()


def to_thruster_inputs(thrusters: ThrusterModel, surge: float, yaw: float) -> tuple[str, np.ndarray]:
    """Normalised (surge, yaw) → per-thruster PWM (µs) or thrust (N) command."""
    cmd = np.clip(np.array([surge + yaw, surge - yaw]), -1.0, 1.0)
    if thrusters.kind == "t200":
        mid = 0.5 * (thrusters.pwm_min_us + thrusters.pwm_max_us)
        half = 0.5 * (thrusters.pwm_max_us - thrusters.pwm_min_us)
        return "pwm", mid + half * cmd
    t_min, t_max = thrusters.bounds()
    return "thrust", np.where(cmd >= 0, cmd * t_max, -cmd * t_min)
