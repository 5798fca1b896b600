"""A velocity estimator that uses the vessel model: an extended Kalman filter
on the 3-DOF equations of motion, driven by the recorded PWM, followed by a
Rauch-Tung-Striebel backward pass [RTS-1965].

Savitzky-Golay [Savitzky-1964; Morel-2024 §5.1] differentiates noisy positions and so trades
lag against noise. The model knows that a 25 kg hull cannot change speed
faster than its thrust allows, which lets it follow steps and turns with
less noise; it is only as good as the model, and the process noise (an
unmodelled acceleration, m/s² and rad/s²) says how far it is trusted.
`scripts/validate_smoother.py` measures where it does better.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from ..drive import INPUT_WORDS
from ..engine.mjcf import CompiledVessel
from ..errors import TwinError
from ..physics.hydrodynamics import acceleration
from ..physics.kinematics import eta_dot
from ..physics.thrusters import allocation_matrix
from .prepared import Prepared


def _transition(compiled: CompiledVessel, dt: float):
    """x_{k+1} = Φ(x_k, pwm_k) by one RK4 step of η̇ = R(ψ)ν, ν̇ = f(ψ, ν, τ)."""
    hydro = compiled.hydro()
    thrusters = compiled.vessel.thrusters
    B = allocation_matrix(compiled.geometry.thruster_y_m)
    t_min, t_max = thrusters.bounds()

    def tau(pwm):
        return B @ (thrusters.gains() * np.clip(thrusters.thrust_from_pwm(pwm), t_min, t_max))

    def f(x, tau_k):
        return np.concatenate([eta_dot(x[2], x[3:]), acceleration(hydro, x[2], x[3:], tau_k)])

    def phi(x, tau_k):
        k1 = f(x, tau_k)
        k2 = f(x + 0.5 * dt * k1, tau_k)
        k3 = f(x + 0.5 * dt * k2, tau_k)
        k4 = f(x + dt * k3, tau_k)
        return x + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)

    return phi, tau


def _jacobian(phi, x, tau_k, eps=1e-6):
    fx = phi(x, tau_k)
    J = np.empty((len(x), len(x)))
    for i in range(len(x)):
        dx = np.zeros(len(x))
        dx[i] = eps
        J[:, i] = (phi(x + dx, tau_k) - fx) / eps
    return fx, J


def smooth_segment(compiled: CompiledVessel, prep: Prepared, sl: slice, *, sigma_pos_m: float = 0.05,
                   sigma_psi_rad: float = 0.01, sigma_acc=(0.3, 0.3, 0.2)) -> np.ndarray:
    """Smoothed states [north, east, ψ, u, v, r] (n, 6) of one segment."""
    t = prep.t[sl]
    n = len(t)
    dt = float(np.median(np.diff(t))) if n > 1 else 0.1
    phi, tau = _transition(compiled, dt)
    z = np.column_stack([prep.north[sl], prep.east[sl], prep.psi[sl]])
    fresh = np.r_[True, np.any(np.diff(z[:, :2], axis=0) != 0, axis=1)]  # a new GNSS fix was held here
    pwm = prep.pwm[sl]
    Q = np.diag([1e-6, 1e-6, 1e-6, *((np.asarray(sigma_acc) * dt) ** 2)])
    R_full = np.diag([sigma_pos_m**2, sigma_pos_m**2, sigma_psi_rad**2])
    x = np.array([*z[0], prep.u[sl][0], prep.v[sl][0], prep.r[sl][0]])
    P = np.diag([sigma_pos_m**2, sigma_pos_m**2, sigma_psi_rad**2, 0.25, 0.25, 0.05])
    xs, Ps, xp, Pp, Fs = (np.zeros((n, 6)), np.zeros((n, 6, 6)), np.zeros((n, 6)), np.zeros((n, 6, 6)),
                          np.zeros((n, 6, 6)))
    for k in range(n):
        if k > 0:
            x, F = _jacobian(phi, x, tau(pwm[k - 1]))
            P = F @ P @ F.T + Q
            Fs[k] = F
        xp[k], Pp[k] = x, P
        rows = [0, 1, 2] if fresh[k] else [2]
        H = np.eye(6)[rows]
        S = H @ P @ H.T + R_full[np.ix_(rows, rows)]
        K = P @ H.T @ np.linalg.inv(S)
        x = x + K @ (z[k, rows] - x[rows])
        P = (np.eye(6) - K @ H) @ P
        xs[k], Ps[k] = x, P
    for k in range(n - 2, -1, -1):  # Rauch-Tung-Striebel
        C = Ps[k] @ Fs[k + 1].T @ np.linalg.inv(Pp[k + 1])
        xs[k] = xs[k] + C @ (xs[k + 1] - xp[k + 1])
    return xs


def model_smoothed(compiled: CompiledVessel, prep: Prepared, **kwargs) -> Prepared:
    """A copy of `prep` with position, heading, u, v, r from the model-based smoother."""
    vessel = compiled.vessel
    if vessel.thrusters.input_kind != "pwm":  # its model turns PWM into thrust: a thruster map of PWM
        raise TwinError(f"the model-based smoother (--smoother model) drives the vessel model with the recorded "
                        f"thruster PWM, and vessel '{vessel.name}' is driven by "
                        f"{INPUT_WORDS.get(vessel.thrusters.input_kind, vessel.thrusters.input_kind)}: use "
                        "--smoother savgol")
    if prep.input_kind != "pwm" or not len(prep.pwm) or not np.all(np.isfinite(prep.pwm)):
        source = Path(str(prep.settings.source or "the recording")).name
        raise TwinError(f"{source}: the model-based smoother (--smoother model) drives the vessel model with the "
                        "recorded thruster PWM, and the recording holds none: use --smoother savgol")
    out = {k: getattr(prep, k).copy() for k in ("north", "east", "psi", "u", "v", "r")}
    for seg in prep.segments:
        if seg.stop - seg.start < 3:
            continue
        xs = smooth_segment(compiled, prep, seg.slice, **kwargs)
        for i, k in enumerate(("north", "east", "psi", "u", "v", "r")):
            out[k][seg.slice] = xs[:, i]
    return replace(prep, **out, settings=replace(prep.settings, smoother="model"))
