"""Write runs to the format their file extension names: .csv, .mcap, .rrd."""
from __future__ import annotations

from pathlib import Path

from .errors import TwinError
from .run import Run
from .vessel import MODEL_DIR, write_text_atomic

FORMATS = (".csv", ".mcap", ".rrd")


def check_paths(paths: list[Path]) -> None:
    """Refuse unknown extensions and missing folders before any work is done."""
    for p in paths:
        if p.suffix.lower() not in FORMATS:
            raise TwinError(f"output '{p}': unknown format (use {', '.join(FORMATS)})")
        if not p.parent.exists():
            raise TwinError(f"output '{p}': folder '{p.parent}' does not exist")


def hull_meshes(vessel_name: str) -> list[Path] | None:
    paths = [MODEL_DIR.parent / "assets" / f"hull_{s}.stl" for s in ("port", "starboard")]
    return paths if vessel_name == "yellowfish" and all(p.is_file() for p in paths) else None


def write(runs: dict[str, Run], path: Path, *, geometry=None, vessel_name: str = "") -> None:
    """The first run goes to .csv/.mcap; every run goes to .rrd on one timeline."""
    suffix = path.suffix.lower()
    first = next(iter(runs.values()))
    if suffix == ".csv":
        write_text_atomic(path, first.to_csv_text())
    elif suffix == ".mcap":
        from .viz.mcap_io import write_run_mcap

        write_run_mcap(first, path, vessel_name)
    elif suffix == ".rrd":
        from .viz.rerun_log import write_runs_rrd

        write_runs_rrd(runs, path, geometry=geometry, hull_mesh_paths=hull_meshes(vessel_name))
    else:
        raise TwinError(f"output '{path}': unknown format")
