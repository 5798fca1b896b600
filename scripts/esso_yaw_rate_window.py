"""How much of the Esso Osaka's R² r the yaw-rate measurement itself takes away.

    python scripts/esso_yaw_rate_window.py [--out docs]

The yaw rate of a recording is the Savitzky-Golay derivative of its heading (twin.prepare). The
Esso files give psi_hat at 10 Hz with a white noise of about 0.08° (twin.diagnose.noise) and
glitches. For each family of tests (turning, random) and each yaw-rate window (0.5 s: the
package's default for a 50-Hz AHRS; 1 s; 2 s): the noise the window leaves (its derivative less the
4-s derivative, sd and MAD), the R² a perfect twin would score against it (twin.fit.metrics.ceiling_r2),
the RMS difference from the files' own yaw-rate stream r_angvelo (which prepare() does not use: an
independent look at which window takes noise out and which starts to take the ship's turns with it;
4, 8 and 16 s too), and the untuned twin's pooled 30-s free-run R² from measured states every 10 s (twin.fit.evaluate),
without wind and with the anemometer's wind as a known input. The duplicate
turn_cut_14-Sep-2020_15_58_08 is left out. The recordings (../shared/data/esso) are read in place;
without them the script says so and exits 0.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import twin.vessel as vessel_mod  # noqa: E402
from twin.engine.mjcf import compile_vessel  # noqa: E402
from twin.files import write_text_atomic  # noqa: E402
from twin.fit.calibrate import GNSS_WINDOW_S, prepare_for  # noqa: E402
from twin.fit.evaluate import TwinPredictor, evaluate  # noqa: E402
from twin.fit.metrics import ceiling_r2  # noqa: E402
from twin.fit.windows import ModelCache  # noqa: E402
from twin.formats import read_recording  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "esso"
DUPLICATE = "turn_cut_14-Sep-2020_15_58_08.csv"
WINDOWS_S = (0.5, 1.0, 2.0)
GYRO_WINDOWS_S = (0.5, 1.0, 2.0, 4.0, 8.0, 16.0)
REFERENCE_S = 4.0  # far below the ship's rudder response (tens of seconds), far above the noise
HORIZON = {"free_run_30s": 30.0}


def family(name: str) -> str:
    return "turning" if name.startswith("turn") else "random"


def run(vessel) -> list[dict]:
    compiled = compile_vessel(vessel)
    files = [f for f in sorted(DATA.glob("*.csv")) if f.name != DUPLICATE]
    recs = {f.name: read_recording(f) for f in files}
    rows = []
    for fam in ("turning", "random"):
        mine = [r for n, r in recs.items() if family(n) == fam]
        gyro = {}
        for w in GYRO_WINDOWS_S:
            diff = []
            for rec in mine:
                prep = prepare_for(rec, compiled, window_s=GNSS_WINDOW_S, heading_window_s=w)
                diff.append((prep.r - np.interp(prep.t, rec.imu.t, rec.imu["yaw_rate_rads"]))[20:-20])
            gyro[w] = float(np.sqrt(np.mean(np.concatenate(diff) ** 2)))
        reference = np.concatenate([prepare_for(r, compiled, window_s=GNSS_WINDOW_S,
                                                heading_window_s=REFERENCE_S).r for r in mine])
        for w in WINDOWS_S:
            preps = [prepare_for(r, compiled, window_s=GNSS_WINDOW_S, heading_window_s=w) for r in mine]
            r = np.concatenate([p.r for p in preps])
            noise = r - reference
            scores = {}
            for wind in (None, "measured"):
                m = evaluate(TwinPredictor(vessel, ModelCache(), wind=wind), preps, stride_s=10.0,
                             horizons=HORIZON)["free_run_30s"]
                scores["measured wind" if wind else "no wind"] = {d: m[d]["r2"] for d in "uvr"}
            rows.append({"family": fam, "tests": len(mine), "window_s": w, "noise_sd": float(np.std(noise)),
                         "noise_mad": float(1.4826 * np.median(np.abs(noise - np.median(noise)))),
                         "r_sd": float(np.std(r)), "ceiling_r2": ceiling_r2(r, reference), "untuned": scores,
                         "rms_to_r_angvelo": gyro[w], "rms_to_r_angvelo_by_window": gyro})
    return rows


def markdown(rows: list[dict], seconds: float) -> str:
    lines = ["# The Esso Osaka's yaw rate: what the measurement leaves a twin", "",
             f"Written by `python scripts/esso_yaw_rate_window.py` ({seconds:.0f} s). The yaw rate is the "
             "Savitzky-Golay derivative of the 10-Hz heading psi_hat over a window; the noise is that derivative "
             f"less the {REFERENCE_S:g}-s one, the ceiling the R² a perfect twin would score against it "
             "(`twin.fit.metrics.ceiling_r2`), the last columns the untuned twin's pooled 30-s free-run R² "
             "u / v / r (from measured states every 10 s; without wind, and with the anemometer's wind as a "
             "known input). The vessel file's `sensors.heading_rate_window_s` takes 1 s for this ship "
             "(0.5 s, the package's default, is for a 50-Hz AHRS).", "",
             "| tests | yaw-rate window s | noise sd (MAD) rad/s | r sd rad/s | ceiling R² r | "
             "RMS to r_angvelo rad/s | untuned, no wind | untuned, measured wind |",
             "|---|---|---|---|---|---|---|---|"]
    for row in rows:
        s = row["untuned"]
        fmt = lambda d: " / ".join(f"{d[k]:.3f}" for k in "uvr")  # noqa: E731
        lines.append(f"| {row['family']} ({row['tests']}) | {row['window_s']:g} | {row['noise_sd']:.4f} "
                     f"({row['noise_mad']:.4f}) | {row['r_sd']:.4f} | {row['ceiling_r2']:.3f} | "
                     f"{row['rms_to_r_angvelo']:.4f} | {fmt(s['no wind'])} | {fmt(s['measured wind'])} |")
    lines += ["", "RMS difference of the heading's derivative from the files' own yaw-rate stream (r_angvelo), by "
              "window: it falls while a longer window takes noise out and rises once it takes the ship's turns "
              "with it.", "", "| tests | " + " | ".join(f"{w:g} s" for w in GYRO_WINDOWS_S) + " |",
              "|---|" + "---|" * len(GYRO_WINDOWS_S)]
    for row in rows:
        if row["window_s"] == WINDOWS_S[0]:
            by = row["rms_to_r_angvelo_by_window"]
            lines.append(f"| {row['family']} | " + " | ".join(f"{by[w]:.4f}" for w in GYRO_WINDOWS_S) + " |")
    return "\n".join(lines) + "\n"


def esso_arguments(doc: str) -> argparse.Namespace | None:
    """--out of an Esso script; None (said) when the recordings are not beside the project."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "out")
    args = ap.parse_args()
    if not DATA.is_dir():
        print(f"the Esso recordings are not here ({DATA}): nothing to do")
        return None
    return args


def main() -> int:
    args = esso_arguments(__doc__)
    if args is None:
        return 0
    started = time.time()
    rows = run(vessel_mod.load("esso_osaka"))
    seconds = time.time() - started
    args.out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(args.out / "esso_yaw_rate_window.md", markdown(rows, seconds))
    write_text_atomic(args.out / "esso_yaw_rate_window.json", json.dumps(rows, indent=1) + "\n")
    print(markdown(rows, seconds))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
