"""Write runs to the format their file extension names: the recording formats
(.csv, .mcap, .tlog, .bin: twin.formats) and rerun's .rrd (twin.viz), which shows
several runs on one timeline."""
from __future__ import annotations

from pathlib import Path

import mujoco

from .errors import TwinError
from .files import RRD_RUN, RRD_VIEW
from .formats import RUN_FORMATS, write_run
from .run import Run

FORMATS = RUN_FORMATS + (".rrd",)


def mesh_placements(mjcf: Path) -> dict[Path, tuple[float, float, float]]:
    """Each mesh file of the MJCF with the body-frame offset of the geom that uses it."""
    spec = mujoco.MjSpec.from_file(str(mjcf))
    meshdir = mjcf.parent / (spec.meshdir or "")
    files = {m.name: meshdir / m.file for m in spec.meshes}
    out = {}
    for geom in spec.geoms:
        if geom.type == mujoco.mjtGeom.mjGEOM_MESH and geom.meshname in files:
            body = geom.parent
            out[files[geom.meshname]] = tuple(float(a + b) for a, b in zip(body.pos, geom.pos))
    return out


def write(runs: dict[str, Run], path: Path, *, geometry=None, vessel_name: str = "",
          mjcf: Path | None = None, origin: tuple[float, float] | None = None, view: bool = False) -> None:
    """The first run goes to .csv/.mcap/.tlog/.bin; every run goes to .rrd on one timeline.

    view: the .rrd is a report's view of runs (`RRD_VIEW`), not runs recorded (`RRD_RUN`); a
    report may then be written over the one but not over the other (`twin.cli.app.kept_data`)."""
    suffix = path.suffix.lower()
    if suffix == ".rrd":
        # late: twin.viz.rerun_log brings rerun (0.23 s), only for an .rrd
        from .viz.rerun_log import write_runs_rrd

        write_runs_rrd(runs, path, geometry=geometry, hull_mesh_paths=mesh_placements(mjcf) if mjcf else None,
                       application_id=RRD_VIEW if view else RRD_RUN)
        return
    if suffix not in RUN_FORMATS:
        raise TwinError(f"output '{path}': unknown format (use {', '.join(FORMATS)})")
    antenna = (0.0, 0.0) if geometry is None else tuple(geometry.gnss_pos_m[:2])
    write_run(next(iter(runs.values())), path, antenna_body_m=antenna, vessel_name=vessel_name, origin=origin)
