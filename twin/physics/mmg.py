"""The MMG standard method for a single-propeller, single-rudder ship [MMG-2015]: hull, propeller and rudder forces at midship.

Frames and signs as the rest of the twin: body FRD with the origin at MIDSHIP on the waterline
(the point the MMG equations and every published coefficient refer to), ν = (u, v_m, r) the
midship velocities, δ > 0 turns the ship to starboard (r > 0), n > 0 drives it ahead. The
rigid body (mass at x_G, its Coriolis terms, MMG eq. 4's left side) is MuJoCo's, added mass
is the twin's exact added-mass term (hydrodynamics.py, without the Munk moment: it is inside
N'_v, see `AddedMass.munk_moment`); this module gives X = X_H + X_P + X_R etc. (eq. 5).

Equations, numbered as in the paper (the numbering follows the paper's published layout as far
as this project could check it; the paper text itself was not available: twin/model/esso_osaka.json, its sources):
  hull (eqs. 7-8)      X_H = ½ρL d U² (−R'_0 + X'_vv v'² + X'_vr v'r' + X'_rr r'² + X'_vvvv v'⁴)
                       Y_H = ½ρL d U² (Y'_v v' + Y'_r r' + Y'_vvv v'³ + Y'_vvr v'²r' + Y'_vrr v'r'² + Y'_rrr r'³)
                       N_H = ½ρL²d U² (N'_v v' + N'_r r' + N'_vvv v'³ + N'_vvr v'²r' + N'_vrr v'r'² + N'_rrr r'³)
                       v' = v_m/U, r' = rL/U, U = √(u² + v_m²)
  propeller (eqs. 10-16) X_P = (1 − t_P) T,  T = ρ n² D_P⁴ K_T(J_P),  K_T = k0 + k1 J_P + k2 J_P²,
                       J_P = u (1 − w_P)/(n D_P),
                       1 − w_P = (1 − w_P0)[1 + (1 − exp(−C_1|β_P|))(C_2 − 1)],  β_P = β − x'_P r',
                       C_2 = C_2⁺ for β_P > 0, C_2⁻ otherwise; β = atan(−v_m/u)
  rudder (eqs. 17-27)  X_R = −(1 − t_R) F_N sin δ,  Y_R = −(1 + a_H) F_N cos δ,
                       N_R = −(x_R + a_H x_H) F_N cos δ,  F_N = ½ρ A_R U_R² f_α sin α_R,
                       U_R² = u_R² + v_R²,  α_R = δ − atan(v_R/u_R),  f_α = 6.13Λ/(Λ + 2.25) (Fujii, [MMG-2015 eq. 20]),
                       u_R = ε u_P √(η{1 + κ(√(1 + 8K_T/(πJ_P²)) − 1)}² + (1 − η)),  η = D_P/H_R,
                       v_R = U γ_R β_R,  β_R = β − l'_R r',  γ_R = γ_R⁻ for β_R < 0, γ_R⁺ otherwise

Written so that they stay finite where the standard's own form is not: u_R is the paper's
expression multiplied through by u_P = u(1 − w_P) (identical for u_P > 0, finite at u_P = 0:
ε √(η (u_P + κ(√(u_P² + 8K_T n²D_P²/π) − u_P))² + (1 − η) u_P²)), and T is ρ D_P⁴(k0 n² + k1 n
u_P/D_P + k2 u_P²/D_P²), which is K_T(J)·ρn²D⁴ for n > 0 and the locked propeller's drag at n = 0.

The standard is a forward-speed model (u > 0, n ≥ 0, |β| up to about 30°). A free-running
model in a pond stops, reverses and drifts, so outside that domain this module extends it,
keeping the standard exact inside it (each extension says why; identification may revise them):
  * U → 0: v', r' and U² use U_nd = max(U, low_speed_m_s); above that speed nothing changes,
    below it the forces stay bounded (r'³ U² = r³L³/U would grow without limit);
  * resistance −R'_0 U² is multiplied by f = clip(2u/U, −1, 1): 1 (the standard) for drift
    angles up to 60°, no surge resistance when moving broadside, opposing the motion astern
    (the standard's −R'_0U² would push a ship going astern further astern);
  * astern the hull meets the water stern first. Taken fore-aft symmetric, its forces at (u, v, r)
    with u < 0 are the forward ones at (|u|, v, −r) with X and N reversed: the terms of X even in v'
    and r', of Y odd in r' and of N odd in v' change sign. They are multiplied by f as R'_0 is, so
    the standard stands ahead up to 60° of drift, and moving broadside a hull turns no sway into yaw
    nor yaw into sway, as a symmetric hull does not. (The standard's polynomial, taken as it is
    astern, turns the Munk moment's sign: a hull backing with a drift yawed the wrong way.);
  * beyond the drift domain (|β| above `drift_domain_deg`, 30°; its captive tests stay within about
    that) the hull polynomial's powers of v' continue along their tangents at the domain's edge s =
    sin 30°: v'^k → s^(k−1)·(k|v'| − (k−1)s) with v'^k's sign, its value and slope kept there. Taken
    as it is, the cubic fitted within ±30° grows as |v'|³ where a hull's cross-flow drag grows as
    v|v| [Hoerner-1965]: the KVLCC2 coefficients gave a broadside sway force of Y' = −1.92 (a
    cross-flow drag coefficient near 1 gives about −1), and a yaw damping N'_vvr v'² at 60° of drift
    4.5 times N'_r. Continued, they give −1.12 and 3.7 times. A pond's free-running model drifts
    beyond 30° for much of a slow manoeuvre (a third of the Esso Osaka's random tests' samples);
  * β = atan2(−v_m, |u|) (the standard's β for u ≥ 0; astern the drift angle is measured from
    the stern), 1 − w_P = 1 for u < 0 (no wake ahead of the propeller when going astern);
  * n < 0 (astern rotation, not in the standard): T = −ρ n² D_P⁴ K_astern, K_astern =
    clip(c0 + c1 u/(|n| D_P), 0, c_max), X_P = T (no thrust deduction), the Esso 3 m set's
    reverse-propeller form [NAOE-MMG-SIM]; no slipstream on the rudder;
  * n < 0 also pushes the stern sideways (a single screw backing: the paddle-wheel effect, which
    swings a right-handed ship's bow to starboard): Y_P = ½ρL d (nD_P)² Y*_P(J_s), N_P =
    ½ρL²d (nD_P)² N*_P(J_s), J_s = u/(n D_P), each piecewise linear in J_s with knots at −0.35 and
    −0.06 (Hachii's form, the Esso 3 m set's coefficients [NAOE-MMG-SIM] a0..a4, b0..b4: a0 + a1 J_s between
    the knots, a2 + a3 J_s below −0.35, a4 above −0.06, continuous at both); zero for n ≥ 0, where
    the standard has none. As published, the lowest piece changes sign near J_s = −0.84 (a ship
    still running ahead fast on a slowly backing screw: bow to port); it is kept as published;
  * u < 0: the rudder sees the hull's flow from astern, u_R = u + ε κ √η √(8K_T n²D_P²/π),
    continuous with the standard's u_R at u = 0; α_R = δ − atan2(v_R, u_R) then reverses the
    rudder's effect, as a rudder going astern does.
  * n and δ are clipped to the vessel's input bounds here, so the engine and the analytic model
    see the same inputs.

R'_0 across speeds: a model ship's resistance at these Froude numbers is almost all friction,
whose coefficient falls with the Reynolds number, so one R'_0 fitted at one speed over-resists a
faster run and under-resists a slower one. With `friction_factor` F = (1 + k)·S/(L·d) (form factor,
wetted surface) > 0, R'_0(U) = R'_0 + F·[C_F(U_nd·L/ν) − C_F(U_ref·L/ν)], C_F the ITTC-1957 line
[ITTC-1957]: R'_0 is the value at `reference_speed_m_s`, and the friction line carries it to other
speeds. F = 0 keeps the standard's constant R'_0. The friction part is at most the whole: where R'_0
(an identified one, say) is less than F·C_F(U_ref), the rest of the resistance would be negative,
which no hull has; the line's factor is then what is overstated (laminar flow over part of a model
at these Reynolds numbers, or a smaller form factor), and the line carries R'_0 with F' = R'_0/C_F(U_ref),
in proportion to C_F: a resistance below its friction line is not taken further below it with speed.

Every function is a plain function of floats and one float array of parameters (layout FIELDS),
so numba compiles the very same code for the native callback (engine/native.py).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

HULL_FIELDS = ("R0", "Xvv", "Xvr", "Xrr", "Xvvvv", "Yv", "Yr", "Yvvv", "Yvvr", "Yvrr", "Yrrr",
               "Nv", "Nr", "Nvvv", "Nvvr", "Nvrr", "Nrrr")


@dataclass(frozen=True)
class MmgHull:
    """Non-dimensional hull derivatives of eqs. 7-8 (primes dropped): R0 is R'_0 (> 0 resists)."""

    R0: float = 0.0
    Xvv: float = 0.0
    Xvr: float = 0.0
    Xrr: float = 0.0
    Xvvvv: float = 0.0
    Yv: float = 0.0
    Yr: float = 0.0
    Yvvv: float = 0.0
    Yvvr: float = 0.0
    Yvrr: float = 0.0
    Yrrr: float = 0.0
    Nv: float = 0.0
    Nr: float = 0.0
    Nvvv: float = 0.0
    Nvvr: float = 0.0
    Nvrr: float = 0.0
    Nrrr: float = 0.0


@dataclass(frozen=True)
class MmgPropeller:
    """Propeller of eqs. 10-16 and its astern extension (module docstring). Its longitudinal
    position x'_P comes from the MJCF's `propeller` site, not from here."""

    diameter_m: float = 0.0
    k0: float = 0.0
    k1: float = 0.0
    k2: float = 0.0
    tP: float = 0.0  # thrust deduction t_P
    wP0: float = 0.0  # wake fraction in straight motion w_P0
    C1: float = 0.0
    C2_plus: float = 1.0  # C_2 for β_P > 0
    C2_minus: float = 1.0  # C_2 for β_P ≤ 0
    astern_kt0: float = 0.0  # K_astern at u = 0 (n < 0)
    astern_kt1: float = 0.0  # its growth with u/(|n|D_P)
    astern_kt_max: float = 0.0  # its cap
    # the astern side force's Y*_P and N*_P (module docstring): a0..a4 and b0..b4 of Hachii's form
    astern_side_y: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)
    astern_side_n: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)


@dataclass(frozen=True)
class MmgRudder:
    """Rudder of eqs. 17-27. Its longitudinal position x_R comes from the MJCF's `rudder` site."""

    area_m2: float = 0.0  # A_R
    aspect_ratio: float = 1.0  # Λ: f_α (Fujii) and the span H_R = √(A_R Λ), η = D_P/H_R
    tR: float = 0.0  # steering resistance deduction t_R
    aH: float = 0.0  # rudder force increase factor a_H
    xH: float = 0.0  # x'_H, where the hull's share of the rudder force acts, in units of L
    gamma_minus: float = 0.0  # flow straightening γ_R for β_R < 0
    gamma_plus: float = 0.0  # γ_R for β_R ≥ 0
    lR: float = 0.0  # l'_R, effective longitudinal position of the rudder in the yaw term
    epsilon: float = 1.0  # ε = (1 − w_R)/(1 − w_P)
    kappa: float = 0.0  # κ, propeller race acceleration at the rudder


@dataclass(frozen=True)
class MmgModel:
    """The ship's MMG description: water density, principal particulars and the three parts.

    lpp_m and draft_m make the forces dimensional; breadth_m and block_coefficient are the
    particulars the hull mesh and `twin validate` check against (not in the forces).
    """

    rho_kg_m3: float = 998.0
    lpp_m: float = 0.0
    breadth_m: float = 0.0
    draft_m: float = 0.0
    block_coefficient: float = 0.0
    low_speed_m_s: float = 0.05  # U_nd floor of the module docstring
    # the drift angle (deg) up to which the hull's polynomial is the standard's; beyond it each power
    # of v' continues along its tangent (module docstring). 90: the polynomial as it is at every drift
    drift_domain_deg: float = 30.0
    # R'_0 following the ITTC-1957 friction line (module docstring): F = (1 + k)·S/(L·d), 0 = a constant
    # R'_0; R'_0 then holds at reference_speed_m_s
    friction_factor: float = 0.0
    reference_speed_m_s: float = 0.0
    hull: MmgHull = MmgHull()
    propeller: MmgPropeller = MmgPropeller()
    rudder: MmgRudder = MmgRudder()


# ---------------------------------------------------------------- packed parameters

FIELDS = ("rho", "L", "d", "U_min", *HULL_FIELDS, "v_domain",
          "D_P", "k0", "k1", "k2", "tP", "wP0", "C1", "C2_plus", "C2_minus", "xP_nd",
          "astern_kt0", "astern_kt1", "astern_kt_max",
          "ay0", "ay1", "ay2", "ay3", "ay4", "bn0", "bn1", "bn2", "bn3", "bn4",
          "A_R", "f_alpha", "eta", "tR", "aH", "xH_m", "xR_m", "gamma_minus", "gamma_plus", "lR_nd",
          "epsilon", "kappa", "n_min", "n_max", "delta_max", "F_fric", "cf_ref", "L_nu")
INDEX = {name: i for i, name in enumerate(FIELDS)}
SIZE = len(FIELDS)
# index constants: numba reads module globals as compile-time constants
_RHO, _L, _D, _UMIN, _H = 0, 1, 2, 3, 4
(_DP, _K0, _K1, _K2, _TP, _WP0, _C1, _C2P, _C2M, _XP, _KA0, _KA1, _KAMAX, _AR, _FA, _ETA, _TR, _AH, _XH, _XR,
 _GM, _GP, _LR, _EPS, _KAPPA, _NMIN, _NMAX, _DMAX) = (INDEX[k] for k in FIELDS[_H + len(HULL_FIELDS):]
                                                      if not k.startswith(("ay", "bn"))
                                                      and k not in ("F_fric", "cf_ref", "L_nu", "v_domain"))
_AY, _BN, _VDOM = INDEX["ay0"], INDEX["bn0"], INDEX["v_domain"]
_FF, _CFREF, _LNU = INDEX["F_fric"], INDEX["cf_ref"], INDEX["L_nu"]
NU_WATER_M2_S = 1.0e-6  # kinematic viscosity of the water the Reynolds number uses [ITTC-2011]
JS_SYN, JS_SYN0 = -0.35, -0.06  # the knots of Hachii's astern side force in J_s (module docstring)


def fujii_lift_slope(aspect_ratio: float) -> float:
    """f_α = 6.13Λ/(Λ + 2.25), Fujii's rudder normal-force gradient (eq. 20 of the standard)."""
    return 6.13 * aspect_ratio / (aspect_ratio + 2.25)


def pack(model: MmgModel, propeller_x_m: float, rudder_x_m: float,
         n_bounds: tuple[float, float] = (-math.inf, math.inf), delta_max_rad: float = math.inf) -> np.ndarray:
    """The float vector of FIELDS: the vessel file's numbers with the MJCF's propeller and rudder
    positions (x'_P = x_P/L, x_R in m) and the input bounds (rps, rad; inf when none)."""
    p, r, h = model.propeller, model.rudder, model.hull
    span_m = math.sqrt(r.area_m2 * r.aspect_ratio)
    values = {"rho": model.rho_kg_m3, "L": model.lpp_m, "d": model.draft_m, "U_min": model.low_speed_m_s,
              **{k: getattr(h, k) for k in HULL_FIELDS}, "v_domain": math.sin(math.radians(model.drift_domain_deg)),
              "D_P": p.diameter_m, "k0": p.k0, "k1": p.k1, "k2": p.k2, "tP": p.tP, "wP0": p.wP0, "C1": p.C1,
              "C2_plus": p.C2_plus, "C2_minus": p.C2_minus, "xP_nd": propeller_x_m / model.lpp_m,
              "astern_kt0": p.astern_kt0, "astern_kt1": p.astern_kt1, "astern_kt_max": p.astern_kt_max,
              **{f"ay{i}": a for i, a in enumerate(p.astern_side_y)},
              **{f"bn{i}": b for i, b in enumerate(p.astern_side_n)},
              "A_R": r.area_m2, "f_alpha": fujii_lift_slope(r.aspect_ratio),
              "eta": p.diameter_m / span_m if span_m > 0 else 0.0, "tR": r.tR, "aH": r.aH,
              "xH_m": r.xH * model.lpp_m, "xR_m": rudder_x_m, "gamma_minus": r.gamma_minus,
              "gamma_plus": r.gamma_plus, "lR_nd": r.lR, "epsilon": r.epsilon, "kappa": r.kappa,
              "n_min": n_bounds[0], "n_max": n_bounds[1], "delta_max": delta_max_rad,
              "F_fric": friction_line_factor(model),
              "cf_ref": ittc57_cf(model.reference_speed_m_s * model.lpp_m / NU_WATER_M2_S)
              if model.friction_factor > 0 else 0.0,
              "L_nu": model.lpp_m / NU_WATER_M2_S}
    return np.array([float(values[k]) for k in FIELDS])


def friction_line_factor(model: MmgModel) -> float:
    """The factor the friction line carries R'_0 with (module docstring): the vessel file's F, or
    R'_0/C_F(U_ref) where R'_0 is less than F·C_F(U_ref) (a friction part larger than the whole); 0
    without a friction line."""
    f = float(model.friction_factor)
    if f <= 0.0:
        return 0.0
    cf_ref = ittc57_cf(model.reference_speed_m_s * model.lpp_m / NU_WATER_M2_S)
    return min(f, max(float(model.hull.R0), 0.0) / cf_ref)


def ittc57_cf(reynolds: float) -> float:
    """C_F = 0.075/(log10 Re − 2)² [ITTC-1957] (Re floored at 1e3: the line's own domain starts far above)."""
    re = max(reynolds, 1e3)
    return 0.075 / (math.log10(re) - 2.0) ** 2


def hull_fields() -> list[str]:
    return [f.name for f in fields(MmgHull)]


# ---------------------------------------------------------------- the forces

def drift_powers(vp: float, s: float) -> tuple[float, float, float]:
    """(v'², v'³, v'⁴) where |v'| ≤ s (the sine of the drift domain), each continued along its
    tangent at |v'| = s beyond it (v'³ odd, the others even): s^(k−1)·(k|v'| − (k−1)s) for v'^k,
    continuous with its slope (module docstring)."""
    a = abs(vp)
    if a <= s:
        v2 = vp * vp
        return v2, v2 * vp, v2 * v2
    v3 = s * s * (3.0 * a - 2.0 * s)
    return s * (2.0 * a - s), v3 if vp >= 0.0 else -v3, s * s * s * (4.0 * a - 3.0 * s)


def mmg_force(p, u: float, v: float, r: float, n: float, delta: float,
              hull_on: bool, propeller_on: bool, rudder_on: bool):
    """(X, Y, N, T, F_N) at midship: the sum of the switched-on parts of X_H + X_P + X_R (N),
    Y (N), N (N m), and the propeller thrust T (N, before thrust deduction) and rudder normal
    force F_N (N) whatever the switches. p: the packed FIELDS; ν relative to the water."""
    rho, L, d = p[_RHO], p[_L], p[_D]
    n = min(max(n, p[_NMIN]), p[_NMAX])
    delta = min(max(delta, -p[_DMAX]), p[_DMAX])
    U = math.sqrt(u * u + v * v)
    Un = max(U, p[_UMIN])  # U_nd
    vp = v / Un
    rp = r * L / Un
    beta = math.atan2(-v, abs(u))
    X = 0.0
    Y = 0.0
    N = 0.0
    # hull, eqs. 7-8 (R'_0 with the direction factor of the module docstring)
    if hull_on:
        h = _H
        q = 0.5 * rho * L * d
        f = 0.0
        if U > 0.0:
            f = min(max(2.0 * u / U, -1.0), 1.0)
        U2 = Un * Un
        r0 = p[h]
        if p[_FF] > 0.0:  # R'_0 along the friction line (ittc57_cf written out: numba compiles this function alone)
            r0 += p[_FF] * (0.075 / (math.log10(max(Un * p[_LNU], 1e3)) - 2.0) ** 2 - p[_CFREF])
        # astern the hull meets the water stern first (module docstring): the terms even in v and r of
        # X, odd in r of Y and odd in v of N change sign with f, as R'_0's does
        # v'², v'³, v'⁴: the standard's within its drift domain, along their tangents beyond it
        # (drift_powers written out: numba compiles this function alone)
        s, a = p[_VDOM], abs(vp)
        if a <= s:
            v2 = vp * vp
            v3, v4 = v2 * vp, v2 * v2
        else:
            v2, v3, v4 = s * (2.0 * a - s), s * s * (3.0 * a - 2.0 * s), s * s * s * (4.0 * a - 3.0 * s)
            if vp < 0.0:
                v3 = -v3
        X += q * (-r0 * U * U * f + U2 * (f * (p[h + 1] * v2 + p[h + 3] * rp * rp + p[h + 4] * v4)
                                             + p[h + 2] * vp * rp))
        Y += q * U2 * (p[h + 5] * vp + f * p[h + 6] * rp + p[h + 7] * v3 + f * p[h + 8] * v2 * rp
                       + p[h + 9] * vp * rp * rp + f * p[h + 10] * rp * rp * rp)
        N += q * L * U2 * (f * p[h + 11] * vp + p[h + 12] * rp + f * p[h + 13] * v3 + p[h + 14] * v2 * rp
                           + f * p[h + 15] * vp * rp * rp + p[h + 16] * rp * rp * rp)
    # propeller, eqs. 10-16: the wake in manoeuvring motion (eqs. 15-16), the thrust multiplied
    # through by n² so that it stays finite at n = 0
    D = p[_DP]
    beta_p = beta - p[_XP] * rp
    c2 = p[_C2P] if beta_p > 0.0 else p[_C2M]
    one_minus_w = (1.0 - p[_WP0]) * (1.0 + (1.0 - math.exp(-p[_C1] * abs(beta_p))) * (c2 - 1.0))
    if u < 0.0:
        one_minus_w = 1.0
    u_p = u * one_minus_w
    if n >= 0.0:
        T = rho * (p[_K0] * n * n * D ** 4 + p[_K1] * n * u_p * D ** 3 + p[_K2] * u_p * u_p * D * D)
        x_p = (1.0 - p[_TP]) * T
        race2 = 0.0  # 8 K_T n² D_P²/π, the propeller race in u_R (eq. 21)
        if n > 0.0:
            race2 = 8.0 * max(T, 0.0) / (math.pi * rho * D * D)
    else:
        nd_abs = -n * D  # K_astern multiplied through by (nD)², so that no tiny n divides
        T = -rho * D * D * min(max(p[_KA0] * nd_abs * nd_abs + p[_KA1] * u * nd_abs, 0.0), p[_KAMAX] * nd_abs * nd_abs)
        x_p = T
        race2 = 0.0
    if propeller_on:
        X += x_p
        if n < 0.0:  # the astern side force, Hachii's piecewise-linear form in J_s (module docstring)
            # multiplied through by (nD)², as T is, so that no tiny n divides: with nD < 0,
            # J_s < c ⇔ u > c·nD
            nd = n * D
            if u < JS_SYN0 * nd:  # J_s above the upper knot: a4, b4
                cy, cn = p[_AY + 4] * nd * nd, p[_BN + 4] * nd * nd
            else:  # a0 + a1 J_s between the knots, a2 + a3 J_s below the lower one
                ky, kn = (_AY + 2, _BN + 2) if u > JS_SYN * nd else (_AY, _BN)
                cy, cn = p[ky] * nd * nd + p[ky + 1] * u * nd, p[kn] * nd * nd + p[kn + 1] * u * nd
            Y += 0.5 * rho * L * d * cy
            N += 0.5 * rho * L * L * d * cn
    # rudder, eqs. 17-27
    eps, kappa, eta = p[_EPS], p[_KAPPA], p[_ETA]
    if u >= 0.0:
        inner = u_p + kappa * (math.sqrt(u_p * u_p + race2) - u_p)
        u_r = eps * math.sqrt(eta * inner * inner + (1.0 - eta) * u_p * u_p)
    else:
        u_r = u + eps * kappa * math.sqrt(eta) * math.sqrt(race2)
    beta_r = beta - p[_LR] * rp
    gamma = p[_GM] if beta_r < 0.0 else p[_GP]
    v_r = gamma * (U * beta - p[_LR] * r * L * U / Un)  # U γ_R β_R (r' on U_nd below the floor)
    alpha_r = delta - math.atan2(v_r, u_r)
    f_n = 0.5 * rho * p[_AR] * (u_r * u_r + v_r * v_r) * p[_FA] * math.sin(alpha_r)
    if rudder_on:
        X += -(1.0 - p[_TR]) * f_n * math.sin(delta)
        Y += -(1.0 + p[_AH]) * f_n * math.cos(delta)
        N += -(p[_XR] + p[_AH] * p[_XH]) * f_n * math.cos(delta)
    return X, Y, N, T, f_n
