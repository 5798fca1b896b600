"""The independent analytic 3-DOF model (numpy + scipy):

    η̇ = R(ψ)ν,   M ν̇_r + C(ν_r)ν_r + D(ν_r)ν_r = τ + τ_wind   [Yellowfish-TR eq. 12]

integrated with an adaptive 8th-order Runge-Kutta (DOP853) at tight
tolerances, piecewise between input changes. It shares the force functions of
`twin.physics` with the engine callbacks but none of the engine: no MuJoCo
rigid-body dynamics, no MuJoCo integrator, its own thrust lag state, and a thrust ramp (slew
limit) in continuous time: from where it stands when an input changes, the command heads for the
held one at the ramp's rate and then follows it (`_ramp`), where the engine is given each step's
mean of the same ramp.

A propeller-and-rudder ship: the held inputs (n rps, δ rad) go to the MMG forces of
physics/mmg.py (through hydrodynamics.acceleration's `controls`), no thrust allocation. A
measured wind (drive.WindSeries) is a known input held like the thrusters' inputs: its
changes are break points of the piecewise integration.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from .drive import InputSeries, WindSeries
from .errors import TwinError
from .physics.hydrodynamics import HydroModel, acceleration, mmg_forces
from .physics.kinematics import eta_dot
from .physics.thrusters import ThrusterModel, allocation_matrix, delivered
from .run import Run


def _ramp(from_n: np.ndarray, command_n: np.ndarray, rate_n_per_s: float, elapsed_s: float) -> np.ndarray:
    """A slew-limited command `elapsed_s` after it stood at `from_n`, heading for `command_n`."""
    reach = rate_n_per_s * elapsed_s
    return np.where(np.abs(command_n - from_n) <= reach, command_n, from_n + np.sign(command_n - from_n) * reach)


def _rhs(hydro: HydroModel, thrusters: ThrusterModel, thruster_y_m, raw: np.ndarray, start_s: float,
         wind_ned=None, ramp_from: tuple[float, np.ndarray] | None = None):
    """Right-hand side with the input `raw` (N, before decay) held; the thrust decays in
    continuous time; its advance loss is a hydrodynamic force (physics/hydrodynamics.py). A propeller and
    rudder's `raw` is (n, δ), the MMG forces' controls. `wind_ned`: the air's velocity held.
    `ramp_from`: (time s, thrust N) where a thrust ramp stood when the input changed."""
    if thrusters.kind == "propeller_rudder":
        controls = np.asarray(raw, float)

        def f_mmg(t, x):
            psi, nu = x[2], x[3:6]
            dx = np.empty_like(x)
            dx[0:3] = eta_dot(psi, nu)
            dx[3:6] = acceleration(hydro, psi, nu, np.zeros(3), controls, wind_ned)
            return dx

        return f_mmg
    B = allocation_matrix(thruster_y_m)
    gains = thrusters.gains()
    lag = thrusters.lag_s
    t_min, t_max = thrusters.bounds()
    rate = thrusters.slew_n_per_s if ramp_from is not None else None

    def f(t, x):
        psi, nu = x[2], x[3:6]
        cmd = np.clip(raw * thrusters.decay_factor(t + start_s), t_min, t_max)
        if ramp_from is not None:
            cmd = _ramp(ramp_from[1], cmd, rate, t - ramp_from[0])
        delivered = x[6:8] if lag > 0 else cmd
        static = gains * delivered  # the advance loss acts on it in the hydrodynamics
        dx = np.empty_like(x)
        dx[0:3] = eta_dot(psi, nu)
        dx[3:6] = acceleration(hydro, psi, nu, B @ static, None, wind_ned, static)
        if lag > 0:
            dx[6:8] = (cmd - x[6:8]) / lag
        return dx

    return f


def simulate(
    hydro: HydroModel,
    thrusters: ThrusterModel,
    thruster_y_m: tuple[float, float],
    inputs: InputSeries,
    t_samples: np.ndarray,
    eta0=None,
    nu0=None,
    start_s: float = 0.0,
    rtol: float = 1e-11,
    atol: float = 1e-11,
    wind: WindSeries | None = None,
) -> Run:
    """Integrate from t_samples[0] and return the state at every sample time.

    The inputs' clock starts at the run's start, as in the engine; `start_s` is the
    recording time of t = 0 for the thrust decay. The input changes reach the
    thrusters delay_s later; a supply voltage the inputs carry (thrusters that follow it) acts
    when it is logged. `wind`: a measured wind on the same clock, held (no delay)."""
    lag = thrusters.lag_s > 0 and thrusters.kind != "propeller_rudder"
    x = np.concatenate([np.zeros(3) if eta0 is None else eta0, np.zeros(3) if nu0 is None else nu0,
                        np.zeros(2)])[: 8 if lag else 6].astype(float)
    t0, t_end = float(t_samples[0]), float(t_samples[-1])
    driven = inputs.driven(thrusters)
    changes = inputs.t + thrusters.delay_s
    inside_run = (changes > t0) & (changes < t_end)
    changed = np.r_[True, np.any(np.diff(driven.values, axis=0) != 0, axis=1)]
    breaks = np.unique(np.concatenate([[t0, t_end], changes[inside_run & changed]]))
    if wind is not None:
        wind_changed = np.r_[True, np.any(np.diff(wind.air_ned, axis=0) != 0, axis=1)]
        breaks = np.unique(np.concatenate([breaks, wind.t[(wind.t > t0) & (wind.t < t_end) & wind_changed]]))
    supplied = thrusters.follows_supply and inputs.supply_v is not None
    if supplied:  # the supply voltage acts when it is logged, not delay_s later
        volt_changed = np.r_[True, np.diff(inputs.supply_v) != 0]
        breaks = np.unique(np.concatenate([breaks, inputs.t[(inputs.t > t0) & (inputs.t < t_end) & volt_changed]]))
    out = np.full((len(t_samples), len(x)), np.nan)
    out[0] = x
    ramping = thrusters.ramping
    ramped, ramp_t, ramp_values = None, [], []  # where the ramp stands at each break
    for a, b in zip(breaks[:-1], breaks[1:]):
        held = driven.at(np.array([a - thrusters.delay_s]))
        if inputs.kind == "propeller_rudder":
            raw = held[0]  # (n, δ): the MMG forces' controls, which the MMG terms switch (not `thrust`)
        else:
            raw = held[0] if inputs.kind == "thrust" else thrusters.thrust_from_pwm(held)[0]
            if not hydro.terms.thrust:
                raw = np.zeros(2)
        air = None if wind is None else wind.at(np.array([a]))[0]
        raw = np.asarray(raw, float)
        if supplied:
            raw = raw * thrusters.supply_factor(inputs.supply_at(np.array([a])))[0]
        ramp_from, stops = None, [a, b]
        if ramping:
            target = np.clip(raw * thrusters.decay_factor(a + start_s), *thrusters.bounds())
            ramped = target if ramped is None else ramped
            ramp_from = (a, ramped)
            ramp_t.append(a)
            ramp_values.append(ramped)
            # where the ramp arrives the thrust has a kink: integrate up to it, then on
            arrive = a + np.abs(target - ramped) / thrusters.slew_n_per_s
            stops = np.unique(np.concatenate([[a, b], arrive[(arrive > a) & (arrive < b)]]))
        for a1, b1 in zip(stops[:-1], stops[1:]):
            inside = (t_samples > a1) & (t_samples <= b1)
            t_eval = np.unique(np.concatenate([t_samples[inside], [b1]]))
            sol = solve_ivp(_rhs(hydro, thrusters, thruster_y_m, raw, start_s, air, ramp_from), (a1, b1), x,
                            method="DOP853", rtol=rtol, atol=atol, t_eval=t_eval)
            if not sol.success:
                raise FloatingPointError(f"analytic integration failed at t = {a1:.2f} s: {sol.message}")
            out[inside] = sol.y.T[np.searchsorted(t_eval, t_samples[inside])]
            x = sol.y[:, -1]
        if ramping:
            ramped = _ramp(ramped, np.clip(raw * thrusters.decay_factor(b + start_s), *thrusters.bounds()),
                           thrusters.slew_n_per_s, b - a)
    if thrusters.kind == "propeller_rudder":
        controls = inputs.commanded_thrust(thrusters, t_samples, start_s)
        forces = np.array([mmg_forces(hydro, nu, c)[3:5] for nu, c in zip(out[:, 3:6], controls)]).reshape(-1, 2)
        return Run(start_s + t_samples, out[:, 0:3], out[:, 3:6], inputs.pwm_at(t_samples), forces,
                   meta={"engine": "analytic", "integrator": "DOP853"})
    gains = thrusters.gains()
    t_min, t_max = thrusters.bounds()
    if lag:
        cmd = out[:, 6:8]
    else:
        cmd = np.clip(inputs.commanded_thrust(thrusters, t_samples, start_s), t_min, t_max)
        if ramping and len(ramp_t):  # from where the ramp stood at the last break before each sample
            i = np.clip(np.searchsorted(ramp_t, t_samples, side="right") - 1, 0, len(ramp_t) - 1)
            cmd = _ramp(np.array(ramp_values)[i], cmd, thrusters.slew_n_per_s,
                        (t_samples - np.array(ramp_t)[i])[:, None])
        cmd = cmd if hydro.terms.thrust else np.zeros_like(cmd)
    thrust = delivered(thrusters.advance_loss, cmd * gains, out[:, 3:6], thruster_y_m)  # as the engine reports it
    return Run(start_s + t_samples, out[:, 0:3], out[:, 3:6], inputs.pwm_at(t_samples), thrust,
               meta={"engine": "analytic", "integrator": "DOP853"})


def straight_speed(compiled, n_rps: float) -> float:
    """u₀ (m/s): a propeller-and-rudder ship's steady straight-running speed at propeller speed n with
    the rudder amidships, in calm water (X(u₀, 0, 0) = 0 of the MMG forces)."""
    hydro = compiled.hydro().with_environment(type(compiled.vessel.environment)())

    def surge(u: float) -> float:
        return float(acceleration(hydro, 0.0, np.array([u, 0.0, 0.0]), np.zeros(3), (n_rps, 0.0))[0])

    hi = 0.1
    while surge(hi) > 0 and hi < 20:
        hi *= 2
    if not surge(0.0) > 0:
        return 0.0
    if not surge(hi) <= 0:  # NaN too: forces that are not numbers balance nowhere
        raise TwinError(f"vessel '{compiled.vessel.name}': no straight-running speed under {hi:g} m/s at {n_rps:g} rps: "
                        "its resistance never balances the propeller's thrust (check mmg.hull.R0 and the propeller's "
                        "k0, k1, k2 and diameter)")
    return float(brentq(surge, 0.0, hi, xtol=1e-10))


@dataclass(frozen=True)
class StraightRun:
    """A straight run in calm water and the sway-yaw motion linearised about it: course stability.

    Attributes:
        throttle: the share of full ahead it runs at (both thrusters' bound, or a ship's rps_max).
        speed_m_s: the surge speed u₀ (m/s) at which the resistance balances the thrust.
        roots_per_s: the two roots (1/s) of ν̇ = J ν in sway and yaw about (u₀, 0, 0): a root with a
            positive real part makes a small deviation grow, and the straight run turns on its own.
    """

    throttle: float
    speed_m_s: float
    roots_per_s: tuple[complex, complex]

    @property
    def stable(self) -> bool:
        """Whether the straight run holds (both roots in the left half-plane)."""
        return max(r.real for r in self.roots_per_s) < 0.0

    @property
    def doubling_s(self) -> float | None:
        """Time (s) in which an unstable run doubles a small deviation; None when it holds."""
        growth = max(r.real for r in self.roots_per_s)
        return math.log(2.0) / growth if growth > 0 else None

    def __str__(self) -> str:
        roots = ", ".join(f"{r.real:+.3g}" + (f"{r.imag:+.3g}j" if abs(r.imag) > 1e-12 else "") for r in self.roots_per_s)
        verdict = "holds a straight course" if self.stable else (
            f"course-unstable: turns on its own, a deviation doubling every {self.doubling_s:.3g} s")
        return f"straight run at {100 * self.throttle:.0f} % (u {self.speed_m_s:.3g} m/s): {verdict} (roots {roots} 1/s)"


def straight_run(compiled, throttle: float = 1.0, static_n=None) -> StraightRun | None:
    """Course stability of the vessel running straight at `throttle` (0-1] of full ahead, in calm water:
    the speed where its surge forces balance, and the roots of its sway and yaw linearised there by
    central differences of the analytic model's accelerations (straight-line stability, [Fossen-2021]).

    Args:
        compiled: the compiled vessel.
        throttle: the share of full ahead (each thruster's upper bound, else its command_scale_n; a
            ship's rps_max).
        static_n: the two thrusters' thrusts (N, after their gains) in place of the throttle's (the
            run's throttle is then their mean's share of full ahead).

    Returns:
        The run, its speed and roots; both thrusters give their mean, so a gain asymmetry does not bend
        it. None where full ahead has no bound (thrusters without one, a ship without rps_max).
    """
    vessel = compiled.vessel
    hydro = compiled.hydro().with_environment(type(vessel.environment)())
    t = vessel.thrusters
    if t.kind == "propeller_rudder":
        n_max = t.channel_bounds()[0][1]
        if not np.isfinite(n_max):
            return None
        drive = {"tau": np.zeros(3), "controls": (throttle * n_max, 0.0), "static": None}
    else:
        full_n = t.bounds()[1]
        if not np.isfinite(full_n) and t.kind != "t200" and t.command_scale_n is not None:
            full_n = t.command_range()[1]  # what a full command stands for, as the scenarios drive it
        if static_n is None and not np.isfinite(full_n):
            return None
        each = (float(np.mean(t.gains())) * throttle * full_n if static_n is None
                else float(np.mean(np.asarray(static_n, float))))
        if static_n is not None and np.isfinite(full_n):
            throttle = each / (float(np.mean(t.gains())) * full_n)
        static = np.array([each, each])
        drive = {"tau": allocation_matrix(compiled.geometry.thruster_y_m) @ static, "controls": None, "static": static}

    def acc(nu: np.ndarray) -> np.ndarray:
        return acceleration(hydro, 0.0, nu, drive["tau"], drive["controls"], None, drive["static"])

    hi = 0.1
    while acc(np.array([hi, 0.0, 0.0]))[0] > 0 and hi < 50:
        hi *= 2
    if not acc(np.array([hi, 0.0, 0.0]))[0] <= 0:
        raise TwinError(f"vessel '{vessel.name}': no straight-running speed under {hi:g} m/s at {100 * throttle:.0f} % "
                        "of full ahead: its resistance never balances its thrust")
    def surge(u: float) -> float:
        return float(acc(np.array([u, 0.0, 0.0]))[0])

    u0 = 0.0 if not surge(0.0) > 0 else float(brentq(surge, 0.0, hi, xtol=1e-10))  # no thrust ahead: at rest
    J = np.empty((2, 2))
    for j, h in ((1, 1e-5 * max(1.0, u0)), (2, 1e-5)):
        step = np.zeros(3)
        step[j] = h
        base = np.array([u0, 0.0, 0.0])
        J[:, j - 1] = (acc(base + step)[1:] - acc(base - step)[1:]) / (2 * h)
    roots = np.linalg.eigvals(J)
    return StraightRun(float(throttle), u0, tuple(complex(r) for r in sorted(roots, key=lambda r: r.real)))


def course_unstable_from_m_s(compiled) -> float | None:
    """The lowest straight-run speed (m/s) at which the vessel is course-unstable (`straight_run`):
    the first of 10, 20, … 100 % of full ahead that is, then the onset bisected between it and the
    last that holds (to 0.1 % of full ahead); None where every one holds, or full ahead has no bound."""
    held = 0.0
    for pct in range(10, 101, 10):
        run = straight_run(compiled, pct / 100.0)
        if run is None:
            return None
        if run.stable:
            held = pct / 100.0
            continue
        lost, onset = pct / 100.0, run
        while lost - held > 1e-3:
            mid = straight_run(compiled, 0.5 * (held + lost))
            held, lost, onset = (held, mid.throttle, mid) if not mid.stable else (mid.throttle, lost, onset)
        return onset.speed_m_s
    return None
