"""One autopilot tick in plain Python floats: a controller's output → the input held on the
thrusters (PWM µs or thrust N) → the thrust command (N), as `drive.to_thruster_inputs` and
`ThrusterModel.command` compute them on arrays.

Why a second version: numpy on 2-element arrays costs microseconds per call (clip, where,
polyval, array creation), and a closed-loop run pays them at every control tick, where they
would be most of `sim.simulate`'s time. The same IEEE-754 operations in the same order on Python
floats give the same bits (Horner's scheme started from 0 as `np.polyval` does; clip as
max-then-min, which keeps NaN as np.clip does), which tests/test_sim_speed.py checks
against the numpy versions. Anything that is not a pair of plain numbers (numpy float32,
arrays, ...) goes through the numpy versions, so the result never depends on the path.

A propeller-and-rudder ship's controller gives (n rps, δ rad) itself (`output =
"propeller_rudder"`) or normalised (surge, yaw) as fractions of their bounds; either way the
engine's controls are (n, δ) as they are.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..drive import to_thruster_inputs
from ..physics.thrusters import ThrusterModel, saturated

Pair = tuple[float, float]


def _plain(x) -> bool:
    """A Python int or float (np.float64 is a float): arithmetic on it is IEEE double, as in numpy."""
    return isinstance(x, (float, int))


def _clip(x: float, lo: float, hi: float) -> float:
    """np.clip for one value: max then min, so NaN stays NaN."""
    return min(max(x, lo), hi)


def _horner(coefficients: tuple[float, ...], x: float) -> float:
    """np.polyval for one value: y = 0, then y·x + c for each coefficient, highest power first."""
    y = 0.0
    for c in coefficients:
        y = y * x + c
    return y


@dataclass(frozen=True)
class TickMap:
    """The thrusters' input and thrust maps for float pairs (`of(thrusters)`)."""

    thrusters: ThrusterModel
    mid_us: float
    half_us: float
    t_min: float
    t_max: float

    @classmethod
    def of(cls, thrusters: ThrusterModel) -> "TickMap":
        if thrusters.kind == "propeller_rudder":
            t_min, t_max = -np.inf, np.inf  # no thrust command: normalised outputs go through drive
        else:
            t_min, t_max = thrusters.command_range() if thrusters.kind != "t200" else thrusters.bounds()
        return cls(thrusters, 0.5 * (thrusters.pwm_min_us + thrusters.pwm_max_us),
                   0.5 * (thrusters.pwm_max_us - thrusters.pwm_min_us), t_min, t_max)

    def held(self, controller, out) -> tuple[str, Pair | np.ndarray]:
        """(kind, input held) from a controller's output, as `sim` defines it: thrusts in N when
        the controller says `output = "thrust"`, else normalised (surge, yaw) through
        `drive.to_thruster_inputs`."""
        output = getattr(controller, "output", "normalised")
        if output in ("thrust", "propeller_rudder"):
            if isinstance(out, tuple) and len(out) == 2 and _plain(out[0]) and _plain(out[1]):
                return output, (float(out[0]), float(out[1]))
            return output, np.asarray(out, float)
        if self.thrusters.kind == "propeller_rudder":
            return to_thruster_inputs(self.thrusters, *out)
        if isinstance(out, (tuple, list)) and len(out) == 2:
            left, right = out[0] + out[1], out[0] - out[1]
            if _plain(left) and _plain(right):
                return self._normalised(_clip(left, -1.0, 1.0), _clip(right, -1.0, 1.0))
        return to_thruster_inputs(self.thrusters, *out)

    def _normalised(self, left: float, right: float) -> tuple[str, Pair]:
        """`to_thruster_inputs` after its clip: PWM about the range's middle, or thrust towards
        the bound on the command's side."""
        if self.thrusters.kind == "t200":
            return "pwm", (self.mid_us + self.half_us * left, self.mid_us + self.half_us * right)
        return "thrust", (left * self.t_max if left >= 0 else -left * self.t_min,
                          right * self.t_max if right >= 0 else -right * self.t_min)

    def raw_thrust(self, kind: str, held) -> Pair:
        """`ThrusterModel.command` before the decay: PWM through eq. 27 or thrust as it is (N); a
        propeller and rudder's (n, δ) as they are."""
        if kind == "propeller_rudder" or self.thrusters.kind == "propeller_rudder":
            if kind != self.thrusters.input_kind:
                raise ValueError(f"thrusters of kind '{self.thrusters.kind}' cannot take {kind} inputs")
            left, right = np.broadcast_to(np.asarray(held, float), (2,)).tolist()
            return left, right
        if isinstance(held, tuple) and (kind != "pwm" or self.thrusters.kind == "t200"):
            return (self._thrust(held[0], 0), self._thrust(held[1], 1)) if kind == "pwm" else held
        if kind == "pwm" and self.thrusters.spanned:  # one pulse for both: each ESC's own range acts on it
            held = np.broadcast_to(np.asarray(held, float), (2,))
        raw = self.thrusters.thrust_from_pwm(held) if kind == "pwm" else np.asarray(held, float)
        left, right = np.broadcast_to(raw, (2,)).tolist()  # shape (1,) drives both, as the array path did
        return left, right

    def _thrust(self, pwm_us: float, side: int) -> float:
        """`ThrusterModel.thrust_from_pwm` for one pulse of thruster `side` (0 left, 1 right)."""
        t = self.thrusters
        span = t.pwm_span_left if side == 0 else t.pwm_span_right
        if span != 1.0:  # the ESC's own range (ThrusterModel.received)
            pwm_us = t.neutral_us + span * (pwm_us - t.neutral_us)
        x = _clip(pwm_us, t.pwm_min_us, t.pwm_max_us) / t.pwm_scale_us - t.pwm_offset
        edge_fwd, edge_rev = t.edges_of(side)
        if x >= edge_fwd:
            fwd = _horner(t.forward, x)
            return fwd if t.full_share == 1.0 else saturated(fwd, t.full_forward_n, t.full_share)
        if x <= edge_rev:
            return _horner(t.reverse, x)
        return 0.0

    def decay(self, t_s: float) -> float:
        """`ThrusterModel.decay_factor` at one recording time t_s (s)."""
        left = 1.0 - self.thrusters.decay_per_min * t_s / 60.0
        return left if left > 0.0 or left != left else 0.0  # np.maximum(0, ·): NaN stays NaN
