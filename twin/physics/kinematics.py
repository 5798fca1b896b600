"""Kinematics η̇ = R(ψ)ν ([Yellowfish-TR eq. 12-13], [Morel-2024 eq. 8])."""
from __future__ import annotations

import numpy as np


def rotation(psi_rad: float) -> np.ndarray:
    """R(ψ), the 3×3 rotation from body to NED [Yellowfish-TR eq. 13]."""
    c, s = np.cos(psi_rad), np.sin(psi_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def eta_dot(psi_rad: float, nu: np.ndarray) -> np.ndarray:
    """η̇ = R(ψ)ν."""
    return rotation(psi_rad) @ nu


def body_to_ned(psi_rad: float, vec_xy: np.ndarray) -> np.ndarray:
    """Rotate a planar body-frame vector into NED [Yellowfish-TR eq. 31]."""
    c, s = np.cos(psi_rad), np.sin(psi_rad)
    return np.array([c * vec_xy[0] - s * vec_xy[1], s * vec_xy[0] + c * vec_xy[1]])


def ned_to_body(psi_rad: float, vec_xy: np.ndarray) -> np.ndarray:
    """Rotate a planar NED vector into the body frame [Yellowfish-TR eq. 36]."""
    c, s = np.cos(psi_rad), np.sin(psi_rad)
    return np.array([c * vec_xy[0] + s * vec_xy[1], -s * vec_xy[0] + c * vec_xy[1]])


def wrap_angle(angle_rad):
    """Wrap to (-π, π]."""
    return (np.asarray(angle_rad) + np.pi) % (2 * np.pi) - np.pi
