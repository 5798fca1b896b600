"""A log's sensors as the vessel description says they are: the recording seen through them.

The vessel's `sensors` (twin.physics.sensors) hold the heading bias and compass deviation
(common and per log), the GNSS antenna's offset from the MJCF site and the PWM log's clock
offset. `prepare_for` prepares a recording [Morel-2024 §5.1] as this vessel's sensors see it:
heading corrected, lever arm from its antenna. The PWM clock offset acts where the PWM drives
the twin (twin.fit.windows). Every command that replays a log (view, evaluate, identify,
diagnose) prepares it here, so they all replay it with the same calibration.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.linalg import block_diag
from scipy.optimize import least_squares

from ..engine.mjcf import CompiledVessel, compile_vessel
from ..physics.hydrodynamics import relative_acceleration
from ..errors import TwinError
from ..physics.sensors import antenna_body_m, log_name, motor_throttle, true_heading
from ..prepare import Prepared, prepare
from ..recording import TRACKED_ORIGIN, Recording, Stream
from ..vessel import Vessel


GNSS_WINDOW_S = 1.0  # Savitzky-Golay window of the GNSS velocities [Morel-2024 §5.1]
HEADING_WINDOW_S = 0.5  # an AHRS at 50 Hz affords a shorter one for the yaw rate


def rate_windows(vessel: Vessel) -> dict:
    """prepare()'s derivative windows for this vessel's sensors: the GNSS velocities' and the yaw
    rate's (the vessel's own `sensors.heading_rate_window_s` where its heading sensor needs one), and
    where the yaw rate is read (`sensors.yaw_rate_source`)."""
    own = vessel.sensors.heading_rate_window_s
    return {"window_s": GNSS_WINDOW_S, "heading_window_s": HEADING_WINDOW_S if own is None else own,
            "yaw_rate_source": vessel.sensors.yaw_rate_source}


def lever_arm_OP_m(compiled: CompiledVessel, rec: Recording | None = None) -> tuple[float, float] | None:
    """OP = (dx, dy) from the real antenna to CO [Yellowfish-TR eq. 28]: minus the antenna's
    body position, the MJCF gnss site plus the vessel's surveyed offset. For a recording whose
    positions are a track it gives as the body origin's (TRACKED_ORIGIN), minus the offset alone
    (None where there is none): the point tracked sits that far off what the log calls the origin."""
    if rec is not None and rec.meta.get("positions") == TRACKED_ORIGIN:
        dx, dy = map(float, compiled.vessel.sensors.antenna_offset_m)
        return None if dx == 0.0 and dy == 0.0 else (-dx, -dy)
    a = antenna_body_m(compiled.geometry.gnss_pos_m, compiled.vessel.sensors)
    return float(-a[0]), float(-a[1])


def calibrated(rec: Recording, vessel: Vessel) -> Recording:
    """The recording with the vessel's heading-sensor error, for this log, taken out (physics/sensors.py)."""
    sensors = vessel.sensors.for_log(rec.source)
    if not sensors.has_heading_error or not len(rec.heading):
        return rec
    throttle = throttle_at_heading(rec, vessel) if sensors.follows_throttle else 0.0
    psi = true_heading(sensors, np.unwrap(rec.heading["psi_rad"]), throttle)
    return replace(rec, heading=Stream(rec.heading.t, {**rec.heading.columns, "psi_rad": psi}))


def throttle_at_heading(rec: Recording, vessel: Vessel) -> np.ndarray:
    """The motors' throttle τ (physics.sensors.motor_throttle) when each heading sample was taken (a
    late AHRS stamps it heading_latency_s after): the PWM logged last before then, on the PWM log's
    clock (stamped pwm_clock_offset_s late), as each ESC receives it (its PWM span: the current the
    motor draws follows what it is driven with)."""
    if not len(rec.pwm):
        raise TwinError(f"{rec.source}: the compass error that follows the throttle (sensors.compass_motor_deg) "
                        "needs the thrusters' PWM, and this recording has none")
    s = vessel.sensors
    t = np.asarray(rec.heading.t, float) - s.heading_latency_s + s.pwm_clock_offset_s
    k = np.clip(np.searchsorted(rec.pwm.t, t, side="right") - 1, 0, len(rec.pwm.t) - 1)
    pwm = np.column_stack([np.asarray(rec.pwm["left_us"])[k], np.asarray(rec.pwm["right_us"])[k]])
    th = vessel.thrusters
    return motor_throttle(_received(th, pwm), rec.pwm_neutral_us, th.pwm_min_us, th.pwm_max_us)


def _received(thrusters, pwm_us) -> np.ndarray:
    """The pulses the ESCs drive their motors with: each ESC's span applied and, where a span acts,
    within the PWM range (an ESC clips what it receives; a log past full throttle without one stays
    as logged, motor_throttle)."""
    if not thrusters.spanned:
        return np.asarray(pwm_us, float)
    return thrusters.at_escs(thrusters.received(pwm_us))


def prepare_for(rec: Recording, compiled: CompiledVessel, **kwargs) -> Prepared:
    """[Morel-2024 §5.1] preparation as this vessel's sensors see the recording: heading
    corrected, lever arm from its antenna, each GNSS fix and heading read at the time it was taken. (The PWM
    clock offset acts where the PWM drives the twin: twin.fit.windows.)"""
    sensors = compiled.vessel.sensors.for_log(rec.source)
    return prepare(calibrated(rec, compiled.vessel), lever_arm_OP_m=lever_arm_OP_m(compiled, rec),
                   gnss_latency_s=sensors.gnss_latency_s, heading_latency_s=sensors.heading_latency_s,
                   logged_heading=rec.heading if len(rec.heading) else None, **kwargs)


# ---------------------------------------------------------------- a log's own calibration, from its kinematics

STRAIGHT_SPEED_M_S = 0.4  # under way, ahead or astern: slower, the GNSS velocity's direction is mostly noise
# Straight enough to read the compass on: running whose turn keeps the hull's own drift angle small. In a
# steady turn a hull crabs by about c·r', r' = |r|·L/U its turn rate per ship length and c its own (the
# twin's sway balance with no thrust and the rudder amidships, sway_balance: about 0.15 for the BlueBoat,
# 0.6 for the Esso Osaka). Running is read where c·r' stays under MAX_DRIFT_RAD (r' at most MAX_TURN_RATE,
# the BlueBoat's weaving), the sideslip left fitted beside the offset where the yaw rate varies (x[1]);
# and where it has stayed so for SETTLE_TIME_CONSTANTS of the hull's sway time constant, as a turn's drift
# angle outlasts the turn (a ship's by several lengths run: between the legs of its zig-zags the yaw rate
# passes zero where the drift angle is largest). A bound on |r| alone (0.35 rad/s) read a slow ship's
# every turn and zig-zag as straight running, and its drift angle as a compass offset
MAX_DRIFT_RAD = 0.03
MAX_TURN_RATE = 0.2
SETTLE_TIME_CONSTANTS = 3.0
STRAIGHT_YAW_RATE_RAD_S = 0.35  # a hull whose sway balance is not known (no length, no sway damping)
MIN_STRETCH_S = 1.0  # a GNSS velocity direction needs a few fixes
PIECE_S = 2.0  # straight running is cut into pieces this long: each gives the offset once
MIN_STRAIGHT_S = 3.0  # less straight running than this says nothing reliable about the compass
DRIFT_HEADING_SPREAD_DEG = 60.0  # straight legs this far apart in heading separate a drift from an offset
SLIP_YAW_SPREAD_RAD_S = 0.02
MIN_OFFSET_DEG, SIGNIFICANT_SIGMA = 1.5, 3.0  # smaller or less sure: a compass's own error, not applied
# a boat this slow through the water has lost its way: over ground it moves with its water and air (a
# GNSS velocity's own noise, averaged over seconds, is about this)
REST_SPEED_M_S = 0.02


@dataclass(frozen=True)
class LogCalibration:
    """A log's own compass offset, estimated from its kinematics alone (no dynamic model).

    Going straight under way, ahead or astern, a symmetric hull's track over ground follows its true heading,
    so the angle between the GNSS track and the logged heading is the compass's error there:
    heading_bias_deg = ψ_logged − ψ_true (twin.physics.sensors' sign), with its 1-σ from the
    spread of the offsets of 2-s pieces of straight running (optimistic where one long stretch
    gives all the pieces: what that stretch shares is not in it). Where straight legs point in different directions, a
    ground drift (current, wind leeway; NED m/s) is fitted with it so that the two are not
    confused; where they point one way, other logs' drifts may be taken (kinematic_calibrations). The
    drift is reported, not applied (it is physics, the twin's business). None where the
    log has too little straight running (why: `note`)."""

    log: str
    heading_bias_deg: float | None
    sigma_deg: float | None
    stretches: int
    seconds: float
    drift_ned_m_s: tuple[float, float] | None
    note: str = ""
    drift_from_logs: int = 0  # the drift is the mean of this many other logs' own (kinematic_calibrations)
    # the offset's 1-σ from the spread of its straight stretches' own offsets (two or more): the pieces
    # of one stretch share its conditions, so where the stretches disagree this is the honest one
    stretch_sigma_deg: float | None = None

    def to_dict(self) -> dict:
        return {"log": self.log, "heading_bias_deg": self.heading_bias_deg, "sigma_deg": self.sigma_deg,
                "stretches": self.stretches, "seconds": round(self.seconds, 1),
                "drift_ned_m_s": None if self.drift_ned_m_s is None else list(self.drift_ned_m_s), "note": self.note,
                **({"drift_from_logs": self.drift_from_logs} if self.drift_from_logs else {}),
                **({"stretch_sigma_deg": self.stretch_sigma_deg} if self.stretch_sigma_deg is not None else {})}

    def __repr__(self) -> str:
        return f"LogCalibration({self.text()})"

    def text(self) -> str:
        if self.heading_bias_deg is None:
            return f"{self.log}: compass offset not applied ({self.note})"
        drift = "" if self.drift_ned_m_s is None else \
            f"; ground drift N {self.drift_ned_m_s[0]:+.3f}, E {self.drift_ned_m_s[1]:+.3f} m/s" + \
            (f" (the mean of {self.drift_from_logs} other logs': its own legs point one way)"
             if self.drift_from_logs else "")
        apart = (f"; its stretches alone give ± {self.stretch_sigma_deg:.1f}°" if self.stretch_sigma_deg is not None
                 and self.stretch_sigma_deg > self.sigma_deg else "")
        return (f"{self.log}: compass offset {self.heading_bias_deg:+.1f}° ± {self.sigma_deg:.1f}° from "
                f"{self.stretches} straight stretch{'es' if self.stretches != 1 else ''} ({self.seconds:.0f} s under way)"
                f"{apart}{drift}")


@dataclass(frozen=True)
class StraightRunning:
    """What straight enough means for one hull at one speed (the note above MAX_DRIFT_RAD): the turn
    rate per ship length under `turn_rate` (rad, r' = |r|·L/U) for at least `settle_s` seconds; or,
    for a hull whose sway balance is not known (length_m 0), |r| under STRAIGHT_YAW_RATE_RAD_S."""

    length_m: float = 0.0
    turn_rate: float = MAX_TURN_RATE
    settle_s: float = 0.0

    def text(self) -> str:
        if self.length_m <= 0:
            return f"|r| < {STRAIGHT_YAW_RATE_RAD_S:g} rad/s"
        return (f"|r|·L/|u| < {self.turn_rate:.2g}, and so for the {self.settle_s:.0f} s before (three sway time "
                f"constants), L {self.length_m:.2f} m")


def sway_balance(compiled: CompiledVessel, speed_m_s: float) -> tuple[float, float]:
    """(c, T_v) of the hull at `speed_m_s` from the twin's sway row of M·ν̇ = τ with no thrust and the
    rudder amidships: c = |β|/r' in a steady turn, where the sway force vanishes at v/r = −(∂Y/∂r)/(∂Y/∂v)
    (β/r' = (v/r)/L), and T_v = M_22/|∂Y/∂v| (s), the time a sideslip takes to die away. NaN where the
    sway force does not depend on v."""
    hydro, length = compiled.hydro(), compiled.geometry.length_m
    mass = hydro.M_RB + hydro.M_A
    step = 1e-4

    def sway(v: float, r: float) -> float:
        return float((mass @ relative_acceleration(hydro, 0.0, np.array([speed_m_s, v, r]), np.zeros(3)))[1])
    dv, dr = (sway(step, 0.0) - sway(-step, 0.0)) / (2 * step), (sway(0.0, step) - sway(0.0, -step)) / (2 * step)
    if not (length > 0 and dv < 0 and np.isfinite(dr)):
        return float("nan"), float("nan")
    return abs(dr / dv) / length, float(mass[1, 1]) / abs(dv)


def straight_running(compiled: CompiledVessel, prep: Prepared, min_speed_m_s: float = STRAIGHT_SPEED_M_S
                     ) -> StraightRunning:
    """StraightRunning of the vessel at the log's median speed under way."""
    speed = np.abs(prep.u[np.isfinite(prep.u)])
    speed = speed[speed > min_speed_m_s]
    if not len(speed):
        return StraightRunning()
    c, settle = sway_balance(compiled, float(np.median(speed)))
    if not (np.isfinite(c) and np.isfinite(settle)):
        return StraightRunning()
    return StraightRunning(compiled.geometry.length_m, min(MAX_TURN_RATE, MAX_DRIFT_RAD / c) if c > 0 else MAX_TURN_RATE,
                           SETTLE_TIME_CONSTANTS * settle)


def straight_stretches(prep: Prepared, straight: StraightRunning = StraightRunning(),
                       min_speed_m_s: float = STRAIGHT_SPEED_M_S, min_stretch_s: float = MIN_STRETCH_S) -> list[slice]:
    """Runs of grid samples going straight under way (ahead or astern) as `straight` says, each at
    least min_stretch_s long and inside one segment."""
    h = prep.settings.grid_dt
    speed = np.abs(prep.u)
    ok = (speed > min_speed_m_s) & np.isfinite(prep.u) & np.isfinite(prep.v) & np.isfinite(prep.r)
    if straight.length_m > 0:
        turning = ~(np.abs(prep.r) * straight.length_m < straight.turn_rate * speed)  # NaN counts as turning
        t = np.arange(len(turning)) * h
        ok &= t - np.maximum.accumulate(np.where(turning, t, -np.inf)) > straight.settle_s
    else:
        ok &= np.abs(prep.r) < STRAIGHT_YAW_RATE_RAD_S
    out = []
    for seg in prep.segments:
        k = seg.start
        while k < seg.stop:
            if not ok[k]:
                k += 1
                continue
            j = k
            while j < seg.stop and ok[j]:
                j += 1
            if (j - k) * h >= min_stretch_s:
                out.append(slice(k, j))
            k = j
    return out


def _ground_velocity(prep: Prepared, sl: slice) -> tuple[np.ndarray, np.ndarray]:
    """NED velocity over ground (m/s) and the logged heading (rad) over one stretch."""
    psi, u, v = prep.psi[sl], prep.u[sl], prep.v[sl]
    c, s = np.cos(psi), np.sin(psi)
    return np.column_stack([c * u - s * v, s * u + c * v]), psi


def kinematic_calibrations(recordings: list[Recording], compiled: CompiledVessel, **limits) -> list[LogCalibration]:
    """Each log's own `kinematic_calibration`; a log whose straight legs point too few ways to tell
    a drift from an offset is then read with the drifts that at least two other logs of the set
    fitted on their own legs, instead of with none (a 0.25 m/s current across a boat at 1 m/s is a
    14° compass offset to a log without a drift), and with its own drift at rest where it has one
    (rest_drift): logs analysed together share their water only mostly. Under each outing's own
    wind they need not, and the log's own drift at rest then reads another offset than the borrowed
    drifts do; the spread of the readings goes into σ and the offset is not applied."""
    first = [kinematic_calibration(r, compiled, **limits) for r in recordings]
    drifts = [c.drift_ned_m_s for c in first if c.drift_ned_m_s is not None]
    if len(drifts) < 2:
        return first
    def others(c: LogCalibration) -> list[tuple[float, float]]:
        return [o.drift_ned_m_s for o in first if o is not c and o.drift_ned_m_s is not None]

    return [kinematic_calibration(r, compiled, borrowed=others(c), **limits)
            if c.drift_ned_m_s is None and c.seconds >= MIN_STRAIGHT_S else c for r, c in zip(recordings, first)]


def settle_s(compiled: CompiledVessel) -> float | None:
    """How long the vessel coasts from 1 m/s to REST_SPEED_M_S in still water, its surge row alone
    ((m − X_u̇)·u̇ = X_u·u + X_uu·u|u|, solved in closed form); None without surge damping (a ship whose
    forces the MMG model makes: rest_drift does not read it)."""
    hydro = compiled.hydro()
    m = float(hydro.M[0, 0])
    a, b = -hydro.damping.Xu / m, -hydro.damping.Xuu / m
    u0, u1 = 1.0, REST_SPEED_M_S
    if hydro.mmg is not None or a < 0 or b < 0 or (a == 0 and b == 0):
        return None
    if a == 0:
        return (1 / u1 - 1 / u0) / b
    return float(np.log(u0 * (a + b * u1) / (u1 * (a + b * u0))) / a)


def rest_drift(prep: Prepared, settle: float | None) -> tuple[float, float] | None:
    """The log's own drift at rest (NED m/s): the median velocity over ground where both thrusters
    have been idle for `settle` s (settle_s: the boat has lost its way and moves with its water and,
    pushed by it, the wind), None with less than MIN_STRAIGHT_S of such samples. A current drifts a
    boat at rest as it drifts one under way; a wind drifts it more, and downwind."""
    if settle is None or prep.input_kind != "pwm":
        return None
    idle = prep.in_deadband.all(axis=1)
    dt = prep.settings.grid_dt
    since = np.zeros(len(idle))  # seconds idle so far, restarted at every segment's start
    for seg in prep.segments:
        run = 0.0
        for i in range(seg.start, seg.stop):
            run = run + dt if idle[i] else 0.0
            since[i] = run
    rest = since > settle
    if rest.sum() * dt < MIN_STRAIGHT_S:
        return None
    c, s = np.cos(prep.psi[rest]), np.sin(prep.psi[rest])
    u, v = prep.u[rest], prep.v[rest]
    return float(np.median(c * u - s * v)), float(np.median(s * u + c * v))


def kinematic_calibration(rec: Recording, compiled: CompiledVessel, borrowed=(), at_rest: bool = True,
                          **limits) -> LogCalibration:
    """The log's compass offset relative to the vessel's common heading calibration (any per-log
    entry the vessel already holds for this log is set aside first), see LogCalibration. borrowed:
    other logs' drifts (NED m/s), at least two, taken where this log's legs cannot fit one: the
    offset read with each in turn and with the log's own drift at rest (rest_drift; at_rest=False
    leaves it out; scripts/calibration_borrowing.py compares both), their mean, and their spread added to σ."""
    name = log_name(rec.source)
    sensors = compiled.vessel.sensors
    own = dict(sensors.heading_bias_by_log_deg)
    own.pop(name, None)
    common = replace(compiled.vessel, sensors=replace(sensors, heading_bias_by_log_deg=tuple(sorted(own.items()))))
    prep = prepare_for(rec, CompiledVessel(common, compiled.model, compiled.geometry))
    straight = straight_running(compiled, prep, limits.get("min_speed_m_s", STRAIGHT_SPEED_M_S))
    stretches = straight_stretches(prep, straight, **limits)
    seconds = sum(sl.stop - sl.start for sl in stretches) * prep.settings.grid_dt
    if seconds < MIN_STRAIGHT_S:
        speed = limits.get("min_speed_m_s", STRAIGHT_SPEED_M_S)
        fast = np.abs(prep.u[np.isfinite(prep.u)])
        top = float(np.percentile(fast, 99)) if len(fast) else 0.0
        if top <= speed:  # too slow throughout: the turn rule never applied
            note = (f"no straight running under way: its |u| reaches {top:.2f} m/s (99th percentile), and below "
                    f"{speed:g} m/s the direction of the GNSS track is mostly noise")
        else:
            note = (f"{seconds:.1f} s of straight running under way (|u| > {speed:g} m/s, {straight.text()}); "
                    f"{MIN_STRAIGHT_S:g} s are needed")
        return LogCalibration(name, None, None, len(stretches), seconds, None, note)
    legs = [_ground_velocity(prep, sl) for sl in stretches]
    vel = np.concatenate([v for v, _ in legs])
    psi = np.concatenate([p for _, p in legs])
    yaw = np.concatenate([prep.r[sl] for sl in stretches])
    spread = _heading_spread_deg(np.array([np.angle(np.mean(np.exp(1j * p))) for _, p in legs]))
    piece = int(round(PIECE_S / prep.settings.grid_dt))
    which = np.concatenate([np.full(len(p), i) for i, (_, p) in enumerate(legs)]) * 10_000 + \
        np.concatenate([np.arange(len(p)) // piece for _, p in legs])
    which = np.unique(which, return_inverse=True)[1]
    with_drift = spread >= DRIFT_HEADING_SPREAD_DEG
    # the sideslip of gentle turns is told from the offset only where the yaw rate varies enough
    with_slip = len(stretches) >= 2 and float(np.std(yaw)) >= SLIP_YAW_SPREAD_RAD_S
    if not with_drift and len(borrowed) >= 2:
        return _with_borrowed(name, vel, psi, yaw if with_slip else 0.0 * yaw, which, len(stretches), seconds,
                              borrowed, spread, rest_drift(prep, settle_s(compiled)) if at_rest else None)

    def across(x):
        """Velocity across the true heading ψ_logged − δ, less the sideslip a hull takes in a gentle
        turn (proportional to r at its speed: x[1]), for a drift (x[2:4]) over ground."""
        delta, slip = x[0], (x[1] if with_slip else 0.0)
        cn, ce = (x[2], x[3]) if with_drift else (0.0, 0.0)
        true = psi - delta
        speed = np.hypot(vel[:, 0] - cn, vel[:, 1] - ce)
        return -(vel[:, 0] - cn) * np.sin(true) + (vel[:, 1] - ce) * np.cos(true) - slip * yaw * speed

    fit = least_squares(across, np.zeros(4 if with_drift else 2), loss="soft_l1", f_scale=0.05)
    delta = float(fit.x[0])
    # each piece of straight running gives the offset once: their spread is the offset's uncertainty
    drift_now = np.r_[fit.x[2:4]] if with_drift else np.zeros(2)
    speed = np.hypot(*(vel - drift_now).T)
    crab = np.arcsin(np.clip(across(np.r_[0.0, fit.x[1:]]) / speed, -1.0, 1.0))
    sigma = _piece_sigma(crab, speed, which)
    leg = np.concatenate([np.full(len(p), i) for i, (_, p) in enumerate(legs)])
    apart = float(np.degrees(_piece_sigma(crab, speed, leg))) if len(legs) >= 2 else None  # told, not applied
    drift = (float(fit.x[2]), float(fit.x[3])) if with_drift else None
    note = "" if with_drift else (f"straight legs within {spread:.0f}° of each other" if len(stretches) > 1 else
                                  "one straight leg") + ": no drift fitted (a current across it reads as offset)"
    offset_deg, sigma_deg = float(np.degrees(delta)), float(np.degrees(sigma))
    if not abs(offset_deg) >= max(SIGNIFICANT_SIGMA * sigma_deg, MIN_OFFSET_DEG):  # NaN σ: not significant
        return LogCalibration(name, None, sigma_deg, len(stretches), seconds, drift,
                              f"offset {offset_deg:+.1f}° ± {sigma_deg:.1f}° is not clearly more than a compass's "
                              f"own error (applied from {MIN_OFFSET_DEG:g}° and {SIGNIFICANT_SIGMA:g} σ)")
    return LogCalibration(name, offset_deg, sigma_deg, len(stretches), seconds, drift, note, stretch_sigma_deg=apart)


def _with_borrowed(name: str, vel, psi, yaw, which, stretches: int, seconds: float, borrowed, spread: float,
                   at_rest: tuple[float, float] | None = None) -> LogCalibration:
    """The offset across the true heading (with the sideslip of gentle turns where `yaw` varies, as
    kinematic_calibration fits it) for each borrowed drift held in turn, and for the log's own drift
    at rest (kinematic_calibrations)."""
    offsets, sigmas = [], []
    for cn, ce in list(borrowed) + ([at_rest] if at_rest is not None else []):
        over = vel - np.array([cn, ce])
        speed = np.hypot(*over.T)

        def across(x, over=over, speed=speed):
            true = psi - x[0]
            return -over[:, 0] * np.sin(true) + over[:, 1] * np.cos(true) - x[1] * yaw * speed

        fit = least_squares(across, np.zeros(2), loss="soft_l1", f_scale=0.05)
        delta = float(fit.x[0])
        crab = np.arcsin(np.clip(across(np.r_[0.0, fit.x[1]]) / speed, -1.0, 1.0))
        offsets.append(np.degrees(delta))
        sigmas.append(np.degrees(_piece_sigma(crab, speed, which)))
    offset_deg = float(np.mean(offsets))
    sigma_deg = float(np.sqrt(np.mean(np.square(sigmas)) + np.var(offsets, ddof=1)))
    drift = tuple(float(x) for x in np.mean(np.asarray(borrowed, float), axis=0))
    own = "" if at_rest is None else f" and its own at rest (N {at_rest[0]:+.3f}, E {at_rest[1]:+.3f} m/s)"
    note = (f"straight legs within {spread:.0f}° of each other: read with the drifts of {len(borrowed)} other "
            f"log{'' if len(borrowed) == 1 else 's'}{own} (offsets {min(offsets):+.1f}° to {max(offsets):+.1f}°)")
    if not abs(offset_deg) >= max(SIGNIFICANT_SIGMA * sigma_deg, MIN_OFFSET_DEG):
        return LogCalibration(name, None, sigma_deg, stretches, seconds, drift,
                              f"offset {offset_deg:+.1f}° ± {sigma_deg:.1f}° is not clearly more than a compass's "
                              f"own error (applied from {MIN_OFFSET_DEG:g}° and {SIGNIFICANT_SIGMA:g} σ); {note}",
                              len(borrowed))
    return LogCalibration(name, offset_deg, sigma_deg, stretches, seconds, drift, note, len(borrowed))


def _piece_sigma(crab_rad: np.ndarray, speed: np.ndarray, which: np.ndarray) -> float:
    """The offset's 1-σ (rad): the spread of the speed-weighted crab angles of the pieces of straight
    running, each piece giving the offset once (NaN from one piece)."""
    per_piece = [np.average(crab_rad[which == i], weights=speed[which == i]) for i in range(which.max() + 1)]
    return float(np.std(per_piece, ddof=1) / np.sqrt(len(per_piece))) if len(per_piece) > 1 else float("nan")


def _heading_spread_deg(angles_rad: np.ndarray) -> float:
    """The largest angle between two headings of the set (deg, 0-180)."""
    d = np.abs(np.angle(np.exp(1j * (angles_rad[:, None] - angles_rad[None, :]))))
    return float(np.degrees(d.max())) if len(angles_rad) > 1 else 0.0


def with_log_calibrations(vessel: Vessel, calibrations: list[LogCalibration]) -> Vessel:
    """The vessel with each log's estimated compass offset as its per-log heading bias (logs whose
    offset could not be estimated keep what the vessel says)."""
    table = dict(vessel.sensors.heading_bias_by_log_deg)
    for c in calibrations:
        if c.heading_bias_deg is not None:
            table[c.log] = c.heading_bias_deg
    return replace(vessel, sensors=replace(vessel.sensors, heading_bias_by_log_deg=tuple(sorted(table.items()))))


# ---------------------------------------------------------------- a compass that follows the throttle, from kinematics

@dataclass(frozen=True)
class ThrottleDependence:
    """Whether the compass error of straight running ahead follows the throttle (physics.sensors'
    compass_motor form, τ·(B sin ψ + C cos ψ)), read from the kinematics of a set of logs: the crab angle
    of each PIECE_S piece (logged heading less the ground track) against each log's own offset and drift
    over ground ((c_N sin ψ − c_E cos ψ)/U, a log whose straight legs point too few ways taking its
    calibration's drift instead), the sideslip of gentle turns (∝ r), and τ sin ψ, τ cos ψ. A one-cycle
    error at one speed is a drift (kinematic_calibration cannot tell them apart); the throttle, which
    grows with the speed where the drift's angle shrinks with it, can. σ from the residuals with the
    pieces of one straight stretch counted together (they share its conditions: cluster-robust)."""

    b_deg: float
    c_deg: float
    sigma_b_deg: float
    sigma_c_deg: float
    chi2: float  # of (B, C) = 0 with its two degrees of freedom
    pieces: int
    stretches: int
    logs: int

    @property
    def shown(self) -> bool:
        """(B, C) differs from zero at the 3-σ level of a two-dimensional test (χ²₂ > 13.8, p < 0.001)."""
        return self.chi2 > 13.8

    def text(self) -> str:
        return (f"compass error following the throttle: B {self.b_deg:+.1f}° ± {self.sigma_b_deg:.1f}°, C "
                f"{self.c_deg:+.1f}° ± {self.sigma_c_deg:.1f}° at full throttle (χ² {self.chi2:.1f} on 2 degrees of "
                f"freedom, {'shown' if self.shown else 'not shown'}) from {self.pieces} pieces of {self.stretches} "
                f"straight stretches ahead in {self.logs} log{'' if self.logs == 1 else 's'}")


def _throttle_pieces(prep: Prepared, vessel: Vessel, drift, compiled: CompiledVessel) -> list[tuple]:
    """(stretch, crab deg, ψ, U m/s, r, τ) of each PIECE_S piece of straight running ahead; crab = logged
    heading less the track over ground less `drift` (NED m/s)."""
    th = vessel.thrusters
    piece = int(round(PIECE_S / prep.settings.grid_dt))
    out = []
    for j, sl in enumerate(straight_stretches(prep, straight_running(compiled, prep))):
        if np.median(prep.u[sl]) <= 0:  # ahead only: astern, the water meets another hull end
            continue
        vel, psi = _ground_velocity(prep, sl)
        tau = motor_throttle(_received(th, prep.pwm[sl]), prep.pwm_neutral_us, th.pwm_min_us, th.pwm_max_us)
        for k in range(0, len(psi) - piece + 1, piece):
            w = vel[k:k + piece].mean(axis=0) - drift
            heading = float(np.angle(np.mean(np.exp(1j * psi[k:k + piece]))))
            crab = np.degrees(np.angle(np.exp(1j * (heading - np.arctan2(w[1], w[0])))))
            out.append((j, crab, heading, float(np.hypot(*w)), float(prep.r[sl][k:k + piece].mean()),
                        float(tau[k:k + piece].mean())))
    return out


def _finite_rows(pieces: list[tuple]) -> np.ndarray:
    """The pieces as an array, those with a value missing (a throttle not logged: NaN) left out: one
    NaN would leave the least squares without a solution."""
    p = np.array(pieces, float).reshape(-1, 6)
    return p[np.all(np.isfinite(p), axis=1)]


MIN_THROTTLE_STRETCHES = 10  # a cluster-robust σ from fewer clusters than this is too optimistic to test on


def throttle_dependence(preps: list[Prepared], vessel: Vessel, drifts=None) -> ThrottleDependence | None:
    """ThrottleDependence of these prepared logs (drifts: each log's calibration drift, NED m/s or None,
    used where the log cannot fit its own); None with fewer than MIN_THROTTLE_STRETCHES straight
    stretches ahead or fewer pieces than twice the unknowns."""
    blocks, y, cluster, common = [], [], [], []
    compiled = compile_vessel(vessel)
    for i, prep in enumerate(preps):
        p = _finite_rows(_throttle_pieces(prep, vessel, np.zeros(2), compiled))
        if not len(p):  # no straight running ahead, or no throttle logged (a log without thruster outputs)
            continue
        own = _heading_spread_deg(p[:, 2]) >= DRIFT_HEADING_SPREAD_DEG
        if not own and drifts is not None and drifts[i] is not None:
            p = _finite_rows(_throttle_pieces(prep, vessel, np.asarray(drifts[i], float), compiled))
        psi, speed = p[:, 2], p[:, 3]
        cols = [np.ones(len(p))] + ([np.degrees(np.sin(psi) / speed), np.degrees(-np.cos(psi) / speed)] if own else [])
        blocks.append(np.column_stack(cols))
        y.append(p[:, 1])
        cluster.append(i * 10_000 + p[:, 0])
        common.append(np.column_stack([p[:, 4], p[:, 5] * np.sin(psi), p[:, 5] * np.cos(psi)]))
    if not y:
        return None
    common = np.vstack(common)
    if np.std(common[:, 0]) < SLIP_YAW_SPREAD_RAD_S:  # straight running so straight that no sideslip is left to fit
        common = common[:, 1:]
    x = np.hstack([block_diag(*blocks), common])
    y, cluster = np.concatenate(y), np.concatenate(cluster)
    if len(np.unique(cluster)) < MIN_THROTTLE_STRETCHES or len(y) < 2 * x.shape[1] or \
            np.linalg.matrix_rank(x) < x.shape[1]:
        return None
    beta, *_ = np.linalg.lstsq(x, y, rcond=None)
    res = y - x @ beta
    bread = np.linalg.inv(x.T @ x)
    scores = [x[cluster == c].T @ res[cluster == c] for c in np.unique(cluster)]
    cov = bread @ sum(np.outer(g, g) for g in scores) @ bread
    bc, cbc = beta[-2:], cov[-2:, -2:]
    return ThrottleDependence(float(bc[0]), float(bc[1]), float(np.sqrt(cbc[0, 0])), float(np.sqrt(cbc[1, 1])),
                              float(bc @ np.linalg.solve(cbc, bc)), len(y), len(scores), len(blocks))
