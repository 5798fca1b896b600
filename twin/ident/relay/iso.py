"""Identification by self-oscillations, IS-O [Relay-ISO §III, Figs. 4-5, Table I].

A relay with hysteresis (output ±C, switching at e = ±xa) closes the loop on
an astatic signal: the heading error e = ψ_ref − ψ for yaw (Fig. 4), the
integral of the surge speed for surge (Fig. 5). The steady self-oscillation's
amplitude Xm, frequency ω, bias x0 and high/low durations TH, TL give, by the
describing function of the relay, the parameters of the uncoupled model of
eq. 6, α ν̇ + β(ν)ν = Δ + τ, for the two drag forms of eq. 7:

    α     = 2C/(π ω² Xm) · [√(1 − ((xa − x0)/Xm)²) + √(1 − ((xa + x0)/Xm)²)]   (both models)
    β_ν   = 4 C xa / (π ω Xm²)          constant drag ("linear model")
    β_νν  = 3 C xa / (2 ω² Xm³)         linear drag  ("nonlinear model", β = β_νν|ν|)
    Δ     = −C (TH − TL)/(TH + TL)

Table I prints Δ = C(TH − TL)/(TH + TL); with TH the time at +C and eq. 6's
signs, the disturbance that the mean relay output balances is its negative.

The relay here is sampled at the autopilot rate, so it switches at the first
sample beyond ±xa; Table I is applied with the switching level actually seen,
xa_eff (mean |e| at the switching samples), which removes the phase lag of the
sampling (with the set xa, α of the Yellowfish's fast yaw comes out ~10 % high).

The twin has linear *and* quadratic damping, so neither one-term drag model is
exact: the describing-function equivalents at the measured speed amplitude
ν_m = ω Xm are β_ν ≈ d₁ + 8/(3π)·d₂·ν_m and β_νν ≈ d₂ + 3π/(8 ν_m)·d₁, where
d₁ = −Nr (−Xu), d₂ = −Nrr (−Xuu).

A propeller-and-rudder ship (the Esso Osaka twin) is identified in yaw with the rudder as the
relay, as [Relay-ISO §V-A] does its tanker model (Table II: "IS-O results for the ship model yaw
DOF using the rudder", at several propeller speeds and rudder angles): the propeller turns at a
constant n, the ship starts from its straight-running speed u₀(n) (δ = 0, no wind), and the
relay puts the rudder at ±δ_c, switching when the heading error passes ±xa. The relay output C
of Table I is the yaw moment that rudder angle gives: the paper's allocation N = L₁ k_F δ τ₁
(eq. 4), here the MMG rudder moment N_R(δ_c) at the operating point (u₀, 0, 0) and n, so α and
β come out in kg·m² and N·m·s (the paper reports them divided by its unknown k_F). Surge and
sway make no sense for it here: the ship has no sway actuator, and its one propeller's thrust
depends on the advance speed and is not symmetric astern (K_T(J)), so a relay in rps is no
relay in force. The twin's own uncoupled yaw values to compare with are M₃₃ (I_z about midship
with the added J_z) and −∂N/∂r at the operating point (hull, propeller and rudder), the
derivative the relay's small oscillations see; the sway coupling (Y_R, N'_v) that a ship
cannot avoid makes IS-O's α and β effective values, not these.
"""
from __future__ import annotations

import io
import math
from dataclasses import asdict, dataclass, replace

import numpy as np

from ...errors import TwinError
from ...physics.hydrodynamics import Terms, mmg_forces
from ...physics.kinematics import wrap_angle
from ...progress import Progress, steps
from ...analytic import straight_speed
from ...physics.thrusters import allocation_matrix

DOFS = ("yaw", "surge", "sway")
CONTROL_DT_S = 0.02  # autopilot rate of the relay, s
SHIP_CONTROL_DT_S = 0.1  # a ship's relay at the Esso tests' 10 Hz, s
SHIP_XA_RAD = math.radians(1.0)
SHIP_DURATION_S = 900.0  # its yaw period is tens of seconds: enough for ~10 periods after the transient
SHIP_RUDDER_DEG = (10.0, 15.0, 20.0, 25.0, 30.0, 35.0)  # [Relay-ISO Table II]'s range of rudder angles
SHIP_RPS = (8.0, 10.0)  # the Esso turning tests' propeller speeds
DEFAULT_XA = {"yaw": math.radians(1.0), "surge": 0.25}  # rad, m: ωα/β ≈ 1 on the Yellowfish (see module doc)
DEFAULT_DURATION_S = {"yaw": 30.0, "surge": 150.0}
DEFAULT_FRACTIONS = (0.2, 0.33, 0.46, 0.6, 0.73, 0.86, 1.0)  # of the largest relay output the thrusters give
UNITS = {"yaw": {"x": "rad", "C": "N·m", "alpha": "kg·m²", "beta_lin": "N·m·s/rad",
                 "beta_quad": "N·m·s²/rad²"},
         "surge": {"x": "m", "C": "N", "alpha": "kg", "beta_lin": "N·s/m", "beta_quad": "N·s²/m²"}}


@dataclass(frozen=True)
class Oscillation:
    """The steady self-oscillation of the relay input e (Table I's measured quantities)."""

    amplitude_xm: float  # Xm (rad or m): half the mean peak-to-peak of e
    frequency_rad_s: float  # ω
    bias_x0: float  # x0: centre of the oscillation
    high_s: float  # TH: mean time at +C per period
    low_s: float  # TL: mean time at −C per period
    xa_eff: float  # switching level actually seen by the sampled relay
    periods: int


@dataclass(frozen=True)
class TableI:
    """[Relay-ISO Table I] applied to one oscillation."""

    alpha: float
    beta_lin: float  # β_ν, constant drag (linear model)
    beta_quad: float  # β_νν, linear drag (nonlinear model)
    disturbance: float  # Δ (N or N·m)


def table_i(relay_c: float, xa: float, osc: Oscillation) -> TableI:
    """[Relay-ISO Table I] for relay output C and hysteresis xa (module docstring for the sign of Δ)."""
    xm, w, x0 = osc.amplitude_xm, osc.frequency_rad_s, osc.bias_x0
    if abs(xa) + abs(x0) >= xm:
        raise TwinError(f"oscillation amplitude {xm:.4g} does not exceed the hysteresis {xa:.4g} plus bias "
                        f"{x0:.4g}: Table I does not apply (smaller --xa)")
    root = math.sqrt(1 - ((xa - x0) / xm) ** 2) + math.sqrt(1 - ((xa + x0) / xm) ** 2)
    return TableI(
        alpha=2 * relay_c / (math.pi * w ** 2 * xm) * root,
        beta_lin=4 * relay_c * xa / (math.pi * w * xm ** 2),
        beta_quad=3 * relay_c * xa / (2 * w ** 2 * xm ** 3),
        disturbance=-relay_c * (osc.high_s - osc.low_s) / (osc.high_s + osc.low_s),
    )


def measure_oscillation(t_s: np.ndarray, e: np.ndarray, relay_out: np.ndarray, settle_s: float) -> Oscillation:
    """Xm, ω, x0, TH, TL from whole periods (rising switch to rising switch) after `settle_s`.

    Peaks are taken per period and averaged, so one sampled peak does not set Xm.
    """
    t_s, e, relay_out = (np.asarray(a, float) for a in (t_s, e, relay_out))
    switch = np.flatnonzero(np.diff(np.sign(relay_out)) != 0) + 1
    switch = switch[t_s[switch] >= settle_s]
    rising = switch[relay_out[switch] > 0]
    if len(rising) < 4:
        raise TwinError(f"no steady self-oscillation: {max(len(rising) - 1, 0)} full periods after "
                        f"{settle_s:g} s (longer --duration or smaller --xa)")
    periods = len(rising) - 1
    highs, lows, tops, bottoms = [], [], [], []
    for a, b in zip(rising[:-1], rising[1:]):
        fall = switch[(switch > a) & (switch < b)][0]
        highs.append(t_s[fall] - t_s[a])
        lows.append(t_s[b] - t_s[fall])
        tops.append(e[a:b].max())
        bottoms.append(e[a:b].min())
    levels = e[switch[(switch >= rising[0]) & (switch <= rising[-1])]]
    top, bottom = float(np.mean(tops)), float(np.mean(bottoms))
    return Oscillation(
        amplitude_xm=(top - bottom) / 2,
        frequency_rad_s=2 * math.pi * periods / (t_s[rising[-1]] - t_s[rising[0]]),
        bias_x0=(top + bottom) / 2,
        high_s=float(np.mean(highs)),
        low_s=float(np.mean(lows)),
        xa_eff=float((levels[levels > 0].mean() - levels[levels < 0].mean()) / 2),
        periods=periods,
    )


class RelayWithHysteresis:
    """The nonlinear element of Figs. 4-5: +C once e ≥ xa, −C once e ≤ −xa, else hold."""

    def __init__(self, relay_c: float, xa: float):
        self.relay_c, self.xa = relay_c, xa
        self.level = relay_c  # start high: the first half-swing kicks the oscillation off

    def __call__(self, e: float) -> float:
        if e >= self.xa:
            self.level = self.relay_c
        elif e <= -self.xa:
            self.level = -self.relay_c
        return self.level


class RelayExperiment:
    """Twin controller for the IS-O experiment of one DOF; returns thrusts in N and logs (t, e, C).

    yaw: e = ψ_ref − ψ (wrapped), relay torque N split as T_L = −T_R (Fig. 4).
    surge: e = x_ref − ∫u dt (trapezoidal integrator, Fig. 5), relay force X split equally.
    """

    output = "thrust"

    def __init__(self, dof: str, relay_c: float, xa: float, thruster_y_m: tuple[float, float],
                 gains=(1.0, 1.0)):
        """gains: the thrusters' (left, right): a thrust command is the map's, which the gains scale,
        so each is divided by its gain and the hull feels the relay's C itself."""
        self.dof = dof
        self.gains = np.asarray(gains, float)
        self.relay = RelayWithHysteresis(relay_c, xa)
        self.allocation_inv = np.linalg.inv(allocation_matrix(thruster_y_m)[[0, 2]])
        self.heading_ref_rad: float | None = None
        self.distance_m, self.last_t_s, self.last_u_m_s = 0.0, 0.0, 0.0
        self.log: list[tuple[float, float, float]] = []

    def error(self, t_s: float, eta: np.ndarray, nu: np.ndarray) -> float:
        if self.dof == "yaw":
            if self.heading_ref_rad is None:
                self.heading_ref_rad = float(eta[2])
            return float(wrap_angle(self.heading_ref_rad - eta[2]))
        self.distance_m += 0.5 * (t_s - self.last_t_s) * (nu[0] + self.last_u_m_s)
        self.last_t_s, self.last_u_m_s = t_s, float(nu[0])
        return -self.distance_m

    def __call__(self, t_s: float, eta: np.ndarray, nu: np.ndarray) -> tuple[float, float]:
        e = self.error(t_s, eta, nu)
        level = self.relay(e)
        self.log.append((t_s, e, level))
        force_n, moment_nm = (level, 0.0) if self.dof == "surge" else (0.0, level)
        thrust_n = self.allocation_inv @ np.array([force_n, moment_nm]) / self.gains
        return float(thrust_n[0]), float(thrust_n[1])


def force_range(thrusters) -> tuple[float, float]:
    """(lo, hi) N one thruster puts on the hull across its commands: the command range times the
    weaker thruster's gain (a command in N is the thrust map's, which the gains scale)."""
    lo, hi = thrusters.command_range()
    gain = float(min(thrusters.gains()))
    return lo * gain, hi * gain


def relay_limit(thruster_y_m: tuple[float, float], bounds_n: tuple[float, float], dof: str) -> float:
    """Largest relay output both signs of which the thrusters deliver (N or N·m)."""
    inv = np.linalg.inv(allocation_matrix(thruster_y_m)[[0, 2]])
    column = inv[:, 0 if dof == "surge" else 1]  # thrusts per unit force or moment
    t_min, t_max = bounds_n
    return float(min(min(t_max / abs(c), -t_min / abs(c)) for c in column if c != 0))


def check_dof(vessel_name: str, dof: str, kind: str = "t200") -> None:
    if dof not in DOFS:
        raise TwinError(f"unknown DOF '{dof}' (yaw, surge or sway)")
    if kind == "propeller_rudder" and dof != "yaw":
        why = ("it has no sway actuator (one propeller along body x, one rudder)" if dof == "sway" else
               "its one propeller's thrust depends on the advance speed and is not symmetric astern (K_T(J)), "
               "so a relay in rps is no relay in force")
        raise TwinError(f"{dof}: vessel '{vessel_name}' is a propeller-and-rudder ship: {why}; identify yaw "
                        "(the rudder as the relay)")
    if dof == "sway":  # the twin's thrusters only ever push along body x (allocation row Y = 0)
        raise TwinError(f"sway: vessel '{vessel_name}' has no sway actuator (both thrusters push along "
                        "body x, allocation row Y = 0), so no relay can drive v; identify yaw or surge")


@dataclass(frozen=True)
class IsoRow:
    """One IS-O experiment: relay output, the oscillation and Table I (a ship's rudder angle and
    propeller speed too)."""

    relay_c: float
    xa_set: float
    oscillation: Oscillation
    estimate: TableI
    alpha_at_set_xa: float  # Table I with the set xa instead of xa_eff, to show the sampling effect
    speed_amplitude: float  # ν_m = ω Xm
    beta_lin_equivalent: float  # the twin's two-term drag seen by the relay (module docstring)
    beta_quad_equivalent: float
    rudder_deg: float | None = None  # a ship's relay in rudder angle: ±δ_c
    rps: float | None = None  # its propeller speed
    speed_m_s: float | None = None  # its straight-running speed u₀ at that propeller speed


@dataclass(frozen=True)
class TwinUncoupled:
    """The twin's own uncoupled parameters of the DOF (Fossen signs flipped to positive drags)."""

    alpha: float  # M[0,0] or M[2,2]
    drag_lin: float  # −Xu or −Nr
    drag_quad: float  # −Xuu or −Nrr


def twin_uncoupled(compiled, dof: str) -> TwinUncoupled:
    d, M = compiled.vessel.damping, compiled.hydro().M
    if dof == "yaw":
        return TwinUncoupled(float(M[2, 2]), -d.Nr, -d.Nrr)
    return TwinUncoupled(float(M[0, 0]), -d.Xu, -d.Xuu)


def iso_row(relay_c: float, xa: float, log: np.ndarray, settle_s: float, twin: TwinUncoupled, **ship) -> IsoRow:
    osc = measure_oscillation(log[:, 0], log[:, 1], log[:, 2], settle_s)
    speed = osc.frequency_rad_s * osc.amplitude_xm
    return IsoRow(
        relay_c=relay_c, xa_set=xa, oscillation=osc, estimate=table_i(relay_c, osc.xa_eff, osc),
        alpha_at_set_xa=table_i(relay_c, xa, osc).alpha, speed_amplitude=speed,
        beta_lin_equivalent=twin.drag_lin + 8 / (3 * math.pi) * twin.drag_quad * speed,
        beta_quad_equivalent=twin.drag_quad + 3 * math.pi / (8 * speed) * twin.drag_lin, **ship,
    )


# ---------------------------------------------------------------- a propeller-and-rudder ship

def is_ship(compiled) -> bool:
    return compiled.vessel.thrusters.kind == "propeller_rudder"


def rudder_moment(compiled, speed_m_s: float, n_rps: float, rudder_rad: float) -> float:
    """N_R (N·m): the MMG rudder moment at the straight-running state (u₀, 0, 0): the relay's C and the
    I-PD's allocation ([Relay-ISO eq. 4]'s N = L₁ k_F δ τ₁)."""
    hydro = compiled.hydro(Terms().only("rudder"))
    return float(mmg_forces(hydro, np.array([speed_m_s, 0.0, 0.0]), (n_rps, rudder_rad))[2])


def ship_twin_uncoupled(compiled, n_rps: float) -> TwinUncoupled:
    """M₃₃ and −∂N/∂r at (u₀(n), 0, 0) with the rudder amidships (hull, propeller, rudder)."""
    hydro, u0, h = compiled.hydro(), straight_speed(compiled, n_rps), 1e-6
    n_at = [mmg_forces(hydro, np.array([u0, 0.0, r]), (n_rps, 0.0))[2] for r in (-h, h)]
    return TwinUncoupled(float(hydro.M[2, 2]), float(-(n_at[1] - n_at[0]) / (2 * h)), 0.0)


class RudderRelayExperiment:
    """[Relay-ISO Fig. 4] with the rudder: e = ψ_ref − ψ (wrapped), rudder ±δ_c (the relay), propeller at n;
    returns (n rps, δ rad) and logs (t, e, C·sign) with C the rudder moment of ±δ_c (N·m)."""

    output = "propeller_rudder"

    def __init__(self, n_rps: float, rudder_rad: float, moment_nm: float, xa: float):
        self.n_rps, self.rudder_rad, self.moment_nm = n_rps, rudder_rad, moment_nm
        self.relay = RelayWithHysteresis(1.0, xa)
        self.heading_ref_rad: float | None = None
        self.log: list[tuple[float, float, float]] = []

    def __call__(self, t_s: float, eta: np.ndarray, nu: np.ndarray) -> tuple[float, float]:
        if self.heading_ref_rad is None:
            self.heading_ref_rad = float(eta[2])
        e = float(wrap_angle(self.heading_ref_rad - eta[2]))
        sign = self.relay(e)
        self.log.append((t_s, e, sign * self.moment_nm))
        return self.n_rps, sign * self.rudder_rad


def run_ship_experiment(compiled, n_rps: float, rudder_deg: float, xa: float, duration_s: float,
                        twin: TwinUncoupled | None = None) -> IsoRow:
    """One rudder-relay experiment from straight running at n (module docstring); the first third is transient."""
    # late: twin.engine.sim (mujoco) is 0.13 s more at every `twin --help`, which loads this module
    from ...engine.sim import simulate

    u0 = straight_speed(compiled, n_rps)
    delta = math.radians(rudder_deg)
    moment = rudder_moment(compiled, u0, n_rps, delta)
    calm = calm_water(compiled)
    controller = RudderRelayExperiment(n_rps, delta, moment, xa)
    simulate(calm, controller, duration_s, control_dt_s=SHIP_CONTROL_DT_S, sample_dt_s=SHIP_CONTROL_DT_S,
             nu0=(u0, 0.0, 0.0))
    return iso_row(moment, xa, np.array(controller.log), duration_s / 3, twin or ship_twin_uncoupled(compiled, n_rps),
                   rudder_deg=rudder_deg, rps=n_rps, speed_m_s=u0)


def calm_water(compiled):
    """The compiled vessel in calm water (IS-O in [Relay-ISO] is run without disturbances)."""
    # late: twin.engine.mjcf (mujoco) is 0.17 s more at every `twin --help`, which loads this module
    from ...engine.mjcf import CompiledVessel

    return CompiledVessel(replace(compiled.vessel, environment=type(compiled.vessel.environment)()), compiled.model,
                          compiled.geometry)


def ship_sweep(compiled, rudder_deg: list[float] | None = None, rps: list[float] | None = None,
               xa: float | None = None, duration_s: float | None = None,
               progress: Progress | None = None) -> "IsoSweep":
    """Table II for a ship's yaw: the rudder relay at every propeller speed and rudder angle
    (`progress` hears each experiment, k of n, before it runs)."""
    v = compiled.vessel
    limit = math.degrees(v.thrusters.channel_bounds()[1][1])
    rudder_deg = list(rudder_deg or SHIP_RUDDER_DEG)
    bad = [d for d in rudder_deg if not 0 < d <= limit + 1e-9]
    if bad:
        raise TwinError(f"rudder relay amplitude {bad[0]:g}° outside (0, {limit:g}°] of the rudder")
    rps = list(rps or SHIP_RPS)
    (_, n_max), _ = v.thrusters.channel_bounds()
    if any(not 0 < n <= n_max + 1e-9 for n in rps):
        raise TwinError(f"propeller speed outside (0, {n_max:g}] rps")
    xa = SHIP_XA_RAD if xa is None else xa
    if not xa > 0:
        raise TwinError("hysteresis xa must be positive")
    duration_s = duration_s or SHIP_DURATION_S
    twins = {n: ship_twin_uncoupled(compiled, n) for n in rps}
    say, runs = steps(progress), [(n, d) for n in rps for d in rudder_deg]
    rows = []
    for k, (n, d) in enumerate(runs):
        say(f"IS-O yaw: rudder relay ±{d:g}° at {n:g} rps", k, len(runs))
        rows.append(run_ship_experiment(compiled, n, d, xa, duration_s, twins[n]))
    say("IS-O yaw: done", len(runs), len(runs))
    return IsoSweep(v.name, "yaw", rows, twins[max(rps)])


def run_experiment(compiled, dof: str, relay_c: float, xa: float, duration_s: float,
                   twin: TwinUncoupled | None = None) -> IsoRow:
    """One relay experiment in the twin ([Relay-ISO Fig. 4] or 5), from rest; the first third is transient."""
    # late: twin.engine.sim (mujoco) is 0.13 s more at every `twin --help`, which loads this module
    from ...engine.sim import simulate

    controller = RelayExperiment(dof, relay_c, xa, compiled.geometry.thruster_y_m, compiled.vessel.thrusters.gains())
    simulate(compiled, controller, duration_s, control_dt_s=CONTROL_DT_S, sample_dt_s=CONTROL_DT_S)
    return iso_row(relay_c, xa, np.array(controller.log), duration_s / 3, twin or twin_uncoupled(compiled, dof))


@dataclass(frozen=True)
class Spread:
    mean: float
    std: float  # sample standard deviation (ddof = 1)
    cv_percent: float  # σ/mean·100 %, the last row of Table II


def spread(values) -> Spread:
    x = np.asarray(values, float)
    std = float(x.std(ddof=1)) if len(x) > 1 else 0.0
    return Spread(float(x.mean()), std, 100 * std / abs(float(x.mean())))


@dataclass(frozen=True)
class IsoSweep:
    """Table II for one DOF: IS-O over several relay outputs, with the twin's values beside it."""

    vessel: str
    dof: str
    rows: list[IsoRow]
    twin: TwinUncoupled

    def spreads(self) -> dict[str, Spread]:
        est = [r.estimate for r in self.rows]
        return {"alpha": spread([e.alpha for e in est]), "beta_lin": spread([e.beta_lin for e in est]),
                "beta_quad": spread([e.beta_quad for e in est])}

    def alpha_error_percent(self) -> float:
        return 100 * (self.spreads()["alpha"].mean / self.twin.alpha - 1)

    def better_drag_model(self) -> str:
        """[Relay-ISO §V-A]: the drag form whose estimates scatter less over the experiments fits better."""
        s = self.spreads()
        return "the linear model (damping β_ν·ν)" if s["beta_lin"].cv_percent <= s["beta_quad"].cv_percent \
            else "the nonlinear model (damping β_νν·|ν|·ν)"

    def to_dict(self) -> dict:
        return {"vessel": self.vessel, "dof": self.dof, "units": UNITS[self.dof],
                "twin_uncoupled": asdict(self.twin), "rows": [asdict(r) for r in self.rows],
                "spread": {k: asdict(v) for k, v in self.spreads().items()},
                "alpha_error_percent": self.alpha_error_percent(), "better_drag_model": self.better_drag_model()}


def sweep(compiled, dof: str, amplitudes: list[float] | None = None, xa: float | None = None,
          duration_s: float | None = None, progress: Progress | None = None) -> IsoSweep:
    """IS-O at several relay outputs C (default: fractions of the largest the thrusters give). A
    propeller-and-rudder ship: `ship_sweep` (amplitudes are rudder angles in degrees). `progress`
    hears each relay experiment, k of n, before it runs."""
    check_dof(compiled.vessel.name, dof, compiled.vessel.thrusters.kind)
    if is_ship(compiled):
        return ship_sweep(compiled, amplitudes, None, xa, duration_s, progress)
    y_m, bounds = compiled.geometry.thruster_y_m, force_range(compiled.vessel.thrusters)
    limit = relay_limit(y_m, bounds, dof)
    amplitudes = amplitudes or [math.floor(f * limit * 100) / 100 for f in DEFAULT_FRACTIONS]
    bad = [c for c in amplitudes if not 0 < c <= limit + 1e-9]
    if bad:
        raise TwinError(f"relay amplitude {bad[0]:g} {UNITS[dof]['C']} outside (0, {limit:.3g}] that the "
                        "thrusters deliver in both directions")
    xa = DEFAULT_XA[dof] if xa is None else xa
    if not xa > 0:
        raise TwinError("hysteresis xa must be positive")
    twin = twin_uncoupled(compiled, dof)
    duration_s = duration_s or DEFAULT_DURATION_S[dof]
    say, rows = steps(progress), []
    for k, c in enumerate(amplitudes):
        say(f"IS-O {dof}: relay ±{c:g} {UNITS[dof]['C']}", k, len(amplitudes))
        rows.append(run_experiment(compiled, dof, c, xa, duration_s, twin))
    say(f"IS-O {dof}: done", len(amplitudes), len(amplitudes))
    return IsoSweep(compiled.vessel.name, dof, rows, twin)


def linear_model(sweep_result: IsoSweep, rps: float | None = None) -> tuple[float, float]:
    """(α, β_ν): mean over the sweep of the constant-drag model, what the I-PD of eq. 11 is tuned with
    (a ship's: over the experiments at propeller speed `rps`, where given)."""
    rows = [r for r in sweep_result.rows if rps is None or r.rps == rps]
    if not rows:
        raise TwinError(f"no IS-O experiment at {rps:g} rps")
    return (float(np.mean([r.estimate.alpha for r in rows])), float(np.mean([r.estimate.beta_lin for r in rows])))


def relay_on_first_order_plant(alpha: float, beta_lin: float, relay_c: float, xa: float, *, beta_quad: float = 0.0,
                               disturbance: float = 0.0, duration_s: float = 60.0, dt_s: float = 0.002,
                               substeps: int = 4) -> np.ndarray:
    """Relay loop around α ν̇ + (β_ν + β_νν|ν|)ν = Δ + τ, x = ∫ν, e = −x (a check of Table I
    without the twin). RK4 substeps; the relay acts every dt_s. Returns rows (t, e, C)."""
    relay = RelayWithHysteresis(relay_c, xa)
    nu = x = 0.0
    h = dt_s / substeps
    log = []

    def accel(v: float, tau: float) -> float:
        return (tau + disturbance - (beta_lin + beta_quad * abs(v)) * v) / alpha

    for k in range(int(round(duration_s / dt_s))):
        level = relay(-x)
        log.append((k * dt_s, -x, level))
        for _ in range(substeps):
            k1 = accel(nu, level)
            k2 = accel(nu + h / 2 * k1, level)
            k3 = accel(nu + h / 2 * k2, level)
            k4 = accel(nu + h * k3, level)
            x += h * (nu + h / 6 * (k1 + k2 + k3))
            nu += h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return np.array(log)


def table_markdown(result: IsoSweep) -> str:
    """Table II layout for one DOF, with the CV row and the twin's values."""
    u = UNITS[result.dof]
    ship = any(r.rudder_deg is not None for r in result.rows)
    head = "| n [rps] | u₀ [m/s] | δ_c [°] " if ship else ""
    lines = [f"{head}| C [{u['C']}] | xa_eff [{u['x']}] | Xm [{u['x']}] | ω [rad/s] | x0 [{u['x']}] | ν_m | "
             f"α [{u['alpha']}] | β_ν [{u['beta_lin']}] | β_νν [{u['beta_quad']}] | Δ [{u['C']}] | "
             "β_ν twin eq. | β_νν twin eq. |", "|" + "---|" * (15 if ship else 12)]
    pad = "| | | " if ship else ""
    for r in result.rows:
        o, e = r.oscillation, r.estimate
        first = f"| {r.rps:g} | {r.speed_m_s:.3f} | {r.rudder_deg:g} " if ship else ""
        lines.append(f"{first}| {r.relay_c:.2f} | {o.xa_eff:.4f} | {o.amplitude_xm:.4f} | {o.frequency_rad_s:.3f} | "
                     f"{o.bias_x0:+.1e} | {r.speed_amplitude:.3f} | {e.alpha:.3f} | {e.beta_lin:.3f} | "
                     f"{e.beta_quad:.3f} | {e.disturbance:+.3f} | {r.beta_lin_equivalent:.3f} | "
                     f"{r.beta_quad_equivalent:.3f} |")
    s = result.spreads()
    lines.append(f"{pad}| **σ/mean** | | | | | | **{s['alpha'].cv_percent:.1f} %** | **{s['beta_lin'].cv_percent:.1f} %** "
                 f"| **{s['beta_quad'].cv_percent:.1f} %** | | | |")
    t = result.twin
    if ship:
        lines.append(f"{pad}| **twin** | | | | | | {t.alpha:.3f} (M₃₃) | {t.drag_lin:.3f} (−∂N/∂r at u₀) | "
                     f"{t.drag_quad:.3f} | 0 | | |")
    else:
        lines.append(f"| **twin** | | | | | | {t.alpha:.3f} | {t.drag_lin:.3f} (linear term only) | "
                     f"{t.drag_quad:.3f} (quadratic term only) | 0 | | |")
    return "\n".join(lines)


def sweep_png(result: IsoSweep) -> bytes:
    """α, β_ν, β_νν against the relay output, beside the twin's coefficients and their
    describing-function equivalents at each experiment's speed amplitude (a ship's: one line per
    propeller speed, the twin's −∂N/∂r at each speed's u₀)."""
    # late: matplotlib (0.3 s) only for the PNG; `twin --help` loads this module
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    u, twin = UNITS[result.dof], result.twin
    ship = any(r.rps is not None for r in result.rows)
    groups = {n: [r for r in result.rows if r.rps == n] for n in dict.fromkeys(r.rps for r in result.rows)}
    fig, axes = plt.subplots(1, 3, figsize=(14, 4))
    for k, (n, rows) in enumerate(groups.items()):
        c = [r.relay_c for r in rows]
        tag = f", {n:g} rps" if ship else ""
        first = k == 0
        panels = (
            ("α", u["alpha"], [r.estimate.alpha for r in rows], [twin.alpha] * len(rows),
             "twin M₃₃ (uncoupled)" if ship else "twin M (uncoupled)", None),
            ("β_ν (constant drag)", u["beta_lin"], [r.estimate.beta_lin for r in rows],
             [r.beta_lin_equivalent for r in rows] if ship else [twin.drag_lin] * len(rows),
             "twin −∂N/∂r at u₀" if ship else "twin linear term", None if ship else [r.beta_lin_equivalent for r in rows]),
            ("β_νν (linear drag)", u["beta_quad"], [r.estimate.beta_quad for r in rows], [twin.drag_quad] * len(rows),
             "twin quadratic term", [r.beta_quad_equivalent for r in rows]),
        )
        for ax, (name, unit, est, own, own_label, equivalent) in zip(axes, panels):
            ax.plot(c, est, "o-", color=f"C{k}", label=f"IS-O (Table I){tag}")
            ax.plot(c, own, "--", color="k" if not ship else f"C{k}", lw=1,
                    label=own_label + tag if (ship or first) else None)
            if equivalent is not None and (ship or first):
                ax.plot(c, equivalent, ":", color="k" if not ship else f"C{k}",
                        label="twin, describing-function equivalent" + tag)
    estimates = {"α": [r.estimate.alpha for r in result.rows], "β_ν (constant drag)": [r.estimate.beta_lin for r in
                 result.rows], "β_νν (linear drag)": [r.estimate.beta_quad for r in result.rows]}
    for ax, (name, est), unit in zip(axes, estimates.items(), (u["alpha"], u["beta_lin"], u["beta_quad"])):
        ax.set_title(f"{name}: CV {spread(est).cv_percent:.1f} %")
        ax.set_xlabel(f"relay output C [{u['C']}]" + (" (rudder moment at ±δ_c)" if ship else ""))
        ax.set_ylabel(f"{name} [{unit}]")
        ax.legend(fontsize=7)
    relay = " with the rudder as the relay" if ship else ""
    fig.suptitle(f"IS-O {result.vessel} {result.dof}{relay} [Relay-ISO Table I]: α {result.alpha_error_percent():+.1f} % "
                 "from the twin's")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return buf.getvalue()
