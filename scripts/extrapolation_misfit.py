"""Where the twins of the extrapolation study miss beyond their runs, by the measured state of each
sample: the BlueBoat's sway and yaw on its five most active runs, the Esso Osaka's yaw and sway on its random
tests for a twin fitted on the turning tests.

    python scripts/extrapolation_misfit.py [--work /tmp/extrapolation] [--out docs/results]

Reads the twins scripts/extrapolation.py saved in --work (blueboat_activity_none.vessel.json,
esso_turn_random_measured.vessel.json, and where `--reach` saved it the twin identified on the judged
runs themselves, TAG.reach.vessel.json) and the judged runs of those splits; bands the free runs'
samples by speed, yaw rate, propeller speed and how long the propeller has been stopped
(twin.fit.evaluate.misfit_by_state), and moves one coefficient at a time on the judged runs to show
which part of the form the misfit answers to. That last table is read on the judged runs: it
chooses nothing and fits nothing. Without ../shared/data it says so and exits 0.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "scripts"))

import extrapolation as study  # noqa: E402
import twin.vessel as vessel_mod  # noqa: E402
from twin.fit.evaluate import evaluate, misfit_by_state  # noqa: E402
from twin.fit.metrics import DOFS  # noqa: E402
from twin.ident.identify import calibrate, prepared  # noqa: E402
from twin.viz.pages import ResultPage, ResultTable  # noqa: E402

# (split, wind, the DOF the target misses, free-run length s, stride s)
CASES = {"blueboat": ("blueboat_activity", None, "v", 10.0, 2.0),
         "esso": ("esso_turn_random", "measured", "r", 30.0, 10.0)}
# the DOF whose gain and correlation are shown beside the missed one's: the one it is coupled with
SECOND = {"blueboat": "r", "esso": "v"}
BANDS = {"blueboat": [("speed √(u² + v²)", "speed_m_s", (0.2, 0.6, 1.2)),
                      ("yaw rate |r|", "yaw_rate_rad_s", (0.1, 0.3, 0.6))],
         "esso": [("propeller speed", "input_0", (-1.0, 1.0, 6.0)),
                  ("time the propeller has been stopped (|n| ≤ 1 rps)", "input_0_rest_s", (0.05, 2.0, 5.0, 10.0)),
                  ("speed √(u² + v²)", "speed_m_s", (0.05, 0.1, 0.2)),
                  # the hull polynomial's own domain ends near 30° (physics/mmg.py)
                  ("drift angle |β|", "drift_rad", (math.radians(10), math.radians(30), math.radians(60)))]}


def tag_of(case: str) -> str:
    """The name extrapolation.py saved the split's twin under."""
    name, wind, *_ = CASES[case]
    return f"{name}_{wind or 'none'}"


def judged(case: str):
    """The split's judged recordings."""
    _, _, _, recs, _, _, split, names = study._split_runs(CASES[case][0])
    return split.pick(recs, names)[1]


def _scored(vessel, recs, wind, horizon_s: float, stride_s: float) -> dict:
    calibrated = calibrate(recs, vessel)[0]
    m = evaluate(calibrated, prepared(recs, calibrated), stride_s=stride_s, horizons={"h": horizon_s}, wind=wind)["h"]
    return {d: m[d]["r2"] for d in DOFS}


def _bands(vessel, recs, case: str) -> list[dict]:
    _, wind, dof, horizon_s, stride_s = CASES[case]
    calibrated = calibrate(recs, vessel)[0]
    preps = prepared(recs, calibrated)
    out = []
    for title, state, edges in BANDS[case]:
        for b in misfit_by_state(calibrated, preps, horizon_s, state, edges, stride_s=stride_s, wind=wind):
            out.append({"by": title, "band": b.label, "samples": b.samples, "share": b.share,
                        "rms": b.rms_error[dof], "gain": b.gain[dof], "correlation": b.correlation[dof],
                        "second": {"dof": SECOND[case], "gain": b.gain[SECOND[case]],
                                   "correlation": b.correlation[SECOND[case]]}})
    return out


MOVED_FACTOR = 1.5  # a coefficient the two twins hold this many times apart (or of other signs) is listed


def moved(prior, fitted, reached) -> list[dict]:
    """The hull and thruster coefficients the twin identified on the judged runs holds MOVED_FACTOR
    or more times from the split's twin (or of the other sign), with the prior's value."""
    def blocks(v):
        parts = {s: getattr(v, s) for s in ("damping", "added_mass", "thrusters")}
        if v.mmg is not None:  # a propeller-and-rudder ship: its hull, propeller and rudder blocks and particulars
            parts |= {"mmg": v.mmg, **{f"mmg.{k}": getattr(v.mmg, k) for k in ("hull", "propeller", "rudder")}}
        return parts

    out = []
    ours, theirs, first = blocks(reached), blocks(fitted), blocks(prior)
    for section, block in ours.items():
        for name, value in vars(block).items():
            a, p = getattr(theirs[section], name), getattr(first[section], name)
            if not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in (value, a, p)):
                continue
            if a == value or (a == 0.0 and value == 0.0):
                continue
            far = (a * value < 0) or max(abs(a), abs(value)) >= MOVED_FACTOR * min(abs(a), abs(value))
            if far:
                out.append({"name": name, "prior": p, "split": a, "reach": value})
    return out


def sensitivities(case: str, vessel, prior, recs) -> list[dict]:
    """One coefficient moved at a time, scored on the judged runs."""
    _, wind, _, horizon_s, stride_s = CASES[case]
    if case == "blueboat":
        d = vessel.damping
        moves = [("identified", vessel), ("Yur × 0", replace(vessel, damping=replace(d, Yur=0.0))),
                 ("Yur × 2", replace(vessel, damping=replace(d, Yur=2.0 * d.Yur))),
                 ("Yv at the prior's", replace(vessel, damping=replace(d, Yv=prior.damping.Yv)))]
        # the yaw's timing: its added inertia and the thrust lag, neither pinned by the least active runs
        a, t = vessel.added_mass, vessel.thrusters
        moves += [(f"Nrdot × {k} (identified {a.Nrdot:.3g} kg·m²)", replace(vessel, added_mass=replace(a, Nrdot=k * a.Nrdot)))
                  for k in (2, 4)]
        moves += [(f"thrust lag {lag:g} s (identified {t.lag_s:.2g})", replace(vessel, thrusters=replace(t, lag_s=lag)))
                  for lag in (0.2, 0.4)]
        # the yaw damping that grows with the speed, which the least active runs (seldom fast) leave at its prior
        moves += [(f"Nur × {k:g} (identified {d.Nur:.3g} N·m·s²/m, prior {prior.damping.Nur:.3g})",
                   replace(vessel, damping=replace(d, Nur=k * d.Nur))) for k in (1.5, 2.0)]
    else:
        m = vessel.mmg
        moves = [("identified", vessel)] + [(f"U floor {u:g} m/s (identified {m.low_speed_m_s:g})",
                                             replace(vessel, mmg=replace(m, low_speed_m_s=u))) for u in (0.01, 0.15)]
        moves.append((f"hull polynomial as it is at every drift (drift domain 90°, identified {m.drift_domain_deg:g}°)",
                      replace(vessel, mmg=replace(m, drift_domain_deg=90.0))))
    return [{"twin": label, "r2": _scored(v, recs, wind, horizon_s, stride_s)} for label, v in moves]


def page(raw: dict) -> ResultPage:
    tables = []
    at = sorted({p["identified_at"] or "unknown" for p in raw["cases"].values()})
    for case, part in raw["cases"].items():
        name, wind, dof, horizon_s, _ = CASES[case]
        r2 = part["sensitivity"][0]["r2"]
        second = part["bands"][0].get("second", {}).get("dof") if part["bands"] else None
        tables.append(ResultTable(
            f"{part['tag']}: {horizon_s:g}-s free runs of the identified twin on the judged runs (R² u {r2['u']:.3f}, "
            f"v {r2['v']:.3f}, r {r2['r']:.3f}), by measured state: share of the samples, each DOF's share of 1 − R² "
            f"(the bands of one state add up to 1 − R²), {dof}'s RMS error, gain (measured on predicted) and "
            "correlation of measured and predicted (a gain away from 1 at a correlation near 1: the twin's shape at "
            "the wrong size)" + (f", and {second}'s gain and correlation" if second else ""),
            ["state", "band", "samples", "share u", "share v", "share r", f"RMS {dof}", f"gain {dof}",
             f"correlation {dof}", *([f"gain {second}", f"correlation {second}"] if second else [])],
            [[row["by"], row["band"], row["samples"], row["share"]["u"], row["share"]["v"], row["share"]["r"],
              row["rms"], row["gain"], row.get("correlation"),
              *([row["second"]["gain"], row["second"]["correlation"]] if second else [])] for row in part["bands"]]))
        if "reach" in part:
            reach = part["reach"]
            tables.append(ResultTable(
                f"{part['tag']}: the same form identified on the judged runs themselves (the form's reach there: "
                f"R² u {reach['r2']['u']:.3f}, v {reach['r2']['v']:.3f}, r {reach['r2']['r']:.3f}), by measured state "
                f"as above: {dof}'s gain and correlation" + (f", and {second}'s" if second else ""),
                ["state", "band", "samples", f"gain {dof}", f"correlation {dof}",
                 *([f"gain {second}", f"correlation {second}"] if second else [])],
                [[row["by"], row["band"], row["samples"], row["gain"], row.get("correlation"),
                  *([row["second"]["gain"], row["second"]["correlation"]] if second else [])]
                 for row in reach["bands"]]))
            tables.append(ResultTable(
                f"{part['tag']}: the coefficients the twin identified on the judged runs holds {MOVED_FACTOR:g} times "
                "or more from the split's twin (or of the other sign)",
                ["coefficient", "prior", "the split's twin", "identified on the judged runs"],
                [[m["name"], m["prior"], m["split"], m["reach"]] for m in reach["moved"]] or [["none", "", "", ""]]))
        tables.append(ResultTable(
            f"{part['tag']}: one coefficient moved, scored on the judged runs (a sensitivity; it fits and chooses "
            "nothing)", ["twin", "R² u", "R² v", "R² r"],
            [[row["twin"], *(row["r2"][d] for d in DOFS)] for row in part["sensitivity"]]))
    return ResultPage(
        name="extrapolation_misfit", title="Where the twins miss beyond their runs",
        ran="python scripts/extrapolation_misfit.py",
        data="the twins `python scripts/extrapolation.py` identified: the BlueBoat's on its five least active runs "
             "[BlueBoat-SI], judged on its five most active; the Esso Osaka's on its turning tests with their "
             f"measured wind [ESSO-FRT], judged on its random tests (identified at commit {', '.join(at)})",
        summary="Each judged sample of the study's free runs, banded by the state the vessel measured there "
                "(twin.fit.evaluate.misfit_by_state): where a band's share of 1 − R² exceeds its share of the "
                "samples, the twin's form misses there; a gain above 1 says the vessel moves more than the twin.",
        tables=tables, raw=raw)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", type=Path, default=Path("/tmp/extrapolation"))
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "results")
    ap.add_argument("--page-only", action="store_true", help="write the page again from its published figures "
                                                             "(--out/data/extrapolation_misfit.json)")
    args = ap.parse_args()
    if args.page_only:
        published = args.out / "data" / "extrapolation_misfit.json"
        if not published.is_file():
            print(f"error: no {published}: run the study first", file=sys.stderr)
            return 2
        figures = json.loads(published.read_text())
        meta = figures.pop("meta")
        again = replace(page(figures), figures_of=(meta["date"], meta["commit"]),
                        raw_file="data/extrapolation_misfit.json",
                        ran="python scripts/extrapolation_misfit.py --page-only")
        print(f"wrote {again.write(args.out)}")
        return 0
    if not study.blueboat_paths() or not study.esso_paths():
        print(f"the shared recordings are not in {study.DATA}: nothing to do")
        return 0
    missing = [f"{tag_of(c)}.vessel.json" for c in CASES if not (args.work / f"{tag_of(c)}.vessel.json").is_file()]
    if missing:
        print(f"error: no {', '.join(missing)} in {args.work}: run `python scripts/extrapolation.py --work "
              f"{args.work}` first", file=sys.stderr)
        return 2
    raw = {"cases": {}}
    for case in CASES:
        tag, recs = tag_of(case), judged(case)
        path = args.work / f"{tag}.vessel.json"
        vessel = vessel_mod.load(str(path))
        prior = vessel_mod.load(study.SPLITS[CASES[case][0]][0])
        split_file = args.work / f"{tag}.json"
        identified_at = json.loads(split_file.read_text()).get("commit") if split_file.is_file() else None
        raw["cases"][case] = {"tag": tag, "identified_at": identified_at, "bands": _bands(vessel, recs, case),
                              "sensitivity": sensitivities(case, vessel, prior, recs)}
        reach = args.work / f"{tag}.reach.vessel.json"
        if reach.is_file():  # `extrapolation.py --reach` saved it: the same form identified on the judged runs
            reached = vessel_mod.load(str(reach))
            _, wind, _, horizon_s, stride_s = CASES[case]
            raw["cases"][case]["reach"] = {"bands": _bands(reached, recs, case),
                                           "r2": _scored(reached, recs, wind, horizon_s, stride_s),
                                           "moved": moved(prior, vessel, reached)}
        print(f"{tag}: banded", flush=True)
    print(f"wrote {page(raw).write(args.out)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
