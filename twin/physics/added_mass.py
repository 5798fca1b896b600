"""Inertia: rigid-body and hydrodynamic added mass (seed 000 eq. 14, seed 004 eq. 5).

The added mass acts through the *relative* acceleration ν̇_r; how it is applied
exactly inside MuJoCo (no lagged acceleration) is in `hydrodynamics.py`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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
        """M_A = -[[Xu̇,0,0],[0,Yv̇,Yṙ],[0,Nv̇,Nṙ]] (seed 000 eq. 14)."""
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
        """M_RB (seed 000 eq. 14, with the yg terms of Fossen's general form)."""
        m = self.mass_kg
        return np.array(
            [
                [m, 0.0, -m * self.yg_m],
                [0.0, m, m * self.xg_m],
                [-m * self.yg_m, m * self.xg_m, self.Iz_kgm2],
            ]
        )


def total_mass_matrix(rigid: RigidBody, added: AddedMass) -> np.ndarray:
    """M = M_RB + M_A (seed 000 eq. 11; seed 004 eq. 5)."""
    return rigid.matrix() + added.matrix()


def is_symmetric_positive_definite(M: np.ndarray, tol: float = 1e-9) -> bool:
    if not np.allclose(M, M.T, atol=tol * max(1.0, np.abs(M).max())):
        return False
    return bool(np.all(np.linalg.eigvalsh(0.5 * (M + M.T)) > 0.0))
