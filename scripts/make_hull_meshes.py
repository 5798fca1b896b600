#!/usr/bin/env python3
"""Generate the Yellowfish hull meshes in assets/ reproducibly (trimesh).

Each fibreglass hull is 128 × 25.5 × 30 cm (seed 000 §II-A). The shape is a
simple catamaran demihull: superelliptic sections (exponent 4: flat deck, full
bilge), constant breadth aft of midships with a transom stern, breadth and
depth tapering to a raked bow. Body frame FRD (x forward, y starboard, z down);
the mesh origin is the bounding-box centre in x and y and the design
waterline in z (deck at z = −0.25 m, keel at z = +0.05 m).

Run:  python scripts/make_hull_meshes.py   (writes assets/hull_port.stl and
assets/hull_starboard.stl; identical output on every run)
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import trimesh

LENGTH_M, BREADTH_M, HEIGHT_M = 1.28, 0.255, 0.30
DECK_Z_M, KEEL_Z_M = -0.25, 0.05
STATIONS, RING_POINTS, EXPONENT = 65, 48, 4.0
ASSETS = Path(__file__).resolve().parent.parent / "assets"


def _section_scale(x_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Relative half-breadth and keel depth along the hull (1 amidships)."""
    s = (x_m + LENGTH_M / 2) / LENGTH_M  # 0 at transom, 1 at bow
    taper = np.clip((s - 0.45) / 0.55, 0.0, 1.0)
    breadth = np.sqrt(np.clip(1.0 - taper**2, 0.0, 1.0)) * 0.96 + 0.04
    depth = 1.0 - 0.55 * taper**2  # keel rises towards the raked bow
    return breadth, depth


def hull_mesh() -> trimesh.Trimesh:
    xs = np.linspace(-LENGTH_M / 2, LENGTH_M / 2, STATIONS)
    breadth, depth = _section_scale(xs)
    theta = np.linspace(0.0, 2 * np.pi, RING_POINTS, endpoint=False)
    c, s = np.cos(theta), np.sin(theta)
    ring_y = np.sign(c) * np.abs(c) ** (2 / EXPONENT)
    ring_z = np.sign(s) * np.abs(s) ** (2 / EXPONENT)
    vertices, faces = [], []
    for i, x in enumerate(xs):
        keel = DECK_Z_M + (KEEL_Z_M - DECK_Z_M) * depth[i]
        zc, half_h = 0.5 * (DECK_Z_M + keel), 0.5 * (keel - DECK_Z_M)
        for y, z in zip(ring_y, ring_z):
            vertices.append((x, 0.5 * BREADTH_M * breadth[i] * y, zc + half_h * z))
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
    mesh = hull_mesh()
    for side in ("port", "starboard"):
        out = ASSETS / f"hull_{side}.stl"
        tmp = out.with_suffix(".stl.tmp")
        tmp.write_bytes(trimesh.exchange.stl.export_stl(mesh))
        tmp.replace(out)
    ext = mesh.bounds[1] - mesh.bounds[0]
    print(f"hull: {ext[0]:.3f} x {ext[1]:.3f} x {ext[2]:.3f} m, volume {mesh.volume * 1e3:.2f} L, "
          f"centroid x {mesh.center_mass[0] * 1e3:+.2f} mm, watertight {mesh.is_watertight}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
