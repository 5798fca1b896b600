"""`twin diagnose` on the real BlueBoat: the untuned first-principles twin (model/blueboat.json)
against seven runs together, what the diagnosis names, and whether its amended twin predicts
the three runs it never saw better than the untuned one.

    python scripts/diagnose_blueboat.py [--out docs/diagnose]

Writes blueboat.md, blueboat.json and blueboat.html under --out. The recordings
(../shared/data/blueboat) have no licence: they are read in place, never copied; without
them the script says so and exits 0.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import twin.vessel as vessel_mod  # noqa: E402
from twin.diagnose import search  # noqa: E402
from twin.diagnose.doctor import diagnose  # noqa: E402
from twin.diagnose.report import write_html  # noqa: E402
from twin.files import write_text_atomic  # noqa: E402
from twin.fit.metrics import DOFS
from twin.fit.evaluate import TwinPredictor, evaluate, horizon_windows  # noqa: E402
from twin.ident.identify import load  # noqa: E402
from twin.fit.windows import ModelCache, measured  # noqa: E402
from twin.formats import read_recording  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from identify_blueboat import wrap  # noqa: E402  (one markdown folder for both reports)

DATA = ROOT.parent / "shared" / "data" / "blueboat"
TRAIN_RUNS = (216, 218, 220, 221, 222, 223, 224)
HELD_OUT_RUNS = (225, 226, 228)
FREE_RUN_10S = {"free_run_10s": 10.0}
MAX_HTML_BYTES = 1_000_000
QUIET_AFTER_S = 30.0  # idle this long after the last thrust: the coast-down (time constant ~10 s) is over
SPIN = {"r_min_rad_s": 0.5, "u_max_m_s": 0.6}  # turning on the spot


def run_paths(runs) -> list[Path]:
    return [DATA / f"fixed_00000{n}.csv" for n in runs]


def fmt(x, digits=3) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def held_out_scores(prior, amended) -> dict:
    """10-s free runs on the held-out runs, each twin scored on the recordings as its own
    sensors see them (an amended heading or antenna calibration changes the measurement too)."""
    out = {}
    for name, vessel in (("untuned", prior), ("amended", amended)):
        preps = load(run_paths(HELD_OUT_RUNS), vessel)
        out[name] = {"all": evaluate(vessel, preps, horizons=FREE_RUN_10S)["free_run_10s"]}
        for n, p in zip(HELD_OUT_RUNS, preps):
            out[name][str(n)] = evaluate(vessel, [p], horizons=FREE_RUN_10S)["free_run_10s"]
    return out


def idle_drift(preps, runs) -> dict:
    """Mean ground velocity (north, east; m/s) per run while the thrusters have idled for
    QUIET_AFTER_S: what a current would have to explain, run by run."""
    out = {}
    for n, p in zip(runs, preps):
        active = np.any(np.abs(p.pwm - np.asarray(p.pwm_neutral_us, float)) > 20.0, axis=1)
        idx = np.arange(len(active))
        last = np.maximum.accumulate(np.where(active, idx, -10**9))
        quiet = (idx - last) * p.settings.grid_dt > QUIET_AFTER_S
        if quiet.sum() < 50:
            continue
        c, s_ = np.cos(p.psi[quiet]), np.sin(p.psi[quiet])
        north = p.u[quiet] * c - p.v[quiet] * s_
        east = p.u[quiet] * s_ + p.v[quiet] * c
        out[str(n)] = {"north_m_s": float(np.mean(north)), "east_m_s": float(np.mean(east)),
                       "seconds": float(quiet.sum() * p.settings.grid_dt)}
    return out


def crab_angles(preps, runs) -> dict:
    """Per run, the angle of the GNSS track against the measured heading, atan2(v, u), on
    straight runs under way (u > 0.6 m/s, |r| < 0.05 rad/s): its mean and spread, and its mean
    below 1 m/s and above 1.2 m/s. A compass offset gives the same angle at every speed; a
    current or wind pushing sideways gives an angle that shrinks as the speed grows."""
    out = {}
    for n, p in zip(runs, preps):
        straight = (p.u > 0.6) & (np.abs(p.r) < 0.05) & np.isfinite(p.v)
        if straight.sum() < 20:
            continue
        crab = np.degrees(np.arctan2(p.v, p.u))
        slow, fast = straight & (p.u < 1.0), straight & (p.u > 1.2)
        out[str(n)] = {"n": int(straight.sum()), "mean_deg": float(np.mean(crab[straight])),
                       "sd_deg": float(np.std(crab[straight])),
                       "slow_deg": float(np.mean(crab[slow])) if slow.sum() >= 5 else None,
                       "fast_deg": float(np.mean(crab[fast])) if fast.sum() >= 5 else None}
    return out


def spin_rate_ratio(vessel, preps) -> float:
    """Median |r| of the twin over |r| measured on the spinning samples of 10-s free runs."""
    wins = horizon_windows(preps, 10.0, 2.0)
    model = TwinPredictor(vessel, ModelCache())
    pred = np.full((len(wins), max(w.n for w in wins) + 1, 3), np.nan)
    for j, w in enumerate(wins):
        pred[j, : w.n + 1] = model.predict_windows(preps[w.rec], np.array([w.start]), w.n)[0]
    _, meas = measured(preps, wins)
    spin = (np.abs(meas[..., 2]) > SPIN["r_min_rad_s"]) & (np.abs(meas[..., 0]) < SPIN["u_max_m_s"])
    spin &= np.isfinite(pred[..., 2])
    return float(np.median(np.abs(pred[..., 2][spin]) / np.abs(meas[..., 2][spin]))) if spin.any() else float("nan")


# ---------------------------------------------------------------- report

def effect_lines(d) -> list[str]:
    if not d.effects:
        return ["None kept: no candidate removed a significant share of the held-out misfit."]
    lines = []
    for e in d.effects:
        params = "; ".join(f"{k} = {v:.4g}" + (f" [{e['ci'][k][0]:.4g}, {e['ci'][k][1]:.4g}]" if k in e["ci"] else "")
                           for k, v in e["parameters"].items())
        rivals = "; ".join(f"{r['name']} ({'told apart' if r['separable'] else 'NOT separable'}, z {r['z']})"
                           for r in e["rivals"]) or "none close"
        lines += [f"- **{e['name']}**: {params} (95 % CI)", f"  held-out misfit removed "
                  f"{100 * e['held_out_gain']:.1f} % (z {e['z']}); per DOF "
                  + ", ".join(f"{k} {100 * v:.0f} %" for k, v in e["improvement"].items()), f"  rivals: {rivals}"]
    return lines


def candidate_rows(d) -> list[str]:
    """Every candidate a round fitted fully, with why it was or was not kept."""
    head = f"{'round':>5s} {'candidate':20s} {'z':>6s} {'removed':>8s}  fitted values"
    rows = [head, "-" * len(head)]
    for k, rnd in enumerate(d.rounds, 1):
        for c in rnd.get("candidates", []):
            vals = ", ".join(f"{n} {v:.3g}" for n, v in c.get("values", {}).items())
            rows.append(f"{k:5d} {c['name'][:20]:20s} {c['z']:6.2f} {100 * c['rel']:7.1f}%  {vals[:52]}")
    return rows


def located_rows(d, limit=8) -> list[str]:
    head = (f"{'dimension':18s} {'bin':14s} {'dof':3s} {'kind':8s} {'n':>6s} {'RMS':>7s} {'bias':>8s} "
            f"{'/noise':>7s} {'z':>5s}")
    rows = [head, "-" * len(head)]
    for e in d.located[:limit]:
        rows.append(f"{e['dimension'][:18]:18s} {str(e['bin'])[:14]:14s} {e['dof']:3s} {e['kind'][:8]:8s} {e['n']:6d} "
                    f"{e['rms']:7.4f} {e['bias']:+8.4f} {fmt(e.get('rms_over_noise'), 1):>7s} {fmt(e.get('z'), 1):>5s}")
    return rows


def unexplained_rows(d) -> list[str]:
    rows = []
    for u in d.unexplained:
        follows = ", ".join(f"{c['signal']} ({c['r']:+.2f})" for c in u.get("correlates_with", [])) or "-"
        rows.append(f"- {u['dof']} ({u['dimension']}: {u['bin']}): RMS {u['rms']:.4f}, "
                    f"{fmt(u.get('rms_over_noise'), 1)} × noise; follows {follows}")
    return rows or ["- nothing"]


def score_rows(scores: dict) -> list[str]:
    head = f"{'twin':8s} {'runs':6s} " + " ".join(f"{'R2 ' + d:>7s}" for d in DOFS) + "  " + \
        " ".join(f"{'MAE ' + d:>7s}" for d in DOFS) + f" {'n':>6s}"
    rows = [head, "-" * len(head)]
    for name, per in scores.items():
        for runs, m in per.items():
            rows.append(f"{name:8s} {runs:6s} " + " ".join(f"{fmt(m[d]['r2']):>7s}" for d in DOFS) + "  "
                        + " ".join(f"{fmt(m[d]['mae'], 4):>7s}" for d in DOFS) + f" {m['u']['n']:6d}")
    return rows


def fit_rows(d) -> list[str]:
    head = f"{'twin':8s} " + " ".join(f"{'R2 ' + k:>7s}" for k in DOFS)
    return [head, "-" * len(head)] + [f"{name:8s} " + " ".join(f"{fmt(fit[k]['r2']):>7s}" for k in DOFS)
                                      for name, fit in (("before", d.fit_before), ("after", d.fit_after))]


def drift_rows(drift: dict) -> list[str]:
    head = f"{'run':>5s} {'idle s':>7s} {'north m/s':>10s} {'east m/s':>10s}"
    return [head, "-" * len(head)] + [f"{n:>5s} {x['seconds']:7.0f} {x['north_m_s']:+10.3f} {x['east_m_s']:+10.3f}"
                                      for n, x in drift.items()]



def crab_rows(crab: dict) -> list[str]:
    head = f"{'run':>5s} {'samples':>8s} {'mean deg':>9s} {'sd deg':>7s} {'u<1 m/s':>8s} {'u>1.2 m/s':>10s}"
    return [head, "-" * len(head)] + [f"{n:>5s} {x['n']:8d} {x['mean_deg']:+9.1f} {x['sd_deg']:7.1f} "
                                      f"{fmt(x['slow_deg'], 1):>8s} {fmt(x['fast_deg'], 1):>10s}"
                                      for n, x in crab.items()]


def markdown(d, scores: dict, extra: dict, seconds: float) -> str:
    fence = "```"
    growth = "; ".join(f"{k}: {v.get('verdict')} (RMS {fmt(v.get('rms_early'), 3)} early, "
                       f"{fmt(v.get('rms_late'), 3)} late)" for k, v in d.growth.items())
    corr = "; ".join(f"{k}: " + ", ".join(f"{c['signal']} {c['r']:+.2f}" for c in v[:3])
                     for k, v in d.correlations.items())
    return "\n".join([
        "# `twin diagnose` of the first-principles BlueBoat twin on real runs",
        "",
        f"Regenerate: `python scripts/diagnose_blueboat.py` ({seconds:.0f} s). Prior: `model/blueboat.json` "
        f"(untuned). Diagnosed on runs {', '.join(map(str, TRAIN_RUNS))} together: {d.windows.get('train')} "
        f"training and {d.windows.get('held_out')} held-out free-run windows of {d.windows.get('length_s')} s "
        "(held-out = every third block of three windows, inside these runs). Then both twins are scored "
        f"on runs {', '.join(map(str, HELD_OUT_RUNS))}, which the diagnosis never saw. HTML with plots: "
        "[blueboat.html](blueboat.html).",
        "",
        "## Effects named",
        "",
        *effect_lines(d),
        "",
        "Candidates fitted fully, per round (kept only with z ≥ "
        f"{search.Z_MIN:g} and ≥ {100 * search.REL_MIN:g} % of the held-out misfit removed, or z ≥ "
        f"{search.Z_LARGE:g} and ≥ {100 * search.REL_LARGE:g} %):",
        "",
        fence, *candidate_rows(d), fence,
        "",
        "## Where the untuned twin disagrees",
        "",
        fence, *located_rows(d), fence,
        "",
        f"Growth along a free run: {growth}.",
        "",
        f"Residual follows: {corr}.",
        "",
        "Unexplained after the amendment:",
        "",
        *unexplained_rows(d),
        "",
        "## Fit before and after",
        "",
        "On the diagnosis's own held-out windows (10-s free runs, R²):",
        "",
        fence, *fit_rows(d), fence,
        "",
        f"On the held-out runs {', '.join(map(str, HELD_OUT_RUNS))} (10-s free runs every 2 s):",
        "",
        fence, *score_rows(scores), fence,
        "",
        *[f"Note: {n}." for n in d.notes],
        "",
        f"Drift with the thrusters idle for over {QUIET_AFTER_S:g} s (ground velocity, all ten runs):",
        "",
        fence, *drift_rows(extra["drift"]), fence,
        "",
        "Track against heading on straight runs under way (u > 0.6 m/s, |r| < 0.05 rad/s), atan2(v, u) per run "
        "(all ten runs; runs with fewer than 20 such samples left out):",
        "",
        fence, *crab_rows(extra["crab"]), fence,
        "",
        "## Discussion",
        "",
        *discussion(d, extra),
    ]) + "\n"


def discussion(d, extra: dict) -> list[str]:
    """What the numbers mean, written from what was found (the honest part is in the wording)."""
    tried = {c["name"]: c for rnd in d.rounds for c in rnd.get("candidates", [])}
    lines = []
    if not d.effects:
        lines.append("The diagnosis amends nothing: the amended twin is the untuned one, and both rows of the "
                     "held-out tables agree. That is the procedure working as designed on weak evidence, not a "
                     "clean bill of health: the residual is far above the noise in every DOF (unexplained, above).")
        lines.append("")
    heading = [tried[k] for k in ("heading_bias", "compass_deviation", "heading_bias_per_log") if k in tried]
    crab = extra["crab"]
    means = [x["mean_deg"] for x in crab.values()]
    if heading:
        best = max(heading, key=lambda c: c["rel"])
        lines.append(
            f"The strongest candidates are heading errors ({best['name']}: {100 * best['rel']:.0f} % of the held-out "
            f"misfit removed, but z {best['z']:.2f}). They point at the same thing as the sway residual, which follows "
            "v and u: under way the measured heading is turned away from the GNSS track.")
        lines.append("")
    if crab:
        steady = all(x["slow_deg"] is None or x["fast_deg"] is None or abs(x["slow_deg"] - x["fast_deg"]) < 2.0
                     for x in crab.values())
        per_log = tried.get("heading_bias_per_log")
        lines.append(
            f"The track-against-heading table says which heading error: the angle is {min(means):+.1f}° to "
            f"{max(means):+.1f}° depending on the run, steady within a run"
            + (" and the same below 1 m/s and above 1.2 m/s" if steady else "")
            + ". That is a compass offset of its own in each log (calibrated afresh, or disturbed by what was on "
            "board that day), not a current or a wind (their angle would shrink as the speed grows), and not one "
            "offset for all runs. The library's `heading_bias_per_log` is that effect"
            + (f"; fitted here it gives {', '.join(f'{v:+.1f}°' for v in per_log['values'].values())} for the "
               f"seven runs and removes {100 * per_log['rel']:.0f} % of the held-out misfit, at z {per_log['z']:.2f}"
               if per_log else ", but it was not among the candidates fitted fully")
            + ". It does not earn its place because of how the evidence is spread: about 85 % of the recorded "
            "time the thrusters idle, and an idle window's residual barely changes with the heading, so most held-out "
            "windows move either way by chance while the few under way carry the whole gain, and the signed-rank test "
            "asks for a consistent gain. Longer runs under way, or a compass calibration logged with each run, would "
            "settle it.")
        lines.append("")
    idle = [e for e in d.located if e["dimension"] == "near_zero_pwm" and e["dof"] == "u"]
    if idle:
        lines.append(
            f"The located bins say one thing: with the thrusters idle the twin's u is {idle[0]['bias']:+.3f} m/s off "
            "the measurement on average (negative: the real boat keeps more speed than the twin, as in the "
            "coast-downs plotted in the HTML report: the twin's surge damping at low speed is too high, or drift "
            "adds to it). The growth verdicts are "
            "'measurement' although the RMS doubles along a run: with 61 windows the growth is not significant.")
        lines.append("")
    east = [x["east_m_s"] for x in extra["drift"].values()]
    lines.append(
        "What the located residual says and no candidate can fix: u is over-predicted backwards when the boat "
        "turns (u residual follows |r|) and r is too small where |r| is large (r residual follows r). In the "
        "held-out spins (226, 228) the twin turns at "
        f"{extra['spin_ratio']:.2f} of the measured yaw rate (median over spinning samples) and backs away while "
        "the boat barely moves. The yaw damping would have to be low at rest and high under way, and reverse "
        "thrust at part throttle weaker than the curve. The library's `speed_damping` (N_|u|r, Y_|u|v) makes "
        "yaw damping grow with speed; "
        + (f"fitted here it removes {100 * tried['speed_damping']['rel']:.0f} % of the held-out misfit at z "
           f"{tried['speed_damping']['z']:.2f}" if "speed_damping" in tried else
           "on these runs it was screened, but its one-step look on the training windows did less than the "
           "candidates fitted fully in each round")
        + ". The spins are a few windows among many; see ../identification/blueboat.md for what a fit of all the "
        "physical parameters at once does.")
    lines.append("")
    if not any(e["name"] == "current" for e in d.effects):
        lines.append(
            "A current is not named, and rightly: idle drift (table) goes east at up to "
            f"{max(east):+.3f} m/s in one run and west at {min(east):+.3f} m/s in another, a few cm/s either way: "
            "wind on the hull and whatever current there was differ per run, so one current for seven runs cannot "
            "earn its place on held-out windows.")
    else:
        lines.append(
            "A current is named, but idle drift (table) differs per run "
            f"(east {min(east):+.3f} to {max(east):+.3f} m/s): one current over seven runs is an average of "
            "different drifts (wind, current), not a property of the water, and should not be kept in the twin.")
    return lines


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "diagnose")
    args = ap.parse_args()
    missing = [p for p in run_paths(TRAIN_RUNS + HELD_OUT_RUNS) if not p.is_file()]
    if missing:
        print(f"skipped: the BlueBoat recordings are not there ({missing[0]}); they live in ../shared, "
              "next to the repository")
        return 0
    started = time.time()
    prior = vessel_mod.load("blueboat")
    recordings = [read_recording(p) for p in run_paths(TRAIN_RUNS)]
    d = diagnose(recordings, prior, log=lambda msg: print(f"{time.time() - started:6.1f} s  {msg}", flush=True))
    scores = held_out_scores(prior, d.amended)
    all_preps = load(run_paths(TRAIN_RUNS + HELD_OUT_RUNS), prior)
    extra = {"drift": idle_drift(all_preps, TRAIN_RUNS + HELD_OUT_RUNS),
             "crab": crab_angles(all_preps, TRAIN_RUNS + HELD_OUT_RUNS),
             "spin_ratio": spin_rate_ratio(prior, all_preps[len(TRAIN_RUNS):])}
    seconds = time.time() - started
    out = {"train_runs": TRAIN_RUNS, "held_out_runs": HELD_OUT_RUNS, "diagnosis": d.to_dict(),
           "amended_vessel": d.amended.to_dict(), "held_out_free_run_10s": scores,
           "idle_drift": extra["drift"], "track_against_heading": extra["crab"],
           "held_out_spin_rate_ratio_twin_over_measured": extra["spin_ratio"],
           "seconds": round(seconds, 1)}
    write_text_atomic(args.out / "blueboat.json", json.dumps(out, indent=1, default=float) + "\n")
    write_text_atomic(args.out / "blueboat.md", wrap(markdown(d, scores, extra, seconds)))
    html = args.out / "blueboat.html"
    write_html(d, html)
    size = html.stat().st_size
    if size > MAX_HTML_BYTES:
        print(f"warning: {html.name} is {size / 1e6:.1f} MB (over the ~1 MB the docs should carry)", file=sys.stderr)
    print("\n".join(effect_lines(d) + score_rows(scores)))
    print(f"wrote {args.out / 'blueboat.md'}, blueboat.json, blueboat.html ({size / 1e3:.0f} kB; {seconds:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
