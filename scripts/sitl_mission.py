"""Fly a waypoint mission with ArduPilot Rover SITL against `twin sitl`, and say how it went.

    python scripts/sitl_mission.py --home 63.4389,10.3985 --waypoints "25,0 25,25 0,25 0,0" \
        [--port 5760] [--set ATC_STR_RAT_FF=0.5 ...] [--json mission.json]

Connects to SITL's MAVLink console (tcp:127.0.0.1:PORT, SITL's SERIAL0), waits until its EKF
navigates on GPS, sets the parameters given with --set, uploads the waypoints (north,east metres
from --home, which must be SITL's --home), arms, flies them in AUTO, then holds and disarms.
Prints the mission's time on ArduPilot's clock, how far the boat strayed from the straight legs
(twin.sitl.ardupilot.path_deviation_m on the EKF's positions) and its mean speed; --json writes
the figures and the EKF track. Run it again with other --set values against the same SITL to
compare tunes: each run starts where the last one ended.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from twin.errors import TwinError
from twin.files import write_text_atomic
from twin.sitl.ardupilot import Rover, path_deviation_m


def fail(message: str) -> None:
    """Bad input or a mission that cannot be flown: one line, exit status 2."""
    print(f"error: {message}", file=sys.stderr)
    sys.exit(2)


def pairs(text: str, what: str) -> list[tuple[float, float]]:
    try:
        out = [tuple(float(x) for x in p.split(",")) for p in text.split()]
    except ValueError:
        out = []
    if not out or any(len(p) != 2 for p in out):
        fail(f"{what} expects NORTH,EAST pairs separated by spaces, got {text!r}")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--port", type=int, default=5760, help="SITL's MAVLink TCP port (SERIAL0)")
    parser.add_argument("--home", required=True, help="LAT,LON of SITL's --home (deg)")
    parser.add_argument("--waypoints", required=True, help='"N,E N,E ...": metres north and east of home')
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                        help="an ArduPilot parameter to set before the mission (repeatable)")
    parser.add_argument("--timeout", type=float, default=600.0, help="wall-clock seconds to give up after")
    parser.add_argument("--json", type=Path, default=None, help="write the figures and the EKF track here")
    args = parser.parse_args()
    try:
        lat, lon = (float(x) for x in args.home.split(","))
    except ValueError:
        fail(f"--home expects LAT,LON in degrees, got {args.home!r}")
    waypoints = pairs(args.waypoints, "--waypoints")
    settings = {}
    for item in args.set:
        name, _, value = item.partition("=")
        try:
            settings[name.strip().upper()] = float(value)
        except ValueError:
            fail(f"--set expects NAME=VALUE with a number, got {item!r}")
    try:
        rover = Rover(args.port)
        rover.wait_ekf(timeout_s=args.timeout)
        for name, value in settings.items():
            rover.set_param(name, value)
        rover.set_mode("HOLD")
        start = rover.position
        rover.upload_mission((lat, lon), waypoints)
        rover.arm(timeout_s=args.timeout)
        rover.set_mode("AUTO")
        t0, first = rover.boot_s, len(rover.track)
        rover.wait(lambda: set(range(1, len(waypoints) + 1)) <= set(rover.reached), "the mission", args.timeout)
        t1 = rover.boot_s
        rover.set_mode("HOLD")
        rover.disarm()
        rover.close()
    except TwinError as exc:
        fail(f"{exc}")
    track = np.array(rover.track[first:])
    path = [start] + waypoints
    off = path_deviation_m(track[:, 1:], path)
    length = sum(math.dist(a, b) for a, b in zip(path[:-1], path[1:]))
    figures = {"waypoints": len(waypoints), "mission_s": t1 - t0, "path_m": length,
               "mean_speed_m_s": length / (t1 - t0), "deviation_max_m": float(off.max()),
               "deviation_mean_m": float(off.mean()), "set": settings}
    print(f"mission: {len(waypoints)} waypoints, {length:.0f} m in {t1 - t0:.1f} s (ArduPilot's clock), "
          f"mean speed {figures['mean_speed_m_s']:.2f} m/s; off the straight legs: largest "
          f"{figures['deviation_max_m']:.2f} m, mean {figures['deviation_mean_m']:.2f} m")
    if args.json:
        figures["track"] = {"t_s": track[:, 0].tolist(), "north_m": track[:, 1].tolist(),
                            "east_m": track[:, 2].tolist()}
        write_text_atomic(args.json, json.dumps(figures, indent=1) + "\n")
        print(f"wrote {args.json}")


if __name__ == "__main__":
    sys.exit(main())
