"""Hydrostatics of closed hull meshes: the volume below a waterline and the
waterline at which the hulls float a given mass (Archimedes).

Frames: body FRD, z down, so the submerged part is z > z_waterline. The
submerged volume is summed over the triangles clipped to that half-space as
signed tetrahedra with their apex on the waterplane; the waterplane cap then
contributes nothing, so the clipped mesh need not be closed.

`pressure_load` is the same clipping for a hull moving in six degrees of freedom under a wavy
surface: the pressure (hydrostatic plus the incident wave's, physics/waves.py) integrated over the
wetted part of the hull mesh, triangle by triangle, at every call of the engine's callback. In
calm water it is Archimedes' force and moment exactly (the pressure ρ g z over the clipped
surface, whose missing waterplane cap carries no pressure); in waves it is the Froude-Krylov load
over the instantaneous wetted surface [Faltinsen-1990], [Journee-Massie-2001].
"""
from __future__ import annotations

import numpy as np
from numba import njit
from scipy.optimize import brentq

from ..errors import TwinError
from .waves import bilinear, cell

RHO_FRESH_KG_M3 = 1000.0


def clip_triangle(tri: np.ndarray, depth: np.ndarray) -> list[np.ndarray]:
    """Part of one triangle with depth > 0, as 0, 1 or 2 triangles (vertex order kept)."""
    inside = depth > 0
    poly = []
    for i in range(3):
        j = (i + 1) % 3
        if inside[i]:
            poly.append(tri[i])
        if inside[i] != inside[j]:
            s = depth[i] / (depth[i] - depth[j])
            poly.append(tri[i] + s * (tri[j] - tri[i]))
    return [np.array([poly[0], poly[k], poly[k + 1]]) for k in range(1, len(poly) - 1)]


def submerged_volume(vertices: np.ndarray, faces: np.ndarray, z_waterline_m: float) -> tuple[float, np.ndarray]:
    """(volume m³, centre of buoyancy m) of the mesh part below the waterline."""
    tris = vertices[faces]
    depth = tris[:, :, 2] - z_waterline_m
    apex = np.array([0.0, 0.0, z_waterline_m])
    full = np.all(depth > 0, axis=1)
    cut = ~full & np.any(depth > 0, axis=1)
    pieces = [tris[full]] + [np.array(clip_triangle(t, d)) for t, d in zip(tris[cut], depth[cut])]
    pieces = [p for p in pieces if len(p)]
    if not pieces:
        return 0.0, apex.copy()
    t = np.concatenate(pieces) - apex
    vol6 = np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2]))
    volume = vol6.sum() / 6.0
    centroid = apex + (vol6[:, None] * t.sum(axis=1)).sum(axis=0) / (4.0 * vol6.sum()) if volume > 0 else apex
    return float(volume), centroid


def waterline_for_mass(meshes: list[tuple[np.ndarray, np.ndarray]], mass_kg: float,
                       rho_kg_m3: float = RHO_FRESH_KG_M3) -> dict[str, float]:
    """Waterline z (m) where the meshes displace mass_kg, with draft and waterplane extents."""
    target = mass_kg / rho_kg_m3
    z_top = min(v[:, 2].min() for v, _ in meshes)
    z_keel = max(v[:, 2].max() for v, _ in meshes)

    def excess(z):
        return sum(submerged_volume(v, f, z)[0] for v, f in meshes) - target

    if excess(z_top + 1e-9) < 0:
        most = (excess(z_top + 1e-9) + target) * rho_kg_m3
        raise TwinError(f"the hulls cannot float the vessel's {mass_kg:.6g} kg: fully submerged they displace "
                        f"{most:.4g} kg (the MJCF's masses are in kg)")
    z_w = brentq(excess, z_top + 1e-9, z_keel - 1e-9, xtol=1e-9)
    length, breadth = waterplane_extent(meshes[0][0], meshes[0][1], z_w)
    return {"waterline_z_m": z_w, "draft_m": z_keel - z_w, "displaced_volume_m3": target,
            "waterline_length_m": length, "waterline_breadth_m": breadth}


def plane_crossings(vertices: np.ndarray, faces: np.ndarray, axis: int, value: float) -> np.ndarray:
    """(n, 3) points where the mesh's edges cross the plane coordinate[axis] = value (each edge once
    per triangle that holds it)."""
    tris = vertices[faces]
    d = tris[:, :, axis] - value
    pts = []
    for a, b in ((0, 1), (1, 2), (2, 0)):
        cross = (d[:, a] > 0) != (d[:, b] > 0)
        s = d[cross, a] / (d[cross, a] - d[cross, b])
        pts.append(tris[cross, a] + s[:, None] * (tris[cross, b] - tris[cross, a]))
    return np.concatenate(pts)


def waterplane_extent(vertices: np.ndarray, faces: np.ndarray, z_m: float) -> tuple[float, float]:
    """Length and breadth (m) of one hull's section by the plane z = z_m."""
    p = plane_crossings(vertices, faces, 2, z_m)
    if len(p) == 0:
        return 0.0, 0.0
    return float(np.ptp(p[:, 0])), float(np.ptp(p[:, 1]))


# ---------------------------------------------------------------- pressure over the wetted hull (numba)


@njit(inline="always")
def _head(z, p0, p1, p2, zh):
    """Incident pressure head (m) at depth z ≥ 0 from its values at 0, zh/2 and zh (quadratic
    Lagrange interpolation in depth; the exponential decay of each component is smooth on [0, zh]),
    held at its value at zh below it: a quadratic carried on grows without bound, where the true
    head only decays further."""
    u = min(z / zh, 1.0)
    return p0 * (1.0 - u) * (1.0 - 2.0 * u) + p1 * 4.0 * u * (1.0 - u) + p2 * u * (2.0 * u - 1.0)


@njit(inline="always")
def _piece(ax, ay, az, pa, bx, by, bz, pb, cx, cy, cz, pc, out):
    """Force and moment (about the origin of the r's) of pressure linear over triangle abc, whose
    right-handed normal points out of the hull: F = −∫p n dA, M = −∫p r × n dA, added to out[0:6]."""
    sx = 0.5 * ((by - ay) * (cz - az) - (bz - az) * (cy - ay))
    sy = 0.5 * ((bz - az) * (cx - ax) - (bx - ax) * (cz - az))
    sz = 0.5 * ((bx - ax) * (cy - ay) - (by - ay) * (cx - ax))
    ps = pa + pb + pc
    out[0] -= ps * sx / 3.0
    out[1] -= ps * sy / 3.0
    out[2] -= ps * sz / 3.0
    # ∫ p r dA / A = ((Σp)(Σr) + Σ p_i r_i)/12
    qx = (ps * (ax + bx + cx) + pa * ax + pb * bx + pc * cx) / 12.0
    qy = (ps * (ay + by + cy) + pa * ay + pb * by + pc * cy) / 12.0
    qz = (ps * (az + bz + cz) + pa * az + pb * bz + pc * cz) / 12.0
    out[3] -= qy * sz - qz * sy
    out[4] -= qz * sx - qx * sz
    out[5] -= qx * sy - qy * sx


@njit(cache=True)
def pressure_load(verts, faces, px, py, pz, R, fields, ox, oy, cpsi, spsi, dx, dy, nx, ny, zh, rho_g, work, out):
    """Hydrostatic and Froude-Krylov load on a hull mesh (module docstring).

    verts (n, 3) body frame (FRD, m), faces (m, 3) with outward right-handed normals; the body at
    (px, py, pz) NED with rotation R (body → NED). fields: the wave grid of waves.grid_fields (its
    first three fields: pressure heads at depths 0, zh/2, zh), nodes at (ox, oy) + heading-frame
    steps dx, dy; an empty grid (nx = 0) is calm water. work (n, 5) scratch. out[0:6] receives
    the force (N, NED) and the moment about the body origin (N m, NED axes)."""
    for f in range(6):
        out[f] = 0.0
    nv = verts.shape[0]
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = R[0, 0], R[0, 1], R[0, 2], R[1, 0], R[1, 1], R[1, 2], R[2, 0], R[2, 1], R[2, 2]
    for v in range(nv):
        bx, by, bz = verts[v, 0], verts[v, 1], verts[v, 2]
        rx = r00 * bx + r01 * by + r02 * bz
        ry = r10 * bx + r11 * by + r12 * bz
        rz = r20 * bx + r21 * by + r22 * bz
        z = pz + rz
        p0 = 0.0
        head = 0.0
        if nx > 0:
            wx, wy = px + rx - ox, py + ry - oy
            q, ux, uy = cell(cpsi * wx + spsi * wy, -spsi * wx + cpsi * wy, dx, dy, nx, ny)
            p0 = bilinear(fields, 0, q, ux, uy, nx)
            head = p0
            if z + p0 > 0.0:  # stretched: each component's decay from the local surface [Wheeler-1970]
                head = _head(z + p0, p0, bilinear(fields, 1, q, ux, uy, nx), bilinear(fields, 2, q, ux, uy, nx), zh)
        work[v, 0] = rx
        work[v, 1] = ry
        work[v, 2] = rz
        work[v, 3] = z + p0  # depth below the local surface
        work[v, 4] = rho_g * (z + head)
    px_ = np.empty(4)
    py_ = np.empty(4)
    pz_ = np.empty(4)
    pp_ = np.empty(4)
    for t in range(faces.shape[0]):
        i, j, k = int(faces[t, 0]), int(faces[t, 1]), int(faces[t, 2])
        di, dj, dk = work[i, 3], work[j, 3], work[k, 3]
        if di <= 0.0 and dj <= 0.0 and dk <= 0.0:
            continue
        if di > 0.0 and dj > 0.0 and dk > 0.0:
            _piece(work[i, 0], work[i, 1], work[i, 2], work[i, 4], work[j, 0], work[j, 1], work[j, 2], work[j, 4],
                   work[k, 0], work[k, 1], work[k, 2], work[k, 4], out)
            continue
        # clip to the wet part: a polygon of 3 or 4 vertices (order kept), fanned from its first
        m = 0
        for e in range(3):
            a = i if e == 0 else (j if e == 1 else k)
            b = j if e == 0 else (k if e == 1 else i)
            da, db = work[a, 3], work[b, 3]
            if da > 0.0:
                px_[m] = work[a, 0]
                py_[m] = work[a, 1]
                pz_[m] = work[a, 2]
                pp_[m] = work[a, 4]
                m += 1
            if (da > 0.0) != (db > 0.0):
                s = da / (da - db)
                px_[m] = work[a, 0] + s * (work[b, 0] - work[a, 0])
                py_[m] = work[a, 1] + s * (work[b, 1] - work[a, 1])
                pz_[m] = work[a, 2] + s * (work[b, 2] - work[a, 2])
                pp_[m] = work[a, 4] + s * (work[b, 4] - work[a, 4])
                m += 1
        for q in range(1, m - 1):
            _piece(px_[0], py_[0], pz_[0], pp_[0], px_[q], py_[q], pz_[q], pp_[q],
                   px_[q + 1], py_[q + 1], pz_[q + 1], pp_[q + 1], out)
    return out


def equilibrium(meshes: list[tuple[np.ndarray, np.ndarray]], mass_kg: float, cg_m: np.ndarray,
                rho_kg_m3: float = RHO_FRESH_KG_M3) -> tuple[float, float, float]:
    """(down z of the body origin m, trim θ rad, heel φ rad) at which the meshes float mass_kg with
    its centre of gravity cg_m (body frame) in calm water: displaced mass equal to the mass, and the
    centre of buoyancy on the vertical through the centre of gravity. Newton's method on the
    clipped volumes (finite-difference Jacobian), from the level waterline; converged to 1e-10 m."""
    level = waterline_for_mass(meshes, mass_kg, rho_kg_m3)
    x = np.array([-level["waterline_z_m"], 0.0, 0.0])
    target = mass_kg / rho_kg_m3

    def residual(q):
        z, th, ph = q
        ct, st, cf, sf = np.cos(th), np.sin(th), np.cos(ph), np.sin(ph)
        R = np.array([[ct, st * sf, st * cf], [0.0, cf, -sf], [-st, ct * sf, ct * cf]])  # Ry(θ) Rx(φ)
        vol, mom = 0.0, np.zeros(3)
        for v, f in meshes:
            vv, c = submerged_volume(v @ R.T + [0.0, 0.0, z], f, 0.0)
            vol += vv
            mom += vv * c
        b = mom / vol if vol > 0 else mom
        g = R @ np.asarray(cg_m, float) + [0.0, 0.0, z]
        return np.array([(vol - target) / target, b[0] - g[0], b[1] - g[1]])

    for _ in range(30):
        r = residual(x)
        if np.max(np.abs(r)) < 1e-11:
            break
        J = np.empty((3, 3))
        for i, h in enumerate((1e-6, 1e-6, 1e-6)):
            dq = np.zeros(3)
            dq[i] = h
            J[:, i] = (residual(x + dq) - residual(x - dq)) / (2 * h)
        x = x - np.linalg.solve(J, r)
    return float(x[0]), float(x[1]), float(x[2])
