"""The twin flown by the real autopilot: ArduPilot Rover SITL (../shared/tools/ardupilot-sitl) against
`twin sitl`, driven over MAVLink with pymavlink (twin.sitl.ardupilot).

Skipped where the binary is absent (a clone without ../shared). Each test starts its own twin (the
CLI, as a user runs it, on a free UDP port) and its own SITL (free TCP port, -I from the process id)
in a temporary folder, and ends both however it ends. SITL runs at its default 1200 Hz frames with
--speedup 100: as fast as the two processes answer each other.
"""
from __future__ import annotations

import contextlib
import math
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from twin.errors import TwinError
from twin.run import read_csv

ROOT = Path(__file__).resolve().parent.parent
SITL_DIR = ROOT.parent / "shared" / "tools" / "ardupilot-sitl"
BINARY = SITL_DIR / "ardurover"
HOME = (37.4136, -5.9786)

pytestmark = pytest.mark.skipif(not BINARY.is_file(), reason="ArduPilot SITL binary not in ../shared/tools")

SUMMARY = re.compile(r"(\d+) frames, ([\d.]+) s of twin time in ([\d.]+) s; (\d+) duplicates answered, (\d+) not "
                     r"\(crossed a late answer\), (\d+) missed, (\d+) restarts")


@contextlib.contextmanager
def twin_sitl(vessel: str, folder: Path):
    """`twin sitl` in a subprocess recording to folder/run.csv; yields (port, box); after the block
    box["summary"] holds the counters of its summary line, box["run"] the recording."""
    params = folder / "boat.parm"
    subprocess.run([sys.executable, "-m", "twin", "sitl", "--vessel", vessel, "--write-params", str(params)],
                   check=True, capture_output=True, timeout=300)
    proc = subprocess.Popen([sys.executable, "-m", "twin", "sitl", "--vessel", vessel, "--port", "0",
                             "--host", "127.0.0.1", "--record", str(folder / "run.csv")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, stdin=subprocess.DEVNULL)
    box: dict = {"params": params}
    try:
        line = proc.stderr.readline()
        found = re.search(r"on udp [\d.]+:(\d+)", line)
        assert found, f"twin sitl did not start: {line!r}"
        yield int(found.group(1)), box
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)  # as a user's kill: the session ends and writes its recording
        try:
            out, err = proc.communicate(timeout=120)
        except subprocess.TimeoutExpired:
            proc.kill()
            out, err = proc.communicate()
    box["returncode"], box["stdout"], box["stderr"] = proc.returncode, out, err
    found = SUMMARY.search(out)
    assert found, f"no summary line: {out!r} {err[-2000:]!r}"
    keys = ("frames", "twin_s", "wall_s", "duplicates", "crossed", "missed", "restarts")
    box["summary"] = {k: float(v) for k, v in zip(keys, found.groups())}
    box["run"] = read_csv(folder / "run.csv")


@contextlib.contextmanager
def ardupilot(port: int, params: Path, folder: Path, wipe: bool = True):
    """ArduPilot Rover SITL on the twin's port, with ArduPilot's Rover defaults and the twin's file;
    yields a connected Rover, and ends the process whatever happens."""
    from twin.sitl.ardupilot import Rover, start_ardurover

    ap = start_ardurover(BINARY, port, [SITL_DIR / "rover.parm", SITL_DIR / "rover-skid.parm", params],
                         folder / "ardupilot", home=(*HOME, 0.0, 0.0), wipe=wipe)
    rover = None
    try:
        rover = Rover(ap.mavlink_port)
        rover.set_param("RC_OVERRIDE_TIME", -1)  # the sticks hold until changed, however slow the wall clock
        yield rover
    except TwinError as exc:
        raise AssertionError(f"{exc}\nSITL said:\n{ap.output()[-3000:]}") from None
    finally:
        if rover is not None:
            rover.close()
        ap.stop()


def track_distance(track: np.ndarray, run) -> tuple[float, float, float]:
    """EKF positions (time_boot_s, n, e) against the twin's recorded track: the clock offset (s) that
    fits them best (ArduPilot's boot clock and the twin's start within a frame or two of each other),
    then the median and largest distance (m) there."""
    t, n, e = track[:, 0], track[:, 1], track[:, 2]

    def distances(offset_s):
        return np.hypot(np.interp(t + offset_s, run.t, run.eta[:, 0]) - n,
                        np.interp(t + offset_s, run.t, run.eta[:, 1]) - e)

    offsets = np.arange(-0.5, 0.5001, 0.005)
    best = offsets[int(np.argmin([np.median(distances(o)) for o in offsets]))]
    d = distances(best)
    return float(best), float(np.median(d)), float(d.max())


@pytest.mark.parametrize("vessel", ["yellowfish", "blueboat"])
def test_ardupilot_flies_the_twin_manual_guided_and_a_mission(vessel, tmp_path):
    started = time.monotonic()
    with twin_sitl(vessel, tmp_path) as (port, box), ardupilot(port, box["params"], tmp_path) as rover:
        rover.wait_ekf(timeout_s=120)
        rover.set_mode("MANUAL")
        rover.arm()
        armed_s = rover.boot_s
        assert rover.distance_to(0.0, 0.0) < 0.05, "the boat moved before it was armed"

        start, yaw0 = rover.position, rover.yaw_rad
        rover.drive(8.0, 1500, 1750)  # half stick ahead, no steering
        north, east = rover.position
        ahead = math.hypot(north - start[0], east - start[1])
        assert ahead > 5.0, f"half stick for 8 s drove {ahead:.1f} m"
        assert abs(math.remainder(rover.yaw_rad - yaw0, math.tau)) < math.radians(10), "it did not hold straight"

        heading1 = rover.heading_rad
        rover.drive(6.0, 1850, 1650)  # steering to starboard
        turned = rover.heading_rad - heading1
        assert turned > math.radians(45), f"a starboard turn of {math.degrees(turned):.0f}° in 6 s"

        rover.sticks(1500, 1500)
        rover.set_mode("GUIDED")
        here = rover.position
        target = (here[0] + 15.0, here[1] + 8.0)
        rover.goto(*target)
        t0 = rover.boot_s
        rover.wait(lambda: rover.distance_to(*target) < 2.0, "the GUIDED target", 120,
                   every=lambda: rover.boot_s - t0 > 60 and pytest.fail("GUIDED target not reached in 60 s"))

        rover.set_mode("HOLD")
        n0, e0 = rover.position
        rover.upload_mission(HOME, [(n0 + 12.0, e0), (n0 + 12.0, e0 + 12.0), (n0, e0)])
        rover.set_mode("AUTO")
        t0 = rover.boot_s
        rover.wait(lambda: {1, 2, 3} <= set(rover.reached), "the three waypoints", 150,
                   every=lambda: rover.boot_s - t0 > 120 and pytest.fail("mission not completed in 120 s"))
        rover.wait(lambda: any("Mission Complete" in t for t in rover.texts), "the end of the mission", 30)
        texts = list(rover.texts)
        track = np.array(rover.track)
        rover.set_mode("HOLD")
    wall_s = time.monotonic() - started

    assert not [t for t in texts if "EKF" in t and ("variance" in t or "fail" in t.lower())], texts
    s, run = box["summary"], box["run"]
    assert box["returncode"] == 0 and "SIGTERM: ending the session" in box["stderr"]
    assert s["missed"] == 0 and s["duplicates"] == 0 and s["crossed"] == 0 and s["restarts"] == 0, s
    assert len(run.t) == s["frames"] + 1 and np.allclose(np.diff(run.t), 1 / 1200, rtol=0, atol=2e-6)
    before = run.t < armed_s - 0.5
    assert before.sum() > 1200 * 30 and np.all(run.eta[before, :2] == 0.0), "a disarmed autopilot moved the boat"
    offset_s, median_m, worst_m = track_distance(track[track[:, 0] > armed_s], run)
    print(f"{vessel}: {s['frames']:.0f} frames, {s['twin_s']:.1f} s of twin time in {wall_s:.1f} s; "
          f"EKF vs twin: clock offset {offset_s * 1e3:.0f} ms, median {median_m:.3f} m, max {worst_m:.3f} m")
    assert abs(offset_s) < 0.2 and worst_m < 0.5, (offset_s, median_m, worst_m)


def test_an_ardupilot_restart_under_a_running_twin_resets_it(tmp_path):
    with twin_sitl("yellowfish", tmp_path) as (port, box):
        with ardupilot(port, box["params"], tmp_path) as rover:
            rover.wait_sim(5.0)
        with ardupilot(port, box["params"], tmp_path, wipe=False) as rover:
            rover.wait_sim(5.0)
    s, run = box["summary"], box["run"]
    assert s["restarts"] == 1 and s["missed"] == 0, s
    assert len(run.t) == s["frames"] + 1 and np.all(np.diff(run.t) > 0)  # the record clock runs on
    assert run.t[-1] == pytest.approx(s["twin_s"], abs=1e-3) and s["twin_s"] > 10.0
    assert np.all(run.eta[:, :2] == 0.0)  # disarmed throughout, the start-up pulses included: never moved
