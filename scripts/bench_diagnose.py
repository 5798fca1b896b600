"""Speed of `twin diagnose` on a 30-minute recording (target: under 60 s on 2 cores).

A 30-minute synthetic recording (realistic sensors) of the Yellowfish with a current
and a thrust lag concealed in it is written as .mcap, then diagnosed from the file.

    python scripts/bench_diagnose.py [--json out/NAME.json] [--pair CHECKOUT]

With --pair, the same benchmark of another checkout of the project (e.g. main's HEAD in a temporary
worktree) runs back to back with this one, each in its own process, alternating (`--repeats` pairs),
so that both see the same machine: both figures are reported.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import twin.vessel as vessel_mod  # noqa: E402
from twin.diagnose.doctor import diagnose  # noqa: E402
from twin.synth.dataset import PROFILES, generate  # noqa: E402
from twin.formats import read_recording, write_recording  # noqa: E402
from twin.vessel import write_text_atomic  # noqa: E402

EFFECTS = ["current=0.2,100", "thruster_lag=0.3"]


def paired(other: Path, minutes: float, repeats: int) -> dict:
    """This checkout's benchmark and `other`'s, alternating, each in a process of its own."""
    runs = {"this": [], "other": []}
    for _ in range(repeats):
        for label, root in (("other", other), ("this", ROOT)):
            with tempfile.TemporaryDirectory() as tmp:
                out = Path(tmp) / "bench.json"
                subprocess.run([sys.executable, str(root / "scripts" / "bench_diagnose.py"), "--minutes", str(minutes),
                                "--json", str(out)], check=True, cwd=root)
                runs[label].append(json.loads(out.read_text()))
    return {"this": {"checkout": str(ROOT), "runs": runs["this"]}, "other": {"checkout": str(other), "runs": runs["other"]}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--minutes", type=float, default=30.0)
    ap.add_argument("--pair", type=Path, default=None, help="another checkout to time back to back with this one")
    ap.add_argument("--repeats", type=int, default=1)
    args = ap.parse_args()
    if args.pair is not None:
        if not (args.pair / "scripts" / "bench_diagnose.py").is_file():
            print(f"error: {args.pair} is not a checkout of the project (no scripts/bench_diagnose.py)")
            sys.exit(2)
        out = paired(args.pair, args.minutes, args.repeats)
        for label in ("other", "this"):
            secs = [r["seconds"] for r in out[label]["runs"]]
            print(f"{label} ({out[label]['checkout']}): {', '.join(f'{x:.1f}' for x in secs)} s; found "
                  f"{', '.join(out[label]['runs'][-1]['effects_found']) or 'nothing'}")
        if args.json:
            write_text_atomic(args.json, json.dumps(out, indent=2) + "\n")
        return
    prior = vessel_mod.load("yellowfish")
    segments = int(round(args.minutes * 60 / 65))  # segments of 40-90 s, 65 s on average
    ds = generate(prior, effects=EFFECTS, n_segments=segments, seed=9, noise=PROFILES["realistic"])
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "long.mcap"
        write_recording(ds.recording, path)
        started = time.time()
        rec = read_recording(path)
        d = diagnose([rec], prior)
        seconds = time.time() - started
    out = {"recording_min": round(rec.duration_s() / 60, 2), "logged_min": round(
        sum(r.t[-1] - r.t[0] for r in ds.runs) / 60, 2), "seconds": round(seconds, 1), "cores": os.cpu_count(),
        "effects_injected": EFFECTS, "effects_found": [e["text"] for e in d.effects],
        "windows": d.windows}
    print(f"diagnosed {out['recording_min']} min ({out['logged_min']} min logged) in {out['seconds']} s on "
          f"{out['cores']} cores; found {', '.join(out['effects_found']) or 'nothing'}")
    if args.json:
        write_text_atomic(args.json, json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
