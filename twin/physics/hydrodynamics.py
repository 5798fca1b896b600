"""The 3-DOF equations of motion, assembled from the force modules:

    M ν̇_r + C(ν_r)ν_r + D(ν_r)ν_r = τ_thrust + τ_wind,    ν_r = ν − ν_c,
    ν̇ = ν̇_r + ν̇_c,  η̇ = R(ψ)ν                     ([Yellowfish-TR eq. 12; Morel-2024 eq. 3-7])

with M = M_RB + M_A and C = C_RB + C_A. For an irrotational earth-fixed
current, M_RB ν̇ + C_RB(ν)ν = M_RB ν̇_r + C_RB(ν_r)ν_r [Fossen-2021 Prop. 10.1],
which is what lets the engine keep integrating the true ν while the
hydrodynamic terms see ν_r.

`relative_acceleration` is the analytic model's right-hand side.
`hydrodynamic_force` is the body-frame force the MuJoCo callback adds to the
engine's own rigid-body dynamics. It applies added mass *exactly*: the
acceleration in −M_A ν̇_r is the one the full equation gives at this instant,
not a lagged or filtered estimate, so the engine's M_RB ν̇ + C_RB(ν)ν = X + τ
reproduces the equation above for any ratio of added to rigid mass.

A propeller-and-rudder ship (physics/mmg.py) adds the MMG hull, propeller and rudder forces
τ_MMG(ν_r, n, δ) to the right-hand side; its inputs (n, δ) are the `controls` the caller passes
(the engine's two controls), since its actuators exert no force themselves. Its wind load is
Fujiwara's regression (physics/fujiwara.py) where the vessel has one, else the simple WindLoad.
The MMG equations of motion [MMG-2015 eq. 4] have no Munk moment: it is part
of the measured N'_v, so such a hull's C_A(ν_r)ν_r drops its yaw row (`munk_moment` False);
C_A then keeps +m_y v r in X and −m_x u r in Y, exactly eq. 4's added-mass terms.

`thrusts` (N, left and right, each actuator's static thrust T0 after gain and lag) carry the
propellers' advance loss −c·√|T0|·u_a (physics/thrusters.py) where the vessel has one: it depends
on the thrust and on the flow through each propeller, so it is a hydrodynamic force of the
callback, not a property of the actuator.

`wind_ned` (where the air goes, NED m/s) overrides the environment's constant wind: a measured,
time-varying wind passed in by the engine (from its controls) or the analytic model.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from .coriolis import coriolis_force
from .damping import Damping, damping_force
from .environment import Environment, WindLoad, current_body, current_body_rate, wind_force
from .fujiwara import wind_force as fujiwara_wind_force
from .mmg import mmg_force
from .seakeeping import known_load
from .thrusters import advance_force


@dataclass(frozen=True)
class Terms:
    """Switches for each force term, so that each can be cross-checked alone.

    The rigid-body inertia and its Coriolis terms are always on: they are the
    engine's own dynamics. A propeller-and-rudder ship's inputs always reach its MMG forces,
    which `mmg_hull`, `propeller` and `rudder` switch; `thrust` (the actuators' own force) and
    `damping` (the Fossen damping, zero unless identification adds some) are other terms.
    """

    added_mass: bool = True
    added_mass_coriolis: bool = True
    damping: bool = True
    thrust: bool = True
    current: bool = True
    wind: bool = True
    mmg_hull: bool = True  # MMG hull forces, eqs. 7-8 (a propeller-and-rudder ship only)
    propeller: bool = True  # MMG propeller thrust X_P, eqs. 10-16
    rudder: bool = True  # MMG rudder forces, eqs. 17-27

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
    mmg: np.ndarray | None = None  # physics.mmg.pack(...): the MMG forces of a propeller-and-rudder ship
    wind_regression: np.ndarray | None = None  # physics.fujiwara.pack(...): replaces wind_load
    munk_moment: bool = True  # C_A's yaw row (the Munk moment); False where N'_v holds it (MMG)
    advance_loss: float = 0.0  # c of physics/thrusters.py, √N·s/m
    thruster_y_m: tuple[float, float] = (0.0, 0.0)  # where the advance loss acts

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
    if model.terms.current and model.environment.has_flow:
        nu_c = current_body(psi_rad, model.environment.flow_ned)
    else:
        nu_c = np.zeros(3)
    return nu - nu_c, nu_c


def _external_force(model: HydroModel, psi_rad: float, nu: np.ndarray, nu_r: np.ndarray,
                    tau_thrust: np.ndarray, controls=None, wind_ned=None, thrusts=None) -> np.ndarray:
    """τ_thrust + τ_advance + τ_wind − C_A(ν_r)ν_r − D(ν_r)ν_r + τ_MMG: every force but inertia and C_RB."""
    t = model.terms
    force = np.array(tau_thrust, dtype=float) if t.thrust else np.zeros(3)
    if t.thrust and model.advance_loss and thrusts is not None:
        force = force + advance_force(model.advance_loss, thrusts, nu_r, model.thruster_y_m)
    if wind_on(model, wind_ned):
        air = model.environment.wind_ned if wind_ned is None else np.asarray(wind_ned, float)
        if model.wind_regression is not None:
            c, s = np.cos(psi_rad), np.sin(psi_rad)
            force = force + np.array(fujiwara_wind_force(model.wind_regression, c, s, nu[0], nu[1], air[0], air[1]))
        else:
            force = force + wind_force(model.wind_load, psi_rad, nu, air)
    if model.environment.wave_load:
        force = force + np.array(known_load(np.asarray(model.environment.wave_load, float), psi_rad, nu_r[0]))
    if t.damping:
        force = force - damping_force(model.damping, nu_r)
    if t.added_mass_coriolis:
        ca = coriolis_force(model.M_A, nu_r)
        if not model.munk_moment:
            ca[2] = 0.0
        force = force - ca
    if model.mmg is not None:
        force = force + mmg_forces(model, nu_r, controls)[:3]
    return force


def wind_on(model: HydroModel, wind_ned=None) -> bool:
    """Whether the wind term acts: switched on, and a wind given (a series, or a constant wind)."""
    return model.terms.wind and (wind_ned is not None or model.environment.wind_speed_m_s != 0.0)


def mmg_forces(model: HydroModel, nu_r: np.ndarray, controls=None) -> np.ndarray:
    """(X, Y, N, T, F_N) of physics.mmg for the controls (n rps, δ rad; none: both 0) with the terms'
    switches: the hull, propeller and rudder forces at midship, the thrust and rudder normal force."""
    n, delta = (0.0, 0.0) if controls is None else (float(controls[0]), float(controls[1]))
    t = model.terms
    return np.array(mmg_force(model.mmg, float(nu_r[0]), float(nu_r[1]), float(nu_r[2]), n, delta,
                              t.mmg_hull, t.propeller, t.rudder))


def relative_acceleration(model: HydroModel, psi_rad: float, nu: np.ndarray,
                          tau_thrust: np.ndarray, controls=None, wind_ned=None, thrusts=None) -> np.ndarray:
    """ν̇_r from M ν̇_r = τ − C(ν_r)ν_r − D(ν_r)ν_r (+ τ_advance + τ_wind + τ_MMG)."""
    nu_r, _ = relative_velocity(model, psi_rad, nu)
    rhs = (_external_force(model, psi_rad, nu, nu_r, tau_thrust, controls, wind_ned, thrusts)
           - coriolis_force(model.M_RB, nu_r))
    return model.M_inv @ rhs


def acceleration(model: HydroModel, psi_rad: float, nu: np.ndarray, tau_thrust: np.ndarray,
                 controls=None, wind_ned=None, thrusts=None) -> np.ndarray:
    """ν̇ = ν̇_r + ν̇_c: the analytic model's body-frame acceleration."""
    _, nu_c = relative_velocity(model, psi_rad, nu)
    return (relative_acceleration(model, psi_rad, nu, tau_thrust, controls, wind_ned, thrusts)
            + current_body_rate(nu_c, nu[2]))


def hydrodynamic_force(model: HydroModel, psi_rad: float, nu: np.ndarray,
                       tau_thrust: np.ndarray, controls=None, wind_ned=None, thrusts=None) -> np.ndarray:
    """Body-frame force X the engine must add to its rigid-body dynamics:

    X = −M_A ν̇_r − C_A(ν_r)ν_r − D(ν_r)ν_r + τ_wind, with ν̇_r exact (see module doc).
    `tau_thrust` is the actuator force the engine applies by itself; it enters
    only through ν̇_r. `controls`, `wind_ned`, `thrusts`: see the module docstring.
    """
    nu_r, _ = relative_velocity(model, psi_rad, nu)
    external = _external_force(model, psi_rad, nu, nu_r, tau_thrust, controls, wind_ned, thrusts)
    thrust = np.array(tau_thrust, dtype=float) if model.terms.thrust else np.zeros(3)
    force = external - thrust
    if model.terms.added_mass:
        nu_dot_r = model.M_inv @ (external - coriolis_force(model.M_RB, nu_r))
        force = force - model.M_A @ nu_dot_r
    return force


def kinetic_energy(M: np.ndarray, nu: np.ndarray) -> float:
    """½ νᵀ M ν in J."""
    return 0.5 * float(nu @ M @ nu)
