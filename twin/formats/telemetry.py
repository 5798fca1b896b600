"""What an ArduPilot boat's sensors would log during a run, at the rates of
[Morel-2024 §3]: GNSS at the antenna (lever arm, [Yellowfish-TR appendix]) every 200 ms,
AHRS heading every 20 ms (with the roll and pitch of a 6-DOF hull), thruster PWM every 100 ms.
Shared by the .tlog and DataFlash .bin writers."""
from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from ..errors import TwinError
from ..geodesy import geodetic_from_ned
from ..run import Run

DEFAULT_ORIGIN = (37.4136, -5.9786)  # any origin works; this one is Seville, the Yellowfish's home
LEFT_CHANNEL, RIGHT_CHANNEL = 1, 3  # SERVO1_FUNCTION = 73, SERVO3_FUNCTION = 74 (ArduRover skid steering)
THRUSTER_PARAMS = {"SERVO1_FUNCTION": 73, "SERVO3_FUNCTION": 74, "SERVO1_REVERSED": 0, "SERVO3_REVERSED": 0}


def log_parameters(params: dict[str, float], neutral_us=(1500.0, 1500.0), with_pwm: bool = True) -> dict[str, float]:
    """The parameters a log of a recording carries: the recording's own, then, when the log
    holds PWM, the thruster mapping it is written with (THRUSTER_PARAMS, trims = the PWM
    neutral). The source's own throttle-left/right functions on other channels are then left
    out: the reader would map those channels instead."""
    if not with_pwm:
        return {k: float(v) for k, v in params.items()}
    own = {k: float(v) for k, v in params.items()
           if not (re.fullmatch(r"SERVO\d+_FUNCTION", k) and v in (73, 74))}
    return own | THRUSTER_PARAMS | {f"SERVO{LEFT_CHANNEL}_TRIM": float(neutral_us[0]),
                                    f"SERVO{RIGHT_CHANNEL}_TRIM": float(neutral_us[1])}


def _empty() -> np.ndarray:
    return np.zeros(0)


@dataclass
class Telemetry:
    """Sensor samples as a log stores them, times in s from the log's start (≥ 0)."""

    gnss_t: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    speed_m_s: np.ndarray  # NaN: unknown
    heading_t: np.ndarray
    psi_rad: np.ndarray  # wrapped to (−π, π]
    r_rad_s: np.ndarray
    pwm_t: np.ndarray  # empty when the run was driven by thrust
    pwm_us: np.ndarray  # (n, 2) left, right
    alt_m: np.ndarray | None = None  # None: altitude 0
    battery_t: np.ndarray = field(default_factory=_empty)
    voltage_v: np.ndarray = field(default_factory=_empty)
    velocity_ned_m_s: np.ndarray | None = None  # (n, 2) north, east at gnss_t; None: unknown
    roll_rad: np.ndarray | None = None  # at heading_t; None: a level hull (the 3-DOF twin)
    pitch_rad: np.ndarray | None = None

    def attitude(self) -> tuple[np.ndarray, np.ndarray]:
        """(roll, pitch) rad at heading_t, zeros for a level hull."""
        if self.roll_rad is None or self.pitch_rad is None:
            return np.zeros(len(self.heading_t)), np.zeros(len(self.heading_t))
        return self.roll_rad, self.pitch_rad

    def course_deg(self) -> np.ndarray:
        """Course over ground at gnss_t (deg in [0, 360), the direction of motion, not the heading);
        NaN when unknown or when the boat barely moves (below 5 cm/s it is noise)."""
        if self.velocity_ned_m_s is None:
            return np.full(len(self.gnss_t), np.nan)
        vn, ve = self.velocity_ned_m_s[:, 0], self.velocity_ned_m_s[:, 1]
        course = np.degrees(np.arctan2(ve, vn)) % 360.0
        return np.where(np.hypot(vn, ve) >= 0.05, course, np.nan)


def antenna_ned(run: Run, antenna_body_m) -> tuple[np.ndarray, np.ndarray]:
    """Antenna position in NED: CO + R(ψ)·r_antenna (the inverse of [Yellowfish-TR eq. 32])."""
    c, s = np.cos(run.eta[:, 2]), np.sin(run.eta[:, 2])
    ax, ay = antenna_body_m[0], antenna_body_m[1]
    return run.eta[:, 0] + c * ax - s * ay, run.eta[:, 1] + s * ax + c * ay


def _sensor_times(run: Run, dt: float) -> np.ndarray:
    """A sensor's sample times every dt over the run's own span (from its first time, not from 0)
    and not inside a gap between its samples (runs joined end to end, as `replay` joins segments):
    a sample there would be the states on either side drawn as a straight line, and inputs held."""
    t = np.asarray(run.t, float)
    times = np.arange(float(t[0]), float(t[-1]) + 1e-9, dt)
    steps = np.diff(t)
    gap = steps > 2.0 * float(np.median(steps))
    if not gap.any():
        return times
    k = np.clip(np.searchsorted(t, times, side="right") - 1, 0, len(steps) - 1)
    return times[~gap[k] | np.isclose(times, t[k])]


def sample(run: Run, antenna_body_m=(0.0, 0.0), origin=DEFAULT_ORIGIN, gnss_dt: float = 0.2,
           heading_dt: float = 0.02, pwm_dt: float = 0.1) -> Telemetry:
    if len(run.t) < 2:
        raise TwinError("a log needs at least two samples")
    north, east = antenna_ned(run, antenna_body_m)
    tg = _sensor_times(run, gnss_dt)
    ng, eg = np.interp(tg, run.t, north), np.interp(tg, run.t, east)
    lat, lon = geodetic_from_ned(ng, eg, *origin)
    velocity = np.column_stack([np.gradient(ng, tg), np.gradient(eg, tg)]) if len(tg) > 1 else np.zeros((len(tg), 2))
    speed = np.hypot(velocity[:, 0], velocity[:, 1])
    th = _sensor_times(run, heading_dt)
    psi = np.angle(np.exp(1j * np.interp(th, run.t, np.unwrap(run.eta[:, 2]))))
    r = np.interp(th, run.t, run.nu[:, 2])
    tp = _sensor_times(run, pwm_dt) if np.all(np.isfinite(run.pwm_us)) else np.zeros(0)
    idx = np.clip(np.searchsorted(run.t, tp + 1e-9, side="right") - 1, 0, len(run.t) - 1)
    six = run.meta.get("six_dof")  # a 6-DOF hull's roll and pitch, beside the heading
    roll = None if six is None else np.interp(th, run.t, six["roll_rad"])
    pitch = None if six is None else np.interp(th, run.t, six["pitch_rad"])
    return Telemetry(tg, lat, lon, speed, th, psi, r, tp, run.pwm_us[idx] if len(tp) else np.zeros((0, 2)),
                     velocity_ned_m_s=velocity, roll_rad=roll, pitch_rad=pitch)
