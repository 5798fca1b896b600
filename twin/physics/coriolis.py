"""Coriolis and centripetal terms C(ν)ν [Morel-2024 eq. 6; Fossen-2011 Thm. 3.2].

One skew-symmetric parameterisation serves the rigid body, the added mass and
their sum: with p = M ν the momentum and ν = [u, v, r],

    C(ν) = [[0, 0, -p_v], [0, 0, p_u], [p_v, -p_u, 0]],  p_u = M[0]·ν, p_v = M[1]·ν

which reduces to [Morel-2024 eq. 6] for the paper's M. Skew symmetry makes νᵀC(ν)ν = 0,
so C conserves the kinetic energy ½νᵀMν.

[Bertoni-2024] prints C with (m11·u) in row 2, column 2 instead of column 3; that
matrix is not skew-symmetric and does not conserve energy (see tests), so the
twin does not use it.
"""
from __future__ import annotations

import numpy as np


def coriolis_matrix(M: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """C(ν) for the 3×3 inertia M (rigid, added or total)."""
    p_u = M[0] @ nu
    p_v = M[1] @ nu
    return np.array([[0.0, 0.0, -p_v], [0.0, 0.0, p_u], [p_v, -p_u, 0.0]])


def coriolis_force(M: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """C(ν)ν, the vector the equations of motion subtract."""
    p_u = M[0] @ nu
    p_v = M[1] @ nu
    u, v, r = nu
    return np.array([-r * p_v, r * p_u, u * p_v - v * p_u])


def printed_coriolis_bertoni(M: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """C exactly as [Bertoni-2024] prints it (kept only to show that it is not skew)."""
    u, v, r = nu
    return np.array(
        [
            [0.0, 0.0, -M[1, 1] * v - M[1, 2] * r],
            [0.0, M[0, 0] * u, 0.0],
            [M[1, 1] * v + M[1, 2] * r, -M[0, 0] * u, 0.0],
        ]
    )
