"""What the sensors report of the true state: the GNSS antenna position ([Yellowfish-TR appendix eqs. 28-32], read backwards) and the AHRS heading with its errors, and the
timing of the PWM log against the other streams.

Heading error (deg) at true heading ψ: a constant bias plus the classic one- and
two-cycle compass deviation (Bowditch): δψ = A + B sin ψ + C cos ψ + D sin 2ψ + E cos 2ψ
(ψ stands in for the magnetic heading; the variation between them is a constant
that the bias absorbs).

The thrusters' own currents add a field of their own at the magnetometer: a body-fixed vector
that grows with what the motors draw, so a one-cycle deviation that comes and goes with the
throttle: δψ_motor = τ·(B_m sin ψ + C_m cos ψ), τ the thrusters' mean throttle |pwm − neutral| /
full range of the pulses each ESC receives, its PWM span applied (0 at idle, 1 both at full, ahead or
astern: a battery's current flows one way either
way). ArduPilot calibrates this as COMPASS_MOT [ArduPilot-CompassMot] with COMPASS_MOT_TYPE = 1 (throttle; = 2 reads
a current sensor instead, which these logs seldom have); the field's direction and size are the
wiring's, so B_m and C_m are each boat's own.

A compass calibrated afresh before every outing, or disturbed by what was loaded
that day, has a bias of its own in each log: `heading_bias_by_log_deg` holds
(log name, deg) pairs added to the common bias for the recording of that name.

The antenna sits at the vessel's MJCF `gnss` site plus `antenna_offset_m` (body
FRD), so a wrongly surveyed lever arm is a sensor parameter, not a new MJCF.
`pwm_clock_offset_s` > 0: the PWM log's stamps are late against GNSS and heading
(the thrust seems to answer before the logged command). `gnss_latency_s` > 0: the GNSS fix
stamped t was taken at t − gnss_latency_s (a receiver's solution latency, with heading and PWM
on time). Its mark in a log: the track over ground lags the heading in every turn, so the
measured sway carries −u·r·latency, which a hull's sway-yaw coupling can imitate.
`heading_latency_s` > 0: the heading sample stamped t was taken at t − heading_latency_s (an
AHRS or compass filter: a first-order filter of time constant τ lags a turn by about τ). Its mark:
the heading lags the track in every turn, so the measured sway carries +u·r·latency, and the yaw
rate taken from the heading lags the thrust; late heading ≡ GNSS and PWM both early by as much.
"""
from __future__ import annotations

from dataclasses import dataclass, fields, replace
from pathlib import PurePath

import numpy as np


@dataclass(frozen=True)
class Sensors:
    """How the vessel's sensors and logs depart from the truth (module docstring): compass bias and
    deviation (deg), the GNSS antenna's offset from the MJCF site (m, body FRD), the PWM log's clock
    offset and the GNSS and heading latencies (s), and where the yaw rate is read."""

    heading_bias_deg: float = 0.0
    compass_deviation_deg: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)  # B, C, D, E
    compass_motor_deg: tuple[float, float] = (0.0, 0.0)  # B_m, C_m: the motors' deviation at full throttle
    antenna_offset_m: tuple[float, float] = (0.0, 0.0)
    pwm_clock_offset_s: float = 0.0
    gnss_latency_s: float = 0.0
    heading_latency_s: float = 0.0
    heading_bias_by_log_deg: tuple[tuple[str, float], ...] = ()
    # the Savitzky-Golay window (s) of the yaw rate taken from this heading sensor; None: the
    # package's default for a fast AHRS (fit.calibrate.HEADING_WINDOW_S). A slower or noisier heading
    # needs a longer one, or its derivative is mostly noise (a vessel file's sources say why)
    heading_rate_window_s: float | None = None
    # where the yaw rate r is read: "heading" (the heading's Savitzky-Golay slope) or "gyro" (the log's
    # rate gyro, where it has one, less its mean offset from the heading's slope over the log). A gyro
    # measures r itself; the heading's slope needs a window that both lags and leaves noise
    yaw_rate_source: str = "heading"
    # (surge, yaw): how far (s, > 0: ahead) the hull's answers to input steps led this twin's own
    # timing on the runs it was identified on (fit/kinematic.py). The kinematics' response template is
    # not the twin's dynamics, so their zero is measured on those runs; other runs are read against it
    input_answer_s: tuple[float, float] = (0.0, 0.0)

    def for_log(self, source: str) -> "Sensors":
        """The sensors of the recording from `source` (a path or name): its own heading bias
        added to the common one."""
        extra = dict(self.heading_bias_by_log_deg).get(log_name(source), 0.0)
        return replace(self, heading_bias_deg=self.heading_bias_deg + extra, heading_bias_by_log_deg=())

    def heading_error_rad(self, psi_rad, throttle=0.0) -> np.ndarray:
        """δψ (rad) the AHRS adds to the true heading ψ (rad) at the motors' throttle τ (0-1, motor_throttle)."""
        psi = np.asarray(psi_rad, float)
        b, c, d, e = self.compass_deviation_deg
        bm, cm = self.compass_motor_deg
        if not self.varies_with_heading:  # a constant bias: no trigonometry over a whole log
            shape = np.broadcast_shapes(psi.shape, np.shape(throttle))
            return np.full(shape, np.radians(self.heading_bias_deg))
        b, c = b + bm * np.asarray(throttle, float), c + cm * np.asarray(throttle, float)
        sn, cs = np.sin(psi), np.cos(psi)  # the double angle's from these: half the trigonometry over a log
        deg = self.heading_bias_deg + b * sn + c * cs + d * (2 * sn * cs) + e * (cs * cs - sn * sn)
        return np.radians(deg)

    def errors(self) -> list[str]:
        """The names of this sensor model's errors (fields off a perfect sensor's value); the yaw
        rate's window and source and the input answers' zero are how the logs are read, not errors."""
        perfect = Sensors()
        return [f.name for f in fields(self) if f.name not in ("heading_rate_window_s", "yaw_rate_source",
                                                                 "input_answer_s")
                and getattr(self, f.name) != getattr(perfect, f.name)]

    @property
    def has_heading_error(self) -> bool:
        return self.heading_bias_deg != 0.0 or self.varies_with_heading

    @property
    def varies_with_heading(self) -> bool:
        return any(x != 0.0 for x in self.compass_deviation_deg) or self.follows_throttle

    @property
    def follows_throttle(self) -> bool:
        return any(x != 0.0 for x in self.compass_motor_deg)


def log_name(source: str) -> str:
    """The name a recording goes by in `heading_bias_by_log_deg`: its file name."""
    return PurePath(str(source)).name


def motor_throttle(pwm_us, neutral_us, pwm_min_us: float, pwm_max_us: float) -> np.ndarray:
    """τ (0-1): the thrusters' mean |pwm − neutral| over the full range on its side (pwm_us (n, k) µs;
    neutral_us one per thruster), beyond the range as logged (a log past full throttle says so)."""
    pwm = np.atleast_2d(np.asarray(pwm_us, float))
    off = pwm - np.asarray(neutral_us, float)
    full = np.where(off >= 0, pwm_max_us - np.asarray(neutral_us, float), np.asarray(neutral_us, float) - pwm_min_us)
    return np.mean(np.abs(off) / full, axis=1)


def measured_heading(sensors: Sensors, psi_rad, throttle=0.0) -> np.ndarray:
    """ψ_m = ψ + δψ(ψ, τ)."""
    return np.asarray(psi_rad, float) + sensors.heading_error_rad(psi_rad, throttle)


def true_heading(sensors: Sensors, psi_measured_rad, throttle=0.0, iterations: int = 4) -> np.ndarray:
    """ψ from ψ_m by fixed-point iteration ψ ← ψ_m − δψ(ψ, τ) (converges for |∂δψ/∂ψ| < 1)."""
    psi_m = np.asarray(psi_measured_rad, float)
    psi = psi_m.copy()
    if not sensors.has_heading_error:
        return psi
    if not sensors.varies_with_heading:  # a bias alone: every iteration gives this
        return psi_m - sensors.heading_error_rad(psi)
    for _ in range(iterations):
        psi = psi_m - sensors.heading_error_rad(psi, throttle)
    return psi


def antenna_body_m(gnss_site_m, sensors: Sensors) -> np.ndarray:
    """Antenna position in the body frame (x, y), m: the MJCF site plus the sensor's offset."""
    return np.asarray(gnss_site_m, float)[:2] + np.asarray(sensors.antenna_offset_m, float)


def antenna_ned(north_m, east_m, psi_rad, antenna_xy_m) -> tuple[np.ndarray, np.ndarray]:
    """Antenna north, east (m) of the vessel at CO (north, east) heading ψ: CO + R2(ψ)·r_a
    ([Yellowfish-TR eq. 32] solved for the antenna)."""
    c, s = np.cos(psi_rad), np.sin(psi_rad)
    ax, ay = antenna_xy_m
    return np.asarray(north_m) + c * ax - s * ay, np.asarray(east_m) + s * ax + c * ay
