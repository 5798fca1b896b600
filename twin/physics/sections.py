"""A ship section heaving on deep water, in two dimensions: its added mass, radiation damping and
radiated wave, by pulsating sources on its contour (the close-fit method [Frank-1967]).

The section is symmetric about its centreline; y is up, the calm surface y = 0 and the water
y < 0; the motion is Re{V e^{iωt}}. Sources of complex strength σ_j, constant on each straight
panel of the half contour and mirrored onto the other half, give the potential
φ(P) = Σ_j σ_j ∫_j G(P, Q) ds_Q with the deep-water Green function of a pulsating source
[Wehausen-Laitone-1960], K = ω²/g, X = x − ξ, Y = y + η:

    G = ln r − ln r' − 2 PV∫₀^∞ e^{kY} cos(kX)/(k − K) dk + 2πi e^{KY} cos(KX),

r and r' the distances to the source and to its image above the surface, whose principal value is
Re[e^{w} E1(w)] − π e^{KY} sin(K|X|) with w = K(Y + i|X|): it satisfies the free-surface condition
φ_y = Kφ and radiates outgoing waves. The strengths make the normal velocity the contour's own at
the panels' midpoints (their normal derivative taken on the water side, so the sources' own jump is
in it). The pressure −ρ iω φ over the contour gives the force −(iω a33 + b33)V; the far field,
φ → C e^{Ky} e^{−iK|x|}, the radiated wave's amplitude per unit heave Ā = ω²|C|/g on each side,
and with it the damping again, b33 = ρ g² Ā²/ω³ (the energy the two waves carry away): the two
agree to within the panels' error (tests/test_sea.py).

The tests hold it to a multipole solution of the heaving semicircle [Ursell-1949] (added mass,
damping and Ā within 1.5-2.5 % at KR 0.2-1) and to its limits: Ā → ω²B/g as ω falls (the
Froude-Krylov force of a long wave and the Haskind relation [Newman-1977]). Valid below the method's
irregular frequencies, the first of which lies at ω√(B/2g) ≈ 1.25-1.5 for these shapes (a box of the
same B and T bounds it from below, √((π/2) coth(πT/B))); the shipped hulls' heave natural
frequencies lie at 0.92-0.95 on their widest strips.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import exp1

from ..errors import TwinError

G = 9.81
PANELS = 20  # on the half contour: the damping within 1 % of 40 panels' on a semicircle and a Lewis box
_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(8)
_NORMAL_STEP = 1e-4  # of the panel's length: the water-side normal derivative's step


@dataclass(frozen=True)
class SectionRadiation:
    """Heave added mass a33 (kg/m), radiation damping b33 (N s/m²) and the radiated wave's
    amplitude per unit heave Ā on each side, at ω (rad/s)."""

    omega_rad_s: float
    a33: float
    b33: float
    amplitude_ratio: float


def lewis_form(beam_m: float, draft_m: float, sigma: float) -> tuple[float, float, float]:
    """(a1, a3, M m) of the Lewis form of beam B, draft T and area coefficient σ = A/(BT)
    [Journee-Massie-2001], σ held within the range where the mapping is not re-entrant,
    3π/32·(2 − min(H0, 1/H0)) < σ < π/32·(10 + H0 + 1/H0):
        H0 = B/(2T), C1 = (3 + 4σ/π) + (1 − 4σ/π)((H0 − 1)/(H0 + 1))²,
        a3 = (−C1 + 3 + √(9 − 2C1))/C1, a1 = (1 + a3)(H0 − 1)/(H0 + 1), M = B/(2(1 + a1 + a3))."""
    h0 = beam_m / (2.0 * draft_m)
    r = ((h0 - 1.0) / (h0 + 1.0)) ** 2
    lo = 3.0 * np.pi / 32.0 * (2.0 - min(h0, 1.0 / h0))
    hi = np.pi / 32.0 * (10.0 + h0 + 1.0 / h0)
    sigma = min(max(sigma, lo + 1e-6), hi - 1e-6)
    c1 = (3.0 + 4.0 * sigma / np.pi) + (1.0 - 4.0 * sigma / np.pi) * r
    a3 = (-c1 + 3.0 + np.sqrt(max(9.0 - 2.0 * c1, 0.0))) / c1
    a1 = (1.0 + a3) * (h0 - 1.0) / (h0 + 1.0)
    return float(a1), float(a3), float(beam_m / (2.0 * (1.0 + a1 + a3)))


def lewis_contour(beam_m: float, draft_m: float, sigma: float, panels: int = PANELS) -> tuple[np.ndarray, np.ndarray]:
    """The half contour (x, y m; y up) of the Lewis form from the waterline (B/2, 0) to the keel
    (0, −T): x = M((1 + a1) sin θ − a3 sin 3θ), y = −M((1 − a1) cos θ + a3 cos 3θ), θ from π/2 to 0."""
    a1, a3, m = lewis_form(beam_m, draft_m, sigma)
    th = np.linspace(np.pi / 2.0, 0.0, panels + 1)
    return (m * ((1.0 + a1) * np.sin(th) - a3 * np.sin(3.0 * th)),
            -m * ((1.0 - a1) * np.cos(th) + a3 * np.cos(3.0 * th)))


def _wave_term(x: np.ndarray, y: np.ndarray, k: float) -> np.ndarray:
    """G less ln r − ln r' (module docstring), at X = x, Y = y < 0."""
    ax = np.abs(x)
    w = k * (y + 1j * ax)
    decay = np.exp(k * y)
    return (-2.0 * (np.exp(w) * exp1(w)).real + 2.0 * np.pi * decay * np.sin(k * ax)
            + 2j * np.pi * decay * np.cos(k * x))


def _log_integral(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """∫ ln|P − Q| ds over each straight segment a→b, exactly: (fields, segments)."""
    d_ab = b - a
    length = np.hypot(d_ab[:, 0], d_ab[:, 1])
    t = d_ab / length[:, None]
    rel = p[:, None, :] - a[None, :, :]
    s0 = rel[..., 0] * t[None, :, 0] + rel[..., 1] * t[None, :, 1]
    d = -rel[..., 0] * t[None, :, 1] + rel[..., 1] * t[None, :, 0]

    def antiderivative(s):
        u = s - s0
        r2 = u * u + d * d
        safe_d = np.where(d == 0.0, 1.0, d)
        return 0.5 * u * np.log(r2) - u + np.where(d == 0.0, 0.0, d * np.arctan(u / safe_d))

    return antiderivative(length[None, :]) - antiderivative(0.0)


def _potentials(p: np.ndarray, a: np.ndarray, b: np.ndarray, k: float) -> np.ndarray:
    """∫ G ds of each source panel and its mirror at the field points p: (fields, panels)."""
    n = len(a)
    mirror = np.array([-1.0, 1.0])
    sa, sb = np.vstack([a, a * mirror]), np.vstack([b, b * mirror])
    out = _log_integral(p, sa, sb).astype(complex)
    frac = (_GAUSS_X + 1.0) / 2.0
    q = sa[:, None, :] + (sb - sa)[:, None, :] * frac[None, :, None]  # (panels, gauss, 2)
    w = _GAUSS_W[None, :] * np.hypot(*(sb - sa).T)[:, None] / 2.0
    x = p[:, None, None, 0] - q[None, :, :, 0]
    y = p[:, None, None, 1] + q[None, :, :, 1]
    out += np.sum((-0.5 * np.log(x * x + y * y) + _wave_term(x, y, k)) * w[None], axis=2)
    return out[:, :n] + out[:, n:]


def heave_radiation(x: np.ndarray, y: np.ndarray, omega: float, rho: float = 1000.0) -> SectionRadiation:
    """The heaving section whose half contour runs through (x, y) (m, y up, from the waterline to
    the keel) at ω (rad/s): module docstring."""
    if not omega > 0:
        raise TwinError(f"a section heaves at a positive frequency, got {omega:g} rad/s")
    k = omega ** 2 / G
    pts = np.column_stack([np.asarray(x, float), np.asarray(y, float)])
    a, b = pts[:-1], pts[1:]
    mid = (a + b) / 2.0
    length = np.hypot(*(b - a).T)
    if np.any(pts[:, 1] > 1e-9) or np.any(pts[:, 0] < -1e-9):
        raise TwinError("a section's half contour runs from the waterline to the keel below the surface (y ≤ 0) "
                        "on one side of the centreline (x ≥ 0)")
    tangent = (b - a) / length[:, None]
    normal = np.column_stack([-tangent[:, 1], tangent[:, 0]])  # into the water, the contour run waterline → keel
    h = (_NORMAL_STEP * length)[:, None]
    phi0 = _potentials(mid, a, b, k)
    phi1 = _potentials(mid + h * normal, a, b, k)
    phi2 = _potentials(mid + 2.0 * h * normal, a, b, k)
    dn = (-3.0 * phi0 + 4.0 * phi1 - phi2) / (2.0 * h)
    strength = np.linalg.solve(dn, normal[:, 1].astype(complex))  # ∂φ/∂n = n_y for a unit upward velocity
    force = 1j * omega * rho * 2.0 * np.sum((phi0 @ strength) * normal[:, 1] * length)  # −∫p n ds, both halves
    # far field: each source and its mirror send C e^{Ky} e^{−iK|x|}, C = Σ σ ∫ 2πi e^{Kη} e^{iKξ} ds
    frac = (_GAUSS_X + 1.0) / 2.0
    far = 0j
    for side in (1.0, -1.0):
        q = a[:, None, :] + (b - a)[:, None, :] * frac[None, :, None]
        w = _GAUSS_W[None, :] * length[:, None] / 2.0
        far += np.sum(strength[:, None] * w * 2j * np.pi * np.exp(k * q[..., 1]) * np.exp(1j * k * side * q[..., 0]))
    return SectionRadiation(float(omega), float(-force.imag / omega), float(-force.real),
                            float(omega ** 2 * abs(far) / G))
