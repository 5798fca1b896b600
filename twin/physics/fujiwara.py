"""Wind loads on a ship by the regression of [Fujiwara-1998]: a Fourier series in the
relative wind angle whose ten coefficients follow from the above-water geometry.

    X_A = C_X q A_F,  Y_A = C_Y q A_L,  N_A = C_N q A_L L   (about midship),  q = ½ρ_a U_A²
    C_X = X0 + X1 cos γ + X3 cos 3γ + X5 cos 5γ
    C_Y = Y1 sin γ + Y3 sin 3γ + Y5 sin 5γ
    C_N = N1 sin γ + N2 sin 2γ + N3 sin 3γ

γ is the twin's relative wind angle (environment.wind_force): γ = −atan2(v_rw, u_rw) with
(u_rw, v_rw) the ship's velocity relative to the air, so γ = 0 for a head wind and γ = +90° for
a wind from port; it equals 2π minus the "from" angle measured clockwise from the bow that the
Esso data log (wind_dir_relative_mid), which is the angle of attack the regression is written
in. A head wind gives C_X < 0 (pushes aft), a wind from port C_Y > 0 (pushes to starboard).

The simple `environment.WindLoad` (c_x, c_y, c_n) is this series' first harmonics (c_x = −X1,
c_y = Y1, c_n = N2) without X0, X3, X5, Y3, Y5, N1, N3; it stays the model of the other vessels.

The regression's geometry: L (m, length overall, here L_pp), B (m, breadth), A_F and A_L (m²,
frontal and lateral projected areas above the waterline), A_OD (m², lateral area of the
superstructure), C (m, distance of the lateral area's centroid from midship, + forward), LCBR
(m, of the superstructure's), HBR (m, height of the top of the superstructure), HC (m, height
of the lateral area's centroid).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

COEFFICIENTS = ("X0", "X1", "X3", "X5", "Y1", "Y3", "Y5", "N1", "N2", "N3")
SIZE = 4 + len(COEFFICIENTS)  # packed: A_F, A_L, L, ρ_a, then COEFFICIENTS


@dataclass(frozen=True)
class FujiwaraWind:
    """Above-water geometry (module docstring), air density and the ten coefficients.

    coefficients None: the regression's values for this geometry (`resolved`); given: used as
    they are (identification may fit them), in the order of COEFFICIENTS."""

    frontal_area_m2: float = 0.0
    lateral_area_m2: float = 0.0
    length_m: float = 0.0
    breadth_m: float = 0.0
    superstructure_area_m2: float = 0.0  # A_OD
    centroid_x_m: float = 0.0  # C
    superstructure_x_m: float = 0.0  # LCBR
    superstructure_height_m: float = 0.0  # HBR
    centroid_height_m: float = 0.0  # HC
    rho_air_kg_m3: float = 1.225
    coefficients: tuple[float, ...] | None = None

    def resolved(self) -> "FujiwaraWind":
        """This load with its coefficients: the given ones, else the regression's."""
        if self.coefficients is not None:
            return self
        return replace(self, coefficients=regression(self))


def regression(g: FujiwaraWind) -> tuple[float, ...]:
    """The ten coefficients of [Fujiwara-1998] for the geometry g (order COEFFICIENTS)."""
    L, B, AF, AL = g.length_m, g.breadth_m, g.frontal_area_m2, g.lateral_area_m2
    AOD, C, LCBR = g.superstructure_area_m2, g.centroid_x_m, g.superstructure_x_m
    HBR, HC = g.superstructure_height_m, g.centroid_height_m
    x0 = -0.330 + 0.293 * (B * HBR / AF) + 0.0193 * (C / HC) + 0.682 * (AOD / L**2)
    x1 = (-1.353 + 1.700 * (AL / (L * B)) + 2.870 * (L * HC / AL) - 0.463 * (L * HBR / AL) - 0.570 * (AOD / AL)
          - 6.640 * (AF / (L * B)) - 0.0123 * (L**2 / AF) + 0.0202 * (L / HC))
    x3 = (0.830 - 0.413 * (AL / (L * HBR)) - 0.0827 * (AL / AF) - 0.563 * (L * HC / AL) + 0.804 * (AOD / AL)
          - 5.670 * (AOD / L**2) + 0.0401 * (C / HC) - 0.132 * (LCBR / L))
    x5 = 0.0372 - 0.0075 * (AL / AOD) - 0.103 * (LCBR / L) + 0.0921 * (AL / (L * B))
    y1 = (0.684 + 0.717 * (LCBR / L) - 3.220 * (C / L) + 0.0281 * (AL / AOD) + 0.0661 * (C / HC)
          + 0.298 * (AF / (B * HBR)))
    y3 = (-0.400 + 0.282 * (AL / (L * B)) + 0.307 * (L * HC / AL) + 0.0519 * (LCBR / L) + 0.0526 * (B / HBR)
          - 0.0814 * (AOD / AL) + 0.0582 * (AF / (B * HBR)))
    y5 = (0.122 - 0.166 * (AL / (L * B)) - 0.0054 * (L / HBR) - 0.0481 * (LCBR / L) - 0.0136 * (B**2 / AF)
          + 0.0864 * (C / L) - 0.0297 * (C * HC / AL))
    n1 = (0.299 + 1.710 * (C / L) + 0.183 * (L * HC / AL) - 1.09 * (AF / AL) - 0.0442 * (C / HC)
          - 0.289 * (AL / (L * B)) + 4.24 * (AF / L**2) - 0.0646 * (B**2 / AF) + 0.0306 * (LCBR / L))
    n2 = (0.117 + 0.123 * (LCBR / L) - 0.323 * (C / L) + 0.0041 * (AL / AOD) - 0.166 * (AF / B**2)
          - 0.0109 * (L / HBR) + 0.174 * (AF / (B * HBR)) + 0.214 * (AL / (L * B)) - 1.06 * (AL / L**2))
    n3 = 0.0230 + 0.0385 * (LCBR / L) - 0.0339 * (AF / (B * HBR)) + 0.0023 * (AL / AF)
    return tuple(float(x) for x in (x0, x1, x3, x5, y1, y3, y5, n1, n2, n3))


def pack(load: FujiwaraWind) -> np.ndarray:
    """[A_F, A_L, L, ρ_a, X0 ... N3] for `wind_force`."""
    c = load.resolved().coefficients
    return np.array([load.frontal_area_m2, load.lateral_area_m2, load.length_m, load.rho_air_kg_m3, *c], float)


def coefficients_at(p, gamma: float) -> tuple[float, float, float]:
    """(C_X, C_Y, C_N) at the relative wind angle γ (rad) from the packed load p."""
    cx = p[4] + p[5] * math.cos(gamma) + p[6] * math.cos(3.0 * gamma) + p[7] * math.cos(5.0 * gamma)
    cy = p[8] * math.sin(gamma) + p[9] * math.sin(3.0 * gamma) + p[10] * math.sin(5.0 * gamma)
    cn = p[11] * math.sin(gamma) + p[12] * math.sin(2.0 * gamma) + p[13] * math.sin(3.0 * gamma)
    return cx, cy, cn


def wind_force(p, cos_psi: float, sin_psi: float, u: float, v: float, wind_north: float, wind_east: float):
    """(X_A, Y_A, N_A) in the body frame (N, N, N m, about midship) for the packed load p, heading
    (cos ψ, sin ψ), body velocity (u, v) over ground and the air's velocity over ground (NED, m/s,
    where the air goes). A plain float function, compiled as it is by numba for the native callback."""
    u_w = cos_psi * wind_north + sin_psi * wind_east
    v_w = -sin_psi * wind_north + cos_psi * wind_east
    u_rw = u - u_w
    v_rw = v - v_w
    q = 0.5 * p[3] * (u_rw * u_rw + v_rw * v_rw)
    g = -math.atan2(v_rw, u_rw)
    cx = p[4] + p[5] * math.cos(g) + p[6] * math.cos(3.0 * g) + p[7] * math.cos(5.0 * g)
    cy = p[8] * math.sin(g) + p[9] * math.sin(3.0 * g) + p[10] * math.sin(5.0 * g)
    cn = p[11] * math.sin(g) + p[12] * math.sin(2.0 * g) + p[13] * math.sin(3.0 * g)
    return cx * q * p[0], cy * q * p[1], cn * q * p[1] * p[2]
