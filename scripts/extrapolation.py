"""The twin beyond its training runs: `twin identify` on the runs of a split that go least far, judged
on the runs that go further (twin.fit.extrapolation), on the shared BlueBoat and Esso Osaka data.

    python scripts/extrapolation.py [--only blueboat_activity,esso_rps,...] [--work /tmp/extrapolation]
                                    [--out docs/results]

Splits (twin.fit.extrapolation): the BlueBoat's five least active runs fitted, its five most active
judged (10-s free runs); the Esso Osaka's tests whose propeller never exceeds 8 rps fitted, those
that reach 10 rps judged; the random tests' stretches of 30 s or more at 6 rps or less fitted, the
turning tests (8 and 10 rps) judged; and each family of tests (random manoeuvres, steady turns) fitted and the
other judged (30-s free runs), each without and with the measured wind as a known input. Per split:
R² of u, v, r of the untuned prior and of the identified twin, pooled over the judged runs (each
log's compass calibration from its own kinematics), the share of judged samples beyond what the fit
saw and the misfit they carry, and, where the identified twin has an uncertainty, how often the
recording falls inside its 90 % prediction band. With --reach, `twin identify` is also run on the
judged runs themselves and scored on them: what the twin's form reaches there when nothing has to
be extrapolated, so a miss of a target reads as extrapolation (the split falls short of the reach)
or as form (the reach itself falls short). With --slope, the saved splits whose twin reads r from a
gyro (the Esso Osaka) are scored also against the heading's slope, so the page tells what the gyro
changes in the yardstick from what it changes in the twin.

Each split is saved in --work as JSON, so splits can run in separate processes; the page is written
from whatever splits are there. The recordings (../shared/data, no or non-commercial licences) are
read in place, never copied; without them the script says so and exits 0.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import twin.vessel as vessel_mod  # noqa: E402
from twin.files import write_text_atomic  # noqa: E402
from twin.fit.evaluate import evaluate, fitted_envelope, misfit_by_manoeuvre  # noqa: E402
from twin.fit.extrapolation import (Split, activities, by_activity, by_day, by_family, by_input_level,  # noqa: E402
                                    low_input_stretches)
from twin.fit.metrics import DOFS  # noqa: E402
from twin.ident.identify import calibrate, identify, prepared, read  # noqa: E402
from twin.physics.sensors import log_name  # noqa: E402
from twin.recording import within  # noqa: E402
from twin.scale.montecarlo import band_coverage  # noqa: E402
from twin.viz.pages import ResultPage, ResultTable, checkout_commit  # noqa: E402

DATA = ROOT.parent / "shared" / "data"
ESSO_DUPLICATE = "turn_cut_14-Sep-2020_15_58_08.csv"  # the first 287 s of turn_14-Sep-2020_15_58_08
TARGETS = {"blueboat": {"u": 0.95, "v": 0.4, "r": 0.8}, "esso_osaka": {"u": 0.9, "v": 0.6, "r": 0.9}}
# per vessel: the free-run horizon the targets are on and the stride of the judged windows; identify
# runs with its own defaults (its window from the vessel's surge time constant: 10 s and 30 s here)
SETTINGS = {"blueboat": {"window_s": 10.0, "stride_s": 2.0}, "esso_osaka": {"window_s": 30.0, "stride_s": 10.0}}


def blueboat_paths() -> list[Path]:
    return sorted((DATA / "blueboat").glob("fixed_*.csv"))


def esso_paths() -> list[Path]:
    return sorted(p for p in (DATA / "esso").glob("*.csv") if p.name != ESSO_DUPLICATE)


def _split_of(name: str, recs, preps):
    if name == "blueboat_activity":
        return by_activity(preps, len(preps) // 2)
    if name == "esso_rps":
        return by_input_level(preps, 8.5)
    if name == "esso_random_turn":
        return by_family([log_name(r.source) for r in recs], "random")
    if name == "esso_turn_random":
        return by_family([log_name(r.source) for r in recs], "turn")
    if name == "esso_turn_day":
        return by_day([log_name(r.source) for r in recs], "14-Sep-2020", family="turn")
    if name == "esso_turn_day_back":
        return by_day([log_name(r.source) for r in recs], "14-Oct-2020", family="turn")
    raise SystemExit(f"unknown split {name}")


# esso_low_rps: the random tests' stretches whose propeller stays at or below LOW_RPS for LOW_STRETCH_S or
# more fitted, every turning test (8 and 10 rps) judged: 10 rps is 1.67 times 6, as 17 rps is 10
LOW_RPS, LOW_STRETCH_S = 6.0, 30.0
BAND_DRAWS = 50  # parameter draws of the 90 % band (30-s free runs)
SPLITS = {"blueboat_activity": ("blueboat", (None,)), "esso_rps": ("esso_osaka", (None, "measured")),
          "esso_low_rps": ("esso_osaka", (None, "measured")),
          "esso_random_turn": ("esso_osaka", (None, "measured")),
          "esso_turn_random": ("esso_osaka", (None, "measured")),
          "esso_turn_day": ("esso_osaka", (None, "measured")),
          "esso_turn_day_back": ("esso_osaka", (None, "measured"))}


def scores(vessel, recs, settings: dict, wind, seen) -> dict:
    """Pooled free-run R² on the judged runs and the part beyond what the fit saw."""
    calibrated = calibrate(recs, vessel)[0]
    preps = prepared(recs, calibrated)
    h, stride = settings["window_s"], settings["stride_s"]
    metrics = evaluate(calibrated, preps, stride_s=stride, horizons={"free_run": h}, wind=wind)["free_run"]
    split = misfit_by_manoeuvre(calibrated, preps, h, stride, wind, fitted=seen)
    out = {"r2": {d: metrics[d]["r2"] for d in DOFS}, "mae": {d: metrics[d]["mae"] for d in DOFS},
           "n": metrics["u"]["n"], "beyond_fit": split.get("beyond_fit")}
    if vessel.sensors.yaw_rate_source == "gyro":
        out["r2_r_heading_slope"] = slope_r2(vessel, recs, settings, wind)
    if vessel.uncertainty:  # how often the judged runs fall inside the 90 % band, with and without the form error
        cov = band_coverage(calibrated, preps, draws=BAND_DRAWS, seed=0, level=0.9, wind=wind)
        out["band"] = {q: cov.inside[q] for q in ("u", "v", "r", "north", "east", "psi")}
        if cov.inside_parameters_only:
            out["band_parameters_only"] = {q: cov.inside_parameters_only[q] for q in ("u", "v", "r", "north", "east",
                                                                                      "psi")}
    return out


def slope_r2(vessel, recs, settings: dict, wind) -> float:
    """R² of r against the heading's slope (the yaw rate before a gyro was read), the same twin's
    free runs: what a gyro's r changes in the yardstick rather than in the twin."""
    slope = replace(vessel, sensors=replace(vessel.sensors, yaw_rate_source="heading"))
    calibrated = calibrate(recs, slope)[0]
    metrics = evaluate(calibrated, prepared(recs, calibrated), stride_s=settings["stride_s"],
                       horizons={"free_run": settings["window_s"]}, wind=wind)["free_run"]
    return metrics["r"]["r2"]


def add_slope_scores(work: Path) -> None:
    """Each saved split whose identified twin reads r from a gyro, scored also against the heading's
    slope (its r2_r_heading_slope), in place."""
    for path in sorted(work.glob("*.json")):
        if path.name.endswith(".vessel.json"):
            continue
        part = json.loads(path.read_text())
        vessel = vessel_mod.load(str(work / f"{path.stem}.vessel.json"))
        if vessel.sensors.yaw_rate_source != "gyro":
            continue
        name, wind = path.stem.rsplit("_", 1)
        *_, recs, _, preps, split, names = _split_runs(name)
        judged = split.pick(recs, names)[1]
        part["identified"]["r2_r_heading_slope"] = slope_r2(vessel, judged, part["settings"],
                                                            None if wind == "none" else wind)
        write_text_atomic(path, json.dumps(part, indent=1, default=float) + "\n")
        print(f"{path.stem}: r against the heading's slope {part['identified']['r2_r_heading_slope']:.3f}", flush=True)


def _split_runs(name: str):
    """The split's vessel name, settings, prior, recordings, their preparation as the prior's
    calibration reads them, the split and the recordings' names."""
    vessel_name, _ = SPLITS[name]
    prior = vessel_mod.load(vessel_name)
    recs = read(blueboat_paths() if vessel_name == "blueboat" else esso_paths())
    calibrated = calibrate(recs, prior)[0]
    preps = prepared(recs, calibrated)
    if name == "esso_low_rps":
        recs, split = _low_rps_runs(recs, preps)
        calibrated = calibrate(recs, prior)[0]
        preps = prepared(recs, calibrated)
        return vessel_name, SETTINGS[vessel_name], prior, recs, calibrated, preps, split, \
            [log_name(r.source) for r in recs]
    return vessel_name, SETTINGS[vessel_name], prior, recs, calibrated, preps, _split_of(name, recs, preps), \
        [log_name(r.source) for r in recs]


def _low_rps_runs(recs, preps):
    """The random tests' slow stretches (each a recording of its own, named FILE#k) and the turning
    tests, and the split that fits the first and judges the second."""
    fitted, judged = [], []
    for rec, prep in zip(recs, preps):
        name = log_name(rec.source)
        if name.startswith("random"):
            for k, (t0, t1) in enumerate(low_input_stretches(prep, LOW_RPS, LOW_STRETCH_S), 1):
                fitted.append(within(rec, t0, t1, f"{rec.source}#{k}"))
        elif name.startswith("turn"):
            judged.append(rec)
    split = Split(f"random ≤ {LOW_RPS:g} rps → turning",
                  f"the random tests' stretches of {LOW_STRETCH_S:g} s or more whose propeller stays at or below "
                  f"{LOW_RPS:g} rps fitted (each a recording FILE#k), the turning tests (8 and 10 rps) judged",
                  tuple(log_name(r.source) for r in fitted), tuple(log_name(r.source) for r in judged))
    return fitted + judged, split


def run_split(name: str, wind, work: Path) -> dict:
    vessel_name, settings, prior, recs, calibrated, preps, split, names = _split_runs(name)
    fit_recs, judged_recs = split.pick(recs, names)
    fit_preps, _ = split.pick(preps, names)
    seen = fitted_envelope(calibrated, fit_preps, settings["window_s"], settings["stride_s"])
    started = time.time()
    ident = identify(fit_recs, prior, wind=wind)
    seconds = time.time() - started
    out = {"split": split.to_dict(), "vessel": vessel_name, "wind": wind or "none", "settings": settings,
           "commit": checkout_commit(ROOT),
           "activity": [a.to_dict() for a in activities(preps)], "identify_seconds": round(seconds, 1),
           "chosen": ident.chosen.label if ident.chosen else None,
           "free_groups": list(ident.chosen.free_groups) if ident.chosen else [],
           "prior": scores(prior, judged_recs, settings, wind, seen),
           "identified": scores(ident.vessel, judged_recs, settings, wind, seen)}
    tag = f"{name}_{wind or 'none'}"
    vessel_mod.save(ident.vessel, work / f"{tag}.vessel.json")
    write_text_atomic(work / f"{tag}.json", json.dumps(out, indent=1, default=float) + "\n")
    return out


def run_reach(name: str, wind, work: Path) -> dict:
    """`twin identify` on a split's judged runs, scored on them (no band): the form's reach there."""
    _, settings, prior, recs, _, _, split, names = _split_runs(name)
    _, judged_recs = split.pick(recs, names)
    started = time.time()
    ident = identify(judged_recs, prior, wind=wind)
    seconds = time.time() - started
    calibrated = calibrate(judged_recs, ident.vessel)[0]
    metrics = evaluate(calibrated, prepared(judged_recs, calibrated), stride_s=settings["stride_s"],
                       horizons={"free_run": settings["window_s"]}, wind=wind)["free_run"]
    out = {"split": name, "split_name": split.to_dict()["name"], "wind": wind or "none", "commit": checkout_commit(ROOT), "identify_seconds": round(seconds, 1),
           "chosen": ident.chosen.label if ident.chosen else None, "r2": {d: metrics[d]["r2"] for d in DOFS}}
    write_text_atomic(work / f"{name}_{wind or 'none'}.reach", json.dumps(out, indent=1, default=float) + "\n")
    vessel_mod.save(ident.vessel, work / f"{name}_{wind or 'none'}.reach.vessel.json")  # for extrapolation_misfit
    return out


def _met(r2: dict, targets: dict) -> str:
    ok = [d for d in DOFS if r2[d] is not None and r2[d] >= targets[d]]
    return "all" if len(ok) == 3 else (", ".join(ok) if ok else "none")


def page(parts: list[dict], reach: dict | None = None) -> ResultPage:
    """reach: {(split, wind): run_reach's record} for the splits whose reach was measured."""
    reach = reach or {}
    rows, beyond_rows, band_rows = [], [], []
    for p in parts:
        targets = TARGETS[p["vessel"]]
        label = f"{p['split']['name']} ({p['vessel']})"
        for twin_name in ("prior", "identified"):
            s = p[twin_name]
            rows.append([label, p["wind"], twin_name, *[s["r2"][d] for d in DOFS],
                         _met(s["r2"], targets) if twin_name == "identified" else "–"])
        got = reach.get((p["split"]["name"], p["wind"]))
        if got:
            rows.append([label, p["wind"], "identified on the judged runs (reach)", *[got["r2"][d] for d in DOFS],
                         _met(got["r2"], targets)])
        b = p["identified"].get("beyond_fit") or {}
        if b.get("samples"):
            beyond_rows.append([label, p["wind"], b["share_of_samples"], *[b["share"][d] for d in DOFS],
                                *[(b.get("r2_beyond") or {}).get(d) for d in DOFS]])
        for key, name in (("band", "parameters and form error"), ("band_parameters_only", "parameters only")):
            if key in p["identified"]:
                band_rows.append([label, p["wind"], name, *[p["identified"][key][d] for d in DOFS]])
    slope_rows = [[f"{p['split']['name']} ({p['vessel']})", p["wind"], p["identified"]["r2"]["r"],
                   p["identified"]["r2_r_heading_slope"]] for p in parts if "r2_r_heading_slope" in p["identified"]]
    splits = {f"{p['split']['name']} ({p['vessel']})": p["split"] for p in parts}
    notes = [f"{name}: {s['rule']}; fitted {', '.join(s['fitted'])}; judged {', '.join(s['judged'])}."
             for name, s in splits.items()]
    notes += [f"Targets: BlueBoat 10-s R² u ≥ {TARGETS['blueboat']['u']}, v ≥ {TARGETS['blueboat']['v']}, "
              f"r ≥ {TARGETS['blueboat']['r']}; Esso Osaka 30-s R² u ≥ {TARGETS['esso_osaka']['u']}, "
              f"v ≥ {TARGETS['esso_osaka']['v']}, r ≥ {TARGETS['esso_osaka']['r']}."]
    if any(p["vessel"] == "esso_osaka" for p in parts):
        notes += ["The Esso Osaka's prior is not blind to the turning tests: its coefficient set (KVLCC2's, over the one "
                  "published for this model) was chosen because it matches the measured steady turns, and R'_0 is held at "
                  "0.35 m/s, the model's speed at 10 rps in these tests (twin/model/esso_osaka.json sources): its rows "
                  "check that prior; the identified rows say what fitting on the split's fitted runs does to it."]
    sources = {name: vessel_mod.load(name).sensors.yaw_rate_source for name in sorted({p["vessel"] for p in parts})}
    read_from = {"gyro": "the log's rate gyro (sensors.yaw_rate_source)",
                 "heading": "the heading's Savitzky-Golay slope"}
    notes += ["Measured r: " + "; ".join(f"{name} from {read_from[src]}" for name, src in sources.items()) + "."]
    notes += [f"{p['split']['name']} ({p['vessel']}, wind {p['wind']}): identify chose {p['chosen']} "
              f"in {p['identify_seconds']:.0f} s, computed at commit {p.get('commit', 'not recorded')}." for p in parts]
    if reach:
        notes += ["Reach: `twin identify` with its defaults on the judged runs themselves, scored on them the same way "
                  "(in-sample: an upper mark for what the twin's form does on those runs, not a prediction)."]
        notes += [f"reach of {name} (wind {wind}): identify chose {got['chosen']} in {got['identify_seconds']:.0f} s, "
                  f"computed at commit {got['commit']}." for (name, wind), got in sorted(reach.items())]
    return ResultPage(
        name="extrapolation", title="The twin beyond its training runs",
        ran="python scripts/extrapolation.py",
        data="the ten shared BlueBoat runs [BlueBoat-SI] and 23 Esso Osaka free-running tests [ESSO-FRT] "
             "(turn_cut_14-Sep-2020_15_58_08 left out: it repeats the first 287 s of another test)",
        summary="`twin identify` with its defaults on the runs of each split that go least far (fewer minutes under way and fewer "
                "turns, a lower propeller speed, another family of manoeuvres, or another day), judged on the runs that go "
                "further: R² of free runs from measured states, pooled over the judged runs, each log's compass "
                "calibration from its own kinematics. The untuned prior is judged the same way.",
        tables=[ResultTable("Free-run R² on the judged runs (10-s free runs for the BlueBoat, 30-s for the Esso Osaka)",
                            ["split", "wind", "twin", "R² u", "R² v", "R² r", "met"],
                            rows),
                ResultTable("Judged samples beyond the span of u, v, r the fit saw (identified twin): their share, "
                            "their part of 1 − R², and their own R²",
                            ["split", "wind", "share of samples", "share of 1 − R² u", "v", "r", "R² beyond u", "v",
                             "r"], beyond_rows),
                ResultTable("Share of the judged runs inside the identified twin's 90 % band (30-s free runs, "
                            f"{BAND_DRAWS} parameter draws)", ["split", "wind", "band", "u", "v", "r"], band_rows)]
        + ([ResultTable("The identified twin's R² r against the log's gyro (as scored above) and against the heading's "
                        "slope (`--slope`): what the gyro changes in the yardstick", ["split", "wind", "R² r (gyro)",
                                                                                   "R² r (heading's slope)"],
                        slope_rows)] if slope_rows else []),
        notes=notes, raw={"splits": parts, "reach": list(reach.values())})


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default=",".join(SPLITS))
    ap.add_argument("--work", type=Path, default=Path("/tmp/extrapolation"))
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "results")
    ap.add_argument("--page-only", action="store_true", help="write the page from the splits in --work")
    ap.add_argument("--slope", action="store_true", help="score the saved splits whose twin reads r from a gyro "
                                                          "also against the heading's slope, then write the page")
    ap.add_argument("--reach", action="store_true", help="identify on the judged runs of the --only splits and score "
                                                          "them there, instead of running the splits")
    args = ap.parse_args()
    if not blueboat_paths() or not esso_paths():
        print(f"the shared recordings are not in {DATA}: nothing to do")
        return 0
    args.work.mkdir(parents=True, exist_ok=True)
    if args.slope:
        add_slope_scores(args.work)
    elif args.reach and not args.page_only:
        for name in args.only.split(","):
            for wind in SPLITS[name][1]:
                got = run_reach(name, wind, args.work)
                print(f"{name} wind {wind or 'none'}: reach R² " + ", ".join(f"{d} {got['r2'][d]:.3f}" for d in DOFS)
                      + f" ({got['identify_seconds']:.0f} s to identify)", flush=True)
    elif not args.page_only:
        for name in args.only.split(","):
            for wind in SPLITS[name][1]:
                t0 = time.time()
                part = run_split(name, wind, args.work)
                r2 = part["identified"]["r2"]
                print(f"{name} wind {wind or 'none'}: identified R² " + ", ".join(f"{d} {r2[d]:.3f}" for d in DOFS)
                      + f" ({time.time() - t0:.0f} s)", flush=True)
    parts = [json.loads(p.read_text()) for p in sorted(args.work.glob("*.json")) if not p.name.endswith(".vessel.json")]
    parts.sort(key=lambda p: (p["vessel"], p["split"]["name"], p["wind"]))
    reach = {(g["split_name"], g["wind"]): g for g in (json.loads(p.read_text()) for p in args.work.glob("*.reach"))}
    print(f"wrote {page(parts, reach).write(args.out)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
