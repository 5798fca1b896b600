#!/usr/bin/env python3
"""Speed of the twin: one run on this machine, medians of repeated timings.

µs per simulated step of the bare engine (same MJCF, no callbacks), the twin
with the Python callbacks and with the native (numba) callbacks, one
evaluation of the analytic model's right-hand side; each as a ratio to the bare
engine. Simulated seconds per wall second of the same work (256 runs of 60 s)
done by one twin, run after run, and by a batch of twins on all cores, and of
the main job end to end: `twin.simulate` of a 1-h zig-zag (vessel loaded and
compiled, the closed-loop scenario at the autopilot rate) written to CSV, as a
ratio to the one twin's rate (the engine's own speed); the three timed in turn.
Default integrator and time step of the vessel's MJCF.

The 6-DOF hull in an irregular sea (`--sea`, default a JONSWAP Hs 0.3 m, Tp 2.5 s short-crested
sea) against the 3-DOF twin, the two timed in turn in the same run: simulated seconds per wall
second of one twin on one core (60 s runs under a constant thrust), and their ratio.

    python scripts/bench.py [--vessel yellowfish] [--batch 256] [--sea 0.3,2.5,30,4] [--json out.json]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np

import twin.vessel as vessel_mod
from twin import api, outputs
from twin.engine import batch, callbacks, native
from twin.engine.mjcf import compile_vessel
from twin.engine.sim import initial_state
from twin.physics.hydrodynamics import acceleration
from twin.physics.thrusters import allocation_matrix


def _us_per_step(model, steps: int, repeats: int) -> float:
    """Median µs per step, stepping inside the engine (mj_step with nstep) from a moving state."""
    data = mujoco.MjData(model)
    out = []
    for _ in range(repeats):
        initial_state(model, data, None, (1.0, 0.1, 0.1))
        data.ctrl[:2] = (10.0, 8.0)
        t0 = time.perf_counter()
        mujoco.mj_step(model, data, nstep=steps)
        out.append((time.perf_counter() - t0) / steps * 1e6)
    return statistics.median(out)


def _analytic_us(cv, repeats: int) -> float:
    hydro, B = cv.hydro(), allocation_matrix(cv.geometry.thruster_y_m)
    nu, tau = np.array([1.0, 0.1, 0.1]), B @ [10.0, 8.0]
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(2000):
            acceleration(hydro, 0.3, nu, tau)
        out.append((time.perf_counter() - t0) / 2000 * 1e6)
    return statistics.median(out)


def _simulate_to_csv_s(vessel: str, duration_s: float, folder: Path) -> float:
    """Wall seconds of what `twin simulate --scenario zigzag --out run.csv` does, in-process:
    twin.api.simulate (load and compile the vessel, run the scenario's controller at the
    autopilot rate) and the run written as CSV."""
    t0 = time.perf_counter()
    run = api.simulate(vessel, "zigzag", duration_s)
    outputs.write({"twin": run}, folder / "run.csv")
    return time.perf_counter() - t0


def _throughputs(model, n_twins: int, duration_s: float, nthread: int, repeats: int, vessel: str,
                 simulate_s: float) -> tuple[float, float, float]:
    """Simulated seconds per wall second of one twin, of a batch and of `twin.simulate` to CSV:
    the same n_twins runs of duration_s (their own initial states and thrusts), one after the
    other on one twin, then all at once on nthread threads, then one zig-zag of simulate_s;
    medians over repeats, the three measured in turn in each. Similar wall times measured
    side by side: a virtual machine's background load comes and goes, and a short
    single-twin timing would catch its quiet moments."""
    h = model.opt.timestep
    nstep = int(round(duration_s / h))
    rng = np.random.default_rng(0)
    states = np.array([batch.initial_state(model, nu0=(rng.uniform(0, 1.5), 0.0, 0.0)) for _ in range(n_twins)])
    thrust = rng.uniform(-10, 20, size=(n_twins, 2))
    controls = np.repeat(thrust[:, None, :], nstep, axis=1)
    full = mujoco.mjtState.mjSTATE_FULLPHYSICS
    data = mujoco.MjData(model)
    single, walls, sims = [], [], []
    folder = Path(tempfile.mkdtemp(prefix="twin-bench-"))
    for _ in range(repeats):
        with native.installed_native():
            t0 = time.perf_counter()
            for state, command in zip(states, thrust):
                mujoco.mj_setState(model, data, state, full)
                data.ctrl[:2] = command
                mujoco.mj_step(model, data, nstep=nstep)
            single.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        _, diverged = batch.rollout(model, states, controls, nthread=nthread)
        walls.append(time.perf_counter() - t0)
        if diverged:
            raise SystemExit(f"benchmark twins diverged: {diverged[:3]}")
        sims.append(_simulate_to_csv_s(vessel, simulate_s, folder))
    (folder / "run.csv").unlink()
    folder.rmdir()
    work = n_twins * duration_s
    return work / statistics.median(single), work / statistics.median(walls), simulate_s / statistics.median(sims)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vessel", default="yellowfish")
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--batch", type=int, default=256)
    ap.add_argument("--batch-duration", type=float, default=60.0)
    ap.add_argument("--simulate-duration", type=float, default=3600.0, help="zig-zag run to CSV, s")
    ap.add_argument("--sea", default="0.3,2.5,30,4", help="the 6-DOF figure's sea, HS,TP,DIR[,SPREAD]")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)

    cv = compile_vessel(vessel_mod.load(args.vessel))
    h = cv.model.opt.timestep
    model = native.with_native_params(cv)
    with native.installed_native():
        _us_per_step(model, 10, 1)  # compile the callback outside the timing
    bare_runs, native_runs = [], []
    for _ in range(args.repeats):  # in turn, for the same reason as _single_and_batch
        bare_runs.append(_us_per_step(cv.model, args.steps, 1))
        with native.installed_native():
            native_runs.append(_us_per_step(model, args.steps, 1))
    bare, native_us = statistics.median(bare_runs), statistics.median(native_runs)
    with callbacks.installed(cv.model, cv.hydro()):
        python = _us_per_step(cv.model, max(300, args.steps // 10), args.repeats)
    analytic = _analytic_us(cv, args.repeats)
    cores = os.cpu_count() or 1
    single, batch_all, simulate = _throughputs(model, args.batch, args.batch_duration, cores, args.repeats,
                                               args.vessel, args.simulate_duration)

    from twin.verify.sea import speed_pair

    pair = speed_pair(vessel_mod.load(args.vessel), args.sea, args.repeats)
    three_rate, six_rate = pair["three_dof_simsec_per_s"], pair["six_dof_simsec_per_s"]
    result = {
        "vessel": args.vessel, "integrator": mujoco.mjtIntegrator(cv.model.opt.integrator).name, "timestep_s": h,
        "cores": cores, "batch_twins": args.batch, "batch_duration_s": args.batch_duration,
        "simulate_duration_s": args.simulate_duration,
        "bare_us": bare, "python_us": python, "native_us": native_us, "analytic_us": analytic,
        "single_simsec_per_s": single, "batch_simsec_per_s": batch_all, "simulate_simsec_per_s": simulate,
        "native_over_bare": native_us / bare, "python_over_bare": python / bare,
        "batch_speedup": batch_all / single, "simulate_over_single": simulate / single,
        "six_dof_sea": args.sea, "three_dof_simsec_per_s": three_rate, "six_dof_sea_simsec_per_s": six_rate,
        "six_dof_over_three_dof": six_rate / three_rate,
    }
    rows = [
        ("bare engine (no callbacks)", f"{bare:8.2f} µs/step", f"{h / (bare * 1e-6):9.0f} sim-s/s", "1.00"),
        ("twin, Python callbacks", f"{python:8.2f} µs/step", f"{h / (python * 1e-6):9.0f} sim-s/s", f"{python / bare:.2f}"),
        ("twin, native callbacks", f"{native_us:8.2f} µs/step", f"{h / (native_us * 1e-6):9.0f} sim-s/s",
         f"{native_us / bare:.2f}"),
        ("analytic model, one RHS", f"{analytic:8.2f} µs/eval", "", ""),
        (f"one twin, the {args.batch} runs in turn", "", f"{single:9.0f} sim-s/s", ""),
        (f"batch of {args.batch} twins, {cores} threads", "", f"{batch_all:9.0f} sim-s/s",
         f"speed-up {batch_all / single:.2f} x one twin"),
        (f"simulate, {args.simulate_duration:g}-s zig-zag to CSV", "", f"{simulate:9.0f} sim-s/s",
         f"{simulate / single:.2f} x one twin"),
        ("one 3-DOF twin (paired with the next)", "", f"{three_rate:9.0f} sim-s/s", ""),
        (f"one 6-DOF twin, sea {args.sea}", "", f"{six_rate:9.0f} sim-s/s",
         f"{six_rate / three_rate:.3f} x the 3-DOF twin"),
    ]
    print(f"{args.vessel}: {result['integrator']}, dt = {h * 1e3:g} ms, {cores} cores")
    print(f"{'':34s} {'per step':>16s} {'throughput':>15s}  ratio to bare")
    for name, a, b, c in rows:
        print(f"{name:34s} {a:>16s} {b:>15s}  {c}")
    if args.json:
        vessel_mod.write_text_atomic(args.json, json.dumps(result, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
