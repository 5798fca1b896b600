"""Does "record more" settle a hint? Checked on truths the library did not write.

    python scripts/record_more_check.py [--out out/...] [--cases CASE:SEED:EFFECT,... --name NAME]

`twin diagnose` reports an effect that removes misfit on held-out blocks but acts in too few of them
for z ≥ 3 as a hint, with how much more recording of the same kind would reach z 3 if the further
blocks voted as these did (twin.diagnose.verdict.more_recording_factor). For each world case of the
proof (scripts/diagnose_proof.py, docs/results/diagnosis_proof.md) whose true effect was only a hint, this
script records the case again with the same seed for that many times the length (scripts/world_sim.py,
--duration-s), diagnoses it, and reports whether the truth is then named, whether anything else is,
and what became of the other hints of the first recording. The world's driving is random: the longer
recording is "the same kind of driving", not the first one continued.
"""
from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import twin.vessel as vessel_mod  # noqa: E402
from twin.diagnose.doctor import diagnose  # noqa: E402
from twin.diagnose.verdict import more_recording_factor, promising  # noqa: E402
from twin.files import write_text_atomic  # noqa: E402
from twin.formats import read_recording  # noqa: E402

WORLD_SIM = ROOT / "scripts" / "world_sim.py"
# (case, seed, the library effect that covers its truth): the proof's misses that were hints
CASES = (("input_delay", 1, "input_delay"), ("battery_sag", 2, "thrust_decay"),
         ("thruster_rate_limit", 2, "thruster_lag"), ("deadzone_asym", 2, "dead_zone"))


def record(case: str, seed: int, folder: Path, params: Path, duration_s: float | None = None) -> tuple[Path, dict]:
    folder.mkdir(parents=True, exist_ok=True)
    csv, truth = folder / f"{case}.csv", folder / "truth.json"
    cmd = [sys.executable, str(WORLD_SIM), "--params", str(params), "--case", case, "--seed", str(seed),
           "--out", str(csv), "--truth", str(truth)]
    if duration_s is not None:
        cmd += ["--duration-s", f"{duration_s:g}"]
    subprocess.run(cmd, check=True, capture_output=True)
    return csv, json.loads(truth.read_text())


def hints(d) -> dict[str, dict]:
    """The candidates the answer reports as hints (twin.diagnose.verdict.promising), by name."""
    return {c["name"]: c for c in promising(d)}


def run(case: str, seed: int, truth_effect: str, work: Path, params: Path, prior) -> dict:
    csv, truth = record(case, seed, work / f"{case}_s{seed}", params)
    diagnosis = diagnose([read_recording(csv)], prior)
    first, hinted = diagnosis.to_dict(), hints(diagnosis)
    out = {"case": case, "seed": seed, "truth": truth_effect, "duration_s": truth["duration_s"],
           "named": [e["name"] for e in first["effects"]],
           "hints": {n: {k: c[k] for k in ("z", "blocks_for", "blocks_against", "excess_gain")} |
                     {"factor": more_recording_factor(c)} for n, c in hinted.items()}}
    factor = out["hints"].get(truth_effect, {}).get("factor")
    if factor is None:
        out["longer"] = None
        return out
    longer_s = 60.0 * math.ceil(factor * truth["duration_s"] / 60.0)
    csv2, truth2 = record(case, seed, work / f"{case}_s{seed}_longer", params, longer_s)
    diagnosis = diagnose([read_recording(csv2)], prior)
    again = diagnosis.to_dict()
    named = [e["name"] for e in again["effects"]]
    out["longer"] = {"duration_s": longer_s, "named": named, "truth_named": truth_effect in named,
                     "others_named": [n for n in named if n != truth_effect],
                     "hints": sorted(hints(diagnosis)),
                     "parameters": {e["name"]: e["parameters"] for e in again["effects"]},
                     "truth_expected": truth2["effects"][0].get("expected_values")}
    return out


def _values(d: dict | None) -> str:
    return "-" if not d else ", ".join(f"{k} {v:.3g}" for k, v in d.items() if isinstance(v, (int, float)))


def markdown(rows: list[dict], seconds: float, command: str = "python scripts/record_more_check.py") -> str:
    lines = ["# Does recording more settle a hint?", "",
             f"Written by `{command}` ({seconds:.0f} s). World cases of the proof whose "
             "true effect was only a hint: the hint's own estimate of how much more recording of the same kind "
             "would reach z 3, then that recording (same seed, same kind of driving, random afresh) diagnosed.", "",
             "| case | seed | truth | first recording: hints (z, blocks for/against, × length) | longer recording | "
             "truth named | fitted (truth's library equivalent) | anything else named | hints left |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        h = "; ".join(f"{n} (z {c['z']:.2f}, {c['blocks_for']}/{c['blocks_against']}, "
                      f"×{c['factor']:.2f})" if c["factor"] else f"{n} (z {c['z']:.2f})" for n, c in r["hints"].items())
        lo = r["longer"]
        if lo is None:
            lines.append(f"| {r['case']} | {r['seed']} | {r['truth']} | {h or '-'} | no estimate | - | - | - | - |")
            continue
        lines.append(f"| {r['case']} | {r['seed']} | {r['truth']} | {h} | {lo['duration_s'] / 60:.0f} min "
                     f"(from {r['duration_s'] / 60:.0f}) | {'yes' if lo['truth_named'] else 'no'} | "
                     f"{_values(lo['parameters'].get(r['truth']))} ({_values(lo['truth_expected'])}) | "
                     f"{', '.join(lo['others_named']) or '-'} | {', '.join(lo['hints']) or '-'} |")
    done = [r for r in rows if r["longer"]]
    lines += ["", f"Truth named on the longer recording: {sum(r['longer']['truth_named'] for r in done)} of {len(done)}; "
              f"longer recordings naming anything else: {sum(bool(r['longer']['others_named']) for r in done)} of "
              f"{len(done)}.", ""]
    return "\n".join(lines)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "diagnose")
    ap.add_argument("--work", type=Path, default=None, help="folder for the recordings (default: a temporary one)")
    ap.add_argument("--cases", default="", help="CASE:SEED:EFFECT,... instead of the proof's four hints")
    ap.add_argument("--name", default="record_more", help="stem of the .md and .json written in --out")
    args = ap.parse_args()
    try:
        cases = [(c, int(s), e) for c, s, e in (x.split(":") for x in args.cases.split(",") if x.strip())] or CASES
    except ValueError:
        ap.error(f"--cases wants CASE:SEED:EFFECT,..., got {args.cases!r}")
    import tempfile

    started = time.time()
    prior = vessel_mod.load("yellowfish")
    with tempfile.TemporaryDirectory() as tmp:
        work = args.work or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        params = work / "params.json"
        params.write_text(subprocess.run([sys.executable, "-m", "twin", "params", "--vessel", "yellowfish", "--json"],
                                         capture_output=True, text=True, check=True).stdout)
        rows = []
        for case, seed, eq in cases:
            rows.append(run(case, seed, eq, work, params, prior))
            print(json.dumps(rows[-1]), flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(args.out / f"{args.name}.md", markdown(rows, time.time() - started, " ".join(
        ["python scripts/record_more_check.py"] + [f"{a}" for a in sys.argv[1:]])))
    write_text_atomic(args.out / f"{args.name}.json", json.dumps(rows, indent=1) + "\n")
    print(f"wrote {args.out / (args.name + '.md')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
