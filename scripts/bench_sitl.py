"""How many ArduPilot frames a second `twin sitl` answers in lock-step, on one core, full physics.

    python scripts/bench_sitl.py [--frames 20000] [--rate 400] [--repeats 3] [--json out.json] [--profile]

The backend runs in this process (run_sitl, yellowfish, current 0.3 m/s and wind 6 m/s on);
ArduPilot's side is a separate process (this script with --client) that sends a frame as soon
as the previous one is answered, as SITL does at unlimited speed-up, and times every frame
from its send to its reply. Two twins: the yellowfish as shipped (no thruster lag or delay),
and the same with lag, transport delay, decay and advance-speed loss (the thrust command is
then recomputed at every physics step). Reported per twin, median over the repeats: frames/s,
times real time (frames/s ÷ frame rate), and the median and 99th-percentile latency per frame
(µs). Target: ≥ 20× real time at 400 Hz frames, i.e. ≥ 8000 frames/s.

--profile runs one extra session under cProfile and prints where the backend's time goes.
"""
from __future__ import annotations

import argparse
import cProfile
import json
import math
import os
import platform
import pstats
import socket
import struct
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from twin.sitl.backend import with_environment
from twin.sitl.server import run_sitl
from twin.vessel import load

TARGET_X_REAL_TIME = 20.0


def client(port: int, frames: int, rate: int) -> None:
    """ArduPilot's side: servo packets (magic 18458, 16 outputs) sent one per answer; prints JSON."""
    packets = []
    for k in range(frames):
        pwm = [0] * 16
        pwm[0] = int(1500 + 350 * math.sin(2 * math.pi * k / 4000))  # throttle left, servo 1
        pwm[2] = int(1500 + 350 * math.cos(2 * math.pi * k / 2600))  # throttle right, servo 3
        packets.append(struct.pack("<HHI16H", 18458, rate, k, *pwm))
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.settimeout(10.0)
    address = ("127.0.0.1", port)
    latency_ns = [0] * frames
    clock = time.perf_counter_ns
    start = clock()
    for k, packet in enumerate(packets):
        sent = clock()
        sock.sendto(packet, address)
        reply = sock.recv(4096)
        latency_ns[k] = clock() - sent
    wall_s = (clock() - start) * 1e-9
    last = json.loads(reply)
    lat_us = np.array(latency_ns) * 1e-3
    print(json.dumps({"frames": frames, "wall_s": wall_s, "latency_median_us": float(np.median(lat_us)),
                      "latency_p99_us": float(np.percentile(lat_us, 99)), "latency_max_us": float(lat_us.max()),
                      "last_timestamp_s": last["timestamp"]}))


def session(vessel, frames: int, rate: int, profile: bool = False) -> dict:
    """One lock-step session against a client process; the client's figures."""
    box = {}

    def start_client(address):
        box["proc"] = subprocess.Popen(
            [sys.executable, __file__, "--client", str(address[1]), "--frames", str(frames), "--rate", str(rate)],
            stdout=subprocess.PIPE, text=True)

    profiler = cProfile.Profile() if profile else None
    if profiler:
        profiler.enable()
    summary = run_sitl(vessel, port=0, host="127.0.0.1", stop_after_frames=frames, ready=start_client,
                       current=(0.3, 40.0), wind=(6.0, 100.0))
    if profiler:
        profiler.disable()
        pstats.Stats(profiler).sort_stats("tottime").print_stats(18)
    out, _ = box["proc"].communicate(timeout=60)
    result = json.loads(out)
    assert summary.counters.frames == frames and result["last_timestamp_s"] == frames / rate
    result["frames_per_s"] = frames / result["wall_s"]
    result["x_real_time"] = result["frames_per_s"] / rate
    return result


def bench(name: str, vessel, args) -> dict:
    runs = [session(vessel, args.frames, args.rate) for _ in range(args.repeats)]
    keys = ("frames_per_s", "x_real_time", "latency_median_us", "latency_p99_us", "latency_max_us")
    median = {k: float(np.median([r[k] for r in runs])) for k in keys}
    print(f"{name:34s} {median['frames_per_s']:8.0f} frames/s  {median['x_real_time']:5.1f}× real time  "
          f"latency median {median['latency_median_us']:5.0f} µs, p99 {median['latency_p99_us']:5.0f} µs "
          f"(runs: {', '.join(format(r['frames_per_s'], '.0f') for r in runs)} frames/s)", flush=True)
    return {"median": median, "runs": runs}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=20000)
    parser.add_argument("--rate", type=int, default=400, help="frame rate ArduPilot asks for, Hz")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", type=Path, default=None, help="write the figures here")
    parser.add_argument("--profile", action="store_true")
    parser.add_argument("--client", type=int, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.client is not None:
        client(args.client, args.frames, args.rate)
        return
    shipped = load("yellowfish")
    effects = replace(shipped, thrusters=replace(shipped.thrusters, lag_s=0.15, delay_s=0.05, decay_per_min=0.05,
                                                 advance_loss=0.8))
    print(f"{args.frames} frames at {args.rate} Hz, lock-step, current 0.3 m/s and wind 6 m/s, "
          f"median of {args.repeats}; target ≥ {TARGET_X_REAL_TIME:g}× real time", flush=True)
    results = {
        "yellowfish": bench("yellowfish", shipped, args),
        "yellowfish + thruster effects": bench("yellowfish + lag/delay/decay/loss", effects, args),
    }
    if args.profile:
        session(with_environment(effects, None, None), args.frames, args.rate, profile=True)
    report = {"frames": args.frames, "rate_hz": args.rate, "repeats": args.repeats,
              "target_x_real_time": TARGET_X_REAL_TIME, "results": results,
              "machine": {"python": platform.python_version(), "cpus": os.cpu_count(),
                          "platform": platform.platform()}}
    if args.json:
        args.json.write_text(json.dumps(report, indent=2) + "\n")
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
