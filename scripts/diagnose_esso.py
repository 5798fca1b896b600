"""The concealed wind on the Esso Osaka's tests, found by `twin diagnose` without
the anemometer, then checked against it.

    python scripts/diagnose_esso.py [--only NAME,...] [--out docs] [--hulls /tmp/esso_ident]

Each test is diagnosed alone from the untuned `esso_osaka` twin; the diagnosis reads positions,
heading and the propeller's and rudder's inputs, never the wind columns. Per test: the
anemometer's mean true wind over the test (vector mean of the air's velocity: speed, and the
direction it blows FROM, clockwise from the pond's x0 = north), whether the diagnosis names wind,
and its estimate beside the anemometer's: the named effect's values, or, when wind is not named,
the wind candidate's own fits (one per fold, their median), with the held-out evidence (z, blocks
for and against). Then the 30-s free-run R² of the twin without wind, with the anemometer's
measured wind as a known input (nothing fitted), and with the diagnosis's constant wind (fitted
on this test: in sample). The duplicate turn_cut_14-Sep-2020_15_58_08 is left out. The
recordings (../shared/data/esso) are read in place; without them the script says so and exits 0.

Then, beside what the issue asks (each test alone), what a user with a day's tests would run:
`twin diagnose` on all tests of one day together, offered one constant wind for the day and a wind
of each test's own (`wind_per_log`, fitted together, judged on the day's pooled blocks); each
estimate compared with each test's anemometer mean and the day's (--by-day only runs this part).

With --hulls DIR, each test is diagnosed instead from the twin `scripts/identify_esso.py` identified
on the OTHER family of tests with their measured wind as a known input (DIR/esso_turn_measured.
vessel.json for a random test, esso_random_measured for a turning one): the hull calibrated on runs
whose wind was measured, as `--wind-measured` is meant for, then a new test diagnosed
without its anemometer. No test's own data, wind or otherwise, reaches the twin it is diagnosed
from. The report is written to esso_wind_diagnosis_calibrated.{md,json} beside the untuned one.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import twin.vessel as vessel_mod  # noqa: E402
from twin.diagnose.doctor import diagnose, measured_wind_evidence  # noqa: E402
from twin.effects import apply_effects  # noqa: E402
from twin.errors import TwinError  # noqa: E402
from twin.files import write_text_atomic  # noqa: E402
from twin.fit.evaluate import evaluate  # noqa: E402
from twin.formats import read_recording  # noqa: E402
from twin.ident.identify import prepared  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "esso"
DUPLICATE = "turn_cut_14-Sep-2020_15_58_08.csv"
HORIZON = {"free_run_30s": 30.0}
STRIDE_S = 10.0
WINDY_M_S, CALM_M_S = 1.5, 0.8  # the study's thresholds on the mean true wind
DIRECTION_DEG, SPEED_SHARE = 30.0, 0.4  # the study's tolerances


def anemometer(*preps) -> dict:
    """Mean true wind of the tests: the air's mean NED velocity → speed and direction FROM (deg)."""
    air = np.vstack([p.wind_ned[np.all(np.isfinite(p.wind_ned), axis=1)] for p in preps])
    north, east = air.mean(axis=0)
    return {"speed_m_s": float(math.hypot(north, east)), "from_deg": _from_deg(north, east),
            "scalar_mean_m_s": float(np.mean(np.hypot(air[:, 0], air[:, 1])))}


def family_of(name: str) -> str:
    return "random" if name.startswith("random") else "turn"


HULL_FILES = {"random": "esso_turn_measured.vessel.json", "turn": "esso_random_measured.vessel.json"}


def load_hulls(directory: Path) -> dict:
    """The twin each family is diagnosed from (module docstring), with where it came from: {family:
    (vessel, {"file", "sha256"})}. TwinError when a file is missing or not a vessel."""
    out = {}
    for fam, name in HULL_FILES.items():
        path = directory / name
        if not path.is_file():
            raise TwinError(f"{directory}: no {name} (run scripts/identify_esso.py --work {directory} first)")
        out[fam] = (vessel_mod.load(str(path)), {"file": name, "sha256": hashlib.sha256(path.read_bytes()).hexdigest()})
    return out


def hull_for(name: str, hulls: dict | None, prior):
    """The twin a test is diagnosed from: the prior, or its family's entry of load_hulls."""
    return prior if hulls is None else hulls[family_of(name)][0]


def _from_deg(air_north: float, air_east: float) -> float:
    return float(math.degrees(math.atan2(-air_east, -air_north)) % 360.0)


def wind_estimate(d) -> dict | None:
    """The wind the diagnosis named, or the wind candidate's fits when it was not named."""
    named = next((e for e in d.effects if e["name"] == "wind"), None)
    if named is not None:
        p = named["parameters"]
        return {"named": True, "speed_m_s": float(p["speed_m_s"]), "from_deg": float(p["dir_deg"]) % 360.0}
    rounds = d.to_dict()["rounds"]
    cand = next((c for c in rounds[0]["candidates"] if c["name"] == "wind"), None) if rounds else None
    if cand is None:
        return None
    north = float(np.median([f["wind_north"] for f in cand["fold_values"]]))
    east = float(np.median([f["wind_east"] for f in cand["fold_values"]]))
    return {"named": False, "speed_m_s": math.hypot(north, east), "from_deg": _from_deg(north, east),
            "z": cand["z"], "blocks_for": cand["blocks_for"], "blocks_against": cand["blocks_against"],
            "excess_gain": cand["excess_gain"]}


def measured_evidence(path: Path, prior) -> dict:
    """The test's own anemometer wind as a known input, judged by the diagnosis's rule (blocks, z,
    share of the excess): how one test's blocks judge the wind as it blew."""
    e = measured_wind_evidence([read_recording(path)], prior)
    return {"z": round(e.z, 2), "excess_gain": round(e.rel_excess, 4), "blocks_for": e.blocks_for,
            "blocks_against": e.blocks_against, "earns_its_place": bool(e.earns_its_place())}


def log_wind_estimates(d, logs: list[str]) -> dict | None:
    """Each log's own wind: the named `wind_per_log`'s values, or its candidate's fits (median over
    the folds) when it was not named; None when the diagnosis had no such candidate."""
    named = next((e for e in d.effects if e["name"] == "wind_per_log"), None)
    if named is not None:
        p = named["parameters"]
        return {"named": True, "per_log": {n: {"speed_m_s": float(p[f"{n} speed_m_s"]),
                                               "from_deg": float(p[f"{n} dir_deg"]) % 360.0} for n in logs},
                "z": named["z"], "excess_gain": named["excess_gain"]}
    rounds = d.to_dict()["rounds"]
    cand = next((c for c in rounds[0]["candidates"] if c["name"] == "wind_per_log"), None) if rounds else None
    if cand is None:
        return None
    per_log = {}
    for n in logs:
        north = float(np.median([f[f"{n}@wind_north"] for f in cand["fold_values"]]))
        east = float(np.median([f[f"{n}@wind_east"] for f in cand["fold_values"]]))
        per_log[n] = {"speed_m_s": math.hypot(north, east), "from_deg": _from_deg(north, east)}
    return {"named": False, "per_log": per_log, "z": cand["z"], "blocks_for": cand["blocks_for"],
            "blocks_against": cand["blocks_against"], "excess_gain": cand["excess_gain"]}


def agrees(est: dict | None, ref: dict) -> bool | None:
    if est is None:
        return None
    diff = abs((est["from_deg"] - ref["from_deg"] + 180.0) % 360.0 - 180.0)
    return diff <= DIRECTION_DEG and abs(est["speed_m_s"] - ref["speed_m_s"]) <= SPEED_SHARE * ref["speed_m_s"]


def run_test(path: Path, prior) -> dict:
    started = time.time()
    rec = read_recording(path)
    prep = prepared([rec], prior)[0]
    ref = anemometer(prep)
    d = diagnose([rec], prior)
    est = wind_estimate(d)
    fits = {"none": evaluate(prior, [prep], stride_s=STRIDE_S, horizons=HORIZON)["free_run_30s"],
            "measured": evaluate(prior, [prep], stride_s=STRIDE_S, horizons=HORIZON, wind="measured")["free_run_30s"]}
    if est is not None:
        with_wind = apply_effects(prior, [f"wind={est['speed_m_s']:.4f},{est['from_deg']:.2f}"])
        fits["diagnosed_constant"] = evaluate(with_wind, prepared([rec], with_wind), stride_s=STRIDE_S,
                                              horizons=HORIZON)["free_run_30s"]
    return {"test": path.name, "anemometer": ref, "named": [e["name"] for e in d.effects], "wind": est,
            "agrees": agrees(est, ref), "held_out_before": d.fit_before, "held_out_after": d.fit_after,
            "fits_30s": fits, "seconds": round(time.time() - started, 1)}


def day_of(name: str) -> str:
    """The test's date from its file name (random_06-Aug-2020_16_24_25_1.csv → 06-Aug-2020); a name
    without one is a day of its own."""
    return next((part for part in name.split("_") if part.count("-") == 2), name)


def run_day(day: str, paths: list[Path], prior) -> dict:
    """All tests of one day diagnosed together: one wind for the day."""
    started = time.time()
    recs = [read_recording(p) for p in paths]
    preps = prepared(recs, prior)
    refs = [anemometer(p) for p in preps]
    day_ref = anemometer(*preps)
    d = diagnose(recs, prior)
    est = wind_estimate(d)
    per_log = log_wind_estimates(d, [p.name for p in paths])
    return {"day": day, "tests": [p.name for p in paths], "anemometer_per_test": refs, "anemometer_day": day_ref,
            "wind_per_log": per_log,
            "agrees_per_log": None if per_log is None else [agrees(per_log["per_log"][p.name], r)
                                                            for p, r in zip(paths, refs)],
            "named": [e["name"] for e in d.effects],
            "named_effects": [{"name": e["name"], "parameters": e["parameters"], "text": e["text"],
                               "not_separable_from": [r["name"] for r in e["rivals"] if not r["separable"]]}
                              for e in d.effects],
            "wind": est, "agrees_day": agrees(est, day_ref),
            "agrees_per_test": [agrees(est, r) for r in refs], "held_out_before": d.fit_before,
            "held_out_after": d.fit_after, "seconds": round(time.time() - started, 1)}


def _named_text(e: dict) -> str:
    text = "wind_per_log (each test's: the table below)" if e["name"] == "wind_per_log" else e["text"]
    rivals = e.get("not_separable_from") or []
    return text + (f" (not separable from {', '.join(rivals)})" if rivals else "")


def _current_dirs(day: dict) -> list[float]:
    """Directions (towards, deg) of the currents a day's diagnosis named."""
    return [float(e["parameters"]["dir_deg"]) for e in day["named_effects"] if e["name"] == "current"]


def _angle(a_deg: float, b_deg: float) -> float:
    return abs((a_deg - b_deg + 180.0) % 360.0 - 180.0)


def day_summary(days: list[dict]) -> dict:
    windy = [(d, r, a) for d in days for r, a in zip(d["anemometer_per_test"], d["agrees_per_test"])
             if r["scalar_mean_m_s"] >= WINDY_M_S]
    named = [(d, r, a) for d, r, a in windy if d["wind"] and d["wind"]["named"]]
    per_log = [(r, a, bool(d["wind_per_log"] and d["wind_per_log"]["named"])) for d in days if d.get("agrees_per_log")
               for r, a in zip(d["anemometer_per_test"], d["agrees_per_log"]) if r["scalar_mean_m_s"] >= WINDY_M_S]
    return {"days": len(days), "tests": sum(len(d["tests"]) for d in days), "windy": len(windy),
            "windy_per_log_named": sum(n for _, _, n in per_log),
            "windy_per_log_named_agreeing": sum(bool(a) and n for _, a, n in per_log),
            "windy_per_log_estimate_agreeing_named_or_not": sum(bool(a) for _, a, _ in per_log),
            "windy_named": len(named), "windy_named_agreeing": sum(bool(a) for _, _, a in named),
            "windy_estimate_agreeing_named_or_not": sum(bool(a) for _, _, a in windy),
            "other_effects_named": sorted({n for d in days for n in d["named"] if n not in ("wind", "wind_per_log")})}


def day_markdown(days: list[dict], s: dict) -> str:
    lines = ["", "## A day's tests diagnosed together (what a user with several logs would run)", "",
             "Not what the study's target asks (each test alone): `twin diagnose` on all tests of one day at once. "
             "It is offered one constant wind for the day (`wind`) and a wind of each test's own (`wind_per_log`: "
             "two numbers per test, fitted together, judged on the day's pooled held-out blocks by the same rule "
             "as any effect); their estimates are compared with each test's anemometer mean (the same tolerances) "
             "and the day's. The evidence is pooled over more blocks than one test has.", "",
             f"- days with two or more tests: {s['days']} ({s['tests']} tests; {s['windy']} of them windy)",
             f"- **wind named for the day on {s['windy_named']} of {s['windy']} windy tests**, its estimate within "
             f"the tolerances of that test's anemometer on {s['windy_named_agreeing']}; the day's wind candidate (named "
             f"or not) within them on {s['windy_estimate_agreeing_named_or_not']} of the {s['windy']}",
             f"- **each test's own wind (`wind_per_log`, one wind per test, fitted together with the day's "
             f"other tests) named on {s.get('windy_per_log_named', 0)} of {s['windy']} windy tests**, "
             f"{s.get('windy_per_log_named_agreeing', 0)} of them within the tolerances of that test's anemometer; "
             f"the candidate's own estimate (named or not) within them on "
             f"{s.get('windy_per_log_estimate_agreeing_named_or_not', 0)} of the {s['windy']}",
             f"- other effects named: {', '.join(s['other_effects_named']) or 'none'}"] + [
             f"- {d['day']}: the named current flows towards {c % 360:.0f}°, {_angle(c, d['anemometer_day']['from_deg'] + 180):.0f}° "
             "from downwind: the wind's drift under another name (the pond has no current)"
             for d in days for c in _current_dirs(d)] + ["",
             "| day | tests | anemometer: the day's vector mean m/s from ° | named | wind estimate m/s from ° (z, blocks +/−, "
             "share of the misfit above the noise removed) | "
             "agrees: day / tests | held-out R² u / v / r before → after | s |", "|---|---|---|---|---|---|---|---|"]
    for d in days:
        a, w = d["anemometer_day"], d["wind"]
        est = "-" if w is None else (f"{w['speed_m_s']:.2f} from {w['from_deg']:.0f}" + (
            "" if w["named"] else f" (z {w['z']:.2f}, {w['blocks_for']}/{w['blocks_against']}, "
                                  f"{100 * w['excess_gain']:.1f} % of the excess)"))
        per = sum(bool(x) for x in d["agrees_per_test"])
        fit = " / ".join(f"{_r2(d['held_out_before'].get(k))} → {_r2(d['held_out_after'].get(k))}" for k in "uvr")
        lines.append(f"| {d['day']} | {len(d['tests'])} | {a['speed_m_s']:.2f} from {a['from_deg']:.0f} | "
                     f"{'; '.join(_named_text(e) for e in d['named_effects']) or '-'} | {est} | {'yes' if d['agrees_day'] else 'no'} / {per} of "
                     f"{len(d['tests'])} | {fit} | {d['seconds']} |")
    lines += ["", "Each test's own wind in its day's diagnosis (`wind_per_log`) beside its anemometer:", "",
              "| day | test | anemometer: vector mean m/s from ° | own wind estimate m/s from ° | agrees | "
              "named (z, blocks +/−, share of the misfit above the noise removed, for the day) |",
              "|---|---|---|---|---|---|"]
    for d in days:
        w = d.get("wind_per_log")
        if not w:
            continue
        ev = f"z {w['z']:.2f}" + (f", {w['blocks_for']}/{w['blocks_against']}" if "blocks_for" in w else "") + \
            f", {100 * w['excess_gain']:.1f} %"
        for name, ref, ok in zip(d["tests"], d["anemometer_per_test"], d["agrees_per_log"]):
            e = w["per_log"][name]
            lines.append(f"| {d['day']} | {name} | {ref['speed_m_s']:.2f} from {ref['from_deg']:.0f} | "
                         f"{e['speed_m_s']:.2f} from {e['from_deg']:.0f} | {'yes' if ok else 'no'} | "
                         f"{'yes' if w['named'] else 'no'} ({ev}) |")
    return "\n".join(lines) + "\n"


def summary(rows: list[dict]) -> dict:
    # windy or calm by the mean wind speed (the "mean true wind"); the estimate is compared with
    # the vector mean, the one constant wind a test's varying wind averages to
    windy = [r for r in rows if r["anemometer"]["scalar_mean_m_s"] >= WINDY_M_S]
    calm = [r for r in rows if r["anemometer"]["scalar_mean_m_s"] < CALM_M_S]
    named = [r for r in windy if r["wind"] and r["wind"]["named"]]
    return {"tests": len(rows), "windy": len(windy), "windy_named": len(named),
            "windy_named_agreeing": sum(bool(r["agrees"]) for r in named),
            "windy_estimate_agreeing_named_or_not": sum(bool(r["agrees"]) for r in windy),
            "calm": len(calm), "calm_with_wind_named": sum(bool(r["wind"] and r["wind"]["named"]) for r in calm),
            "other_effects_named": sorted({n for r in rows for n in r["named"] if n != "wind"}),
            "windy_measured_wind_judged": sum("measured_wind_evidence" in r for r in windy),
            "windy_measured_wind_earns": sum(bool(r.get("measured_wind_evidence", {}).get("earns_its_place"))
                                             for r in windy)}


def _r2(m: dict | None) -> str:
    return "-" if not m or m.get("r2") is None else f"{m['r2']:.2f}"


def markdown(rows: list[dict], s: dict, hulls: str | None = None) -> str:
    source = ("untuned `esso_osaka` twin" if not hulls else
              f"{hulls}: a random test from the twin identified on the turning tests, a turning test from the one "
              "identified on the random tests, each with those tests' measured wind as a known input, so that no "
              "test's own data reaches the twin it is diagnosed from")
    lines = ["# The concealed wind on the Esso Osaka's tests" + (
             ": from a hull calibrated on other tests" if hulls else ""), "",
             f"Written by `python scripts/diagnose_esso.py{' --hulls DIR' if hulls else ''}`. Each test diagnosed "
             f"alone by `twin diagnose` from {'the ' if not hulls else ''}{source}; the diagnosis reads no wind "
             "column; its wind checked against the anemometer's mean "
             "true wind over the test: windy or calm by its mean speed, the estimate compared with its vector mean "
             "(speed, direction FROM, clockwise from the pond's x0 = north). Targets: "
             f"wind named on ≥ 70 % of the tests whose mean true wind is ≥ {WINDY_M_S} m/s, its direction within "
             f"{DIRECTION_DEG:g}° and speed within {100 * SPEED_SHARE:g} %; nothing wind-like named below "
             f"{CALM_M_S} m/s. The candidates a diagnosis offers this ship: current, wind, and the sensor effects "
             "(the PWM thruster effects and the [Morel-2024] damping scales do not apply to it).", "",
             f"- tests: {s['tests']}; with mean true wind ≥ {WINDY_M_S} m/s: {s['windy']}; below {CALM_M_S} m/s: "
             f"{s['calm']}" + (" (none is that calm, so the calm criterion is untested)" if not s["calm"] else
                                f", wind named on {s['calm_with_wind_named']} of them"),
             f"- **wind named on {s['windy_named']} of {s['windy']} windy tests** (target ≥ 70 %), "
             f"{s['windy_named_agreeing']} of them within the tolerances",
             f"- the wind candidate's own estimate (named or not) within the tolerances on "
             f"{s['windy_estimate_agreeing_named_or_not']} of {s['windy']} windy tests",
             f"- other effects named anywhere: {', '.join(s['other_effects_named']) or 'none'}"] + ([
             f"- **the test's own anemometer wind**, put into the twin as a known input (the wind as it blew, nothing "
             f"fitted) and judged by the same rule against the twin without wind, earns its place on "
             f"{s['windy_measured_wind_earns']} of {s['windy_measured_wind_judged']} windy tests: even the true wind, "
             f"through this twin, is proven by one test's blocks on few tests (`--measured-evidence`)"] if s.get("windy_measured_wind_judged") else []) + [
             "",
             "| test | anemometer: mean speed; vector mean m/s from ° | named | wind estimate m/s from ° (z, blocks +/−) | agrees | "
             "measured wind judged by the rule (z, blocks +/−, share of the excess) | "
             "30-s R² u / v / r: no wind | measured wind | diagnosed constant wind (in sample) | s |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        a, w, f = r["anemometer"], r["wind"], r["fits_30s"]
        est = "-" if w is None else (f"{w['speed_m_s']:.2f} from {w['from_deg']:.0f}" +
                                     ("" if w["named"] else f" (z {w['z']:.2f}, {w['blocks_for']}/{w['blocks_against']})"))
        cell = {k: " / ".join(_r2(f.get(k, {}).get(d)) for d in "uvr") for k in ("none", "measured", "diagnosed_constant")}
        m = r.get("measured_wind_evidence")
        judged = "-" if not m else (f"z {m['z']:.2f}, {m['blocks_for']}/{m['blocks_against']}, "
                                    f"{100 * m['excess_gain']:.1f} %" + (" (earns)" if m["earns_its_place"] else ""))
        lines.append(f"| {r['test']} | {a['scalar_mean_m_s']:.2f}; {a['speed_m_s']:.2f} from {a['from_deg']:.0f} | {', '.join(r['named']) or '-'} | "
                     f"{est} | {'-' if r['agrees'] is None else ('yes' if r['agrees'] else 'no')} | {judged} | {cell['none']} | "
                     f"{cell['measured']} | {cell['diagnosed_constant']} | {r['seconds']} |")
    return "\n".join(lines) + "\n"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="", help="comma-separated test file names")
    ap.add_argument("--out", type=Path, default=ROOT / "out")
    ap.add_argument("--render", type=Path, help="only write the report again from this script's JSON")
    ap.add_argument("--measured-evidence", action="store_true",
                    help="only each test's measured wind judged by the diagnosis's rule (rows and days kept from "
                         "--out's JSON)")
    ap.add_argument("--hulls", type=Path, help="diagnose each test from the twin scripts/identify_esso.py identified "
                    "on the other family with measured wind (its --work directory)")
    ap.add_argument("--by-day", action="store_true",
                    help="only the days' pooled diagnoses (the tests' rows are kept from --out's JSON)")
    args = ap.parse_args()
    if args.render:
        if not args.render.is_file():
            print(f"error: {args.render}: no such file", file=sys.stderr)
            return 2
        old = json.loads(args.render.read_text())
        return _write(args.out, old["tests"], old.get("days", []), old.get("hulls"))
    if not DATA.is_dir():
        print(f"no Esso recordings at {DATA}: nothing to do")
        return 0
    only = {s.strip() for s in args.only.split(",") if s.strip()}
    prior = vessel_mod.load("esso_osaka")
    hulls, twins = None, None
    if args.hulls:
        try:
            twins = load_hulls(args.hulls)
        except TwinError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        hulls = ("the twin identified on the other family with measured wind (scripts/identify_esso.py; "
                 + "; ".join(f"{fam} tests from {info['file']}, sha256 {info['sha256'][:12]}"
                             for fam, (_, info) in twins.items()) + ")")
    paths = [p for p in sorted(DATA.glob("*.csv")) if p.name != DUPLICATE and (not only or p.name in only)]
    rows = []
    if args.measured_evidence:
        previous = args.out / f"{_stem(hulls)}.json"
        if not previous.is_file():
            print(f"error: {previous}: no such file (run the diagnosis first)", file=sys.stderr)
            return 2
        old = json.loads(previous.read_text())
        for r in old["tests"]:
            if not only or r["test"] in only:
                r["measured_wind_evidence"] = measured_evidence(DATA / r["test"], hull_for(r["test"], twins, prior))
                print(f"{r['test']:40s} measured wind: {r['measured_wind_evidence']}", flush=True)
        return _write(args.out, old["tests"], old.get("days", []), hulls)
    if args.by_day:
        previous = args.out / f"{_stem(hulls)}.json"
        rows = json.loads(previous.read_text())["tests"] if previous.is_file() else []
    else:
        for path in paths:
            rows.append(run_test(path, hull_for(path.name, twins, prior)))
            r = rows[-1]
            print(f"{r['test']:40s} anemometer {r['anemometer']['speed_m_s']:.2f} from "
                  f"{r['anemometer']['from_deg']:.0f}; named {','.join(r['named']) or '-'}; estimate {r['wind']}; "
                  f"{r['seconds']} s", flush=True)
    by_day: dict[str, list[Path]] = {}
    for path in paths:
        by_day.setdefault(day_of(path.name), []).append(path)
    days = []
    for day, group in by_day.items():
        if len(group) < 2:
            continue
        if twins and len({family_of(p.name) for p in group}) > 1:
            print(f"{day}: tests of both families, no one hull to diagnose them from: skipped", flush=True)
            continue
        days.append(run_day(day, group, hull_for(group[0].name, twins, prior)))
        d = days[-1]
        print(f"{day}: {len(group)} tests; named {','.join(d['named']) or '-'}; estimate {d['wind']}; "
              f"{d['seconds']} s", flush=True)
    return _write(args.out, rows, days, hulls)


def beside_untuned(untuned: dict, calibrated: dict) -> str:
    """The calibrated hull's counts beside the untuned twin's (esso_wind_diagnosis.json)."""
    def counts(d: dict) -> list[str]:
        s, days = d["summary"], d.get("days_summary") or {}
        return [f"{s['windy_named']} of {s['windy']}", f"{s['windy_estimate_agreeing_named_or_not']} of {s['windy']}",
                f"{s.get('windy_measured_wind_earns', '-')} of {s['windy']}",
                f"{days.get('windy_per_log_named', '-')} of {days.get('windy', '-')} "
                f"({days.get('windy_per_log_named_agreeing', '-')} within the tolerances)",
                ", ".join(sorted(set(s["other_effects_named"]) | set(days.get("other_effects_named", [])))) or "none"]
    rows = [("untuned prior (esso_wind_diagnosis.md)", counts(untuned)),
            ("hull identified on the other family with measured wind (this page)", counts(calibrated))]
    lines = ["", "## Beside the untuned twin", "",
             "| twin diagnosed from | wind named, per test | estimate within tolerance, per test | measured wind earns "
             "its place, per test | each test's own wind named, by day | other effects named (the pond has no "
             "current: any current is the wind's drift misattributed) |", "|---|---|---|---|---|---|"]
    lines += [f"| {name} | " + " | ".join(c) + " |" for name, c in rows]
    return "\n".join(lines) + "\n"


def _stem(hulls: str | None) -> str:
    return "esso_wind_diagnosis" + ("_calibrated" if hulls else "")


def _write(out: Path, rows: list[dict], days: list[dict], hulls: str | None = None) -> int:
    s = summary(rows)
    out.mkdir(parents=True, exist_ok=True)
    payload = {"summary": s, "hulls": hulls, "tests": rows, "days_summary": day_summary(days) if days else None,
               "days": days}
    write_text_atomic(out / f"{_stem(hulls)}.json", json.dumps(payload, indent=1, default=float) + "\n")
    text = markdown(rows, s, hulls) + (day_markdown(days, payload["days_summary"]) if days else "")
    if hulls and (out / "esso_wind_diagnosis.json").is_file():
        text += beside_untuned(json.loads((out / "esso_wind_diagnosis.json").read_text()), payload)
    write_text_atomic(out / f"{_stem(hulls)}.md", text)
    print(json.dumps(s))
    if days:
        print(json.dumps(payload["days_summary"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
