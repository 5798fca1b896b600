"""Hydrodynamic damping D(ν)ν with linear and quadratic terms [Morel-2024 eq. 7],
plus the speed-proportional sway and yaw terms of manoeuvring theory.

Fossen's sign convention: the coefficients of a dissipative hull are negative
(Xu < 0, Xuu < 0, ...), and D(ν) = -[...] is positive.
Names: `Xuu` is X_{|u|u}, `Yrv` is Y_{|r|v}, `Yvr` is Y_{|v|r}, and so on.

`Yuv` (Y_{|u|v}) and `Nur` (N_{|u|r}): a hull moving ahead at u meets sway and yaw
with lift-like forces, so its linear sway and yaw derivatives grow with the speed
(Y_v = Y_v'·½ρL²U, N_r = N_r'·½ρL⁴U in non-dimensional manoeuvring form; Fossen
2011 §6.4). [Morel-2024 eq. 7] has no such term: it is zero in every vessel file unless
identification asks for it.

`Yur` (Y_{ur}) and `Nuv` (N_{uv}): the sway-yaw coupling of the same lift, Y_r = Y_r'·½ρL³U and
N_v = N_v'·½ρL³U. Signed u, not |u|: the hull's lift acts towards its leading end, which is the
stern when it goes astern, so the coupling changes sign with the direction of travel (the
direct terms above do not). A light slender hull has Y_r' larger than its non-dimensional mass
m' (KVLCC2: Y_r' 0.083 against m' 0.18; a 15-kg catamaran of 1.2 m: m' ≈ 0.02), so in a turn it
slips inwards, against the centrifugal (m − X_u̇)·u·r that alone makes it slip outwards.

`astern_excess` (dimensionless, 0 in every vessel file unless a diagnosis or identification asks for
it): going astern (u < 0) the surge damping is (1 + astern_excess)·(Xu + Xuu·|u|)·u. A hull drawn to
go ahead meets the water with its transom when it backs, and resists more than ahead at the same
speed; [Morel-2024 eq. 7] has one curve for both directions. Dissipative for astern_excess > −1.
"""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np


@dataclass(frozen=True)
class Damping:
    """The hull's damping coefficients in Fossen's signs (module docstring: a dissipative hull has
    Xu, Xuu, Yv, Nr ≤ 0), linear (N s/m, N m s/rad), quadratic (N s²/m², ...) and speed-grown
    (Yuv, Yur, Nuv, Nur); `astern_excess` dimensionless."""

    Xu: float = 0.0
    Xuu: float = 0.0
    Yv: float = 0.0
    Yvv: float = 0.0
    Yrv: float = 0.0
    Yr: float = 0.0
    Yvr: float = 0.0
    Yrr: float = 0.0
    Nv: float = 0.0
    Nvv: float = 0.0
    Nrv: float = 0.0
    Nr: float = 0.0
    Nvr: float = 0.0
    Nrr: float = 0.0
    Yuv: float = 0.0
    Nur: float = 0.0
    Yur: float = 0.0
    Nuv: float = 0.0
    astern_excess: float = 0.0

    def surge_factor(self, u):
        """1 ahead, 1 + astern_excess astern (u < 0): the share of the surge drag curve that acts."""
        return np.where(np.asarray(u) < 0.0, 1.0 + self.astern_excess, 1.0)

    @classmethod
    def names(cls) -> list[str]:
        return [f.name for f in fields(cls)]

    def matrix(self, nu: np.ndarray) -> np.ndarray:
        """D(ν) of [Morel-2024 eq. 7]."""
        au, av, ar = np.abs(nu)
        u = nu[0]
        return -np.array(
            [
                [(self.Xu + self.Xuu * au) * float(self.surge_factor(u)), 0.0, 0.0],
                [0.0, self.Yv + self.Yvv * av + self.Yrv * ar + self.Yuv * au,
                 self.Yr + self.Yvr * av + self.Yrr * ar + self.Yur * u],
                [0.0, self.Nv + self.Nvv * av + self.Nrv * ar + self.Nuv * u,
                 self.Nr + self.Nvr * av + self.Nrr * ar + self.Nur * au],
            ]
        )

    def linear_matrix(self) -> np.ndarray:
        """D at ν = 0: the linear part that fixes the low-speed behaviour."""
        return self.matrix(np.zeros(3))


def damping_force(damping: Damping, nu: np.ndarray) -> np.ndarray:
    """D(ν)ν, the vector the equations of motion subtract."""
    return damping.matrix(nu) @ nu


def _directions() -> np.ndarray:
    grid = np.array([(a, b, c) for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1)], dtype=float)
    grid = grid[np.any(grid != 0, axis=1)]
    return grid / np.linalg.norm(grid, axis=1, keepdims=True)


_DIRECTIONS = _directions()


def dissipated_power(damping: Damping, nu: np.ndarray) -> np.ndarray:
    """νᵀD(ν)ν for each row of nu (K, 3): the power the damping takes out (W), D of eq. 7."""
    u, v, r = nu.T
    au, av, ar = np.abs(u), np.abs(v), np.abs(r)
    d = damping
    surge = (d.Xu + d.Xuu * au) * u * d.surge_factor(u)
    sway = (d.Yv + d.Yvv * av + d.Yrv * ar + d.Yuv * au) * v + (d.Yr + d.Yvr * av + d.Yrr * ar + d.Yur * u) * r
    yaw = (d.Nv + d.Nvv * av + d.Nrv * ar + d.Nuv * u) * v + (d.Nr + d.Nvr * av + d.Nrr * ar + d.Nur * au) * r
    return -(u * surge + v * sway + r * yaw)


def is_dissipative(damping: Damping, speeds=(0.05, 0.5, 2.0, 5.0)) -> bool:
    """True when νᵀD(ν)ν ≥ 0 on a fixed sphere of directions at several speeds.

    D(ν) mixes |u|, |v| and |r| factors, so positivity is checked on a
    deterministic set of 26 directions (cube faces, edges and corners) rather
    than by a closed form.
    """
    nu = (np.asarray(speeds, dtype=float)[:, None, None] * _DIRECTIONS[None]).reshape(-1, 3)
    return bool(np.all(dissipated_power(damping, nu) >= -1e-12))
