"""Proof of `twin diagnose` on concealed effects: recordings generated from a truth the
diagnosis never sees (each effect alone at a realistic and a small magnitude, pairs,
closed-loop runs where an autopilot hides the effect, and null cases), with the twin's
realistic sensors (GNSS 5 Hz at the antenna with noise, heading 50 Hz, PWM 10 Hz).

    python scripts/diagnose_proof.py [--only NAME,...] [--segments 8] [--world-seeds 1,2] [--out out/...]
                                     [--refit GROUPS --refit-weight 1] [--add-given]

Two kinds of truth. The library's cases are made by `twin dataset` from the library's own effect
functions (they prove the search finds what it can express). The world cases are made by
scripts/world_sim.py, an independent simulator that never calls the library: effects in forms of
their own (one thruster weakened, Blendermann-like wind tables, battery sag, slew-rate limits,
hysteresis dead zones, hull fouling ∝ u³, toed thrusters, GNSS latency, per-log compass offsets, a wind per outing),
idle-heavy and closed-loop driving, several logs per case. Each world truth names the library
effect that covers it (or "none (model-form)") and the alternatives that approximate it.

Every world truth is also judged *as given*: the library's form of it at the truth's own values
(nothing fitted) against the prior, by the diagnosis's rule on the same blocks
(`twin.diagnose.doctor.given_evidence`). Where even that does not earn its place, the recording
cannot prove the truth in the library's form, whatever the search does: such a miss is the data's,
not the method's. `--add-given` does this for the world cases already in OUT/proof.json (their
recordings made again; no diagnosis run).

--refit runs every diagnosis with those identification groups refitted beside each candidate
(`twin diagnose --refit`); their own effects (a damping scale, the thrust gain, ...) are then not
candidates, so a truth of that kind cannot be named. Write those runs to another --out.

Writes proof.json and proof.md in --out (out/diagnose; the results page is
docs/results/diagnosis_proof.md): per case the effects injected, what
the diagnosis found, the parameter error, and the held-out fit gain; for the world cases the
share of true effects named and of recordings with spurious physics.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path



ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import twin.vessel as vessel_mod  # noqa: E402
from twin.diagnose.doctor import diagnose, given_evidence  # noqa: E402
from twin.diagnose.report import answer, as_json  # noqa: E402
from twin.formats import read_recording  # noqa: E402
from twin.synth.dataset import PROFILES, generate  # noqa: E402
from twin.effects import as_effect, effect  # noqa: E402
from twin.physics.sensors import log_name  # noqa: E402
from twin.vessel import write_text_atomic  # noqa: E402

REFIT: dict = {}  # diagnose()'s refit and refit_weight, from --refit (none: the default diagnosis)
MIXED = ["rc", "forward_varying", "zigzag", "circle_varying", "forward_constant", "circle_constant"]
CLOSED = ["autopilot"]

# (case name, effects, manoeuvres, magnitude label)
CASES = [
    ("null-a", [], MIXED, "-"), ("null-b", [], MIXED, "-"), ("null-autopilot", [], CLOSED, "-"),
    ("current", ["current=0.25,60"], MIXED, "realistic"), ("current-small", ["current=0.08,200"], MIXED, "small"),
    ("wind", ["wind=7,30"], MIXED, "realistic"), ("wind-small", ["wind=3.5,250"], MIXED, "small"),
    ("thruster_lag", ["thruster_lag=0.5"], MIXED, "realistic"),
    ("thruster_lag-small", ["thruster_lag=0.2"], MIXED, "small"),
    ("thrust_ramp", ["thrust_ramp=2.5"], MIXED, "realistic"), ("thrust_ramp-small", ["thrust_ramp=1"], MIXED, "small"),
    ("input_delay", ["input_delay=0.4"], MIXED, "realistic"), ("input_delay-small", ["input_delay=0.16"], MIXED, "small"),
    ("clock_offset", ["clock_offset=0.4"], MIXED, "realistic"),
    ("clock_offset-neg", ["clock_offset=-0.3"], MIXED, "realistic"),
    ("dead_zone", ["dead_zone=0.2,0.2"], MIXED, "realistic"), ("dead_zone-small", ["dead_zone=0.12,0.13"], MIXED, "small"),
    ("thruster_asymmetry", ["thruster_asymmetry=0.85"], MIXED, "realistic"),
    ("thruster_asymmetry-small", ["thruster_asymmetry=0.95"], MIXED, "small"),
    ("thrust_decay", ["thrust_decay=0.04"], MIXED, "realistic"), ("thrust_decay-small", ["thrust_decay=0.015"], MIXED, "small"),
    ("thrust_speed_loss", ["thrust_speed_loss=1.5"], MIXED, "realistic"),
    ("thrust_speed_loss-small", ["thrust_speed_loss=0.6"], MIXED, "small"),
    ("compass_deviation", ["compass_deviation=6,-4"], MIXED, "realistic"),
    ("compass_deviation-small", ["compass_deviation=2,-1.5"], MIXED, "small"),
    ("heading_bias", ["heading_bias=5"], MIXED, "realistic"), ("heading_bias-small", ["heading_bias=2"], MIXED, "small"),
    ("quadratic_damping", ["quadratic_damping=Xuu:1.5"], MIXED, "realistic"),
    ("quadratic_damping-small", ["quadratic_damping=Xuu:1.2"], MIXED, "small"),
    ("linear_damping", ["linear_damping=Nr:0.6"], MIXED, "realistic"),
    ("linear_damping-small", ["linear_damping=Nr:0.85"], MIXED, "small"),
    ("coupling_damping", ["coupling_damping=-6,-4"], MIXED, "realistic"),
    ("added_mass", ["added_mass=Yvdot:1.6"], MIXED, "realistic"),
    ("speed_damping", ["speed_damping=-20,-15"], MIXED, "realistic"),
    ("speed_coupling", ["speed_coupling=15,-5"], MIXED, "realistic"),
    ("cg_offset", ["cg_offset=0.15,0"], MIXED, "realistic"),
    ("gnss_lever_arm", ["gnss_lever_arm=0.4,-0.3"], MIXED, "realistic"),
    ("gnss_lever_arm-small", ["gnss_lever_arm=0.15,-0.1"], MIXED, "small"),
    ("pair current+asymmetry", ["current=0.2,300", "thruster_asymmetry=0.88"], MIXED, "realistic"),
    ("pair lag+heading_bias", ["thruster_lag=0.4", "heading_bias=4"], MIXED, "realistic"),
    ("pair wind+decay", ["wind=7,120", "thrust_decay=0.04"], MIXED, "realistic"),
    ("pair delay+quadratic", ["input_delay=0.3", "quadratic_damping=Xuu:1.5"], MIXED, "realistic"),
    ("autopilot asymmetry", ["thruster_asymmetry=0.85"], CLOSED, "realistic"),
    ("autopilot current", ["current=0.25,60"], CLOSED, "realistic"),
    ("autopilot heading_bias", ["heading_bias=5"], CLOSED, "realistic"),
    # last, so the earlier cases keep their seeds (11 + index): the dataset logs the packs' voltage
    ("supply_voltage", ["supply_voltage=1.5,16"], MIXED, "realistic"),
    ("full_thrust", ["full_thrust=0.75"], MIXED, "realistic"),
    ("heading_latency", ["heading_latency=0.3"], MIXED, "realistic"),
    ("compass_motor", ["compass_motor=8,-5"], MIXED, "realistic"),
    ("compass_motor-small", ["compass_motor=3,-2"], MIXED, "small"),
]
# Several logs diagnosed together, each with its own heading bias (a compass calibrated afresh
# before every outing): (case name, bias of each log in deg, manoeuvres). Each log has half the
# segments of a single-log case.
MULTI_LOG = [("heading_bias per log", [6.0, -4.0, 2.0], MIXED)]
MULTI_LOG_SEED_OFFSET = 47  # random seeds of the multi-log cases start here, so that a case added to CASES moves none


def _truth_values(effect) -> dict[str, float]:
    return effect.flat()


def _param_error(injected, found) -> float | None:
    """Largest relative error over the injected effect's parameters (angles: degrees / 360)."""
    errs = []
    for k, true in _truth_values(injected).items():
        got = found["parameters"].get(k)
        if got is None:
            continue
        if "dir" in k:
            errs.append(abs((got - true + 180.0) % 360.0 - 180.0) / 360.0)
        elif k in ("b_deg", "c_deg", "bias_deg", "heading_bias_deg", "dx_m", "dy_m", "Yr", "Nv", "pwm_clock_offset_s", "Yuv", "Nur") \
                or injected.name == "heading_bias_per_log":
            scale = max(abs(x) for x in _truth_values(injected).values())
            errs.append(abs(got - true) / scale)
        else:
            errs.append(abs(got - true) / abs(true) if true else abs(got))
    return max(errs) if errs else None


def run_case(name, effects, manoeuvres, segments, seed) -> dict:
    prior = vessel_mod.load("yellowfish")
    ds = generate(prior, effects=effects, n_segments=segments, manoeuvres=manoeuvres, seed=seed,
                  noise=PROFILES["realistic"])
    return _score(name, effects, manoeuvres, seed, prior, [ds.recording])


def run_multi_log(name, biases_deg, manoeuvres, segments, seed) -> dict:
    """Logs with their own heading bias, diagnosed together; the truth is one per-log effect."""
    prior = vessel_mod.load("yellowfish")
    recordings = [generate(prior, effects=[f"heading_bias={b}"], n_segments=max(3, segments // 2),
                           manoeuvres=manoeuvres, seed=1000 * seed + i, noise=PROFILES["realistic"]).recording
                  for i, b in enumerate(biases_deg)]
    truth = effect("heading_bias_per_log", **{log_name(r.source): b for r, b in zip(recordings, biases_deg)})
    return _score(name, [truth.text], manoeuvres, seed, prior, recordings)


def _score(name, effects, manoeuvres, seed, prior, recordings) -> dict:
    started = time.time()
    d = diagnose(recordings, prior, **REFIT)
    found = {e["name"]: e for e in d.effects}
    # an effect named only as a rival that this recording cannot tell from the one kept
    ambiguous = {r["name"]: (e["name"], r) for e in d.effects for r in e["rivals"] if not r["separable"]}
    rows = []
    calibrations = {c.log: c.heading_bias_deg for c in d.calibrations if c.heading_bias_deg is not None}
    for e in (as_effect(x) for x in effects):
        hit = found.get(e.name)
        kept_instead, rival = ambiguous.get(e.name, (None, None))
        if hit is None and rival is not None:
            hit = {"parameters": rival["parameters"], "ci": None, "separable": False}
        if hit is None and e.name in ("heading_bias", "heading_bias_per_log") and calibrations:
            # the per-log kinematic calibration runs before the search and takes a compass offset out
            if e.name == "heading_bias":
                hit = {"parameters": {"heading_bias_deg": next(iter(calibrations.values()))}, "ci": None,
                       "separable": True, "by_calibration": True}
            else:
                hit = {"parameters": {log: calibrations.get(log, 0.0) for log in _truth_values(e)}, "ci": None,
                       "separable": True, "by_calibration": True}
        rows.append({"effect": e.name, "injected": _truth_values(e), "found": hit is not None,
                     "by_calibration": bool(hit and hit.get("by_calibration")),
                     "as_rival_of": kept_instead if e.name not in found else None,
                     "parameters": hit["parameters"] if hit else None, "ci": hit["ci"] if hit else None,
                     "error": _param_error(e, hit) if hit else None,
                     "separable": hit["separable"] if hit else None})
    injected = {as_effect(x).name for x in effects}
    named_for = {r["as_rival_of"] for r in rows if r["as_rival_of"]}  # kept in place of an injected one
    extra = [e["name"] for e in d.effects if e["name"] not in injected and e["name"] not in named_for]
    return {"case": name, "effects": effects, "manoeuvres": manoeuvres, "rows": rows, "extra": extra,
            "fit_before": d.fit_before, "fit_after": d.fit_after, "seconds": round(time.time() - started, 1),
            "unexplained": len(d.unexplained), "found_all": all(r["found"] for r in rows), "seed": seed,
            "hints": [u.split(" may be missing")[0] for u in answer(d)["unsettled"] if " may be missing" in u],
            "kept": [{"name": e["name"], "parameters": e["parameters"], "rivals": e["rivals"]} for e in d.effects]}


# ------------------------------------------------------------------ independent truths (world_sim)

WORLD_SIM = ROOT / "scripts" / "world_sim.py"
# the library's effects that express the same physics in another parametrisation
SAME = {"thruster_asymmetry": {"thruster_asymmetry", "thruster_gain_left", "thruster_gain_right"},
        "wind": {"wind", "wind_shape"}, "heading_bias_per_log": {"heading_bias_per_log"},
        "input_delay": {"input_delay"}, "dead_zone": {"dead_zone"},
        # a drag growing faster than u²: the quadratic scales, or the surge resistance curve (Xu and Xuu
        # together, the joint change the world's truth file gives beside the quadratic one alone)
        "quadratic_damping": {"quadratic_damping", "surge_resistance"},
        # a slew limit: the ramp, or the first-order lag, its nearest equivalent, also counted as naming it
        "thrust_ramp": {"thrust_ramp", "thruster_lag"},
        # a pack that sags: the thrust decaying in time, or following the logged battery voltage (the
        # world's own form, thrust ∝ (V/V_ref)²)
        "thrust_decay": {"thrust_decay", "supply_voltage"},
        # each log's own wind, and the load's shape the world's tables give it (as wind_shape is for one wind)
        "wind_per_log": {"wind_per_log", "wind_load_shape"}}
CALIBRATION_TOLERANCE_DEG = 1.5


def world_cases() -> list[str]:
    out = subprocess.run([sys.executable, str(WORLD_SIM), "--list"], capture_output=True, text=True, check=True)
    return [line.split()[0] for line in out.stdout.splitlines() if line.strip()]


def world_recording(case: str, seed: int, work: Path, params: Path) -> tuple[dict, list]:
    """The truth and the recordings world_sim writes for a case and seed (the same bytes every time)."""
    folder = work / f"{case}_s{seed}"
    folder.mkdir(parents=True, exist_ok=True)
    truth_path = folder / "truth.json"
    cmd = [sys.executable, str(WORLD_SIM), "--params", str(params), "--case", case, "--seed", str(seed),
           "--truth", str(truth_path)]
    cmd += ["--out-dir", str(folder)] if _multilog(case) else ["--out", str(folder / f"{case}.csv")]
    subprocess.run(cmd, check=True, capture_output=True)
    return json.loads(truth_path.read_text()), [read_recording(p) for p in sorted(folder.glob("*.csv"))]


def add_given(result: dict, work: Path, params: Path) -> dict:
    """An earlier run's result with each truth judged as given (its recording made again: world_sim is
    deterministic); the diagnosis is not run again."""
    truth, recordings = world_recording(result["case"], result["seed"], work, params)
    prior = vessel_mod.load("yellowfish")
    for row, t in zip(result["rows"], truth["effects"]):
        row["given"] = given_truth(recordings, prior, t)
    return result


def run_world(case: str, seed: int, work: Path, params: Path) -> dict:
    """One world_sim recording (or group of logs), diagnosed with the yellowfish prior, scored
    against the truth file the simulator wrote."""
    truth, recordings = world_recording(case, seed, work, params)
    started = time.time()
    prior = vessel_mod.load("yellowfish")
    d = diagnose(recordings, prior, **REFIT)
    out = score_world(case, seed, truth, as_json(d), round(time.time() - started, 1))
    for row, t in zip(out["rows"], truth["effects"]):
        row["given"] = given_truth(recordings, prior, t)
    return out


def library_form(truth_effect: dict, prior: vessel_mod.Vessel) -> str | None:
    """The library's form of a world effect at the truth's own values (the effect text the simulator's
    `expected_values` translate to), or None where the library has no form of it (model-form truths,
    measurement faults). A world form the library's does not cover (a hysteresis's stop edges, a tidal
    current's drift, a wind table's shape) is given as the library's nearest: the truth as the twin can
    hold it, not the truth."""
    kind, x = truth_effect["kind"], truth_effect.get("expected_values") or {}
    if kind in GIVEN_AS:
        name, keys = GIVEN_AS[kind]
        return f"{name}=" + ",".join(str(abs(x[k]) if name == "dead_zone" else x[k]) for k in keys)
    t = prior.thrusters
    width = lambda pwm: abs(float(t.normalised(pwm)) - float(t.normalised(t.neutral_us)))  # noqa: E731
    forms = {
        "deadzone_hysteresis": lambda: f"motor_start={width(x['start_fwd_pwm_us'])},{width(x['start_rev_pwm_us'])}",
        "hull_fouling": lambda: f"quadratic_damping=Xuu:{x['Xuu_total_alone'] / prior.damping.Xuu}",
        "yaw_drag_shape": lambda: f"linear_damping=Nr:{x['Nr_total_alone'] / prior.damping.Nr}",
        "compass_offset_per_log": lambda: "heading_bias_per_log=" + ",".join(
            f"{log}:{deg}" for log, deg in x["offset_deg_by_log"].items()),
        "wind_per_outing": lambda: "wind_per_log=" + ",".join(
            f"{log}:{w['speed_m_s']}@{w['dir_from_deg']}" for log, w in x["by_log"].items()),
    }
    return forms[kind]() if kind in forms else None


# world kind → (library effect, the truth's expected values in the effect's order); a tidal current is
# given at its mean, a wind of another table shape through the library's own shape
GIVEN_AS = {
    "weak_thruster_left": ("thruster_gain_left", ("gain_left",)),
    "weak_thruster_right": ("thruster_gain_right", ("gain_right",)),
    "both_thrusters_strong": ("thrust_gain", ("gain",)),
    "wind_shape": ("wind", ("speed_m_s", "dir_from_deg")),
    "constant_current": ("current", ("speed_m_s", "dir_deg")),
    "current_tidal": ("current", ("speed_m_s", "dir_deg")),
    "battery_sag": ("thrust_decay", ("linear_fit_decay_per_min",)),
    "thruster_rate_limit": ("thrust_ramp", ("ramp_s",)),
    "input_delay": ("input_delay", ("delay_s",)),
    "deadzone_asym": ("dead_zone", ("fwd_delta_unit", "rev_delta_unit")),
    "gnss_latency": ("gnss_latency", ("gnss_latency_s",)),
    "gnss_antenna_offset": ("gnss_lever_arm", ("antenna_offset_x_m", "antenna_offset_y_m")),
    "compass_iron": ("compass_deviation", ("b_deg", "c_deg", "d_deg", "e_deg")),
    "compass_motor_field": ("compass_motor", ("b_deg", "c_deg")),
    "thrust_ventilation": ("full_thrust", ("share",)),
    "pwm_clock_offset": ("clock_offset", ("pwm_clock_offset_s",)),
    "astern_drag": ("astern_resistance", ("excess",)),
    "heading_lag": ("heading_latency", ("heading_latency_s",)),
}


def given_truth(recordings, prior, truth_effect: dict) -> dict | None:
    """The truth in the library's form at its own values, nothing fitted, judged by the diagnosis's rule
    on the recording's blocks (doctor.given_evidence): whether the recording can prove it at all."""
    text = library_form(truth_effect, prior)
    if text is None:
        return None
    # each log's compass offset is what the kinematic calibration finds before any candidate: given on top
    # of it, it would change nothing; judged against the twin without it, it says what the rule would
    e = given_evidence(recordings, prior, [text], calibrated=truth_effect["kind"] != "compass_offset_per_log")
    return {"effect": text, "z": round(e.z, 2), "excess_gain": round(e.rel_excess, 4), "blocks_for": e.blocks_for,
            "blocks_against": e.blocks_against, "earns_its_place": bool(e.earns_its_place())}


def _multilog(case: str) -> bool:
    return "multilog" in case or case == "compass_offset_per_log"


def _base(name: str) -> str:
    return name.split(" (")[0].strip()


def score_world(case: str, seed: int, truth: dict, d: dict, seconds: float) -> dict:
    named = [e["name"] for e in d["effects"]]
    rows, explained = [], set()
    for t in truth["effects"]:
        eq = t.get("library_equivalent") or "none"
        alternatives = {_base(a) for a in t.get("library_alternatives") or []}
        same = SAME.get(eq, {eq})
        how = None
        if set(named) & same:
            how, hit = "named", sorted(set(named) & same)
        elif eq == "heading_bias_per_log" and _calibrated_ok(t, d):
            how, hit = "calibrated", ["per-log compass calibration"]
        elif set(named) & alternatives:
            how, hit = "alternative", sorted(set(named) & alternatives)
        else:
            hit = []
        explained |= set(hit)
        model_form = eq.startswith("none")
        rows.append({"kind": t["kind"], "equivalent": eq, "model_form": model_form, "how": how, "by": hit,
                     "params": t.get("params"), "expected": t.get("expected_values"),
                     "found_params": {e["name"]: e["parameters"] for e in d["effects"] if e["name"] in hit}})
    spurious = [n for n in named if n not in explained]
    return {"case": case, "seed": seed, "description": truth.get("description", ""), "rows": rows, "named": named,
            "spurious": spurious, "fit_before": d["fit_before"], "fit_after": d["fit_after"], "seconds": seconds,
            "unsettled": d["answer"]["unsettled"], "form": d["answer"]["form"],
            "calibrations": [c for c in d.get("calibrations", []) if c.get("heading_bias_deg") is not None]}


def _calibrated_ok(truth_effect: dict, d: dict) -> bool:
    """Every log's compass offset recovered by the per-log calibration within the tolerance."""
    want = (truth_effect.get("params") or {}).get("offset_deg_by_log") or {}
    got = {c["log"]: c["heading_bias_deg"] for c in d.get("calibrations", [])}
    return bool(want) and all(abs(deg) < CALIBRATION_TOLERANCE_DEG or
                              (got.get(log) is not None and abs(got[log] - deg) <= CALIBRATION_TOLERANCE_DEG)
                              for log, deg in want.items())


def world_summary(results: list[dict]) -> dict:
    real = [row for r in results for row in r["rows"] if not row["model_form"]]
    form = [row for r in results for row in r["rows"] if row["model_form"]]
    nulls = [r for r in results if not r["rows"]]
    with_truth = [r for r in results if r["rows"]]
    return {"recordings": len(results), "true_effects": len(real),
            "named": sum(x["how"] == "named" for x in real), "calibrated": sum(x["how"] == "calibrated" for x in real),
            "alternative": sum(x["how"] == "alternative" for x in real),
            "model_form_truths": len(form), "model_form_approximated": sum(x["how"] == "alternative" for x in form),
            "nulls": len(nulls), "nulls_clean": sum(not r["named"] for r in nulls),
            "with_spurious": sum(bool(r["spurious"]) for r in results),
            "with_spurious_among_effect_cases": sum(bool(r["spurious"]) for r in with_truth),
            "effect_cases": len(with_truth), **_given_summary(real)}


def _given_summary(real: list[dict]) -> dict:
    """The truths judged as given (run_world's `given`): how many the recording can prove in the library's
    form at their own values, and of those and of the rest how many the diagnosis named (or calibrated)."""
    judged = [x for x in real if x.get("given")]
    if not judged:
        return {}
    found = lambda x: x["how"] in ("named", "calibrated")  # noqa: E731
    provable = [x for x in judged if x["given"]["earns_its_place"]]
    rest = [x for x in judged if not x["given"]["earns_its_place"]]
    return {"given_judged": len(judged), "given_provable": len(provable),
            "named_where_provable": sum(map(found, provable)), "named_where_not_provable": sum(map(found, rest))}


def world_markdown(results: list[dict]) -> str:
    s = world_summary(results)
    share = lambda a, b: f"{a} of {b} ({100 * a / max(b, 1):.0f} %)"  # noqa: E731
    lines = ["## Truths the library did not write (scripts/world_sim.py)", "",
             "Each recording is made by an independent simulator with its own forms of the effects (see "
             "scripts/world_cases.md); the diagnosis sees only the CSV log and the yellowfish prior. "
             "*named*: the library effect that covers the truth (for a weakened thruster its per-thruster gain, for "
             "a wind of another coefficient shape `wind` or `wind_shape`, and beside each log's own wind "
             "(`wind_per_log`) the load shape `wind_load_shape`); *calibrated*: per-log compass offsets "
             "recovered by the kinematic calibration within 1.5°; *alternative*: an effect the truth file lists as "
             "approximating it; *spurious*: anything else named.", "",
             f"- true effects named: {share(s['named'] + s['calibrated'], s['true_effects'])} "
             f"({s['named']} named, {s['calibrated']} by the per-log calibration); "
             f"a further {s['alternative']} named only in an approximating form",
             f"- recordings with spurious physics: {share(s['with_spurious'], s['recordings'])}",
             f"- null recordings clean: {share(s['nulls_clean'], s['nulls'])}",
             f"- truths outside the library (model-form): {s['model_form_truths']}, of which "
             f"{s['model_form_approximated']} drew an approximating effect the truth lists",
             *([f"- **the truth as given** (the library's form at the truth's own values, nothing fitted, judged by "
                f"the same rule on the same blocks: can this recording prove it at all?): earns its place for "
                f"{share(s['given_provable'], s['given_judged'])} of the true effects; of those the diagnosis named "
                f"{share(s['named_where_provable'], s['given_provable'])}; of the "
                f"{s['given_judged'] - s['given_provable']} the recording cannot prove as given, it named "
                f"{s['named_where_not_provable']} (a fitted form may do better than the given one)"]
               if s.get("given_judged") else []), "",
             "| case | seed | truth (library equivalent) | found | the truth as given: z, share of the excess | "
             "spurious | hints not proven | held-out R² u / v / r before → after | s |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        truth = "; ".join(f"{x['kind']} ({x['equivalent']})" for x in r["rows"]) or "none"
        found = "; ".join(f"{'✔' if x['how'] in ('named', 'calibrated') else ('≈' if x['how'] else '✘')} "
                          f"{', '.join(x['by']) or '-'}" for x in r["rows"]) or ("✔ nothing" if not r["named"] else "")
        hints = "; ".join(u.split(" may be missing")[0] for u in r["unsettled"] if "may be missing" in u) or "-"
        fit = " / ".join(f"{_r2(r['fit_before'][k])} → {_r2(r['fit_after'][k])}" for k in "uvr")
        given = "; ".join(_given_cell(x.get("given")) for x in r["rows"]) or "-"
        lines.append(f"| {r['case']} | {r['seed']} | {truth} | {found} | {given} | {', '.join(r['spurious']) or '-'} | "
                     f"{hints} | {fit} | {r['seconds']} |")
    return "\n".join(lines) + "\n"


def _given_cell(g: dict | None) -> str:
    if not g:
        return "-"
    return f"{'earns' if g['earns_its_place'] else 'no'} (z {g['z']:.2f}, {100 * g['excess_gain']:.1f} %)"


def markdown(results: list[dict]) -> str:
    lines = ["# `twin diagnose` on concealed effects", "",
             "## Truths made by the library's own effect functions (`twin dataset`)", "",
             "These prove that the search finds what the library can express, no more. "
             "Recordings from a truth the diagnosis never sees; realistic sensors (GNSS 5 Hz at the antenna, "
             "2 cm white + 0.5 m wander; heading 50 Hz, 0.3°; PWM 10 Hz). Prior twin: `yellowfish`. "
             "Regenerate: `python scripts/diagnose_proof.py`.", "",
             "| case | injected | found | parameter error | extra effects named | hints not proven | "
             "held-out R² u / v / r before → after | s |",
             "|---|---|---|---|---|---|---|---|"]
    for r in results:
        inj = "; ".join(r["effects"]) or "none"
        found = ", ".join(("✔ " if x["found"] else "✘ ") + x["effect"] + _ambiguity(x) for x in r["rows"]) \
            or ("✔ nothing" if not r["extra"] else "✘")
        err = ", ".join(f"{100 * x['error']:.0f} %" for x in r["rows"] if x["error"] is not None) or "-"
        fit = " / ".join(f"{_r2(r['fit_before'][k])} → {_r2(r['fit_after'][k])}" for k in "uvr")
        lines.append(f"| {r['case']} | {inj} | {found} | {err} | {', '.join(r['extra']) or '-'} | "
                     f"{', '.join(r.get('hints', [])) or '-'} | {fit} | "
                     f"{r['seconds']} |")
    singles = [r for r in results if len(r["effects"]) == 1 and "small" not in r["case"] and "autopilot" not in r["case"]]
    ok = [r for r in singles if r["found_all"] and all((x["error"] or 0) <= 0.2 for x in r["rows"])]
    nulls = [r for r in results if not r["effects"]]
    pairs = [r for r in results if len(r["effects"]) == 2]
    lines += ["", "✔ … (not separable …): the effect was found, but this recording cannot tell it from the rival "
                  "named, and the diagnosis says so; the error is that of the effect's own fit.",
              "", f"Single effects at realistic magnitude found with the parameter within 20 %: {len(ok)} of "
                  f"{len(singles)}. Null cases with no effect named: {sum(not r['extra'] for r in nulls)} of "
                  f"{len(nulls)}. Pairs with both found: {sum(r['found_all'] for r in pairs)} of {len(pairs)}."]
    return "\n".join(lines) + "\n"


def _ambiguity(row: dict) -> str:
    if row.get("by_calibration"):
        return " (by the per-log compass calibration)"
    if row["as_rival_of"]:
        return f" (not separable from {row['as_rival_of']}, which was kept)"
    return "" if row["separable"] in (None, True) else " (not separable from a rival)"


def _r2(m) -> str:
    return "-" if m.get("r2") is None else f"{m['r2']:.3f}"


def refit_note(args) -> str:
    """What a --refit run is, above its report (an empty string otherwise)."""
    if not REFIT:
        return ""
    groups = ",".join(REFIT["refit"])
    return (f"> Every diagnosis below ran with `--refit {groups}` (beliefs ×{REFIT['refit_weight']:g}): the prior's "
            "own coefficients of those groups refitted beside each candidate; the effects they already move are "
            f"not candidates. Regenerate: `python scripts/diagnose_proof.py --refit \"{groups}\" --only "
            f"{args.only} --world-seeds {args.world_seeds} --out {args.out.relative_to(ROOT)}`.\n\n")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="", help="comma-separated case names (library or world)")
    ap.add_argument("--segments", type=int, default=8)
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--world-seeds", default="1,2", help="seeds of the world_sim cases ('' for none)")
    ap.add_argument("--no-library", action="store_true", help="only the world_sim cases")
    ap.add_argument("--append", action="store_true",
                    help="keep the cases already in OUT/proof.json and add these (same case and seed: replaced)")
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "diagnose")
    ap.add_argument("--refit", default="", help="identification groups refitted beside every candidate (comma separated)")
    ap.add_argument("--refit-weight", type=float, default=1.0)
    ap.add_argument("--add-given", action="store_true",
                    help="judge the truths of the world cases already in OUT/proof.json as given (no diagnosis run)")
    args = ap.parse_args()
    if args.refit:
        REFIT.update(refit=tuple(g.strip() for g in args.refit.split(",") if g.strip()), refit_weight=args.refit_weight)
    only = {s.strip() for s in args.only.split(",") if s.strip()}
    args.out.mkdir(parents=True, exist_ok=True)
    results, world = [], []
    if args.add_given:  # nothing diagnosed: the results already in OUT are completed
        args.append, args.no_library = True, True
    if args.append and (args.out / "proof.json").is_file():
        old = json.loads((args.out / "proof.json").read_text())
        results, world = old.get("library", []), old.get("world", [])

    def save():
        order = {c: i for i, c in enumerate(world_cases())}  # a re-run case back in its place
        world.sort(key=lambda w: (w["seed"], order.get(w["case"], len(order))))
        write_text_atomic(args.out / "proof.json", json.dumps({"library": results, "world": world,
                                                               "world_summary": world_summary(world)},
                                                              indent=1, default=float) + "\n")

    for k, (name, effects, manoeuvres, _) in enumerate([] if args.no_library else CASES):
        if only and name not in only:
            continue
        res = run_case(name, effects, manoeuvres, args.segments, args.seed + k)
        results[:] = [r for r in results if r["case"] != name] + [res]
        found = ", ".join(f"{x['effect']}={'yes' if x['found'] else 'NO'}" for x in res["rows"]) or "-"
        print(f"{name:28s} found: {found:40s} extra: {','.join(res['extra']) or '-':20s} {res['seconds']} s",
              flush=True)
        save()
    for k, (name, biases, manoeuvres) in enumerate([] if args.no_library else MULTI_LOG):
        if only and name not in only:
            continue
        res = run_multi_log(name, biases, manoeuvres, args.segments, args.seed + MULTI_LOG_SEED_OFFSET + k)
        results[:] = [r for r in results if r["case"] != name] + [res]
        print(f"{name:28s} found: {'yes' if res['found_all'] else 'NO':40s} extra: {','.join(res['extra']) or '-':20s} "
              f"{res['seconds']} s", flush=True)
        save()
    seeds = [int(x) for x in args.world_seeds.split(",") if x.strip()]
    if args.add_given:
        seeds = []
        with tempfile.TemporaryDirectory() as tmp:
            params = Path(tmp) / "yellowfish_params.json"
            params.write_text(subprocess.run([sys.executable, "-m", "twin", "params", "--vessel", "yellowfish", "--json"],
                                             capture_output=True, text=True, check=True).stdout)
            for k, res in enumerate(world):
                if res["rows"] and not all("given" in row for row in res["rows"]):
                    world[k] = add_given(res, Path(tmp), params)
                    print(f"{res['case']:30s} s{res['seed']} given: "
                          f"{[row['given'] and row['given']['earns_its_place'] for row in res['rows']]}", flush=True)
                    save()
    if seeds:
        with tempfile.TemporaryDirectory() as tmp:
            work = Path(tmp)
            params = work / "yellowfish_params.json"
            params.write_text(subprocess.run([sys.executable, "-m", "twin", "params", "--vessel", "yellowfish", "--json"],
                                             capture_output=True, text=True, check=True).stdout)
            for seed in seeds:
                for case in world_cases():
                    if only and case not in only:
                        continue
                    res = run_world(case, seed, work, params)
                    world[:] = [w for w in world if (w["case"], w["seed"]) != (case, seed)] + [res]
                    print(f"{case:30s} s{seed} named {','.join(res['named']) or '-':40s} spurious "
                          f"{','.join(res['spurious']) or '-':20s} {res['seconds']} s", flush=True)
                    save()
    save()
    text = refit_note(args) + (markdown(results) if results else "# `twin diagnose` on concealed effects\n") + \
        "\n" + (world_markdown(world) if world else "")
    write_text_atomic(args.out / "proof.md", text)
    print(f"wrote {args.out / 'proof.md'}")


if __name__ == "__main__":
    main()
