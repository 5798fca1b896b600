"""The hull in waves: what the 6-DOF twin needs from the hull meshes besides the pressure they
carry (physics/hydrostatics.py): a lighter mesh for the engine, sections for strip theory, the
heave, roll and pitch added mass and damping, the waterline for the mean wave-drift force, and the
closed forms they are checked against.

Hydrodynamic mesh. The engine integrates the pressure over a mesh resampled from the vessel's
own: `n_stations` sections cut from it (stations closer together at the ends, where the lines
change fastest), each section's outline resampled to `n_ring` points by arc length (its corners
kept) and scaled about its centroid to the exact section area, lofted and closed. On the
catamarans and the ship shipped here it floats the vessel's mass within half a millimetre of the
full mesh (tests/test_sea.py), at a fifth of the triangles.

Added mass (infinite frequency, the constant of a time-domain model [Cummins-1962]) by strip
theory [Journee-Massie-2001] (strip theory): each section's heave added mass per unit length from its
Lewis form (beam B, draft T, area coefficient σ) [Lewis-1929], [Journee-Massie-2001] (the Lewis
form's a1, a3 and M33(∞)); the hull's A33 = Σ∫a33 dx, A55 = Σ∫a33 x² dx and A44 = Σ∫(a33 y_c² + a44)
dx with y_c the section's centreline and a44 = ρπB⁴/256 the roll added moment of a floating flat
section (half that of a plate of width B rotating in infinite fluid, ρπ(B/2)⁴/8 [Newman-1977 Table
4.2], the free surface a rigid lid at infinite frequency).

Damping (radiation, linear, at the heave natural frequency ω_n) per section: the heave damping of
its Lewis form at ω_n by pulsating sources on its contour (physics/sections.py, [Frank-1967]),
b33 = ρ g² Ā²/ω³ [Faltinsen-1990] with Ā the section's own radiated-wave amplitude. It is applied per
section on the section's velocity relative to the water (the relative-motion principle
[Journee-Massie-2001]).

Diffraction correction: the relative-motion principle with the Smith effect [Journee-Massie-2001
§6.3.2]: each section feels a33 ζ̈* + b33 ζ̇* beside the Froude-Krylov pressure, ζ̈* and ζ̇* the
incident vertical acceleration and velocity at the section's mean depth T_m = area/B. Horizontally
the same long-wave form: the vessel's own surge and sway added mass (its 3-DOF M_A), spread over
the sections as a22 is, times the horizontal particle acceleration.

Mean and slow wave drift (surge, sway, yaw) per component of unit amplitude: the short-wave
asymptote for a wall-sided hull [Faltinsen-1990] (its drift chapter), F = ½ρg ∫_illuminated sin²(θ+β) n dl
over the waterline, times the reflected energy of a fixed surface-piercing barrier of the hull's
draft, R² = 1 − K1²(kT)/(K1²(kT) + π² I1²(kT)) [Ursell-1947] (Maruo's far-field drift,
½ρg a_R² per unit length [Maruo-1960], with the barrier's reflection: 0 in long waves, the short-
wave asymptote in short ones). The slow drift in an irregular sea follows Newman's approximation
[Newman-1974]: F(t) = |Σ_{T_i>0} a_i √T_i e^{iθ_i}|² − |Σ_{T_i<0} a_i √−T_i e^{iθ_i}|², whose mean
is Σ a_i² T_i (the difference-frequency part only).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.special import i1, k1

from . import waves
from .hydrostatics import pressure_load as _pressure
from .hydrostatics import plane_crossings, submerged_volume
from .sections import heave_radiation, lewis_contour, lewis_form

G = 9.81
N_STATIONS, N_RING = 25, 24


# ---------------------------------------------------------------- sections and the hydrodynamic mesh


def section(vertices: np.ndarray, faces: np.ndarray, x: float) -> np.ndarray:
    """The closed outline (y, z) of the mesh cut by the plane x = const, ordered by angle about its
    centroid (a hull section is star-shaped about it); empty when the plane misses the mesh."""
    p = plane_crossings(vertices, faces, 0, x)[:, 1:]
    if len(p) < 3:
        return np.zeros((0, 2))
    c = p.mean(axis=0)
    p = p[np.argsort(np.arctan2(p[:, 1] - c[1], p[:, 0] - c[0]))]
    keep = np.r_[True, np.linalg.norm(np.diff(p, axis=0), axis=1) > 1e-9]
    return p[keep]


def polygon_area(poly: np.ndarray) -> float:
    y, z = poly[:, 0], poly[:, 1]
    return 0.5 * abs(float(np.dot(y, np.roll(z, -1)) - np.dot(z, np.roll(y, -1))))


def _resample(poly: np.ndarray, n: int) -> np.ndarray:
    """n points along the outline by arc length from its lowest point (largest z), the sample
    nearest each corner (a turn over 30°) moved onto it, scaled about the centroid to the area."""
    closed = np.vstack([poly, poly[:1]])
    seg = np.linalg.norm(np.diff(closed, axis=0), axis=1)
    d = np.r_[0.0, np.cumsum(seg)]
    start = d[int(np.argmax(poly[:, 1]))]
    s = (np.linspace(0.0, d[-1], n, endpoint=False) + start) % d[-1]
    e_in = poly - np.roll(poly, 1, axis=0)
    e_out = np.roll(poly, -1, axis=0) - poly
    cosang = np.einsum("ij,ij->i", e_in, e_out) / np.maximum(np.linalg.norm(e_in, axis=1) * np.linalg.norm(e_out, axis=1), 1e-30)
    for corner in np.flatnonzero(cosang < np.cos(np.deg2rad(30.0))):
        gap = (s - d[corner] + d[-1] / 2) % d[-1] - d[-1] / 2
        s[int(np.argmin(np.abs(gap)))] = d[corner]
    out = np.column_stack([np.interp(s, d, closed[:, 0]), np.interp(s, d, closed[:, 1])])
    c = poly.mean(axis=0)
    area = polygon_area(out)
    return c + (out - c) * np.sqrt(polygon_area(poly) / area) if area > 0 else out


def hydro_mesh(vertices: np.ndarray, faces: np.ndarray, n_stations: int = N_STATIONS,
               n_ring: int = N_RING) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of the engine's hydrodynamic mesh of one closed hull (module docstring):
    outward right-handed faces as the source mesh's."""
    x0, x1 = float(vertices[:, 0].min()), float(vertices[:, 0].max())
    u = 0.5 * (1.0 - np.cos(np.linspace(0.0, np.pi, n_stations)))
    xs = x0 + (x1 - x0) * (1e-4 + (1.0 - 2e-4) * u)
    rings = []
    for x in xs:
        poly = section(vertices, faces, x)
        if len(poly) < 3:
            raise ValueError(f"the hull mesh has no closed section at x = {x:.3f} m")
        r = _resample(poly, n_ring)
        rings.append(np.column_stack([np.full(n_ring, x), r]))
    verts = np.vstack(rings + [rings[0].mean(axis=0), rings[-1].mean(axis=0)])
    n, m = n_ring, n_stations
    out = []
    for i in range(m - 1):
        for j in range(n):
            a, b = i * n + j, i * n + (j + 1) % n
            out += [(a, b, b + n), (a, b + n, a + n)]
    stern, bow = m * n, m * n + 1
    for j in range(n):
        out += [(stern, (j + 1) % n, j), (bow, (m - 1) * n + j, (m - 1) * n + (j + 1) % n)]
    faces_out = np.array(out, dtype=np.int64)
    if _signed_volume(verts, faces_out) < 0:
        faces_out = faces_out[:, ::-1].copy()
    return verts, faces_out


def _signed_volume(v: np.ndarray, f: np.ndarray) -> float:
    t = v[f]
    return float(np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum() / 6.0)


# ---------------------------------------------------------------- strip theory


def lewis_heave(beam_m: float, draft_m: float, sigma: float, rho: float) -> float:
    """Infinite-frequency heave added mass per unit length (kg/m) of a Lewis section of beam B,
    draft T and area coefficient σ = A/(BT) [Journee-Massie-2001]:
        H0 = B/(2T), C1 = (3 + 4σ/π) + (1 − 4σ/π)((H0 − 1)/(H0 + 1))²,
        a3 = (−C1 + 3 + √(9 − 2C1))/C1, a1 = (1 + a3)(H0 − 1)/(H0 + 1),
        M = B/(2(1 + a1 + a3)), a33 = ρ π/2 M² ((1 + a1)² + 3 a3²).
    σ is held within the range where the Lewis mapping exists."""
    if not (beam_m > 0 and draft_m > 0):
        return 0.0
    a1, a3, m = lewis_form(beam_m, draft_m, sigma)
    return float(rho * np.pi / 2.0 * m * m * ((1.0 + a1) ** 2 + 3.0 * a3 * a3))


def heave_damping(beam_m: float, draft_m: float, sigma: float, omega: float, rho: float) -> float:
    """Radiation heave damping per unit length (N s/m²) of the Lewis section of beam B, draft T and
    area coefficient σ at ω, by pulsating sources on its contour (physics/sections.py, [Frank-1967])."""
    if not (beam_m > 0 and draft_m > 0):
        return 0.0
    return heave_radiation(*lewis_contour(beam_m, draft_m, sigma), omega, rho).b33


@dataclass(frozen=True)
class Strip:
    """One section of a hull at its flotation: station x, centreline y (m), waterline beam B, draft
    T, submerged area A (m²), the length it stands for dx (m)."""

    x: float
    y: float
    beam: float
    draft: float
    area: float
    dx: float

    @property
    def sigma(self) -> float:
        return self.area / (self.beam * self.draft) if self.beam > 0 and self.draft > 0 else 0.0

    @property
    def mean_depth(self) -> float:
        return self.area / self.beam if self.beam > 0 else 0.0


def strips(vertices: np.ndarray, faces: np.ndarray, z_waterline: float, n: int = 12) -> list[Strip]:
    """n equal strips of one hull (in the body frame, FRD) below the level waterline z_waterline."""
    x0, x1 = float(vertices[:, 0].min()), float(vertices[:, 0].max())
    edges = np.linspace(x0, x1, n + 1)
    out = []
    for a, b in zip(edges[:-1], edges[1:]):
        x = 0.5 * (a + b)
        poly = section(vertices, faces, x)
        if len(poly) < 3:
            continue
        wet = _clip_below(poly, z_waterline)
        if len(wet) < 3:
            out.append(Strip(x, float(poly[:, 0].mean()), 0.0, 0.0, 0.0, b - a))
            continue
        beam = float(np.ptp(wet[np.abs(wet[:, 1] - z_waterline) < 1e-9][:, 0])) if np.any(
            np.abs(wet[:, 1] - z_waterline) < 1e-9) else float(np.ptp(wet[:, 0]))
        draft = float(wet[:, 1].max() - z_waterline)
        out.append(Strip(x, float(0.5 * (wet[:, 0].max() + wet[:, 0].min())), beam, draft, polygon_area(wet), b - a))
    return out


def _clip_below(poly: np.ndarray, z: float) -> np.ndarray:
    """The part of a closed (y, z) polygon with z' > z (below the waterline, z down)."""
    out = []
    n = len(poly)
    for i in range(n):
        a, b = poly[i], poly[(i + 1) % n]
        ina, inb = a[1] > z, b[1] > z
        if ina:
            out.append(a)
        if ina != inb:
            s = (z - a[1]) / (b[1] - a[1])
            out.append(a + s * (b - a))
    return np.array(out) if out else np.zeros((0, 2))


@dataclass(frozen=True)
class Radiation:
    """Heave, roll and pitch added mass (kg, kg m², kg m², about the body origin) and the strips'
    added mass and damping per unit length (a33, b33 at the heave natural frequency)."""

    A33: float
    A44: float
    A55: float
    a33: np.ndarray
    b33: np.ndarray


def radiation(all_strips: list[Strip], rho: float, omega: float | None) -> Radiation:
    """Strip sums of the module docstring; b33 at ω (the heave natural frequency), none without one
    (the added mass, of infinite frequency, does not depend on it)."""
    a33 = np.array([lewis_heave(s.beam, s.draft, s.sigma, rho) for s in all_strips])
    b33 = np.array([0.0 if omega is None else heave_damping(s.beam, s.draft, s.sigma, omega, rho)
                    for s in all_strips])
    dx = np.array([s.dx for s in all_strips])
    x = np.array([s.x for s in all_strips])
    y = np.array([s.y for s in all_strips])
    beam = np.array([s.beam for s in all_strips])
    a44_own = rho * np.pi * beam ** 4 / 256.0
    return Radiation(float(np.sum(a33 * dx)), float(np.sum((a33 * y ** 2 + a44_own) * dx)),
                     float(np.sum(a33 * x ** 2 * dx)), a33, b33)


# ---------------------------------------------------------------- closed forms


@dataclass(frozen=True)
class Waterplane:
    """The hull's level waterplane at a waterline z_w (body frame): area (m²), centre of floatation
    (x_f, y_f), second moments about the body axes through the origin (m⁴), displaced volume (m³)
    and centre of buoyancy (m)."""

    area: float
    x_f: float
    y_f: float
    Ixx: float  # ∫ y² dA
    Iyy: float  # ∫ x² dA
    volume: float
    centre: np.ndarray


def waterplane(meshes: list[tuple[np.ndarray, np.ndarray]], z_w: float, dz: float = 1e-5) -> Waterplane:
    """From the submerged volume V(z) and its moments: A_wp = dV/dz, and the first and second
    moments of the waterplane from the derivatives of V x_B and of the volume's rotation (a
    finite difference of the exact clipped volumes, so a mesh of any shape)."""
    def moments(z):
        out = np.zeros(4)
        for v, f in meshes:
            vol, c = submerged_volume(v, f, z)
            out += [vol, vol * c[0], vol * c[1], 0.0]
        return out
    lo, hi = moments(z_w - dz), moments(z_w + dz)  # z down: z_w − dz is a higher waterline
    area = (lo[0] - hi[0]) / (2 * dz)
    x_f = (lo[1] - hi[1]) / (2 * dz) / area
    y_f = (lo[2] - hi[2]) / (2 * dz) / area
    # second moments from the section outlines at the waterline
    Ixx = Iyy = 0.0
    for v, f in meshes:
        h = (v[:, 0].max() - v[:, 0].min()) / 240
        for x in v[:, 0].min() + h * (np.arange(240) + 0.5):  # the midpoint rule
            poly = section(v, f, x)
            if len(poly) < 3:
                continue
            ys = _waterline_crossings(poly, z_w)
            if len(ys) < 2:
                continue
            a, b = min(ys), max(ys)
            Ixx += (b ** 3 - a ** 3) / 3.0 * h
            Iyy += x * x * (b - a) * h
    vol = centre = None
    total = np.zeros(4)
    cs = np.zeros(3)
    for v, f in meshes:
        vv, c = submerged_volume(v, f, z_w)
        total[0] += vv
        cs += vv * c
    vol = float(total[0])
    centre = cs / vol if vol > 0 else cs
    return Waterplane(float(area), float(x_f), float(y_f), float(Ixx), float(Iyy), vol, centre)


def _waterline_crossings(poly: np.ndarray, z: float) -> list[float]:
    out = []
    n = len(poly)
    for i in range(n):
        a, b = poly[i], poly[(i + 1) % n]
        if (a[1] > z) != (b[1] > z):
            s = (z - a[1]) / (b[1] - a[1])
            out.append(float(a[0] + s * (b[0] - a[0])))
    return out


def restoring(wp: Waterplane, mass_kg: float, z_g: float, rho: float = 1000.0) -> dict[str, float]:
    """Linear hydrostatic stiffness of a free-floating hull about its level flotation
    [Journee-Massie-2001], [Faltinsen-1990]: C33 = ρ g A_wp and, with the metacentric heights
    GM_T = I_T/V + KB − KG, GM_L = I_L/V + KB − KG, C44 = ρ g V GM_T, C55 = ρ g V GM_L, where the
    waterplane's second moments are about its centre of floatation and heights are measured up from
    the keel along −z (z down: KB − KG = z_G − z_B)."""
    I_T = wp.Ixx - wp.area * wp.y_f ** 2
    I_L = wp.Iyy - wp.area * wp.x_f ** 2
    gm_t = I_T / wp.volume + (z_g - wp.centre[2])
    gm_l = I_L / wp.volume + (z_g - wp.centre[2])
    rg = rho * G
    return {"C33": rg * wp.area, "C44": rg * wp.volume * gm_t, "C55": rg * wp.volume * gm_l,
            "GM_T": gm_t, "GM_L": gm_l, "I_T": I_T, "I_L": I_L}


# ---------------------------------------------------------------- wave drift


def reflection_squared(k_rad_m: np.ndarray, draft_m: float) -> np.ndarray:
    """R² of a fixed thin vertical barrier of draft T in deep water [Ursell-1947]."""
    kt = np.maximum(np.asarray(k_rad_m, float) * draft_m, 1e-9)
    big = kt > 50.0
    kt_s = np.where(big, 1.0, kt)
    t2 = k1(kt_s) ** 2 / (k1(kt_s) ** 2 + np.pi ** 2 * i1(kt_s) ** 2)
    return np.where(big, 1.0, 1.0 - t2)


def waterline_segments(vertices: np.ndarray, faces: np.ndarray, z_w: float) -> np.ndarray:
    """(n, 4) segments (x0, y0, x1, y1) of the hull's waterline at z_w, oriented so that the outward
    normal is (dy, −dx)/|d| (counter-clockwise seen from above in FRD: x forward, y starboard)."""
    tris = vertices[faces]
    d = tris[:, :, 2] - z_w
    segs = []
    for t, dd in zip(tris, d):
        pts = []
        for a, b in ((0, 1), (1, 2), (2, 0)):
            if (dd[a] > 0) != (dd[b] > 0):
                s = dd[a] / (dd[a] - dd[b])
                pts.append(t[a] + s * (t[b] - t[a]))
        if len(pts) == 2:
            p, q = pts
            n_face = np.cross(t[1] - t[0], t[2] - t[0])
            seg = np.array([p[0], p[1], q[0], q[1]])
            # outward horizontal normal of the segment must agree with the face's
            nx, ny = q[1] - p[1], -(q[0] - p[0])
            if nx * n_face[0] + ny * n_face[1] < 0:
                seg = np.array([q[0], q[1], p[0], p[1]])
            segs.append(seg)
    return np.array(segs) if segs else np.zeros((0, 4))


def drift_table(segments: np.ndarray, n_headings: int = 72) -> np.ndarray:
    """(n_headings, 3): the drift force and moment (X, Y, N in the body frame, about the origin) per
    ½ρg a² on a wall-sided waterline in short waves travelling towards body heading β_j =
    2πj/n [Faltinsen-1990]: Σ over illuminated segments (n·k̂ < 0) of (n·k̂)² (−n) dl."""
    p0, p1 = segments[:, :2], segments[:, 2:]
    d = p1 - p0
    length = np.linalg.norm(d, axis=1)
    n = np.column_stack([d[:, 1], -d[:, 0]]) / np.maximum(length, 1e-30)[:, None]
    mid = 0.5 * (p0 + p1)
    out = np.zeros((n_headings, 3))
    for j, beta in enumerate(np.arange(n_headings) * 2.0 * np.pi / n_headings):
        k = np.array([np.cos(beta), np.sin(beta)])
        nk = n @ k
        lit = nk < 0
        f = (nk[lit] ** 2 * length[lit])[:, None] * (-n[lit])
        out[j, 0] = f[:, 0].sum()
        out[j, 1] = f[:, 1].sum()
        out[j, 2] = np.sum(mid[lit, 0] * f[:, 1] - mid[lit, 1] * f[:, 0])
    return out


def natural_periods(wp: Waterplane, C: dict[str, float], mass_kg: float, cg_m: np.ndarray, inertia_cg: np.ndarray,
                    rad: Radiation, rho: float = 1000.0) -> dict[str, float]:
    """Heave, roll and pitch natural periods of the free-floating hull, linear, with the added mass
    the engine uses (A33 on heave, A44 on roll, A55 on pitch, about the body origin).

    Uncoupled ("heave_uncoupled" ...): T = 2π √((M + A)/C) with C33 = ρ g A_wp, C44 = ρ g V GM_T,
    C55 = ρ g V GM_L and the rigid inertias about the centre of gravity. Coupled ("heave", "pitch",
    "roll"): the periods of `coupled_modes`."""
    modes = coupled_modes(wp, C, mass_kg, cg_m, inertia_cg, rad, rho)
    out = {k: period for k, (period, _) in modes.items()}
    out.update({f"{k}_uncoupled": v for k, v in _uncoupled(C, mass_kg, inertia_cg, rad).items()})
    return out


def _uncoupled(C: dict[str, float], mass_kg: float, inertia_cg: np.ndarray, rad: Radiation) -> dict[str, float]:
    def period(m, c):
        return float(2 * np.pi * np.sqrt(m / c)) if c > 0 else float("nan")

    return {"heave": period(mass_kg + rad.A33, C["C33"]), "roll": period(inertia_cg[0] + rad.A44, C["C44"]),
            "pitch": period(inertia_cg[1] + rad.A55, C["C55"])}


def coupled_modes(wp: Waterplane, C: dict[str, float], mass_kg: float, cg_m: np.ndarray, inertia_cg: np.ndarray,
                  rad: Radiation, rho: float = 1000.0) -> dict[str, tuple[float, np.ndarray]]:
    """The heave, pitch and roll modes of the free-floating hull: per mode its period (s) and its
    shape, the displacement (down m, pitch rad, roll rad) it oscillates along, scaled to a largest
    component of 1. The stiffness is written about the body origin, where heave and pitch couple
    through the centre of floatation (C35 = −ρ g A_wp x_f, C55 = ρ g (∫x² dA + V (z_G − z_B))) and
    the rigid body through its centre of gravity, surge and sway free (they have no stiffness):
    ω² are the non-zero eigenvalues of M⁻¹C on (surge, heave, pitch) and (sway, heave, roll), each
    mode named by the uncoupled period it is nearest. A hull whose heave and pitch periods are close
    and coupled through x_f answers a pure heave or pitch displacement in both modes at once."""
    xg, yg, zg = (float(c) for c in cg_m)
    rg = rho * G
    bg = wp.volume * (zg - float(wp.centre[2]))
    m = mass_kg
    # (surge, heave, pitch) about the origin; pitch positive bow up
    M = np.array([[m, 0.0, m * zg], [0.0, m + rad.A33, -m * xg],
                  [m * zg, -m * xg, inertia_cg[1] + m * (xg * xg + zg * zg) + rad.A55]])
    Cm = np.zeros((3, 3))
    Cm[1, 1] = rg * wp.area
    Cm[1, 2] = Cm[2, 1] = -rg * wp.area * wp.x_f
    Cm[2, 2] = rg * (wp.Iyy + bg)
    # (sway, heave, roll): roll positive starboard down
    Mr = np.array([[m, 0.0, -m * zg], [0.0, m + rad.A33, m * yg],
                   [-m * zg, m * yg, inertia_cg[0] + m * (yg * yg + zg * zg) + rad.A44]])
    Cr = np.zeros((3, 3))
    Cr[1, 1] = rg * wp.area
    Cr[1, 2] = Cr[2, 1] = rg * wp.area * wp.y_f
    Cr[2, 2] = rg * (wp.Ixx + bg)
    uncoupled = _uncoupled(C, m, inertia_cg, rad)

    def oscillating(Mb, Cb, third: int):
        w2, vec = np.linalg.eig(np.linalg.solve(Mb, Cb))
        order = np.argsort(np.real(w2))[1:]  # the zero of the free surge or sway left out
        out = []
        for i in order:
            v = np.real(vec[:, i])
            shape = np.zeros(3)
            shape[0], shape[third] = v[1], v[2]
            shape /= shape[np.argmax(np.abs(shape))]
            out.append((float(2 * np.pi / np.sqrt(np.real(w2[i]))), shape))
        return out

    pair = sorted(oscillating(M, Cm, 1), key=lambda ps: ps[0])
    names = sorted(("heave", "pitch"), key=lambda k: uncoupled[k])
    modes = {names[0]: pair[0], names[1]: pair[1]}
    modes["roll"] = min(oscillating(Mr, Cr, 2), key=lambda ps: abs(ps[0] - uncoupled["roll"]))
    return modes


# ---------------------------------------------------------------- the packed sea load (numba)

SEA_MAGIC = 3.1415926535897932e9
HEADER = 48
# header slots
(_MAGIC, _SIZE, _NV, _NF, _NC, _NS, _NX, _NY, _GX0, _GY0, _DX, _DY, _ZH, _RHOG, _FK, _DIFF, _DAMP, _DRIFT,
 _ND, _I0, _J0, _ZBOUND, _XU, _YV, _ON) = range(25)
_QADR, _DADR = 26, 32  # qpos and dof addresses of north, east, down, yaw, pitch, roll
_NTHR, _THR, MAX_THRUSTERS = 25, 38, 2  # the thrusters' level load: count, then (actuator, a_x, a_y, a_N) each
_ZREST = 46  # the body origin's down at rest (m)


def sea_layout(nv: int, nf: int, nc: int, ns: int, nd: int) -> dict[str, slice]:
    """Where each block of the packed sea (`pack_sea`) starts and ends."""
    sizes = (("verts", 3 * nv), ("faces", 3 * nf), ("comps", 6 * nc), ("weights", 7 * nc), ("drift_c", nc),
             ("strips", 6 * ns), ("drift", 3 * nd))
    out, start = {}, HEADER
    for name, n in sizes:
        out[name] = slice(start, start + n)
        start += n
    out["end"] = slice(start, start)
    return out


def pack_sea(verts: np.ndarray, faces: np.ndarray, comps: np.ndarray, weights: np.ndarray, drift_c: np.ndarray,
             strip_rows: np.ndarray, drift: np.ndarray, grid: dict, switches: tuple[bool, bool, bool, bool],
             qpos_adr: tuple[int, ...], dof_adr: tuple[int, ...], rho: float, added_xy: tuple[float, float],
             active: bool = True, thrust_arms: np.ndarray | None = None, rest_down_m: float = 0.0) -> np.ndarray:
    """The float64 vector `sea_load` reads. strip_rows (ns, 6): x, y (m), a33·dx (kg), b33·dx (N s/m),
    the strip's share of the surge and of the sway added mass; drift (nd, 3) the table of
    `drift_table`; drift_c (nc) ½ρg R²(k_i T) per component; grid: nx, ny, gx0, gy0, dx, dy, zh,
    i0, j0 (`grid_fields`); switches: Froude-Krylov waves, diffraction, damping, drift;
    thrust_arms (≤ MAX_THRUSTERS, 4): actuator index and its level load per newton (`level_thrust`);
    rest_down_m: the body origin's down at rest, from which the hull's heave is measured."""
    nv, nf, nc, ns, nd = len(verts), len(faces), len(comps), len(strip_rows), len(drift)
    lay = sea_layout(nv, nf, nc, ns, nd)
    p = np.zeros(lay["end"].start)
    p[_MAGIC], p[_SIZE] = SEA_MAGIC, len(p)
    p[_NV], p[_NF], p[_NC], p[_NS] = nv, nf, nc, ns
    p[_NX], p[_NY], p[_GX0], p[_GY0] = grid["nx"], grid["ny"], grid["gx0"], grid["gy0"]
    p[_DX], p[_DY], p[_ZH] = grid["dx"], grid["dy"], grid["zh"]
    p[_I0], p[_J0] = grid["i0"], grid["j0"]
    p[_RHOG] = rho * G
    p[_FK], p[_DIFF], p[_DAMP], p[_DRIFT] = (float(s) for s in switches)
    p[_ND] = nd
    p[_ZBOUND] = float(np.sum(np.abs(comps[:, 0]))) if nc else 0.0
    p[_XU], p[_YV] = added_xy
    p[_ON] = float(active)
    p[_ZREST] = rest_down_m
    arms = np.zeros((0, 4)) if thrust_arms is None else np.asarray(thrust_arms, float).reshape(-1, 4)
    if len(arms) > MAX_THRUSTERS:
        raise ValueError(f"at most {MAX_THRUSTERS} thrusters have a level load, got {len(arms)}")
    p[_NTHR] = len(arms)
    p[_THR:_THR + arms.size] = np.ravel(arms)
    p[_QADR:_QADR + 6] = qpos_adr
    p[_DADR:_DADR + 6] = dof_adr
    p[lay["verts"]] = np.ravel(verts)
    p[lay["faces"]] = np.ravel(faces)
    if nc:
        p[lay["comps"]] = np.ravel(comps)
        p[lay["weights"]] = np.ravel(weights)
        p[lay["drift_c"]] = drift_c
    p[lay["strips"]] = np.ravel(strip_rows)
    p[lay["drift"]] = np.ravel(drift)
    return p


@njit(cache=True)
def rotation(psi, theta, phi):
    """R = Rz(ψ) Ry(θ) Rx(φ): body (FRD) → NED [Fossen-2021] (zyx Euler angles)."""
    cp, sp = np.cos(psi), np.sin(psi)
    ct, st = np.cos(theta), np.sin(theta)
    cf, sf = np.cos(phi), np.sin(phi)
    R = np.empty((3, 3))
    R[0, 0] = cp * ct
    R[0, 1] = -sp * cf + cp * st * sf
    R[0, 2] = sp * sf + cp * cf * st
    R[1, 0] = sp * ct
    R[1, 1] = cp * cf + sf * st * sp
    R[1, 2] = -cp * sf + st * sp * cf
    R[2, 0] = -st
    R[2, 1] = ct * sf
    R[2, 2] = ct * cf
    return R


@njit(cache=True)
def level_thrust(p, psi, actuator_force):
    """The thrusters' generalised force on (north, east, yaw) as the 3-DOF twin applies it: each
    actuator's force times its arms (a_x, a_y) forward and to starboard and a_N about the yaw axis,
    taken with the hull level, turned by the heading ψ alone. A thruster tilted with a trimmed or
    heeled hull pushes along its tilted axis; the horizontal model is the calm-water twin's, whose
    thrust map was identified level, so the level part is put back while heave, pitch and roll keep
    the tilted force and its moments. Returns (ok, north, east, yaw)."""
    n = int(p[_NTHR])
    fn, fe, fy = 0.0, 0.0, 0.0
    c, s = np.cos(psi), np.sin(psi)
    for k in range(n):
        i = int(p[_THR + 4 * k])
        if i < 0 or i >= actuator_force.shape[0]:
            return False, 0.0, 0.0, 0.0
        f = actuator_force[i]
        ax, ay, an = p[_THR + 4 * k + 1], p[_THR + 4 * k + 2], p[_THR + 4 * k + 3]
        fn += f * (c * ax - s * ay)
        fe += f * (s * ax + c * ay)
        fy += f * an
    return n > 0, fn, fe, fy


@njit(cache=True)
def sea_load(p, t, qpos, qvel, out, water):
    """Generalised forces of the hull in waves on (north, east, down, yaw, pitch, roll), added to
    out at the packed dof addresses: the pressure load over the wetted mesh (hydrostatics and
    Froude-Krylov), the strips' diffraction and radiation damping, and the wave drift (module
    docstring). water (2,) receives the incident wave's horizontal particle velocity (north, east,
    m/s) at the body origin, at the strips' mean depth below the hull as it heaves: the water the
    horizontal model sees the hull move through, so that a small hull rides the orbits and drifts
    with their Stokes drift [Stokes-1847]. Returns the body-frame drift force (X, Y, N) for the record."""
    water[0] = 0.0
    water[1] = 0.0
    if p[_ON] == 0.0:
        return 0.0, 0.0, 0.0
    nv, nf, nc, ns, nd = int(p[_NV]), int(p[_NF]), int(p[_NC]), int(p[_NS]), int(p[_ND])
    o_v = HEADER
    o_f = o_v + 3 * nv
    o_c = o_f + 3 * nf
    o_w = o_c + 6 * nc
    o_dc = o_w + 7 * nc
    o_s = o_dc + nc
    o_d = o_s + 6 * ns
    q0, q1, q2, q3, q4, q5 = (int(p[_QADR]), int(p[_QADR + 1]), int(p[_QADR + 2]), int(p[_QADR + 3]),
                              int(p[_QADR + 4]), int(p[_QADR + 5]))
    x, y, z = qpos[q0], qpos[q1], qpos[q2]
    psi, theta, phi = qpos[q3], qpos[q4], qpos[q5]
    d0, d1, d2, d3, d4, d5 = (int(p[_DADR]), int(p[_DADR + 1]), int(p[_DADR + 2]), int(p[_DADR + 3]),
                              int(p[_DADR + 4]), int(p[_DADR + 5]))
    R = rotation(psi, theta, phi)
    cpsi, spsi = np.cos(psi), np.sin(psi)
    verts = p[o_v:o_f].reshape((nv, 3))
    faces = p[o_f:o_c].reshape((nf, 3))
    nx, ny = int(p[_NX]), int(p[_NY])
    waves_on = nc > 0 and p[_FK] != 0.0
    dx, dy = p[_DX], p[_DY]
    ox = x + cpsi * p[_GX0] - spsi * p[_GY0]
    oy = y + spsi * p[_GX0] + cpsi * p[_GY0]
    if nc > 0:
        fields = np.empty((7, nx * ny))
        phase = np.empty((2, nc))
        comps = p[o_c:o_w].reshape((nc, 6))
        weights = p[o_w:o_dc].reshape((7, nc))
        waves.grid_fields(comps, weights, t, ox, oy, cpsi, spsi, dx, dy, nx, ny, fields, phase, int(p[_I0]),
                          int(p[_J0]))
        # at the strip depth below the heaving hull: the orbits a surface-following body rides
        heave = z - p[_ZREST]
        wn_ = 0.0
        we_ = 0.0
        for i in range(nc):
            e = -weights[4, i] * np.exp(-comps[i, 2] * heave) * phase[0, i]
            wn_ += e * comps[i, 3]
            we_ += e * comps[i, 4]
        water[0] = wn_
        water[1] = we_
    else:
        fields = np.zeros((7, 1))
        phase = np.zeros((2, 1))
        water[0] = 0.0
        water[1] = 0.0
    work = np.empty((nv, 5))
    load = np.zeros(6)
    _pressure(verts, faces, x, y, z, R, fields, ox, oy, cpsi, spsi, dx, dy, nx if waves_on else 0, ny,
              p[_ZH], p[_RHOG], work, load)
    fx, fy, fz, mx, my, mz = load[0], load[1], load[2], load[3], load[4], load[5]
    # angular velocity (NED) from the joint rates, ψ̇ e_z + θ̇ Rz(ψ) e_y + φ̇ R e_x: its horizontal part
    wth, wphi = qvel[d4], qvel[d5]
    wx_ = -spsi * wth + R[0, 0] * wphi
    wy_ = cpsi * wth + R[1, 0] * wphi
    vz = qvel[d2]
    diff_on = nc > 0 and p[_DIFF] != 0.0
    damp_on = p[_DAMP] != 0.0
    if diff_on or damp_on:
        for k in range(ns):
            sx, sy = p[o_s + 6 * k], p[o_s + 6 * k + 1]
            a33, b33 = p[o_s + 6 * k + 2], p[o_s + 6 * k + 3]
            rx = R[0, 0] * sx + R[0, 1] * sy
            ry = R[1, 0] * sx + R[1, 1] * sy
            rz = R[2, 0] * sx + R[2, 1] * sy
            az = 0.0
            wz = 0.0
            an = 0.0
            ae = 0.0
            if nc > 0:
                wxg, wyg = ox - x, oy - y
                gx = cpsi * (rx - wxg) + spsi * (ry - wyg)
                gy = -spsi * (rx - wxg) + cpsi * (ry - wyg)
                q, ux, uy = waves.cell(gx, gy, dx, dy, nx, ny)
                az = waves.bilinear(fields, 3, q, ux, uy, nx)
                wz = waves.bilinear(fields, 4, q, ux, uy, nx)
                an = waves.bilinear(fields, 5, q, ux, uy, nx)
                ae = waves.bilinear(fields, 6, q, ux, uy, nx)
            f_n = 0.0
            f_e = 0.0
            f_d = 0.0
            if diff_on:
                f_d += a33 * az
                ax_b = cpsi * an + spsi * ae
                ay_b = -spsi * an + cpsi * ae
                xb = -p[_XU] * p[o_s + 6 * k + 4] * ax_b
                yb = -p[_YV] * p[o_s + 6 * k + 5] * ay_b
                f_n += cpsi * xb - spsi * yb
                f_e += spsi * xb + cpsi * yb
            if damp_on:
                vpz = vz + wx_ * ry - wy_ * rx  # NED z of v + ω × r
                f_d -= b33 * (vpz - wz)
            fx += f_n
            fy += f_e
            fz += f_d
            mx += ry * f_d - rz * f_e
            my += rz * f_n - rx * f_d
            mz += rx * f_e - ry * f_n
    dx_b = 0.0
    dy_b = 0.0
    dn_b = 0.0
    if nc > 0 and p[_DRIFT] != 0.0:
        comps = p[o_c:o_w].reshape((nc, 6))
        step = 2.0 * np.pi / nd
        acc = np.zeros(12)  # per DOF: Σ⁺ (re, im), Σ⁻ (re, im)
        for i in range(nc):
            rel = np.arctan2(comps[i, 4], comps[i, 3]) - psi
            u = (rel % (2.0 * np.pi)) / step
            j = int(u) % nd
            j1 = (j + 1) % nd
            f = u - int(u)
            for dof in range(3):
                tc = p[o_dc + i] * ((1.0 - f) * p[o_d + 3 * j + dof] + f * p[o_d + 3 * j1 + dof])
                if tc > 0.0:
                    s = comps[i, 0] * np.sqrt(tc)
                    acc[4 * dof] += s * phase[0, i]
                    acc[4 * dof + 1] += s * phase[1, i]
                elif tc < 0.0:
                    s = comps[i, 0] * np.sqrt(-tc)
                    acc[4 * dof + 2] += s * phase[0, i]
                    acc[4 * dof + 3] += s * phase[1, i]
        dx_b = acc[0] ** 2 + acc[1] ** 2 - acc[2] ** 2 - acc[3] ** 2
        dy_b = acc[4] ** 2 + acc[5] ** 2 - acc[6] ** 2 - acc[7] ** 2
        dn_b = acc[8] ** 2 + acc[9] ** 2 - acc[10] ** 2 - acc[11] ** 2
        fx += cpsi * dx_b - spsi * dy_b
        fy += spsi * dx_b + cpsi * dy_b
        mz += dn_b
    out[d0] += fx
    out[d1] += fy
    out[d2] += fz
    out[d3] += mz
    out[d4] += -spsi * mx + cpsi * my
    out[d5] += R[0, 0] * mx + R[1, 0] * my + R[2, 0] * mz
    return dx_b, dy_b, dn_b


def site_ned(eta: np.ndarray, down_m, pitch_rad, roll_rad, site_body_m: np.ndarray):
    """(north, east, down) m of a body site (FRD, m from the body origin, e.g. a GNSS antenna on a
    mast) on a 6-DOF hull: p + Rz(ψ) Ry(θ) Rx(φ) r, for arrays of states (η rows, heave, pitch, roll)."""
    eta = np.asarray(eta, float)
    psi, th, ph = eta[:, 2], np.asarray(pitch_rad, float), np.asarray(roll_rad, float)
    x, y, z = (float(c) for c in site_body_m)
    cp, sp, ct, st, cf, sf = np.cos(psi), np.sin(psi), np.cos(th), np.sin(th), np.cos(ph), np.sin(ph)
    n = cp * ct * x + (-sp * cf + cp * st * sf) * y + (sp * sf + cp * cf * st) * z
    e = sp * ct * x + (cp * cf + sf * st * sp) * y + (-cp * sf + st * sp * cf) * z
    d = -st * x + ct * sf * y + ct * cf * z
    return eta[:, 0] + n, eta[:, 1] + e, np.asarray(down_m, float) + d


# ---------------------------------------------------------------- a sea's mean load, known (3-DOF)

KNOWN_HEADINGS = 8  # waves from every 45° off the bow
KNOWN_SPEEDS = 6  # at most this many speeds through the water
KNOWN_SIZE = 3 + KNOWN_SPEEDS + KNOWN_HEADINGS * KNOWN_SPEEDS * 3


def pack_known_load(from_rad: float, speeds_m_s, load) -> np.ndarray:
    """The block `known_load` reads: on, the waves' mean direction (from, rad, NED), the number of
    speeds, the speeds (m/s, rising, padded) and the mean load (X, Y N; N N m, body frame) per
    heading of the waves off the bow (0, 45°, ... clockwise: 90° from starboard) and speed; `load`
    (KNOWN_HEADINGS, n, 3)."""
    speeds = np.asarray(speeds_m_s, float)
    load = np.asarray(load, float)
    n = len(speeds)
    if not 1 <= n <= KNOWN_SPEEDS or load.shape != (KNOWN_HEADINGS, n, 3) or np.any(np.diff(speeds) <= 0):
        raise ValueError(f"a known load needs 1-{KNOWN_SPEEDS} rising speeds and a ({KNOWN_HEADINGS}, n, 3) table")
    out = np.zeros(KNOWN_SIZE)
    out[0], out[1], out[2] = 1.0, from_rad, n
    out[3:3 + n] = speeds
    table = np.zeros((KNOWN_HEADINGS, KNOWN_SPEEDS, 3))
    table[:, :n] = load
    out[3 + KNOWN_SPEEDS:] = table.ravel()
    return out


def known_table(block) -> tuple[np.ndarray, np.ndarray]:
    """(speeds m/s, load (KNOWN_HEADINGS, speeds, 3)) of a `pack_known_load` block."""
    block = np.asarray(block, float)
    n = int(block[2])
    table = block[3 + KNOWN_SPEEDS:].reshape(KNOWN_HEADINGS, KNOWN_SPEEDS, 3)[:, :n]
    return block[3:3 + n].copy(), table.copy()


@njit(cache=True)
def known_load(block, psi, u_r, at=0):
    """The sea's mean load on surge, sway and yaw (body frame) of a hull heading ψ at u_r through the
    water, from the block of `pack_known_load` starting at block[at]: linear in the waves' heading
    off the bow and in the speed (held at the ends; astern as at rest)."""
    if block.shape[0] < at + KNOWN_SIZE or block[at] == 0.0:
        return 0.0, 0.0, 0.0
    n = int(block[at + 2])
    rel = (block[at + 1] - psi) % (2.0 * np.pi)
    h = rel / (2.0 * np.pi / KNOWN_HEADINGS)
    j0 = int(h) % KNOWN_HEADINGS
    j1 = (j0 + 1) % KNOWN_HEADINGS
    fh = h - int(h)
    k0, k1, fs = 0, 0, 0.0
    if n > 1 and u_r > block[at + 3]:
        k0 = n - 1
        k1 = n - 1
        for k in range(n - 1):
            if u_r <= block[at + 4 + k]:
                k0, k1 = k, k + 1
                fs = (u_r - block[at + 3 + k]) / (block[at + 4 + k] - block[at + 3 + k])
                break
    base = at + 3 + KNOWN_SPEEDS
    a0 = base + (j0 * KNOWN_SPEEDS + k0) * 3
    a1 = base + (j0 * KNOWN_SPEEDS + k1) * 3
    b0 = base + (j1 * KNOWN_SPEEDS + k0) * 3
    b1 = base + (j1 * KNOWN_SPEEDS + k1) * 3
    x = (1.0 - fh) * ((1.0 - fs) * block[a0] + fs * block[a1]) + fh * ((1.0 - fs) * block[b0] + fs * block[b1])
    y = (1.0 - fh) * ((1.0 - fs) * block[a0 + 1] + fs * block[a1 + 1]) + fh * ((1.0 - fs) * block[b0 + 1]
                                                                               + fs * block[b1 + 1])
    z = (1.0 - fh) * ((1.0 - fs) * block[a0 + 2] + fs * block[a1 + 2]) + fh * ((1.0 - fs) * block[b0 + 2]
                                                                               + fs * block[b1 + 2])
    return x, y, z
