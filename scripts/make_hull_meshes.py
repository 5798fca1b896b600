#!/usr/bin/env python3
"""Generate the hull meshes in twin/assets/ reproducibly (trimesh).

Yellowfish: each fibreglass hull is 128 × 25.5 × 30 cm (seed 000 §II-A).
BlueBoat: 120 × 23 × 25 cm per hull, an approximation of Blue Robotics'
published 1.2 m length (the hull lines are not published). The shape is a
simple catamaran demihull: superelliptic sections (exponent 4: flat deck, full
bilge), constant breadth aft of midships with a transom stern, breadth and
depth tapering to a raked bow. Body frame FRD (x forward, y starboard, z down);
the mesh origin is the bounding-box centre in x and y and the design
waterline in z (Yellowfish: deck at z = −0.25 m, keel at z = +0.05 m).

Run:  python scripts/make_hull_meshes.py   (writes twin/assets/<vessel>_hull_port.stl
and twin/assets/<vessel>_hull_starboard.stl; identical output on every run)
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import trimesh

HULLS = {  # length, breadth, deck z, keel z (m)
    "yellowfish": (1.28, 0.255, -0.25, 0.05),
    "blueboat": (1.20, 0.23, -0.18, 0.07),
}
STATIONS, RING_POINTS, EXPONENT = 65, 48, 4.0
ASSETS = Path(__file__).resolve().parent.parent / "twin" / "assets"


def _section_scale(x_m: np.ndarray, length_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Relative half-breadth and keel depth along the hull (1 amidships)."""
    s = (x_m + length_m / 2) / length_m  # 0 at transom, 1 at bow
    taper = np.clip((s - 0.45) / 0.55, 0.0, 1.0)
    breadth = np.sqrt(np.clip(1.0 - taper**2, 0.0, 1.0)) * 0.96 + 0.04
    depth = 1.0 - 0.55 * taper**2  # keel rises towards the raked bow
    return breadth, depth


def hull_mesh(vessel: str = "yellowfish") -> trimesh.Trimesh:
    length_m, breadth_m, deck_z_m, keel_z_m = HULLS[vessel]
    xs = np.linspace(-length_m / 2, length_m / 2, STATIONS)
    breadth, depth = _section_scale(xs, length_m)
    theta = np.linspace(0.0, 2 * np.pi, RING_POINTS, endpoint=False)
    c, s = np.cos(theta), np.sin(theta)
    ring_y = np.sign(c) * np.abs(c) ** (2 / EXPONENT)
    ring_z = np.sign(s) * np.abs(s) ** (2 / EXPONENT)
    vertices, faces = [], []
    for i, x in enumerate(xs):
        keel = deck_z_m + (keel_z_m - deck_z_m) * depth[i]
        zc, half_h = 0.5 * (deck_z_m + keel), 0.5 * (keel - deck_z_m)
        for y, z in zip(ring_y, ring_z):
            vertices.append((x, 0.5 * breadth_m * breadth[i] * y, zc + half_h * z))
    n = RING_POINTS
    for i in range(STATIONS - 1):
        for j in range(n):
            a, b = i * n + j, i * n + (j + 1) % n
            faces += [(a, b, b + n), (a, b + n, a + n)]
    for end, station in (("stern", 0), ("bow", STATIONS - 1)):
        centre = np.mean(vertices[station * n:(station + 1) * n], axis=0)
        k = len(vertices)
        vertices.append(tuple(centre))
        for j in range(n):
            a, b = station * n + j, station * n + (j + 1) % n
            faces.append((k, b, a) if end == "stern" else (k, a, b))
    mesh = trimesh.Trimesh(np.array(vertices), np.array(faces), process=True)
    trimesh.repair.fix_normals(mesh)
    if not mesh.is_watertight or mesh.volume <= 0:
        raise SystemExit("hull mesh is not a closed positive volume")
    return mesh


def main() -> int:
    ASSETS.mkdir(exist_ok=True)
    for vessel in HULLS:
        mesh = hull_mesh(vessel)
        for side in ("port", "starboard"):
            out = ASSETS / f"{vessel}_hull_{side}.stl"
            tmp = out.with_suffix(".stl.tmp")
            tmp.write_bytes(trimesh.exchange.stl.export_stl(mesh))
            tmp.replace(out)
        ext = mesh.bounds[1] - mesh.bounds[0]
        print(f"{vessel} hull: {ext[0]:.3f} x {ext[1]:.3f} x {ext[2]:.3f} m, volume {mesh.volume * 1e3:.2f} L, "
              f"centroid x {mesh.center_mass[0] * 1e3:+.2f} mm, watertight {mesh.is_watertight}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
