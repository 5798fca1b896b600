"""Pure-function 3-DOF marine physics (surge, sway, yaw), shared by the MuJoCo
callbacks and the analytic model. Nothing here imports mujoco.

Conventions (Fossen; [Yellowfish-TR §III]): η = [x, y, ψ] in NED (x north, y east,
ψ from north towards east), ν = [u, v, r] in the body frame FRD (x forward,
y starboard, z down). Forces τ = [X, Y, N] in N, N, N·m.
"""
from __future__ import annotations

from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent.parent


def drop_stale_jit_caches(sources: list[Path], cache_dirs: list[Path]) -> list[Path]:
    """Remove numba's cached compilations (.nbi, .nbc) older than the newest of `sources`; returns
    what was removed.

    Numba invalidates a function's cache when its own file changes, not when a jitted function it
    calls from another file does (numba's notes on caching): the sea load compiled with the old
    pressure integration would keep running it after hydrostatics.py changed. Dropping every cache
    older than the newest jitted source costs one recompilation after an edit and nothing else."""
    try:
        newest = max(p.stat().st_mtime for p in sources)
    except (OSError, ValueError):  # no sources to compare with
        return []
    removed = []
    for d in cache_dirs:
        for cached in sorted(d.glob("*.nb[ic]")):
            try:
                if cached.stat().st_mtime < newest:
                    cached.unlink()
                    removed.append(cached)
            except OSError:  # read-only, or another process removed it first
                continue
    return removed


drop_stale_jit_caches(sorted((_PACKAGE / "physics").glob("*.py")) + [_PACKAGE / "engine" / "native.py"],
                      [_PACKAGE / "physics" / "__pycache__", _PACKAGE / "engine" / "__pycache__"])
