"""How the BlueBoat answers its thrusters from rest, against the twin identified on its least active runs.

    python scripts/rest_response.py [--page-only]

The ten shared BlueBoat runs [BlueBoat-SI] spend most of their time with both thrusters at rest (within
AT_REST_US of neutral, inside the BlueBoat's dead band of +31/−37 µs). Two things happen there that the twin's form decides and that a diagnosis of such runs
meets in every block of idling:

- kicks: a thruster driven outside its dead band for at most KICK_MAX_S, after REST_BEFORE_S or more
  with both at rest and followed by as long at rest. From the measured state before each kick, the
  twin (`twin identify` with its defaults on the five least active runs) runs free over ANSWER_S
  with the logged PWM; the largest change of r and of u over that time, measured and the twin's;
- coasting turns: a stretch of at least COAST_MIN_S with both thrusters at rest, starting COAST_SKIP_S
  after the last thrust, the hull still turning (|r| > COAST_MIN_RATE_RAD_S) one way throughout: the
  time constant of r's decay (a line through log |r|), measured and the twin's free run from the
  same state.

The definitions were set before the study was run. Without ../shared/data the script says so and exits 0.
"""
from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import twin.vessel as vessel_mod  # noqa: E402
from twin.fit.evaluate import TwinPredictor, evaluate  # noqa: E402
from twin.ident.identify import calibrate, identify, prepared, read  # noqa: E402
from twin.viz.pages import ResultPage, ResultTable, checkout_commit, study_main  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "blueboat"
FITTED = (218, 221, 222, 223, 226)  # the five least active (extrapolation.py's split)
JUDGED = (216, 220, 224, 225, 228)
AT_REST_US = 25.0  # both thrusters within this of their neutral: at rest
KICK_MAX_S, REST_BEFORE_S, ANSWER_S = 0.3, 2.0, 3.0
COAST_SKIP_S, COAST_MIN_S, COAST_MAX_S, COAST_MIN_RATE_RAD_S = 0.3, 2.0, 4.0, 0.06


def _runs(at_rest: np.ndarray, segment: np.ndarray) -> list[tuple[int, int, bool]]:
    """(start, stop, at rest) of the stretches of equal rest state within one segment."""
    out, k = [], 0
    while k < len(at_rest):
        j = k
        while j < len(at_rest) and at_rest[j] == at_rest[k] and segment[j] == segment[k]:
            j += 1
        out.append((k, j, bool(at_rest[k])))
        k = j
    return out


def kicks(prep, predictor, run: int) -> list[dict]:
    """Every kick from rest in one prepared run (module docstring), measured and the twin's answer."""
    h = prep.settings.grid_dt
    rest = np.all(np.abs(prep.pwm - np.asarray(prep.pwm_neutral_us)) <= AT_REST_US, axis=1)
    stretches = _runs(rest, prep.segment)
    n_answer, out = int(round(ANSWER_S / h)), []
    for (a0, a1, r0), (b0, b1, r1), (c0, c1, r2) in zip(stretches, stretches[1:], stretches[2:]):
        if not (r0 and not r1 and r2) or (b1 - b0) * h > KICK_MAX_S + 1e-9 or (a1 - a0) * h < REST_BEFORE_S:
            continue
        if (c1 - c0) * h < REST_BEFORE_S or b0 + n_answer >= len(prep.t) or prep.segment[b0 - 1] != prep.segment[b0 + n_answer]:
            continue
        start = b0 - 1
        twin = predictor.predict_windows(prep, np.array([start]), n_answer)[0]
        sl = slice(start, start + n_answer + 1)
        measured_r, measured_u = prep.r[sl] - prep.r[start], prep.u[sl] - prep.u[start]
        twin_r, twin_u = twin[:, 2] - twin[0, 2], twin[:, 0] - twin[0, 0]
        pwm = prep.pwm[b0:b1]
        out.append({"run": run, "t_s": round(float(prep.t[b0] - prep.t[0]), 1), "seconds": round((b1 - b0) * h, 2),
                    "pwm_us": [[int(p) for p in row] for row in pwm[[0, -1]]],
                    "measured_dr_rad_s": float(np.max(np.abs(measured_r))), "twin_dr_rad_s": float(np.nanmax(np.abs(twin_r))),
                    "measured_du_m_s": float(np.max(np.abs(measured_u))), "twin_du_m_s": float(np.nanmax(np.abs(twin_u)))})
    return out


def _time_constant(t: np.ndarray, r: np.ndarray) -> float | None:
    r = np.asarray(r, float)
    if not np.all(np.isfinite(r)) or np.any(np.sign(r) != np.sign(r[0])) or np.any(np.abs(r) < 1e-3):
        return None
    slope = float(np.polyfit(t, np.log(np.abs(r)), 1)[0])
    return -1.0 / slope if slope < 0 else None


def coasts(prep, predictor, run: int) -> list[dict]:
    """Every coasting turn at rest in one prepared run (module docstring): r's time constant, measured and the twin's."""
    h = prep.settings.grid_dt
    rest = np.all(np.abs(prep.pwm - np.asarray(prep.pwm_neutral_us)) <= AT_REST_US, axis=1)
    out = []
    for a, b, at_rest in _runs(rest, prep.segment):
        start = a + int(round(COAST_SKIP_S / h))
        stop = min(b, start + int(round(COAST_MAX_S / h)))
        # a stretch that opens a segment has no last thrust to count from
        opens = a == 0 or prep.segment[a - 1] != prep.segment[a]
        if not at_rest or opens or (stop - start - 1) * h < COAST_MIN_S or abs(prep.r[start]) <= COAST_MIN_RATE_RAD_S:
            continue
        r = prep.r[start:stop]
        if np.any(np.sign(r) != np.sign(r[0])) or np.any(np.abs(r) < 0.005):
            continue
        t = prep.t[start:stop] - prep.t[start]
        twin = predictor.predict_windows(prep, np.array([start]), stop - start - 1)[0]
        out.append({"run": run, "t_s": round(float(prep.t[start] - prep.t[0]), 1), "r0_rad_s": float(r[0]),
                    "seconds": round(float(t[-1]), 1), "measured_tau_s": _time_constant(t, r),
                    "twin_tau_s": _time_constant(t, twin[:, 2])})
    return out


def events(twin, recs: dict) -> dict:
    """The kicks and coasting turns of every run, the twin's free runs beside the measured."""
    rows = {"kicks": [], "coasts": []}
    for group, runs in (("fitted", FITTED), ("judged", JUDGED)):
        group_recs = [recs[n] for n in runs]
        calibrated = calibrate(group_recs, twin)[0]
        predictor = TwinPredictor(calibrated)
        for n, prep in zip(runs, prepared(group_recs, calibrated)):
            rows["kicks"] += [{"group": group, **k} for k in kicks(prep, predictor, n)]
            rows["coasts"] += [{"group": group, **c} for c in coasts(prep, predictor, n)]
    return rows


def scores(twin, recs: dict, runs: tuple[int, ...]) -> dict:
    """10-s free-run R² of u, v, r on `runs`, each log's compass calibration from its own kinematics."""
    group = [recs[n] for n in runs]
    calibrated = calibrate(group, twin)[0]
    m = evaluate(calibrated, prepared(group, calibrated), stride_s=2.0, horizons={"h": 10.0})["h"]
    return {d: m[d]["r2"] for d in ("u", "v", "r")}


def sensitivities(twin, recs: dict) -> list[dict]:
    """One coefficient of the identified twin moved (nothing refitted): what it does at rest and to the scores."""
    d, a, t = twin.damping, twin.added_mass, twin.thrusters
    moves = [("identified", twin),
             ("N_r × 0.25", replace(twin, damping=replace(d, Nr=0.25 * d.Nr))),
             ("N_ṙ × 3", replace(twin, added_mass=replace(a, Nrdot=3.0 * a.Nrdot))),
             ("thrust lag 0.3 s", replace(twin, thrusters=replace(t, lag_s=0.3)))]
    out = []
    for label, v in moves:
        ev = events(v, recs)
        ratio = [k["measured_dr_rad_s"] / k["twin_dr_rad_s"] for k in ev["kicks"] if k["twin_dr_rad_s"] > 0]
        out.append({"twin": label, "kick_ratio": _median(ratio), "twin_tau_s": [c["twin_tau_s"] for c in ev["coasts"]],
                    "fitted": scores(v, recs, FITTED), "judged": scores(v, recs, JUDGED)})
    return out


def run_study() -> dict:
    recs = {n: read([DATA / f"fixed_00000{n}.csv"])[0] for n in FITTED + JUDGED}
    twin = identify([recs[n] for n in FITTED], vessel_mod.load("blueboat")).vessel
    return {"commit": checkout_commit(ROOT), "twin": {"gain_left": twin.thrusters.gain_left,
            "gain_right": twin.thrusters.gain_right, "lag_s": twin.thrusters.lag_s, "Nr": twin.damping.Nr,
            "Nrr": twin.damping.Nrr, "Nrdot": twin.added_mass.Nrdot}, **events(twin, recs),
            "sensitivities": sensitivities(twin, recs)}


def _median(values) -> float:
    v = [x for x in values if x is not None and np.isfinite(x)]
    return float(np.median(v)) if v else float("nan")


def _tau(x) -> str:
    return "-" if x is None else f"{x:.1f}"


def page(raw: dict) -> ResultPage:
    kick_rows = [[k["group"], k["run"], k["t_s"], k["seconds"], " → ".join(f"{a}/{b}" for a, b in k["pwm_us"]),
                  round(k["measured_dr_rad_s"], 3), round(k["twin_dr_rad_s"], 3),
                  round(k["measured_du_m_s"], 3), round(k["twin_du_m_s"], 3)] for k in raw["kicks"]]
    coast_rows = [[c["group"], c["run"], c["t_s"], round(c["r0_rad_s"], 3), c["seconds"],
                   "-" if c["measured_tau_s"] is None else round(c["measured_tau_s"], 2),
                   "-" if c["twin_tau_s"] is None else round(c["twin_tau_s"], 2)] for c in raw["coasts"]]
    ratio = [k["measured_dr_rad_s"] / k["twin_dr_rad_s"] for k in raw["kicks"] if k["twin_dr_rad_s"] > 0]
    pairs = ", ".join(f"{_tau(c['measured_tau_s'])} / {_tau(c['twin_tau_s'])}" for c in raw["coasts"])
    t = raw["twin"]
    summary = (f"{len(raw['kicks'])} kicks from rest ({sum(k['group'] == 'fitted' for k in raw['kicks'])} on the "
               f"fitted runs): the largest change of the yaw rate within {ANSWER_S:g} s is {_median(ratio):.2f} of "
               f"the twin's at the median (its map, gains {t['gain_left']:.2f}/{t['gain_right']:.2f}, and thrust lag "
               f"{t['lag_s']:.3f} s: no delay from rest). "
               f"{len(raw['coasts'])} coasting turns with both thrusters at rest: r decays with a time constant of "
               f"{pairs} (measured / twin, s; identified N_r {t['Nr']:.2f} N m s, N_rr {t['Nrr']:.2f} N m s², N_ṙ "
               f"{t['Nrdot']:.2f} kg m²): the twin's yaw dies away several times faster. Few events, all on the "
               "judged runs (the least active runs hold none), but each the same way; a diagnosis of such runs meets "
               "them in every block of idling.")
    moved = {m["twin"]: m for m in raw.get("sensitivities", [])}
    slow = moved.get("N_r × 0.25")
    if slow:
        best_kick = max((m for m in moved.values() if m["twin"] != "identified"), key=lambda m: m["kick_ratio"])
        summary += (f" No one coefficient mends either: with N_r × 0.25 the twin coasts at "
                    f"{_median(slow['twin_tau_s']):.1f} s but predicts r at R² {slow['fitted']['r']:.3f} on the fitted "
                    f"runs and {slow['judged']['r']:.3f} on the judged; the kicks come nearest with "
                    f"{best_kick['twin']}, at {best_kick['kick_ratio']:.2f} of the twin's (last table).")
    return ResultPage(
        name="rest_response", title="The BlueBoat answering its thrusters from rest",
        ran="python scripts/rest_response.py",
        data=f"the ten shared BlueBoat runs [BlueBoat-SI]; the twin `twin identify` makes with its defaults from runs "
             f"{', '.join(map(str, FITTED))} (the least active), its free runs from the measured states on those runs "
             f"(fitted) and on runs {', '.join(map(str, JUDGED))} (judged)",
        summary=summary,
        tables=[ResultTable(f"Kicks: a thruster outside ±{AT_REST_US:g} µs of neutral for at most {KICK_MAX_S:g} s, "
                            f"with at least {REST_BEFORE_S:g} s at rest before and after; the largest change of r "
                            f"(rad/s) and u (m/s) within {ANSWER_S:g} s, measured and in the twin's free run",
                            ["runs", "run", "t s", "s", "PWM left/right µs (first → last)", "Δr measured",
                             "Δr twin", "Δu measured", "Δu twin"], kick_rows),
                ResultTable(f"Coasting turns: both thrusters at rest from {COAST_SKIP_S:g} s after the last thrust "
                            f"for {COAST_MIN_S:g}-{COAST_MAX_S:g} s, |r| > {COAST_MIN_RATE_RAD_S:g} rad/s at the "
                            "start and one way throughout; r's time constant (s)",
                            ["runs", "run", "t s", "r at start rad/s", "s", "τ measured", "τ twin"], coast_rows),
                ResultTable("One coefficient of the identified twin moved, nothing refitted (a sensitivity; it fits and "
                            "chooses nothing): the kicks' median ratio (measured Δr over the twin's), the twin's τ of "
                            "each coasting turn, and 10-s R² on the fitted and the judged runs",
                            ["twin", "kick ratio", "τ twin s", "fitted R² u", "fitted R² v", "fitted R² r",
                             "judged R² u", "judged R² v", "judged R² r"],
                            [[m["twin"], round(m["kick_ratio"], 2),
                              ", ".join("-" if x is None else f"{x:.2f}" for x in m["twin_tau_s"]),
                              *[round(m[g][dof], 3) for g in ("fitted", "judged") for dof in ("u", "v", "r")]]
                             for m in raw.get("sensitivities", [])])],
        notes=["The twin is the one `python scripts/extrapolation.py` judges on the activity split (identified "
               "afresh here, same runs and defaults).",
               "The kicks are in the logs as the autopilot wrote its outputs (10 Hz); whether the ESCs answered them "
               "is what the table asks.",
               "τ \"-\": r crossed zero or fell under 0.001 rad/s within the stretch (faster than any time constant "
               "a line through log |r| can give)."],
        raw=raw)


def main() -> int:
    return study_main(__doc__.splitlines()[0], "rest_response", DATA, "BlueBoat recordings", run_study, page, ROOT / "docs" / "results")


if __name__ == "__main__":
    sys.exit(main())
