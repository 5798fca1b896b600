"""Issues 6 and 7 on real data: identify the BlueBoat on seven runs and judge every model on
the three runs it never saw, one step ahead and in free runs of 10 s and 30 s.

    python scripts/identify_blueboat.py [--sets NAME,...] [--out docs/identification]

Models: persistence (one step only), the plain baseline, the seed 004 static and dynamic
grey-boxes, the untuned first-principles twin (model/blueboat.json) and twins identified by
simulation (simfit) with several parameter sets and window lengths. The simulation fit kept
is the one with the best 10-s free-run R² on the TRAINING runs (mean of u and r); the
held-out runs are only ever scored. Writes blueboat.md, blueboat.json and
blueboat_identified.json (a vessel description `twin.vessel.load` reads) under --out.

The recordings (../shared/data/blueboat) have no licence: they are read in place, never
copied; without them the script says so and exits 0.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
import textwrap
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import twin  # noqa: E402
import twin.vessel as vessel_mod  # noqa: E402
from twin.errors import TwinError  # noqa: E402
from twin.files import write_text_atomic  # noqa: E402
from twin.fit import simfit  # noqa: E402
from twin.ident.seed004.baseline import fit_plain  # noqa: E402
from twin.fit.evaluate import (DOFS, TwinPredictor, evaluate, horizon_windows,  # noqa: E402
                                 r2_mae)
from twin.ident.seed004.greybox import fit_dynamic, fit_static  # noqa: E402
from twin.ident.identify import load  # noqa: E402
from twin.fit.windows import ModelCache, measured  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "blueboat"
TRAIN_RUNS = (216, 218, 220, 221, 222, 223, 224)
HELD_OUT_RUNS = (225, 226, 228)
HORIZONS = {"one_step": None, "free_run_10s": 10.0, "free_run_30s": 30.0}
FREE_RUN_10S = {"free_run_10s": 10.0}

# Speed on 2 shared cores: the candidate twins of a fit run with RK4 at 0.05 s (the MJCF's
# own 0.02 s costs 2.5 times more; every score below uses the vessel's own step), windows
# tile the data without overlap (a 10-s window every 5 s doubles the cost for little new
# information: 85 % of the recorded time the thrusters idle), and each fit stops after
# MAX_EVALUATIONS cost evaluations (not always converged: see the report).
FIT_TIMESTEP_S = 0.05
MAX_EVALUATIONS = 25

ASYM = simfit.DEFAULT + ("asymmetry",)
# (name, parameters, window_s, why it is worth trying[, start]): start "measured" (the free runs
# from the recorded initial velocities, as the twin is judged) unless "free" (estimated with the fit)
CANDIDATES = [
    ("default", simfit.DEFAULT, 10.0, "simfit.DEFAULT: damping, added mass, thrust curve, lag"),
    ("default/free", simfit.DEFAULT, 10.0, "the same with each window's initial velocities estimated "
     "(`twin identify`'s default: unbiased by noisy starts when the model is right)", "free"),
    ("+asym", ASYM, 10.0, "the real boat turns under equal PWM: right/left thrust ratio"),
    ("+asym+Yr,Nv", ASYM + ("Yr", "Nv"), 10.0, "linear sway-yaw coupling damping"),
    ("+asym+Yr,Nv/free", ASYM + ("Yr", "Nv"), 10.0, "the same with free starts", "free"),
    ("+asym+current", ASYM + ("current_north", "current_east"), 10.0,
     "one current for all seven runs (a real current differs per run)"),
    ("+asym+Nur,Yuv", ASYM + ("Nur", "Yuv"), 10.0,
     "speed-proportional yaw and sway damping N_|u|r, Y_|u|v (manoeuvring derivatives grow with U)"),
    ("+asym+Yrdot", ASYM + ("Yrdot",), 10.0,
     "M23 = -Yrdot puts M23·u·r in yaw: yaw damping growing with forward speed"),
    ("yaw+surge", ("Xu", "Xuu", "Nr", "Nrr", "Nrdot", "thrust_gain", "reverse_scale", "asymmetry", "Yrdot"), 10.0,
     "sway left at the prior: measured v looks like a heading artefact (see report)"),
    ("+asym 5s", ASYM, 5.0, "shorter windows: closer to one-step, less drift to fit"),
    ("+asym 20s", ASYM, 20.0, "longer windows: slower dynamics weigh more"),
]


# ---------------------------------------------------------------- data

def run_paths(runs) -> list[Path]:
    return [DATA / f"fixed_00000{n}.csv" for n in runs]


def data_missing() -> list[Path]:
    return [p for p in run_paths(TRAIN_RUNS + HELD_OUT_RUNS) if not p.is_file()]


class Persistence:
    """ν̂(k+1) = ν(k): what one-step R² has to beat (a free run of it is no model at all)."""

    def predict_windows(self, prep, starts, n_steps: int) -> np.ndarray:
        nu = np.column_stack([prep.u, prep.v, prep.r])
        return np.repeat(nu[np.asarray(starts, int)][:, None, :], n_steps + 1, axis=1)


@contextlib.contextmanager
def engine_warnings(counter: list[int]):
    """Candidate twins that blow up make MuJoCo print a warning each on file descriptor 2;
    simfit already scores them as failures, so count the lines instead of flooding the log."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            text = sink.read().decode("utf-8", "replace")
            counter[0] += text.count("WARNING")
            other = [ln for ln in text.splitlines() if ln.strip() and "WARNING" not in ln]
            if other:
                print("\n".join(other), file=sys.stderr)


# ---------------------------------------------------------------- models

def reference_models(train, prior) -> tuple[dict, dict]:
    """Models fitted on the training runs, and {name: why it could not be fitted}."""
    models = {"persistence": Persistence(), "plain baseline": fit_plain(train, prior)}
    failed = {}
    for name, fit in (("static grey-box", fit_static), ("dynamic grey-box", fit_dynamic)):
        try:
            models[name] = fit(train)
        except TwinError as exc:
            failed[name] = str(exc)
    models["untuned twin"] = TwinPredictor(prior, ModelCache())
    return models, failed


def fit_candidate(prior, train, held, name, params, window_s, warnings, start: str = "measured") -> dict:
    started = time.time()
    with engine_warnings(warnings):
        res = simfit.fit(prior, train, params, anchor="mass", window_s=window_s, stride_s=window_s,
                         max_evaluations=MAX_EVALUATIONS, cache=ModelCache(FIT_TIMESTEP_S),
                         free_start=start == "free")
        scores = {"train": evaluate(res.vessel, train, horizons=FREE_RUN_10S)["free_run_10s"],
                  "held_out": evaluate(res.vessel, held, horizons=FREE_RUN_10S)["free_run_10s"]}
    return {"name": name, "params": list(params), "window_s": window_s, "start": start, "result": res,
            "vessel": res.vessel, **scores, "score": selection_score(scores["train"]),
            "seconds": round(time.time() - started, 1)}


def implausible(c: dict, prior, train) -> str | None:
    """Why a fitted twin cannot be a hull model, or None. Two a-priori rules: (1) positive yaw
    damping (linearised steady turn) at every surge speed of the training runs: a twin that is
    unstable in yaw at speeds it was fitted on has traded physics for the score; (2) no value
    pinned at an optimiser bound other than zero (zero is a physical bound: no such term)."""
    u = np.concatenate([p.u for p in train])
    lo, hi = np.nanpercentile(u, [1, 99])
    for speed in np.linspace(lo, hi, 9):
        damping = yaw_damping_n_m_s(c["vessel"], float(speed))[0]
        if damping <= 0:
            return f"yaw damping {damping:.0f} N m s at u = {speed:.1f} m/s (unstable in yaw)"
    table = simfit.parameters(prior)
    for e in c["result"].estimates:
        p = table[e.name]
        for bound in (p.lo, p.hi):
            if e.identifiable and bound != 0 and abs(e.value - bound) <= 1e-6 * max(1.0, abs(bound)):
                return f"{e.name} at its bound {bound:g}"
    return None


def selection_score(fit: dict) -> float:
    """Mean 10-s free-run R² of u and r. Not v: the measured sway follows the heading turning
    away from the GNSS track under thrust (see the report), which no hull parameter explains,
    and its negative R² would make the choice one of who fits that artefact least badly."""
    vals = [fit[d]["r2"] for d in ("u", "r")]
    return float(np.mean(vals)) if all(v is not None for v in vals) else -np.inf


def identified_vessel(best: dict, prior) -> vessel_mod.Vessel:
    res = best["result"]
    names = ", ".join(e.name for e in res.estimates if e.identifiable)
    kept = ", ".join(e.name for e in res.estimates if not e.identifiable)
    text = (f"scripts/identify_blueboat.py: simulation fit ({best['name']}) on BlueBoat runs "
            f"{', '.join(map(str, TRAIN_RUNS))} with free-run windows of {best['window_s']:g} s, anchor mass; "
            f"pinned down: {names}"
            + (f"; not pinned down alone (fitted value kept, no uncertainty): {kept}" if kept else "")
            + f". 10-s free-run R² u/r on the training runs {fmt(best['train']['u']['r2'])}/"
            f"{fmt(best['train']['r']['r2'])}, on held-out runs {', '.join(map(str, HELD_OUT_RUNS))} "
            f"{fmt(best['held_out']['u']['r2'])}/{fmt(best['held_out']['r']['r2'])}")
    return replace(best["vessel"], name=f"{prior.name}_identified", sources={**prior.sources, "identification": text})


# ---------------------------------------------------------------- scoring

def window_predictions(model, preps, horizon, stride_s=2.0) -> tuple[np.ndarray, np.ndarray]:
    """(prediction, measurement) (W, n, 3) over the evaluate() windows of one horizon, start dropped."""
    wins = horizon_windows(preps, horizon, stride_s)
    n = max(w.n for w in wins)
    pred = np.full((len(wins), n + 1, 3), np.nan)
    groups: dict[tuple[int, int], list[int]] = {}
    for j, w in enumerate(wins):  # one batch per recording and length: a twin runs them at once
        groups.setdefault((w.rec, w.n), []).append(j)
    for (rec, steps), rows in groups.items():
        starts = np.array([wins[j].start for j in rows])
        pred[rows, : steps + 1] = model.predict_windows(preps[rec], starts, steps)[:, : steps + 1]
    _, meas = measured(preps, wins)
    return pred[:, 1:], meas[:, 1:]


def common_sample_scores(models: dict, preps, horizon) -> dict:
    """Scores on the samples every model predicts: the grey-boxes stop a free run when it leaves
    the thrust regions they were fitted for (surge: both thrusters forward), so their own
    scores leave out the hard stretches (spins) the twins are judged on."""
    runs = {name: window_predictions(m, preps, horizon) for name, m in models.items()}
    meas = next(iter(runs.values()))[1]
    every = np.all([np.isfinite(p).all(axis=-1) | np.isinf(p).any(axis=-1) for p, _ in runs.values()], axis=0)
    every &= np.isfinite(meas).all(axis=-1)
    return {name: r2_mae(np.where(every[..., None], p, np.nan), meas) for name, (p, _) in runs.items()}


def fmt(x, digits=3) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def metric_rows(name: str, metrics: dict) -> list[str]:
    rows = []
    for horizon, m in metrics.items():
        r2 = " ".join(f"{fmt(m[d]['r2']):>7s}" for d in DOFS)
        mae = " ".join(f"{fmt(m[d]['mae'], 4):>7s}" for d in DOFS)
        div = sum(m[d].get("diverged", 0) for d in DOFS)
        note = f" div. {div}" if div else ""
        rows.append(f"{name[:18]:18s} {horizon:12s} {r2}  {mae} {m['u']['n']:6d}{note}")
    return rows


METRIC_HEAD = (f"{'model':18s} {'horizon':12s} " + " ".join(f"{'R2 ' + d:>7s}" for d in DOFS) + "  "
               + " ".join(f"{'MAE ' + d:>7s}" for d in DOFS) + f" {'n':>6s}")


def candidate_rows(cands: list[dict], best: dict) -> list[str]:
    """One row per fit: the twin simfit returned (values it cannot pin down at the prior, the
    rest refitted around them)."""
    head = (f"{'set':16s} {'win':>4s} {'train u':>7s} {'v':>6s} {'r':>6s} {'score':>6s} | "
            f"{'held u':>7s} {'v':>6s} {'r':>6s} {'s':>5s}")
    rows = [head, "-" * len(head)]
    for c in cands:
        if "error" in c:
            rows.append(f"{c['name']:16s} {c['window_s']:4.0f}  failed: {c['error'][:60]}")
            continue
        t, h = c["train"], c["held_out"]
        mark = " <- kept" if c is best else ""
        rows.append(f"{c['name']:16s} {c['window_s']:4.0f} {fmt(t['u']['r2']):>7s} {fmt(t['v']['r2']):>6s} "
                    f"{fmt(t['r']['r2']):>6s} {selection_score(t):6.3f} | {fmt(h['u']['r2']):>7s} "
                    f"{fmt(h['v']['r2']):>6s} {fmt(h['r']['r2']):>6s} {c['seconds']:5.0f}{mark}")
    return rows


def rejected_lines(cands: list[dict]) -> list[str]:
    bad = [c for c in cands if c.get("implausible")]
    if not bad:
        return []
    return ["Not eligible, whatever their score (a-priori rules, `implausible` in the script):", "",
            *[f"- {c['name']}: {c['implausible']}" for c in bad], ""]


def estimate_rows(res: simfit.FitResult) -> list[str]:
    """The kept fit's values; '-' for ± where the value is not pinned down on its own."""
    head = f"{'parameter':14s} {'unit':10s} {'prior':>10s} {'fitted':>11s} {'± 1σ':>9s}  pinned down"
    rows = [head, "-" * len(head)]
    for e in res.estimates:
        sigma = f"{e.sigma:9.3g}" if e.sigma is not None else f"{'-':>9s}"
        why = e.note.replace("uncertainty ", "").split(" exceeds")[0][:32]  # "±1.2e+03", or the reason
        rows.append(f"{e.name:14s} {e.unit[:10]:10s} {e.prior:10.4g} {e.value:11.4g} {sigma}  "
                    f"{'yes' if e.identifiable else f'no ({why})'}")
    stop = "stopped at the evaluation cap" if "maximum number" in res.message else "converged"
    rows.append(f"free-run cost {res.cost_before:.4g} → {res.cost_after:.4g} over {res.n_windows} windows "
                f"({res.n_evaluations} candidate twins, {res.seconds:.0f} s, {stop})")
    return rows


def per_run_rows(models: dict, held, runs) -> tuple[list[str], dict]:
    head = f"{'model':22s} " + " ".join(f"{f'{n} u':>7s} {f'{n} r':>7s}" for n in runs)
    rows, out = [head, "-" * len(head)], {}
    for name, m in models.items():
        per = [evaluate(m, [p], horizons=FREE_RUN_10S)["free_run_10s"] for p in held]
        out[name] = {str(n): x for n, x in zip(runs, per)}
        rows.append(f"{name[:22]:22s} " + " ".join(f"{fmt(x['u']['r2']):>7s} {fmt(x['r']['r2']):>7s}" for x in per))
    return rows, out


# ---------------------------------------------------------------- report


def wrap(text: str, width: int = 100) -> str:
    """Prose lines of a markdown text folded to `width` columns; fenced blocks left as they are."""
    out, fenced = [], False
    for line in text.split("\n"):
        if line.startswith("```"):
            fenced = not fenced
        if fenced or len(line) <= width or line.startswith("```"):
            out.append(line)
            continue
        indent = "  " if line.startswith("- ") else ""
        out.append(textwrap.fill(line, width, subsequent_indent=indent, break_long_words=False,
                                 break_on_hyphens=False))
    return "\n".join(out)

def markdown(ctx: dict) -> str:
    best = ctx["best"]
    fence = "```"
    parts = [
        "# BlueBoat: identification on seven runs, judged on three it never saw",
        "",
        f"Regenerate: `python scripts/identify_blueboat.py` ({ctx['seconds']:.0f} s on this machine). Training runs "
        f"{', '.join(map(str, TRAIN_RUNS))}; held-out runs {', '.join(map(str, HELD_OUT_RUNS))} "
        "(`../shared/data/blueboat/fixed_000002NN.csv`, thr_left mapped to the starboard thruster). "
        "Prior: `model/blueboat.json`. Free runs start from measured states every 2 s and are driven by "
        "the recorded PWM; R² and MAE (m/s, rad/s) over the predicted samples (seed 004 eqs. 40-41).",
        "",
        "## Held-out runs, every model on its own samples",
        "",
        fence, METRIC_HEAD, "-" * len(METRIC_HEAD), *ctx["table_rows"], fence,
        "",
        *[f"- {name}: **refused**: {why}" for name, why in ctx["failed"].items()],
        "",
        "n counts the scored samples (per DOF). The grey-boxes' free runs stop where a window leaves "
        "the thrust regions they were fitted for (surge model: both thrusters forward), so they are "
        "scored on fewer, easier samples; the plain baseline diverges over 30 s (R² unbounded, shown "
        "as -). The same 10-s free runs on the samples every model predicts:",
        "",
        fence, METRIC_HEAD, "-" * len(METRIC_HEAD), *ctx["common_rows"], fence,
        "",
        "The dynamic grey-box's refusal is its own check (seed 004 Prop. 3, α at the stability bound), "
        "not a failure of this script.",
        "",
        "10-s free-run R² per held-out run (225: straight runs and a zig-zag under way; 226, 228: "
        "spins on the spot, one thruster forward, one in reverse):",
        "",
        fence, *ctx["per_run_rows"], fence,
        "",
        "## Simulation fits tried (kept: best score on the TRAINING runs)",
        "",
        "score = mean 10-s free-run R² of u and r on the training runs; kept: the best score among the "
        "physically plausible fits; the held-out columns were not used for the choice. Windows tile the data (stride = window); candidate runs use RK4 "
        f"at {FIT_TIMESTEP_S} s and each fit stops after {MAX_EVALUATIONS} cost evaluations "
        f"({ctx['engine_warnings']} engine warnings from diverging candidates were suppressed).",
        "",
        fence, *candidate_rows(ctx["candidates"], best), fence,
        "",
        *rejected_lines(ctx["candidates"]),
        "Each row scores the twin `simfit.fit` returns: a value it cannot pin down stays at the prior "
        "and the rest is refitted around it.",
        "",
        *[f"- {c['name']}: {c['why']}" for c in ctx["candidates"]],
        "",
        f"Kept: **{best['name']}**, windows of {best['window_s']:g} s; saved as "
        "`blueboat_identified.json` (`twin simulate --model docs/identification/blueboat_identified.json`).",
        "",
        fence, *estimate_rows(best["result"]), fence,
        "",
        "Linearised steady turn (linear damping, Coriolis and Munk terms; quadratic terms left out): yaw "
        "moment per yaw rate and sway per yaw rate at surge speed u (m/s):",
        "",
        fence, *physics_rows(ctx["physics"]), fence,
        "",
        "Kept twin, 10-s free runs on each training run:",
        "",
        fence, *ctx["physics"]["train_rows"], fence,
        "",
        "## Discussion",
        "",
        *discussion(ctx),
    ]
    return "\n".join(parts) + "\n"


# ---------------------------------------------------------------- what the kept twin means

SPEEDS_M_S = (-2.0, -1.0, 0.0, 1.0, 2.0, 3.0)


def yaw_damping_n_m_s(vessel, u_m_s: float) -> tuple[float, float]:
    """Steady turn at surge speed u, linear terms only: (yaw moment per yaw rate, N m s; sway
    per yaw rate, m/s per rad/s). Sway settles where Yv·v + (Yr − M11·u)·r = 0, and that v
    feeds back into yaw through Nv and the Munk moment, so coupling makes the damping depend
    on speed even though no coefficient does."""
    M = np.asarray(twin.effective_parameters(vessel)["M"], float)
    d = vessel.damping
    v_per_r = -(d.Yr - M[0, 0] * u_m_s) / d.Yv if d.Yv else 0.0
    moment = (d.Nr - M[1, 2] * u_m_s) + (d.Nv - (M[1, 1] - M[0, 0]) * u_m_s) * v_per_r
    return -moment, v_per_r


def measured_spin_sway(held) -> float:
    """Median |v|/|r| (m/s per rad/s) of the held-out samples spinning on the spot."""
    ratios = []
    for p in held:
        spin = (np.abs(p.r) > 0.5) & (np.abs(p.u) < 0.6)
        ratios.append(np.abs(p.v[spin]) / np.abs(p.r[spin]))
    both = np.concatenate(ratios)
    return float(np.median(both)) if len(both) else float("nan")


def training_rows(vessel, train) -> tuple[list[str], dict]:
    head = (f"{'run':>5s} " + " ".join(f"{'R2 ' + d:>7s}" for d in DOFS) + " "
            + " ".join(f"{'MAE ' + d:>7s}" for d in DOFS))
    rows, out = [head, "-" * len(head)], {}
    for n, p in zip(TRAIN_RUNS, train):
        m = evaluate(vessel, [p], horizons=FREE_RUN_10S)["free_run_10s"]
        out[str(n)] = m
        rows.append(f"{n:5d} " + " ".join(f"{fmt(m[d]['r2']):>7s}" for d in DOFS) + " "
                    + " ".join(f"{fmt(m[d]['mae'], 4):>7s}" for d in DOFS))
    return rows, out


def physics(ctx: dict, prior, train, held) -> dict:
    kept = ctx["best"]["vessel"]
    table = {name: [yaw_damping_n_m_s(v, u) for u in SPEEDS_M_S] for name, v in (("untuned", prior), ("kept", kept))}
    rows, per_run = training_rows(kept, train)
    return {"yaw": table, "spin_v_per_r_measured": measured_spin_sway(held), "train_rows": rows,
            "train_per_run": per_run}


def physics_rows(phys: dict) -> list[str]:
    head = f"{'twin':8s} {'':16s}" + "".join(f"{f'u={u:+.0f}':>8s}" for u in SPEEDS_M_S)
    rows = [head, "-" * len(head)]
    for name, vals in phys["yaw"].items():
        rows.append(f"{name:8s} {'τN/r (N m s)':16s}" + "".join(f"{m:8.1f}" for m, _ in vals))
        rows.append(f"{'':8s} {'v/r (m/s/rad/s)':16s}" + "".join(f"{w:8.2f}" for _, w in vals))
    return rows


def discussion(ctx: dict) -> list[str]:
    best, phys, cands = ctx["best"], ctx["physics"], ctx["candidates"]
    h, m, common = best["held_out"], ctx["metrics"], ctx["common"]
    plain = m["plain baseline"]["free_run_10s"]
    by = {c["name"]: c for c in cands if "error" not in c}
    est = {e.name: e for e in best["result"].estimates}

    def val(name: str, spec: str) -> str:
        return format(est[name].value, spec) if name in est else "(not fitted)"
    yaw = dict(zip(SPEEDS_M_S, phys["yaw"]["kept"]))
    untuned = dict(zip(SPEEDS_M_S, phys["yaw"]["untuned"]))
    current_r2 = fmt(by["+asym+current"]["held_out"]["r"]["r2"]) if "+asym+current" in by else "-"
    gains = [e.value for c in cands if "error" not in c and not c.get("implausible")
             for e in c["result"].estimates if e.name == "thrust_gain"] or [float("nan")]
    worst = min(phys["train_per_run"].items(),
                key=lambda kv: kv[1]["r"]["r2"] if kv[1]["r"]["r2"] is not None else -1e9)
    out = [
        f"Result. The kept twin ({best['name']}, chosen on the training runs) predicts the held-out runs over "
        f"10 s with R² u {fmt(h['u']['r2'])}, r {fmt(h['r']['r2'])} (plain baseline: u {fmt(plain['u']['r2'])}, "
        f"r {fmt(plain['r']['r2'])}; the issue measured about 0.96 and 0.3 for the baseline before the reader's "
        "thruster mapping was corrected, not re-run here). On the samples every model predicts it has R² u "
        f"{fmt(common['identified twin']['u']['r2'])}, r {fmt(common['identified twin']['r']['r2'])} against the "
        f"static grey-box's {fmt(common['static grey-box']['u']['r2'])}, {fmt(common['static grey-box']['r']['r2'])}, "
        "and unlike the grey-box it predicts the spins at all. The target r ≥ 0.6 is "
        f"{'met' if (h['r']['r2'] or -1) >= 0.6 else 'NOT met'}; v is not predicted (R² {fmt(h['v']['r2'])}).",
        "",
        *start_paragraph(by),
        "What generalises. Surge under way: run 225's u has R² "
        f"{fmt(ctx['per_run']['identified twin']['225']['u']['r2'])} (untuned "
        f"{fmt(ctx['per_run']['untuned twin']['225']['u']['r2'])}); the thrust curve needs a gain of "
        f"{val('thrust_gain', '.2f')} over the 10 V T200 curve (a 4S battery; plausible fits: "
        f"{min(gains):.2f}-{max(gains):.2f}). The "
        f"asymmetry (right/left thrust {val('asymmetry', '.3f')}) is what the runs ask for under equal PWM. Yaw under "
        "way and in spins: the kept twin gets both (runs "
        f"{', '.join(map(str, HELD_OUT_RUNS))}: r R² "
        f"{', '.join(fmt(ctx['per_run']['identified twin'][str(n)]['r']['r2']) for n in HELD_OUT_RUNS)})"
        + (" because its yaw damping grows with speed. " if yaw[2.0][0] > yaw[0.0][0] else
           " although its yaw damping does not grow with speed. ")
        + "The untuned twin's falls with speed (Munk moment: "
        f"{untuned[0.0][0]:.0f} N m s at rest, {untuned[2.0][0]:.0f} at 2 m/s; kept twin: {yaw[0.0][0]:.0f} and "
        f"{yaw[2.0][0]:.0f}, table below), so it spins far too slowly; its yaw time constant M33/|Nr| ≈ 0.07 s is "
        "also why its one-step r is poor. Fitting constant Nr, Nrr (sets default, +asym) can only "
        "split the difference (held-out r "
        f"{fmt(by['default']['held_out']['r']['r2']) if 'default' in by else '-'}, "
        f"{fmt(by['+asym']['held_out']['r']['r2']) if '+asym' in by else '-'}).",
        "",
        *(coupling_paragraph(ctx, yaw, worst) if "Yr" in best["params"] else []),
        "What does not generalise. (1) Sway: under thrust the measured heading turns away from the GNSS track "
        "(run 218: heading 75° → 56°, track 77° → 64° in 3 s, drift angle then 5-8° while coasting straight), "
        "so the measured v grows and decays with u. No hull parameter lets a coasting hull keep a drift angle; "
        "a heading error that grows with thrust (a compass disturbed by the motor currents, followed slowly by the "
        "AHRS) would, and that is a sensor, not hull, effect"
        + ((f" (the kept fit puts Yv at {est['Yv'].value:.0f} N s/m). " if est["Yv"].identifiable else
            f" (the kept fit cannot pin the sway damping down: Yv {est['Yv'].value:.0f} N s/m, left at its "
            "prior). ") if "Yv" in est else ". ")
        + "(2) Surge in spins: the boat barely moves (226, 228) while the twins back away (kept twin: u R² "
        f"{fmt(ctx['per_run']['identified twin']['226']['u']['r2'])}, "
        f"{fmt(ctx['per_run']['identified twin']['228']['u']['r2'])}): at the spin PWMs the real forward and "
        "reverse thrusts nearly cancel where the T200 curve makes reverse the stronger. A smaller reverse_scale "
        "would fix that but takes yaw moment out of the spins, which the twins already under-turn; the fits keep "
        f"it near 1 (kept: {val('reverse_scale', '.2f')}). (3) Currents: one current over seven runs "
        f"(+asym+current: held-out r {current_r2}) "
        "does not help; each run drifts its own way (idle drift of a few cm/s in a direction that changes from run "
        "to run: ../diagnose/blueboat.md). (4) Window length: 5-s windows (the cost then sits in the "
        "first seconds after each measured start) fit yaw worse on training and held-out runs alike; 20-s "
        "windows are no better than 10-s ones.",
        "",
        "Caveats. Fits stop after a capped number of evaluations on a rough cost, and different sets land in "
        "different minima: differences of a few hundredths in the scores mean little. The held-out runs contain "
        "two spins and the training runs one, so held-out r can exceed training r.",
    ]
    return out


def start_paragraph(by: dict) -> list[str]:
    """What estimating each window's initial velocities does on these recordings."""
    pairs = [(m, by[m + "/free"]) for m in by if m + "/free" in by]
    pairs = [(by[m], f) for m, f in pairs]
    if not pairs:
        return []
    def nrdot(c):
        return next((e.value for e in c["result"].estimates if e.name == "Nrdot"), float("nan"))

    text = "; ".join(f"{m['name']}: train score {m['score']:.3f} measured, {f['score']:.3f} free; held-out r "
                     f"{fmt(m['held_out']['r']['r2'])}, {fmt(f['held_out']['r']['r2'])}; Nrdot {nrdot(m):.3g}, "
                     f"{nrdot(f):.3g} kg m2" for m, f in pairs)
    better = "measured" if all(m["score"] > f["score"] for m, f in pairs) else (
        "free" if all(f["score"] > m["score"] for m, f in pairs) else None)
    verdict = {"measured": "the fits from the measured starts score better, as they are judged from measured "
                           "starts: the BlueBoat's measured sway carries a heading artefact that a free start absorbs "
                           "at each window's start and a free run from the recorded state does not",
               "free": "the fits with free starts score better, even judged from measured starts",
               None: "neither start is better on every set"}[better]
    return [
        "Initial velocities. `twin identify` estimates each window's initial velocities with the parameters "
        "(on synthetic data with GNSS jitter this removes a 13-60 % bias in yaw inertia: synthetic.md); "
        f"`--start measured` fits from the recorded ones. Here {verdict} ({text}). From measured starts the "
        "yaw added mass grows large, the errors-in-variables signature seen on synthetic data (a heavier hull "
        "in yaw follows a wrong initial yaw rate less). Both are tried; the training score decides.",
        "",
    ]


def coupling_paragraph(ctx: dict, yaw: dict, worst) -> list[str]:
    """Why the kept twin's yaw works and what it costs (for a kept set with Yr, Nv)."""
    phys = ctx["physics"]
    return [
        "How it does it, and why that is not the hull. No coefficient of the vessel description depends on speed. "
        "The fit found the dependence through sway: with large coupling Yr, Nv a turn drags sway along, and the "
        "sway feeds yaw back, so that the linearised yaw damping τN/r is "
        f"{yaw[0.0][0]:.0f} N m s at rest and {yaw[2.0][0]:.0f} at 2 m/s. The price: (1) sway in a spin of "
        f"{yaw[0.0][1]:.2f} m/s per rad/s, where the boat shows {phys['spin_v_per_r_measured']:.2f} (median over "
        f"held-out spin samples), hence v R² {fmt(ctx['per_run']['identified twin']['228']['v']['r2'])} on run 228; "
        f"(2) the damping falls with reverse speed ({yaw[-2.0][0]:.0f} N m s at −2 m/s), so on the long reverse "
        f"leg of run {worst[0]} the twin's yaw wanders (r R² {fmt(worst[1]['r']['r2'])}, MAE "
        f"{fmt(worst[1]['r']['mae'], 3)} rad/s; run 221 barely turns, so any wander gives a large negative R²). "
        "Yrdot (M23·u·r) does the same more directly and fails in reverse the same way. Coupling values "
        "without ± are not pinned down on their own. A speed-proportional yaw damping N_|u|r (and Y_|u|v), as in "
        "linear manoeuvring models, would say the same without the false sway: the set +asym+Nur,Yuv fits it, "
        "but on these runs it ran to a twin that is unstable in yaw in reverse (not eligible, above).",
        "",
    ]


def to_json(ctx: dict) -> dict:
    def cand(c):
        if "error" in c:
            return {k: c[k] for k in ("name", "params", "window_s", "error")}
        return {"name": c["name"], "params": c["params"], "window_s": c["window_s"], "start": c["start"],
                "why": c["why"],
                "train_free_run_10s": c["train"], "held_out_free_run_10s": c["held_out"], "score": c["score"],
                "implausible": c.get("implausible"),
                "seconds": c["seconds"], "simfit": c["result"].to_dict()}

    return {"train_runs": TRAIN_RUNS, "held_out_runs": HELD_OUT_RUNS, "held_out": ctx["metrics"],
            "held_out_common_samples_free_run_10s": ctx["common"], "held_out_per_run_free_run_10s": ctx["per_run"],
            "refused": ctx["failed"],
            "steady_turn": {"speeds_m_s": SPEEDS_M_S, "yaw_moment_per_r_n_m_s_and_v_per_r": ctx["physics"]["yaw"],
                            "spin_v_per_r_measured": ctx["physics"]["spin_v_per_r_measured"]},
            "kept_train_per_run_free_run_10s": ctx["physics"]["train_per_run"],
            "candidates": [cand(c) for c in ctx["candidates"]],
            "kept": ctx["best"]["name"],
            "selection": "max mean(R2 u, R2 r) of 10-s free runs on the training runs among the plausible fits",
            "fit_settings": {"timestep_s": FIT_TIMESTEP_S, "max_evaluations": MAX_EVALUATIONS, "anchor": "mass",
                             "stride": "= window"},
            "seconds": round(ctx["seconds"], 1)}


# ---------------------------------------------------------------- main

def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sets", default="", help="comma-separated candidate names (default: all)")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "identification")
    args = ap.parse_args()
    missing = data_missing()
    if missing:
        print(f"skipped: the BlueBoat recordings are not there ({missing[0]}); they live in ../shared, "
              "next to the repository")
        return 0
    started = time.time()
    prior = vessel_mod.load("blueboat")
    train, held = load(run_paths(TRAIN_RUNS), prior), load(run_paths(HELD_OUT_RUNS), prior)
    models, failed = reference_models(train, prior)
    only = {s.strip() for s in args.sets.split(",") if s.strip()}
    warnings, cands = [0], []
    for name, params, window_s, why, *start in CANDIDATES:
        if only and name not in only:
            continue
        try:
            c = fit_candidate(prior, train, held, name, params, window_s, warnings, *start)
        except TwinError as exc:
            c = {"name": name, "params": list(params), "window_s": window_s, "error": str(exc), "score": -np.inf}
        c["why"] = why
        cands.append(c)
        if "error" not in c:
            print(f"{name:16s} {window_s:4.0f} s  train u {fmt(c['train']['u']['r2'])} r {fmt(c['train']['r']['r2'])}"
                  f"  held-out u {fmt(c['held_out']['u']['r2'])} r {fmt(c['held_out']['r']['r2'])}  "
                  f"{c['seconds']:.0f} s", flush=True)
        else:
            print(f"{name:16s} failed: {c['error']}", flush=True)
    fitted = [c for c in cands if "error" not in c]
    if not fitted:
        print("error: no simulation fit succeeded", file=sys.stderr)
        return 1
    for c in fitted:
        c["implausible"] = implausible(c, prior, train)
    eligible = [c for c in fitted if not c["implausible"]] or fitted
    best = max(eligible, key=lambda c: c["score"])
    vessel = identified_vessel(best, prior)
    path = vessel_mod.save(vessel, args.out / "blueboat_identified.json")
    vessel_mod.load(str(path))  # the file must stand on its own (its MJCF found relative to it)
    models["identified twin"] = TwinPredictor(vessel, ModelCache())

    metrics, rows = {}, []
    with engine_warnings(warnings):
        for name, model in models.items():
            horizons = {"one_step": None} if name == "persistence" else HORIZONS
            metrics[name] = evaluate(model, held, horizons=horizons)
            rows += metric_rows(name, metrics[name])
        free = {k: m for k, m in models.items() if k != "persistence"}
        common = common_sample_scores(free, held, 10.0)
        per_rows, per_run = per_run_rows({k: free[k] for k in ("plain baseline", "untuned twin", "identified twin")},
                                         held, HELD_OUT_RUNS)
    common_rows = [r for name, m in common.items() for r in metric_rows(name, {"free_run_10s": m})]
    ctx = {"best": best, "candidates": cands, "failed": failed, "metrics": metrics, "table_rows": rows,
           "common": common, "common_rows": common_rows, "per_run": per_run, "per_run_rows": per_rows,
           "engine_warnings": warnings[0]}
    with engine_warnings(warnings):
        ctx["physics"] = physics(ctx, prior, train, held)
    ctx["seconds"] = time.time() - started
    write_text_atomic(args.out / "blueboat.json", json.dumps(to_json(ctx), indent=1, default=float) + "\n")
    write_text_atomic(args.out / "blueboat.md", wrap(markdown(ctx)))
    print("\n".join([METRIC_HEAD, *rows]))
    print(f"kept {best['name']}; wrote {args.out / 'blueboat.md'}, blueboat.json, {path.name} "
          f"({time.time() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
