"""Physical first guesses from an identified grey-box model, for a simulation-based fit.

[Morel-2024] identifies input gains h·M⁻¹·τ and the lumped σ = M⁻¹(…), never a force:
every coefficient is known only up to the inertia it is divided by. One absolute
anchor is therefore taken from the vessel description, M11 = m − X_u̇ (compiled
MJCF plus added mass), and everything else follows from it:

- thrust curve T(δ) = a·δ² + b·δ (eq. 14) per thruster from the surge input gain,
  compared with the vessel's forward curve (a least-squares scale over the PWM
  range beyond the dead zone);
- X_u = M11·R_u(1), X_|u|u = M11·P_u(1,1) (Fossen signs: negative when dissipative),
  and the surge disturbance force M11·c̄_u;
- M22 twice, from the Coriolis terms: M11·u̇ ∋ M22·v·r and M22·v̇ ∋ −M11·u·r;
- the effective yaw inertia 1/M⁻¹(3,3) (= M33 − M23²/M22) from the ratio of the
  yaw to the surge input gain with the thruster spacing d: the same thrust
  curve drives both, through d/2 and 1/M11;
- N_r, N_|r|r from the yaw σ coefficients times that inertia (M23 ≈ 0 assumed);
- the lag time constant τ = −h/ln α of the dynamic model;
- the constant disturbances c̄_u, c̄_v, c̄_r.

For the dynamic model, the input coefficients are h·β·M⁻¹·(a, b); the steady
state of eq. 15 is T = β/(1 − α)·T_st, and a thruster map is a steady-state
curve, so the thrust scale uses γ/(1 − α) (β and T_st are not separable).

Every entry is {"value", "unit", "note"}; value is None, with the reason in the
note, when the data cannot say (no excitation, wrong sign, missing model term).
"""
from __future__ import annotations

import math

import numpy as np

from ...engine.mjcf import compile_vessel
from ...physics.thrusters import lag_time_constant_s
from ...vessel import Vessel
from .models import DofFit, DynamicModel, StaticModel

SLOW_LAG_S = 2.0  # a small propeller spins up in a few tenths of a second
MAX_SHAPE_MISFIT = 0.3  # yaw and surge see one thrust curve; beyond this they plainly do not


def first_guesses(model: StaticModel | DynamicModel, vessel: Vessel, *,
                  pwm_neutral_us: float | None = None, zoh: bool = True) -> dict[str, dict]:
    """Physical values implied by `model` for `vessel` (module docstring).
    pwm_neutral_us: the neutral the model's δ was computed from (default: the
    vessel's thruster map neutral, pwm_offset·pwm_scale_us). zoh: undo the
    forward-Euler bias of eq. 9 per DOF (`discretisation_factors`)."""
    compiled = compile_vessel(vessel)
    M11 = float(compiled.hydro().M[0, 0])
    y_left, y_right = compiled.geometry.thruster_y_m
    d = y_right - y_left
    thr = vessel.thrusters
    neutral = thr.pwm_offset * thr.pwm_scale_us if pwm_neutral_us is None else float(pwm_neutral_us)
    h = model.h
    dc = 1.0 / (1.0 - model.alpha) if isinstance(model, DynamicModel) else 1.0
    coef = {dof: _coefficients(model.dofs[dof], dof, zoh) for dof in ("u", "v", "r")}
    surge, sway, yaw = (_thrust_curves(*coef[dof][:2], dof, model.options.thrust_form) for dof in ("u", "v", "r"))

    anchor = "anchor from the vessel description (m − X_u̇), not identified"
    out: dict[str, dict] = {"M11": _entry(M11, "kg", anchor)}
    out.update(_thrust_entries(surge, M11 * dc / h, thr, neutral))
    out.update(_surge_entries(coef["u"], M11, h))
    out.update(_inertia_entries(surge, yaw, sway, coef, M11, d, h))
    out.update(_lag_entry(model))
    factors = ", ".join(f"{coef[d][2]:.3f}" for d in ("u", "v", "r"))
    out["discretisation"] = _entry(None, "–", f"zero-order-hold factors applied (u, v, r): {factors}" if zoh
                                   else "forward-Euler coefficients of eq. 9 used as they are")
    return out


def discretisation_factors(pole: float) -> tuple[float, float]:
    """(ln p, f) for a DOF's own pole p = 1 + h·R_j of eq. 9.

    Eq. 9 is a forward-Euler step, exact only for h ≪ the DOF's time constant. For
    a linear first-order DOF ẋ = λx + b·w held constant over a step, the exact
    step is x(k+1) = p·x(k) + (p − 1)/λ·b·w with p = e^(λh): the regression's
    h·R_j = p − 1 is exact for λ = ln p/h, and every forcing coefficient it
    returns (input gain, σ terms) is h·b·(p − 1)/(λh), i.e. too small by
    f = ln p/(p − 1). With a yaw time constant M33/|N_r| near h this is a factor
    of 1.5 on M33 (Yellowfish: 0.12 s against h = 0.1 s). (0, 1) when p is not in
    (0, 1): no correction.
    """
    if not 0.0 < pole < 1.0:
        return 0.0, 1.0
    return math.log(pole), math.log(pole) / (pole - 1.0)


# ---------------------------------------------------------------- thrust

def _thrust_curves(g: dict, se: dict, dof: str, form: str) -> dict[str, tuple[float, float]]:
    """Per-thruster (value, standard error) of the input-gain coefficients of one DOF, by
    name af, bf, ar, br, in the DOF's own units (h·M⁻¹·thrust, times d/2 for v and r)."""
    if form == "thruster":
        keys = ("Σf δ²", "Σf δ", "Σr δ²", "Σr δ")
        return {n: (g[k], se[k]) for n, k in zip(("af", "bf", "ar", "br"), keys)}
    if dof == "u":  # eq. 20: X(6) = 2h·M⁻¹(1,1)·a_f, X(7) = 2h·M⁻¹(1,1)·b_f
        return {"af": (g["δ̄²+Δδ²/4"] / 2, se["δ̄²+Δδ²/4"] / 2), "bf": (g["δ̄"] / 2, se["δ̄"] / 2)}
    # eqs. 26-28 in (f,r), k = h·M⁻¹(j,3)·d/2:
    # X(10) = k(a_f − a_r), X(11) = k(a_f + a_r), X(12) = k(b_f − b_r), X(13) = k(b_f + b_r)
    x10, x11, x12, x13 = (g[k] for k in ("s(δ̄²+Δδ²/4)", "δ̄Δδ", "sδ̄", "Δδ/2"))
    e10, e11, e12, e13 = (se[k] for k in ("s(δ̄²+Δδ²/4)", "δ̄Δδ", "sδ̄", "Δδ/2"))
    half = lambda a, b: 0.5 * math.hypot(a, b)  # noqa: E731 — SE of (x ± y)/2 for independent x, y
    return {"af": ((x11 + x10) / 2, half(e11, e10)), "ar": ((x11 - x10) / 2, half(e11, e10)),
            "bf": ((x13 + x12) / 2, half(e13, e12)), "br": ((x13 - x12) / 2, half(e13, e12))}


def _thrust_entries(surge: dict, to_newton: float, thr, neutral_us: float) -> dict[str, dict]:
    out = {}
    for name, label in (("af", "a_f"), ("bf", "b_f"), ("ar", "a_r"), ("br", "b_r")):
        if name in surge:
            value, se = surge[name]
            note = f"{label} of eq. 14 in δ = (PWM − {neutral_us:g})/400 per thruster; {_precision(value, se)}"
            out[f"thrust_{name}"] = _entry(value * to_newton, "N", note)
    af, bf = surge["af"][0] * to_newton, surge["bf"][0] * to_newton
    pwm = np.linspace(neutral_us + thr.deadzone_fwd * thr.pwm_scale_us if thr.kind == "t200" else neutral_us,
                      thr.pwm_max_us, 50)
    delta = (pwm - neutral_us) / 400.0
    identified = af * delta ** 2 + bf * delta
    full = float(af + bf)
    out["thrust_full_forward"] = _entry(full, "N", "identified T at δ = 1 (one thruster)")
    if thr.kind != "t200":
        out["thrust_scale_forward"] = _entry(None, "×", "the vessel has no PWM→thrust map to compare with")
        return out
    curve = np.asarray(thr.thrust_from_pwm(pwm), float)
    scale = float(curve @ identified / (curve @ curve))
    misfit = float(np.sqrt(np.mean((identified - scale * curve) ** 2)) / max(np.max(np.abs(identified)), 1e-12))
    out["thrust_scale_forward"] = _entry(scale, "×", f"identified forward curve / vessel forward curve, least squares "
                                         f"over {pwm[0]:.0f}-{pwm[-1]:.0f} µs; shape misfit {misfit:.0%} of peak")
    if not af + bf > 0:
        out["thrust_scale_forward"]["note"] += "; identified forward thrust is not positive: check PWM polarity"
    return out


# ---------------------------------------------------------------- surge hull

def _surge_entries(coef: tuple, M11: float, h: float) -> dict[str, dict]:
    c, se, _ = coef
    out = {}
    for key, term, unit, what in (("Xu", "u", "kg/s", "linear surge damping M11·R_u(1)"),
                                  ("Xuu", "u|u|", "kg/m", "quadratic surge damping M11·P_u(1,1)")):
        value = M11 * c[term] / h
        note = f"{what}; {_precision(c[term], se[term])}"
        if value > 0:
            note += "; positive: not dissipative, the regression traded it against another term"
        out[key] = _entry(value, unit, note)
    out["X_bias"] = _entry(M11 * c["1"] / h, "N", f"constant surge force M11·c̄_u; {_precision(c['1'], se['1'])}")
    out["cu"] = _entry(c["1"] / h, "m/s²", f"c̄_u of eq. 12; {_precision(c['1'], se['1'])}")
    m22 = M11 * c["v·r"] / h
    out["M22_from_surge"] = _positive(m22, "kg", "M22 from the surge Coriolis term M22·v·r (M11·u̇ ∋ M22·v·r); "
                                      f"{_precision(c['v·r'], se['v·r'])}")
    return out


# ---------------------------------------------------------------- yaw and sway

def _inertia_entries(surge: dict, yaw: dict, sway: dict, coef: dict[str, tuple], M11: float, d: float,
                     h: float) -> dict[str, dict]:
    out = {}
    kappa, rel, misfit = _curve_ratio(yaw, surge)
    # yaw coefficient / surge coefficient = (d/2)·M⁻¹(3,3) / M⁻¹(1,1) for the same thrust curve
    inv33 = 2.0 * kappa / (d * M11) if kappa is not None else None
    if inv33 is None:
        out["M33_eff"] = _entry(None, "kg m²", "no common thrust-curve term between surge and yaw input gains")
    elif inv33 <= 0:
        out["M33_eff"] = _entry(None, "kg m²", f"yaw input gain has the opposite sign of τr = d/2·(T_L − T_R) "
                                f"(ratio {kappa:.3g}): left/right channels swapped or a channel reversed?")
    else:
        note = (f"1/M⁻¹(3,3) = M33 − M23²/M22 from the yaw/surge input-gain ratio with d = {d:.3f} m; "
                f"ratio ±{rel:.0%} (1 SE), curve shapes differ by {misfit:.0%}")
        if misfit > MAX_SHAPE_MISFIT:
            note += ": the yaw and surge thrust curves are not one curve, not trustworthy"
        out["M33_eff"] = _entry(1.0 / inv33, "kg m²", note)
    kappa_v, rel_v, misfit_v = _curve_ratio(sway, yaw)
    out["M23_over_M22"] = _entry(None if kappa_v is None else -kappa_v, "–",
                                 "−M⁻¹(2,3)/M⁻¹(3,3) = M23/M22 from the sway/yaw input-gain ratio"
                                 + ("" if kappa_v is None else f"; ±{rel_v:.0%} (1 SE), shapes differ by "
                                    f"{misfit_v:.0%}"))
    c, se, _ = coef["r"]
    for key, term, unit, what in (("Nr", "r", "kg m²/s", "linear yaw damping"),
                                  ("Nrr", "r|r|", "kg m²", "quadratic yaw damping")):
        if inv33 is None or inv33 <= 0:
            out[key] = _entry(None, unit, f"{what}: needs M33_eff")
            continue
        value = c[term] / h / inv33
        note = f"{what} M33_eff·σ_r coefficient (M23 ≈ 0 assumed); {_precision(c[term], se[term])}"
        if value > 0:
            note += "; positive: not dissipative"
        out[key] = _entry(value, unit, note)
    out["cr"] = _entry(c["1"] / h, "rad/s²", f"c̄_r of eq. 12; {_precision(c['1'], se['1'])}")
    if inv33 is not None and inv33 > 0:
        out["N_bias"] = _entry(c["1"] / h / inv33, "N m", "constant yaw moment M33_eff·c̄_r")
    cv, sev, _ = coef["v"]
    out["cv"] = _entry(cv["1"] / h, "m/s²", f"c̄_v of eq. 12; {_precision(cv['1'], sev['1'])}")
    ur = cv["u·r"] / h
    out["M22_from_sway"] = _positive(-M11 / ur if ur else math.inf, "kg",
                                     "M22 from the sway Coriolis term (M22·v̇ ∋ −M11·u·r); "
                                     f"{_precision(cv['u·r'], sev['u·r'])}")
    return out


def _curve_ratio(num: dict, den: dict) -> tuple[float | None, float, float]:
    """Least-squares κ with num-curve ≈ κ·den-curve over δ ∈ [−1, 1] (the branches both
    have), its relative standard error from the coefficients' errors, and the shape
    misfit (RMS of num − κ·den over RMS of num: 0 when the curves are proportional)."""
    delta = np.linspace(-1.0, 1.0, 81)
    rows_num, rows_den, rows_se = [], [], []
    for a, b, side in (("af", "bf", delta >= 0), ("ar", "br", delta < 0)):
        if a in num and a in den:
            x = delta[side]
            rows_num.append(num[a][0] * x ** 2 + num[b][0] * x)
            rows_den.append(den[a][0] * x ** 2 + den[b][0] * x)
            rows_se.append(np.hypot(num[a][1] * x ** 2, num[b][1] * x))
    if not rows_num:
        return None, math.nan, math.nan
    n, m, e = (np.concatenate(r) for r in (rows_num, rows_den, rows_se))
    if not np.any(m):
        return None, math.nan, math.nan
    kappa = float(n @ m / (m @ m))
    scale = max(float(np.sqrt(np.mean(n ** 2))), 1e-300)
    rel = float(np.sqrt(np.mean(e ** 2))) / scale
    misfit = float(np.sqrt(np.mean((n - kappa * m) ** 2))) / scale
    return kappa, rel, misfit


# ---------------------------------------------------------------- lag

def _lag_entry(model) -> dict[str, dict]:
    if not isinstance(model, DynamicModel):
        return {"lag_s": _entry(None, "s", "the static model has no thruster lag (fit_dynamic identifies α)")}
    try:
        tau = float(lag_time_constant_s(model.alpha, model.h))
    except ValueError:
        return {"lag_s": _entry(None, "s", f"α = {model.alpha:.4f} is not a stable lag in (0, 1)")}
    note = (f"τ = −h/ln α with α = {model.alpha:.4f} (eq. 35 over {', '.join(model.alpha_dofs)}); "
            f"per-DOF candidate roots {_roots_text(model.alpha_roots_by_dof)}")
    if tau > SLOW_LAG_S:
        note += (f"; slower than {SLOW_LAG_S:g} s, unlike a T200 spin-up: α may absorb velocity smoothing "
                 "or hull dynamics")
    return {"lag_s": _entry(tau, "s", note), "alpha": _entry(model.alpha, "–", "discrete pole of eq. 15")}


def _roots_text(roots: dict) -> str:
    return "; ".join(f"{d}: {', '.join(f'{x:.3f}' for x in r) or 'none'}" for d, r in roots.items())


# ---------------------------------------------------------------- helpers

def _coefficients(fit: DofFit, dof: str, zoh: bool) -> tuple[dict[str, float], dict[str, float], float]:
    """Coefficients and standard errors by name, with the zero-order-hold correction
    (`discretisation_factors`) when zoh, and the factor applied."""
    c, se = dict(zip(fit.fit.names, fit.fit.coef)), dict(zip(fit.fit.names, fit.fit.stderr))
    if not zoh:
        return c, se, 1.0
    log_pole, f = discretisation_factors(1.0 + c[dof])
    if f == 1.0:
        return c, se, 1.0
    c = {k: (log_pole if k == dof else v * f) for k, v in c.items()}
    se = {k: v * f for k, v in se.items()}
    return c, se, f


def _precision(value: float, se: float) -> str:
    if not np.isfinite(se):
        return "no standard error"
    if se >= abs(value):
        return f"not significant (standard error {se:.2g} ≥ |value| {abs(value):.2g})"
    return f"±{se / abs(value):.0%} (1 SE)"


def _positive(value: float, unit: str, note: str) -> dict:
    if not (np.isfinite(value) and value > 0):
        return _entry(None, unit, f"{note}; implied value {value:.3g} is not a positive mass")
    return _entry(value, unit, note)


def _entry(value, unit: str, note: str) -> dict:
    return {"value": None if value is None else float(value), "unit": unit, "note": note}
