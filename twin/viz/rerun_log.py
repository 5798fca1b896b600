"""Runs as one rerun recording (.rrd): hull poses on the water and time-series plots.

Entity paths, for each run name:
  world                          NED view coordinates (x north, y east, z down), static
  world/<name>/path              LineStrips3D of (x, y, 0) in m, static: one strip per stretch
                                 without a gap (gap_ends), and the plots cleared in each gap
  world/<name>/vessel            Transform3D over "time": translation (x, y, 0) m, yaw ψ about z
  world/<name>/vessel/<hull>     Mesh3D per hull mesh (body FRD, m), or a Boxes3D "hull", static
  world/<name>/vessel/sites      Points3D of thrusters, GNSS, IMU (when a Geometry is given), static
  plots/<quantity>/<name>        Scalars over "time" for u, v (m/s), r (rad/s), thrust (N), PWM (µs)
                                 or a ship's propeller speed (rps) and rudder angle (deg),
                                 the series named after the run or run.meta["series_labels"][quantity]
  world/<name>/sea               Mesh3D of the sea surface around the vessel over "time" (a 6-DOF run
                                 in waves: every SEA_EVERY_S, at most SEA_FRAMES frames), and the
                                 vessel's transform then carries its heave, roll and pitch; plots of
                                 heave (m), roll and pitch (deg)
All runs share the timeline "time" (duration, s), so runs line up in plots and in 3D.
"""
from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from ..errors import TwinError
from ..files import write_bytes_atomic
from ..formats.mcap import check_run
from ..physics.waves import elevation
from ..recording import GAP_S
from ..run import Run

TIMELINE = "time"
# hull body positions in model/yellowfish.xml (m, body FRD); other meshes sit at the body origin
BOX_SIZE_M = (1.28, 0.98, 0.3)
BOX_CENTER_M = (0.0, 0.0, -0.10)  # the hull meshes span z = -0.25 .. 0.05 m (z down)
PLOTS = ("u", "v", "r", "thrust_left", "thrust_right", "pwm_left", "pwm_right", "propeller_rps", "rudder_deg")
SIX_PLOTS = ("heave", "roll", "pitch")
SEA_EVERY_S, SEA_FRAMES, SEA_NODES, SEA_HALF_M = 0.25, 1200, 33, 4.0
PALETTE = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75)]

HullMeshes = Sequence[str | Path] | Mapping[str | Path, Sequence[float]]


def write_runs_rrd(runs: dict[str, Run], path: str | Path, *, geometry=None,
                   hull_mesh_paths: HullMeshes | None = None, application_id: str = "twin") -> None:
    """Write `runs` (name → Run) to the rerun file `path` atomically (temporary name, then rename).

    geometry: a `twin.engine.mjcf.Geometry`; its sites (m, body FRD) are drawn on each hull.
    hull_mesh_paths: mapping mesh file → offset in the body frame (m), or a list of
    mesh files already in the body frame. Without meshes a 1.28 × 0.98 × 0.3 m box is drawn.
    """
    path = Path(path)
    for name, run in runs.items():
        check_run(run, name)
    meshes = _load_meshes(hull_mesh_paths)  # fail on a bad mesh before touching the disk
    with rrd_file(path, application_id, _blueprint()) as rec:
        for i, (name, run) in enumerate(runs.items()):
            _log_run(rec, name, run, PALETTE[i % len(PALETTE)], geometry, meshes)


@contextmanager
def rrd_file(path: str | Path, application_id: str, blueprint: rrb.Blueprint) -> Iterator[rr.RecordingStream]:
    """A private recording stream (never the global one, never a viewer) saved to `path` when the
    block ends, with the NED "world" view coordinates. Logged into memory, not through rerun's file
    sink: that sink writes on its own thread and a failed write there (a full disk) is not raised,
    so its file could be truncated yet renamed over a good one. The bytes are then written as any
    output is (files.write_bytes_atomic: through a link, the old file kept on a failed write)."""
    rec = rr.RecordingStream(application_id)
    stream = rec.binary_stream()
    try:
        rec.send_blueprint(blueprint, make_active=False, make_default=True)
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_DOWN, static=True)
        yield rec
        data = stream.read(flush=True) or b""
    finally:
        rec.disconnect()
    if not data:
        raise TwinError(f"{Path(path).name}: rerun did not write the recording")
    write_bytes_atomic(path, data)


def _blueprint() -> rrb.Blueprint:
    # one plot per quantity, so the same quantity from every run shares axes
    plots = [rrb.TimeSeriesView(origin=f"plots/{q}", name=q) for q in PLOTS + SIX_PLOTS]
    return rrb.Blueprint(rrb.Horizontal(rrb.Spatial3DView(origin="world", name="water"), rrb.Grid(*plots)))


def _load_meshes(hull_mesh_paths: HullMeshes | None) -> list[tuple[str, np.ndarray, rr.Mesh3D]]:
    """(entity name, body offset in m, mesh) for each mesh file."""
    if not hull_mesh_paths:
        return []
    import trimesh  # late: 0.3 s, only needed when meshes are drawn

    if isinstance(hull_mesh_paths, Mapping):
        items = [(Path(p), np.asarray(off, dtype=float)) for p, off in hull_mesh_paths.items()]
    else:
        items = [(Path(p), np.zeros(3)) for p in hull_mesh_paths]
    out = []
    for p, offset in items:
        try:
            m = trimesh.load(p, force="mesh")
        except Exception as exc:  # trimesh raises many types for missing or malformed files
            raise TwinError(f"{p.name}: cannot load hull mesh ({exc})") from None
        if len(m.faces) == 0:
            raise TwinError(f"{p.name}: hull mesh has no triangles")
        mesh = rr.Mesh3D(vertex_positions=m.vertices, triangle_indices=m.faces,
                         vertex_normals=m.vertex_normals, albedo_factor=(242, 204, 26, 255))
        out.append((rr.escape_entity_path_part(p.stem), offset, mesh))
    return out


def gap_ends(t: np.ndarray) -> np.ndarray:
    """Indices i after which a run's samples stop for longer than GAP_S and five sample periods (the
    segments of a recording, the logs of an outing): nothing is drawn between t[i] and t[i + 1]."""
    dt = np.diff(np.asarray(t, float))
    if len(dt) == 0:
        return np.zeros(0, dtype=int)
    return np.flatnonzero(dt > max(GAP_S, 5.0 * float(np.median(dt))))


def _log_run(rec: rr.RecordingStream, name: str, run: Run, color, geometry, meshes) -> None:
    key = rr.escape_entity_path_part(name)
    times = [rr.TimeColumn(TIMELINE, duration=np.asarray(run.t, dtype=float))]
    xyz = np.column_stack([run.eta[:, 0], run.eta[:, 1], np.zeros(len(run.t))])
    breaks = gap_ends(run.t)
    strips = np.split(xyz, breaks + 1)
    rec.log(f"world/{key}/path", rr.LineStrips3D(strips, colors=[color] * len(strips), radii=[0.03] * len(strips)),
            static=True)
    six = run.meta.get("six_dof")
    if six is not None:
        xyz[:, 2] = six["down_m"]
        quat = _quaternions(run.eta[:, 2], six["pitch_rad"], six["roll_rad"])
    else:
        half = run.eta[:, 2] / 2
        quat = np.column_stack([np.zeros_like(half), np.zeros_like(half), np.sin(half), np.cos(half)])  # xyzw, yaw
    rec.send_columns(f"world/{key}/vessel", indexes=times,
                     columns=rr.Transform3D.columns(translation=xyz, quaternion=quat))
    _log_hull(rec, f"world/{key}/vessel", color, geometry, meshes)
    cols = run.columns()
    held = run.propeller_rudder()
    nothing = np.full(len(run.t), np.nan)
    cols |= {"propeller_rps": nothing if held is None else held[:, 0],
             "rudder_deg": nothing if held is None else np.rad2deg(held[:, 1])}
    if six is not None:
        cols = {**cols, "heave": np.asarray(six["down_m"]) - six["equilibrium"][0],
                "roll": np.rad2deg(six["roll_rad"]), "pitch": np.rad2deg(six["pitch_rad"])}
        if six.get("components") is not None:
            _log_sea(rec, f"world/{key}/sea", run, six["components"])
    for q in PLOTS + (SIX_PLOTS if six is not None else ()):
        if np.all(np.isnan(cols[q])):
            continue  # e.g. PWM of a thrust-driven run, a ship's propeller beside a PWM boat's
        entity = f"plots/{q}/{key}"
        label = run.meta.get("series_labels", {}).get(q, name)  # e.g. a thrust that was derived, not measured
        rec.log(entity, rr.SeriesLines(colors=[color], names=[label]), static=True)
        rec.send_columns(entity, indexes=times, columns=rr.Scalars.columns(scalars=cols[q]))
        for i in breaks:  # a plot draws a hole where its entity is cleared (rerun's Clear archetype)
            rec.set_time(TIMELINE, duration=float(0.5 * (run.t[i] + run.t[i + 1])))
            rec.log(entity, rr.Clear(recursive=False))
    for lim in run.meta.get("limits", []):  # an input the engine bounded: said where it happened
        rec.set_time(TIMELINE, duration=float(run.t[0] + lim["first_s"]))
        rec.log(f"log/{key}", rr.TextLog(f"{lim['thruster']} thruster {lim['quantity']} requested beyond the bound "
                                         f"{lim['bound']:g} {lim['unit']} for {lim['seconds']:.2f} s (by up to "
                                         f"{abs(lim['worst_excess']):.3g} {lim['unit']})", level="WARN"))


def _quaternions(psi, theta, phi) -> np.ndarray:
    """xyzw quaternions of R = Rz(ψ) Ry(θ) Rx(φ)."""
    cy, sy = np.cos(psi / 2), np.sin(psi / 2)
    cp, sp = np.cos(np.asarray(theta) / 2), np.sin(np.asarray(theta) / 2)
    cr, sr = np.cos(np.asarray(phi) / 2), np.sin(np.asarray(phi) / 2)
    return np.column_stack([sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
                            cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy])


def _log_sea(rec: rr.RecordingStream, entity: str, run: Run, components) -> None:
    """The incident sea surface on a square around the vessel (NED, z = −ζ), every SEA_EVERY_S."""
    u = np.linspace(-SEA_HALF_M, SEA_HALF_M, SEA_NODES)
    gx, gy = np.meshgrid(u, u)
    n = SEA_NODES
    tri = [(i * n + j, i * n + j + 1, (i + 1) * n + j) for i in range(n - 1) for j in range(n - 1)]
    tri += [(i * n + j + 1, (i + 1) * n + j + 1, (i + 1) * n + j) for i in range(n - 1) for j in range(n - 1)]
    tri = np.array(tri)
    step = max(1, int(round(SEA_EVERY_S / max(float(np.median(np.diff(run.t))), 1e-9)))) if len(run.t) > 1 else 1
    start = float(run.meta.get("start_s", run.t[0]))
    for k in list(range(0, len(run.t), step))[:SEA_FRAMES]:
        x = run.eta[k, 0] + gx.ravel()
        y = run.eta[k, 1] + gy.ravel()
        z = -elevation(components, x, y, float(run.t[k]) - start)
        rec.set_time(TIMELINE, duration=float(run.t[k]))
        rec.log(entity, rr.Mesh3D(vertex_positions=np.column_stack([x, y, z]), triangle_indices=tri,
                                  albedo_factor=(40, 110, 200, 140)))


def _log_hull(rec: rr.RecordingStream, vessel: str, color, geometry, meshes) -> None:
    """Static children of the moving vessel frame, all in body FRD (m)."""
    for hull, offset, mesh in meshes:
        rec.log(f"{vessel}/{hull}", rr.Transform3D(translation=offset), mesh, static=True)
    if not meshes:
        rec.log(f"{vessel}/hull", rr.Boxes3D(sizes=[BOX_SIZE_M], centers=[BOX_CENTER_M], colors=[color]),
                static=True)
    if geometry is not None:
        sites = np.vstack([geometry.thruster_pos_m, geometry.gnss_pos_m, geometry.imu_pos_m])
        rec.log(f"{vessel}/sites", rr.Points3D(sites, radii=[0.03], colors=[color],
                                               labels=["thruster L", "thruster R", "GNSS", "IMU"]), static=True)
