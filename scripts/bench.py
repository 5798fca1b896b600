#!/usr/bin/env python3
"""Speed of the twin, one run on this machine, medians of repeated timings.

Reports µs per simulated step for the bare engine (same MJCF, no callbacks),
the twin with the Python callbacks, and one evaluation of the analytic
model's right-hand side; and simulated seconds per wall second.

    python scripts/bench.py [--vessel yellowfish] [--steps 2000] [--json out.json]
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import mujoco
import numpy as np

import twin.vessel as vessel_mod
from twin.engine import callbacks
from twin.engine.mjcf import compile_vessel
from twin.engine.sim import initial_state
from twin.physics.hydrodynamics import acceleration
from twin.physics.thrusters import allocation_matrix


def _time_steps(model, data, steps: int, repeats: int) -> float:
    """Median µs per mj_step over `repeats` runs of `steps` steps."""
    out = []
    for _ in range(repeats):
        initial_state(model, data, None, (1.0, 0.1, 0.1))
        data.ctrl[:2] = (10.0, 8.0)
        t0 = time.perf_counter()
        for _ in range(steps):
            mujoco.mj_step(model, data)
        out.append((time.perf_counter() - t0) / steps * 1e6)
    return statistics.median(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vessel", default="yellowfish")
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)

    cv = compile_vessel(vessel_mod.load(args.vessel))
    model, data = cv.model, mujoco.MjData(cv.model)
    h = model.opt.timestep
    bare = _time_steps(model, data, args.steps, args.repeats)
    with callbacks.installed(model, cv.hydro()):
        python = _time_steps(model, data, max(200, args.steps // 4), args.repeats)

    hydro, B = cv.hydro(), allocation_matrix(cv.geometry.thruster_y_m)
    nu, tau = np.array([1.0, 0.1, 0.1]), B @ [10.0, 8.0]
    evals = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        for _ in range(2000):
            acceleration(hydro, 0.3, nu, tau)
        evals.append((time.perf_counter() - t0) / 2000 * 1e6)
    analytic = statistics.median(evals)

    result = {
        "vessel": args.vessel,
        "integrator": mujoco.mjtIntegrator(model.opt.integrator).name,
        "timestep_s": h,
        "bare_us": bare,
        "python_us": python,
        "analytic_us": analytic,
        "python_over_bare": python / bare,
        "bare_simsec_per_s": h / (bare * 1e-6),
        "single_simsec_per_s": h / (python * 1e-6),
    }
    print(f"{'vessel':28s} {args.vessel} ({result['integrator']}, dt = {h * 1e3:g} ms)")
    print(f"{'bare engine':28s} {bare:9.2f} µs/step  {result['bare_simsec_per_s']:10.0f} sim-s per s")
    print(f"{'twin, Python callbacks':28s} {python:9.2f} µs/step  {result['single_simsec_per_s']:10.0f} sim-s per s"
          f"  ({python / bare:.1f} × bare)")
    print(f"{'analytic model (one RHS)':28s} {analytic:9.2f} µs/eval")
    if args.json:
        vessel_mod.write_text_atomic(args.json, json.dumps(result, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
