"""Where a run asked its thrusters for more than the vessel file allows.

A vessel file may bound the thruster inputs: the PWM range of an ESC (pwm_min_us,
pwm_max_us, which also bounds the thrust through the map) or, for thrust inputs, the
thrust range a source gives (thrust_min_n, thrust_max_n), or a propeller and rudder's speed and
angle (rps_max, rudder_max_deg; reported in rps and degrees). The engine applies such a bound;
this module says when a run's inputs went beyond it, for how long and by how much, so that
no limit acts silently. A vessel whose source gives no bound has none (unbounded thrust).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..drive import InputSeries
from ..vessel import Vessel

SIDES = ("left", "right")


@dataclass(frozen=True)
class Limited:
    """One thruster's input held beyond the vessel's bound: which bound, for how long (s), the
    largest excess (in the input's unit) and when it began (s from the run's start)."""

    thruster: str  # left, right, or propeller, rudder
    quantity: str  # "PWM", "thrust", or "speed", "angle"
    unit: str
    bound: float
    seconds: float
    worst_excess: float
    first_s: float

    def text(self) -> str:
        side = "above" if self.worst_excess > 0 else "below"
        what = self.thruster if self.thruster in ("propeller", "rudder") else f"{self.thruster} thruster"
        return (f"{what} {self.quantity} requested {side} the vessel file's bound "
                f"{self.bound:g} {self.unit} for {self.seconds:.2f} s from t = {self.first_s:.2f} s "
                f"(by up to {abs(self.worst_excess):.3g} {self.unit}); the engine applied the bound")

    def to_dict(self) -> dict:
        return {"thruster": self.thruster, "quantity": self.quantity, "unit": self.unit, "bound": self.bound,
                "seconds": round(self.seconds, 6), "worst_excess": self.worst_excess, "first_s": self.first_s}


def _held_seconds(series: InputSeries, duration_s: float) -> np.ndarray:
    """How long each input row is held within [0, duration_s]."""
    start = np.clip(series.t, 0.0, duration_s)
    end = np.clip(np.append(series.t[1:], duration_s), 0.0, duration_s)
    return np.maximum(end - start, 0.0)


def beyond_bounds(vessel: Vessel, series: InputSeries, duration_s: float) -> list[Limited]:
    """Every (thruster, direction) whose requested input left the vessel's bound during the run."""
    t = vessel.thrusters
    channels = [(side, None, None, None, 1.0) for side in SIDES]  # (name, lo, hi, quantity, unit scale)
    if series.kind == "pwm":
        lo, hi, quantity, unit = t.pwm_min_us, t.pwm_max_us, "PWM", "µs"
    elif series.kind == "propeller_rudder":
        (n_lo, n_hi), (d_lo, d_hi) = t.channel_bounds()
        channels = [("propeller", n_lo, n_hi, ("speed", "rps"), 1.0),
                    ("rudder", np.degrees(d_lo), np.degrees(d_hi), ("angle", "deg"), 180.0 / np.pi)]
    else:
        lo, hi = t.bounds()
        quantity, unit = "thrust", "N"
    held = _held_seconds(series, duration_s)
    out = []
    for j, (side, c_lo, c_hi, c_quantity, scale) in enumerate(channels):
        if c_quantity is not None:
            lo, hi, (quantity, unit) = c_lo, c_hi, c_quantity
        values = np.asarray(series.values[:, j], float) * scale
        for bound, excess in ((hi, values - hi), (lo, values - lo)):
            if not np.isfinite(bound):
                continue
            over = (excess > 0 if bound == hi else excess < 0) & (held > 0)
            if not over.any():
                continue
            worst = excess[over][np.argmax(np.abs(excess[over]))]
            out.append(Limited(side, quantity, unit, float(bound), float(held[over].sum()), float(worst),
                               float(max(series.t[over][0], 0.0))))
    return out
