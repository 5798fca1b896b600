"""The 3-DOF equations of motion, assembled from the force modules:

    M ν̇_r + C(ν_r)ν_r + D(ν_r)ν_r = τ_thrust + τ_wind,    ν_r = ν − ν_c,
    ν̇ = ν̇_r + ν̇_c,  η̇ = R(ψ)ν                     (seed 000 eq. 12; seed 004 eq. 3-7)

with M = M_RB + M_A and C = C_RB + C_A. For an irrotational earth-fixed
current, M_RB ν̇ + C_RB(ν)ν = M_RB ν̇_r + C_RB(ν_r)ν_r (Fossen 2011 Prop. 10.1),
which is what lets the engine keep integrating the true ν while the
hydrodynamic terms see ν_r.

`relative_acceleration` is the analytic model's right-hand side.
`hydrodynamic_force` is the body-frame force the MuJoCo callback adds to the
engine's own rigid-body dynamics. It applies added mass *exactly*: the
acceleration in −M_A ν̇_r is the one the full equation gives at this instant,
not a lagged or filtered estimate, so the engine's M_RB ν̇ + C_RB(ν)ν = X + τ
reproduces the equation above for any ratio of added to rigid mass.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from .coriolis import coriolis_force
from .damping import Damping, damping_force
from .environment import Environment, WindLoad, current_body, current_body_rate, wind_force


@dataclass(frozen=True)
class Terms:
    """Switches for each force term, so that each can be cross-checked alone.

    The rigid-body inertia and its Coriolis terms are always on: they are the
    engine's own dynamics.
    """

    added_mass: bool = True
    added_mass_coriolis: bool = True
    damping: bool = True
    thrust: bool = True
    current: bool = True
    wind: bool = True

    def only(self, *names: str) -> "Terms":
        off = {k: False for k in self.__dataclass_fields__}
        return Terms(**{**off, **{n: True for n in names}})


@dataclass(frozen=True)
class HydroModel:
    """Everything the force functions need, as plain numbers."""

    M_RB: np.ndarray
    M_A: np.ndarray
    damping: Damping
    wind_load: WindLoad = field(default_factory=WindLoad)
    environment: Environment = field(default_factory=Environment)
    terms: Terms = field(default_factory=Terms)

    @property
    def M_A_active(self) -> np.ndarray:
        return self.M_A if self.terms.added_mass else np.zeros((3, 3))

    @cached_property
    def M(self) -> np.ndarray:
        return self.M_RB + self.M_A_active

    @cached_property
    def M_inv(self) -> np.ndarray:
        return np.linalg.inv(self.M)

    def with_terms(self, terms: Terms) -> "HydroModel":
        return replace(self, terms=terms)

    def with_environment(self, environment: Environment) -> "HydroModel":
        return replace(self, environment=environment)


def relative_velocity(model: HydroModel, psi_rad: float, nu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(ν_r, ν_c) with the current switched by `terms.current`."""
    if model.terms.current and model.environment.current_speed_m_s != 0.0:
        nu_c = current_body(psi_rad, model.environment.current_ned)
    else:
        nu_c = np.zeros(3)
    return nu - nu_c, nu_c


def _external_force(model: HydroModel, psi_rad: float, nu: np.ndarray, nu_r: np.ndarray,
                    tau_thrust: np.ndarray) -> np.ndarray:
    """τ_thrust + τ_wind − C_A(ν_r)ν_r − D(ν_r)ν_r: every force but inertia and C_RB."""
    t = model.terms
    force = np.array(tau_thrust, dtype=float) if t.thrust else np.zeros(3)
    if t.wind and model.environment.wind_speed_m_s != 0.0:
        force = force + wind_force(model.wind_load, psi_rad, nu, model.environment.wind_ned)
    if t.damping:
        force = force - damping_force(model.damping, nu_r)
    if t.added_mass_coriolis:
        force = force - coriolis_force(model.M_A, nu_r)
    return force


def relative_acceleration(model: HydroModel, psi_rad: float, nu: np.ndarray,
                          tau_thrust: np.ndarray) -> np.ndarray:
    """ν̇_r from M ν̇_r = τ − C(ν_r)ν_r − D(ν_r)ν_r (+ τ_wind)."""
    nu_r, _ = relative_velocity(model, psi_rad, nu)
    rhs = _external_force(model, psi_rad, nu, nu_r, tau_thrust) - coriolis_force(model.M_RB, nu_r)
    return model.M_inv @ rhs


def acceleration(model: HydroModel, psi_rad: float, nu: np.ndarray, tau_thrust: np.ndarray) -> np.ndarray:
    """ν̇ = ν̇_r + ν̇_c: the analytic model's body-frame acceleration."""
    _, nu_c = relative_velocity(model, psi_rad, nu)
    return relative_acceleration(model, psi_rad, nu, tau_thrust) + current_body_rate(nu_c, nu[2])


def hydrodynamic_force(model: HydroModel, psi_rad: float, nu: np.ndarray,
                       tau_thrust: np.ndarray) -> np.ndarray:
    """Body-frame force X the engine must add to its rigid-body dynamics:

    X = −M_A ν̇_r − C_A(ν_r)ν_r − D(ν_r)ν_r + τ_wind, with ν̇_r exact (see module doc).
    `tau_thrust` is the actuator force the engine applies by itself; it enters
    only through ν̇_r.
    """
    nu_r, _ = relative_velocity(model, psi_rad, nu)
    external = _external_force(model, psi_rad, nu, nu_r, tau_thrust)
    thrust = np.array(tau_thrust, dtype=float) if model.terms.thrust else np.zeros(3)
    force = external - thrust
    if model.terms.added_mass:
        nu_dot_r = model.M_inv @ (external - coriolis_force(model.M_RB, nu_r))
        force = force - model.M_A @ nu_dot_r
    return force


def kinetic_energy(M: np.ndarray, nu: np.ndarray) -> float:
    """½ νᵀ M ν in J."""
    return 0.5 * float(nu @ M @ nu)
