"""Write runs to the format their file extension names: .csv, .mcap, .rrd."""
from __future__ import annotations

from pathlib import Path

from .errors import TwinError
from .run import Run
from .vessel import write_text_atomic

FORMATS = (".csv", ".mcap", ".rrd", ".tlog", ".bin")


def check_paths(paths: list[Path]) -> None:
    """Refuse unknown extensions and missing folders before any work is done."""
    for p in paths:
        if p.suffix.lower() not in FORMATS:
            raise TwinError(f"output '{p}': unknown format (use {', '.join(FORMATS)})")
        if not p.parent.exists():
            raise TwinError(f"output '{p}': folder '{p.parent}' does not exist")


def mesh_placements(mjcf: Path) -> dict[Path, tuple[float, float, float]]:
    """Each mesh file of the MJCF with the body-frame offset of the geom that uses it."""
    import mujoco

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
          mjcf: Path | None = None) -> None:
    """The first run goes to .csv/.mcap/.tlog/.bin; every run goes to .rrd on one timeline."""
    suffix = path.suffix.lower()
    first = next(iter(runs.values()))
    if suffix == ".csv":
        write_text_atomic(path, first.to_csv_text())
    elif suffix == ".mcap":
        from .viz.mcap_io import write_run_mcap

        write_run_mcap(first, path, vessel_name)
    elif suffix == ".tlog":
        from .viz.tlog_io import write_run_tlog

        antenna = (0.0, 0.0) if geometry is None else tuple(geometry.gnss_pos_m[:2])
        write_run_tlog(first, path, antenna_body_m=antenna)
    elif suffix == ".bin":
        from .viz.dataflash_io import write_run_bin

        antenna = (0.0, 0.0) if geometry is None else tuple(geometry.gnss_pos_m[:2])
        write_run_bin(first, path, antenna_body_m=antenna)
    elif suffix == ".rrd":
        from .viz.rerun_log import write_runs_rrd

        write_runs_rrd(runs, path, geometry=geometry, hull_mesh_paths=mesh_placements(mjcf) if mjcf else None)
    else:
        raise TwinError(f"output '{path}': unknown format")
