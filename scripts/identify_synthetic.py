"""Identification recovery on synthetic data with a known truth.

A truth Yellowfish differs from the prior twin by damping, added mass, thrust gain and
a thrust lag; a 20-segment dataset (seed 1) is identified with `twin identify`'s
pipeline, then judged on a held-out dataset from another seed (seed 2): parameters
against the truth, and 10-s free-run R² of u and r. Done noise-free and with the
realistic sensor noise.

    python scripts/identify_synthetic.py [--segments 20] [--out out/...]
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import twin.vessel as vessel_mod  # noqa: E402
from twin.engine.mjcf import compile_vessel  # noqa: E402
from twin.synth.dataset import PROFILES, generate  # noqa: E402
from twin.fit.evaluate import evaluate  # noqa: E402
from twin.fit.calibrate import GNSS_WINDOW_S, HEADING_WINDOW_S  # noqa: E402
from twin.ident.identify import identify, prepared  # noqa: E402
from twin.files import write_text_atomic  # noqa: E402

TRUTH = ["linear_damping=Xu:1.4,Nr:0.7", "quadratic_damping=Xuu:0.8,Nrr:1.3,Yvv:1.2",
         "added_mass=Yvdot:1.3,Nrdot:1.5", "thrust_gain=1.12", "thruster_lag=0.3"]
DOMINANT = ("M11", "M33", "Xuu", "Yv", "Nr", "thrust_full_n")


def physical(v) -> dict[str, float]:
    """The numbers the targets name, from a vessel description."""
    M = compile_vessel(v).hydro().M
    t = v.thrusters
    return {"M11": M[0, 0], "M22": M[1, 1], "M33": M[2, 2], "Xu": v.damping.Xu, "Xuu": v.damping.Xuu,
            "Yv": v.damping.Yv, "Yvv": v.damping.Yvv, "Nr": v.damping.Nr, "Nrr": v.damping.Nrr,
            "thrust_full_n": float(t.thrust_from_pwm(t.pwm_max_us) * t.gain_left),
            "reverse_full_n": float(t.thrust_from_pwm(t.pwm_min_us) * t.gain_left), "lag_s": t.lag_s}


def run(noise: str, segments: int) -> dict:
    prior = vessel_mod.load("yellowfish")
    train = generate(prior, effects=TRUTH, n_segments=segments, seed=1, noise=PROFILES[noise])
    held = generate(prior, effects=TRUTH, n_segments=8, seed=2, noise=PROFILES[noise])
    started = time.time()
    # exactly what `twin identify` does with the recording (its own preparation and calibration)
    report = identify([train.recording], prior)
    seconds = time.time() - started
    truth, got, before = physical(train.truth_vessel), physical(report.vessel), physical(prior)
    rows = [{"name": k, "truth": truth[k], "prior": before[k], "identified": got[k],
             "error": (got[k] - truth[k]) / truth[k] if truth[k] else None} for k in truth]
    held_preps = prepared([held.recording], report.vessel)
    horizons = {"one_step": None, "free_run_10s": 10.0}
    scores = {name: evaluate(v, held_preps, horizons=horizons)
              for name, v in (("truth", train.truth_vessel), ("prior", prior), ("identified", report.vessel))}
    return {"noise": noise, "segments": segments, "sg_windows_s": [GNSS_WINDOW_S, HEADING_WINDOW_S],
            "seconds": round(seconds, 1), "parameters": rows, "held_out": scores,
            "simfit": report.fit.to_dict() if report.fit else None, "choices": report.chosen.label if report.chosen
            else None, "notes": report.notes}


def markdown(results: list[dict]) -> str:
    lines = ["# Identification recovery on synthetic data", "",
             "Truth: the Yellowfish twin with " + ", ".join(f"`{e}`" for e in TRUTH) + ". Prior: the untuned "
             f"`yellowfish`. Training: {results[0]['segments']} segments (seed 1) of the six identification "
             "manoeuvres and the autopilot; judged on 8 held-out segments (seed 2). "
             "`python scripts/identify_synthetic.py`.", ""]
    for r in results:
        lines += [f"## Sensor noise: {r['noise']} (Savitzky-Golay windows {r['sg_windows_s'][0]} s GNSS, "
                  f"{r['sg_windows_s'][1]} s heading; fit {r['seconds']} s)", "",
                  "| parameter | truth | prior | identified | error |", "|---|---|---|---|---|"]
        for p in r["parameters"]:
            err = "-" if p["error"] is None else f"{100 * p['error']:+.1f} %"
            mark = " **" if p["name"] in DOMINANT else ""
            lines.append(f"| {p['name']}{mark} | {p['truth']:.4g} | {p['prior']:.4g} | {p['identified']:.4g} | {err} |")
        lines += ["", "Held-out 10-s free runs (R²):", "", "| twin | u | v | r |", "|---|---|---|---|"]
        for name, s in r["held_out"].items():
            f = s["free_run_10s"]
            lines.append(f"| {name} | " + " | ".join(f"{f[k]['r2']:.3f}" for k in "uvr") + " |")
        lines.append("")
    lines.append("M11 is the anchor (m from the MJCF, Xu̇ at its prior): GNSS, heading and PWM fix only M⁻¹τ and "
                 "M⁻¹D, so one absolute scale must come from outside the recording (twin/fit/simfit.py). "
                 "Names in bold are the targets' dominant terms.")
    lines += ["", "Each window's initial velocities are estimated with the parameters (`simfit.fit`, free_start): "
              "fitted from the measured starts instead, the realistic case gave M33 +12.8 %, Nr −5.4 %, "
              "Yvv −10.9 % (and +61 % on M33 with the 2 cm GNSS jitter alone): errors in the initial "
              "velocities that the fit absorbed into the yaw dynamics."]
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--segments", type=int, default=20)
    ap.add_argument("--noise", default="none,realistic")
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "identification")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    results = []
    for noise in args.noise.split(","):
        results.append(run(noise, args.segments))
        print(f"{noise}: done in {results[-1]['seconds']} s", flush=True)
    write_text_atomic(args.out / "synthetic.json", json.dumps(results, indent=1, default=float) + "\n")
    write_text_atomic(args.out / "synthetic.md", markdown(results))
    print(markdown(results))


if __name__ == "__main__":
    main()
