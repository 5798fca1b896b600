#!/usr/bin/env python3
"""Generate the hull meshes in twin/assets/ reproducibly (trimesh).

Yellowfish: each fibreglass hull is 128 × 25.5 × 30 cm [Yellowfish-TR §II-A].
BlueBoat: 120 × 23 × 25 cm per hull, an approximation of Blue Robotics'
published 1.2 m length (the hull lines are not published). The shape is a
simple catamaran demihull: superelliptic sections (exponent 4: flat deck, full
bilge), constant breadth aft of midships with a transom stern, breadth and
depth tapering to a raked bow. Body frame FRD (x forward, y starboard, z down);
the mesh origin is the bounding-box centre in x and y and the design
waterline in z (Yellowfish: deck at z = −0.25 m, keel at z = +0.05 m).

The hull lines are assumed; the mass distribution is not (the Yellowfish's is published: hulls of
uniform density with their centroids at x_hull, the rest at x_box [Yellowfish-TR Tables III-IV]).
A keel that only rises towards the bow puts the centre of buoyancy at the flotation draft far aft
of the centre of gravity, and the boat would float bow down. So the keel also rises over the aft
55 % of the length (a rocker, quadratic towards the transom, mirroring the bow's taper), by the
amount that puts the centre of buoyancy at the nominal mass's flotation over the centre of
gravity (bisection, 60 halvings): the vessel floats level, its published centre of gravity and
hull centroid where its sources put them. The MJCF places each hull at x_hull − (the mesh's
centroid), which this script prints.

Esso Osaka 3 m model (a single hull, full form) from its principal particulars: L_pp 3.0 m,
B 0.489 m, draft d 0.201 m, block coefficient C_b 0.830 [ESSO-FRT]. Sections are
superellipses (exponent 10: flat bottom and sides, a small bilge radius; midship coefficient
0.986) about the waterline, with a flat keel at the draft and a freeboard of 0.10 m (visual only:
the depth is not published); the waterline has a parallel middle body, an elliptic bow and a
parabolic run aft 1/0.6 times as long as the bow's. The run lengths are solved (bisection) so
that the mesh's displaced volume below the design waterline z = 0 is exactly C_b·L·B·d. The mesh
origin is midship on the waterline, the twin's body origin for this ship (MMG convention).

Run:  python scripts/make_hull_meshes.py   (writes twin/assets/<vessel>_hull_port.stl,
twin/assets/<vessel>_hull_starboard.stl and twin/assets/esso_osaka_hull.stl; identical output
on every run)
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
BOW_RISE, STERN_RUN = 0.55, 0.55  # keel rise at the bow (share of the depth); aft share of the length with rocker


def _mass_distribution(vessel: str) -> tuple[float, float, float]:
    """(total mass kg, x of the centre of gravity m, x of each hull's centroid m) of the nominal case:
    the Yellowfish's from [Yellowfish-TR] Tables III-IV (eq. 17), the BlueBoat's as blueboat.xml
    assumes it (hulls, frame and battery all centred on x = 0)."""
    if vessel == "yellowfish":
        from twin.references import YELLOWFISH_TR as S

        m_hull, m_box = S["m_hull_kg"]["nominal"], S["m_box_kg"]["nominal"]
        x_hull, x_box = S["x_hull_mm"]["nominal"] / 1e3, S["x_box_mm"]["nominal"] / 1e3
        mass = 2 * m_hull + m_box
        return mass, (2 * m_hull * x_hull + m_box * x_box) / mass, x_hull
    return 15.0, 0.0, 0.0
ASSETS = Path(__file__).resolve().parent.parent / "twin" / "assets"
SHIPS = {  # L_pp, B, draft, C_b, freeboard (m)
    "esso_osaka": (3.0, 0.489, 0.201, 0.830, 0.10),
}
SHIP_STATIONS, SHIP_RING_POINTS, SHIP_EXPONENT, BOW_TO_STERN_RUN, END_WIDTH = 121, 64, 10.0, 0.6, 0.02


def _section_scale(x_m: np.ndarray, length_m: float, stern_rise: float) -> tuple[np.ndarray, np.ndarray]:
    """Relative half-breadth and keel depth along the hull (1 amidships)."""
    s = (x_m + length_m / 2) / length_m  # 0 at transom, 1 at bow
    taper = np.clip((s - 0.45) / 0.55, 0.0, 1.0)
    rocker = np.clip((STERN_RUN - s) / STERN_RUN, 0.0, 1.0)
    breadth = np.sqrt(np.clip(1.0 - taper**2, 0.0, 1.0)) * 0.96 + 0.04
    depth = 1.0 - BOW_RISE * taper**2 - stern_rise * rocker**2  # keel rises towards the raked bow and the transom
    return breadth, depth


def hull_mesh(vessel: str = "yellowfish", stern_rise: float | None = None) -> trimesh.Trimesh:
    """The demihull; `stern_rise` (share of the depth the keel rises at the transom) by default the
    one that floats the vessel level (`level_stern_rise`)."""
    if stern_rise is None:
        stern_rise = level_stern_rise(vessel)
    length_m, breadth_m, deck_z_m, keel_z_m = HULLS[vessel]
    xs = np.linspace(-length_m / 2, length_m / 2, STATIONS)
    breadth, depth = _section_scale(xs, length_m, stern_rise)
    theta = np.linspace(0.0, 2 * np.pi, RING_POINTS, endpoint=False)
    c, s = np.cos(theta), np.sin(theta)
    ring_y = np.sign(c) * np.abs(c) ** (2 / EXPONENT)
    ring_z = np.sign(s) * np.abs(s) ** (2 / EXPONENT)
    rings = []
    for i, x in enumerate(xs):
        keel = deck_z_m + (keel_z_m - deck_z_m) * depth[i]
        zc, half_h = 0.5 * (deck_z_m + keel), 0.5 * (keel - deck_z_m)
        rings.append(np.array([(x, 0.5 * breadth_m * breadth[i] * y, zc + half_h * z) for y, z in zip(ring_y, ring_z)]))
    return _closed_mesh(rings, RING_POINTS)


def buoyancy_offset_m(vessel: str, mesh: trimesh.Trimesh) -> float:
    """x of the centre of buoyancy minus x of the centre of gravity (m) of the vessel's two hulls,
    each placed with its centroid at x_hull, floating the nominal mass level."""
    from twin.physics.hydrostatics import submerged_volume, waterline_for_mass

    mass, x_g, x_hull = _mass_distribution(vessel)
    v = np.asarray(mesh.vertices) + [x_hull - mesh.center_mass[0], 0.0, 0.0]
    f = np.asarray(mesh.faces)
    z_w = waterline_for_mass([(v, f)], mass / 2)["waterline_z_m"]  # each hull floats half
    return float(submerged_volume(v, f, z_w)[1][0] - x_g)


def level_stern_rise(vessel: str) -> float:
    """The keel's rise at the transom (share of the depth) that floats the vessel level (bisection,
    60 halvings): more rise, less buoyancy aft."""
    lo, hi = 0.0, 0.9
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if buoyancy_offset_m(vessel, hull_mesh(vessel, mid)) < 0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _closed_mesh(stations: list[np.ndarray], ring_points: int) -> trimesh.Trimesh:
    """Rings of vertices (one per station, aft to fore) joined into a closed surface with end caps."""
    vertices = [tuple(p) for ring in stations for p in ring]
    n, faces = ring_points, []
    for i in range(len(stations) - 1):
        for j in range(n):
            a, b = i * n + j, i * n + (j + 1) % n
            faces += [(a, b, b + n), (a, b + n, a + n)]
    for end, station in (("stern", 0), ("bow", len(stations) - 1)):
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


def _waterline_halfbreadth(s: np.ndarray, stern_run: float) -> np.ndarray:
    """Relative half-breadth along the ship, s = 2x/L in [−1, 1]: 1 on the parallel middle body, an
    ellipse over the bow run, a parabola over the stern run (both in units of s), END_WIDTH at the ends."""
    bow_run = BOW_TO_STERN_RUN * stern_run
    t_bow = np.clip((s - (1 - bow_run)) / bow_run, 0.0, 1.0)
    t_stern = np.clip(((-1 + stern_run) - s) / stern_run, 0.0, 1.0)
    w = np.sqrt(1 - t_bow**2) * (1 - t_stern**2)
    return np.maximum(w, END_WIDTH)


def ship_mesh(vessel: str, stern_run: float) -> trimesh.Trimesh:
    length_m, breadth_m, draft_m, _, freeboard_m = SHIPS[vessel]
    xs = np.linspace(-length_m / 2, length_m / 2, SHIP_STATIONS)
    half = 0.5 * breadth_m * _waterline_halfbreadth(2 * xs / length_m, stern_run)
    theta = np.linspace(0.0, 2 * np.pi, SHIP_RING_POINTS, endpoint=False)
    c, s = np.cos(theta), np.sin(theta)
    ring_y = np.sign(c) * np.abs(c) ** (2 / SHIP_EXPONENT)
    ring_z = np.sign(s) * np.abs(s) ** (2 / SHIP_EXPONENT)
    depth = np.where(ring_z > 0, draft_m, freeboard_m)  # z down: keel below, deck above the waterline
    return _closed_mesh([np.column_stack([np.full(len(theta), x), b * ring_y, depth * ring_z])
                         for x, b in zip(xs, half)], SHIP_RING_POINTS)


def block_coefficient(vessel: str, mesh: trimesh.Trimesh) -> float:
    from twin.physics.hydrostatics import submerged_volume

    length_m, breadth_m, draft_m, _, _ = SHIPS[vessel]
    return submerged_volume(mesh.vertices, mesh.faces, 0.0)[0] / (length_m * breadth_m * draft_m)


def ship_hull(vessel: str) -> trimesh.Trimesh:
    """The ship's mesh with the run lengths that give its block coefficient (bisection, 60 halvings)."""
    target = SHIPS[vessel][3]
    lo, hi = 0.05, 1.0  # stern run in units of s: a longer run, a finer hull
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if block_coefficient(vessel, ship_mesh(vessel, mid)) > target:
            lo = mid
        else:
            hi = mid
    return ship_mesh(vessel, 0.5 * (lo + hi))


def _write_stl(mesh: trimesh.Trimesh, out: Path) -> None:
    tmp = out.with_suffix(".stl.tmp")
    tmp.write_bytes(trimesh.exchange.stl.export_stl(mesh))
    tmp.replace(out)


def main() -> int:
    ASSETS.mkdir(exist_ok=True)
    for vessel in HULLS:
        rise = level_stern_rise(vessel)
        mesh = hull_mesh(vessel, rise)
        for side in ("port", "starboard"):
            _write_stl(mesh, ASSETS / f"{vessel}_hull_{side}.stl")
        ext = mesh.bounds[1] - mesh.bounds[0]
        x_hull = _mass_distribution(vessel)[2]
        print(f"{vessel} hull: {ext[0]:.3f} x {ext[1]:.3f} x {ext[2]:.3f} m, volume {mesh.volume * 1e3:.2f} L, "
              f"centroid x {mesh.center_mass[0] * 1e3:+.2f} mm, watertight {mesh.is_watertight}; keel rise at the "
              f"transom {rise:.4f} of the depth, centre of buoyancy {buoyancy_offset_m(vessel, mesh) * 1e3:+.4f} mm "
              f"from the centre of gravity; MJCF hull body x = {x_hull - mesh.center_mass[0]:.5f} m")
    for vessel in SHIPS:
        mesh = ship_hull(vessel)
        _write_stl(mesh, ASSETS / f"{vessel}_hull.stl")
        ext = mesh.bounds[1] - mesh.bounds[0]
        print(f"{vessel} hull: {ext[0]:.3f} x {ext[1]:.3f} x {ext[2]:.3f} m, C_b {block_coefficient(vessel, mesh):.4f} "
              f"at the design draft, watertight {mesh.is_watertight}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
