"""Speed of `twin identify` on the ten shared BlueBoat runs, its choices judged on left-out runs
included (target: under 60 s on 2 cores).

    python scripts/bench_identify.py [--json out/NAME.json] [--repeats 1]

Times what `twin identify RUNS... --vessel blueboat` does after reading the files (calibration,
windows, the leave-one-run-out choices, the final fit), and reports the machine's load average
at the start so a figure from a shared machine is read as such. Without ../shared/data it says
so and exits 0.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import twin.vessel as vessel_mod  # noqa: E402
from twin.files import write_text_atomic  # noqa: E402
from twin.ident.identify import identify, read  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "blueboat"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--repeats", type=int, default=1)
    args = ap.parse_args()
    paths = sorted(DATA.glob("fixed_*.csv"))
    if not paths:
        print(f"the BlueBoat recordings are not in {DATA}: nothing to time")
        return 0
    prior = vessel_mod.load("blueboat")
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    recordings = read(paths)
    read_s = time.perf_counter() - t0
    times, result = [], None
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        result = identify(recordings, prior, sources=[str(p) for p in paths])
        times.append(time.perf_counter() - t0)
    out = {"runs": len(paths), "read_s": round(read_s, 2), "identify_s": [round(t, 1) for t in times],
           "best_s": round(min(times), 1), "cores": os.cpu_count(), "load_average_at_start": round(load, 2),
           "chosen": result.chosen.label, "configurations_judged": len(result.choices),
           "expect_on_a_new_run": result.chosen.cv.summary()}
    print(json.dumps(out, indent=1))
    if args.json:
        write_text_atomic(args.json, json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
