"""First-principles estimates of a small vessel's hull and propulsor coefficients from its own
geometry: the priors identification starts from and returns to where the recordings say nothing.

Each function is one published method, pure (no MuJoCo, no files), in Fossen's sign convention
(a dissipative coefficient is negative) and the names of physics.damping:

- `ittc57_cf`: the ITTC-1957 model-ship correlation line, C_F = 0.075/(log10 Re − 2)² [ITTC-1957].
- `resistance_curve`: R(u) = ½ρS[(1 + k)C_F(Re) + C_R]u² with a residuary coefficient C_R (wave
  making) that holds a stated top speed at full thrust, and the Xu, Xuu of physics.damping that
  follow it most closely over the speed range (least squares).
- `slender_hull_derivatives`: Clarke, Gedling and Hine's regressions of the linear manoeuvring
  derivatives on L, B, T and C_B [Clarke-1983], for one hull; they grow with the forward speed U
  (Y_v = ½ρL²U·Y'_v, ...), so they are the speed-proportional terms Yuv, Yur, Nuv, Nur. The
  ideal-fluid parts that the engine already applies through the added-mass Coriolis matrix C_A
  (the Munk moment (Y_v̇ − X_u̇)uv in N_v, X_u̇ur in Y_r) are taken out so they are not counted
  twice [Fossen-2021 §6.4].
- `propulsor_lateral`: a thruster moving sideways through the water at v_lat turns the lateral
  momentum of the flow it swallows (ṁ = ρA_pU through the propeller disc: ρA_pU·v_lat, momentum
  theory [Glauert-1935]) and its duct sheds lift as a slender ring (the lateral added mass of a
  ring of outer diameter D, ρπD²/4 per unit length, carried past its trailing edge at U:
  ρπD²U/4·v_lat [Newman-1977 §7.9]). At a thruster at (x_t, y_t), v_lat = v + x_t·r.
- `propulsor_at_rest`: the same momentum turned by a thruster working at rest, whose disc
  passes its own induced flow: linear Yv, Yr, Nv, Nr at a stated thrust.
- `cross_flow_drag`: the hull's quadratic sway and yaw damping by strip theory,
  Y = −½ρC_D∫T(x)|v + xr|(v + xr)dx and N its moment [Fossen-2021 §6.4.4; Hoerner-1965 for C_D]:
  Yvv and Nrr along each axis exactly; the cross terms are not estimated.
- `twin_hull_yaw`: two hulls at ±s from the centreline meet the water at u ∓ r·s, so their surge
  resistance differs by −2s²r·dR_h/du: a yaw damping s²·Xu + 2s²·Xuu·|u| (R_h = R/2 per hull).
- `lateral_profile`: a hull mesh's draft T(x) along its length below a waterline (the strip
  widths the integrals above use).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

NU_FRESH_M2_S = 1.0e-6  # kinematic viscosity of fresh water near 20 °C [ITTC-2011]


@dataclass(frozen=True)
class Design:
    """What a vessel's first-principles estimate needs beyond its MJCF (the `design` block of a
    vessel file): the top speed at full thrust in calm water and where that figure comes from,
    the hull form factor 1 + k, the cross-flow drag coefficient of its sections, its thrusters'
    duct and propeller diameters (0 where there is no duct) and the battery voltage its T200
    thrusters run on (None: the map's own)."""

    top_speed_m_s: float
    top_speed_source: str = ""
    form_factor: float = 1.2
    cross_flow_cd: float = 1.0
    duct_diameter_m: float = 0.0
    propeller_diameter_m: float = 0.0
    battery_v: float | None = None  # the supply the thrust map is scaled to (T200 curves per voltage)


def ittc57_cf(reynolds) -> np.ndarray:
    """C_F of the ITTC-1957 line at Reynolds number(s) Re = uL/ν, on arrays: physics.mmg.ittc57_cf's
    line and floor (Re at least 1e3, where the line is finite; at 100 it divides by zero)."""
    re = np.maximum(np.asarray(reynolds, float), 1e3)
    return 0.075 / (np.log10(re) - 2.0) ** 2


@dataclass(frozen=True)
class ResistanceCurve:
    """R(u) = ½ρS[(1 + k)C_F(uL/ν) + C_R]u² and the Xu, Xuu (N s/m, N s²/m²) of physics.damping
    closest to it over [0, top speed]."""

    wetted_m2: float
    length_m: float
    form_factor: float  # 1 + k
    residuary_cr: float
    rho_kg_m3: float
    xu: float
    xuu: float

    def resistance_n(self, u_m_s) -> np.ndarray:
        u = np.abs(np.asarray(u_m_s, float))
        cf = ittc57_cf(u * self.length_m / NU_FRESH_M2_S)
        return 0.5 * self.rho_kg_m3 * self.wetted_m2 * (self.form_factor * cf + self.residuary_cr) * u ** 2


def resistance_curve(wetted_m2: float, length_m: float, form_factor: float, top_speed_m_s: float,
                     thrust_at_top_n: float, rho_kg_m3: float = 1000.0) -> ResistanceCurve:
    """The resistance curve whose total at `top_speed_m_s` equals the full thrust there
    (`thrust_at_top_n`, N): friction from the ITTC-1957 line with the form factor, the rest
    residuary (C_R ≥ 0); Xu, Xuu by least squares on 50 speeds in (0, top speed]."""
    u_top = float(top_speed_m_s)
    cf_top = float(ittc57_cf(u_top * length_m / NU_FRESH_M2_S))
    q = 0.5 * rho_kg_m3 * wetted_m2 * u_top ** 2
    cr = max(0.0, thrust_at_top_n / q - form_factor * cf_top)
    curve = ResistanceCurve(wetted_m2, length_m, form_factor, cr, rho_kg_m3, 0.0, 0.0)
    u = np.linspace(u_top / 50, u_top, 50)
    basis = np.column_stack([u, u * u])
    (a, b), *_ = np.linalg.lstsq(basis, curve.resistance_n(u), rcond=None)
    return ResistanceCurve(wetted_m2, length_m, form_factor, cr, rho_kg_m3, -float(a), -float(b))


@dataclass(frozen=True)
class SpeedDerivatives:
    """Linear sway-yaw derivatives divided by the forward speed (physics.damping): Yuv (N s²/m²),
    Yur (N s²/m), Nuv (N s²/m), Nur (N m s²/m); with the added-mass parts Yvdot (kg), Nrdot (kg m²)
    where the method gives them."""

    Yuv: float
    Yur: float
    Nuv: float
    Nur: float
    Yvdot: float = 0.0
    Nrdot: float = 0.0

    def __add__(self, other: "SpeedDerivatives") -> "SpeedDerivatives":
        return SpeedDerivatives(*(getattr(self, f) + getattr(other, f) for f in
                                  ("Yuv", "Yur", "Nuv", "Nur", "Yvdot", "Nrdot")))


def slender_hull_derivatives(length_m: float, beam_m: float, draft_m: float, block_coefficient: float,
                             rho_kg_m3: float = 1000.0) -> SpeedDerivatives:
    """One hull's linear derivatives per unit forward speed [Clarke-1983] (the ideal-fluid parts the
    engine's C_A applies still inside: see `without_added_mass_coriolis`), and its sway and yaw
    added mass from the same regressions."""
    L, B, T, cb = length_m, beam_m, draft_m, block_coefficient
    k = math.pi * (T / L) ** 2
    yv = -k * (1.0 + 0.40 * cb * B / T)
    yr = -k * (-0.5 + 2.2 * B / L - 0.080 * B / T)
    nv = -k * (0.5 + 2.4 * T / L)
    nr = -k * (0.25 + 0.039 * B / T - 0.56 * B / L)
    yvdot = -k * (1.0 + 0.16 * cb * B / T - 5.1 * (B / L) ** 2)
    nrdot = -k * (1.0 / 12.0 + 0.017 * cb * B / T - 0.33 * B / L)
    half = 0.5 * rho_kg_m3
    return SpeedDerivatives(half * L ** 2 * yv, half * L ** 3 * yr, half * L ** 3 * nv, half * L ** 4 * nr,
                            half * L ** 3 * yvdot, half * L ** 5 * nrdot)


def without_added_mass_coriolis(d: SpeedDerivatives, xudot: float, yvdot: float) -> SpeedDerivatives:
    """Linear derivatives with the parts the added-mass Coriolis matrix already gives taken out:
    C_A makes Y = X_u̇·u·r and N = (Y_v̇ − X_u̇)·u·v [Fossen-2021], so what the damping must
    add is Y_r − X_u̇ and N_v − (Y_v̇ − X_u̇) per unit speed."""
    return SpeedDerivatives(d.Yuv, d.Yur - xudot, d.Nuv - (yvdot - xudot), d.Nur, d.Yvdot, d.Nrdot)


def propulsor_lateral(x_m: float, duct_diameter_m: float, propeller_diameter_m: float,
                      rho_kg_m3: float = 1000.0) -> SpeedDerivatives:
    """The lateral force of one thruster at x_m (m, body x) per unit forward speed: −(ρπD_d²/4 +
    ρπD_p²/4)·U·(v + x·r) (module docstring), as Yuv, Yur, Nuv, Nur."""
    c = rho_kg_m3 * math.pi / 4.0 * (duct_diameter_m ** 2 + propeller_diameter_m ** 2)
    return SpeedDerivatives(-c, -c * x_m, -c * x_m, -c * x_m ** 2)


def propulsor_at_rest(x_m: float, propeller_diameter_m: float, thrust_n: float, rho_kg_m3: float = 1000.0
                      ) -> tuple[float, float, float, float]:
    """(Yv N s/m, Yr N s, Nv N s, Nr N m s): the lateral momentum a thruster at x_m turns when it
    works at rest, its disc passing ṁ = ρA_p·w with w = √(T/(2ρA_p)) the actuator disc's induced
    velocity at thrust T [Glauert-1935]: −ṁ·(v + x·r) at its site."""
    area = math.pi * propeller_diameter_m ** 2 / 4.0
    if area <= 0.0:  # no propeller disc given (a design block's 0): no flow turned
        return 0.0, 0.0, 0.0, 0.0
    mdot = rho_kg_m3 * area * math.sqrt(max(thrust_n, 0.0) / (2.0 * rho_kg_m3 * area))
    return -mdot, -mdot * x_m, -mdot * x_m, -mdot * x_m ** 2


def cross_flow_drag(x_m: np.ndarray, draft_m: np.ndarray, c_d: float, rho_kg_m3: float = 1000.0
                    ) -> tuple[float, float]:
    """(Yvv N s²/m², Nrr N m s²) of one hull by strip theory: −½ρC_D∫T dx and −½ρC_D∫T|x|³dx over
    the stations x_m (m, body x about the centre of rotation) with drafts draft_m (m)."""
    x, t = np.asarray(x_m, float), np.asarray(draft_m, float)
    half = 0.5 * rho_kg_m3 * c_d
    return -half * float(np.trapezoid(t, x)), -half * float(np.trapezoid(t * np.abs(x) ** 3, x))


def twin_hull_yaw(half_spacing_m: float, xu: float, xuu: float) -> tuple[float, float]:
    """(ΔNr N m s, ΔNur N m s²/m): the yaw damping of two hulls at ±s whose surge resistance
    (Xu, Xuu for both together) acts at u ∓ r·s (module docstring), to first order in r."""
    s2 = half_spacing_m ** 2
    return s2 * xu, 2.0 * s2 * xuu


def lateral_profile(vertices: np.ndarray, faces: np.ndarray, z_waterline_m: float, stations: int = 60
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(x (m), T(x) (m)): the draft below the waterline (body z down) at `stations` stations along
    the mesh's length, from the edges of its triangles crossing each station's plane."""
    tris = vertices[faces]
    x0, x1 = float(vertices[:, 0].min()), float(vertices[:, 0].max())
    xs = np.linspace(x0, x1, stations + 2)[1:-1]
    depth = np.zeros(len(xs))
    for i, xc in enumerate(xs):
        d = tris[:, :, 0] - xc
        deepest = -np.inf
        for a, b in ((0, 1), (1, 2), (2, 0)):
            cross = (d[:, a] > 0) != (d[:, b] > 0)
            if cross.any():
                s = d[cross, a] / (d[cross, a] - d[cross, b])
                z = tris[cross, a, 2] + s * (tris[cross, b, 2] - tris[cross, a, 2])
                deepest = max(deepest, float(z.max()))
        depth[i] = max(0.0, deepest - z_waterline_m) if np.isfinite(deepest) else 0.0
    return np.concatenate([[x0], xs, [x1]]), np.concatenate([[0.0], depth, [0.0]])
