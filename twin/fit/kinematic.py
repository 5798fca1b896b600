"""What a recording's own kinematics and timing tell of its sensors and clocks, without a dynamic
model: where the GNSS antenna sits, whether the input log, the heading or the GNSS fixes are late. A twin's form
error cannot reach these estimates, so a diagnosis can name such effects, and put them in before it
fits anything, where its dynamic search would find them buried under that error.

Antenna (lever_arm). A point p of the hull (body x forward, y to starboard) moves over ground as
the hull's reference point plus R(ψ)·p. Within a few seconds the reference point's track is smooth
(a position, a velocity and an acceleration: the hull's mass bounds how fast its velocity changes),
while R(ψ)·p swings round with every large change of heading: in windows of WINDOW_S in which the
heading turns by MIN_TURN_DEG or more at under SPIN_SPEED_M_S over ground (spins), the antenna's fixes
less a quadratic in
time per window leave R(ψ)·p, one p for the whole recording. Only windows in which the hull turns
nearly on the spot count: under way it turns on a circle of radius U/r, which a quadratic follows only
to about (U/r)·Δψ³/120 (kept under TRACK_TOLERANCE_M). What is measured is the antenna
against the point the hull turns about at those rates, which for a hull that is symmetric fore and
aft and spins on its thrusters is its middle: the twin's reference point. A hull that creeps ahead
while it spins (a thruster's reverse thrust weaker than its forward) moves by a body velocity that
is the same for spins of either hand, which looks like an antenna to one side whose side flips
with the hand of the spin: with spins of both hands (MIN_WINDOWS_EACH_HAND each) it is fitted beside
p (as u_c per unit of the turn's sign). A creep also carries a sideslip (the sway balance of the
Munk term, v ≈ −m11·u·r/|Yv| in a steady turn), and the point the hull turns about moves along it
by −v/r, the creep per unit rate times m11·r/|Yv|, which rests on a sway damping the kinematics do
not know: that is the same for spins of either hand, as an antenna is, and no kinematics tell them
apart. So the antenna is named only from spins of both hands
in which the creep is shown (its 3-σ bound) under MIN_ARM_M, the smallest antenna told; with spins of one hand only, or
a hull that creeps, it is not told. It is never named from the dynamics (diagnose).

Timing (input_timing). After a step of the inputs the hull answers at once with an acceleration
(a thruster's known lag aside): the heading (or the integrated gyro) and the GNSS fixes in a short
window around each step are fitted with a template, the input's force shifted by s seconds, through
the twin's thrust map and lag, into a first-order response (a Nomoto model, its gain and time
constant free per event, the time constant on a grid) plus the state before the step. Each event's
best s is its own estimate; the median over events is the estimate and its robust 1-σ from their
spread. Only events whose template removes at least MIN_EVENT_GAIN of what a quadratic in time
leaves are counted: the others are steps the controller made in answer to the motion (closed loop),
where the input follows the motion rather than leading it. The surge answers through the GNSS
(forward thrust, projected on the heading; the fixes' swing R(ψ)·p about the hull for an antenna p
anywhere on it is fitted beside, so where the antenna sits does not move the answer), the yaw through
the heading, or the gyro where the log has one. An input log late by d moves both answers by +d; a
heading late by L moves the heading's answer by −L and not the surge's; the gyro, where there is
one, tells the heading's lateness directly (prepare.timing) and its answer then carries the input's
timing alone. GNSS fixes stamped
late move the surge's answer alone. Relative timing is
all a log can tell: a heading late by L is the GNSS and the input early by as much, so the reading
is the one that explains the answers with one late stream. A heading or a fix is named late, never
early: a filter or a receiver delays, it cannot lead. An input log is named late only: motion that
answers later than the twin expects may as well be a thrust lag or an ESC's delay the twin lacks,
which the diagnosis's search tells apart.

A shift is named only when it exceeds TIMING_FLOOR_SAMPLES sample periods of the streams compared
(by half a step of the grid the shifts are read on: a shift read at the floor is the resolution) and
three σ: a log whose streams are stamped at 10 Hz carries no timing finer than that. Results are
relative to the twin given: its antenna offset, thrust lag, input delay and sensor latencies are
taken as they are, and what is found is what they lack. The template is not the twin's dynamics
(a free first-order response against its thrust lag), so even on the runs a twin was fitted on the
answers need not come at zero: `twin identify` measures them there (Sensors.input_answer_s, per
degree of freedom) and other runs are read against that zero.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.signal import lfilter

from ..effects import apply_effects
from ..engine.mjcf import CompiledVessel, compile_vessel
from ..physics.sensors import antenna_body_m, antenna_ned
from ..prepare.prepared import local_ned
from ..prepare.timing import STEP_S as GYRO_STEP_S
from ..prepare.timing import heading_lag
from ..recording import EXACT_ORIGIN, TRACKED_ORIGIN, Recording
from ..vessel import Vessel
from .calibrate import calibrated

WINDOW_S = 3.0  # a spin's window: long enough to swing the heading, short enough for a quadratic track
WINDOW_STEP_S = 1.5
MIN_TURN_DEG = 30.0
SPIN_SPEED_M_S = 0.5  # turning on the spot: faster over ground, a window's track is metres long and its
# curvature, not the antenna, decides what a quadratic leaves
GROUP_S = 8.0  # windows are left out together within this span (jackknife): overlapping neighbours share fixes
MIN_GROUPS = 4
MIN_WINDOWS_EACH_HAND = 3
MIN_ARM_M = 0.10  # an antenna closer than this to where the twin has it moves a 0.5-rad/s spin's fix by 5 cm/s
TRACK_TOLERANCE_M = MIN_ARM_M / 2
TIMING_FLOOR_SAMPLES = 1.5
PRE_S, POST_S = 1.5, 1.5  # an event's window around the input step: short after it, where the onset decides
SHIFT_MAX_S, SHIFT_STEP_S = 1.2, 0.02
FINE_S = 0.01
TIME_CONSTANTS_S = tuple(round(0.05 * 2 ** (k / 2), 3) for k in range(13)) + (math.inf,)  # 0.05-3.2 s, steps of √2
STEP_SHARE = 0.15  # an input step: a change of this share of the input's largest force in one sample
MIN_EVENT_GAIN = 0.8
MIN_EVENTS = 5


@dataclass(frozen=True)
class KinematicFinding:
    """One effect as the kinematics or timing tell it: `values` in the library's terms for the
    twin (its current value plus what it lacks), `change` what the twin lacks, their 1-σ; `told`:
    named; `absent`: not told, though the kinematics would have told it at the floor (3 σ within
    it): a diagnosis need not search for it, as its dynamics would measure it worse; `why`: how, or
    why not; `basis`: what it rests on."""

    effect: str
    values: dict[str, float]
    change: dict[str, float]
    sigma: dict[str, float | None]
    told: bool
    absent: bool
    why: str
    basis: str = ""
    detail: dict = field(default_factory=dict)

    def effect_params(self) -> dict[str, float]:
        return dict(self.values)

    def text(self) -> str:
        # a value read with no σ is no reading: a finding not told says only why
        vals = ", ".join(f"{k} {v:+.3g}" + (f" ± {self.sigma[k]:.2g}" if self.sigma.get(k) else "")
                         for k, v in self.change.items() if self.told or self.sigma.get(k))
        state = "named" if self.told else ("not there" if self.absent else "not told")
        return f"{self.effect} from kinematics: {state} ({'; '.join(x for x in (vals, self.why) if x)})"

    def to_dict(self) -> dict:
        return {"effect": self.effect, "values": self.values, "change": self.change, "sigma": self.sigma,
                "told": self.told, "absent": self.absent, "why": self.why, "basis": self.basis,
                "detail": self.detail}


# ---------------------------------------------------------------- the antenna

def _fresh_fixes(rec: Recording, latency_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, north, east) of the fixes a logger recorded anew (a repeat carries no new time), each at
    the time it was taken (the twin's GNSS latency)."""
    n, e, _ = local_ned(rec.gnss)
    t = np.asarray(rec.gnss.t, float)
    new = np.r_[True, (np.diff(n) != 0) | (np.diff(e) != 0)]
    ok = new & np.isfinite(n) & np.isfinite(e)
    return t[ok] - latency_s, n[ok], e[ok]


def _heading_at(rec: Recording, t: np.ndarray, latency_s: float) -> np.ndarray:
    psi = np.unwrap(np.asarray(rec.heading["psi_rad"], float))
    return np.interp(t, np.asarray(rec.heading.t, float) - latency_s, psi)


def _spin_windows(rec: Recording, vessel: Vessel, site_m: tuple[float, float] | None = None) -> list[tuple]:
    """(group, hand, design (2n, 3), observation (2n,)) of each window of a large heading change, the
    quadratic track of the window projected out: columns R(ψ)·e_x, R(ψ)·e_y, R(ψ)·e_y·hand. site_m:
    (x, y) m added to every fix as R(ψ)·site_m (a track given as the body origin's, read as if taken
    at the antenna site, as a receiver's fixes are)."""
    s = vessel.sensors.for_log(rec.source)
    rec = calibrated(rec, vessel)
    t, n, e = _fresh_fixes(rec, s.gnss_latency_s)
    if len(t) < 8:
        return []
    psi = _heading_at(rec, t, s.heading_latency_s)
    if site_m is not None:
        n, e = antenna_ned(n, e, psi, site_m)
    period = float(np.median(np.diff(t)))
    out = []
    for a in np.arange(t[0], t[-1] - WINDOW_S, WINDOW_STEP_S):
        m = (t >= a) & (t < a + WINDOW_S)
        if m.sum() < 8 or np.max(np.diff(t[m])) > 3 * period:
            continue
        turned = psi[m][-1] - psi[m][0]
        if abs(turned) < math.radians(MIN_TURN_DEG) or np.ptp(psi[m]) < math.radians(MIN_TURN_DEG):
            continue
        tt = t[m] - a
        # a hull under way turns on a circle of radius U/r, which a quadratic in time follows to about
        # (U/r)·Δψ³/120 (the cubic's part a quadratic leaves over the window): the window is kept
        # where that is well under the smallest antenna told
        speed = float(np.sum(np.hypot(np.diff(n[m]), np.diff(e[m])))) / WINDOW_S
        swing = abs(turned)
        if speed > SPIN_SPEED_M_S or speed / (swing / WINDOW_S) * swing ** 3 / 120.0 > TRACK_TOLERANCE_M:
            continue
        poly = np.column_stack([np.ones_like(tt), tt, tt * tt])
        proj = np.eye(len(tt)) - poly @ np.linalg.pinv(poly)
        c, sn = np.cos(psi[m]), np.sin(psi[m])
        hand = float(np.sign(turned))
        design = np.vstack([proj @ np.column_stack([c, -sn, -sn * hand]), proj @ np.column_stack([sn, c, c * hand])])
        out.append((int(a // GROUP_S), hand, design, np.r_[proj @ n[m], proj @ e[m]]))
    return out


def lever_arm(recordings: list[Recording], vessel: Vessel, compiled: CompiledVessel | None = None
              ) -> KinematicFinding:
    """Where the GNSS antenna sits against where the twin has it (module docstring): the
    `gnss_lever_arm` the twin lacks. A simulated run's exact track of the body origin has no antenna
    and is left out; a track a log gives as the body origin's (TRACKED_ORIGIN), where the twin has the
    point tracked at its sensors' offset from the origin, is read as if taken at the MJCF antenna
    site, so that every log tells the same site plus offset."""
    compiled = compiled or compile_vessel(vessel)
    offset = tuple(map(float, vessel.sensors.antenna_offset_m))
    have = antenna_body_m(compiled.geometry.gnss_pos_m, vessel.sensors)
    site = tuple(map(float, compiled.geometry.gnss_pos_m[:2]))
    windows = []
    for k, rec in enumerate(r for r in recordings if r.meta.get("positions") != EXACT_ORIGIN):
        if len(rec.gnss) and len(rec.heading):
            site_m = site if rec.meta.get("positions") == TRACKED_ORIGIN else None
            windows += [(k * 100_000 + g, hand, d, y) for g, hand, d, y in _spin_windows(rec, vessel, site_m)]
    hands = {h: sum(1 for _, hh, _, _ in windows if hh == h) for h in (-1.0, 1.0)}
    groups = sorted({g for g, _, _, _ in windows})
    both = min(hands.values()) >= MIN_WINDOWS_EACH_HAND
    basis = (f"{len(windows)} windows of {WINDOW_S:g} s turning {MIN_TURN_DEG:g}° or more ({hands[1.0]} to starboard, "
             f"{hands[-1.0]} to port) in {len(groups)} groups")

    def finding(change, sigma, told, absent, why, detail=None):
        values = {"dx_m": offset[0] + change.get("dx_m", 0.0), "dy_m": offset[1] + change.get("dy_m", 0.0)}
        return KinematicFinding("gnss_lever_arm", values, change, sigma, told, absent, why, basis, detail or {})

    if len(groups) < MIN_GROUPS:
        return finding({}, {}, False, False, f"{len(groups)} group{'' if len(groups) == 1 else 's'} of large heading changes; "
                       f"{MIN_GROUPS} are needed")
    if not both:
        return finding({}, {}, False, False, f"spins of one hand only ({MIN_WINDOWS_EACH_HAND} of each are needed): "
                       "a creep through the water cannot be told from the antenna")

    def solve(items):
        d = np.vstack([w[2] for w in items])
        y = np.concatenate([w[3] for w in items])
        return np.linalg.lstsq(d, y, rcond=None)[0]

    p = solve(windows)
    left_out = np.array([solve([w for w in windows if w[0] != g]) for g in groups])
    m = len(groups)
    cov = (m - 1) / m * (left_out - left_out.mean(0)).T @ (left_out - left_out.mean(0))
    sig = np.sqrt(np.diag(cov))
    delta = p[:2] - have
    chi2 = float(delta @ np.linalg.solve(cov[:2, :2], delta))
    change = {"dx_m": float(delta[0]), "dy_m": float(delta[1])}
    sigma = {"dx_m": float(sig[0]), "dy_m": float(sig[1])}
    size = float(np.hypot(*delta))
    # a hull creeping through the water while it spins sideslips by the Munk moment's partner (sway
    # m11·u·r/|Yv|), which moves the point it turns about along it by the creep per unit rate times
    # m11·r/|Yv|, a sway damping the kinematics do not know: the antenna is read against the hull's
    # middle only where the creep is shown smaller than the smallest antenna told (its 3-σ bound)
    creep_bound = abs(float(p[2])) + 3 * float(sig[2])
    still = creep_bound <= MIN_ARM_M
    detail = {"antenna_body_m": [float(p[0]), float(p[1])], "twin_antenna_body_m": [float(have[0]), float(have[1])],
              "creep_m_s_per_rad_s": float(p[2]), "creep_bound_m": creep_bound, "chi2": chi2}
    if not still:
        return finding(change, sigma, False, False, f"{size:.2f} m, but the hull creeps while it spins "
                       f"({float(p[2]):+.2f} ± {float(sig[2]):.2f} m/s per rad/s): its sideslip moves the point it "
                       "turns about", detail)
    if chi2 >= 13.8 and size >= MIN_ARM_M:  # χ²₂ at p 0.001
        return finding(change, sigma, True, False, f"χ² {chi2:.1f} against the twin's antenna", detail)
    absent = 3 * float(max(sig[0], sig[1])) <= MIN_ARM_M  # an antenna MIN_ARM_M off would have been told
    return finding(change, sigma, False, absent, f"χ² {chi2:.1f}, {size:.2f} m: within the noise or under "
                   f"{MIN_ARM_M:g} m", detail)


# ---------------------------------------------------------------- input and heading timing

@dataclass(frozen=True)
class Answer:
    """One degree of freedom's answer to the input steps: the median shift (s, > 0: the motion
    answers the input logged later, i.e. the input log is late) over the events counted, its robust
    1-σ, how many events were counted of how many steps."""

    dof: str
    shift_s: float | None
    sigma_s: float | None
    events: int
    steps: int
    time_constant_s: float | None = None  # the events' median best time constant of the response

    def to_dict(self) -> dict:
        return {"dof": self.dof, "shift_s": self.shift_s, "sigma_s": self.sigma_s, "events": self.events,
                "steps": self.steps, "time_constant_s": self.time_constant_s}

    def against(self, zero_s: float) -> "Answer":
        """The answer read against `zero_s` (the twin's own runs' answer) rather than against 0."""
        return self if self.shift_s is None else replace(self, shift_s=self.shift_s - zero_s)


def _input_force(rec: Recording, vessel: Vessel) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(t on a FINE_S grid of the input log's clock, surge force, yaw moment) in the twin's terms, up
    to a scale each: PWM through the thrust map, gains and first-order lag; a propeller and rudder as
    n|n| and the rudder angle (each event fits its own gain)."""
    th = vessel.thrusters
    if len(rec.pwm):
        t = np.asarray(rec.pwm.t, float)
        pwm = np.column_stack([rec.pwm["left_us"], rec.pwm["right_us"]])
        if th.kind != "t200":
            return None
        thrust = th.thrust_from_pwm(pwm) * np.array([th.gain_left, th.gain_right])
        surge, yaw = thrust.sum(axis=1), thrust[:, 0] - thrust[:, 1]
    elif len(rec.prop_rudder):
        t = np.asarray(rec.prop_rudder.t, float)
        n = np.asarray(rec.prop_rudder["n_rps"], float)
        surge, yaw = n * np.abs(n), np.asarray(rec.prop_rudder["delta_rad"], float)
    else:
        return None
    ok = np.isfinite(surge) & np.isfinite(yaw)
    t, surge, yaw = t[ok], surge[ok], yaw[ok]
    if len(t) < 10:
        return None
    fine = np.arange(t[0], t[-1], FINE_S)
    i = np.clip(np.searchsorted(t, fine, side="right") - 1, 0, len(t) - 1)
    force = np.column_stack([surge[i], yaw[i]])
    if len(rec.pwm) and th.lag_s > 0:
        a = 1.0 - math.exp(-FINE_S / th.lag_s)
        force = lfilter([a], [1.0, a - 1.0], force, axis=0, zi=(1 - a) * force[:1])[0]
    return fine, force[:, 0], force[:, 1]


def _steps(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Times of the input's steps: a change of STEP_SHARE of its largest magnitude within one logged
    sample, one per POST_S."""
    scale = float(np.max(np.abs(x))) if len(x) else 0.0
    if scale <= 0:
        return np.zeros(0)
    sample = int(round(0.1 / FINE_S))
    jump = np.abs(x[sample:] - x[:-sample]) >= STEP_SHARE * scale
    idx = np.flatnonzero(jump & ~np.r_[False, jump[:-1]]) + sample
    out: list[float] = []
    for k in idx:
        if not out or t[k] - out[-1] > POST_S:
            out.append(float(t[k]))
    return np.array(out)


def _lowpass(x: np.ndarray, tau_s: float) -> np.ndarray:
    """A first-order lag of time constant tau_s along the last axis, from rest at the first value."""
    if not math.isfinite(tau_s):
        return x
    a = 1.0 - math.exp(-FINE_S / tau_s)
    zi = (1 - a) * x[..., :1]
    return lfilter([a], [1.0, a - 1.0], x, axis=-1, zi=zi)[0]


def _event_costs(t_obs: np.ndarray, obs: np.ndarray, t_in: np.ndarray, drive: np.ndarray, event: float,
                 shifts: np.ndarray, direction: np.ndarray | None) -> tuple[np.ndarray, float] | None:
    """Residual sums of squares of one event's template for every time constant and shift (rows,
    columns), and of the state before the step alone (a constant acceleration). obs: (n,) heading,
    or (n, 2) north and east with `direction` the heading on the fine grid (the thrust pushes along
    it)."""
    m = (t_obs >= event - PRE_S) & (t_obs <= event + POST_S)
    if m.sum() < 8 or event - PRE_S - SHIFT_MAX_S < t_in[0] or event + POST_S + SHIFT_MAX_S > t_in[-1]:
        return None
    grid = np.arange(event - PRE_S, event + POST_S + FINE_S / 2, FINE_S)
    tg = grid - grid[0]
    t = t_obs[m] - grid[0]
    # linear interpolation from the fine grid to the observation times
    k = np.clip(np.searchsorted(tg, t, side="right") - 1, 0, len(tg) - 2)
    w = (t - tg[k]) / FINE_S

    def at(x):  # rows of x on the fine grid, at the observation times
        return x[:, k] * (1.0 - w) + x[:, k + 1] * w
    if direction is not None:
        c, sn = np.cos(direction), np.sin(direction)
        y = np.r_[obs[m, 0], obs[m, 1]]
        ones, zeros = np.ones_like(t), np.zeros_like(t)
        # R(ψ)·p of an antenna p anywhere on the hull: its swing in a turn is not the surge's answer
        psi = at(direction[None, :])[0]
        nuisance = [np.r_[ones, zeros], np.r_[zeros, ones], np.r_[t, zeros], np.r_[zeros, t],
                    np.r_[np.cos(psi), np.sin(psi)], np.r_[-np.sin(psi), np.cos(psi)]]

        def along(x):  # the track of speeds x (rows) along the heading
            x = np.atleast_2d(x)
            return np.hstack([at(np.cumsum(x * c, axis=1) * FINE_S), at(np.cumsum(x * sn, axis=1) * FINE_S)])
    else:
        y = obs[m]
        nuisance = [np.ones_like(t)]

        def along(x):  # the heading of yaw rates x (rows)
            return at(np.cumsum(np.atleast_2d(x), axis=1) * FINE_S)

    def projector(cols):
        b = np.column_stack(cols)
        return np.eye(len(y)) - b @ np.linalg.pinv(b)

    steady, ramp = along(np.ones_like(tg))[0], along(tg)[0]
    q = projector(nuisance + [steady, ramp])
    quad = float(y @ q @ y)
    drives = np.interp(grid[None, :] + shifts[:, None], t_in, drive)
    drives -= drives[:, :1]
    costs = np.full((len(TIME_CONSTANTS_S), len(shifts)), np.inf)
    for j, tau in enumerate(TIME_CONSTANTS_S):
        q = projector(nuisance + [steady, along(np.exp(-tg / tau))[0] if math.isfinite(tau) else ramp])
        qy = q @ y
        response = _lowpass(drives, tau) if math.isfinite(tau) else np.cumsum(drives, axis=1) * FINE_S
        a = along(response) @ q
        norm = np.einsum("ij,ij->i", a, a)
        costs[j] = float(qy @ qy) - np.where(norm > 0, (a @ qy) ** 2 / np.where(norm > 0, norm, 1.0), 0.0)
    return costs, quad


def _answer(dof: str, per_event: list[tuple[np.ndarray, float]], shifts: np.ndarray, steps: int) -> Answer:
    """The median of the events' best shifts, each at its own best time constant: a controller that
    limits the turn rate or the speed makes the response's time differ from event to event."""
    clear = [(c, quad) for c, quad in per_event if quad > 0 and 1.0 - float(np.min(c)) / quad >= MIN_EVENT_GAIN]
    if len(clear) < MIN_EVENTS:
        return Answer(dof, None, None, len(clear), steps)
    best = [float(shifts[int(np.argmin(np.min(c, axis=0)))]) for c, _ in clear]
    shared = int(np.median([np.argmin(np.min(c, axis=1)) for c, _ in clear]))
    b = np.array(best)
    med = float(np.median(b))
    mad = float(np.median(np.abs(b - med)))
    sigma = max(1.2533 * 1.4826 * mad / math.sqrt(len(b)), SHIFT_STEP_S / 2)
    return Answer(dof, med, sigma, len(b), steps, TIME_CONSTANTS_S[shared])


def _answers(recordings: list[Recording], vessel: Vessel) -> tuple[Answer, Answer, bool, float]:
    """The surge's and the yaw's answers pooled over the recordings, whether the yaw was read from a
    gyro, and the coarsest sample period of the streams compared."""
    shifts = np.round(np.arange(-SHIFT_MAX_S, SHIFT_MAX_S + SHIFT_STEP_S / 2, SHIFT_STEP_S), 4)
    surge_events, yaw_events, n_surge, n_yaw = [], [], 0, 0
    gyro = all(len(r.imu) and "yaw_rate_rads" in r.imu.columns for r in recordings)
    periods = {"input": 0.0, "heading": 0.0}
    for rec in recordings:
        if not (len(rec.gnss) and len(rec.heading)):
            continue
        forces = _input_force(rec, vessel)
        if forces is None:
            continue
        s = vessel.sensors.for_log(rec.source)
        rec = calibrated(rec, vessel)
        # the twin's own timing: its input delay and clock offset move what it drives with
        lookup = s.pwm_clock_offset_s - vessel.thrusters.delay_s
        t_in, surge, yaw = forces
        t_in = t_in - lookup
        periods["heading"] = max(periods["heading"], _period(rec.heading.t))
        periods["input"] = max(periods["input"], _period(rec.pwm.t if len(rec.pwm) else rec.prop_rudder.t))
        if gyro:
            tg = np.asarray(rec.imu.t, float)
            rate = np.asarray(rec.imu["yaw_rate_rads"], float)
            ok = np.isfinite(rate)
            t_yaw, heading = tg[ok], np.r_[0.0, np.cumsum(0.5 * (rate[ok][1:] + rate[ok][:-1]) * np.diff(tg[ok]))]
        else:
            t_yaw = np.asarray(rec.heading.t, float) - s.heading_latency_s
            heading = np.unwrap(np.asarray(rec.heading["psi_rad"], float))
        t_fix, n, e = _fresh_fixes(rec, s.gnss_latency_s)
        fix_heading = _heading_at(rec, t_fix, s.heading_latency_s)
        for ev in _steps(t_in, yaw):
            n_yaw += 1
            c = _event_costs(t_yaw, heading, t_in, yaw, ev, shifts, None)
            if c is not None:
                yaw_events.append(c)
        for ev in _steps(t_in, surge):
            n_surge += 1
            grid = np.arange(ev - PRE_S, ev + POST_S + FINE_S / 2, FINE_S)
            c = _event_costs(t_fix, np.column_stack([n, e]), t_in, surge, ev, shifts,
                             np.interp(grid, t_fix, fix_heading))
            if c is not None:
                surge_events.append(c)
    return (_answer("surge", surge_events, shifts, n_surge), _answer("yaw", yaw_events, shifts, n_yaw), gyro,
            periods)


def _period(t) -> float:
    t = np.asarray(t, float)
    return float(np.median(np.diff(t))) if len(t) > 2 else 0.0


def input_answers(recordings: list[Recording], vessel: Vessel) -> tuple[float, float]:
    """(surge, yaw) s: how far the hull's answers to the input steps of `recordings` lead the twin's
    own timing, as Sensors.input_answer_s keeps them for the runs a twin is identified on. A degree of
    freedom with too few clear answers takes the other's (the input's timing is common to both);
    with neither, (0, 0)."""
    surge, yaw = _answers(recordings, vessel)[:2]
    a, b = surge.shift_s, yaw.shift_s
    if a is None and b is None:
        return 0.0, 0.0
    return round(float(b if a is None else a), 3), round(float(a if b is None else b), 3)


def input_timing(recordings: list[Recording], vessel: Vessel) -> tuple[KinematicFinding, ...]:
    """(clock_offset, heading_latency, gnss_latency) as the timing of the hull's answers to the input
    steps tells them (module docstring), relative to the twin's own timing and read against its own
    runs' answers (Sensors.input_answer_s)."""
    surge, yaw, gyro, periods = _answers(recordings, vessel)
    zero_surge, zero_yaw = vessel.sensors.input_answer_s
    surge, yaw = surge.against(zero_surge), yaw.against(zero_yaw)
    # a stamp is good to a sample period of its own stream: the input log's for the clock, the
    # heading's for its lateness
    floor = TIMING_FLOOR_SAMPLES * (max(periods["input"], periods["heading"]) or 0.1)
    # a shift exceeds the floor by half a step of the grid the events' shifts are read on: one read at
    # the floor itself is the resolution, not a lateness
    above = floor + SHIFT_STEP_S / 2
    s = vessel.sensors
    basis = (f"surge: {surge.events} of {surge.steps} input steps answered clearly; yaw ({'gyro' if gyro else 'heading'}): "
             f"{yaw.events} of {yaw.steps}")
    if zero_surge or zero_yaw:  # a twin identify wrote: its own runs' answers are the zero (module docstring)
        basis += (f"; read against the twin's answers on the runs it was fitted on (surge {zero_surge:+.2f} s, "
                  f"yaw {zero_yaw:+.2f} s)")
    detail = {"surge": surge.to_dict(), "yaw": yaw.to_dict(), "gyro": gyro, "floor_s": floor}

    def finding(effect, key, now, change, sigma, told, absent, why):
        return KinematicFinding(effect, {key: now + change}, {key: change}, {key: sigma}, told, absent, why, basis,
                                detail)

    def clock(change, sigma, told, absent, why):
        return finding("clock_offset", "pwm_clock_offset_s", s.pwm_clock_offset_s, change, sigma, told, absent, why)

    def late(change, sigma, told, absent, why):
        return finding("heading_latency", "heading_latency_s", s.heading_latency_s, change, sigma, told, absent, why)

    def fix_late(change, sigma, told, absent, why):
        return finding("gnss_latency", "gnss_latency_s", s.gnss_latency_s, change, sigma, told, absent, why)

    def sure(x, sig):
        return x is not None and abs(x) > above and abs(x) > 3 * sig

    def later(x, sig):  # a filter or a receiver delays, it never leads: an early stream is not named
        return sure(x, sig) and x > 0

    def leads(x, sig):
        # the motion answering before the logged input: only a late log does that, while an answer
        # that comes late is as well a thrust lag or an ESC's delay the twin lacks (the search's to tell)
        return sure(x, sig) and x > 0

    def nil(x, sig):  # not told, though the answers would have told a shift of the floor's size
        return x is not None and sig is not None and 3 * sig <= floor and not sure(x, sig)

    heading = _gyro_heading(recordings, vessel, floor) if gyro else None
    if surge.shift_s is None or yaw.shift_s is None:
        why = "too few input steps answered clearly in " + " and ".join(
            a.dof for a in (surge, yaw) if a.shift_s is None) + ": which stream is late cannot be told"
        answer = next((a for a in (surge, yaw) if a.shift_s is not None), None)
        # one answer alone still tells an input log late where the motion leads it (no stream's
        # lateness makes the motion lead), and the gyro's answer is the input's timing alone
        if answer is not None and (leads(answer.shift_s, answer.sigma_s) or (gyro and answer is yaw)):
            text = (f"the {answer.dof} ({'gyro' if gyro and answer is yaw else 'heading' if answer is yaw else 'GNSS'}) "
                    f"answers {answer.shift_s:+.2f} ± {answer.sigma_s:.2f} s (floor {floor:.2f} s); {why}")
            return (clock(answer.shift_s, answer.sigma_s, leads(answer.shift_s, answer.sigma_s),
                          gyro and answer is yaw and nil(answer.shift_s, answer.sigma_s), text),
                    heading or late(0.0, None, False, False, why), fix_late(0.0, None, False, False, why))
        return (clock(0.0, None, False, False, why), heading or late(0.0, None, False, False, why),
                fix_late(0.0, None, False, False, why))
    # the surge answers through the GNSS, the yaw through the heading (or the gyro): an input log late
    # moves both, a late heading the yaw's alone (not with a gyro), a late receiver the surge's alone
    diff = surge.shift_s - yaw.shift_s
    sig_d = math.hypot(surge.sigma_s, yaw.sigma_s)
    agree = abs(diff) <= max(above, 3 * sig_d)
    w = np.array([1 / surge.sigma_s ** 2, 1 / yaw.sigma_s ** 2])
    both = float((w[0] * surge.shift_s + w[1] * yaw.shift_s) / w.sum())
    sig_b = float(1 / math.sqrt(w.sum()))
    text = (f"surge answers {surge.shift_s:+.2f} ± {surge.sigma_s:.2f} s, yaw ({'gyro' if gyro else 'heading'}) "
            f"{yaw.shift_s:+.2f} ± {yaw.sigma_s:.2f} s (floor {floor:.2f} s)")
    if agree:
        return (clock(both, sig_b, leads(both, sig_b), nil(both, sig_b), text),
                heading or late(diff, sig_d, False, nil(diff, sig_d), text),
                fix_late(-diff, sig_d, False, nil(diff, sig_d), text))
    on_time_surge = abs(surge.shift_s) <= max(above, 3 * surge.sigma_s)
    on_time_yaw = abs(yaw.shift_s) <= max(above, 3 * yaw.sigma_s)
    if diff > 0 and on_time_surge and not gyro:  # the yaw answers late: the heading is
        return (clock(surge.shift_s, surge.sigma_s, False, nil(surge.shift_s, surge.sigma_s), text),
                late(diff, sig_d, later(diff, sig_d), False, text), fix_late(0.0, None, False, False, text))
    if diff < 0 and on_time_yaw:  # the surge answers late: the GNSS fixes are
        return (clock(yaw.shift_s, yaw.sigma_s, False, nil(yaw.shift_s, yaw.sigma_s), text),
                heading or late(0.0, None, False, False, text), fix_late(-diff, sig_d, later(-diff, sig_d), False, text))
    return (clock(surge.shift_s, surge.sigma_s, leads(surge.shift_s, surge.sigma_s), False, text),
            heading or late(diff, sig_d, later(diff, sig_d) and not gyro, False, text),
            fix_late(0.0, None, False, False, text))


def _gyro_heading(recordings: list[Recording], vessel: Vessel, floor: float) -> KinematicFinding:
    """heading_latency from each log's heading against its gyro, pooled (inverse variance)."""
    s = vessel.sensors
    lags = [heading_lag(r) for r in recordings]
    got = [g for g in lags if g.lag_s is not None and g.sigma_s]
    basis = f"heading against the gyro in {len(got)} of {len(recordings)} logs"
    if not got:
        why = "; ".join(sorted({g.note or "too few pieces of the log to give the lag's spread" for g in lags}))
        return KinematicFinding("heading_latency", {"heading_latency_s": s.heading_latency_s},
                                {"heading_latency_s": 0.0}, {"heading_latency_s": None}, False, False, why, basis)
    w = np.array([1 / g.sigma_s ** 2 for g in got])
    lag = float(np.sum(w * [g.lag_s for g in got]) / w.sum())
    sig = float(1 / math.sqrt(w.sum()))
    change = lag - s.heading_latency_s
    told = abs(change) > floor + GYRO_STEP_S / 2 and abs(change) > 3 * sig and lag > 0
    absent = not told and 3 * sig <= floor
    return KinematicFinding("heading_latency", {"heading_latency_s": lag}, {"heading_latency_s": change},
                            {"heading_latency_s": sig}, told, absent,
                            f"the heading is {lag:+.2f} ± {sig:.2f} s late against the gyro (floor {floor:.2f} s)",
                            basis, {"logs": [g.lag_s for g in got]})


def kinematic_findings(recordings: list[Recording], vessel: Vessel) -> list[KinematicFinding]:
    """Every sensor and timing effect the recordings' kinematics can tell, against the twin `vessel`:
    the antenna, the input log's clock, the heading's and the GNSS fixes' lateness (each finding's
    values are the vessel's own plus what it lacks)."""
    timing = list(input_timing(recordings, vessel))
    # the antenna is read with the heading and the clocks as the timing tells them: a late heading
    # turns every spin's fixes by the turn of its lateness
    timed = with_findings(vessel, timing)
    return [lever_arm(recordings, timed, compile_vessel(timed))] + timing


def with_findings(vessel: Vessel, findings: list[KinematicFinding]) -> Vessel:
    """The vessel with every told finding's values put in (its sensors)."""
    told = [(f.effect, f.effect_params()) for f in findings if f.told]
    return apply_effects(vessel, told) if told else replace(vessel)
