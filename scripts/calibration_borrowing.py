"""Per-log compass calibration where a log's straight legs point one way: read with the drifts other
logs fitted alone against the same with the log's own drift at rest
as one more reading (twin.fit.calibrate.rest_drift), on the multi-log world recordings of
scripts/world_sim.py (code independent of the package: null outings, compass offsets per log,
each outing's own wind, a shared current with offsets per log).

    python scripts/calibration_borrowing.py --seeds 39-78 --work DIR [--json out/NAME.json] 

Recordings are written to DIR (kept: a second run reads them); each log is calibrated both ways
and compared with the world's truth (its compass offset; 0 where it has none).
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import twin.vessel as vessel_mod  # noqa: E402
from twin.engine.mjcf import compile_vessel  # noqa: E402
from twin.fit.calibrate import MIN_STRAIGHT_S, kinematic_calibration  # noqa: E402
from twin.formats import read_recording  # noqa: E402
from twin.vessel import write_text_atomic  # noqa: E402

CASES = ("null_multilog", "compass_offset_per_log", "wind_per_outing_multilog", "pair_current_compass_multilog")


def seeds_of(text: str) -> list[int]:
    lo, _, hi = text.partition("-")
    return list(range(int(lo), int(hi or lo) + 1))


def recordings(work: Path, case: str, seed: int, params: Path) -> dict:
    truth = work / f"{case}_s{seed}.truth.json"
    if not truth.exists():
        subprocess.run([sys.executable, str(ROOT / "scripts" / "world_sim.py"), "--params", str(params), "--case", case,
                        "--seed", str(seed), "--out-dir", str(work)], check=True, stdout=subprocess.DEVNULL)
    return json.loads(truth.read_text())


def true_offsets(truth: dict) -> dict[str, float]:
    for e in truth["effects"]:
        if e["kind"] == "compass_offset_per_log":
            return e["params"]["offset_deg_by_log"]
    return {}


def calibrate(work: Path, truth: dict, compiled) -> list[dict]:
    """Every log of one recording: the offset applied both ways (None: not applied) and the truth."""
    recs = [read_recording(work / name) for name in truth["logs"]]
    first = [kinematic_calibration(r, compiled) for r in recs]
    offsets = true_offsets(truth)
    rows = []
    for rec, c in zip(recs, first):
        donors = [o.drift_ned_m_s for o in first if o is not c and o.drift_ned_m_s is not None]
        borrowing = c.drift_ned_m_s is None and c.seconds >= MIN_STRAIGHT_S and len(donors) >= 2
        before = kinematic_calibration(rec, compiled, borrowed=donors, at_rest=False) if borrowing else c
        now = kinematic_calibration(rec, compiled, borrowed=donors) if borrowing else c
        rows.append({"case": truth["case"], "seed": truth["seed"], "log": c.log, "truth_deg": offsets.get(c.log, 0.0),
                     "borrowing": borrowing, "before_deg": before.heading_bias_deg,
                     "before_sigma_deg": before.sigma_deg,
                     "now_deg": now.heading_bias_deg, "now_sigma_deg": now.sigma_deg, "note": now.note})
    return rows


def tally(rows: list[dict], key: str) -> dict:
    applied = [r for r in rows if r[key] is not None]
    err = np.array([r[key] - r["truth_deg"] for r in applied])
    return {"applied": len(applied), "within_1_5_deg": int(np.sum(np.abs(err) <= 1.5)),
            "off_more_than_3_deg": int(np.sum(np.abs(err) > 3.0)),
            "false_where_no_offset": int(sum(1 for r in applied if r["truth_deg"] == 0.0 and abs(r[key]) > 1.5)),
            "borrowing_applied": sum(1 for r in applied if r["borrowing"])}


def markdown(out: dict) -> str:
    b, n = out["before"], out["now"]
    lines = [f"# Borrowed drifts in the per-log compass calibration: seeds {out['seeds']}", "",
             f"{out['recordings']} multi-log world recordings ({', '.join(CASES)}), {out['logs']} logs; "
             f"{out['borrowing']} logs had legs pointing one way and at least two other logs' drifts to read them "
             "with (`python scripts/calibration_borrowing.py`).", "",
             "| | applied | within 1.5° of the truth | off by more than 3° | applied where there was no offset | "
             "borrowing logs applied |", "| --- | --- | --- | --- | --- | --- |",
             f"| other logs' drifts only (before) | {b['applied']} | {b['within_1_5_deg']} | "
             f"{b['off_more_than_3_deg']} | {b['false_where_no_offset']} | {b['borrowing_applied']} |",
             f"| and the log's own drift at rest (now) | {n['applied']} | {n['within_1_5_deg']} | "
             f"{n['off_more_than_3_deg']} | {n['false_where_no_offset']} | {n['borrowing_applied']} |", "",
             "Every borrowing log:", "",
             "| case | seed | log | truth ° | before ° (σ) | now ° (σ) | now: the readings |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    def cell(v, s):
        return "not applied" + (f" (σ {s:.1f})" if s is not None else "") if v is None else f"{v:+.2f} ({s:.2f})"
    for r in out["rows"]:
        if r["borrowing"]:
            lines.append(f"| {r['case']} | {r['seed']} | {r['log'].rsplit('_', 1)[-1]} | {r['truth_deg']:+.2f} | "
                         f"{cell(r['before_deg'], r['before_sigma_deg'])} | {cell(r['now_deg'], r['now_sigma_deg'])} | "
                         f"{r['note'].split('read with ')[-1]} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="39-78", help="a seed or a range, e.g. 39-78")
    ap.add_argument("--work", type=Path, required=True, help="folder for the world recordings (kept)")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--md", type=Path)
    args = ap.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    prior = vessel_mod.load("yellowfish")
    params = args.work / "yellowfish_params.json"
    if not params.exists():
        dump = subprocess.run([sys.executable, "-m", "twin", "params", "--vessel", "yellowfish", "--json"], check=True,
                              capture_output=True, text=True, cwd=ROOT).stdout
        write_text_atomic(params, dump)
    compiled = compile_vessel(prior)
    rows, recs = [], 0
    for seed in seeds_of(args.seeds):
        for case in CASES:
            rows += calibrate(args.work, recordings(args.work, case, seed, params), compiled)
            recs += 1
    out = {"seeds": args.seeds, "recordings": recs, "logs": len(rows), "borrowing": sum(r["borrowing"] for r in rows),
           "before": tally(rows, "before_deg"), "now": tally(rows, "now_deg"), "rows": rows}
    text = markdown(out)
    print(text)
    if args.json:
        write_text_atomic(args.json, json.dumps(out, indent=1) + "\n")
    if args.md:
        write_text_atomic(args.md, text)


if __name__ == "__main__":
    main()
