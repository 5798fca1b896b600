"""Issue 16 item 4: the concealed wind on the Esso Osaka's tests, found by `twin diagnose` without
the anemometer, then checked against it.

    python scripts/diagnose_esso.py [--only NAME,...] [--out docs]

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
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import twin.vessel as vessel_mod  # noqa: E402
from twin.diagnose.doctor import diagnose  # noqa: E402
from twin.effects import apply_effects  # noqa: E402
from twin.files import write_text_atomic  # noqa: E402
from twin.fit.evaluate import evaluate  # noqa: E402
from twin.formats import read_recording  # noqa: E402
from twin.ident.identify import prepared  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "esso"
DUPLICATE = "turn_cut_14-Sep-2020_15_58_08.csv"
HORIZON = {"free_run_30s": 30.0}
STRIDE_S = 10.0
WINDY_M_S, CALM_M_S = 1.5, 0.8  # the thresholds on the mean true wind
DIRECTION_DEG, SPEED_SHARE = 30.0, 0.4  # the tolerances


def anemometer(prep) -> dict:
    """Mean true wind of the test: the air's mean NED velocity → speed and direction FROM (deg)."""
    air = prep.wind_ned[np.all(np.isfinite(prep.wind_ned), axis=1)]
    north, east = air.mean(axis=0)
    return {"speed_m_s": float(math.hypot(north, east)), "from_deg": _from_deg(north, east),
            "scalar_mean_m_s": float(np.mean(np.hypot(air[:, 0], air[:, 1])))}


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
            "other_effects_named": sorted({n for r in rows for n in r["named"] if n != "wind"})}


def _r2(m: dict | None) -> str:
    return "-" if not m or m.get("r2") is None else f"{m['r2']:.2f}"


def markdown(rows: list[dict], s: dict) -> str:
    lines = ["# The concealed wind on the Esso Osaka's tests (issue 16 item 4)", "",
             "Written by `python scripts/diagnose_esso.py`. Each test diagnosed alone by `twin diagnose` from the "
             "untuned `esso_osaka` twin, without the wind columns; its wind checked against the anemometer's mean "
             "true wind over the test: windy or calm by its mean speed, the estimate compared with its vector mean "
             "(speed, direction FROM, clockwise from the pond's x0 = north). Targets: "
             f"wind named on ≥ 70 % of the tests whose mean true wind is ≥ {WINDY_M_S} m/s, its direction within "
             f"{DIRECTION_DEG:g}° and speed within {100 * SPEED_SHARE:g} %; nothing wind-like named below "
             f"{CALM_M_S} m/s. The candidates a diagnosis offers this ship: current, wind, and the sensor effects "
             "(the PWM thruster effects and the seed 004 damping scales do not apply to it).", "",
             f"- tests: {s['tests']}; with mean true wind ≥ {WINDY_M_S} m/s: {s['windy']}; below {CALM_M_S} m/s: "
             f"{s['calm']}" + (" (none is that calm, so the calm criterion is untested)" if not s["calm"] else
                                f", wind named on {s['calm_with_wind_named']} of them"),
             f"- **wind named on {s['windy_named']} of {s['windy']} windy tests** (target ≥ 70 %), "
             f"{s['windy_named_agreeing']} of them within the tolerances",
             f"- the wind candidate's own estimate (named or not) within the tolerances on "
             f"{s['windy_estimate_agreeing_named_or_not']} of {s['windy']} windy tests",
             f"- other effects named anywhere: {', '.join(s['other_effects_named']) or 'none'}", "",
             "| test | anemometer: mean speed; vector mean m/s from ° | named | wind estimate m/s from ° (z, blocks +/−) | agrees | "
             "30-s R² u / v / r: no wind | measured wind | diagnosed constant wind (in sample) | s |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        a, w, f = r["anemometer"], r["wind"], r["fits_30s"]
        est = "-" if w is None else (f"{w['speed_m_s']:.2f} from {w['from_deg']:.0f}" +
                                     ("" if w["named"] else f" (z {w['z']:.2f}, {w['blocks_for']}/{w['blocks_against']})"))
        cell = {k: " / ".join(_r2(f.get(k, {}).get(d)) for d in "uvr") for k in ("none", "measured", "diagnosed_constant")}
        lines.append(f"| {r['test']} | {a['scalar_mean_m_s']:.2f}; {a['speed_m_s']:.2f} from {a['from_deg']:.0f} | {', '.join(r['named']) or '-'} | "
                     f"{est} | {'-' if r['agrees'] is None else ('yes' if r['agrees'] else 'no')} | {cell['none']} | "
                     f"{cell['measured']} | {cell['diagnosed_constant']} | {r['seconds']} |")
    return "\n".join(lines) + "\n"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="", help="comma-separated test file names")
    ap.add_argument("--out", type=Path, default=ROOT / "docs")
    ap.add_argument("--render", type=Path, help="only write the report again from this script's JSON")
    args = ap.parse_args()
    if args.render:
        rows = json.loads(args.render.read_text())["tests"]
        s = summary(rows)
        write_text_atomic(args.out / "esso_wind_diagnosis.json",
                          json.dumps({"summary": s, "tests": rows}, indent=1, default=float) + "\n")
        write_text_atomic(args.out / "esso_wind_diagnosis.md", markdown(rows, s))
        print(json.dumps(s))
        return 0
    if not DATA.is_dir():
        print(f"no Esso recordings at {DATA}: nothing to do")
        return 0
    only = {s.strip() for s in args.only.split(",") if s.strip()}
    prior = vessel_mod.load("esso_osaka")
    rows = []
    for path in sorted(DATA.glob("*.csv")):
        if path.name == DUPLICATE or (only and path.name not in only):
            continue
        rows.append(run_test(path, prior))
        r = rows[-1]
        print(f"{r['test']:40s} anemometer {r['anemometer']['speed_m_s']:.2f} from {r['anemometer']['from_deg']:.0f}; "
              f"named {','.join(r['named']) or '-'}; estimate {r['wind']}; {r['seconds']} s", flush=True)
    s = summary(rows)
    args.out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(args.out / "esso_wind_diagnosis.json",
                      json.dumps({"summary": s, "tests": rows}, indent=1, default=float) + "\n")
    write_text_atomic(args.out / "esso_wind_diagnosis.md", markdown(rows, s))
    print(json.dumps(s))
    return 0


if __name__ == "__main__":
    sys.exit(main())
