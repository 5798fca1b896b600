"""I-PD dynamic-positioning control tuned from IS-O [Relay-ISO §IV, eqs. 9-11, Fig. 6].

Per DOF, with the IS-O linear (constant-drag) model α ν̇ + β ν = τ:

    τ = K_I ∫(η*_ref − η*) dt − K_P η* − K_D ν                      (eq. 9)
    η/η_ref = 1 / (α/K_I s³ + (β + K_D)/K_I s² + K_P/K_I s + 1)    (eq. 10)
    K_I = α/a3,  K_P = a1 α/a3,  K_D = a2 α/a3 − β                 (eq. 11)

so that the loop follows the model function G_m = 1/(a3 s³ + a2 s² + a1 s + 1),
here binomial, 1/(s/ω_n + 1)³. The reference enters only through the integral,
so a step never kicks the thrusters [Relay-ISO §IV]. β is the describing function's linear
equivalent at the relay's speeds; near the target, at rest, the hull gives only its linear drag
β₀ (−X_u, −N_r of the twin), so the loop's damping there is β₀ + K_D. Where eq. 11 gives a K_D
below −β₀ it is taken as −β₀: a loop with negative damping at rest swings about the target (the
BlueBoat's surge at ω_n 0.25: eq. 11's K_D −6.4 against its β₀ 0.44 swings ±2.5 m about a 14-m
move's end; at −0.44 it settles, IAE ratio 1.00). The Yellowfish's heading keeps eq. 11's −20.7
(β₀ 40). A ship steering at speed is not at rest: its K_D is eq. 11's.

Anti-windup (Fig. 6): the thrusters saturate, so the integrator is driven back
by what the allocation could not deliver (back-calculation),
d/dt ∫ = (η*_ref − η*) + (τ_sat − τ)/(K_I T_t), with T_t = 1/(3 ω_n).

The twin has no sway thruster, so dynamic positioning to a point is done as
heading towards the point (a heading step to the bearing from the start) plus
the surge I-PD on the along-track distance x* (along the start-to-target
line). The surge step starts once the heading model function has settled
(8/ω_n,ψ, 99 %): a surge force while the bow still points elsewhere pushes the
vessel off the line, and with no sway force nothing brings it back (started
together, the Yellowfish ends 0.9 m beside a 14 m target). The cross-track
offset y* is not controlled; it is reported.

The controller uses the twin's η and ν as measured (no estimator: the twin's
state is noise-free, and a Kalman filter would only add its lag).

A propeller-and-rudder ship (the "cruising" mode of [Relay-ISO §II-A.2]: X = τ₁, N = L₁ k_F δ τ₁) steers
with the rudder alone at a constant propeller speed: the heading I-PD's moment N is allocated to
the rudder angle by inverting the rudder's moment at the straight-running operating point,
N_R(δ) = A sin δ cos δ (α_R = δ there, so F_N ∝ sin δ and N_R ∝ F_N cos δ; A from the MMG rudder
force at u₀ and n), δ = ½ asin(2N/A), clipped to the rudder's ±35°; the anti-windup sees the
moment A sin δ cos δ of the clipped angle. Its yaw is slow (α/β ≈ 7 s) and its rudder weak (about
2 N·m at 35°), so its model function is slower than the Yellowfish's: SHIP_HEADING_OMEGA_RAD_S.
"""
from __future__ import annotations

import io
import math
import textwrap
from dataclasses import dataclass, field

import numpy as np

from ...physics.kinematics import wrap_angle
from ...physics.thrusters import allocation_matrix
from .iso import SHIP_CONTROL_DT_S, calm_water, force_range, rudder_moment, straight_speed

# a point move has settled when its last quarter stays within this of the target: the larger of a
# distance (m) and a share of the move
SETTLED_M = 0.5
SETTLED_SHARE = 0.05

CONTROL_DT_S = 0.02
# Binomial ω_n for the Yellowfish ([Relay-ISO] used 0.2 heading / 0.1 surge for a slower tanker model).
# Heading: the fastest round value whose 45° step needs ~80 % of the ±15.4 N·m the thrusters give
# (a margin for model error and the quadratic drag the linear model leaves out); a 90° step then needs
# ~1.6× the limit, so it saturates as in [Relay-ISO Fig. 9]. Surge: a 14 m move peaks near 1 m/s and
# 10 N (a fifth of the thrust), and the heading loop is 5.6× faster, so the bow is on the line first.
HEADING_OMEGA_RAD_S = 1.4
SURGE_OMEGA_RAD_S = 0.25
# Binomial ω_n for the Esso Osaka ship (rudder, 10 rps): the paper's own 0.2 rad/s for its tanker model would ask
# more than the rudder's moment for a 45° step; 0.15 rad/s needs about 80 % of it on the IS-O model (as the
# Yellowfish's choice), so a 45° step stays inside and a 90° step saturates (docs/results/esso_iso_yaw.md).
SHIP_HEADING_OMEGA_RAD_S = 0.15
SHIP_RPS = 10.0
SHIP_RUDDER_MAX_DEG = 35.0  # the Esso model's rudder stops (dataset README: ±35°)


@dataclass(frozen=True)
class ModelFunction:
    """G_m(s) = 1/(a3 s³ + a2 s² + a1 s + 1)."""

    a3: float
    a2: float
    a1: float
    omega_n_rad_s: float

    def step(self, t_s: np.ndarray) -> np.ndarray:
        """Unit-step response of the binomial G_m: 1 − e^{−ω t}(1 + ω t + (ω t)²/2)."""
        x = self.omega_n_rad_s * np.maximum(np.asarray(t_s, float), 0.0)
        return 1.0 - np.exp(-x) * (1.0 + x + x ** 2 / 2)

    def peak_effort(self, alpha: float, beta: float, step: float) -> float:
        """max |α ÿ + β ẏ| (N or N·m) along the model response to a step: what the thrusters must give
        for the loop to follow G_m on the linear model. ẏ/ω = x²e^{−x}/2, ÿ/ω² = (x − x²/2)e^{−x}."""
        w = self.omega_n_rad_s
        x = np.linspace(0.0, 20.0, 4001)
        effort = alpha * w ** 2 * (x - x ** 2 / 2) * np.exp(-x) + beta * w * x ** 2 * np.exp(-x) / 2
        return float(abs(step) * np.max(np.abs(effort)))


def binomial(omega_n_rad_s: float) -> ModelFunction:
    """(s/ω_n + 1)³: a3 = 1/ω_n³, a2 = 3/ω_n², a1 = 3/ω_n."""
    w = omega_n_rad_s
    return ModelFunction(1 / w ** 3, 3 / w ** 2, 3 / w, w)


@dataclass(frozen=True)
class IpdGains:
    """[Relay-ISO eq. 11] from the IS-O α, β and the model function; with the hull's drag at rest
    beta_rest, K_D at least −beta_rest (module docstring); kd_eq11: eq. 11's own K_D."""

    ki: float
    kp: float
    kd: float
    kd_eq11: float | None = None

    @classmethod
    def tuned(cls, alpha: float, beta: float, model: ModelFunction, beta_rest: float | None = None) -> "IpdGains":
        kd = model.a2 * alpha / model.a3 - beta
        held = kd if beta_rest is None else max(kd, -beta_rest)
        return cls(ki=alpha / model.a3, kp=model.a1 * alpha / model.a3, kd=held, kd_eq11=kd)


class IpdLoop:
    """One DOF of eq. 9 with back-calculation anti-windup."""

    def __init__(self, gains: IpdGains, tracking_s: float):
        self.gains, self.tracking_s = gains, tracking_s
        self.integral = 0.0

    def command(self, position: float, velocity: float) -> float:
        g = self.gains
        return g.ki * self.integral - g.kp * position - g.kd * velocity

    def advance(self, reference: float, position: float, commanded: float, delivered: float, dt_s: float) -> None:
        # what the thrusters could not deliver pulls the integral back, so it cannot wind up in saturation
        unwind = (delivered - commanded) / (self.gains.ki * self.tracking_s)
        self.integral += dt_s * ((reference - position) + unwind)


def _range_for(coefs: np.ndarray, offsets: np.ndarray, bounds_n: tuple[float, float]) -> tuple[float, float]:
    """The interval of z for which offsets_i + coefs_i·z stays within the thrust bounds for every thruster."""
    lo, hi = -math.inf, math.inf
    for c, o in zip(coefs, offsets):
        if c == 0:
            continue
        a, b = (bounds_n[0] - o) / c, (bounds_n[1] - o) / c
        lo, hi = max(lo, min(a, b)), min(hi, max(a, b))
    return lo, hi


def allocate(force_n: float, moment_nm: float, thruster_y_m: tuple[float, float],
             bounds_n: tuple[float, float]) -> tuple[np.ndarray, float, float]:
    """Inverse of [Yellowfish-TR eq. 26] with yaw priority: (T_L, T_R), the delivered X and N.

    The yaw moment is clipped to what the thrusters give at X = 0, then X to what is left:
    a heading error is never traded for speed.
    """
    inv = np.linalg.inv(allocation_matrix(thruster_y_m)[[0, 2]])
    per_force, per_moment = inv[:, 0], inv[:, 1]
    moment_nm = float(np.clip(moment_nm, *_range_for(per_moment, np.zeros(2), bounds_n)))
    force_n = float(np.clip(force_n, *_range_for(per_force, per_moment * moment_nm, bounds_n)))
    return per_force * force_n + per_moment * moment_nm, force_n, moment_nm


@dataclass
class LoopLog:
    t_s: list = field(default_factory=list)
    reference: list = field(default_factory=list)
    position: list = field(default_factory=list)
    commanded: list = field(default_factory=list)
    delivered: list = field(default_factory=list)


class DpController:
    """[Relay-ISO Fig. 6] for a twin-thruster vessel: heading I-PD (yaw moment) and, if a target
    distance is given, surge I-PD on the along-track distance x* (force), yaw first in the
    allocation. Returns thrusts in N. Called every CONTROL_DT_S; the integrals advance by
    forward Euler after the command is formed."""

    output = "thrust"

    def __init__(self, heading: IpdLoop, bearing_rad: float, thruster_y_m, bounds_n,
                 surge: IpdLoop | None = None, distance_m: float = 0.0, surge_start_s: float = 0.0,
                 gains=(1.0, 1.0)):
        """bounds_n: what one thruster puts on the hull (iso.force_range); gains: the thrusters'
        (left, right), by which each allocated force is divided into the map's command."""
        self.heading, self.surge = heading, surge
        self.gains = np.asarray(gains, float)
        self.bearing_rad, self.distance_m, self.surge_start_s = bearing_rad, distance_m, surge_start_s
        self.thruster_y_m, self.bounds_n = thruster_y_m, bounds_n
        self.start: np.ndarray | None = None  # η at t = 0: the origin of η*
        self.heading_unwrapped_rad, self.last_psi_rad = 0.0, 0.0
        self.yaw_log, self.surge_log = LoopLog(), LoopLog()

    def _positions(self, eta: np.ndarray) -> tuple[float, float, float, float]:
        """(ψ*, ψ*_ref, x*, x*_ref) relative to the start: ψ unwrapped so a turn through ±180° is continuous."""
        self.heading_unwrapped_rad += float(wrap_angle(eta[2] - self.last_psi_rad))
        self.last_psi_rad = float(eta[2])
        track = np.array([math.cos(self.bearing_rad), math.sin(self.bearing_rad)])
        along_m = float((eta[:2] - self.start[:2]) @ track)
        return self.heading_unwrapped_rad, float(wrap_angle(self.bearing_rad - self.start[2])), along_m, \
            self.distance_m

    def __call__(self, t_s: float, eta: np.ndarray, nu: np.ndarray) -> tuple[float, float]:
        if self.start is None:
            self.start, self.last_psi_rad = np.array(eta, float), float(eta[2])
        psi, psi_ref, x, x_ref = self._positions(eta)
        moment_cmd = self.heading.command(psi, float(nu[2]))
        surging = self.surge is not None and t_s >= self.surge_start_s
        force_cmd = self.surge.command(x, float(nu[0])) if surging else 0.0
        thrust_n, force_sat, moment_sat = allocate(force_cmd, moment_cmd, self.thruster_y_m, self.bounds_n)
        self.heading.advance(psi_ref, psi, moment_cmd, moment_sat, CONTROL_DT_S)
        self._log(self.yaw_log, t_s, psi_ref, psi, moment_cmd, moment_sat)
        if surging:
            self.surge.advance(x_ref, x, force_cmd, force_sat, CONTROL_DT_S)
            self._log(self.surge_log, t_s, x_ref, x, force_cmd, force_sat)
        thrust_n = thrust_n / self.gains
        return float(thrust_n[0]), float(thrust_n[1])

    @staticmethod
    def _log(log: LoopLog, *values) -> None:
        for name, value in zip(("t_s", "reference", "position", "commanded", "delivered"), values):
            getattr(log, name).append(value)


@dataclass(frozen=True)
class RudderAllocation:
    """N_R(δ) = A sin δ cos δ at the operating point, inverted with the rudder's limit (module docstring)."""

    gain_nm: float  # A (N·m)
    max_rad: float

    @classmethod
    def at(cls, compiled, speed_m_s: float, n_rps: float, max_deg: float = SHIP_RUDDER_MAX_DEG) -> "RudderAllocation":
        ref = math.radians(10.0)
        return cls(rudder_moment(compiled, speed_m_s, n_rps, ref) / (math.sin(ref) * math.cos(ref)),
                   math.radians(max_deg))

    def moment(self, rudder_rad: float) -> float:
        return self.gain_nm * math.sin(rudder_rad) * math.cos(rudder_rad)

    def rudder(self, moment_nm: float) -> float:
        """δ for the moment, clipped to ±max (the moment of the limit where more is asked)."""
        limit = math.sin(2 * self.max_rad)
        return 0.5 * math.asin(float(np.clip(2 * moment_nm / self.gain_nm, -limit, limit)))


class ShipHeadingController:
    """[Relay-ISO Fig. 6], heading only, for a propeller-and-rudder ship: the heading I-PD's moment as a
    rudder angle (RudderAllocation), the propeller at n. Returns (n rps, δ rad); called every control_dt_s."""

    output = "propeller_rudder"

    def __init__(self, heading: IpdLoop, step_rad: float, allocation: RudderAllocation, n_rps: float,
                 control_dt_s: float):
        self.heading, self.step_rad, self.allocation, self.n_rps = heading, step_rad, allocation, n_rps
        self.control_dt_s = control_dt_s
        self.start_rad: float | None = None
        self.heading_unwrapped_rad, self.last_psi_rad = 0.0, 0.0
        self.yaw_log = LoopLog()

    def __call__(self, t_s: float, eta: np.ndarray, nu: np.ndarray) -> tuple[float, float]:
        if self.start_rad is None:
            self.start_rad = self.last_psi_rad = float(eta[2])
        self.heading_unwrapped_rad += float(wrap_angle(eta[2] - self.last_psi_rad))
        self.last_psi_rad = float(eta[2])
        psi = self.heading_unwrapped_rad
        moment_cmd = self.heading.command(psi, float(nu[2]))
        rudder = self.allocation.rudder(moment_cmd)
        moment_sat = self.allocation.moment(rudder)
        self.heading.advance(self.step_rad, psi, moment_cmd, moment_sat, self.control_dt_s)
        for name, value in zip(("t_s", "reference", "position", "commanded", "delivered"),
                               (t_s, self.step_rad, psi, moment_cmd, moment_sat)):
            getattr(self.yaw_log, name).append(value)
        return self.n_rps, rudder


def ship_heading_step(compiled, yaw: DofModel, step_deg: float, n_rps: float = SHIP_RPS,
                      duration_s: float | None = None, anti_windup: bool = True) -> DpRun:
    """Heading step of `step_deg` at t = 0 steered by the rudder (module docstring), from straight running
    at the propeller speed n in calm water ([Relay-ISO Figs. 8-9] for the ship)."""
    # late: twin.engine.sim (mujoco) is 0.13 s more at every `twin --help`, which loads this module
    from ...engine.sim import simulate

    u0 = straight_speed(compiled, n_rps)
    ctrl = ShipHeadingController(yaw.loop(anti_windup), math.radians(step_deg), RudderAllocation.at(compiled, u0, n_rps),
                                 n_rps, SHIP_CONTROL_DT_S)
    duration_s = duration_s or settle_s(yaw.model)
    run = simulate(calm_water(compiled), ctrl, duration_s, control_dt_s=SHIP_CONTROL_DT_S,
                   sample_dt_s=SHIP_CONTROL_DT_S, nu0=(u0, 0.0, 0.0))
    name = f"heading step {step_deg:g}° (rudder, {n_rps:g} rps)" + ("" if anti_windup else " without anti-windup")
    return DpRun(name, run, [_response("yaw", "deg", ctrl.yaw_log, yaw.model)])


def iae(t_s: np.ndarray, error: np.ndarray) -> float:
    """Integral of the absolute error (trapezoidal)."""
    a = np.abs(np.asarray(error, float))
    return float(np.sum(0.5 * (a[1:] + a[:-1]) * np.diff(t_s)))


@dataclass
class LoopResponse:
    """One controlled DOF against its model function [Relay-ISO Figs. 8, 9, 11]."""

    name: str
    unit: str
    t_s: np.ndarray
    reference: float
    response: np.ndarray  # η* of the twin, relative to the start
    model: np.ndarray  # G_m step response to the same reference
    commanded: np.ndarray
    delivered: np.ndarray

    @property
    def iae_ratio(self) -> float | None:
        """IAE of the twin / IAE of the model function ([Relay-ISO §V-B]: about 1.02 for 45°); None
        where the loop was asked no step (a point dead ahead: the heading's reference is 0)."""
        model = iae(self.t_s, self.reference - self.model)
        return iae(self.t_s, self.reference - self.response) / model if model > 0 else None

    @property
    def max_deviation(self) -> float:
        return float(np.max(np.abs(self.response - self.model)))

    @property
    def overshoot(self) -> float:
        """How far the response went past the reference (0 if it never did)."""
        return max(0.0, float(np.max((self.response - self.reference) * np.sign(self.reference))))

    @property
    def saturated_percent(self) -> float:
        return 100 * float(np.mean(np.abs(self.commanded - self.delivered) > 1e-9))

    def summary(self, scale: float = 1.0) -> dict:
        return {"dof": self.name, "unit": self.unit, "reference": self.reference * scale,
                "iae_ratio": self.iae_ratio, "max_deviation_from_model": self.max_deviation * scale,
                "overshoot": self.overshoot * scale,
                "final_error": float(self.reference - self.response[-1]) * scale,
                "saturated_percent_of_time": self.saturated_percent,
                "peak_command": float(np.max(np.abs(self.commanded))),
                "peak_delivered": float(np.max(np.abs(self.delivered)))}


def _response(name: str, unit: str, log: LoopLog, model: ModelFunction) -> LoopResponse:
    t = np.array(log.t_s)
    ref = float(log.reference[0])
    return LoopResponse(name, unit, t, ref, np.array(log.position), ref * model.step(t - t[0]),
                        np.array(log.commanded), np.array(log.delivered))


@dataclass(frozen=True)
class DofModel:
    """IS-O linear model of one DOF, the model function chosen for it and the hull's own linear
    drag at rest (N·s/m or N·m·s; None: eq. 11 as it is)."""

    alpha: float
    beta: float
    model: ModelFunction
    beta_rest: float | None = None

    @property
    def gains(self) -> IpdGains:
        return IpdGains.tuned(self.alpha, self.beta, self.model, self.beta_rest)

    def loop(self, anti_windup: bool = True) -> IpdLoop:
        return IpdLoop(self.gains, tracking_s=1 / (3 * self.model.omega_n_rad_s) if anti_windup else math.inf)


@dataclass
class DpRun:
    """A closed-loop run: the twin's run and the loop responses against their model functions."""

    name: str
    run: object  # twin.run.Run
    loops: list[LoopResponse]
    target_ne_m: tuple[float, float] | None = None

    def summary(self) -> dict:
        out = {"run": self.name, "loops": [lp.summary(180 / math.pi if lp.unit == "deg" else 1.0)
                                           for lp in self.loops]}
        if self.target_ne_m is not None:
            moved = self.run.eta[:, :2] - self.run.eta[0, :2]
            distance = np.hypot(*(np.array(self.target_ne_m) - moved).T)
            out["final_distance_to_target_m"] = float(distance[-1])
            out["max_cross_track_m"] = float(np.max(np.abs(self._cross_track_m())))
            last = distance[len(distance) * 3 // 4:]  # the run's last quarter
            out["last_quarter_distance_m"] = [float(last.min()), float(last.max())]
            out["settled"] = bool(last.max() <= max(SETTLED_M, SETTLED_SHARE * float(np.hypot(*self.target_ne_m))))
        return out

    def _cross_track_m(self) -> np.ndarray:
        n, e = self.target_ne_m
        rel = self.run.eta[:, :2] - self.run.eta[0, :2]
        return (rel[:, 1] * n - rel[:, 0] * e) / math.hypot(n, e)


def settle_s(model: ModelFunction) -> float:
    """Time by which the binomial step response is within 0.1 % (14/ω_n): the IAE window."""
    return 14 / model.omega_n_rad_s


def heading_step(compiled, yaw: DofModel, step_deg: float, duration_s: float | None = None,
                 anti_windup: bool = True) -> DpRun:
    """Heading reference stepped by `step_deg` at t = 0 [Relay-ISO Figs. 8-9]."""
    # late: twin.engine.sim (mujoco) is 0.13 s more at every `twin --help`, which loads this module
    from ...engine.sim import simulate

    duration_s = duration_s or settle_s(yaw.model)
    ctrl = DpController(yaw.loop(anti_windup), math.radians(step_deg), compiled.geometry.thruster_y_m,
                        force_range(compiled.vessel.thrusters), gains=compiled.vessel.thrusters.gains())
    run = simulate(compiled, ctrl, duration_s, control_dt_s=CONTROL_DT_S, sample_dt_s=CONTROL_DT_S)
    name = f"heading step {step_deg:g}°" + ("" if anti_windup else " without anti-windup")
    return DpRun(name, run, [_response("yaw", "deg", ctrl.yaw_log, yaw.model)])


def point_move(compiled, yaw: DofModel, surge: DofModel, target_ne_m: tuple[float, float],
               duration_s: float | None = None) -> DpRun:
    """Move to a point (north, east from the start, heading 0 at the start): heading step to the
    bearing plus surge I-PD on the along-track distance (module docstring)."""
    # late: twin.engine.sim (mujoco) is 0.13 s more at every `twin --help`, which loads this module
    from ...engine.sim import simulate

    bearing = math.atan2(target_ne_m[1], target_ne_m[0])
    ctrl = DpController(yaw.loop(), bearing, compiled.geometry.thruster_y_m, force_range(compiled.vessel.thrusters),
                        surge=surge.loop(), distance_m=math.hypot(*target_ne_m),
                        surge_start_s=8 / yaw.model.omega_n_rad_s, gains=compiled.vessel.thrusters.gains())
    duration_s = duration_s or settle_s(yaw.model) + settle_s(surge.model)
    run = simulate(compiled, ctrl, duration_s, control_dt_s=CONTROL_DT_S, sample_dt_s=CONTROL_DT_S)
    loops = [_response("surge x*", "m", ctrl.surge_log, surge.model), _response("yaw", "deg", ctrl.yaw_log, yaw.model)]
    return DpRun(f"point ({target_ne_m[0]:g} m N, {target_ne_m[1]:g} m E)", run, loops, target_ne_m)


def response_png(dp: DpRun, title: str) -> bytes:
    """[Relay-ISO Fig. 8] layout per loop: response and model function, controller output, difference;
    for a point move also the path (Fig. 10)."""
    # late: matplotlib (0.3 s) only for the PNG; `twin --help` loads this module
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cols = len(dp.loops) + (dp.target_ne_m is not None)
    fig, axes = plt.subplots(3, cols, figsize=(5.2 * cols, 8), squeeze=False)
    for j, lp in enumerate(dp.loops):
        k = 180 / math.pi if lp.unit == "deg" else 1.0
        ax = axes[0, j]
        ax.plot(lp.t_s, np.full_like(lp.t_s, lp.reference * k), "k-", lw=0.8, label="reference")
        ax.plot(lp.t_s, lp.model * k, "k:", lw=1.5, label="model function $G_m$")
        ax.plot(lp.t_s, lp.response * k, "C0", label="twin")
        ax.set_ylabel(f"{lp.name} [{lp.unit}]")
        ax.set_title(f"{lp.name}: IAE ratio {'–' if lp.iae_ratio is None else f'{lp.iae_ratio:.3f}'}")
        ax.legend(fontsize=8)
        force = "N·m" if lp.name == "yaw" else "N"
        axes[1, j].plot(lp.t_s, lp.commanded, "C1", lw=0.8, label="I-PD output")
        if getattr(dp.run.meta.get("inputs"), "kind", "") == "propeller_rudder":
            rudder = axes[1, j].twinx()
            inputs = dp.run.meta["inputs"]
            rudder.step(inputs.t + dp.run.t[0], np.degrees(inputs.values[:, 1]), "C4", lw=0.8, where="post")
            rudder.set_ylabel("rudder [deg]", color="C4")
        axes[1, j].plot(lp.t_s, lp.delivered, "C3", lw=1.2, label="delivered (saturated)")
        axes[1, j].set_ylabel(f"{'N' if lp.name == 'yaw' else 'X'} [{force}]")
        axes[1, j].legend(fontsize=8)
        axes[2, j].plot(lp.t_s, (lp.response - lp.model) * k, "C2")
        axes[2, j].set_ylabel(f"twin − model [{lp.unit}]")
        axes[2, j].set_xlabel("t [s]")
    if dp.target_ne_m is not None:
        _path_axes(fig, axes[:, -1], dp)
    fig.suptitle(textwrap.fill(title, 48 * cols), fontsize=11)  # one column is narrow: wrap, don't clip
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return buf.getvalue()


def _path_axes(fig, column, dp: DpRun) -> None:
    for ax in column:
        ax.remove()
    ax = fig.add_subplot(1, len(dp.loops) + 1, len(dp.loops) + 1)
    rel = dp.run.eta[:, :2] - dp.run.eta[0, :2]
    ax.plot(rel[:, 1], rel[:, 0], "C0", label="twin path")
    ax.plot([0, dp.target_ne_m[1]], [0, dp.target_ne_m[0]], "k:", lw=1, label="start → target")
    ax.plot(dp.target_ne_m[1], dp.target_ne_m[0], "rx", ms=10, label="target")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.set_aspect("equal")
    ax.legend(fontsize=8)
    ax.set_title("path [Relay-ISO Fig. 10]")
