#!/usr/bin/env python3
"""An independent 3-DOF "world" for small twin-thruster surface vessels.

Why this exists: the twin's diagnosis must be proven on recordings whose truth was
written by code other than the twin's own effect functions, in physical forms the
twin library does not have. This file is that other code. It imports only numpy,
scipy and the standard library, never `twin`.

What it does: reads the vessel's effective parameters (`twin params --json`),
integrates its own equations of motion (Fossen form, NED world, FRD body, ψ from
north to east) with a fixed-step RK4 at 0.01 s, drives the vessel as a user would
(RC sticks, idle-heavy lake logs, a waypoint autopilot closing its loops on the
*measured* heading and GNSS, groups of outings), injects one or two named physical
effects, and writes what the sensors would have logged (generic CSV layout of the
twin's README) plus a truth JSON.

    M ν̇ + C_RB(ν)ν + C_A(ν_r)ν_r + D(ν_r)ν_r = τ_thr + τ_wind + M_A ν̇_c
    η̇ = R(ψ) ν,    ν_r = ν − ν_c,    ν_c = R(ψ)ᵀ V_c(t)

C(ν) of a symmetric 3-DOF inertia M is the standard skew-symmetric form
[[0, 0, −(M22 v + M23 r)], [0, 0, M11 u], [M22 v + M23 r, −M11 u, 0]], once for
M_RB with ν and once for M_A with ν_r (irrotational current). A thruster force F_x at
lateral position y gives the yaw moment −y·F_x.

Usage:
    world_sim.py --params P.json --case CASE --seed N --out rec.csv [--truth truth.json]
    world_sim.py --params P.json --case CASE --seed N --out-dir DIR        (multi-log cases)
    world_sim.py --list
    world_sim.py --params P.json --selftest

The cases, their equations, truth parameters and what a perfect diagnosis says: scripts/world_cases.md.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

DT_S = 0.01                      # integration step (s)
TICK_S = 0.1                     # PWM log and autopilot period (s), 10 Hz
GNSS_PERIOD_S = 0.2              # 5 Hz
VOLT_PERIOD_S = 0.5              # battery voltage log, 2 Hz
WARMUP_S = 20.0                  # simulated before logging starts, so the log opens on a settled state
ORIGIN_LAT_DEG, ORIGIN_LON_DEG = 63.44, 10.40
RHO_AIR_KG_M3 = 1.225
WGS84_A_M, WGS84_E2 = 6378137.0, 6.69437999014e-3
NEUTRAL_US = 1500.0
HOTEL_POWER_W = 12.0             # electronics draw, W
T200_POWER_W_PER_N15 = 1.0       # electrical power ≈ k·|T|^1.5 per thruster (W, T in N)


class UsageError(Exception):
    """A bad argument or input: reported on one line, exit 2."""


# ---------------------------------------------------------------- vessel parameters

@dataclass(frozen=True)
class Vessel:
    """The vessel's effective 3-DOF parameters as `twin params --json` prints them."""
    M: np.ndarray
    M_inv: np.ndarray
    M_RB: np.ndarray
    M_A: np.ndarray
    damping: dict
    pwm_scale_us: float
    pwm_offset: float
    fwd_abc: tuple
    rev_abc: tuple
    dz_fwd: float
    dz_rev: float
    pwm_min_us: float
    pwm_max_us: float
    thrust_min_n: float | None
    thrust_max_n: float | None
    lag_s: float
    delay_s: float
    gain_left: float
    gain_right: float
    left_xy_m: tuple
    right_xy_m: tuple
    antenna_xy_m: tuple
    frontal_area_m2: float
    lateral_area_m2: float
    length_m: float
    current_speed_m_s: float
    current_dir_deg: float


DAMPING_NAMES = ("Xu", "Xuu", "Yv", "Yvv", "Yrv", "Yr", "Yvr", "Yrr", "Nv", "Nvv", "Nrv", "Nr", "Nvr", "Nrr",
                 "Yuv", "Nur")


def load_vessel(path: Path) -> Vessel:
    """Parse and check a `twin params --json` file; anything this world cannot model is refused, not ignored."""
    try:
        p = json.loads(Path(path).read_text())
    except (OSError, ValueError) as e:
        raise UsageError(f"cannot read params {path}: {e}") from None
    try:
        M, M_RB, M_A = (np.array(p[k], float) for k in ("M", "M_RB", "M_A"))
        th = p["thrusters"]
        damping = {k: float(p["damping"].get(k, 0.0)) for k in DAMPING_NAMES}
        unknown = sorted(k for k, x in p["damping"].items() if k not in DAMPING_NAMES and float(x) != 0.0)
        if unknown:
            raise UsageError(f"params: damping terms {', '.join(unknown)} are not modelled by this world")
        env = p.get("environment", {})
        wl = p["wind_load"]
        if M.shape != (3, 3) or M_RB.shape != (3, 3) or M_A.shape != (3, 3):
            raise UsageError("params: M, M_RB, M_A must be 3x3")
        if np.any(np.linalg.eigvalsh(0.5 * (M + M.T)) <= 0):
            raise UsageError("params: M is not positive definite")
        if th.get("reversed_channels"):
            raise UsageError("params: reversed thruster channels are not modelled by this world")
        for k in ("decay_per_min", "advance_loss"):
            if float(th.get(k) or 0.0) != 0.0:
                raise UsageError(f"params: thrusters.{k} != 0 is not modelled by this world")
        if float(env.get("wind_speed_m_s") or 0.0) != 0.0 or env.get("wind_by_log"):
            raise UsageError("params: a wind in the environment is not modelled by the null world")
        return Vessel(
            M=M, M_inv=np.linalg.inv(M), M_RB=M_RB, M_A=M_A, damping=damping,
            pwm_scale_us=float(th["pwm_scale_us"]), pwm_offset=float(th["pwm_offset"]),
            fwd_abc=tuple(map(float, th["forward"])), rev_abc=tuple(map(float, th["reverse"])),
            dz_fwd=float(th["deadzone_fwd"]), dz_rev=float(th["deadzone_rev"]),
            pwm_min_us=float(th["pwm_min_us"]), pwm_max_us=float(th["pwm_max_us"]),
            thrust_min_n=None if th.get("thrust_min_n") is None else float(th["thrust_min_n"]),
            thrust_max_n=None if th.get("thrust_max_n") is None else float(th["thrust_max_n"]),
            lag_s=float(th.get("lag_s") or 0.0), delay_s=float(th.get("delay_s") or 0.0),
            gain_left=float(th.get("gain_left", 1.0)), gain_right=float(th.get("gain_right", 1.0)),
            left_xy_m=tuple(map(float, th["positions_m"]["left"][:2])),
            right_xy_m=tuple(map(float, th["positions_m"]["right"][:2])),
            antenna_xy_m=tuple(map(float, p["gnss_antenna_m"][:2])),
            frontal_area_m2=float(wl["frontal_area_m2"]), lateral_area_m2=float(wl["lateral_area_m2"]),
            length_m=float(wl["length_m"]),
            current_speed_m_s=float(env.get("current_speed_m_s") or 0.0),
            current_dir_deg=float(env.get("current_dir_deg") or 0.0),
        )
    except (KeyError, TypeError, ValueError, IndexError) as e:
        raise UsageError(f"params {path}: missing or malformed field {e}") from None


def pwm_to_unit(pwm_us: float, v: Vessel) -> float:
    """δ̃ of the T200 map: pwm/scale − offset after clipping to the ESC range."""
    p = min(max(pwm_us, v.pwm_min_us), v.pwm_max_us)
    return p / v.pwm_scale_us - v.pwm_offset


def unit_to_pwm(d: float, v: Vessel) -> float:
    """PWM (µs) of a δ̃ value, to state dead-zone edges in the units a user logs."""
    return (d + v.pwm_offset) * v.pwm_scale_us


def curve_thrust_n(d: float, v: Vessel, forward: bool) -> float:
    """The T200 quadratic branch (without dead zone), N."""
    a, b, c = v.fwd_abc if forward else v.rev_abc
    return a * d * d + b * d + c


# ---------------------------------------------------------------- effects (the world's own physics)

@dataclass
class Effects:
    """Everything in this world that the vessel parameters do not say. Defaults: nothing."""
    gain_left: float = 1.0
    gain_right: float = 1.0
    toe_in_deg: float = 0.0                   # each thruster's axis turned inward by this angle
    delay_s: float = 0.0                      # transport delay of the PWM
    slew_n_per_s: float | None = None         # thrust rate limit
    dz_fwd: float | None = None               # dead-zone edges in δ̃ (None: the params')
    dz_rev: float | None = None
    hysteresis: tuple | None = None           # (start_fwd, stop_fwd, start_rev, stop_rev) in δ̃
    ventilation: tuple | None = None          # (knee_share, slope): forward thrust beyond knee_share of full grows at slope
    battery_sag: bool = False                 # thrust ∝ (V/V_ref)²
    battery_wh: float = 150.0
    battery_soc0: float = 0.95
    battery_r_ohm: float = 0.02
    fouling_k3: float = 0.0                   # X_extra = −k3·u_r³
    yaw_coulomb_nm: float = 0.0               # N_extra = −Nc·tanh(r/r0) − Nrrr·r³
    yaw_r0_rad_s: float = 0.08
    yaw_nrrr: float = 0.0
    astern_drag: float = 1.0                  # hull drag × this factor while the water meets the transom (u_r < 0)
    sea: dict | None = None                   # zero-mean chop: sigma_x_n, sigma_y_n, sigma_n_nm, tau_s (body axes)
    current: dict | None = None               # speed0, speed1, dir0_deg, dir1_deg (towards)
    wind: dict | None = None                  # speed, from_deg, gust_sigma, gust_tau_s, dir_sigma_deg, dir_tau_s
    heading_offset_deg: float = 0.0
    magnetometer: tuple | None = None         # (hard_x, hard_y, soft_xx, soft_yy, soft_xy) in units of the field
    motor_field: tuple | None = None          # (cx, cy): the magnetometer's field offset per W of motor power, body x/y
    gnss_latency_s: float = 0.0
    antenna_offset_m: tuple = (0.0, 0.0)
    pwm_clock_offset_s: float = 0.0
    heading_lag_s: float = 0.0                # the logged heading through a first-order low-pass (an AHRS filter)
    faults: dict | None = None                # outlier_share, outlier_m, dropouts, spike_share, spike_deg


# Blendermann-like [Blendermann-1994] wind coefficient tables at γ = 0, 20, ..., 180 deg (apparent wind from the bow = 0,
# symmetric port/starboard); a shape unlike cos γ / sin γ / sin 2γ: a flat head-wind plateau, drag
# peaking on the quarter, side force broad and skewed aft, a yaw moment changing sign abaft the beam.
WIND_GAMMA_STEP_DEG = 20.0
WIND_CX = (-0.50, -0.58, -0.50, -0.25, 0.02, 0.15, 0.35, 0.52, 0.55, 0.45)
WIND_CY = (0.00, -0.35, -0.65, -0.85, -0.92, -0.90, -0.78, -0.55, -0.28, 0.00)
WIND_CN = (0.00, 0.05, 0.08, 0.07, 0.03, -0.01, -0.04, -0.05, -0.03, 0.00)


def wind_coefficients(gamma_abs_deg: float) -> tuple[float, float, float]:
    """Linear interpolation in the tables at |γ| (deg, 0..180)."""
    x = min(max(gamma_abs_deg, 0.0), 180.0) / WIND_GAMMA_STEP_DEG
    i = min(int(x), len(WIND_CX) - 2)
    f = x - i
    return (WIND_CX[i] + f * (WIND_CX[i + 1] - WIND_CX[i]), WIND_CY[i] + f * (WIND_CY[i + 1] - WIND_CY[i]),
            WIND_CN[i] + f * (WIND_CN[i + 1] - WIND_CN[i]))


# ---------------------------------------------------------------- equations of motion

def make_rhs(v: Vessel, fx: Effects) -> Callable:
    """The state derivative as a closure over scalars: the RK4 loop calls it 4 times per 0.01 s step,
    so it avoids numpy on 3-vectors (Python floats are ~10x faster at this size)."""
    i11, i12, i13 = (float(x) for x in v.M_inv[0])
    i21, i22, i23 = (float(x) for x in v.M_inv[1])
    i31, i32, i33 = (float(x) for x in v.M_inv[2])
    rb11, rb22, rb23 = float(v.M_RB[0, 0]), float(v.M_RB[1, 1]), 0.5 * float(v.M_RB[1, 2] + v.M_RB[2, 1])
    a11, a22, a23 = float(v.M_A[0, 0]), float(v.M_A[1, 1]), 0.5 * float(v.M_A[1, 2] + v.M_A[2, 1])
    ma = [[float(x) for x in row] for row in v.M_A]
    d = v.damping
    Xu, Xuu = d["Xu"], d["Xuu"]
    Yv, Yvv, Yrv, Yuv, Yr, Yvr, Yrr = d["Yv"], d["Yvv"], d["Yrv"], d["Yuv"], d["Yr"], d["Yvr"], d["Yrr"]
    Nv, Nvv, Nrv, Nr, Nvr, Nrr, Nur = d["Nv"], d["Nvv"], d["Nrv"], d["Nr"], d["Nvr"], d["Nrr"], d["Nur"]
    k3 = fx.fouling_k3
    nc, r0, nrrr = fx.yaw_coulomb_nm, fx.yaw_r0_rad_s, fx.yaw_nrrr
    astern_extra = fx.astern_drag - 1.0
    has_wind = fx.wind is not None
    qa_f = 0.5 * RHO_AIR_KG_M3 * v.frontal_area_m2
    qa_l = 0.5 * RHO_AIR_KG_M3 * v.lateral_area_m2
    qa_n = qa_l * v.length_m
    cos, sin, tanh, atan2 = math.cos, math.sin, math.tanh, math.atan2

    def rhs(psi, u, vv, r, X, Y, N, cn, ce, dcn, dce, wn, we):
        c, s = cos(psi), sin(psi)
        uc, vc = cn * c + ce * s, -cn * s + ce * c
        ur, vr = u - uc, vv - vc
        # rigid-body Coriolis C_RB(ν)ν
        c13, c23 = -(rb22 * vv + rb23 * r), rb11 * u
        f1, f2, f3 = -c13 * r, -c23 * r, c13 * u + c23 * vv
        # added-mass Coriolis C_A(ν_r)ν_r
        e13, e23 = -(a22 * vr + a23 * r), a11 * ur
        f1 -= e13 * r
        f2 -= e23 * r
        f3 += e13 * ur + e23 * vr
        # damping −D(ν_r)ν_r with Fossen's signs (coefficients negative)
        aur, avr, ar = abs(ur), abs(vr), abs(r)
        f1 += (Xu + Xuu * aur) * ur
        f2 += (Yv + Yvv * avr + Yrv * ar + Yuv * aur) * vr + (Yr + Yvr * avr + Yrr * ar) * r
        f3 += (Nv + Nvv * avr + Nrv * ar) * vr + (Nr + Nvr * avr + Nrr * ar + Nur * aur) * r
        if k3:
            f1 -= k3 * ur * ur * ur
        if astern_extra and ur < 0.0:
            f1 += astern_extra * (Xu + Xuu * aur) * ur
        if nc or nrrr:
            f3 -= nc * tanh(r / r0) + nrrr * r * r * r
        # M_A ν̇_c: the water's acceleration seen in the turning body frame
        if cn or ce:
            ucd = r * vc + dcn * c + dce * s
            vcd = -r * uc - dcn * s + dce * c
            f1 += ma[0][0] * ucd + ma[0][1] * vcd
            f2 += ma[1][0] * ucd + ma[1][1] * vcd
            f3 += ma[2][0] * ucd + ma[2][1] * vcd
        if has_wind:
            ua = wn * c + we * s - u          # air velocity relative to the hull, body axes
            va = -wn * s + we * c - vv
            q = ua * ua + va * va
            gamma = atan2(-va, -ua)           # where the apparent wind comes from; + = starboard
            cx, cy, cnn = wind_coefficients(abs(gamma) * 57.29577951308232)
            sg = 1.0 if gamma >= 0.0 else -1.0
            f1 += qa_f * q * cx
            f2 += qa_l * q * cy * sg
            f3 += qa_n * q * cnn * sg
        f1 += X
        f2 += Y
        f3 += N
        return (c * u - s * vv, s * u + c * vv, r,
                i11 * f1 + i12 * f2 + i13 * f3, i21 * f1 + i22 * f2 + i23 * f3, i31 * f1 + i32 * f2 + i33 * f3)

    return rhs


def rk4_step(rhs: Callable, x: tuple, dt: float, forces: tuple, env: tuple) -> tuple:
    """One classical RK4 step of (n, e, ψ, u, v, r) with forces and environment held over the step."""
    n, e, psi, u, v, r = x
    h2 = 0.5 * dt
    k1 = rhs(psi, u, v, r, *forces, *env)
    k2 = rhs(psi + h2 * k1[2], u + h2 * k1[3], v + h2 * k1[4], r + h2 * k1[5], *forces, *env)
    k3 = rhs(psi + h2 * k2[2], u + h2 * k2[3], v + h2 * k2[4], r + h2 * k2[5], *forces, *env)
    k4 = rhs(psi + dt * k3[2], u + dt * k3[3], v + dt * k3[4], r + dt * k3[5], *forces, *env)
    w = dt / 6.0
    return (n + w * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0]), e + w * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1]),
            psi + w * (k1[2] + 2 * k2[2] + 2 * k3[2] + k4[2]), u + w * (k1[3] + 2 * k2[3] + 2 * k3[3] + k4[3]),
            v + w * (k1[4] + 2 * k2[4] + 2 * k3[4] + k4[4]), r + w * (k1[5] + 2 * k2[5] + 2 * k3[5] + k4[5]))


# ---------------------------------------------------------------- environment time series

def gauss_markov(rng: np.random.Generator, n: int, dt_s: float, sigma: float, tau_s: float) -> np.ndarray:
    """First-order Gauss-Markov samples (stationary from the first), exact discretisation
    x[k] = a·x[k−1] + σ√(1−a²)·w[k], a = exp(−dt/τ)."""
    a = math.exp(-dt_s / tau_s)
    w = (rng.standard_normal(n) * sigma * math.sqrt(1 - a * a)).tolist()
    x = [0.0] * n
    acc = float(rng.standard_normal()) * sigma
    for i in range(n):
        acc = a * acc + w[i] if i else acc
        x[i] = acc
    return np.array(x)


def current_series(spec: dict | None, v: Vessel, t_s: np.ndarray, total_s: float) -> tuple:
    """North/east water velocity (m/s, towards) and its time derivative on the step grid.
    Speed ramps between speed0 and speed1 along a half cosine; direction turns linearly dir0 → dir1."""
    n = len(t_s)
    if spec is None:
        sp, dr = v.current_speed_m_s, math.radians(v.current_dir_deg)
        return (np.full(n, sp * math.cos(dr)), np.full(n, sp * math.sin(dr)), np.zeros(n), np.zeros(n))
    x = np.clip(t_s / total_s, 0.0, 1.0)
    s0, s1 = spec["speed0"], spec["speed1"]
    d0, d1 = math.radians(spec["dir0_deg"]), math.radians(spec["dir1_deg"])
    inside = (t_s >= 0) & (t_s <= total_s)
    sp = s0 + (s1 - s0) * 0.5 * (1 - np.cos(np.pi * x))
    dsp = (s1 - s0) * 0.5 * np.pi / total_s * np.sin(np.pi * x) * inside
    ang = d0 + (d1 - d0) * x
    dang = (d1 - d0) / total_s * inside
    cn, ce = sp * np.cos(ang), sp * np.sin(ang)
    return cn, ce, dsp * np.cos(ang) - sp * np.sin(ang) * dang, dsp * np.sin(ang) + sp * np.cos(ang) * dang


def wind_series(spec: dict | None, rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Air velocity north/east (m/s, the direction the air moves TO) per step: mean speed with gusts
    (Gauss-Markov) and a meandering direction; also speed and from-direction for the truth."""
    if spec is None:
        z = np.zeros(n)
        return z, z, z, z
    speed = np.maximum(spec["speed"] + gauss_markov(rng, n, DT_S, spec["gust_sigma"], spec["gust_tau_s"]), 0.0)
    frm = spec["from_deg"] + gauss_markov(rng, n, DT_S, spec["dir_sigma_deg"], spec["dir_tau_s"])
    fr = np.radians(frm)
    return -speed * np.cos(fr), -speed * np.sin(fr), speed, frm


# ---------------------------------------------------------------- thrusters and battery

CELL_SOC = (0.0, 0.05, 0.10, 0.20, 0.40, 0.60, 0.80, 0.90, 1.00)
CELL_V = (3.30, 3.50, 3.60, 3.68, 3.76, 3.85, 3.97, 4.06, 4.18)


def ocv_4s_v(soc: float) -> float:
    """Open-circuit voltage of a 4S LiPo at state of charge soc (LiPo discharge curve, steep at both ends)."""
    return 4.0 * float(np.interp(soc, CELL_SOC, CELL_V))


def motor_power_w(tl_n, tr_n):
    """Electrical power of both thrusters (W) at thrusts tl, tr (N): k·|T|^1.5 each (floats or arrays)."""
    return T200_POWER_W_PER_N15 * (abs(tl_n) ** 1.5 + abs(tr_n) ** 1.5)


class ThrusterChain:
    """PWM command → thrust per thruster, step by step: transport delay, static T200 map with its dead zone
    (or this world's wider/hysteretic one), gain, first-order lag (params) or slew limit (effect), battery."""

    def __init__(self, v: Vessel, fx: Effects, steps_per_tick: int, dt_s: float):
        self.v, self.fx, self.spt, self.dt = v, fx, steps_per_tick, dt_s
        self.delay_steps = int(round((v.delay_s + fx.delay_s) / dt_s))
        self.dz_f = v.dz_fwd if fx.dz_fwd is None else fx.dz_fwd
        self.dz_r = v.dz_rev if fx.dz_rev is None else fx.dz_rev
        self.gains = (v.gain_left * fx.gain_left, v.gain_right * fx.gain_right)
        self.lag_a = 1.0 - math.exp(-dt_s / v.lag_s) if v.lag_s > 0 else 1.0
        self.thrust = [0.0, 0.0]
        self.last_pwm = [None, None]
        self.target = [0.0, 0.0]
        self.spinning = [0, 0]                           # hysteresis state: +1 forward, −1 reverse, 0 stopped
        self.soc = fx.battery_soc0
        self.v_ref = ocv_4s_v(self.soc)
        self.volt = self.v_ref
        self.factor = 1.0
        self.energy_wh = 0.0
        self.full_fwd_n = curve_thrust_n(pwm_to_unit(v.pwm_max_us, v), v, True)

    def static_n(self, side: int, pwm_us: float) -> float:
        """Thrust of the map at this PWM, N, before gain and dynamics."""
        v, d = self.v, pwm_to_unit(pwm_us, self.v)
        h = self.fx.hysteresis
        if h is not None:
            start_f, stop_f, start_r, stop_r = h
            st = self.spinning[side]
            if st == 1 and d < stop_f:
                st = 0
            if st == -1 and d > stop_r:
                st = 0
            if st == 0:
                st = 1 if d >= start_f else (-1 if d <= start_r else 0)
            self.spinning[side] = st
            t = curve_thrust_n(d, v, st > 0) if st else 0.0
        elif d >= self.dz_f:
            t = curve_thrust_n(d, v, True)
        elif d <= self.dz_r:
            t = curve_thrust_n(d, v, False)
        else:
            t = 0.0
        if self.fx.ventilation is not None:
            knee = self.fx.ventilation[0] * self.full_fwd_n
            if t > knee:
                t = knee + self.fx.ventilation[1] * (t - knee)
        if v.thrust_min_n is not None:
            t = max(t, v.thrust_min_n)
        if v.thrust_max_n is not None:
            t = min(t, v.thrust_max_n)
        return t

    def step(self, k: int, cmd_l: list, cmd_r: list) -> tuple[float, float]:
        """Thrust (N) over step k, from the commands logged per tick (lists that grow as the run goes)."""
        kd = k - self.delay_steps
        i = kd // self.spt
        pl, pr = (cmd_l[i], cmd_r[i]) if kd >= 0 else (NEUTRAL_US, NEUTRAL_US)
        out = []
        for side, pwm in ((0, pl), (1, pr)):
            if pwm != self.last_pwm[side]:      # the map (and a settled hysteresis) only changes with the PWM
                self.last_pwm[side] = pwm
                self.target[side] = self.gains[side] * self.static_n(side, pwm)
            target = self.target[side]
            t = self.thrust[side]
            if self.fx.slew_n_per_s is not None:
                lim = self.fx.slew_n_per_s * self.dt
                t += min(max(target - t, -lim), lim)
            else:
                t += self.lag_a * (target - t)
            self.thrust[side] = t
            out.append(t * self.factor)
        return out[0], out[1]

    def update_battery(self, tl_n: float, tr_n: float, dt_s: float) -> None:
        """Energy drawn over dt (W·h), the pack's terminal voltage and, with battery sag, the thrust factor."""
        p_w = HOTEL_POWER_W + T200_POWER_W_PER_N15 * (abs(tl_n) ** 1.5 + abs(tr_n) ** 1.5)
        self.energy_wh += p_w * dt_s / 3600.0
        self.soc = max(self.fx.battery_soc0 - self.energy_wh / self.fx.battery_wh, 0.0)
        ocv = ocv_4s_v(self.soc)
        self.volt = ocv - p_w / ocv * self.fx.battery_r_ohm
        if self.fx.battery_sag:
            self.factor = (self.volt / self.v_ref) ** 2


def thruster_forces(v: Vessel, fx: Effects) -> Callable[[float, float], tuple]:
    """(T_left, T_right) N → (X, Y, N) in the body: a thruster's axis toed inward by α gives
    F = T (cos α, ±sin α) (left thruster pushes towards starboard), yaw moment x·F_y − y·F_x."""
    (xl, yl), (xr, yr) = v.left_xy_m, v.right_xy_m
    a = math.radians(fx.toe_in_deg)
    ca, sa = math.cos(a), math.sin(a)
    nl, nr = xl * sa - yl * ca, -xr * sa - yr * ca

    def forces(tl: float, tr: float) -> tuple:
        return ((tl + tr) * ca, (tl - tr) * sa, nl * tl + nr * tr)

    return forces


# ---------------------------------------------------------------- sensors

def iron_error_rad(psi: np.ndarray, iron: tuple) -> np.ndarray:
    """Heading error of a magnetic compass whose own iron bends the field it reads: the earth's
    horizontal field (unit, pointing north) seen in the body frame FRD is (cos ψ, −sin ψ); the
    soft iron scales and shears it, the hard iron adds a fixed body vector; the compass reports
    atan2(−m_y, m_x). Exact, not the deviation's Fourier series."""
    hx, hy, sxx, syy, sxy = iron
    bx, by = np.cos(psi), -np.sin(psi)
    mx = (1.0 + sxx) * bx + sxy * by + hx
    my = sxy * bx + (1.0 + syy) * by + hy
    return np.angle(np.exp(1j * (np.arctan2(-my, mx) - psi)))


@dataclass
class Sensors:
    """What is logged and when: sample steps, noise already drawn (so the autopilot sees exactly what
    the log later holds), the compass offset, GNSS latency, the true antenna position and faults."""
    first_step: int
    n_steps: int
    hdg_stride: int
    hdg_phase: int
    gnss_stride: int
    gnss_phase: int
    hdg_noise_rad: np.ndarray
    gyro_noise_rad_s: np.ndarray
    hdg_spike_rad: np.ndarray
    gnss_err_m: np.ndarray          # (n, 2) white + wander + outliers, north/east
    gnss_valid: np.ndarray
    heading_offset_rad: float
    antenna_xy_m: tuple
    latency_steps: int
    noise_info: dict = field(default_factory=dict)
    fault_info: dict = field(default_factory=dict)
    magnetometer: tuple | None = None
    motor_field: tuple | None = None

    def heading_error_rad(self, psi: np.ndarray | float, motor_power_w: np.ndarray | float = 0.0) -> np.ndarray | float:
        """Logged minus true heading: the offset plus the magnetometer's iron error and the field of the
        motor currents (a body-fixed offset growing with the power drawn, as ArduPilot's COMPASS_MOT)."""
        psi = np.asarray(psi, float)
        iron = self.magnetometer or (0.0, 0.0, 0.0, 0.0, 0.0)
        if self.motor_field is not None:
            p = np.asarray(motor_power_w, float)
            iron = (iron[0] + self.motor_field[0] * p, iron[1] + self.motor_field[1] * p) + tuple(iron[2:])
        elif self.magnetometer is None:
            return self.heading_offset_rad + 0.0 * psi
        return self.heading_offset_rad + iron_error_rad(psi, iron)

    def heading_steps(self) -> np.ndarray:
        return np.arange(self.first_step + self.hdg_phase, self.n_steps, self.hdg_stride)

    def gnss_steps(self) -> np.ndarray:
        return np.arange(self.first_step + self.gnss_phase, self.n_steps, self.gnss_stride)

    def latest_heading(self, k: int, psi: list, r: list, power: list) -> tuple[float, float] | None:
        """The newest heading (rad) and gyro rate (rad/s) at step k, as the autopilot reads them."""
        j = (k - self.first_step - self.hdg_phase) // self.hdg_stride
        if j < 0:
            return None
        ks = self.first_step + self.hdg_phase + j * self.hdg_stride
        return (psi[ks] + float(self.heading_error_rad(psi[ks], power[ks])) + self.hdg_noise_rad[j] +
                self.hdg_spike_rad[j],
                r[ks] + self.gyro_noise_rad_s[j])

    def latest_fix(self, k: int, n: list, e: list, psi: list) -> tuple[float, float, float] | None:
        """The newest valid GNSS fix stamped at or before step k: (north, east, stamp step)."""
        j = (k - self.latency_steps - self.first_step - self.gnss_phase) // self.gnss_stride
        while j >= 0 and not self.gnss_valid[j]:
            j -= 1
        if j < 0:
            return None
        ks = self.first_step + self.gnss_phase + j * self.gnss_stride
        ax, ay = self.antenna_xy_m
        c, s = math.cos(psi[ks]), math.sin(psi[ks])
        return (n[ks] + c * ax - s * ay + self.gnss_err_m[j, 0], e[ks] + s * ax + c * ay + self.gnss_err_m[j, 1],
                ks + self.latency_steps)


def make_sensors(rng: np.random.Generator, v: Vessel, fx: Effects, first_step: int, n_steps: int) -> Sensors:
    """Draw the sensor errors for a whole log: GNSS 2 cm white + Gauss-Markov wander (0.3-0.5 m, 1-5 min),
    heading 0.3° white at 10-50 Hz, gyro 0.005 rad/s, and the case's faults."""
    hz = int(rng.choice([10, 20, 25, 50]))
    hdg_stride = int(round(1.0 / (hz * DT_S)))
    gnss_stride = int(round(GNSS_PERIOD_S / DT_S))
    hdg_phase, gnss_phase = int(rng.integers(0, hdg_stride)), int(rng.integers(0, gnss_stride))
    n_h = len(range(first_step + hdg_phase, n_steps, hdg_stride))
    n_g = len(range(first_step + gnss_phase, n_steps, gnss_stride))
    white_m, hdg_sd_deg, gyro_sd = 0.02, 0.3, 0.005
    wander_m, wander_tau_s = float(rng.uniform(0.3, 0.5)), float(rng.uniform(60.0, 300.0))
    err = np.column_stack([rng.standard_normal(n_g) * white_m + gauss_markov(rng, n_g, GNSS_PERIOD_S, wander_m, wander_tau_s)
                           for _ in range(2)])
    valid = np.ones(n_g, bool)
    spikes = np.zeros(n_h)
    fault_info: dict = {}
    f = fx.faults
    if f:
        k_out = rng.random(n_g) < f["outlier_share"]
        ang = rng.uniform(0, 2 * np.pi, n_g)
        mag = rng.uniform(*f["outlier_m"], n_g)
        err[k_out, 0] += mag[k_out] * np.cos(ang[k_out])
        err[k_out, 1] += mag[k_out] * np.sin(ang[k_out])
        drops = []
        for _ in range(f["dropouts"]):
            j0 = int(rng.integers(0, n_g))
            dur = int(rng.uniform(*f["dropout_s"]) / GNSS_PERIOD_S)
            valid[j0:j0 + dur] = False
            drops.append([round(j0 * GNSS_PERIOD_S, 1), round(dur * GNSS_PERIOD_S, 1)])
        k_sp = rng.random(n_h) < f["spike_share"]
        spikes[k_sp] = np.radians(rng.uniform(*f["spike_deg"], int(k_sp.sum())) * rng.choice([-1, 1], int(k_sp.sum())))
        fault_info = {"gnss_outliers": int(k_out.sum()), "gnss_samples": n_g,
                      "gnss_dropouts_start_s_duration_s": drops, "heading_spikes": int(k_sp.sum()), "heading_samples": n_h}
    ant = (v.antenna_xy_m[0] + fx.antenna_offset_m[0], v.antenna_xy_m[1] + fx.antenna_offset_m[1])
    return Sensors(first_step, n_steps, hdg_stride, hdg_phase, gnss_stride, gnss_phase,
                   rng.standard_normal(n_h) * math.radians(hdg_sd_deg), rng.standard_normal(n_h) * gyro_sd, spikes,
                   err, valid, math.radians(fx.heading_offset_deg), ant, int(round(fx.gnss_latency_s / DT_S)),
                   {"gnss_white_m": white_m, "gnss_wander_sigma_m": round(wander_m, 3),
                    "gnss_wander_tau_s": round(wander_tau_s, 1), "gnss_hz": 5, "heading_hz": hz,
                    "heading_noise_deg": hdg_sd_deg, "yaw_rate_noise_rad_s": gyro_sd, "pwm_hz": 10,
                    "pwm_quantisation_us": 1, "voltage_hz": 2, "voltage_noise_v": 0.02}, fault_info, fx.magnetometer,
                   fx.motor_field)


# ---------------------------------------------------------------- drivers

def wrap_pi(a: float) -> float:
    """Angle in (−π, π]."""
    return (a + math.pi) % (2 * math.pi) - math.pi


def sticks_to_pwm(surge: float, yaw: float) -> tuple[float, float]:
    """Skid-steer mixing of stick levels in [−1, 1] (yaw > 0 turns to starboard), yaw kept on saturation."""
    left, right = surge + yaw, surge - yaw
    over = max(abs(left), abs(right))
    if over > 1.0:
        shift = math.copysign(over - 1.0, surge) if surge else 0.0
        left, right = left - shift, right - shift
        left, right = max(-1.0, min(1.0, left)), max(-1.0, min(1.0, right))
    return NEUTRAL_US + 400.0 * left, NEUTRAL_US + 400.0 * right


RC_STYLES = {  # hold kinds and their weights
    "default": {"cruise": 0.34, "turn": 0.22, "spin": 0.08, "reverse": 0.07, "idle": 0.15, "creep": 0.14,
                "creep_rev": 0.03, "nudge": 0.03},
    "spins": {"cruise": 0.26, "turn": 0.22, "spin": 0.25, "reverse": 0.05, "idle": 0.12, "creep": 0.10},
    "low": {"cruise": 0.16, "turn": 0.12, "spin": 0.06, "reverse": 0.08, "idle": 0.10, "creep": 0.20,
            "creep_rev": 0.14, "nudge": 0.14},
    "heavy": {"cruise": 0.50, "turn": 0.22, "spin": 0.06, "reverse": 0.04, "idle": 0.08, "creep": 0.10},
    "astern": {"cruise": 0.28, "turn": 0.16, "spin": 0.06, "reverse": 0.20, "idle": 0.12, "creep": 0.10,
               "creep_rev": 0.08},
}


class World:
    """What a driver may look at while the run goes: true state lists, commands so far, sensors."""

    def __init__(self, sensors: Sensors):
        self.sensors = sensors
        self.n: list = []
        self.e: list = []
        self.psi: list = []
        self.u: list = []
        self.v: list = []
        self.r: list = []
        self.power: list = []   # motor power drawn over each step (W): what the motor currents' field follows


class HumanDriver:
    """RC sticks held at random levels for random intervals (ramped in 0.2-0.8 s, with hand jitter),
    surge mostly forward, some reversing, turns, spins and creeping; the human brings the boat back
    when it strays beyond the lake radius. With idle_share: an idle-heavy lake log, drifting at neutral
    most of the time with short bursts under way."""

    def __init__(self, rng: np.random.Generator, style: str = "default", idle_share: float | None = None,
                 lake_radius_m: float = 100.0):
        self.rng, self.weights = rng, RC_STYLES[style]
        self.idle_share, self.lake_r = idle_share, lake_radius_m
        self.home: tuple | None = None
        self.end_tick, self.ramp_ticks, self.start_tick = 0, 1, 0
        self.prev, self.target, self.now = (0.0, 0.0), (0.0, 0.0), (0.0, 0.0)
        self.jitter = 0.0
        self.burst_left_s = 0.0
        self.neutral_s = self.underway_s = 0.0
        self.kinds = list(self.weights)
        self.p = np.array([self.weights[k] for k in self.kinds])
        self.p /= self.p.sum()

    def new_hold(self, tick: int, w: World, k: int) -> None:
        """Pick the next stick levels and how long to hold them."""
        rng = self.rng
        if self.home is None:
            self.home = (w.n[k], w.e[k])
        dn, de = self.home[0] - w.n[k], self.home[1] - w.e[k]
        kind = str(rng.choice(self.kinds, p=self.p))
        if self.idle_share is not None:
            if self.burst_left_s <= 0.0:
                f = self.idle_share         # drift long enough to bring the neutral share back to f
                need_s = (f * self.underway_s - (1 - f) * self.neutral_s) / (1 - f)
                drift_s = max(need_s * rng.uniform(0.6, 1.4), 10.0)
                self.burst_left_s = rng.uniform(10.0, 50.0)
                self.set_hold(tick, (0.0, 0.0), drift_s, 1)
                return
            if kind == "idle":
                kind = "cruise"
        if math.hypot(dn, de) > self.lake_r:
            rel = wrap_pi(math.atan2(de, dn) - w.psi[k])
            if abs(rel) > 0.4:
                self.set_hold(tick, (0.2, math.copysign(0.45, rel)), abs(rel) / 0.35 * rng.uniform(0.8, 1.2), 4)
            else:
                self.set_hold(tick, (rng.uniform(0.4, 0.7), rng.normal(0, 0.03)), rng.uniform(8, 20), 5)
            return
        u = rng.uniform
        sign = rng.choice([-1.0, 1.0])
        table = {
            "cruise": ((u(0.25, 0.7), rng.normal(0, 0.05)), u(5, 30)),      # up to ~2 m/s
            "turn": ((u(0.2, 0.6), sign * u(0.15, 0.5)), u(3, 15)),
            "spin": ((u(-0.05, 0.1), sign * u(0.3, 0.9)), u(3, 12)),
            "reverse": ((-u(0.2, 0.7), rng.normal(0, 0.05)), u(2, 8)),
            "idle": ((0.0, 0.0), u(3, 20)),
            "creep": ((u(0.03, 0.2), sign * u(0.0, 0.12)), u(5, 20)),
            "creep_rev": ((-u(0.03, 0.2), sign * u(0.0, 0.08)), u(4, 15)),
            "nudge": ((u(-0.03, 0.03), sign * u(0.05, 0.2)), u(3, 10)),      # docking: one slightly ahead, one astern
        }
        sticks, dur = table[kind]
        self.set_hold(tick, sticks, dur, int(rng.integers(2, 9)))

    def set_hold(self, tick: int, sticks: tuple, dur_s: float, ramp_ticks: int) -> None:
        """Hold these stick levels (surge, yaw) for dur_s after a ramp; in an idle-heavy log a burst's
        last hold is cut so that bursts stay short, and the time at neutral and under way is counted."""
        if self.idle_share is not None and sticks != (0.0, 0.0):
            dur_s = min(dur_s, self.burst_left_s + 2.0)
            self.burst_left_s -= dur_s
        self.prev, self.target = self.now, (float(sticks[0]), float(sticks[1]))
        self.start_tick, self.ramp_ticks = tick, max(ramp_ticks, 1)
        self.end_tick = tick + max(int(dur_s / TICK_S), 2)
        if sticks == (0.0, 0.0):
            self.neutral_s += (self.end_tick - tick) * TICK_S
        else:
            self.underway_s += (self.end_tick - tick) * TICK_S

    def command(self, tick: int, k: int, w: World) -> tuple[float, float]:
        if tick >= self.end_tick:
            self.new_hold(tick, w, k)
        f = min((tick - self.start_tick + 1) / self.ramp_ticks, 1.0)
        self.now = tuple(a + f * (b - a) for a, b in zip(self.prev, self.target))
        if self.target == (0.0, 0.0) and f >= 1.0:
            return NEUTRAL_US, NEUTRAL_US                      # sticks released: RC deadband gives exact neutral
        self.jitter = 0.8 * self.jitter + self.rng.normal(0, 0.006)
        pl, pr = sticks_to_pwm(self.now[0] + self.jitter, self.now[1] + 0.5 * self.jitter)
        return float(round(pl)), float(round(pr))


class Autopilot:
    """A waypoint autopilot of this world's own design, closing its loops on the MEASURED heading
    (gyro for damping) and GNSS (antenna taken as the boat's position, speed by differencing fixes):
    line-of-sight guidance, heading PI-D, speed PI with a rough feed-forward, skid-steer mixer, pivot
    turns when far off course, HOLD (motors stopped, drifting) between laps."""

    def __init__(self, rng: np.random.Generator):
        self.rng = rng
        self.kp, self.ki, self.kd = rng.uniform(1.0, 1.5), rng.uniform(0.05, 0.12), rng.uniform(0.25, 0.45)
        self.ff, self.kp_u, self.ki_u = rng.uniform(0.28, 0.36), rng.uniform(0.25, 0.4), rng.uniform(0.03, 0.08)
        self.lookahead_m, self.accept_m = rng.uniform(4.0, 8.0), 3.0
        self.wps: list = []
        self.speeds: list = []
        self.i_wp = 1
        self.i_psi = self.i_u = 0.0
        self.hold_until = -1
        self.last_fix: tuple | None = None
        self.vel_ne = (0.0, 0.0)
        self.gains = {"heading_kp_per_rad": self.kp, "heading_ki_per_rad_s": self.ki, "heading_kd_per_rad_s": self.kd,
                      "speed_ff_per_m_s": self.ff, "speed_kp": self.kp_u, "speed_ki": self.ki_u,
                      "los_lookahead_m": self.lookahead_m}
        self.gains = {k: round(float(x), 3) for k, x in self.gains.items()}

    def plan(self, start_ne: tuple) -> None:
        """A small mission: 4-6 waypoints on a jittered loop 30-70 m around the start, a speed per leg."""
        rng = self.rng
        n = int(rng.integers(4, 7))
        rad = rng.uniform(30.0, 70.0)
        a0 = rng.uniform(0, 2 * np.pi)
        ang = a0 + np.sort(rng.uniform(0, 2 * np.pi, n)) * rng.choice([-1, 1])
        self.wps = [start_ne] + [(start_ne[0] + rad * rng.uniform(0.6, 1.2) * math.cos(a),
                                  start_ne[1] + rad * rng.uniform(0.6, 1.2) * math.sin(a)) for a in ang] + [start_ne]
        self.speeds = [float(rng.uniform(0.8, 1.6)) for _ in self.wps]

    def command(self, tick: int, k: int, w: World) -> tuple[float, float]:
        s = w.sensors
        hdg, fix = s.latest_heading(k, w.psi, w.r, w.power), s.latest_fix(k, w.n, w.e, w.psi)
        if hdg is None or fix is None:
            return NEUTRAL_US, NEUTRAL_US
        psi_m, r_m = hdg
        if not self.wps:
            self.plan((fix[0], fix[1]))
        if self.last_fix is not None and fix[2] != self.last_fix[2]:
            dt = (fix[2] - self.last_fix[2]) * DT_S
            vn, ve = (fix[0] - self.last_fix[0]) / dt, (fix[1] - self.last_fix[1]) / dt
            self.vel_ne = (0.7 * self.vel_ne[0] + 0.3 * vn, 0.7 * self.vel_ne[1] + 0.3 * ve)
        self.last_fix = fix
        if tick < self.hold_until:
            return NEUTRAL_US, NEUTRAL_US
        a, b = self.wps[self.i_wp - 1], self.wps[self.i_wp]
        dist = math.hypot(b[0] - fix[0], b[1] - fix[1])
        if dist < self.accept_m:
            self.i_wp += 1
            if self.i_wp >= len(self.wps):
                self.i_wp = 1
                self.hold_until = tick + int(self.rng.uniform(15.0, 60.0) / TICK_S)
                self.i_psi = self.i_u = 0.0
                return NEUTRAL_US, NEUTRAL_US
            a, b = self.wps[self.i_wp - 1], self.wps[self.i_wp]
            dist = math.hypot(b[0] - fix[0], b[1] - fix[1])
        chi = math.atan2(b[1] - a[1], b[0] - a[0])
        e_ct = -(fix[0] - a[0]) * math.sin(chi) + (fix[1] - a[1]) * math.cos(chi)
        psi_d = chi - math.atan(e_ct / self.lookahead_m)
        e_psi = wrap_pi(psi_d - psi_m)
        self.i_psi = max(min(self.i_psi + e_psi * TICK_S, 0.3 / self.ki), -0.3 / self.ki)
        yaw = self.kp * e_psi + self.ki * self.i_psi - self.kd * r_m
        u_d = self.speeds[self.i_wp] * min(1.0, max(dist / 10.0, 0.5))
        u_m = self.vel_ne[0] * math.cos(psi_m) + self.vel_ne[1] * math.sin(psi_m)
        if abs(e_psi) > math.radians(60):
            thr = 0.12                                          # pivot turn
        else:
            self.i_u = max(min(self.i_u + (u_d - u_m) * TICK_S, 0.3 / self.ki_u), -0.3 / self.ki_u)
            thr = self.ff * u_d + self.kp_u * (u_d - u_m) + self.ki_u * self.i_u
        thr = max(min(thr, 1.0), -0.2)
        pl, pr = sticks_to_pwm(thr, max(min(yaw, 0.7), -0.7))
        return float(round(pl)), float(round(pr))


class ArrayDriver:
    """Replays given PWM per tick (the self-test uses it to drive two step sizes identically)."""

    def __init__(self, cmds: np.ndarray):
        self.cmds = cmds

    def command(self, tick: int, k: int, w: World) -> tuple[float, float]:
        i = min(tick, len(self.cmds) - 1)
        return float(self.cmds[i, 0]), float(self.cmds[i, 1])


# ---------------------------------------------------------------- the run

@dataclass
class Run:
    """The true history at every step, the logged commands per tick, battery per tick, environment."""
    t_s: np.ndarray
    x: np.ndarray          # (n, 6): north, east, psi, u, v, r (ground velocities, body)
    thrust_n: np.ndarray   # (n, 2)
    cmd_us: np.ndarray     # (ticks, 2)
    volt_v: np.ndarray     # per tick
    factor: np.ndarray     # per tick
    current_ne: np.ndarray  # (n, 2)
    wind_speed: np.ndarray
    wind_from_deg: np.ndarray
    first_step: int
    steps_per_tick: int
    energy_wh: float


def simulate(v: Vessel, fx: Effects, driver, sensors: Sensors, rng: np.random.Generator, duration_s: float,
             x0: tuple, dt_s: float = DT_S) -> Run:
    """Integrate the world for WARMUP_S + duration_s at dt_s; the driver is asked every 0.1 s."""
    spt = int(round(TICK_S / dt_s))
    first = int(round(WARMUP_S / dt_s))
    n_ticks = int(round((WARMUP_S + duration_s) / TICK_S))
    n_steps = n_ticks * spt
    t = (np.arange(n_steps + 1) - first) * dt_s
    cn, ce, dcn, dce = current_series(fx.current, v, t, duration_s)
    wn, we, wsp, wfrom = wind_series(fx.wind, rng, n_steps + 1)
    cn_l, ce_l, dcn_l, dce_l, wn_l, we_l = (a.tolist() for a in (cn, ce, dcn, dce, wn, we))
    rhs, forces = make_rhs(v, fx), thruster_forces(v, fx)
    if fx.sea is not None:   # drawn after the wind, and only here, so no other case's draws move
        chop = [gauss_markov(rng, n_steps + 1, dt_s, fx.sea[key], fx.sea["tau_s"]).tolist()
                for key in ("sigma_x_n", "sigma_y_n", "sigma_n_nm")]
        thrust_forces = forces

        def forces(tl, tr, k):
            fx_, fy_, fn_ = thrust_forces(tl, tr)
            return fx_ + chop[0][k], fy_ + chop[1][k], fn_ + chop[2][k]
    else:
        thrust_forces = forces
        forces = lambda tl, tr, k: thrust_forces(tl, tr)  # noqa: E731
    chain = ThrusterChain(v, fx, spt, dt_s)
    w = World(sensors)
    x = tuple(float(a) for a in x0)
    if x[3:] == (0.0, 0.0, 0.0):   # start drifting with the water, as a boat that has been idle
        c, s = math.cos(x[2]), math.sin(x[2])
        x = x[:3] + (cn_l[0] * c + ce_l[0] * s, -cn_l[0] * s + ce_l[0] * c, 0.0)
    for lst, val in zip((w.n, w.e, w.psi, w.u, w.v, w.r, w.power), x + (0.0,)):
        lst.append(val)
    cmd_l: list = []
    cmd_r: list = []
    thr: list = []
    volts: list = []
    factors: list = []
    for tick in range(n_ticks):
        k0 = tick * spt
        pl, pr = driver.command(tick - first // spt, k0, w) if k0 >= first else (NEUTRAL_US, NEUTRAL_US)
        cmd_l.append(pl)
        cmd_r.append(pr)
        sum_l = sum_r = 0.0
        for k in range(k0, k0 + spt):
            tl, tr = chain.step(k, cmd_l, cmd_r)
            thr.append((tl, tr))
            w.power.append(motor_power_w(tl, tr))
            sum_l += abs(tl)
            sum_r += abs(tr)
            x = rk4_step(rhs, x, dt_s, forces(tl, tr, k), (cn_l[k], ce_l[k], dcn_l[k], dce_l[k], wn_l[k], we_l[k]))
            w.n.append(x[0])
            w.e.append(x[1])
            w.psi.append(x[2])
            w.u.append(x[3])
            w.v.append(x[4])
            w.r.append(x[5])
        chain.update_battery(sum_l / spt, sum_r / spt, TICK_S)
        volts.append(chain.volt)
        factors.append(chain.factor)
    thr.append(thr[-1])
    return Run(t, np.column_stack([w.n, w.e, w.psi, w.u, w.v, w.r]), np.array(thr), np.column_stack([cmd_l, cmd_r]),
               np.array(volts), np.array(factors), np.column_stack([cn, ce]), wsp, wfrom, first, spt, chain.energy_wh)


# ---------------------------------------------------------------- recording

def geodetic_from_ne(north_m: np.ndarray, east_m: np.ndarray, lat0: float, lon0: float) -> tuple:
    """Flat-earth (tangent plane) inverse with the WGS-84 radii of curvature at lat0."""
    s2 = math.sin(math.radians(lat0)) ** 2
    r_n = WGS84_A_M / math.sqrt(1 - WGS84_E2 * s2)
    r_m = r_n * (1 - WGS84_E2) / (1 - WGS84_E2 * s2)
    return lat0 + np.degrees(north_m / r_m), lon0 + np.degrees(east_m / (r_n * math.cos(math.radians(lat0))))


def gap_mask(t_s: np.ndarray, gaps: list) -> np.ndarray:
    """True where a sample is kept (outside every logging gap [start, start + length))."""
    keep = np.ones(len(t_s), bool)
    for g0, glen in gaps:
        keep &= ~((t_s >= g0) & (t_s < g0 + glen))
    return keep


def low_pass(signal: np.ndarray, tau_s: float, dt_s: float) -> np.ndarray:
    """First-order low-pass y' = (x − y)/τ, exact for x held over each step, started at x[0] (the heading
    is continuous: the true ψ here is never wrapped)."""
    a = math.exp(-dt_s / tau_s)
    y = np.empty_like(signal)
    acc = float(signal[0])
    for i, xi in enumerate(signal.tolist()):
        acc = a * acc + (1.0 - a) * xi
        y[i] = acc
    return y


def recording_streams(run: Run, s: Sensors, fx: Effects, rng: np.random.Generator, t_boot_s: float,
                      gaps: list) -> list[tuple[np.ndarray, dict]]:
    """The logged streams [(stamps s, {column: formatted strings})], vectorised from the true history."""
    x = run.x
    streams = []
    kh = s.heading_steps()
    jh = np.arange(len(kh))
    psi = x[:, 2] if not fx.heading_lag_s else low_pass(x[:, 2], fx.heading_lag_s, DT_S)
    before = np.maximum(kh - 1, 0)   # the power drawn over the step that led to the sampled state
    power = motor_power_w(run.thrust_n[before, 0], run.thrust_n[before, 1])
    hdg = psi[kh] + s.heading_error_rad(psi[kh], power) + s.hdg_noise_rad[jh] + s.hdg_spike_rad[jh]
    rate = x[kh, 5] + s.gyro_noise_rad_s[jh]
    th = run.t_s[kh]
    keep = gap_mask(th, gaps)
    streams.append((th[keep] + t_boot_s, {"heading_deg": np.char.mod("%.3f", np.degrees(hdg[keep]) % 360.0),
                                          "yaw_rate": np.char.mod("%.5f", rate[keep])}))
    kg = s.gnss_steps()
    ax, ay = s.antenna_xy_m
    c, sn = np.cos(x[kg, 2]), np.sin(x[kg, 2])
    an = x[kg, 0] + c * ax - sn * ay + s.gnss_err_m[:, 0]
    ae = x[kg, 1] + sn * ax + c * ay + s.gnss_err_m[:, 1]
    tg = run.t_s[kg] + s.latency_steps * DT_S
    keep = gap_mask(tg, gaps) & s.gnss_valid & (tg <= run.t_s[-1])
    lat, lon = geodetic_from_ne(an[keep], ae[keep], ORIGIN_LAT_DEG, ORIGIN_LON_DEG)
    streams.append((tg[keep] + t_boot_s, {"lat": np.char.mod("%.9f", lat), "lon": np.char.mod("%.9f", lon)}))
    first_tick = run.first_step // run.steps_per_tick
    tp = (np.arange(first_tick, len(run.cmd_us)) - first_tick) * TICK_S
    cmd = run.cmd_us[first_tick:]
    tp_log = tp + fx.pwm_clock_offset_s
    keep = gap_mask(tp, gaps)
    streams.append((tp_log[keep] + t_boot_s, {"pwm_left": np.char.mod("%d", cmd[keep, 0].astype(int)),
                                              "pwm_right": np.char.mod("%d", cmd[keep, 1].astype(int))}))
    every = int(round(VOLT_PERIOD_S / TICK_S))
    iv = np.arange(first_tick + 5, len(run.volt_v), every)
    tv = (iv + 1 - first_tick) * TICK_S
    keep = gap_mask(tv, gaps) & (tv <= run.t_s[-1])
    volt = np.round(run.volt_v[iv] + rng.normal(0, 0.02, len(iv)), 2)
    streams.append((tv[keep] + t_boot_s, {"voltage": np.char.mod("%.2f", volt[keep])}))
    return streams


def csv_text(streams: list) -> str:
    """Generic CSV: one row per distinct stamp (1 µs), each stream's cells filled on its own rows."""
    cols = ["t"] + [c for _, d in streams for c in d]
    stamps_us = [np.round(t * 1e6).astype(np.int64) for t, _ in streams]
    rows_us = np.unique(np.concatenate(stamps_us))
    table = np.full((len(rows_us), len(cols)), "", dtype=object)
    table[:, 0] = [f"{x / 1e6:.6f}" for x in rows_us.tolist()]
    ci = 1
    for (_, d), tu in zip(streams, stamps_us):
        idx = np.searchsorted(rows_us, tu)
        for name in d:
            table[idx, ci] = d[name]
            ci += 1
    return ",".join(cols) + "\n" + "\n".join(",".join(row) for row in table.tolist()) + "\n"


def write_atomic(path: Path, text: str) -> None:
    """Write to a temporary file in the same folder, then rename over the target."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    except OSError as e:
        raise UsageError(f"cannot write {path}: {e.strerror or e}") from None
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException as e:
        if os.path.exists(tmp):
            os.unlink(tmp)
        if isinstance(e, OSError):
            raise UsageError(f"cannot write {path}: {e.strerror or e}") from None
        raise


# ---------------------------------------------------------------- cases

@dataclass
class LogPlan:
    """One outing: its driver, duration, effects and the rng that drives it."""
    driver: str
    duration_s: float
    fx: Effects
    rng: np.random.Generator
    style: str = "default"


@dataclass
class CaseSpec:
    """A named case: what it is, how it is driven, how long, and the builder of its effects
    ((rng, vessel) -> (Effects, truth entries); magnitudes drawn per seed inside stated ranges)."""
    description: str
    driver: str                  # rc | idle | closed_loop | multilog
    duration_s: float            # per log
    build: Callable              # (rng) -> (Effects for all logs, list of truth effect dicts, per-log effect tweak or None)
    style: str = "default"
    n_logs: tuple = (1, 1)


def effect(kind: str, form: str, params: dict, library: str, expected: dict, alternatives: list | None = None,
           notes: str = "") -> dict:
    """A truth entry in physical terms and what a diagnosis of the twin library should name."""
    d = {"kind": kind, "physical_form": form, "params": params, "library_equivalent": library,
         "expected_values": expected}
    if alternatives:
        d["library_alternatives"] = alternatives
    if notes:
        d["notes"] = notes
    return d


def r3(x: float) -> float:
    """Rounded for the truth file (mm, ms, 0.1 %)."""
    return round(float(x), 3)


def b_weak(side: str) -> Callable:
    """Builder of a weak thruster on `side` (k drawn in 0.65-0.80)."""
    def build(rng, v):
        k = r3(rng.uniform(0.65, 0.80))
        fx = Effects(**{f"gain_{side}": k})
        other = "right" if side == "left" else "left"
        return fx, [effect(f"weak_thruster_{side}", f"T_{side} = k·T200(pwm) in both directions (fouled/damaged "
                           f"propeller), T_{other} nominal; no compensation",
                           {"k": k}, "thruster_asymmetry",
                           {f"gain_{side}": k, f"gain_{other}": 1.0, "ratio_left_over_right":
                            r3(k if side == "left" else 1 / k)},
                           ["thrust_gain (mean gain (1+k)/2 with asymmetry)"])]
    return build


def b_strong(rng, v):
    """Both thrusters k = 1.12-1.18."""
    k = r3(rng.uniform(1.12, 1.18))
    return Effects(gain_left=k, gain_right=k), [effect(
        "both_thrusters_strong", "T = k·T200(pwm) on both thrusters (higher battery voltage than the map's)",
        {"k": k}, "thrust_gain", {"gain": k})]


def wind_spec(rng) -> dict:
    """Mean wind 4-6.5 m/s from anywhere, gusts 15 % of the mean (τ 6 s), direction meander 8° (τ 90 s)."""
    sp = r3(rng.uniform(4.0, 6.5))
    return {"speed": sp, "from_deg": r3(rng.uniform(0, 360)), "gust_sigma": r3(0.15 * sp), "gust_tau_s": 6.0,
            "dir_sigma_deg": 8.0, "dir_tau_s": 90.0}


def wind_effect(spec: dict) -> dict:
    """Truth entry of the Blendermann-like wind."""
    return effect(
        "wind_shape",
        "apparent wind (air velocity minus the hull's ground velocity, body axes) V_a, γ = atan2(−v_a, −u_a) "
        "(+ from starboard); X = ½ρ_a V_a² A_F Cx(|γ|), Y = ½ρ_a V_a² A_L Cy(|γ|) sgn γ, "
        "N = ½ρ_a V_a² A_L L Cn(|γ|) sgn γ, C tables (Blendermann-like) linearly interpolated every 20°; "
        "speed with Gauss-Markov gusts, direction meandering",
        {"mean_speed_m_s": spec["speed"], "from_deg": spec["from_deg"], "gust_sigma_m_s": spec["gust_sigma"],
         "gust_tau_s": spec["gust_tau_s"], "dir_sigma_deg": spec["dir_sigma_deg"], "dir_tau_s": spec["dir_tau_s"],
         "rho_air_kg_m3": RHO_AIR_KG_M3, "gamma_deg": list(np.arange(0, 181, 20).tolist()),
         "Cx": list(WIND_CX), "Cy": list(WIND_CY), "Cn": list(WIND_CN), "areas": "A_F, A_L, L of the params"},
        "wind", {"speed_m_s": spec["speed"], "dir_from_deg": spec["from_deg"]},
        notes="the library's cos/sin coefficient shape differs: its fitted speed may be off by tens of %, "
              "the direction should be within ~20°")


def b_wind(rng, v):
    """Wind through the world's coefficient tables."""
    spec = wind_spec(rng)
    return Effects(wind=spec), [wind_effect(spec)]


def current_effect(spec: dict, tidal: bool) -> dict:
    """Truth entry of a constant or turning/strengthening current."""
    mean_dir = 0.5 * (spec["dir0_deg"] + spec["dir1_deg"])
    if tidal:
        form = ("water velocity V_c(t) towards dir(t) = dir0 + (dir1−dir0)·t/T with speed s0 + (s1−s0)·½(1−cos πt/T); "
                "irrotational: D and C_A act on ν_r = ν − R(ψ)ᵀV_c, plus M_A ν̇_c")
        exp = {"speed_m_s": r3(0.5 * (spec["speed0"] + spec["speed1"])), "dir_deg": r3(mean_dir % 360),
               "speed_start_m_s": spec["speed0"], "speed_end_m_s": spec["speed1"],
               "dir_start_deg": spec["dir0_deg"] % 360, "dir_end_deg": spec["dir1_deg"] % 360}
        notes = "a constant-current fit should land near the log's mean vector; the change over the log is model-form"
    else:
        form = "constant water velocity V_c towards dir; D and C_A act on ν_r = ν − R(ψ)ᵀV_c"
        exp = {"speed_m_s": spec["speed0"], "dir_deg": spec["dir0_deg"] % 360}
        notes = ""
    return effect("current_tidal" if tidal else "constant_current", form,
                  {k: (val % 360 if "dir" in k else val) for k, val in spec.items()}, "current", exp, notes=notes)


def current_spec(rng, tidal: bool) -> dict:
    """Constant 0.12-0.25 m/s, or tidal: 0.08-0.15 → 0.2-0.3 m/s while turning 50-90°."""
    if not tidal:
        sp, d = r3(rng.uniform(0.12, 0.25)), r3(rng.uniform(0, 360))
        return {"speed0": sp, "speed1": sp, "dir0_deg": d, "dir1_deg": d}
    d0 = r3(rng.uniform(0, 360))
    return {"speed0": r3(rng.uniform(0.08, 0.15)), "speed1": r3(rng.uniform(0.2, 0.3)), "dir0_deg": d0,
            "dir1_deg": r3(d0 + rng.choice([-1, 1]) * rng.uniform(50, 90))}


def b_current(tidal: bool) -> Callable:
    """Builder of a current case."""
    def build(rng, v):
        spec = current_spec(rng, tidal)
        return Effects(current=spec), [current_effect(spec, tidal)]
    return build


def b_battery(rng, v):
    """A 40-50 Wh pack at 80-90 % charge drained by the run; thrust follows (V/V_ref)²."""
    wh, soc0, r = r3(rng.uniform(40.0, 50.0)), r3(rng.uniform(0.8, 0.9)), 0.03
    fx = Effects(battery_sag=True, battery_wh=wh, battery_soc0=soc0, battery_r_ohm=r)
    return fx, [effect(
        "battery_sag",
        "T = T200(pwm)·(V/V_ref)², V = OCV_4S(SoC) − I·R_int, SoC = SoC0 − E_drawn/E_pack, "
        "E_drawn = ∫(P_hotel + k_P Σ|T|^1.5) dt; V_ref = open-circuit voltage at the start (LiPo curve, "
        "steeper when low): the loss follows the energy used, not the clock",
        {"pack_wh": wh, "soc0": soc0, "r_int_ohm": r, "hotel_w": HOTEL_POWER_W,
         "k_p_w_per_n1_5": T200_POWER_W_PER_N15, "ocv_cell_soc": list(CELL_SOC), "ocv_cell_v": list(CELL_V)},
        "thrust_decay", {}, ["thrust_gain (mean factor)"],
        notes="the voltage column logs the pack voltage (every case logs it; only here does thrust follow it)")]


def b_slew(rng, v):
    """Thrust rate limit 10-16 N/s."""
    rate = r3(rng.uniform(10.0, 16.0))
    return Effects(slew_n_per_s=rate), [effect(
        "thruster_rate_limit", "dT/dt = clip((T200(pwm) − T)/dt, ±R): thrust slews at a fixed rate R (ESC ramp), "
        "not a first-order lag", {"rate_n_per_s": rate}, "thrust_ramp",
        {"ramp_s": None, "equivalent_lag_s": None}, ["thruster_lag", "input_delay"],
        notes="ramp_s: the map's full forward thrust over R (the library's thrust_ramp; "
              "the proof also accepts the first-order lag as naming it); "
              "equivalent_lag_s: the first-order lag whose response best matches the slewed thrust")]


def b_delay(rng, v):
    """Transport delay 0.3-0.5 s."""
    d = round(float(rng.uniform(0.3, 0.5)), 2)
    return Effects(delay_s=d), [effect(
        "input_delay", "T(t) = T200(pwm(t − d)): pure transport delay between the logged command and the thrust",
        {"delay_s": d}, "input_delay", {"delay_s": d}, ["thruster_lag", "clock_offset (negative)"])]


def b_deadzone_asym(rng, v):
    """Dead-zone edges forward 1540-1548 µs, reverse 1415-1425 µs."""
    pf, pr = round(float(rng.uniform(1540, 1548))), round(float(rng.uniform(1415, 1425)))
    df, dr = pwm_to_unit(pf, v), pwm_to_unit(pr, v)
    fx = Effects(dz_fwd=df, dz_rev=dr)
    return fx, [effect(
        "deadzone_asym", "zero thrust for PWM in (rev_edge, fwd_edge); outside it the params' T200 branches "
        "unchanged (a step at each edge); reverse band much wider than the params'",
        {"fwd_edge_pwm_us": pf, "rev_edge_pwm_us": pr,
         "params_fwd_edge_pwm_us": r3(unit_to_pwm(v.dz_fwd, v)), "params_rev_edge_pwm_us": r3(unit_to_pwm(v.dz_rev, v))},
        "dead_zone", {"fwd_edge_pwm_us": pf, "rev_edge_pwm_us": pr, "fwd_delta_unit": r3(df), "rev_delta_unit": r3(dr)})]


def b_hysteresis(rng, v):
    """Start/stop hysteresis: start 1550-1565 / 1425-1440 µs, stop 1510-1520 / 1478-1488 µs."""
    start_f, stop_f = round(float(rng.uniform(1550, 1565))), round(float(rng.uniform(1510, 1520)))
    start_r, stop_r = round(float(rng.uniform(1425, 1440))), round(float(rng.uniform(1478, 1488)))
    h = tuple(pwm_to_unit(p, v) for p in (start_f, stop_f, start_r, stop_r))
    return Effects(hysteresis=h), [effect(
        "deadzone_hysteresis", "motor start/stop hysteresis: a stopped thruster starts only past start_fwd/start_rev; "
        "a spinning one keeps its T200 branch until the PWM passes stop_fwd/stop_rev back towards neutral",
        {"start_fwd_pwm_us": start_f, "stop_fwd_pwm_us": stop_f, "start_rev_pwm_us": start_r, "stop_rev_pwm_us": stop_r},
        "motor_start", {"start_fwd_pwm_us": start_f, "start_rev_pwm_us": start_r,
                        "fwd_edge_pwm_us": r3(0.5 * (start_f + stop_f)), "rev_edge_pwm_us": r3(0.5 * (start_r + stop_r))},
        alternatives=["dead_zone"],
        notes="the library's motor_start keeps the stop edges at its dead zone (31 / 37 µs from neutral, where the "
              "T200 curve gives under 0.7 N) and fits the start edges; a dead zone alone can only average the "
              "start and stop edges")]


def b_fouling(rng, v):
    """Cubic surge drag, k3 0.8-1.4 N s³/m³."""
    k3 = r3(rng.uniform(0.8, 1.4))
    return Effects(fouling_k3=k3), [effect(
        "hull_fouling", "extra surge drag X = −k3·u_r³ (grows with the cube of the water speed)", {"k3_n_s3_m3": k3},
        "quadratic_damping", {}, ["linear_damping", "thrust_gain"],
        notes="expected: least-squares projection of −k3·u_r³ on the library's surge forms over this log's speeds")]


def b_yawdrag(rng, v):
    """Coulomb-like plus cubic yaw drag, Nc 1.2-1.8 N m, Nrrr 3-6 N m s³."""
    nc, nrrr, r0 = r3(rng.uniform(1.2, 1.8)), r3(rng.uniform(3.0, 6.0)), 0.08
    return Effects(yaw_coulomb_nm=nc, yaw_r0_rad_s=r0, yaw_nrrr=nrrr), [effect(
        "yaw_drag_shape", "extra yaw moment N = −Nc·tanh(r/r0) − Nrrr·r³: a Coulomb-like term (large "
        "relative to Nr·r at low r) plus a cubic term; spins are slower",
        {"Nc_nm": nc, "r0_rad_s": r0, "Nrrr_nm_s3": nrrr}, "linear_damping", {},
        ["quadratic_damping", "added_mass"],
        notes="expected: least-squares projection of the extra moment on r and r|r| over this log's yaw rates")]


def b_astern(rng, v):
    """Hull drag astern 1.8-2.6 times the params' (a transom stern leading)."""
    k = r3(rng.uniform(1.8, 2.6))
    return Effects(astern_drag=k), [effect(
        "astern_drag", "while the water meets the transom (u_r < 0) the surge drag is k·(Xu + Xuu·|u_r|)·u_r: a hull "
        "drawn to go ahead resists going astern more (flat transom, spray rails); ahead unchanged",
        {"factor": k}, "astern_resistance", {"factor": k, "excess": r3(k - 1.0)},
        ["reverse_thrust (astern thrust weaker: the same steady speed astern, not the same coast-down)"],
        notes="the library's astern_resistance scales the whole surge curve astern by 1 + excess, "
              "as this world does")]


def b_sea(rng, v):
    """Zero-mean chop: body-axis force and moment as Gauss-Markov series (σ X, Y 2-3 N, N 0.8-1.2 N m, τ 1.5-3 s)."""
    sea = {"sigma_x_n": r3(rng.uniform(2.0, 3.0)), "sigma_y_n": r3(rng.uniform(2.0, 3.0)),
           "sigma_n_nm": r3(rng.uniform(0.8, 1.2)), "tau_s": r3(rng.uniform(1.5, 3.0))}
    return Effects(sea=sea), [effect(
        "sea_chop", "short wind waves as zero-mean random forcing: X, Y, N each a first-order Gauss-Markov series "
        "(σ, τ) in body axes, independent of the boat's state; no mean drift", sea, "none (model-form)", {},
        notes="no deterministic effect describes it and none should be named: the residual it leaves is for the "
              "report's 'twin's form' lines, not for a library effect")]


def b_toe(rng, v):
    """Thrusters toed in 5-8°."""
    a = r3(rng.uniform(5.0, 8.0))
    (xl, yl) = v.left_xy_m
    arm = abs(yl) * math.cos(math.radians(a)) - abs(xl) * math.sin(math.radians(a))
    return Effects(toe_in_deg=a), [effect(
        "thruster_toe", "each thruster axis turned inward by α: F_left = T_l(cos α, +sin α), F_right = T_r(cos α, "
        "−sin α); sway force (T_l − T_r) sin α and yaw moment Σ x·F_y − y·F_x (arm |y|cos α − |x|sin α)",
        {"toe_in_deg": a}, "none (model-form)",
        {"yaw_arm_ratio": r3(arm / abs(yl)), "surge_ratio": r3(math.cos(math.radians(a))),
         "sway_per_differential_thrust": r3(math.sin(math.radians(a)))},
        ["linear_damping (Nr up)", "added_mass", "coupling_damping"],
        notes="the differential yaw moment is lower by the ratio above; nothing in the library adds a sway force from thrust")]


def b_latency(rng, v):
    """GNSS stamped 0.2-0.4 s late."""
    lat = round(float(rng.uniform(0.2, 0.4)), 2)
    return Effects(gnss_latency_s=lat), [effect(
        "gnss_latency", "GNSS fix of the antenna at time t is stamped t + L (heading and PWM on time)",
        {"latency_s": lat}, "gnss_latency", {"gnss_latency_s": lat}, ["input_delay (~L)", "clock_offset (~−L)"],
        notes="the library's gnss_latency shifts the fixes back by L, as this world stamps them")]


def b_antenna(rng, v):
    """Antenna 0.3-0.5 m (random direction) from the params' position."""
    mag, ang = rng.uniform(0.3, 0.5), rng.uniform(0, 2 * np.pi)
    off = (r3(mag * math.cos(ang)), r3(mag * math.sin(ang)))
    true = (r3(v.antenna_xy_m[0] + off[0]), r3(v.antenna_xy_m[1] + off[1]))
    return Effects(antenna_offset_m=off), [effect(
        "gnss_antenna_offset", "antenna at the params' position + Δ (body FRD x, y)",
        {"offset_x_m": off[0], "offset_y_m": off[1], "true_antenna_x_m": true[0], "true_antenna_y_m": true[1]},
        "gnss_lever_arm", {"antenna_offset_x_m": off[0], "antenna_offset_y_m": off[1],
                           "antenna_x_m": true[0], "antenna_y_m": true[1]})]


def b_iron(rng, v):
    """Compass iron: hard iron 0.06-0.10 of the field in a random body direction, soft iron ±1-3 %
    per axis and up to 1 % shear."""
    mag, ang = rng.uniform(0.06, 0.10), rng.uniform(0, 2 * np.pi)
    iron = (r3(mag * math.cos(ang)), r3(mag * math.sin(ang)),
            r3(rng.choice([-1, 1]) * rng.uniform(0.01, 0.03)), r3(rng.choice([-1, 1]) * rng.uniform(0.01, 0.03)),
            r3(rng.uniform(-0.01, 0.01)))
    psi = np.linspace(-np.pi, np.pi, 720, endpoint=False)
    basis = np.column_stack([np.ones_like(psi), np.sin(psi), np.cos(psi), np.sin(2 * psi), np.cos(2 * psi)])
    a, b, c, d, e = np.degrees(np.linalg.lstsq(basis, iron_error_rad(psi, iron), rcond=None)[0])
    peak = float(np.degrees(np.abs(iron_error_rad(psi, iron)).max()))
    return Effects(magnetometer=iron), [effect(
        "compass_iron", "magnetic compass reading a field bent by the boat's own iron: the earth's field in the body "
        "frame, scaled and sheared by soft iron, plus a fixed hard-iron vector; heading = atan2(−m_y, m_x), exact",
        {"hard_x": iron[0], "hard_y": iron[1], "soft_xx": iron[2], "soft_yy": iron[3], "soft_xy": iron[4]},
        "compass_deviation", {"b_deg": r3(b), "c_deg": r3(c), "d_deg": r3(d), "e_deg": r3(e), "a_deg": r3(a),
                              "peak_error_deg": r3(peak)},
        ["heading_bias (the constant part, or the mean over the headings sailed)"],
        notes="the library's candidate fits the one-cycle terms B, C; the two-cycle D, E and the constant A "
              "(soft iron) are left over, and a single log's compass calibration may take a constant")]


def b_motor_field(rng, v):
    """The motor currents' own field at the compass: a body-fixed offset of 0.08-0.15 of the earth's horizontal
    field at both thrusters' full forward power, in a random body direction, growing with the power drawn."""
    mag, ang = rng.uniform(0.08, 0.15), rng.uniform(0, 2 * np.pi)
    full_w = 2.0 * motor_power_w(curve_thrust_n(pwm_to_unit(v.pwm_max_us, v), v, True), 0.0)
    per_w = (mag * math.cos(ang) / full_w, mag * math.sin(ang) / full_w)
    psi = np.linspace(-np.pi, np.pi, 720, endpoint=False)
    full = iron_error_rad(psi, (mag * math.cos(ang), mag * math.sin(ang), 0, 0, 0))
    peak = float(np.degrees(np.abs(full).max()))
    basis = np.column_stack([np.sin(psi), np.cos(psi)])
    b, c = np.degrees(np.linalg.lstsq(basis, full, rcond=None)[0])
    return Effects(motor_field=per_w), [effect(
        "compass_motor_field", "magnetic compass disturbed by the thrusters' currents (ArduPilot's COMPASS_MOT): the "
        "field read is the earth's plus c·P, a body-fixed vector times the motor power drawn; heading = "
        "atan2(−m_y, m_x), exact; at idle no error",
        {"field_at_full_power": r3(mag), "direction_body_deg": r3(math.degrees(ang)), "full_power_w": r3(full_w),
         "peak_error_at_full_power_deg": r3(peak)},
        "compass_motor", {"b_deg": r3(b), "c_deg": r3(c)},
        ["heading_bias (the error's mean where the boat runs under power)",
         "compass_deviation (its heading-dependent part at the power mostly drawn)"],
        notes="the library's form follows the throttle linearly, ArduPilot's "
              "COMPASS_MOT_TYPE 1; this world's follows the electrical power, about the cube of the throttle for a "
              "T200, so at part throttle the library's form at these full-throttle values overstates the error and "
              "a fitted one comes out smaller. A hull, thruster or wind effect named would be invented")]


def b_ventilation(rng, v):
    """Forward thrust beyond 40-55 % of full grows at 0.3-0.5 of the map's slope (a propeller near the
    surface drawing air under heavy load): a knee in the thrust curve, not a gain."""
    knee, slope = r3(rng.uniform(0.40, 0.55)), r3(rng.uniform(0.3, 0.5))
    full = curve_thrust_n(pwm_to_unit(v.pwm_max_us, v), v, True)
    return Effects(ventilation=(knee, slope)), [effect(
        "thrust_ventilation", "forward thrust T of the map above the knee k·T_full becomes k·T_full + s·(T − k·T_full) "
        "(both thrusters; astern unchanged)", {"knee_share_of_full": knee, "slope_beyond": slope},
        "full_thrust", {"full_thrust_n": r3(full), "thrust_at_full_n": r3(knee * full + slope * (1 - knee) * full),
                        "share": r3(knee + slope * (1 - knee))},
        ["thrust_gain (the loss averaged over the PWM driven)", "thrust_speed_loss (a loss growing with speed)",
         "surge_resistance (more drag at the speeds high thrust reaches)"],
        notes="the library's full_thrust bends the curve over smoothly (T/√(1 + k(T/T_full)²)) where this world has a "
              "knee; its share is the thrust at full PWM. A yaw damping standing in for it (a spin's forward thruster "
              "gives less than the map) or a sensor effect beside it would be invented")]


def b_clock(rng, v):
    """PWM log stamped 0.3-0.5 s late."""
    d = round(float(rng.uniform(0.3, 0.5)), 2)
    return Effects(pwm_clock_offset_s=d), [effect(
        "pwm_clock_offset", "the PWM log's stamps are late by d against GNSS and heading (logged at t + d)",
        {"offset_s": d}, "clock_offset", {"pwm_clock_offset_s": d},
        notes="sign as the library's pwm_clock_offset_s: > 0 = PWM stamps late (thrust seems to answer early)")]


def b_heading_lag(rng, v):
    """The logged heading lags the boat through a first-order filter, τ 0.3-0.6 s; the gyro's yaw rate does not."""
    tau = round(float(rng.uniform(0.3, 0.6)), 2)
    return Effects(heading_lag_s=tau), [effect(
        "heading_lag", "logged heading = first-order low-pass of the true heading (τ): an AHRS or compass filter "
        "that smooths the heading and makes it late by about τ in a turn; the gyro's yaw rate column unfiltered",
        {"tau_s": tau}, "heading_latency", {"heading_latency_s": tau},
        ["gnss_latency (negative, about −τ: the track early against the heading)",
         "clock_offset (negative, about −τ: the PWM early against the heading)"],
        notes="the library's heading_latency is a pure delay: a first-order filter's delay at "
              "low frequency is τ, and it also damps the heading's faster wiggles, which a delay does not; a "
              "thruster lag or any hull effect named would be invented")]


def b_faults(rng, v):
    """GNSS outliers 2-4 % (1-3 m), 3-6 dropouts of 2-15 s, heading spikes 0.3-1 % (5-40°)."""
    f = {"outlier_share": r3(rng.uniform(0.02, 0.04)), "outlier_m": (1.0, 3.0), "dropouts": int(rng.integers(3, 7)),
         "dropout_s": (2.0, 15.0), "spike_share": r3(rng.uniform(0.003, 0.01)), "spike_deg": (5.0, 40.0)}
    return Effects(faults=f), [effect(
        "measurement_faults", "GNSS multipath outliers (a share of fixes displaced 1-3 m in a random direction), "
        "GNSS dropouts (fixes missing 2-15 s), heading spikes (single samples ±5-40°); the boat itself is nominal",
        {k: (list(x) if isinstance(x, tuple) else x) for k, x in f.items()}, "none", {},
        notes="a robust diagnosis names no physical effect")]


def b_null(rng, v):
    """Nothing beyond the params (sensor noise only)."""
    return Effects(), []


def heading_offsets(rng, n: int) -> list[float]:
    """Per-log compass offsets of mixed sign, 1.5-7°."""
    mags = rng.uniform(1.5, 7.0, n)
    signs = np.array([1, -1] * n)[:n]
    rng.shuffle(signs)
    return [round(float(m * s), 2) for m, s in zip(mags, signs)]


def pair(*builders: Callable) -> Callable:
    """Two effects at once: merge the non-default fields of each builder's Effects."""
    def build(rng, v):
        fx, truth = Effects(), []
        base = Effects()
        for b in builders:
            f, t = b(rng, v)
            for k in vars(f):
                if getattr(f, k) != getattr(base, k):
                    setattr(fx, k, getattr(f, k))
            truth += t
        return fx, truth
    return build


CASES: dict[str, CaseSpec] = {
    "null_rc": CaseSpec("no effect, RC driving, sensor noise only", "rc", 900, b_null),
    "null_idle": CaseSpec("no effect, idle-heavy lake log (75-90 % at neutral)", "idle", 1800, b_null),
    "null_closed_loop": CaseSpec("no effect, waypoint autopilot on measured heading/GNSS", "closed_loop", 900, b_null),
    "null_multilog": CaseSpec("no effect, 3-4 outings (mixed drivers), no compass offsets", "multilog", 480, b_null,
                              n_logs=(3, 4)),
    "weak_thruster_left": CaseSpec("left thruster delivers k = 0.65-0.8 of its thrust, RC", "rc", 900, b_weak("left")),
    "weak_thruster_right": CaseSpec("right thruster delivers k = 0.65-0.8, autopilot compensating", "closed_loop", 900,
                                    b_weak("right")),
    "both_thrusters_strong": CaseSpec("both thrusters deliver 1.12-1.18x, RC", "rc", 720, b_strong),
    "wind_shape": CaseSpec("steady wind 4-6.5 m/s with gusts, Blendermann-like coefficient tables, RC", "rc", 900,
                           b_wind),
    "wind_shape_idle": CaseSpec("the same wind on an idle-heavy log (drifting downwind)", "idle", 1500, b_wind),
    "constant_current": CaseSpec("constant current 0.12-0.25 m/s, idle-heavy", "idle", 1500, b_current(False)),
    "current_tidal": CaseSpec("current turning 50-90° and strengthening 0.1 -> 0.25 m/s over the log, RC", "rc", 1200,
                              b_current(True)),
    "current_closed_loop": CaseSpec("constant current 0.12-0.25 m/s, autopilot crabbing against it", "closed_loop",
                                    900, b_current(False)),
    "battery_sag": CaseSpec("thrust ∝ (V/V_ref)², V from a small aged 4S pack drained by the run, RC (heavy use)",
                            "rc", 1080, b_battery, style="heavy"),
    "thruster_rate_limit": CaseSpec("thrust slews at 10-16 N/s instead of following the PWM, RC", "rc", 720, b_slew),
    "input_delay": CaseSpec("PWM acts 0.3-0.5 s late (transport delay), RC", "rc", 720, b_delay),
    "deadzone_asym": CaseSpec("dead zone PWM ~1420-1545 (reverse much wider than the params'), RC low sticks", "rc",
                              900, b_deadzone_asym, style="low"),
    "deadzone_hysteresis": CaseSpec("motor start/stop hysteresis around neutral, RC low sticks", "rc", 900,
                                    b_hysteresis, style="low"),
    "hull_fouling": CaseSpec("extra surge drag −k3·u³ (k3 0.8-1.4 N s³/m³), RC", "rc", 900, b_fouling),
    "yaw_drag_shape": CaseSpec("extra yaw drag −Nc·tanh(r/r0) − Nrrr·r³, RC with many spins", "rc", 900, b_yawdrag,
                               style="spins"),
    "astern_drag": CaseSpec("hull drag astern 1.8-2.6x the params' (transom leading), RC with reversing", "rc", 900,
                            b_astern, style="astern"),
    "sea_chop": CaseSpec("zero-mean random forcing of short waves (σ 2-3 N, 0.8-1.2 N m, τ 1.5-3 s), RC", "rc", 900,
                         b_sea),
    "thruster_toe": CaseSpec("thrusters toed in 5-8°: sway force and smaller yaw arm under thrust, RC", "rc", 900,
                             b_toe, style="spins"),
    "compass_offset_per_log": CaseSpec("3-4 outings, each with its own compass offset (±1.5-7°)", "multilog", 480,
                                       b_null, n_logs=(3, 4)),
    "gnss_latency": CaseSpec("GNSS stamped 0.2-0.4 s late, RC", "rc", 900, b_latency),
    "gnss_antenna_offset": CaseSpec("antenna 0.3-0.5 m from where the params say, RC with spins", "rc", 900,
                                    b_antenna, style="spins"),
    "compass_iron": CaseSpec("magnetic compass with hard and soft iron (deviation 3.5-6°, exact atan2 form), RC",
                             "rc", 900, b_iron),
    "compass_motor_field": CaseSpec("compass disturbed by the thrusters' currents (0.08-0.15 of the field at full "
                                    "power, body-fixed direction), RC", "rc", 900, b_motor_field),
    "thrust_ventilation": CaseSpec("forward thrust saturating beyond 40-55 % of full (slope ×0.3-0.5), RC heavy "
                                   "sticks", "rc", 900, b_ventilation, style="heavy"),
    "pwm_clock_offset": CaseSpec("PWM log stamped 0.3-0.5 s late against GNSS/heading, RC", "rc", 900, b_clock),
    "heading_lag": CaseSpec("logged heading through a 0.3-0.6 s first-order filter (AHRS), RC", "rc", 900,
                            b_heading_lag),
    "measurement_faults": CaseSpec("GNSS outliers 2-4 %, dropouts, heading spikes; boat nominal, RC", "rc", 900,
                                   b_faults),
    "pair_weak_left_wind": CaseSpec("weak left thruster + Blendermann wind, RC", "rc", 900,
                                    pair(b_weak("left"), b_wind)),
    "wind_per_outing_multilog": CaseSpec("3-4 outings, each under its own Blendermann-like wind (4-6.5 m/s from "
                                         "anywhere, gusts): the wind changed between outings", "multilog", 480,
                                         b_null, n_logs=(3, 4)),
    "pair_current_compass_multilog": CaseSpec("constant current + per-log compass offsets, 3-4 outings", "multilog",
                                              480, b_current(False), n_logs=(3, 4)),
    "pair_fouling_delay_cl": CaseSpec("hull fouling + 0.3-0.5 s input delay under the autopilot", "closed_loop", 900,
                                      pair(b_fouling, b_delay)),
}
MULTILOG_OFFSETS = {"compass_offset_per_log", "pair_current_compass_multilog"}
MULTILOG_WINDS = {"wind_per_outing_multilog"}


# ---------------------------------------------------------------- expected values from the realised run

def logged_steps(run: Run) -> np.ndarray:
    """Logged steps (not warm-up)."""
    return np.arange(run.first_step, len(run.t_s))


def relative_velocity(run: Run) -> tuple[np.ndarray, np.ndarray]:
    """u_r, v_r over the whole run."""
    psi = run.x[:, 2]
    c, s = np.cos(psi), np.sin(psi)
    cn, ce = run.current_ne[:, 0], run.current_ne[:, 1]
    return run.x[:, 3] - (cn * c + ce * s), run.x[:, 4] - (-cn * s + ce * c)


def project(extra: np.ndarray, basis: list[np.ndarray]) -> list[float]:
    """Least-squares coefficients of `extra` on the basis columns (how the library's forms would absorb it)."""
    A = np.column_stack(basis)
    return [float(c) for c in np.linalg.lstsq(A, extra, rcond=None)[0]]


def finalize_expected(tr: dict, run: Run, fx: Effects, v: Vessel) -> None:
    """Fill expected values that depend on what the log actually did (speeds, yaw rates, energy)."""
    k = logged_steps(run)
    ur, _ = relative_velocity(run)
    kind = tr["kind"]
    if kind == "hull_fouling":
        u = ur[k]
        extra = -fx.fouling_k3 * u ** 3
        (dxuu,) = project(extra, [u * np.abs(u)])
        dxu, dxuu2 = project(extra, [u, u * np.abs(u)])
        tr["expected_values"] = {"delta_Xuu_alone": r3(dxuu), "delta_Xu_joint": r3(dxu), "delta_Xuu_joint": r3(dxuu2),
                                 "Xuu_total_alone": r3(v.damping["Xuu"] + dxuu),
                                 "u_r_rms_m_s": r3(np.sqrt(np.mean(u ** 2)))}
    elif kind == "yaw_drag_shape":
        r = run.x[k, 5]
        extra = -fx.yaw_coulomb_nm * np.tanh(r / fx.yaw_r0_rad_s) - fx.yaw_nrrr * r ** 3
        (dnr,) = project(extra, [r])
        dnr2, dnrr2 = project(extra, [r, r * np.abs(r)])
        tr["expected_values"] = {"delta_Nr_alone": r3(dnr), "delta_Nr_joint": r3(dnr2), "delta_Nrr_joint": r3(dnrr2),
                                 "Nr_total_alone": r3(v.damping["Nr"] + dnr), "r_rms_rad_s": r3(np.sqrt(np.mean(r ** 2)))}
    elif kind == "battery_sag":
        first_tick = run.first_step // run.steps_per_tick
        f = run.factor[first_tick:]
        t_min = np.arange(len(f)) * TICK_S / 60.0
        slope = np.polyfit(t_min, f, 1)[0]
        tr["expected_values"] = {"thrust_factor_start": r3(f[:600].mean()), "thrust_factor_end": r3(f[-600:].mean()),
                                 "linear_fit_decay_per_min": round(float(-slope), 5),
                                 "voltage_start_v": r3(run.volt_v[first_tick]), "voltage_end_v": r3(run.volt_v[-1]),
                                 "energy_wh": r3(run.energy_wh)}
    elif kind == "thruster_rate_limit":
        full = ThrusterChain(v, Effects(), run.steps_per_tick, DT_S).static_n(0, v.pwm_max_us)
        tr["expected_values"] = {"ramp_s": r3(full / tr["params"]["rate_n_per_s"]), **equivalent_lag(run, v)}


def equivalent_lag(run: Run, v: Vessel) -> dict:
    """The first-order lag τ whose response to this log's commanded thrust best matches the slewed thrust
    (least squares over a grid of τ): what a lag-only model should fit here."""
    spt = run.steps_per_tick
    chain = ThrusterChain(v, Effects(), spt, DT_S)
    k = logged_steps(run)[:-1]
    from scipy.signal import lfilter      # imported here: scipy.signal takes ~0.5 s to import
    sides = []
    for side, gain in ((0, v.gain_left), (1, v.gain_right)):
        target_tick = np.array([gain * chain.static_n(side, p) for p in run.cmd_us[:, side]])
        sides.append((target_tick[k // spt], run.thrust_n[k, side]))

    def sse(tau: float) -> float:
        a = 1.0 - math.exp(-DT_S / tau)
        return sum(float(np.sum((lfilter([a], [1.0, -(1.0 - a)], x, zi=[(1.0 - a) * y[0]])[0] - y) ** 2))
                   for x, y in sides)

    coarse = np.arange(0.02, 2.0, 0.05)
    best = coarse[int(np.argmin([sse(t) for t in coarse]))]
    fine = np.arange(max(best - 0.05, 0.01), best + 0.05, 0.005)
    errs = [sse(t) for t in fine]
    i = int(np.argmin(errs))
    return {"equivalent_lag_s": r3(fine[i]), "rms_misfit_of_that_lag_n": r3(math.sqrt(errs[i] / (2 * len(k))))}


# ---------------------------------------------------------------- generating a case

def case_rng(case: str, seed: int) -> np.random.Generator:
    """Deterministic per (seed, case): different noise and driving for each case at the same seed."""
    return np.random.default_rng([seed, zlib.crc32(case.encode())])


def make_driver(kind: str, rng: np.random.Generator, style: str):
    """The driver object of a log: a human on RC sticks (optionally idle-heavy) or the autopilot."""
    if kind == "rc":
        return HumanDriver(rng, style)
    if kind == "idle":
        return HumanDriver(rng, style, idle_share=float(rng.uniform(0.75, 0.9)))
    if kind == "closed_loop":
        return Autopilot(rng)
    raise UsageError(f"unknown driver {kind!r}")


def logging_gaps(rng: np.random.Generator, dur_s: float) -> list:
    """Half the logs have 1-2 gaps of 15-60 s where nothing was logged (logging restarted), apart from
    each other and from the ends."""
    if rng.random() < 0.5:
        return []
    n = int(rng.integers(1, 3))
    starts = np.sort(rng.uniform(0.15, 0.85, n)) * dur_s
    if n == 2 and starts[1] - starts[0] < 120.0:
        starts = starts[:1]
    return [[round(float(g0), 1), round(float(rng.uniform(15.0, 60.0)), 1)] for g0 in starts]


def run_log(v: Vessel, plan: LogPlan, path: Path) -> dict:
    """Simulate one outing, write its CSV; return what the truth says about this log."""
    rng = plan.rng
    drv = make_driver(plan.driver, rng, plan.style)
    first = int(round(WARMUP_S / DT_S))
    n_steps = int(round((WARMUP_S + plan.duration_s) / TICK_S)) * int(round(TICK_S / DT_S)) + 1
    sensors = make_sensors(rng, v, plan.fx, first, n_steps)
    x0 = (float(rng.uniform(-50, 50)), float(rng.uniform(-50, 50)), float(rng.uniform(-np.pi, np.pi)), 0.0, 0.0, 0.0)
    run = simulate(v, plan.fx, drv, sensors, rng, plan.duration_s, x0)
    t_boot = round(float(rng.uniform(30.0, 400.0)), 2)
    gaps = logging_gaps(rng, plan.duration_s)
    write_atomic(path, csv_text(recording_streams(run, sensors, plan.fx, rng, t_boot, gaps)))
    k = logged_steps(run)
    spd = np.hypot(run.x[k, 3], run.x[k, 4])
    first_tick = first // run.steps_per_tick
    neutral = np.all(run.cmd_us[first_tick:] == NEUTRAL_US, axis=1).mean()
    info = {"file": path.name, "driver": plan.driver, "duration_s": plan.duration_s, "t_first_s": t_boot,
            "logging_gaps_s": gaps, "noise": sensors.noise_info, "start_state": {
                "north_m": r3(x0[0]), "east_m": r3(x0[1]), "psi_deg": r3(math.degrees(x0[2]))},
            "origin_lat_lon_deg": [ORIGIN_LAT_DEG, ORIGIN_LON_DEG], "share_at_neutral_pwm": r3(neutral),
            "speed_max_m_s": r3(spd.max()), "speed_mean_m_s": r3(spd.mean()),
            "yaw_rate_max_rad_s": r3(np.abs(run.x[k, 5]).max())}
    if plan.fx.heading_offset_deg:
        info["heading_offset_deg"] = plan.fx.heading_offset_deg
    if sensors.fault_info:
        info["faults"] = sensors.fault_info
    if isinstance(drv, Autopilot):
        info["autopilot_gains"] = drv.gains
        info["waypoints_ne_m"] = [[r3(a), r3(b)] for a, b in drv.wps]
    if plan.fx.wind is not None:
        info["wind_realised"] = {"mean_speed_m_s": r3(run.wind_speed[k].mean()),
                                 "mean_from_deg": r3(np.degrees(np.angle(np.exp(1j * np.radians(run.wind_from_deg[k])).mean())) % 360)}
    info["_run"] = run
    return info


def generate(v: Vessel, case: str, seed: int, out: Path | None, out_dir: Path | None, truth_path: Path | None,
             driver_override: str | None, duration_override: float | None) -> dict:
    """Build the case's effects, run its log(s), write CSV(s) and the truth JSON."""
    if case not in CASES:
        raise UsageError(f"unknown case {case!r} (see --list)")
    spec = CASES[case]
    rng = case_rng(case, seed)
    fx, truth = spec.build(rng, v)
    dur = duration_override or spec.duration_s
    multi = spec.driver == "multilog"
    if driver_override and multi:
        raise UsageError("--driver does not apply to multi-log cases")
    if multi:
        n = int(rng.integers(spec.n_logs[0], spec.n_logs[1] + 1))
        drivers = list(rng.permutation(["rc", "closed_loop", "idle", "rc"]))[:n]
        if "idle" not in drivers:
            drivers[-1] = "idle"
        offsets = heading_offsets(rng, n) if case in MULTILOG_OFFSETS else [0.0] * n
        base = out_dir if out_dir is not None else (out.parent if out else None)
        stem = out.stem if out else f"{case}_s{seed}"
        if base is None:
            raise UsageError("a multi-log case needs --out-dir or --out")
        paths = [base / f"{stem}_log{i + 1}.csv" for i in range(n)]
        winds = [wind_spec(rng) for _ in range(n)] if case in MULTILOG_WINDS else [None] * n
        plans = []
        for i in range(n):
            f_i = Effects(**{k: getattr(fx, k) for k in vars(fx)})
            f_i.heading_offset_deg = offsets[i]
            if winds[i] is not None:
                f_i.wind = winds[i]
            d_i = dur * (2.0 if drivers[i] == "idle" else 1.0) * float(rng.uniform(0.85, 1.15))
            plans.append(LogPlan(drivers[i], round(d_i, 1), f_i, np.random.default_rng(rng.integers(2 ** 63))))
        if case in MULTILOG_OFFSETS:
            by_log = {p.name: o for p, o in zip(paths, offsets)}
            truth.append(effect("compass_offset_per_log", "each outing's heading = true heading + its own constant "
                                "offset (compass calibrated afresh or disturbed by that day's load); the boat is nominal",
                                {"offset_deg_by_log": by_log}, "heading_bias_per_log",
                                {"offset_deg_by_log": by_log, "mean_offset_deg": r3(np.mean(offsets)),
                                 "offset_minus_mean_deg_by_log": {k: r3(o - np.mean(offsets)) for k, o in by_log.items()}},
                                ["heading_bias (the common mean)"],
                                notes="a diagnosis may report a common heading_bias (the mean) plus per-log deviations"))
        if case in MULTILOG_WINDS:
            by_log = {p.name: w for p, w in zip(paths, winds)}
            entry = wind_effect(winds[0])
            truth.append(effect(
                "wind_per_outing", "each outing under its own wind: " + entry["physical_form"],
                {"wind_by_log": by_log}, "wind_per_log",
                {"by_log": {k: {"speed_m_s": w["speed"], "dir_from_deg": w["from_deg"]} for k, w in by_log.items()}},
                ["wind (one mean wind for every log)", "wind_shape (one mean wind for every log)"],
                notes="the library's cos/sin coefficient shape differs: each log's fitted speed may be off by tens "
                      "of %, its direction should be within ~20°"))
    else:
        if out is None:
            if out_dir is None:
                raise UsageError("--out (or --out-dir) is required")
            out = out_dir / f"{case}_s{seed}.csv"
        paths = [out]
        plans = [LogPlan(driver_override or spec.driver, dur, fx, np.random.default_rng(rng.integers(2 ** 63)),
                         spec.style)]
    logs = [run_log(v, p, path) for p, path in zip(plans, paths)]
    for tr in truth:
        finalize_expected(tr, logs[0]["_run"], plans[0].fx, v)
    for lg in logs:
        del lg["_run"]
    truth_doc = {"case": case, "seed": seed, "description": spec.description, "logs": [p.name for p in paths],
                 "effects": truth, "driver": "multilog" if multi else plans[0].driver,
                 "duration_s": round(sum(p.duration_s for p in plans), 1), "log_details": logs,
                 "conventions": "NED, ψ from north to east, body FRD; current towards dir, wind from dir (deg cw from "
                                "north); PWM neutral 1500 µs, forward = higher",
                 "generator": "scripts/world_sim.py (independent of the twin package)",
                 "notes": "null world = the params' vessel physics exactly (M, C_RB, C_A, D, T200 map, positions, "
                          "antenna); everything listed in effects is added by this world"}
    if truth_path is None:
        truth_path = paths[0].parent / f"{paths[0].stem if not multi else stem}.truth.json"
    write_atomic(truth_path, json.dumps(truth_doc, indent=2, ensure_ascii=False) + "\n")
    return truth_doc


# ---------------------------------------------------------------- self-test

def reference_nu(v: Vessel, cmds: np.ndarray, duration_s: float, x0: tuple) -> np.ndarray:
    """An independent integration of the null world: M ν̇ = τ − C(ν)ν − D(ν)ν with full matrices and
    numpy's solver, DOP853 at tight tolerance tick by tick (thrust constant over each 0.1 s tick)."""
    from scipy.integrate import solve_ivp

    def cmat(M: np.ndarray, nu: np.ndarray) -> np.ndarray:
        u, vv, r = nu
        a = M[1, 1] * vv + 0.5 * (M[1, 2] + M[2, 1]) * r
        b = M[0, 0] * u
        return np.array([[0, 0, -a], [0, 0, b], [a, -b, 0]])

    d = v.damping

    def dmat(nu: np.ndarray) -> np.ndarray:
        u, vv, r = np.abs(nu)
        return -np.array([[d["Xu"] + d["Xuu"] * u, 0, 0],
                          [0, d["Yv"] + d["Yvv"] * vv + d["Yrv"] * r + d["Yuv"] * u, d["Yr"] + d["Yvr"] * vv + d["Yrr"] * r],
                          [0, d["Nv"] + d["Nvv"] * vv + d["Nrv"] * r, d["Nr"] + d["Nvr"] * vv + d["Nrr"] * r + d["Nur"] * u]])

    chain = ThrusterChain(v, Effects(), 1, TICK_S)
    B = np.array([[1, 1], [0, 0], [-v.left_xy_m[1], -v.right_xy_m[1]]])
    first_tick = int(round(WARMUP_S / TICK_S))
    x = np.array(x0, float)
    out = [x[3:].copy()]
    for i in range(len(cmds)):
        pl, pr = cmds[i] if i >= first_tick else (NEUTRAL_US, NEUTRAL_US)
        tau = B @ np.array([v.gain_left * chain.static_n(0, pl), v.gain_right * chain.static_n(1, pr)])

        def f(_t, y):
            nu = y[3:]
            acc = np.linalg.solve(v.M, tau - cmat(v.M_RB, nu) @ nu - cmat(v.M_A, nu) @ nu - dmat(nu) @ nu)
            c, s = math.cos(y[2]), math.sin(y[2])
            return [c * nu[0] - s * nu[1], s * nu[0] + c * nu[1], nu[2], *acc]

        x = solve_ivp(f, (0, TICK_S), x, method="DOP853", rtol=1e-11, atol=1e-12).y[:, -1]
        out.append(x[3:].copy())
    return np.array(out)


def selftest(v: Vessel) -> int:
    """A null RC run of 120 s: this world's RK4 at 0.01 s and 0.005 s against the independent reference."""
    if v.lag_s or v.delay_s or v.current_speed_m_s:
        print("selftest: params with lag, delay or current: the reference models none; comparing anyway")
    rng = np.random.default_rng(12345)
    dur = 120.0
    first = int(round(WARMUP_S / DT_S))
    x0 = (0.0, 0.0, 0.3, 0.0, 0.0, 0.0)
    n_steps = int(round((WARMUP_S + dur) / TICK_S)) * 10 + 1
    sens = make_sensors(np.random.default_rng(1), v, Effects(), first, n_steps)
    run = simulate(v, Effects(), HumanDriver(rng, "spins"), sens, rng, dur, x0)
    cmds = run.cmd_us
    ref = reference_nu(v, cmds, dur, x0)
    rows, worst = [], 0.0
    for dt in (0.01, 0.005):
        first_k = int(round(WARMUP_S / dt))
        sens = make_sensors(np.random.default_rng(1), v, Effects(), first_k, int(round((WARMUP_S + dur) / dt)) + 1)
        r = simulate(v, Effects(), ArrayDriver(cmds[first // 10:]), sens, rng, dur, x0, dt_s=dt)
        nu = r.x[::r.steps_per_tick, 3:]
        err = np.abs(nu - ref).max(axis=0)
        worst = max(worst, float(err.max()))
        rows.append((dt, err))
    spd = np.hypot(ref[:, 0], ref[:, 1])
    print(f"selftest: null RC run {dur:.0f} s (max speed {spd.max():.2f} m/s, max |r| {np.abs(ref[:, 2]).max():.2f} rad/s)"
          f" vs independent DOP853 (rtol 1e-11) of M ν̇ = τ − C(ν)ν − D(ν)ν")
    for dt, err in rows:
        print(f"  RK4 dt = {dt:.3f} s: max |Δu| {err[0]:.2e} m/s, |Δv| {err[1]:.2e} m/s, |Δr| {err[2]:.2e} rad/s")
    ok = worst < 1e-5
    print(f"selftest: {'PASS' if ok else 'FAIL'} (tolerance 1e-5)")
    return 0 if ok else 1


# ---------------------------------------------------------------- command line

class Parser(argparse.ArgumentParser):
    """argparse with a one-line error and exit code 2."""

    def error(self, message: str) -> None:
        print(f"error: {message}", file=sys.stderr)
        sys.exit(2)


def main(argv: list[str] | None = None) -> int:
    """Command line; every expected failure is one line on stderr and exit 2."""
    ap = Parser(description="Independent 3-DOF world: sensor recordings + truth for named cases.")
    ap.add_argument("--params", type=Path, help="output of `twin params --vessel NAME --json`")
    ap.add_argument("--case", help="case name (see --list)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, help="recording CSV (single-log cases; stem for multi-log)")
    ap.add_argument("--out-dir", type=Path, help="folder for multi-log recordings")
    ap.add_argument("--truth", type=Path, help="truth JSON (default: beside the recording)")
    ap.add_argument("--driver", choices=["rc", "idle", "closed_loop"], help="override the case's driver")
    ap.add_argument("--duration-s", type=float, help="override the case's duration (per log)")
    ap.add_argument("--list", action="store_true", help="list the cases")
    ap.add_argument("--selftest", action="store_true", help="null run against an independent integration")
    a = ap.parse_args(argv)
    try:
        if a.list:
            w = max(map(len, CASES))
            for name, spec in CASES.items():
                print(f"{name:<{w}}  [{spec.driver}, {spec.duration_s / 60:.0f} min{'/log' if spec.driver == 'multilog' else ''}]"
                      f"  {spec.description}")
            return 0
        if a.params is None:
            raise UsageError("--params is required")
        v = load_vessel(a.params)
        if a.selftest:
            return selftest(v)
        if a.case is None:
            raise UsageError("--case is required (see --list)")
        if a.seed < 0:
            raise UsageError("--seed must be >= 0")
        if a.duration_s is not None and not (10.0 <= a.duration_s <= 6 * 3600):
            raise UsageError("--duration-s must be between 10 and 21600")
        doc = generate(v, a.case, a.seed, a.out, a.out_dir, a.truth, a.driver, a.duration_s)
        print(f"{a.case} seed {a.seed}: {', '.join(doc['logs'])} ({doc['duration_s']:.0f} s)")
        return 0
    except UsageError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except OSError as e:
        print(f"error: {e.strerror or e}: {e.filename or ''}".rstrip(": "), file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
