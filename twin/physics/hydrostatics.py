"""Hydrostatics of closed hull meshes: the volume below a waterline and the
waterline at which the hulls float a given mass (Archimedes).

Frames: body FRD, z down, so the submerged part is z > z_waterline. The
submerged volume is summed over the triangles clipped to that half-space as
signed tetrahedra with their apex on the waterplane; the waterplane cap then
contributes nothing, so the clipped mesh need not be closed.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

RHO_FRESH_KG_M3 = 1000.0


def _clip_triangle(tri: np.ndarray, depth: np.ndarray) -> list[np.ndarray]:
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
    pieces = [tris[full]] + [np.array(_clip_triangle(t, d)) for t, d in zip(tris[cut], depth[cut])]
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
        raise ValueError(f"the hulls cannot float {mass_kg:.2f} kg: fully submerged volume is too small")
    z_w = brentq(excess, z_top + 1e-9, z_keel - 1e-9, xtol=1e-9)
    length, breadth = waterplane_extent(meshes[0][0], meshes[0][1], z_w)
    return {"waterline_z_m": z_w, "draft_m": z_keel - z_w, "displaced_volume_m3": target,
            "waterline_length_m": length, "waterline_breadth_m": breadth}


def waterplane_extent(vertices: np.ndarray, faces: np.ndarray, z_m: float) -> tuple[float, float]:
    """Length and breadth (m) of one hull's section by the plane z = z_m."""
    tris = vertices[faces]
    d = tris[:, :, 2] - z_m
    pts = []
    for a, b in ((0, 1), (1, 2), (2, 0)):
        cross = (d[:, a] > 0) != (d[:, b] > 0)
        s = d[cross, a] / (d[cross, a] - d[cross, b])
        pts.append(tris[cross, a] + s[:, None] * (tris[cross, b] - tris[cross, a]))
    p = np.concatenate(pts)
    if len(p) == 0:
        return 0.0, 0.0
    return float(np.ptp(p[:, 0])), float(np.ptp(p[:, 1]))
