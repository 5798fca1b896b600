"""How many ArduPilot frames a second `twin sitl` answers in lock-step, full physics, at Rover SITL's
default 1200 Hz frames; writes docs/results/bench_sitl.md and docs/results/data/bench_sitl.json.

    python scripts/bench_sitl.py [--frames 24000] [--rate 1200] [--repeats 3] [--no-page] [--profile]

The twin runs in this process (run_sitl, yellowfish, current 0.3 m/s and wind 6 m/s, so that it
never rests); ArduPilot's side is a separate process (this script with --client) that sends a frame
as soon as the previous one is answered, as SITL does at unlimited speed-up, and times every frame
from its send to its reply. Two twins: the yellowfish as shipped (no thruster lag or delay), and
the same with lag, transport delay, decay and advance-speed loss (the thrust command is then
recomputed at every physics step). Their sessions alternate (A, B, A, B, ...) so that both meet the
same load on a shared machine.

Two figures per session: the round trip (frames/s and times real time as the client sees them:
the twin, the client and two UDP hops in turn), and the twin's own CPU time per frame (its serving
thread's, UDP system calls included), whose inverse is what one core running the twin alone can
answer; beside them, the same client against a bare UDP echo, the floor the machine's sockets set. Target: the twin at ≥ 20× real time at 1200 Hz frames on one core, i.e. ≤ 41.7 µs a frame.
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

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from twin.files import write_text_atomic  # noqa: E402
from twin.sitl.backend import with_environment  # noqa: E402
from twin.sitl.server import run_sitl  # noqa: E402
from twin.vessel import load  # noqa: E402
from twin.viz.pages import ResultPage, ResultTable, checkout_commit  # noqa: E402

TARGET_X_REAL_TIME = 20.0
NAME = "bench_sitl"


def client(port: int, frames: int, rate: int) -> None:
    """ArduPilot's side: servo packets (magic 18458, 16 outputs) sent one per answer; prints JSON."""
    packets = []
    for k in range(frames):
        pwm = [0] * 16
        pwm[0] = int(1500 + 350 * math.sin(2 * math.pi * k / (10 * rate)))  # throttle left, servo 1
        pwm[2] = int(1500 + 350 * math.cos(2 * math.pi * k / (6.5 * rate)))  # throttle right, servo 3
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
    """One lock-step session against a client process: the client's figures and the twin's CPU."""
    box = {}

    def start_client(address):
        box["proc"] = subprocess.Popen(
            [sys.executable, __file__, "--client", str(address[1]), "--frames", str(frames), "--rate", str(rate)],
            stdout=subprocess.PIPE, text=True)

    profiler = cProfile.Profile() if profile else None
    if profiler:
        profiler.enable()
    load_before = os.getloadavg()[0]
    summary = run_sitl(vessel, port=0, host="127.0.0.1", stop_after_frames=frames, ready=start_client,
                       current=(0.3, 40.0), wind=(6.0, 100.0), esc_arm_s=0.0)
    if profiler:
        profiler.disable()
        pstats.Stats(profiler).sort_stats("tottime").print_stats(18)
    out, _ = box["proc"].communicate(timeout=120)
    result = json.loads(out)
    assert summary.counters.frames == frames and math.isclose(result["last_timestamp_s"], frames / rate)
    result["frames_per_s"] = frames / result["wall_s"]
    result["x_real_time"] = result["frames_per_s"] / rate
    result["twin_cpu_us_per_frame"] = summary.serve_cpu_s / frames * 1e6
    result["twin_x_real_time_one_core"] = (1.0 / rate) / (summary.serve_cpu_s / frames)
    result["load_average_1min"] = [load_before, os.getloadavg()[0]]
    return result


def echo_session(frames: int, rate: int) -> dict:
    """The platform's floor: the same client against a bare UDP echo in this process (one blocking
    receive and one send of a reply of the twin's size a frame, nothing computed), its thread's CPU
    per frame; on a virtual machine the wake-up from each blocking receive costs more than the work."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    proc = subprocess.Popen([sys.executable, __file__, "--client", str(sock.getsockname()[1]), "--frames", str(frames),
                             "--rate", str(rate)], stdout=subprocess.PIPE, text=True)
    buffer = bytearray(4096)
    replies = [json.dumps({"timestamp": (k + 1) / rate, "pad": "x" * 240}).encode() for k in range(frames)]
    load_before = os.getloadavg()[0]
    cpu0 = time.thread_time()
    for reply in replies:
        _, peer = sock.recvfrom_into(buffer)
        sock.sendto(reply, peer)
    cpu_s = time.thread_time() - cpu0
    sock.close()
    out, _ = proc.communicate(timeout=120)
    result = json.loads(out)
    result["frames_per_s"] = frames / result["wall_s"]
    result["x_real_time"] = result["frames_per_s"] / rate
    result["twin_cpu_us_per_frame"] = cpu_s / frames * 1e6
    result["twin_x_real_time_one_core"] = (1.0 / rate) / (cpu_s / frames)
    result["compute_us_per_frame"] = 0.0
    result["load_average_1min"] = [load_before, os.getloadavg()[0]]
    return result


ECHO = "bare UDP echo (the platform's floor)"
KEYS = ("frames_per_s", "x_real_time", "twin_cpu_us_per_frame", "twin_x_real_time_one_core", "latency_median_us",
        "latency_p99_us", "compute_us_per_frame")


def compute_only(vessel, frames: int, rate: int) -> float:
    """CPU µs per frame of the same frames without the socket: what the server's loop does with a
    packet (unpack the two thrusters' outputs, step, format), in this thread."""
    from twin.sitl.backend import SitlTwin
    from twin.sitl.protocol import format_reply, pack_servo_packet, pair_reader

    twin = SitlTwin(with_environment(vessel, (0.3, 40.0), (6.0, 100.0)), record=False, esc_arm_s=0.0)
    packets = [bytearray(pack_servo_packet(rate, k, [int(1500 + 350 * math.sin(2 * math.pi * k / (10 * rate))), 0,
                                                     int(1500 + 350 * math.cos(2 * math.pi * k / (6.5 * rate)))]
                                           + [0] * 13))
               for k in range(frames)]
    unpack = pair_reader(*twin.channels)[0].unpack_from
    step = twin.step_pair
    with twin.active():
        twin.warm_up()
        start = time.thread_time()
        for packet in packets:
            _, frame_rate, _, a, b = unpack(packet)
            format_reply(step(a, b, frame_rate))
        return (time.thread_time() - start) / frames * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=24000)
    parser.add_argument("--rate", type=int, default=1200, help="frame rate ArduPilot asks for, Hz (SIM_RATE_HZ)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-page", action="store_true", help="print only; do not write the results page")
    parser.add_argument("--profile", action="store_true", help="one more session under cProfile")
    parser.add_argument("--client", type=int, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.client is not None:
        client(args.client, args.frames, args.rate)
        return
    shipped = load("yellowfish")
    effects = replace(shipped, thrusters=replace(shipped.thrusters, lag_s=0.15, delay_s=0.05, decay_per_min=0.05,
                                                 advance_loss=0.8))
    twins = {"yellowfish": shipped, "yellowfish + lag, delay, decay, advance loss": effects}
    print(f"{args.frames} frames at {args.rate} Hz, lock-step, current 0.3 m/s and wind 6 m/s; the two twins in "
          f"turn, {args.repeats} sessions each; target: the twin ≥ {TARGET_X_REAL_TIME:g}× real time on one core",
          flush=True)
    runs = {name: [] for name in (*twins, ECHO)}
    for _ in range(args.repeats):
        echo = echo_session(args.frames, args.rate)
        runs[ECHO].append(echo)
        print(f"{ECHO:46s} round trip {echo['frames_per_s']:6.0f} frames/s; {echo['twin_cpu_us_per_frame']:5.1f} µs "
              f"CPU a frame; load {echo['load_average_1min'][0]:.1f}", flush=True)
        for name, vessel in twins.items():
            r = session(vessel, args.frames, args.rate)
            r["compute_us_per_frame"] = compute_only(vessel, args.frames, args.rate)
            runs[name].append(r)
            print(f"{name:46s} round trip {r['frames_per_s']:6.0f} frames/s ({r['x_real_time']:4.1f}×); twin "
                  f"{r['twin_cpu_us_per_frame']:5.1f} µs CPU a frame ({r['twin_x_real_time_one_core']:4.1f}× on one "
                  f"core), of which {r['compute_us_per_frame']:.1f} µs without the socket; "
                  f"load {r['load_average_1min'][0]:.1f}", flush=True)
    if args.profile:
        session(with_environment(effects, None, None), args.frames, args.rate, profile=True)
    medians = {name: {k: float(np.median([r[k] for r in rs])) for k in KEYS} for name, rs in runs.items()}
    raw = {"frames": args.frames, "rate_hz": args.rate, "repeats": args.repeats,
           "target_x_real_time": TARGET_X_REAL_TIME, "median": medians, "runs": runs,
           "machine": {"python": platform.python_version(), "cpus": os.cpu_count(), "platform": platform.platform()}}
    for name, m in medians.items():
        print(f"median {name}: twin {m['twin_cpu_us_per_frame']:.1f} µs a frame = {m['twin_x_real_time_one_core']:.1f}× "
              f"real time on one core; round trip {m['frames_per_s']:.0f} frames/s = {m['x_real_time']:.1f}×")
    if args.no_page:
        return
    loads = [x for rs in runs.values() for r in rs for x in r["load_average_1min"]]
    rows = [[name, m["twin_cpu_us_per_frame"], m["twin_x_real_time_one_core"], m["frames_per_s"], m["x_real_time"],
             m["latency_median_us"], m["latency_p99_us"], m["compute_us_per_frame"]] for name, m in medians.items()]
    per_run = [[name, i + 1, r["twin_cpu_us_per_frame"], r["twin_x_real_time_one_core"], r["frames_per_s"],
                r["x_real_time"], r["load_average_1min"][0]] for name, rs in runs.items() for i, r in enumerate(rs)]
    best = min(m["twin_x_real_time_one_core"] for name, m in medians.items() if name != ECHO)
    floor = medians[ECHO]["twin_cpu_us_per_frame"]
    slowest = max(m["twin_cpu_us_per_frame"] for name, m in medians.items() if name != ECHO)
    page = ResultPage(
        name=NAME, title="Benchmark: `twin sitl` at 1200 Hz frames",
        ran=f"python scripts/bench_sitl.py --frames {args.frames} --rate {args.rate} --repeats {args.repeats}",
        data=f"the Yellowfish twin, current 0.3 m/s and wind 6 m/s, {args.frames} frames of sinusoidal PWM at "
             f"{args.rate} Hz (Rover SITL's default SIM_RATE_HZ) from a client process that answers at once",
        summary=(f"Is the twin fast enough to be ArduPilot's physics at 1200 Hz frames, at ≥ {TARGET_X_REAL_TIME:g}× "
                 f"real time on one core? Median over {args.repeats} sessions per twin, the two twins in turn, the "
                 f"twin's own CPU time per frame (its serving thread, UDP system calls included) gives "
                 f"{best:.1f}× real time on one core for the slower twin: "
                 + ("the target is met." if best >= TARGET_X_REAL_TIME else
                    f"short of the {TARGET_X_REAL_TIME:g}× target in these runs.")
                 + f" The machine was shared: 1-min load average {min(loads):.1f}-{max(loads):.1f} on "
                 f"{os.cpu_count()} cores during the runs, and CPU time per frame grows with the other load. The "
                 f"round trip, where the twin, the client and two UDP hops take turns, is slower still. On the "
                 f"same machine in the same runs a bare UDP echo, which computes nothing, costs {floor:.1f} µs of CPU "
                 f"a frame ({(1.0 / args.rate) / (floor * 1e-6):.1f}× real time at most on one core): the twin's "
                 f"frame costs {slowest - floor:.1f} µs more than that floor."),
        tables=[ResultTable("Medians", ["twin", "twin CPU per frame (µs)", "× real time, one core",
                                        "round trip (frames/s)", "round trip (× real time)",
                                        "latency median (µs)", "latency p99 (µs)", "without the socket (µs)"], rows),
                ResultTable("Sessions, in the order run", ["twin", "session", "twin CPU per frame (µs)",
                                                          "× real time, one core", "round trip (frames/s)",
                                                          "round trip (× real time)", "load average (1 min)"],
                            per_run)],
        notes=["*Without the socket*: the same frames unpacked, stepped and formatted in one thread, measured "
               "right after each session; the difference to the twin's CPU per frame is the two UDP system calls "
               "and the loop around them. The time goes mostly to `mj_step` (RK4, four evaluations of the native "
               "hydrodynamic callback per step) and to formatting the reply's twelve numbers.",
               "The effects twin recomputes the thrust command (delay, decay, lag) at every physics step."],
        raw_file=f"data/{NAME}.json")
    date, commit = time.strftime("%Y-%m-%d"), checkout_commit(ROOT)
    results = ROOT / "docs" / "results"
    meta = {"title": page.title, "ran": page.ran, "data": page.data, "date": date, "commit": commit}
    write_text_atomic(results / "data" / f"{NAME}.json",
                      json.dumps({"meta": meta, **raw}, indent=1) + "\n")
    print(f"wrote {page.write(results)}")


if __name__ == "__main__":
    main()
