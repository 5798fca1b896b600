"""`twin diagnose` on the real BlueBoat: the untuned first-principles twin (twin/model/blueboat.json)
against seven runs together (each log's compass calibration first), what the diagnosis
concludes, and whether its amended twin predicts the three runs it never saw better than the
untuned one. Then the same with the twin's own coefficients of identify's core groups (REFIT)
refitted beside every candidate (`twin diagnose --refit`): each candidate judged against the twin
as these runs would identify it, not against the untuned one.

    python scripts/diagnose_blueboat.py [--out out/...]

Writes blueboat.md, blueboat.json and blueboat.html under --out. The recordings
(../shared/data/blueboat) have no licence: they are read in place, never copied; without them
the script says so and exits 0. Everything reported is computed by the package
(twin.diagnose, twin.fit); the script only runs it and writes the report.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import twin.vessel as vessel_mod  # noqa: E402
from twin.diagnose.doctor import diagnose  # noqa: E402
from twin.diagnose.report import as_json, format_text, write_html  # noqa: E402
from twin.files import write_text_atomic  # noqa: E402
from twin.fit.evaluate import evaluate  # noqa: E402
from twin.fit.metrics import DOFS  # noqa: E402
from twin.ident.identify import calibrate, prepared, read  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "blueboat"
TRAIN_RUNS = (216, 218, 220, 221, 222, 223, 224)
HELD_OUT_RUNS = (225, 226, 228)
REFIT = ("surge", "yaw", "sway", "thrust curve")


def paths(runs) -> list[Path]:
    return [DATA / f"fixed_00000{n}.csv" for n in runs]


def held_out(vessel, recordings) -> dict:
    """10-s free runs on the held-out runs, each log's own compass calibration applied."""
    v = calibrate(recordings, vessel)[0]
    return evaluate(v, prepared(recordings, v), horizons={"free_run_10s": 10.0})["free_run_10s"]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "diagnose")
    args = ap.parse_args()
    if any(not p.is_file() for p in paths(TRAIN_RUNS + HELD_OUT_RUNS)):
        print(f"the BlueBoat recordings are not in {DATA}: nothing to do")
        return 0
    started = time.time()
    prior = vessel_mod.load("blueboat")
    train, held = read(paths(TRAIN_RUNS)), read(paths(HELD_OUT_RUNS))
    d = diagnose(train, prior)
    before, after = held_out(prior, held), held_out(d.amended, held)
    refitted = diagnose(train, prior, refit=REFIT)
    after_refit = held_out(refitted.amended, held)
    seconds = time.time() - started
    args.out.mkdir(parents=True, exist_ok=True)
    write_html(d, args.out / "blueboat.html")
    write_text_atomic(args.out / "blueboat.json", json.dumps(
        {"diagnosis": as_json(d), "refitted": as_json(refitted),
         "held_out_runs": {"untuned": before, "amended": after, "refitted and amended": after_refit},
         "seconds": seconds},
        indent=1, default=float) + "\n")
    fence = "```"
    lines = ["# `twin diagnose` of the first-principles BlueBoat twin on real runs", "",
             f"Regenerate: `python scripts/diagnose_blueboat.py` ({seconds:.0f} s). Prior: `twin/model/blueboat.json` "
             f"(untuned). Diagnosed on runs {', '.join(map(str, TRAIN_RUNS))} together; the amended twin and the "
             f"untuned one are then scored on runs {', '.join(map(str, HELD_OUT_RUNS))}, which the diagnosis never "
             "saw. HTML with plots: [blueboat.html](blueboat.html). The identified twin's diagnosis is in "
             "[../identification/blueboat.md](../identification/blueboat.md).", "",
             "## What the diagnosis says", "", fence, format_text(d).rstrip(), fence, "",
             f"## With the core groups refitted beside every candidate (`--refit {','.join(REFIT)}`)", "",
             "Each candidate is fitted together with the twin's own coefficients of these groups (maximum a "
             "posteriori, beliefs ×1) on each fold's training blocks, and judged against those coefficients "
             "refitted alone on the same blocks: the twin as these runs would identify it.", "",
             fence, format_text(refitted).rstrip(), fence, "",
             "Every candidate judged (fitted on each fold, z over the held-out blocks, share of the misfit above "
             "the noise removed, blocks for/against):", "",
             "| round | candidate | z | share of the excess | blocks +/− | fitted per fold |",
             "|---|---|---|---|---|---|"]
    for k, r in enumerate(refitted.rounds, 1):
        for c in r["candidates"]:
            folds = "; ".join(", ".join(f"{n.split('@')[-1]} {v:.3g}" for n, v in list(fv.items())[:4])
                              for fv in c.get("fold_values", []))
            lines.append(f"| {k} | {c['name']} | {c['z']:.2f} | {100 * c['excess_gain']:.1f} % | "
                         f"{c['blocks_for']}/{c['blocks_against']} | {folds} |")
    lines += ["", "## On the three runs it never saw (10-s free runs, each log's compass calibration applied)", "",
              "| twin | " + " | ".join(f"R² {k}" for k in DOFS) + " | " + " | ".join(f"MAE {k}" for k in DOFS) + " |",
              "|---|" + "---|" * (2 * len(DOFS))]
    for name, m in (("untuned", before), ("amended by the diagnosis", after),
                    ("core refitted, amended by its diagnosis", after_refit)):
        lines.append(f"| {name} | " + " | ".join(f"{m[k]['r2']:.3f}" for k in DOFS) + " | "
                     + " | ".join(f"{m[k]['mae']:.4f}" for k in DOFS) + " |")
    write_text_atomic(args.out / "blueboat.md", "\n".join(lines) + "\n")
    print(f"wrote {args.out / 'blueboat.md'} ({seconds:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
