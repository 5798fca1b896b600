"""What the Esso Osaka twin predicts beyond the propeller speeds of its tests.

    python scripts/esso_beyond_rps.py [--out docs/results]

The shared tests [ESSO-FRT] run the propeller at 10 rps at most; faster tests of the same model run
at 12 to 17 rps. Three twins: the prior (twin/model/esso_osaka.json), `twin identify` with its
defaults and the measured wind on the tests whose propeller never exceeds 8.5 rps (the extrapolation
page's split, twin.fit.extrapolation.by_input_level), and on all the tests.

1. Where there are data: every turning test at 10 rps starts from rest, its rudder keeping the
   course for about 90 s. Each twin replays those first 90 s in one free run from the measured
   start, driven by the logged propeller and rudder and the measured wind: its speed at 30, 60 and
   90 s against the measured.
2. Beyond them: each twin from rest in calm air at 6 to 17 rps, rudder amidships and at 20° and
   35°, for 240 s: the steady speed and yaw rate (the mean over the last 40 s). The vessel file's
   bound of 10 rps is lifted for these runs, as a replay of a faster test lifts it
   (ThrusterModel.as_logged).

Each twin's R'_0, wake fraction and the factor its friction line carries R'_0 with
(physics/mmg.py friction_line_factor) are listed, since they set the steady speed. The recordings are
read in place; without them the script says so and exits 0.
"""
from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import twin.vessel as vessel_mod  # noqa: E402
from twin.drive import InputSeries  # noqa: E402
from twin.fit.evaluate import TwinPredictor  # noqa: E402
from twin.fit.extrapolation import by_input_level  # noqa: E402
from twin.fit.windows import ModelCache  # noqa: E402
from twin.ident.identify import calibrate, identify, prepared, read  # noqa: E402
from twin.physics.mmg import friction_line_factor  # noqa: E402
from twin.physics.sensors import log_name  # noqa: E402
from twin.simulation import simulate  # noqa: E402
from twin.viz.pages import ResultPage, ResultTable  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "esso"
DUPLICATE = "turn_cut_14-Sep-2020_15_58_08.csv"  # the first 287 s of turn_14-Sep-2020_15_58_08
FITTED_RPS = 8.5  # the extrapolation page's split
START_RPS = 10.0  # the turning tests whose start from rest is replayed
REPLAY_AT_S = (30.0, 60.0, 90.0)
RPS = (6.0, 8.0, 10.0, 12.0, 15.0, 17.0)
RUDDER_DEG = (0.0, 20.0, 35.0)
STEADY_RUN_S, STEADY_MEAN_S = 240.0, 40.0


def unbounded(vessel):
    """The vessel with its propeller and rudder bounds lifted (a faster test's replay lifts them too)."""
    return replace(vessel, thrusters=vessel.thrusters.as_logged())


def replay_start(twin, recs) -> list[dict]:
    """Each recording's first REPLAY_AT_S[-1] s as one free run of `twin` (measured start, logged inputs,
    measured wind): measured and predicted u at REPLAY_AT_S."""
    seen, _ = calibrate(recs, twin)
    predictor = TwinPredictor(seen, ModelCache(), "measured")
    out = []
    for rec, prep in zip(recs, prepared(recs, seen)):
        start = prep.segments[0].start
        steps = int(round(REPLAY_AT_S[-1] / prep.settings.grid_dt))
        nu = predictor.predict_windows(prep, np.array([start]), steps)[0]
        at = [int(round(s / prep.settings.grid_dt)) for s in REPLAY_AT_S]
        out.append({"log": log_name(rec.source), "measured_u": [float(prep.u[start + k]) for k in at],
                    "predicted_u": [float(nu[k, 0]) for k in at]})
    return out


def steady(twin, rps: float, rudder_deg: float) -> tuple[float, float]:
    """(u m/s, r °/s) of `twin` from rest in calm air at a constant propeller speed and rudder angle:
    the mean over the run's last STEADY_MEAN_S."""
    series = InputSeries(np.array([0.0]), np.array([[rps, np.radians(rudder_deg)]]), "propeller_rudder")
    run = simulate(unbounded(twin), series, STEADY_RUN_S, nu0=(0.0, 0.0, 0.0))
    late = run.t > STEADY_RUN_S - STEADY_MEAN_S
    return float(run.nu[late, 0].mean()), float(np.degrees(run.nu[late, 2].mean()))


def resistance_row(label: str, twin) -> list:
    m = twin.mmg
    return [label, m.hull.R0, m.propeller.wP0, m.friction_factor, friction_line_factor(m)]


def esso_study(doc: str):
    """An Esso Osaka study's --out and its tests: (args, the prior, the recordings, their names), or None
    (said) when the recordings are not beside the project."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "results")
    args = ap.parse_args()
    paths = sorted(p for p in DATA.glob("*.csv") if p.name != DUPLICATE)
    if not paths:
        print(f"the Esso Osaka recordings are not in {DATA}: nothing to do")
        return None
    recs = read(paths)
    return args, vessel_mod.load("esso_osaka"), recs, [log_name(r.source) for r in recs]


def main() -> int:
    started = time.time()
    study = esso_study(__doc__)
    if study is None:
        return 0
    args, prior, recs, names = study
    split = by_input_level(prepared(recs, calibrate(recs, prior)[0]), FITTED_RPS)
    slow, _ = split.pick(recs, names)
    twins = {"prior": prior,
             f"identified, tests ≤ {FITTED_RPS:g} rps": identify(slow, prior, wind="measured").vessel,
             "identified, all tests": identify(recs, prior, wind="measured").vessel}
    # the turning tests beyond the split's level: those at 10 rps, each from rest
    starts = [r for r in recs if log_name(r.source) in split.judged and log_name(r.source).startswith("turn")]
    replays = {label: replay_start(t, starts) for label, t in twins.items()}
    replay_rows = []
    for i, rec in enumerate(starts):
        measured = replays["prior"][i]["measured_u"]
        replay_rows.append([log_name(rec.source), *measured,
                            *[replays[label][i]["predicted_u"][-1] for label in twins]])
    errors = {label: np.array([[p - m for p, m in zip(x["predicted_u"], x["measured_u"])] for x in rows])
              for label, rows in replays.items()}
    error_rows = [[label, *np.mean(e, axis=0), *np.sqrt(np.mean(e ** 2, axis=0))] for label, e in errors.items()]
    steady_raw = {label: {f"{rps:g}": {f"{d:g}": steady(t, rps, d) for d in RUDDER_DEG} for rps in RPS}
                  for label, t in twins.items()}
    straight_rows = [[f"{rps:g}", *[steady_raw[label][f"{rps:g}"]["0"][0] for label in twins]] for rps in RPS]
    turn_rows = [[f"{rps:g}", f"{d:g}", *[x for label in twins for x in steady_raw[label][f"{rps:g}"][f"{d:g}"]]]
                 for rps in (START_RPS, RPS[-1]) for d in RUDDER_DEG[1:]]
    labels = list(twins)
    top = {label: steady_raw[label][f"{RPS[-1]:g}"]["0"][0] for label in labels}
    at_ten = {label: steady_raw[label][f"{START_RPS:g}"]["0"][0] for label in labels}
    bias = {label: float(np.mean(errors[label][:, -1])) for label in labels}
    summary = (
        f"Replaying the first {REPLAY_AT_S[-1]:g} s of the {len(starts)} turning tests that start from rest at "
        f"{START_RPS:g} rps, the prior's speed at {REPLAY_AT_S[-1]:g} s is off the measured by {bias[labels[0]]:+.3f} m/s "
        f"on average, the twin identified on the tests at ≤ {FITTED_RPS:g} rps (which never saw {START_RPS:g} rps) by "
        f"{bias[labels[1]]:+.3f} and the twin identified on all tests (these among them) by {bias[labels[2]]:+.3f}: "
        "where there are data, the identified twins' lower resistance (and thrust, through the wake fraction) "
        "follows the measured start better than the prior's, one of them from slower tests alone. "
        f"Beyond the tests they part: the steady straight speed at {RPS[-1]:g} rps is {top[labels[0]]:.3f} m/s for the "
        f"prior, {top[labels[1]]:.3f} and {top[labels[2]]:.3f} for the identified twins (at {START_RPS:g} rps "
        f"{at_ten[labels[0]]:.3f}, {at_ten[labels[1]]:.3f} and {at_ten[labels[2]]:.3f}). The recordings do not tell "
        "which holds at 12 to 17 rps: a faster run is where the resistance each twin carries (its R'_0, wake "
        "fraction and the factor its friction line carries R'_0 with, below) is tested.")
    page = ResultPage(
        "esso_beyond_rps", "The Esso Osaka twin beyond its tests' propeller speeds",
        "python scripts/esso_beyond_rps.py",
        f"{len(recs)} Esso Osaka free-running tests [ESSO-FRT] ({DUPLICATE} left out: it repeats the first 287 s "
        f"of another test), with their measured wind; the twins identified with `twin identify`'s defaults",
        summary,
        [ResultTable("Each twin's resistance: R'_0 at the reference speed, the wake fraction w_P0, the vessel file's "
                     "friction-line factor F and the factor the line carries R'_0 with (physics/mmg.py)",
                     ["twin", "R'_0", "w_P0", "F", "F carried"],
                     [resistance_row(label, t) for label, t in twins.items()]),
         ResultTable(f"The first {REPLAY_AT_S[-1]:g} s of each turning test at {START_RPS:g} rps from rest, one free run "
                     "from the measured start (logged propeller, rudder and wind): measured u (m/s) and each twin's "
                     f"at {REPLAY_AT_S[-1]:g} s",
                     ["test", *[f"measured at {s:g} s" for s in REPLAY_AT_S], *labels], replay_rows),
         ResultTable("The same replays: each twin's error in u (m/s, predicted less measured), mean and RMS over "
                     "the tests",
                     ["twin", *[f"mean at {s:g} s" for s in REPLAY_AT_S], *[f"RMS at {s:g} s" for s in REPLAY_AT_S]],
                     error_rows),
         ResultTable(f"Steady straight speed (m/s) from rest in calm air, rudder amidships ({STEADY_RUN_S:g}-s runs)",
                     ["propeller (rps)", *labels], straight_rows),
         ResultTable("Steady turns from rest in calm air: u (m/s) and r (°/s)",
                     ["propeller (rps)", "rudder (°)", *[f"{label}: {q}" for label in labels for q in ("u", "r")]],
                     turn_rows)],
        notes=["The replayed tests' wind is the anemometer's (1-3.5 m/s in these starts), as `twin evaluate "
               "--wind-measured` takes it; the steady runs are in calm air.",
               f"The twin identified on the tests at ≤ {FITTED_RPS:g} rps is fitted on {', '.join(split.fitted)}."],
        raw={"split": split.to_dict(), "resistance": [resistance_row(label, t) for label, t in twins.items()],
             "replays": replays, "steady": steady_raw, "seconds": round(time.time() - started, 1)})
    print(page.write(args.out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
