#!/usr/bin/env python3
"""Time to read and prepare the shared recordings, and the velocities (surge u,
sway v, yaw rate r) recomputed from position and heading against the BlueBoat
files' own columns (surge, sway, yaw_rate).

    python scripts/bench_recordings.py [--shared ../shared] [--json out.json]

The figures in docs/: python scripts/bench_recordings.py --json out/NAME.json


Needs ../shared (not part of the project; never copied into it).
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from pathlib import Path

import numpy as np

from twin.prepare import prepare
from twin.formats import read_recording
from twin.vessel import write_text_atomic


def _timed(fn, *args, **kwargs):
    t0 = time.perf_counter()
    out = fn(*args, **kwargs)
    return out, time.perf_counter() - t0


def _own_columns(path: Path) -> dict[str, np.ndarray]:
    with open(path) as fh:
        rows = list(csv.DictReader(fh))
    t = np.array([float(r["original_timestamp"]) for r in rows]) / 1000.0
    col = {k: np.array([float(r[k]) if r[k] not in ("", "nan") else np.nan for r in rows])
           for k in ("surge", "sway", "yaw_rate")}
    return {"t": t - t[0], **col}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--shared", type=Path, default=Path(__file__).resolve().parents[2] / "shared")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    data = args.shared / "data"
    if not data.is_dir():
        print(f"error: {data} not found", file=sys.stderr)
        return 2
    logs = sorted((data / "ardupilot").iterdir(), key=lambda p: p.stat().st_size, reverse=True)
    largest = logs[0]
    rec, t_read = _timed(read_recording, largest, channels={"left": 1, "right": 3})
    _, t_prep = _timed(prepare, rec)
    result = {"largest_log": largest.name, "largest_log_mb": largest.stat().st_size / 1e6,
              "largest_read_s": t_read, "largest_prepare_s": t_prep, "blueboat": {}}
    print(f"{largest.name} ({result['largest_log_mb']:.1f} MB): read {t_read:.2f} s, prepare {t_prep:.3f} s")
    total = 0.0
    for path in sorted((data / "blueboat").glob("*.csv")):
        rec, t_read = _timed(read_recording, path)
        prep, t_prep = _timed(prepare, rec)
        total += t_read + t_prep
        own = _own_columns(path)
        corr = {}
        for ours, theirs in (("u", "surge"), ("v", "sway"), ("r", "yaw_rate")):
            ref = np.interp(prep.t, own["t"], own[theirs])
            ok = np.isfinite(ref) & np.isfinite(getattr(prep, ours))
            corr[ours] = float(np.corrcoef(getattr(prep, ours)[ok], ref[ok])[0, 1])
        result["blueboat"][path.name] = {"read_prepare_s": t_read + t_prep,
                                         **{f"corr_{dof}": corr[dof] for dof in ("u", "v", "r")}}
        print(f"{path.name}: {t_read + t_prep:.3f} s, corr u {corr['u']:.3f}, v {corr['v']:.3f}, r {corr['r']:.3f}")
    result["blueboat_total_s"] = total
    print(f"all ten BlueBoat files: {total:.2f} s")
    if args.json:
        write_text_atomic(args.json, json.dumps(result, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
