"""Identification manoeuvres shaped like [Morel-2024 §6.1]: a pilot with two joysticks
(PWM mean δ̄ and difference Δδ, §5.1) drives forward runs at constant and varying
speed, zig-zags, and circles at constant and varying rate; plus free RC driving
and an autopilot that holds heading and speed on straight legs (closed loop).

Open-loop manoeuvres are PWM series at the autopilot's 10 Hz output rate
(integer µs, forward = higher): the batch engine runs them. Closed-loop ones
(zig-zag, autopilot) are controllers for `engine.sim.simulate`.

Normalised PWM δ = (PWM − 1500 µs)/400 µs ∈ [−1, 1] [Yellowfish-TR §V-B];
δL = δ̄ + Δδ/2, δR = δ̄ − Δδ/2. Positive Δδ speeds the left thruster up and
turns the vessel to starboard.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..errors import TwinError
from ..drive import InputSeries
from ..physics.kinematics import wrap_angle
from ..drive import ZigZag

PWM_DT_S = 0.1
NEUTRAL_US = 1500.0
OPEN_LOOP = ("rc", "forward_constant", "forward_varying", "circle_constant", "circle_varying")
CLOSED_LOOP = ("zigzag", "autopilot")
ALL = OPEN_LOOP + CLOSED_LOOP
# by name only, not in a default dataset (which the proof and the benches keep as they were)
ASTERN = ("astern_varying",)
# trials: fixed programs a diagnosis proposes to tell two readings of a log apart (diagnose/separate.py),
# each from rest; a dataset segment longer than its program repeats it
TRIALS = ("full_ahead_coast", "throttle_steps", "spins", "turns", "astern_stop")
KNOWN = ALL + ASTERN + TRIALS


def _program(steps: list[tuple[float, float, float]]) -> tuple[np.ndarray, np.ndarray]:
    """Sticks (δ̄, Δδ) held for each (seconds, δ̄, Δδ) in turn, sampled every PWM_DT_S."""
    mean = np.concatenate([np.full(int(round(s / PWM_DT_S)), m) for s, m, _ in steps])
    diff = np.concatenate([np.full(int(round(s / PWM_DT_S)), d) for s, _, d in steps])
    return mean, diff


def trial_program(name: str) -> tuple[np.ndarray, np.ndarray]:
    """The sticks (δ̄, Δδ) of a trial (TRIALS), every PWM_DT_S from rest. Each isolates what one
    family of effects changes: a thrust that falls with speed against a weaker thrust (full ahead from
    rest: the same top speed, another acceleration), a drag against a thrust loss (the coast-down, where
    no thrust acts), the thrust map's shape (throttle steps), a one-sided thruster (spins and turns
    both ways), the astern thrust and drag."""
    steps = {
        "full_ahead_coast": [(3.0, 0.0, 0.0), (25.0, 1.0, 0.0), (17.0, 0.0, 0.0)],
        "throttle_steps": [(3.0, 0.0, 0.0), (8.0, 0.25, 0.0), (8.0, 0.5, 0.0), (8.0, 0.75, 0.0), (8.0, 1.0, 0.0),
                           (10.0, 0.0, 0.0)],
        "spins": [(3.0, 0.0, 0.0), (12.0, 0.0, 1.6), (6.0, 0.0, 0.0), (12.0, 0.0, -1.6), (6.0, 0.0, 0.0)],
        "turns": [(3.0, 0.0, 0.0), (15.0, 0.6, 0.6), (15.0, 0.6, -0.6), (8.0, 0.0, 0.0)],
        "astern_stop": [(3.0, 0.0, 0.0), (15.0, -0.8, 0.0), (12.0, 0.0, 0.0)],
    }
    if name not in steps:
        raise TwinError(f"unknown trial '{name}' (known: {', '.join(TRIALS)})")
    return _program(steps[name])


def trial(name: str, duration_s: float | None = None) -> InputSeries:
    """A trial's PWM series from rest (trial_program), repeated to fill `duration_s` (its own length
    when None)."""
    mean, diff = trial_program(name)
    if duration_s is not None:
        n = max(1, int(round(duration_s / PWM_DT_S)))
        mean, diff = np.resize(mean, n), np.resize(diff, n)
    return _series(mean, diff)


@dataclass
class Manoeuvre:
    """One trajectory segment: its name, duration and what drives it (an InputSeries
    of PWM, or a controller (t, η, ν) → (surge, yaw) normalised)."""

    name: str
    duration_s: float
    drive: InputSeries | Callable


def sticks_to_pwm(mean: np.ndarray, diff: np.ndarray) -> np.ndarray:
    """Two joysticks (δ̄, Δδ) → (n, 2) PWM µs, left and right, integers as an autopilot logs them."""
    left = np.clip(mean + diff / 2, -1.0, 1.0)
    right = np.clip(mean - diff / 2, -1.0, 1.0)
    return np.round(NEUTRAL_US + 400.0 * np.column_stack([left, right]))


def _held(rng: np.random.Generator, n: int, levels: Callable[[], float], hold_s=(1.5, 5.0),
          ramp_s=(0.3, 1.5)) -> np.ndarray:
    """A stick moved between random levels held for random times, with ramps between them
    (a thumb does not jump), sampled every PWM_DT_S."""
    out, value = np.empty(n), levels()
    i = 0
    while i < n:
        target = levels()
        ramp = max(1, int(rng.uniform(*ramp_s) / PWM_DT_S))
        hold = max(1, int(rng.uniform(*hold_s) / PWM_DT_S))
        seg = np.concatenate([np.linspace(value, target, ramp + 1)[1:], np.full(hold, target)])
        out[i: i + len(seg)] = seg[: n - i]
        i += len(seg)
        value = target
    return out


def _series(mean: np.ndarray, diff: np.ndarray) -> InputSeries:
    return InputSeries(np.arange(len(mean)) * PWM_DT_S, sticks_to_pwm(mean, diff), "pwm")


def rc(rng: np.random.Generator, duration_s: float) -> InputSeries:
    """Free RC driving: both sticks anywhere forward-ish, regions (f,f), (f,r), (r,f) and a
    little (r,r) ([Morel-2024] avoids reversing both)."""
    n = int(round(duration_s / PWM_DT_S))
    mean = _held(rng, n, lambda: rng.uniform(-0.1, 0.8))
    diff = _held(rng, n, lambda: rng.uniform(-0.9, 0.9) * (rng.uniform() < 0.75))
    return _series(mean, diff)


def forward_constant(rng: np.random.Generator, duration_s: float) -> InputSeries:
    """Straight run at one throttle, a small steering trim to hold the line."""
    n = int(round(duration_s / PWM_DT_S))
    mean = np.full(n, rng.uniform(0.15, 0.9))
    diff = _held(rng, n, lambda: rng.uniform(-0.06, 0.06), hold_s=(2.0, 6.0))
    return _series(mean, diff)


def forward_varying(rng: np.random.Generator, duration_s: float) -> InputSeries:
    """Straight run with the throttle moved up and down."""
    n = int(round(duration_s / PWM_DT_S))
    mean = _held(rng, n, lambda: rng.uniform(0.05, 0.95), hold_s=(2.0, 8.0), ramp_s=(0.5, 4.0))
    diff = _held(rng, n, lambda: rng.uniform(-0.06, 0.06), hold_s=(2.0, 6.0))
    return _series(mean, diff)


def astern_varying(rng: np.random.Generator, duration_s: float) -> InputSeries:
    """Backing: both sticks astern with the throttle moved, a small steering trim (docking, picking up
    a mooring), now and then ahead to stop: the hull's drag astern, which the other manoeuvres barely
    reach."""
    n = int(round(duration_s / PWM_DT_S))
    mean = _held(rng, n, lambda: rng.uniform(-0.8, -0.1) if rng.uniform() < 0.8 else rng.uniform(0.0, 0.4),
                 hold_s=(2.0, 8.0), ramp_s=(0.5, 3.0))
    diff = _held(rng, n, lambda: rng.uniform(-0.1, 0.1), hold_s=(2.0, 6.0))
    return _series(mean, diff)


def circle_constant(rng: np.random.Generator, duration_s: float) -> InputSeries:
    """A circle at one throttle and one steering (either side)."""
    n = int(round(duration_s / PWM_DT_S))
    mean = np.full(n, rng.uniform(0.1, 0.7))
    diff = np.full(n, rng.choice([-1, 1]) * rng.uniform(0.2, 0.9))
    return _series(mean, diff)


def circle_varying(rng: np.random.Generator, duration_s: float) -> InputSeries:
    """Turning with the rate (steering) and the speed (throttle) varied."""
    n = int(round(duration_s / PWM_DT_S))
    side = rng.choice([-1, 1])
    mean = _held(rng, n, lambda: rng.uniform(0.0, 0.8))
    diff = _held(rng, n, lambda: side * rng.uniform(0.1, 1.0))
    return _series(mean, diff)


@dataclass
class Autopilot:
    """Heading and throttle hold on straight legs, as ArduPilot's steering and speed loops
    do in AUTO: a PI on the heading error, so that a steady yaw disturbance (thrust
    asymmetry, a current's Munk moment, wind) is compensated and the track looks normal.
    Legs change heading every leg_s; ψ from the measurement it is given."""

    rng: np.random.Generator
    throttle: float = 0.5
    leg_s: float = 25.0
    kp: float = 0.9  # yaw stick per rad of heading error
    ki: float = 0.25  # per rad·s
    _target: float | None = None
    _integral: float = 0.0
    _last_t: float = 0.0
    _leg_end: float = -1.0
    output: str = field(default="normalised", init=False)

    def __call__(self, t: float, eta: np.ndarray, nu: np.ndarray) -> tuple[float, float]:
        if t >= self._leg_end:
            base = eta[2] if self._target is None else self._target
            self._target = base + self.rng.uniform(-2.5, 2.5)
            self._leg_end = t + self.leg_s
            self.throttle = float(self.rng.uniform(0.3, 0.8))
        error = float(wrap_angle(self._target - eta[2]))
        dt = max(0.0, t - self._last_t)
        self._last_t = t
        self._integral = float(np.clip(self._integral + error * dt, -1.5, 1.5))  # anti-windup
        yaw = float(np.clip(self.kp * error + self.ki * self._integral - 0.3 * nu[2], -0.8, 0.8))
        return self.throttle, yaw


def make(name: str, rng: np.random.Generator, duration_s: float) -> Manoeuvre:
    """A manoeuvre by name (see KNOWN)."""
    if name in OPEN_LOOP + ASTERN:
        return Manoeuvre(name, duration_s, globals()[name](rng, duration_s))
    if name in TRIALS:
        return Manoeuvre(name, duration_s, trial(name, duration_s))
    if name == "zigzag":
        return Manoeuvre(name, duration_s, ZigZag(surge=float(rng.uniform(0.2, 0.6)), yaw=float(rng.uniform(0.3, 0.7)),
                                                  switch_deg=float(rng.uniform(10, 30)), at_s=2.0))
    if name == "autopilot":
        return Manoeuvre(name, duration_s, Autopilot(rng))
    raise TwinError(f"unknown manoeuvre '{name}' (known: {', '.join(KNOWN)})")


def plan(names: list[str], n_segments: int, rng: np.random.Generator,
         duration_s: tuple[float, float] = (40.0, 90.0)) -> list[Manoeuvre]:
    """n_segments manoeuvres cycling through `names`, each of a random duration."""
    if not names:
        raise TwinError("no manoeuvres given")
    for n in names:
        if n not in KNOWN:
            raise TwinError(f"unknown manoeuvre '{n}' (known: {', '.join(KNOWN)})")
    if n_segments < 1:
        raise TwinError("a dataset needs at least one segment")
    return [make(names[k % len(names)], rng, float(np.round(rng.uniform(*duration_s), 1)))
            for k in range(n_segments)]
