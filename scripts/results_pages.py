"""The pages of docs/results: one per study, written from the raw figures its script left in
docs/results/data/NAME.json (twin.viz.pages.ResultPage). A study script writes its raw figures
under out/ (its --out or --json); this script takes them into docs/results/data/NAME.json
(`--collect`, from the paths in COLLECT) and turns them into the page, with the date and commit of
the run they come from.

    python scripts/diagnose_proof.py                       # a study: raw figures into out/
    python scripts/results_pages.py --collect diagnosis_proof
    python scripts/results_pages.py                        # every page from docs/results/data

A page is never edited by hand: run the study again, then this script.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from twin.viz.pages import ResultPage, ResultTable, write_index  # noqa: E402

RESULTS = ROOT / "docs" / "results"
DATA = RESULTS / "data"

# name: (title, the study's command, the data it ran on, one sentence of what it asks)
STUDIES = {
    "diagnosis_proof": ("Diagnosis on concealed effects", "python scripts/diagnose_proof.py",
                        "synthetic recordings: effects injected by the library's own functions, and recordings of "
                        "an independent simulator (scripts/world_sim.py) with physics the library does not write",
                        "Does `twin diagnose` name the effect a recording hides, and nothing when it hides none?"),
    # a proof set fixed before it was run: world seeds no study had used, the cases where the GNSS fixes'
    # latency is the truth, a current beside which it was drawn, and a null
    "gnss_latency_world": ("GNSS latency on an independent simulator's truths (world seeds 57-59)",
                           "python scripts/diagnose_proof.py --no-library --world-seeds 57,58,59 "
                           "--only gnss_latency,current_tidal,null_rc --out out/diagnose/gnss_latency",
                           "recordings of an independent simulator (scripts/world_sim.py) at seeds no other study "
                           "used: GNSS fixes stamped 0.2-0.4 s late, a tidal current, and a null",
                           "Is a GNSS fixes' latency named where it is there, and nowhere else? (The diagnosis reads "
                           "the latency from the kinematics alone.)"),
    "gnss_latency_world_searched": ("GNSS latency on an independent simulator's truths (world seeds 57-59), the "
                                    "latency searched in the dynamics as well",
                                    "python scripts/diagnose_proof.py --no-library --world-seeds 57,58,59 --only "
                                    "gnss_latency,current_tidal,null_rc --out out/diagnose/gnss_latency_searched, with "
                                    "the diagnosis of commit 2e24909",
                                    "the same recordings as gnss_latency_world (the set fixed at 225fb76)",
                                    "The same question, with the diagnosis that also searched the dynamics for the "
                                    "latency (twin/diagnose/doctor.py with gnss_latency not in KINEMATIC_ONLY)."),
    "blueboat_diagnosis": ("BlueBoat: diagnosis of the untuned twin", "python scripts/diagnose_blueboat.py",
                           "BlueBoat recordings [BlueBoat-SI]", "What does the diagnosis name on a real boat?"),
    "blueboat_heldout_band": ("BlueBoat: prediction band on held-out runs", "python scripts/identify_blueboat.py",
                              "BlueBoat recordings [BlueBoat-SI]",
                              "How much of a held-out run lies inside the identified uncertainty's band?"),
    "esso_identification": ("Esso Osaka: identification on free-running tests", "python scripts/identify_esso.py",
                            "free-running tests of the Esso Osaka 3 m model [ESSO-FRT]",
                            "How well does the identified ship twin predict tests of another family?"),
    "esso_wind_diagnosis": ("Esso Osaka: the concealed wind found by the diagnosis", "python scripts/diagnose_esso.py",
                            "free-running tests with the on-board anemometer [ESSO-FRT]",
                            "Does the diagnosis find the wind the anemometer measured, without being told?"),
    "esso_wind_diagnosis_calibrated": ("Esso Osaka: the concealed wind, logs calibrated",
                                       "python scripts/diagnose_esso.py", "free-running tests [ESSO-FRT]",
                                       "The same with each log's compass calibration applied."),
    "esso_astern_side_force": ("Esso Osaka: the astern side force", "python scripts/esso_astern_side_force.py",
                               "free-running tests [ESSO-FRT]",
                               "What do the random tests say is missing when the propeller runs astern?"),
    "esso_yaw_checks": ("Esso Osaka: what the yaw lacks, one suspect at a time", "python scripts/esso_yaw_checks.py",
                        "random free-running tests [ESSO-FRT]", "Which single change lifts the yaw prediction?"),
    "esso_yaw_rate_window": ("Esso Osaka: the yaw-rate measurement's share of R² r",
                             "python scripts/esso_yaw_rate_window.py", "free-running tests [ESSO-FRT]",
                             "How much of the R² of r does the yaw-rate measurement itself take away?"),
    "synthetic_identification": ("Identification on synthetic data with a known truth",
                                 "python scripts/identify_synthetic.py", "`twin dataset` recordings of the Yellowfish",
                                 "Does identification recover the truth's parameters?"),
    "record_more": ("Does recording more settle a hint?", "python scripts/record_more_check.py",
                    "independent-simulator recordings (scripts/world_sim.py)",
                    "When the diagnosis only hints at an effect, does the longer recording it asks for settle it?"),
    "record_more_astern": ("Does recording more astern settle a hint?", "python scripts/record_more_check.py",
                           "independent-simulator recordings with astern running",
                           "The same for a drag that acts only astern."),
    "calibration_borrowing": ("Per-log compass calibration with borrowed drifts",
                              "python scripts/calibration_borrowing.py",
                              "multi-log independent-simulator recordings (scripts/world_sim.py)",
                              "Is a log's compass offset read right when its straight legs point one way?"),
    "calibration_borrowing_seen": ("Per-log compass calibration with borrowed drifts (recordings of the choice)",
                                   "python scripts/calibration_borrowing.py",
                                   "the multi-log recordings the rule was chosen on", "The same on those recordings."),
    "compass_throttle": ("Compass error growing with the throttle", "python scripts/compass_throttle.py",
                         "independent-simulator recordings with a motor-disturbed compass",
                         "Is the compass's motor interference named, and how well is it fitted?"),
    "smoother_validation": ("Velocity estimation: Savitzky-Golay against the model smoother",
                            "python scripts/validate_smoother.py", "synthetic recordings with known velocities",
                            "Which velocity estimate is closer to the truth?"),
    "crosscheck_yellowfish": ("Engine against the analytic model: Yellowfish", "twin crosscheck --vessel yellowfish",
                              "the shipped Yellowfish vessel", "Do the MuJoCo engine and the 3-DOF reference agree?"),
    "crosscheck_cybership1": ("Engine against the analytic model: CyberShip I", "twin crosscheck --vessel cybership1",
                              "the shipped CyberShip I vessel", "Do the MuJoCo engine and the 3-DOF reference agree?"),
    "validation_yellowfish_nominal": ("Yellowfish against its technical report (nominal case)",
                                      "twin validate --vessel yellowfish", "[Yellowfish-TR] tables",
                                      "Do the formulas, tables, engine and meshes agree?"),
    "validation_yellowfish_min": ("Yellowfish against its technical report (light case)",
                                  "twin validate --vessel yellowfish --case min", "[Yellowfish-TR] tables",
                                  "Do the formulas, tables, engine and meshes agree?"),
    "validation_yellowfish_max": ("Yellowfish against its technical report (heavy case)",
                                  "twin validate --vessel yellowfish --case max", "[Yellowfish-TR] tables",
                                  "Do the formulas, tables, engine and meshes agree?"),
    "iso_yaw": ("Identification by self-oscillation in yaw (Yellowfish)", "python scripts/iso_dp.py",
                "the Yellowfish twin", "Does IS-O [Relay-ISO Table I] recover the twin's own inertia and drag?"),
    "iso_surge": ("Identification by self-oscillation in surge (Yellowfish)", "python scripts/iso_dp.py",
                  "the Yellowfish twin", "Does IS-O [Relay-ISO Table I] recover the twin's own inertia and drag?"),
    "dp": ("I-PD dynamic positioning tuned from IS-O (Yellowfish)", "python scripts/iso_dp.py",
           "the Yellowfish twin", "How does the I-PD [Relay-ISO eqs. 9-11] follow its model function?"),
    "esso_iso_yaw": ("Identification by self-oscillation in yaw (Esso Osaka)",
                     "python scripts/iso_dp.py --vessel esso_osaka", "the Esso Osaka twin",
                     "IS-O with the rudder as the relay's output."),
    "esso_dp": ("I-PD heading control tuned from IS-O (Esso Osaka)", "python scripts/iso_dp.py --vessel esso_osaka",
                "the Esso Osaka twin", "How does the rudder I-PD follow its model function?"),
    "bench_diagnose": ("Benchmark: `twin diagnose` on a 30-minute recording", "python scripts/bench_diagnose.py",
                       "a synthetic 30-minute recording", "How long does a diagnosis take on 2 cores?"),
    "bench_identify": ("Benchmark: `twin identify` on the BlueBoat", "python scripts/bench_identify.py",
                       "ten BlueBoat recordings [BlueBoat-SI]", "How long does an identification take on 2 cores?"),
    "bench_recordings": ("Benchmark: reading and preparing recordings", "python scripts/bench_recordings.py",
                         "the shared ArduPilot logs and the BlueBoat recordings", "How long do reading and "
                         "preparing take?"),
    "bench_scale": ("Benchmark: Monte Carlo locally and on Ray", "python scripts/bench_scale.py",
                    "draws of an identified twin", "How many simulated seconds per second, locally and on Ray?"),
    "bench_engine": ("Benchmark: the engine", "python scripts/bench.py", "the Yellowfish twin",
                     "How fast do single runs, batches and `simulate` go?"),
    "bench_sitl": ("Benchmark: `twin sitl` at 1200 Hz frames", "python scripts/bench_sitl.py",
                   "the Yellowfish twin answering a client process at 1200 Hz frames",
                   "Is the twin fast enough to be ArduPilot SITL's physics at its default 1200 Hz frames?"),
}


# where each study script writes its raw figures by default (its --out / --json)
COLLECT = {
    "diagnosis_proof": "out/diagnose/proof.json", "gnss_latency_world": "out/diagnose/gnss_latency/proof.json",
    "gnss_latency_world_searched": "out/diagnose/gnss_latency_searched/proof.json",
    "blueboat_diagnosis": "out/diagnose/blueboat.json",
    "record_more": "out/diagnose/record_more.json", "record_more_astern": "out/diagnose/record_more_astern.json",
    "blueboat_heldout_band": "out/identification/blueboat_heldout_band.json",
    "synthetic_identification": "out/identification/synthetic.json",
    "esso_identification": "out/esso_identification.json", "esso_wind_diagnosis": "out/esso_wind_diagnosis.json",
    "esso_wind_diagnosis_calibrated": "out/esso_wind_diagnosis_calibrated.json",
    "esso_astern_side_force": "out/esso_astern_side_force.json", "esso_yaw_checks": "out/esso_yaw_checks.json",
    "esso_yaw_rate_window": "out/esso_yaw_rate_window.json", "compass_throttle": "out/compass_throttle.json",
    "calibration_borrowing": "out/calibration_borrowing.json", "iso_yaw": "out/iso/iso_yaw.json",
    "iso_surge": "out/iso/iso_surge.json", "dp": "out/iso/dp.json", "esso_iso_yaw": "out/iso/esso_iso_yaw.json",
    "esso_dp": "out/iso/esso_dp.json", "bench_diagnose": "out/bench_diagnose.json",
    "bench_identify": "out/bench_identify.json", "bench_recordings": "out/bench_recordings.json",
    "bench_scale": "out/bench_scale.json",
}


def provenance() -> dict:
    path = DATA / "provenance.json"
    return json.loads(path.read_text()) if path.exists() else {}


def _last_change(path: Path) -> tuple[str, str] | None:
    """(date, commit) of the last commit that changed `path`; None when it has uncommitted changes."""
    rel = str(path.relative_to(ROOT))
    dirty = subprocess.run(["git", "status", "--porcelain", "--", rel], capture_output=True, text=True, cwd=ROOT)
    if dirty.stdout.strip():
        return None
    out = subprocess.run(["git", "log", "-1", "--format=%cs %h", "--", rel], capture_output=True, text=True, cwd=ROOT)
    parts = out.stdout.split()
    return (parts[0], parts[1]) if len(parts) == 2 else None


def _scores(obj, path=(), depth=0, out=None) -> list[tuple[str, dict]]:
    """Every {u, v, r} → {r2, ...} block in the raw figures, with where it lies."""
    out = [] if out is None else out
    if isinstance(obj, dict):
        if all(isinstance(obj.get(d), dict) and "r2" in obj[d] for d in "uvr"):
            out.append((" / ".join(path) or "all", obj))
            return out
        if depth < 6:
            for k, v in obj.items():
                _scores(v, path + (str(k),), depth + 1, out)
    elif isinstance(obj, list) and depth < 5:
        for i, v in enumerate(obj[:40]):
            label = (v.get("case") or v.get("name") or (f"{v['train']} → {v.get('test')}, wind {v.get('wind')}" if "train" in v else None)) if isinstance(v, dict) else None
            _scores(v, path + (str(label or i),), depth + 1, out)
    return out


def _figures(obj, prefix="", out=None) -> list[tuple[str, object]]:
    """The raw figures' scalar numbers and words, two levels deep."""
    out = [] if out is None else out
    if isinstance(obj, dict):
        for k, v in obj.items():
            if isinstance(v, (int, float, str, bool)) and not isinstance(v, str) or (isinstance(v, str) and len(v) < 60):
                out.append((prefix + str(k), v))
            elif isinstance(v, dict) and not prefix:
                _figures(v, f"{k}.", out)
    return out


def score_table(raw) -> ResultTable | None:
    rows = [[where, *(block[d].get("r2") for d in "uvr")] for where, block in _scores(raw)]
    if not rows:
        return None
    return ResultTable("R² of the predictions (u, v, r)", ["what", "R² u", "R² v", "R² r"], rows[:60])


def proof_tables(raw: dict) -> list[ResultTable]:
    lib = raw.get("library", [])
    found = sum(1 for c in lib if c.get("found_all"))
    nulls = [c for c in lib if not c.get("effects")]
    clean = sum(1 for c in nulls if not c.get("extra"))
    s = raw.get("world_summary", {})
    tables = [ResultTable("Truths of the independent simulator", list(s), [list(s.values())])]
    if lib:  # a study of the world cases alone (--no-library) has none
        rows = [[c.get("case"), ", ".join(e if isinstance(e, str) else e.get("text", str(e))
                                          for e in c.get("effects", [])) or "none", "yes" if c.get("found_all") else "no",
                 ", ".join(x if isinstance(x, str) else x.get("text", str(x)) for x in c.get("extra", [])) or "–"]
                for c in lib]
        tables[:0] = [ResultTable("Truths written by the library's own effects", ["cases", "every truth named",
                                                                                "null cases", "null cases clean"],
                                  [[len(lib), found, len(nulls), clean]])]
        tables.append(ResultTable("Each library case: the truth, named in full?, anything else named",
                                  ["case", "truth", "named", "also named"], rows))
    wrows = [[c.get("case"), c.get("seed"), ", ".join(map(str, c.get("named", []))) or "–",
              ", ".join(map(str, c.get("spurious", []))) or "–"] for c in raw.get("world", [])]
    tables.append(ResultTable("Each independent-simulator recording (random seed): named, and named without a truth",
                              ["case", "seed", "named", "spurious"], wrows))
    return tables


MAX_COLUMNS = 14


def _flat(obj, prefix: str = "", depth: int = 0) -> dict:
    """A record's scalars, nested dicts' scalars under dotted keys (three levels), lists of words
    joined and other lists counted."""
    out = {}
    for k, v in obj.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict) and depth < 2:
            out.update(_flat(v, f"{key}.", depth + 1))
        elif isinstance(v, list):
            out[key] = ", ".join(map(str, v)) if all(isinstance(x, (str, int, float)) for x in v) else len(v)
        elif not isinstance(v, dict):
            out[key] = v
    return out


def _records(title: str, items: list, label: str | None = None) -> ResultTable | None:
    """A list of records as one table, a column per key (the first MAX_COLUMNS met)."""
    rows = [_flat(x) for x in items if isinstance(x, dict)]
    if not rows:
        return None
    columns = list(dict.fromkeys(k for r in rows for k in r))[:MAX_COLUMNS]
    return ResultTable(title, columns, [[r.get(c, "–") for c in columns] for r in rows])


def record_tables(raw) -> list[ResultTable]:
    """The figures of a study whose raw file is records: a list of records is one table; a mapping
    gives a table per entry that holds records (a list of them, or records under names)."""
    if isinstance(raw, list):
        table = _records("Each record", raw)
        return [table] if table else []
    tables = []
    for key, value in raw.items() if isinstance(raw, dict) else ():
        if isinstance(value, list):
            table = _records(str(key), value)
        elif isinstance(value, dict) and value and all(isinstance(v, dict) for v in value.values()):
            table = _records(str(key), [{"": name, **v} for name, v in value.items()])
        elif isinstance(value, dict) and value and all(isinstance(v, list) for v in value.values()):
            table = _records(str(key), [{"": name, **x} for name, v in value.items() for x in v if isinstance(x, dict)])
        else:
            table = None
        if table:
            tables.append(table)
    return tables


def compass_tables(raw: dict) -> list[ResultTable]:
    """The compass-throttle study: each independent-simulator recording's truth against what the
    calibration read, and the BlueBoat's reading."""
    def truth(r):
        return "none" if not r.get("truth") else f"B {r['truth']['b_deg']:+.1f}°, C {r['truth']['c_deg']:+.1f}°"

    def read(r):
        x = r.get("result")
        if not x:
            return "not told"
        return (f"B {x['b_deg']:+.1f}° ± {x['sigma_b_deg']:.1f}, C {x['c_deg']:+.1f}° ± {x['sigma_c_deg']:.1f}"
                f" (χ² {x['chi2']:.1f})")
    rows = [[r["case"], r["seed"], truth(r), read(r), "yes" if (r.get("result") or {}).get("shown") else "no"]
            for r in raw.get("world", [])]
    tables = [ResultTable("Each independent-simulator recording: the motors' compass deviation at full throttle, "
                          "true and read", ["case", "seed", "truth", "read (± 1σ)", "shown"], rows)]
    boat = raw.get("blueboat")
    if boat:
        tables.append(ResultTable("The BlueBoat's ten runs", ["logs", "read"],
                                  [[len(boat.get("logs", [])), boat.get("text", "")]]))
    return tables


def page(name: str) -> ResultPage:
    title, ran, data, question = STUDIES[name]
    raw = json.loads((DATA / f"{name}.json").read_text())
    proof = name in ("diagnosis_proof", "gnss_latency_world", "gnss_latency_world_searched")
    tables = proof_tables(raw) if proof else compass_tables(raw) if name == "compass_throttle" else []
    scores = score_table(raw)
    if scores and not proof:
        tables.append(scores)
    figures = _figures(raw)
    if not tables:
        tables = record_tables(raw)
        # the study's own numbers beside its records (a benchmark's largest log and its time)
        top = [(k, v) for k, v in figures if "." not in k]
        if tables and top:
            tables.insert(0, ResultTable("Figures", ["figure", "value"], [[k, v] for k, v in top]))
    if figures and not tables:
        tables.append(ResultTable("Figures", ["figure", "value"], [[k, v] for k, v in figures[:60]]))
    targets = raw.get("targets") if isinstance(raw, dict) else None
    summary = question + (f" Targets (R² u, v, r): {targets}." if isinstance(targets, dict) else "")
    prov = provenance().get(name)
    path = DATA / f"{name}.json"
    if prov and hashlib.sha256(path.read_bytes()).hexdigest() == prov["sha256"]:
        figures_of = (prov["date"], prov["commit"])  # the run's date and commit, as recorded beside its figures
    else:
        figures_of = _last_change(path)
    return ResultPage(name, title, f"{ran}; python scripts/results_pages.py {name}", data, summary, tables,
                      raw_file=f"data/{name}.json", figures_of=figures_of, images=images_of(name))


def images_of(name: str) -> list[str]:
    """The figures beside the pages that belong to study `name`: its own name, or its name and a
    suffix (dp_heading45.png); a validation page's are its vessel and case's (yellowfish_nominal_topview.png)."""
    stems = (name, name.removeprefix("validation_")) if name.startswith("validation_") else (name,)
    return sorted(p.name for p in RESULTS.glob("*.png")
                  if any(p.stem == s or p.stem.startswith(s + "_") for s in stems))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("names", nargs="*", help="pages to write (default: every study with a data file)")
    parser.add_argument("--collect", action="store_true",
                        help="first copy each study's fresh raw figures from out/ (COLLECT) into docs/results/data")
    args = parser.parse_args()
    if args.collect:
        for n in args.names or COLLECT:
            src = ROOT / COLLECT.get(n, f"out/{n}.json")
            if src.exists():
                (DATA / f"{n}.json").write_bytes(src.read_bytes())
                print(f"collected {src.relative_to(ROOT)}")
    names = args.names or [n for n in STUDIES if (DATA / f"{n}.json").exists()]
    unknown = [n for n in names if n not in STUDIES]
    if unknown:
        parser.error(f"unknown stud{'y' if len(unknown) == 1 else 'ies'}: {', '.join(unknown)}")
    for n in names:
        print(page(n).write(RESULTS))
    write_index(RESULTS)


if __name__ == "__main__":
    main()
