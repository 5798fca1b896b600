#!/usr/bin/env python3
"""Where the model-based smoother does better than Savitzky-Golay: synthetic
recordings from the twin (known truth) with GNSS noise at the antenna (5 Hz),
heading noise (50 Hz) and PWM at 10 Hz, velocities estimated both ways.

    python scripts/validate_smoother.py [--seeds 3] [--json out.json]
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

import twin
from twin.engine.mjcf import compile_vessel
from twin.recording import Recording, Stream
from twin.prepare import prepare
from twin.prepare.smoother import model_smoothed
from twin.vessel import write_text_atomic


def synthetic_recording(run, antenna_m, rng, sigma_gnss_m: float, sigma_psi_rad: float) -> Recording:
    """Sensors at their real rates and noise from a twin run sampled every 10 ms."""
    tg = np.arange(0, run.t[-1], 0.2)
    th = np.arange(0, run.t[-1], 0.02)
    tp = np.arange(0, run.t[-1], 0.1)
    psi_g = np.interp(tg, run.t, run.eta[:, 2])
    c, s = np.cos(psi_g), np.sin(psi_g)
    north = np.interp(tg, run.t, run.eta[:, 0]) + c * antenna_m[0] - s * antenna_m[1]
    east = np.interp(tg, run.t, run.eta[:, 1]) + s * antenna_m[0] + c * antenna_m[1]
    idx = np.clip(np.searchsorted(run.t, tp + 1e-9, side="right") - 1, 0, len(run.t) - 1)
    return Recording(
        source="synthetic", kind="synthetic",
        gnss=Stream(tg, {"north_m": north + rng.normal(0, sigma_gnss_m, len(tg)),
                         "east_m": east + rng.normal(0, sigma_gnss_m, len(tg))}),
        heading=Stream(th, {"psi_rad": np.interp(th, run.t, run.eta[:, 2]) + rng.normal(0, sigma_psi_rad, len(th))}),
        pwm=Stream(tp, {"left_us": run.pwm_us[idx, 0], "right_us": run.pwm_us[idx, 1]}),
    )


def rmse(a, b):
    return float(np.sqrt(np.mean((a - b) ** 2)))


def _misfit(vessel, factor: float):
    """The same vessel with every damping term and the thrust scaled: a model that is wrong."""
    from dataclasses import asdict, replace

    from twin.physics.damping import Damping

    damping = Damping(**{k: v * factor for k, v in asdict(vessel.damping).items()})
    thrusters = replace(vessel.thrusters, gain_left=vessel.thrusters.gain_left / factor,
                        gain_right=vessel.thrusters.gain_right / factor)
    return replace(vessel, damping=damping, thrusters=thrusters)


def compare(vessel_name: str, seed: int, sigma_gnss_m: float, model_error: float) -> dict:
    vessel = twin.load_vessel(vessel_name)
    compiled = compile_vessel(vessel)
    run = twin.simulate(vessel, "random", 120.0, seed=seed, sample_dt_s=0.02, control_dt_s=0.1)
    antenna = compiled.geometry.gnss_pos_m[:2]
    rec = synthetic_recording(run, antenna, np.random.default_rng(seed), sigma_gnss_m, 0.005)
    prep = prepare(rec, lever_arm_OP_m=tuple(-antenna))
    model = compile_vessel(_misfit(vessel, model_error)) if model_error != 1.0 else compiled
    smoothed = model_smoothed(model, prep, sigma_pos_m=max(sigma_gnss_m, 0.01))
    truth = {k: np.interp(prep.t, run.t, run.nu[:, i]) for i, k in enumerate("uvr")}
    keep = (prep.t > 2) & (prep.t < prep.t[-1] - 2)
    out = {"vessel": vessel_name, "seed": seed, "sigma_gnss_m": sigma_gnss_m, "model_error": model_error}
    for k in "uvr":
        out[f"{k}_rmse_savgol"] = rmse(getattr(prep, k)[keep], truth[k][keep])
        out[f"{k}_rmse_model"] = rmse(getattr(smoothed, k)[keep], truth[k][keep])
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    rows = [compare("yellowfish", seed, sg, err) for err in (1.0, 1.5) for sg in (0.02, 0.3)
            for seed in range(args.seeds)]
    print("RMSE of u, v (m/s) and r (rad/s) against the truth, Savitzky-Golay / model smoother;")
    print("model error 1.5: the smoother's damping x1.5 and thrust /1.5 of the truth")
    print(f"{'seed':>4s} {'GNSS σ':>7s} {'model err':>9s}  " + "  ".join(f"{k} SG / model" for k in "uvr"))
    for r in rows:
        print(f"{r['seed']:4d} {r['sigma_gnss_m']:6.2f}m {r['model_error']:9.1f}  " + "  ".join(
            f"{r[k + '_rmse_savgol']:.4f}/{r[k + '_rmse_model']:.4f}" for k in "uvr"))
    if args.json:
        write_text_atomic(args.json, json.dumps(rows, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
