#!/usr/bin/env python3
"""Speed of a Monte Carlo beyond one twin: simulated seconds per wall second of the same
10,000-draw Monte Carlo (an identified yellowfish's covariance through the first seconds of a
zig-zag) run (i) on one core (the batch engine on one thread, 1,000 of the draws: the rate does
not depend on how many), (ii) by the local batch engine on every core, (iii) on Ray on this
machine's cores (a private instance, workers warmed up first). The three are timed in turn in
each repeat and the medians kept (the machine's other load comes and goes). Also: Ray's cost
per task (no-op tasks), the bytes a batch sends back and what every batch shares, the cold
start of a Ray run (workers importing twin and compiling the native callback), and a check that
(ii) and (iii) give the same band bit for bit.

    python scripts/bench_scale.py [--model id.json] [--draws 10000] [--mission-s 10] [--json out/NAME.json]

Without --model, the vessel is the yellowfish with a hand-written uncertainty block: the speed
does not depend on the numbers in it.
"""
from __future__ import annotations

import argparse
import json
import logging
import os
import pickle
import statistics
import sys
import time
from pathlib import Path

import numpy as np

import twin.vessel as vessel_mod
from twin.scale import batches, montecarlo as mc

def _vessel(model: str | None):
    """The vessel file given, or the yellowfish with a hand-made block: ln|Xu|, ln|Nr|, ln(gain) with
    σ 0.2, 0.2, 0.05 (the speed does not depend on the numbers)."""
    if model:
        return vessel_mod.load(model)
    from dataclasses import replace

    v = vessel_mod.load("yellowfish")
    values = {"Xu": v.damping.Xu, "Nr": v.damping.Nr, "thrust_gain": v.thrusters.gain_left}
    block = {"coordinates": [{"name": k, "log": True, "sign": float(np.sign(x))} for k, x in values.items()],
             "mean": [float(np.log(abs(x))) for x in values.values()],
             "covariance": np.diag([0.2 ** 2, 0.2 ** 2, 0.05 ** 2]).tolist()}
    return replace(v, uncertainty=block)


def _timed(vessel, mission, draws: int, batch_size: int, executor) -> tuple[float, mc.MonteCarlo]:
    t0 = time.perf_counter()
    result = mc.run(vessel, mission, draws, seed=1, batch_size=batch_size, executor=executor)
    return time.perf_counter() - t0, result


def _noop(payload, b, extra=None):
    return None


def _task_overhead_s(ray_executor, n_tasks: int, cpus: int) -> float:
    """CPU seconds Ray spends per task beyond the work: no-op tasks, wall × CPUs / tasks."""
    plan = batches.plan(n_tasks, 1, 0)
    t0 = time.perf_counter()
    batches.gather(ray_executor, _noop, None, plan)
    return (time.perf_counter() - t0) * cpus / n_tasks


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", help="identified vessel file (default: yellowfish with a hand-written block)")
    ap.add_argument("--draws", type=int, default=10000)
    ap.add_argument("--one-core-draws", type=int, default=1000)
    ap.add_argument("--mission-s", type=float, default=10.0)
    ap.add_argument("--batch-size", type=int, default=64)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--cpus", type=int, default=os.cpu_count() or 1, help="CPUs of the local Ray instance")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)

    import ray

    vessel = _vessel(args.model)
    mission = mc.scenario_mission(vessel, "zigzag", args.mission_s, 0.5)
    one_core, local = batches.LocalExecutor(nthread=1), batches.LocalExecutor()
    t0 = time.perf_counter()
    ray.init(num_cpus=args.cpus, include_dashboard=False, log_to_driver=False, logging_level=logging.WARNING)
    init_s = time.perf_counter() - t0
    on_ray = batches.RayExecutor("auto")
    cold_s, _ = _timed(vessel, mission, args.batch_size * args.cpus, args.batch_size, on_ray)
    _timed(vessel, mission, args.batch_size, args.batch_size, local)  # this process's native callback compiled
    walls = {"one_core": [], "local": [], "ray": []}
    same = True
    for _ in range(args.repeats):
        walls["one_core"].append(_timed(vessel, mission, args.one_core_draws, args.batch_size, one_core)[0])
        w_local, r_local = _timed(vessel, mission, args.draws, args.batch_size, local)
        w_ray, r_ray = _timed(vessel, mission, args.draws, args.batch_size, on_ray)
        walls["local"].append(w_local)
        walls["ray"].append(w_ray)
        same &= all(np.array_equal(r_local.band.values[q], r_ray.band.values[q]) for q in mc.QUANTITIES)
    overhead_s = _task_overhead_s(on_ray, 400, args.cpus)
    ray.shutdown()

    job = mc._Job(vessel, mission, mc.Variation(covariance=True))
    b = batches.plan(args.batch_size, args.batch_size, 1)[0]
    result_bytes = len(pickle.dumps(mc.run_batch(job, b)))
    payload_bytes = len(pickle.dumps(job))
    args_bytes = len(pickle.dumps(b))
    work = {"one_core": args.one_core_draws * args.mission_s, "local": args.draws * args.mission_s,
            "ray": args.draws * args.mission_s}
    rate = {k: work[k] / statistics.median(v) for k, v in walls.items()}
    batch_s = args.batch_size * args.mission_s / rate["one_core"]
    out = {
        "machine_cpus": os.cpu_count(), "ray_cpus": args.cpus, "ray_version": ray.__version__,
        "draws": args.draws, "one_core_draws": args.one_core_draws, "mission_s": args.mission_s,
        "batch_size": args.batch_size, "repeats": args.repeats,
        "simsec_per_s": {k: round(v, 1) for k, v in rate.items()},
        "ray_over_local": round(rate["ray"] / rate["local"], 3),
        "local_over_one_core": round(rate["local"] / rate["one_core"], 3),
        "wall_s": {k: [round(x, 2) for x in v] for k, v in walls.items()},
        "batch_cost_s_one_core": round(batch_s, 3),
        "ray_task_overhead_ms": round(1e3 * overhead_s, 2),
        "ray_overhead_share_of_batch": round(overhead_s / batch_s, 4),
        "batch_result_bytes": result_bytes, "batch_args_bytes": args_bytes, "shared_payload_bytes": payload_bytes,
        "ray_init_s": round(init_s, 2), "ray_cold_run_s": round(cold_s, 2),
        "ray_cold_run_draws": args.batch_size * args.cpus, "ray_equals_local": bool(same),
    }
    print(f"{'':28s}{'sim-s/s':>10s}{'wall s (median)':>18s}")
    for k, label in (("one_core", f"(i) one core, {args.one_core_draws} draws"),
                     ("local", f"(ii) local, {args.draws} draws"), ("ray", f"(iii) Ray {args.cpus} CPUs")):
        print(f"{label:28s}{rate[k]:10.0f}{statistics.median(walls[k]):18.2f}")
    print(f"Ray / local {out['ray_over_local']:.3f}; local / one core {out['local_over_one_core']:.2f}; "
          f"same band: {same}")
    print(f"one batch of {args.batch_size} × {args.mission_s:g} s on one core: {batch_s:.2f} s; Ray per task "
          f"{out['ray_task_overhead_ms']:.1f} ms ({100 * out['ray_overhead_share_of_batch']:.2f} % of a batch)")
    print(f"bytes per batch: {result_bytes} back, {args_bytes} out; shared once: {payload_bytes}; "
          f"Ray start {init_s:.1f} s, cold run of {out['ray_cold_run_draws']} draws {cold_s:.1f} s")
    if args.json:
        args.json.write_text(json.dumps(out, indent=2) + "\n")
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
