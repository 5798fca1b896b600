"""Inertia: rigid-body and hydrodynamic added mass ([Yellowfish-TR eq. 14], [Morel-2024 eq. 5]).

The added mass acts through the *relative* acceleration ν̇_r; how it is applied
exactly inside MuJoCo (no lagged acceleration) is in `hydrodynamics.py`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import quad
from scipy.special import elliprd


@dataclass(frozen=True)
class AddedMass:
    """Hydrodynamic derivatives in Fossen's notation (negative for a real hull).

    Units: Xudot, Yvdot in kg; Yrdot, Nvdot in kg·m; Nrdot in kg·m².
    """

    Xudot: float = 0.0
    Yvdot: float = 0.0
    Yrdot: float = 0.0
    Nvdot: float = 0.0
    Nrdot: float = 0.0

    def matrix(self) -> np.ndarray:
        """M_A = -[[Xu̇,0,0],[0,Yv̇,Yṙ],[0,Nv̇,Nṙ]] [Yellowfish-TR eq. 14]."""
        return 0.0 - np.array(
            [[self.Xudot, 0.0, 0.0], [0.0, self.Yvdot, self.Yrdot], [0.0, self.Nvdot, self.Nrdot]]
        )


@dataclass(frozen=True)
class RigidBody:
    """Planar rigid-body inertia about the body origin CO.

    mass_kg, CG offset (xg_m, yg_m) from CO, yaw inertia Iz_kgm2 about CO's z axis.
    """

    mass_kg: float
    xg_m: float
    yg_m: float
    Iz_kgm2: float

    def matrix(self) -> np.ndarray:
        """M_RB ([Yellowfish-TR eq. 14], with the yg terms of Fossen's general form)."""
        m = self.mass_kg
        return np.array(
            [
                [m, 0.0, -m * self.yg_m],
                [0.0, m, m * self.xg_m],
                [-m * self.yg_m, m * self.xg_m, self.Iz_kgm2],
            ]
        )


def total_mass_matrix(rigid: RigidBody, added: AddedMass) -> np.ndarray:
    """M = M_RB + M_A ([Yellowfish-TR eq. 11; Morel-2024 eq. 5])."""
    return rigid.matrix() + added.matrix()


def is_symmetric_positive_definite(M: np.ndarray, tol: float = 1e-9) -> bool:
    if not np.allclose(M, M.T, atol=tol * max(1.0, np.abs(M).max())):
        return False
    return bool(np.all(np.linalg.eigvalsh(0.5 * (M + M.T)) > 0.0))


def ellipsoid_lamb_coefficients(a_m: float, b_m: float, c_m: float) -> tuple[float, float, float]:
    """α0, β0, γ0 of [Yellowfish-TR eq. 22-23] by numerical quadrature.

    α0 = abc ∫₀^∞ dλ / ((a²+λ)Δ),  Δ = √((a²+λ)(b²+λ)(c²+λ)); β0, γ0 alike.
    Their sum is 2 for any ellipsoid, which the tests use as a check.
    """
    def delta(lam):
        return np.sqrt((a_m**2 + lam) * (b_m**2 + lam) * (c_m**2 + lam))

    abc = a_m * b_m * c_m
    return tuple(
        abc * quad(lambda lam, s=s: 1.0 / ((s**2 + lam) * delta(lam)), 0.0, np.inf, epsabs=1e-14, epsrel=1e-12)[0]
        for s in (a_m, b_m, c_m)
    )


def ellipsoid_lamb_coefficients_closed_form(a_m: float, b_m: float, c_m: float) -> tuple[float, float, float]:
    """The same integrals in closed form with Carlson's R_D: α0 = ⅔abc·R_D(b², c², a²)."""
    abc = a_m * b_m * c_m
    a2, b2, c2 = a_m**2, b_m**2, c_m**2
    return (2 / 3 * abc * elliprd(b2, c2, a2), 2 / 3 * abc * elliprd(c2, a2, b2), 2 / 3 * abc * elliprd(a2, b2, c2))


def ellipsoid_added_mass(a_m: float, b_m: float, c_m: float, rho_kg_m3: float) -> dict[str, float]:
    """Xu̇, Yv̇, Nṙ of one submerged ellipsoid [Yellowfish-TR eq. 21]."""
    alpha, beta, _ = ellipsoid_lamb_coefficients(a_m, b_m, c_m)
    displaced = 4.0 / 3.0 * np.pi * rho_kg_m3 * a_m * b_m * c_m
    d2 = a_m**2 - b_m**2
    denominator = 2 * d2 + (a_m**2 + b_m**2) * (alpha - beta)
    # a body of revolution about z (a = b) has no added yaw inertia: the 0/0 limit is 0
    n_rdot = 0.0 if abs(denominator) < 1e-15 else -0.2 * d2**2 * (beta - alpha) / denominator * displaced
    return {
        "alpha0": alpha,
        "beta0": beta,
        "Xudot": -alpha / (2 - alpha) * displaced,
        "Yvdot": -beta / (2 - beta) * displaced,
        "Nrdot": n_rdot,
    }


def half_body_added_mass(a_m: float, b_m: float, draft_m: float, rho_kg_m3: float) -> dict[str, float]:
    """Xu̇, Yv̇, Nṙ of a hull piercing the free surface, taken as the lower half of an ellipsoid
    of semi-axes a, b (half its waterline length and breadth) and c = its draft.

    At the low frequencies of manoeuvring the free surface acts as a rigid wall (the potential's
    vertical derivative vanishes on it), so the flow about the half-body in the surface is the
    flow about the double body (the whole ellipsoid, mirrored in the surface) cut in two, and it
    carries half the double body's added mass [Newman-1977 ch. 4]. The half-ellipsoid displaces
    ⅔πabc, the hull's own volume when its block coefficient is near π/6. [Yellowfish-TR eq. 21]
    (ellipsoid_added_mass) takes the whole ellipsoid as submerged, which doubles it."""
    whole = ellipsoid_added_mass(a_m, b_m, draft_m, rho_kg_m3)
    return {**whole, **{k: 0.5 * whole[k] for k in ("Xudot", "Yvdot", "Nrdot")}}


def catamaran_added_mass_as_printed(single: dict[str, float], hull_mass_kg: float, hull_spacing_m: float) -> dict:
    """[Yellowfish-TR eq. 25] as printed: Xu̇ = 2Xu̇|e, Yv̇ = 2Yv̇|e, Nṙ = Nṙ|e − m_hull·y_m²."""
    return {"Xudot": 2 * single["Xudot"], "Yvdot": 2 * single["Yvdot"],
            "Nrdot": single["Nrdot"] - hull_mass_kg * hull_spacing_m**2}


def catamaran_added_mass_consistent(single: dict[str, float], hull_spacing_m: float,
                                    hull_x_m: float = 0.0) -> dict:
    """Two hulls, each carrying its own ellipsoid added mass, centred at (x_h, ±y_m/2).

    Yawing at r moves each hull centre with surge velocity ∓r·y_m/2 and sway
    velocity r·x_h, so by the parallel-axis theorem for added mass
    Nṙ = 2Nṙ|e + 2Xu̇|e (y_m/2)² + 2Yv̇|e x_h². It is the hulls' *added* masses
    that move, not their rigid mass, which is already in I_z.
    """
    return {"Xudot": 2 * single["Xudot"], "Yvdot": 2 * single["Yvdot"],
            "Nrdot": 2 * single["Nrdot"] + 2 * single["Xudot"] * (hull_spacing_m / 2) ** 2
            + 2 * single["Yvdot"] * hull_x_m**2}
