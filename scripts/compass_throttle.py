"""Does a compass error follow the throttle? The kinematic test (twin.fit.calibrate.throttle_dependence)
on the independent simulator's recordings, where the answer is known, and then on the real BlueBoat runs.

    python scripts/compass_throttle.py [--seeds 1,2,3,4,5,6] [--json out/NAME.json]

World recordings (scripts/world_sim.py, code that never calls the library): `compass_motor_field` (the
magnetometer's field disturbed by c·P, the motors' electrical power: the library's form follows the
throttle instead) and `null_rc` (the same RC driving, no sensor error), one log per seed, each tested alone
with its own kinematic calibration. Then the ten shared BlueBoat runs together (../shared/data/blueboat,
read in place). Writes the JSON and a Markdown table beside it.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import twin.vessel as vessel_mod  # noqa: E402
from twin.files import write_text_atomic  # noqa: E402
from twin.fit.calibrate import MIN_THROTTLE_STRETCHES, throttle_dependence  # noqa: E402
from twin.ident.identify import calibrate, prepared, read  # noqa: E402

BLUEBOAT = ROOT.parent / "shared" / "data" / "blueboat"


def tested(paths: list[Path], vessel_name: str) -> dict:
    """The logs calibrated (each one's compass offset and drift) and tested together."""
    recs = read(paths)
    vessel, cals = calibrate(recs, vessel_mod.load(vessel_name))
    dep = throttle_dependence(prepared(recs, vessel), vessel, [c.drift_ned_m_s for c in cals])
    return {"logs": [p.name for p in paths], "result": None if dep is None else {
        "b_deg": dep.b_deg, "c_deg": dep.c_deg, "sigma_b_deg": dep.sigma_b_deg, "sigma_c_deg": dep.sigma_c_deg,
        "chi2": dep.chi2, "shown": dep.shown, "pieces": dep.pieces, "stretches": dep.stretches},
        "text": f"not told: fewer than {MIN_THROTTLE_STRETCHES} straight stretches ahead, or too few pieces of them"
        if dep is None else dep.text()}


def world(case: str, seed: int, work: Path, params: Path) -> dict:
    out = work / f"{case}_{seed}.csv"
    subprocess.run([sys.executable, str(ROOT / "scripts" / "world_sim.py"), "--params", str(params), "--case", case,
                    "--seed", str(seed), "--out", str(out)], check=True, capture_output=True)
    truth = json.loads(out.with_suffix(".truth.json").read_text())
    given = next((e.get("expected_values") for e in truth.get("effects", []) if e.get("kind") == case), None)
    return {"case": case, "seed": seed, "truth": given, **tested([out], "yellowfish")}


def _summary(doc: dict) -> str:
    def count(case):
        runs = [w for w in doc["world"] if w["case"] == case]
        return sum(bool(w["result"] and w["result"]["shown"]) for w in runs), len(runs)

    (hit, n), (false, nulls) = count("compass_motor_field"), count("null_rc")
    return (f"Shown on {hit} of {n} recordings whose compass follows the motors' power, and on {false} of {nulls} "
            "null recordings of the same driving.")


def markdown(doc: dict) -> str:
    lines = ["# Does the compass error follow the throttle? A kinematic test", "",
             "Written by `python scripts/compass_throttle.py` (twin.fit.calibrate.throttle_dependence): the crab "
             "angle of 2-s pieces of straight running ahead (logged heading less the track over ground) against each "
             "log's own offset and drift (fitted with it where the log's legs point 60° or more apart, else its "
             "calibration's), the sideslip of gentle turns (∝ r) and τ sin ψ, τ cos ψ (τ the throttle: the library's "
             "`compass_motor` form). Shown where (B, C) ≠ 0 at χ² > 13.8 on two degrees of freedom (p < 0.001), σ "
             "counting the pieces of one straight stretch together; not told from fewer than 10 straight stretches "
             "ahead. The world's error follows the motors' power (about the throttle cubed), so the fitted "
             "coefficients, per unit throttle, come out below the truth's at full power.", "",
             _summary(doc), "",
             "## The independent simulator (one log each, 15 min RC driving)", "",
             "| case | seed | truth B, C at full power (deg) | B ± σ | C ± σ | χ² | shown | pieces |",
             "|---|---|---|---|---|---|---|---|"]
    for w in doc["world"]:
        r, t = w["result"], w["truth"] or {}
        truth = f"{t['b_deg']:+.1f}, {t['c_deg']:+.1f}" if "b_deg" in t else "none"
        if r is None:
            lines.append(f"| {w['case']} | {w['seed']} | {truth} | - | - | - | - | 0 |")
            continue
        lines.append(f"| {w['case']} | {w['seed']} | {truth} | {r['b_deg']:+.1f} ± {r['sigma_b_deg']:.1f} | "
                     f"{r['c_deg']:+.1f} ± {r['sigma_c_deg']:.1f} | {r['chi2']:.1f} | {'yes' if r['shown'] else 'no'} "
                     f"| {r['pieces']} |")
    lines += ["", "## The BlueBoat runs (ten logs together)", "", doc["blueboat"]["text"] if doc["blueboat"] else
              "../shared/data/blueboat absent: not run", ""]
    return "\n".join(lines)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1,2,3,4,5,6")
    ap.add_argument("--json", type=Path, default=ROOT / "out" / "compass_throttle.json")
    a = ap.parse_args()
    seeds = [int(s) for s in a.seeds.split(",") if s]
    doc = {"world": [], "blueboat": None}
    with tempfile.TemporaryDirectory() as tmp:
        params = Path(tmp) / "yellowfish_params.json"
        params.write_text(subprocess.run([sys.executable, "-m", "twin", "params", "--vessel", "yellowfish", "--json"],
                                         check=True, capture_output=True, text=True, cwd=ROOT).stdout)
        for case in ("compass_motor_field", "null_rc"):
            for seed in seeds:
                doc["world"].append(world(case, seed, Path(tmp), params))
                print(case, seed, doc["world"][-1]["text"], flush=True)
    if BLUEBOAT.is_dir():
        doc["blueboat"] = tested(sorted(BLUEBOAT.glob("*.csv")), "blueboat")
        print("blueboat", doc["blueboat"]["text"])
    write_text_atomic(a.json, json.dumps(doc, indent=1))
    write_text_atomic(a.json.with_suffix(".md"), markdown(doc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
