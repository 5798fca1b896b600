"""Linear (Airy) deep-water waves: spectra, seeded components, kinematics and the incident pressure.

A sea is a sum of regular components i with amplitude a_i, circular frequency ω_i, wave number
k_i = ω_i²/g (deep water), propagation direction β_i (rad, clockwise from north: the direction the
wave travels *to*) and phase ε_i. In the NED frame (z down) at a point (x, y, z) and time t

    θ_i = k_i (x cos β_i + y sin β_i) − ω_i t + ε_i
    ζ   = Σ a_i cos θ_i                                (elevation, up)
    p   = ρ g z + ρ g Σ a_i e^{−k_i (z + ζ)} cos θ_i   (incident pressure under the surface, z + ζ ≥ 0)
    u_h = Σ ω_i a_i e^{−k_i z} cos θ_i (cos β_i, sin β_i)  (horizontal particle velocity)
    w   = Σ ω_i a_i e^{−k_i z} sin θ_i                 (vertical particle velocity, up)

[Faltinsen-1990], [DNV-RP-C205] (its wave-theory section). The pressure's decay is counted from the
local surface, not from the mean level (Wheeler's stretching [Wheeler-1970], [DNV-RP-C205]): it is
zero on the surface under crests and troughs alike, and its gradient there (a regular wave)
ρ(g − ω²ζ), the water's own vertical acceleration. *Why:* decaying from the mean level, linear
theory leaves a pressure of order ρgka² on the surface in the troughs and none under the crests, a
mean lift of that order on a hull riding the waves, which draws a light hull's drift away from the
Stokes drift in long swell.

Spectra: JONSWAP with peak enhancement γ (3.3 by default) and Pierson-Moskowitz (γ = 1), in the
form of [DNV-RP-C205] (its wave-spectrum section; the Pierson-Moskowitz spectrum is γ = 1);
directional spreading D(θ) ∝ cos^n(θ − θ_mean) for |θ − θ_mean| < π/2 [DNV-RP-C205].
Directions of a `Sea` are given as where the waves come *from* (like the wind), degrees clockwise
from north.

Components of an irregular sea are drawn from one seed: frequencies at the centres of equal bins
in [ω_lo, ω_hi], each shifted by a uniform random fraction of its bin (so the record does not
repeat after 2π/Δω), amplitudes a_i = √(2 S(ω_i) Δω) scaled so that 4√(Σ a_i²/2) equals H_s
exactly, random phases, and for a short-crested sea one direction per frequency drawn from D(θ)
(each component keeps its whole energy: no phase-locked pairs, and the count stays that of the
frequencies).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..errors import TwinError

G = 9.81
BREAKING_STEEPNESS = 1.0 / 7.0  # H/λ of the steepest regular wave in deep water [Michell-1893]
N_COMPONENTS = 48  # components of an irregular sea
BAND = (0.55, 3.0)  # the frequency band of an irregular sea, in units of the peak frequency


@dataclass(frozen=True)
class Sea:
    """A sea state: significant wave height (m), peak period (s), mean direction the waves come
    from (deg, clockwise from north) and cosine-power spreading n (None: long-crested). A regular
    sea (`regular`) is one wave of height hs_m and period tp_s. `seed` draws the components."""

    hs_m: float
    tp_s: float
    dir_deg: float
    spread: float | None = None
    gamma: float = 3.3
    regular: bool = False
    seed: int = 0

    def text(self) -> str:
        if self.regular:
            return f"regular wave H {self.hs_m:g} m, T {self.tp_s:g} s from {self.dir_deg:g}°"
        crest = "long-crested" if self.spread is None else f"cos^{self.spread:g} spreading"
        return f"JONSWAP Hs {self.hs_m:g} m, Tp {self.tp_s:g} s from {self.dir_deg:g}°, {crest}, seed {self.seed}"

    def to_dict(self) -> dict:
        return {"hs_m": self.hs_m, "tp_s": self.tp_s, "dir_deg": self.dir_deg, "spread": self.spread,
                "gamma": self.gamma, "regular": self.regular, "seed": self.seed}


@dataclass(frozen=True)
class Components:
    """The regular components of a sea (arrays of equal length, SI, β the propagation direction)."""

    amplitude_m: np.ndarray
    omega_rad_s: np.ndarray
    k_rad_m: np.ndarray
    beta_rad: np.ndarray
    phase_rad: np.ndarray

    def __len__(self) -> int:
        return len(self.amplitude_m)

    @property
    def hs_m(self) -> float:
        """Significant height of the components, 4√m0."""
        return float(4.0 * np.sqrt(0.5 * np.sum(self.amplitude_m ** 2)))

    def pack(self) -> np.ndarray:
        """(n, 5) rows a, ω, k, cos β, sin β ... and the phase: (n, 6) for the native kernels."""
        return np.column_stack([self.amplitude_m, self.omega_rad_s, self.k_rad_m, np.cos(self.beta_rad),
                                np.sin(self.beta_rad), self.phase_rad])


def parse_sea(text: str, seed: int = 0) -> Sea:
    """`--sea HS,TP,DIR[,SPREAD]` (JONSWAP) or `--sea regular,H,T,DIR` → Sea, checked."""
    parts = [p.strip() for p in text.split(",")]
    regular = parts[0].lower() == "regular"
    numbers = parts[1:] if regular else parts
    want = "regular,H,T,DIR" if regular else "HS,TP,DIR[,SPREAD] (or regular,H,T,DIR)"
    if len(numbers) not in ((3,) if regular else (3, 4)):
        raise TwinError(f"sea expects {want}, got '{text}'")
    try:
        values = [float(x) for x in numbers]
    except ValueError:
        raise TwinError(f"sea expects {want} as numbers, got '{text}'") from None
    if not all(math.isfinite(x) for x in values):
        raise TwinError(f"sea {text}: every value must be finite")
    sea = Sea(values[0], values[1], values[2] % 360.0, values[3] if len(values) == 4 else None, regular=regular,
              seed=seed)
    check_sea(sea)
    return sea


def wavelength_m(period_s: float) -> float:
    """Deep-water wavelength λ = g T²/(2π)."""
    return G * period_s ** 2 / (2.0 * np.pi)


def check_sea(sea: Sea, min_period_s: float | None = None, what: str = "") -> None:
    """Positive height and period, a spreading power ≥ 1, no wave steeper than breaking
    (H/λ ≤ 1/7; for an irregular sea H_s over the peak wavelength), and a period not shorter
    than `min_period_s` (what the engine's time step and wave grid resolve)."""
    name = "H" if sea.regular else "Hs"
    if not sea.hs_m > 0 or not sea.tp_s > 0:
        raise TwinError(f"sea: the wave height and period must be positive, got {name} {sea.hs_m:g} m, "
                        f"T {sea.tp_s:g} s")
    if sea.spread is not None and not sea.spread >= 1:
        raise TwinError(f"sea: the spreading power must be at least 1 (cos^n, n ≥ 1), got {sea.spread:g}")
    lam = wavelength_m(sea.tp_s)
    if sea.hs_m / lam > BREAKING_STEEPNESS:
        raise TwinError(f"sea: {name} {sea.hs_m:g} m at a period of {sea.tp_s:g} s (wavelength {lam:.2f} m) is "
                        f"steeper than breaking (H/λ = {sea.hs_m / lam:.3f} > 1/7)")
    if min_period_s is not None and sea.tp_s < min_period_s:
        raise TwinError(f"sea: a {'' if sea.regular else 'peak '}period of {sea.tp_s:g} s is shorter than the "
                        f"{min_period_s:.2f} s {what or 'the simulation resolves'}")


def jonswap(omega: np.ndarray, hs_m: float, tp_s: float, gamma: float = 3.3) -> np.ndarray:
    """JONSWAP spectral density S(ω) (m² s/rad) [DNV-RP-C205]; γ = 1 is Pierson-Moskowitz."""
    omega = np.asarray(omega, float)
    wp = 2.0 * np.pi / tp_s
    s_pm = 5.0 / 16.0 * hs_m ** 2 * wp ** 4 * omega ** -5.0 * np.exp(-1.25 * (omega / wp) ** -4.0)
    if gamma == 1.0:
        return s_pm
    sigma = np.where(omega <= wp, 0.07, 0.09)
    a_gamma = 1.0 - 0.287 * np.log(gamma)
    return a_gamma * s_pm * gamma ** np.exp(-0.5 * ((omega - wp) / (sigma * wp)) ** 2)


def pierson_moskowitz(omega: np.ndarray, hs_m: float, tp_s: float) -> np.ndarray:
    """Pierson-Moskowitz spectral density S(ω) (m² s/rad) [DNV-RP-C205]."""
    return jonswap(omega, hs_m, tp_s, 1.0)


def spreading(theta_rad: np.ndarray, n: float) -> np.ndarray:
    """D(θ) = Γ(1 + n/2)/(√π Γ(1/2 + n/2)) cos^n θ for |θ| < π/2, else 0 [DNV-RP-C205];
    ∫ D dθ = 1."""
    theta = np.asarray(theta_rad, float)
    # the gammas' ratio through their logarithms: each alone overflows beyond n ≈ 340
    c = math.exp(math.lgamma(1.0 + n / 2.0) - math.lgamma(0.5 + n / 2.0)) / math.sqrt(math.pi)
    return np.where(np.abs(theta) < np.pi / 2, c * np.abs(np.cos(theta)) ** n, 0.0)


def _spread_draws(rng: np.random.Generator, n_draws: int, n: float) -> np.ndarray:
    """Directions (rad, about the mean) drawn from D(θ) by inverting its CDF on a fine grid."""
    grid = np.linspace(-np.pi / 2, np.pi / 2, 2001)
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (spreading(grid[1:], n) + spreading(grid[:-1], n)) * np.diff(grid))])
    cdf /= cdf[-1]
    return np.interp(rng.uniform(0.0, 1.0, n_draws), cdf, grid)


def components(sea: Sea, n: int = N_COMPONENTS, omega_max: float | None = None) -> Components:
    """The sea's regular components (module docstring). `omega_max` (rad/s) drops the spectrum's
    tail above what the engine resolves; the rest is scaled to the sea's H_s all the same only
    when it keeps at least 90 % of the variance (else TwinError)."""
    beta_mean = np.deg2rad(sea.dir_deg) + np.pi  # from → towards
    if sea.regular:
        omega = 2.0 * np.pi / sea.tp_s
        return Components(np.array([sea.hs_m / 2.0]), np.array([omega]), np.array([omega ** 2 / G]),
                          np.array([beta_mean]), np.array([0.0]))
    rng = np.random.default_rng(sea.seed)
    wp = 2.0 * np.pi / sea.tp_s
    lo, hi = BAND[0] * wp, BAND[1] * wp
    edges = np.linspace(lo, hi, n + 1)
    d_omega = edges[1] - edges[0]
    omega = edges[:-1] + d_omega * rng.uniform(0.0, 1.0, n)
    phase = rng.uniform(0.0, 2.0 * np.pi, n)
    beta = beta_mean + (_spread_draws(rng, n, sea.spread) if sea.spread is not None else np.zeros(n))
    s = jonswap(omega, sea.hs_m, sea.tp_s, sea.gamma)
    keep = np.ones(n, bool) if omega_max is None else omega <= omega_max
    total = float(np.sum(s))
    if np.sum(s[keep]) < 0.9 * total:
        raise TwinError(f"sea: Tp {sea.tp_s:g} s puts more than a tenth of the sea's energy at periods shorter "
                        f"than the {2 * np.pi / omega_max:.2f} s the simulation resolves")
    amp = np.sqrt(2.0 * s * d_omega)[keep]
    amp *= (sea.hs_m / 4.0) / np.sqrt(0.5 * np.sum(amp ** 2))
    omega, beta, phase = omega[keep], beta[keep], phase[keep]
    return Components(amp, omega, omega ** 2 / G, beta, phase)


def phases(c: Components, x: np.ndarray, y: np.ndarray, t: float) -> np.ndarray:
    """θ_i at the points (x, y) (m, NED) and time t: shape (points, components)."""
    x = np.asarray(x, float)[..., None]
    y = np.asarray(y, float)[..., None]
    return c.k_rad_m * (x * np.cos(c.beta_rad) + y * np.sin(c.beta_rad)) - c.omega_rad_s * t + c.phase_rad


def elevation(c: Components, x, y, t: float) -> np.ndarray:
    """ζ (m, up) at the points (x, y) at time t."""
    return np.sum(c.amplitude_m * np.cos(phases(c, x, y, t)), axis=-1)


def pressure(c: Components, x, y, z, t: float, rho: float = 1000.0) -> np.ndarray:
    """Incident pressure (Pa, gauge) at (x, y, z) (z down), 0 above the surface; each component decays
    with the depth below the local surface (module docstring)."""
    th = phases(c, x, y, t)
    z = np.asarray(z, float)
    zeta = np.sum(c.amplitude_m * np.cos(th), axis=-1)
    depth = np.maximum(z + zeta, 0.0)
    p = rho * G * (z + np.sum(c.amplitude_m * np.exp(-c.k_rad_m * depth[..., None]) * np.cos(th), axis=-1))
    return np.where(z + zeta > 0.0, p, 0.0)


def velocity(c: Components, x, y, z, t: float) -> np.ndarray:
    """Particle velocity (north, east, down) m/s at (x, y, z ≥ 0)."""
    th = phases(c, x, y, t)
    e = c.omega_rad_s * c.amplitude_m * np.exp(-c.k_rad_m * np.asarray(z, float)[..., None])
    h_n = np.sum(e * np.cos(th) * np.cos(c.beta_rad), axis=-1)
    h_e = np.sum(e * np.cos(th) * np.sin(c.beta_rad), axis=-1)
    return np.stack([h_n, h_e, -np.sum(e * np.sin(th), axis=-1)], axis=-1)


def acceleration(c: Components, x, y, z, t: float) -> np.ndarray:
    """Particle acceleration (north, east, down) m/s² at (x, y, z ≥ 0)."""
    th = phases(c, x, y, t)
    e = c.omega_rad_s ** 2 * c.amplitude_m * np.exp(-c.k_rad_m * np.asarray(z, float)[..., None])
    return np.stack([np.sum(e * np.sin(th) * np.cos(c.beta_rad), axis=-1),
                     np.sum(e * np.sin(th) * np.sin(c.beta_rad), axis=-1),
                     np.sum(e * np.cos(th), axis=-1)], axis=-1)


def stokes_drift(c: Components, depth_m: float) -> np.ndarray:
    """The Stokes drift (north, east, m/s) of the components at a depth in deep water [Stokes-1847]:
    Σ ω k a² e^{−2kz} along each component's direction of travel."""
    speed = c.omega_rad_s * c.k_rad_m * c.amplitude_m ** 2 * np.exp(-2.0 * c.k_rad_m * depth_m)
    return np.array([np.sum(speed * np.cos(c.beta_rad)), np.sum(speed * np.sin(c.beta_rad))])


# ---------------------------------------------------------------- fields on a grid (numba)

N_FIELDS = 7  # grid_fields: pressure heads at three depths, then at the strip depth: vertical
#              acceleration and velocity (down), horizontal acceleration (north, east)


def field_weights(c: Components, levels_m: tuple[float, float, float], strip_depth_m: float) -> np.ndarray:
    """(7, n) weights of each component in the seven grid fields (`grid_fields`): a e^{−k z_l} for
    the three pressure levels z_l (multiplying cos θ), a ω² e^{−k z_m} (cos θ), −a ω e^{−k z_m}
    (sin θ), a ω² e^{−k z_m} cos β and a ω² e^{−k z_m} sin β (sin θ)."""
    a, w, k, b = c.amplitude_m, c.omega_rad_s, c.k_rad_m, c.beta_rad
    em = a * np.exp(-k * strip_depth_m)
    return np.ascontiguousarray(np.vstack([a * np.exp(-k * levels_m[0]), a * np.exp(-k * levels_m[1]),
                                           a * np.exp(-k * levels_m[2]), w * w * em, -w * em,
                                           w * w * em * np.cos(b), w * w * em * np.sin(b)]))


@njit(cache=True, fastmath={"reassoc", "contract"})
def grid_fields(comps, weights, t, ox, oy, cpsi, spsi, dx, dy, nx, ny, out, phase_co, i0, j0):
    """The seven fields (`field_weights`) at the nodes of a grid in the heading frame: node (i, j)
    sits at (ox, oy) + i·dx·(cψ, sψ) + j·dy·(−sψ, cψ) (NED, m). weights (7, n); out (7, ny·nx),
    overwritten.

    The phase of each component is carried from node to node by complex rotation (one sine and
    cosine per component and direction, not per node). phase_co (2, n) receives cos θ, sin θ at
    node (i0, j0)."""
    n = comps.shape[0]
    cr = np.empty(n)
    sr = np.empty(n)
    cx = np.empty(n)
    sx = np.empty(n)
    cy = np.empty(n)
    sy = np.empty(n)
    for i in range(n):
        k, cb, sb = comps[i, 2], comps[i, 3], comps[i, 4]
        th = k * (cb * ox + sb * oy) - comps[i, 1] * t + comps[i, 5]
        cr[i] = np.cos(th)
        sr[i] = np.sin(th)
        ax = k * (cb * cpsi + sb * spsi) * dx
        ay = k * (-cb * spsi + sb * cpsi) * dy
        cx[i] = np.cos(ax)
        sx[i] = np.sin(ax)
        cy[i] = np.cos(ay)
        sy[i] = np.sin(ay)
    w0, w1, w2, w3 = weights[0], weights[1], weights[2], weights[3]
    w4, w5, w6 = weights[4], weights[5], weights[6]
    c = np.empty(n)
    s = np.empty(n)
    for j in range(ny):
        c[:] = cr
        s[:] = sr
        for l in range(nx):
            q = j * nx + l
            if j == j0 and l == i0:
                phase_co[0, :] = c
                phase_co[1, :] = s
            f0 = 0.0
            f1 = 0.0
            f2 = 0.0
            f3 = 0.0
            f4 = 0.0
            f5 = 0.0
            f6 = 0.0
            for i in range(n):
                ci = c[i]
                si = s[i]
                f0 += w0[i] * ci
                f1 += w1[i] * ci
                f2 += w2[i] * ci
                f3 += w3[i] * ci
                f4 += w4[i] * si
                f5 += w5[i] * si
                f6 += w6[i] * si
                c[i] = ci * cx[i] - si * sx[i]
                s[i] = si * cx[i] + ci * sx[i]
            out[0, q] = f0
            out[1, q] = f1
            out[2, q] = f2
            out[3, q] = f3
            out[4, q] = f4
            out[5, q] = f5
            out[6, q] = f6
        for i in range(n):
            ci = cr[i]
            cr[i] = ci * cy[i] - sr[i] * sy[i]
            sr[i] = sr[i] * cy[i] + ci * sy[i]


@njit(inline="always")
def cell(gx, gy, dx, dy, nx, ny):
    """(node index, ux, uy) of the bilinear cell holding heading-frame point (gx, gy), clamped."""
    fx = min(max(gx / dx, 0.0), nx - 1.000001)
    fy = min(max(gy / dy, 0.0), ny - 1.000001)
    i = int(fx)
    j = int(fy)
    return j * nx + i, fx - i, fy - j


@njit(inline="always")
def bilinear(fields, f, q, ux, uy, nx):
    row = fields[f]
    return ((1.0 - uy) * ((1.0 - ux) * row[q] + ux * row[q + 1])
            + uy * ((1.0 - ux) * row[q + nx] + ux * row[q + nx + 1]))


@njit(inline="always")
def interpolate(fields, f, gx, gy, dx, dy, nx, ny):
    """Bilinear value of field f (fields (7, ny·nx)) at heading-frame grid coordinates (gx, gy)
    (m from node (0, 0)), clamped to the grid."""
    q, ux, uy = cell(gx, gy, dx, dy, nx, ny)
    return bilinear(fields, f, q, ux, uy, nx)
