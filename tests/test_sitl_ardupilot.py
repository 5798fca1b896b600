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
import os
import re
import signal
import socket
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from twin.errors import TwinError
from twin.run import read_csv
from twin.sitl.ardupilot import MODES
import twin_command

ROOT = Path(__file__).resolve().parent.parent
SITL_DIR = ROOT.parent / "shared" / "tools" / "ardupilot-sitl"
BINARY = SITL_DIR / "ardurover"
HOME = (37.4136, -5.9786)

pytestmark = pytest.mark.skipif(not (BINARY.is_file() and os.access(BINARY, os.X_OK)),
                                reason="no executable ArduPilot SITL binary in ../shared/tools/ardupilot-sitl")

SUMMARY = re.compile(r"(\d+) frames, ([\d.]+) s of twin time in ([\d.]+) s; (\d+) duplicates answered, (\d+) not "
                     r"\(crossed a late answer\), (\d+) missed, (\d+) restarts")


@contextlib.contextmanager
def twin_sitl(vessel: str, folder: Path):
    """`twin sitl` in a subprocess recording to folder/run.csv; yields (port, box); after the block
    box["summary"] holds the counters of its summary line, box["run"] the recording."""
    from twin.sitl.params import boat_parameters
    from twin.vessel import load

    params = folder / "boat.parm"
    params.write_text(boat_parameters(load(vessel)))  # what `twin sitl --write-params` writes
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


def test_ardupilot_flies_the_twin_manual_guided_and_a_mission(tmp_path):
    """The Yellowfish flown in MANUAL, GUIDED and AUTO, then ArduPilot restarted under the running
    twin: the twin resets to the origin at rest, and the new ArduPilot flies on from its own boot.
    (The BlueBoat is flown by test_the_autopilot_guide_runs_as_written, from a twin identified from a log.)"""
    started = time.monotonic()
    vessel = "yellowfish"
    with twin_sitl(vessel, tmp_path) as (port, box):
        with ardupilot(port, box["params"], tmp_path) as rover:
            rover.wait_ekf(timeout_s=120)
            # a mission's --set: ArduPilot's own list is the table of names (it ignores an unknown one)
            rover.check_params(["ATC_STR_RAT_FF", "WP_SPEED"])
            with pytest.raises(TwinError, match=r"no parameter WP_SPD \(did you mean WP_SPEED\?\): nothing was set"):
                rover.check_params(["WP_SPEED", "WP_SPD"])
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
            here, heading = rover.position, rover.yaw_rad
            target = (here[0] + 15.0 * math.cos(heading), here[1] + 15.0 * math.sin(heading))  # 15 m ahead
            rover.goto(*target)
            t0 = rover.boot_s
            rover.wait(lambda: rover.distance_to(*target) < 2.0, "the GUIDED target", 120,
                       every=lambda: rover.boot_s - t0 > 60 and pytest.fail("GUIDED target not reached in 60 s"))
            phases = {"ekf+arm": armed_s, "guided": rover.boot_s - t0}

            rover.set_mode("HOLD")
            n0, e0 = rover.position
            c, s = math.cos(rover.yaw_rad), math.sin(rover.yaw_rad)
            legs = [(10.0, 2.0), (20.0, -1.0), (30.0, 1.0)]  # ahead, left and right of the line: a survey zigzag
            rover.upload_mission(HOME, [(n0 + a * c - b * s, e0 + a * s + b * c) for a, b in legs])
            rover.set_mode("AUTO")
            t0 = rover.boot_s
            rover.wait(lambda: {1, 2, 3} <= set(rover.reached), "the three waypoints", 150,
                       every=lambda: rover.boot_s - t0 > 120 and pytest.fail("mission not completed in 120 s"))
            rover.wait(lambda: any("Mission Complete" in t for t in rover.texts), "the end of the mission", 30)
            phases["auto"] = rover.boot_s - t0
            texts = list(rover.texts)
            track = np.array(rover.track)
            # a mission's --home is checked against SITL's own before anything is uploaded
            rover.check_home(HOME)
            with pytest.raises(TwinError, match="111.[0-9] km from SITL's home"):
                rover.check_home((HOME[0] + 1.0, HOME[1]))
            rover.stop()  # what a failed mission leaves: held and disarmed
            assert not rover.armed and rover.mode == MODES["HOLD"]
        with ardupilot(port, box["params"], tmp_path, wipe=False) as again:
            again.wait_sim(3.0)
    wall_s = time.monotonic() - started

    assert not [t for t in texts if "EKF" in t and ("variance" in t or "fail" in t.lower())], texts
    s, run = box["summary"], box["run"]
    assert box["returncode"] == 0 and "SIGTERM: ending the session" in box["stderr"]
    assert s["missed"] == 0 and s["duplicates"] == 0 and s["crossed"] == 0 and s["restarts"] == 1, s
    assert len(run.t) == s["frames"] + 1 and run.t[-1] == pytest.approx(s["twin_s"], abs=0.01)
    # one clock across ArduPilot's restart: the record runs on frame after frame
    assert np.allclose(np.diff(run.t), 1 / 1200, rtol=0, atol=2e-6)
    # the twin back at the origin, at rest, from the new ArduPilot's first frame on (disarmed)
    moved = np.flatnonzero(np.any(run.eta != 0.0, axis=1))
    at = int(moved[-1]) + 1
    assert np.hypot(*run.eta[at - 1, :2]) > 10.0 and run.t[-1] - run.t[at] > 2.0
    assert np.all(run.eta[at:] == 0.0) and np.all(run.nu[at:] == 0.0)
    before = run.t < armed_s - 0.5
    assert before.sum() > 1200 * 30 and np.all(run.eta[before, :2] == 0.0), "a disarmed autopilot moved the boat"
    offset_s, median_m, worst_m = track_distance(track[track[:, 0] > armed_s], run)
    print(f"{vessel}: {s['frames']:.0f} frames, {s['twin_s']:.1f} s of twin time in {wall_s:.1f} s; "
          f"EKF vs twin: clock offset {offset_s * 1e3:.0f} ms, median {median_m:.3f} m, max {worst_m:.3f} m; "
          f"simulated s per phase {phases}")
    assert abs(offset_s) < 0.2 and worst_m < 0.5, (offset_s, median_m, worst_m)


GUIDE = ROOT / "docs" / "guide" / "10-autopilot.md"
FENCE = re.compile(r"^```(bash|text)\n(.*?)^```", re.S | re.M)


def _port_free(kind: int, port: int) -> bool:
    with socket.socket(socket.AF_INET, kind) as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


def test_the_autopilot_guide_runs_as_written(tmp_path):
    """docs/guide/10-autopilot.md, block by block in one folder: ```bash lines run in turn; ```text blocks
    headed `# terminal 1` / `# terminal 2` start in the background as a user's terminals would,
    `# terminal 3` blocks run in the foreground, and the block headed `# after Ctrl-C in terminals
    1 and 2` runs after a SIGINT to each (ArduPilot first). Other ```text blocks are output or build
    notes. ArduPilot comes from ../shared (on PATH, with its parameter files as ROVER_PARAMS); the
    log the page starts from is made by the command of the page that makes it."""
    if not (_port_free(socket.SOCK_DGRAM, 9002) and _port_free(socket.SOCK_STREAM, 5760)):
        pytest.skip("the guide's default ports (udp 9002, tcp 5760) are taken on this machine")
    env = {**os.environ, "ROVER_PARAMS": str(SITL_DIR),
           "PATH": os.pathsep.join([str(SITL_DIR), str(Path(sys.executable).parent), os.environ.get("PATH", "")])}
    make_log = [line for line in (ROOT / "docs" / "guide" / "03-own-log.md").read_text().splitlines()
                if line.startswith("twin dataset") and "--out my_log.csv" in line]
    assert make_log, "the own-log page no longer makes my_log.csv"

    def run(line: str, timeout_s: float = 600) -> str:
        args = twin_command.in_process(line)
        if args is not None and args[0] != "mission":  # a mission talks to ArduPilot: its own process
            done = twin_command.twin(*args, cwd=tmp_path, env=env)
        else:
            done = subprocess.run(["bash", "-c", line], cwd=tmp_path, env=env, capture_output=True, text=True,
                                  timeout=timeout_s, stdin=subprocess.DEVNULL)
        assert done.returncode == 0, f"`{line}` failed:\n{done.stdout[-1500:]}\n{done.stderr[-1500:]}"
        return done.stdout

    run(make_log[0])
    terminals: dict[str, subprocess.Popen] = {}
    printed = []
    try:
        for lang, body in FENCE.findall(GUIDE.read_text()):
            lines = [line for line in body.splitlines() if line.strip()]
            commands = [line for line in lines if not line.lstrip().startswith("#")]
            head = lines[0] if lines else ""
            if lang == "bash":
                for line in commands:
                    run(line)
            elif head.startswith(("# terminal 1", "# terminal 2")):
                name = head.split()[2]
                (command,) = commands
                log = open(tmp_path / f"terminal{name}.log", "w")
                terminals[name] = subprocess.Popen(["bash", "-c", command], cwd=tmp_path, env=env, stdout=log,
                                                   stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                                   start_new_session=True)
                time.sleep(1.0)  # the twin listening before ArduPilot sends, as a user starts them in turn
            elif head.startswith("# terminal 3"):
                printed += [run(line, 900) for line in commands]
            elif head.startswith("# after Ctrl-C in terminals 1 and 2"):
                for name in ("2", "1"):
                    proc = terminals[name]
                    os.killpg(proc.pid, signal.SIGINT)
                    try:
                        proc.wait(60)
                    except subprocess.TimeoutExpired:
                        os.killpg(proc.pid, signal.SIGKILL)
                        proc.wait()
                assert terminals["1"].returncode == 0, (tmp_path / "terminal1.log").read_text()[-2000:]
                printed += [run(line) for line in commands]
    finally:
        for proc in terminals.values():
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
    twin_log = (tmp_path / "terminal1.log").read_text()
    found = SUMMARY.search(twin_log)
    assert found and int(found.group(6)) == 0, twin_log[-2000:]  # no frame missed
    missions = [re.search(r"mission: 4 waypoints, (\d+) m in ([\d.]+) s .*largest ([\d.]+) m, mean ([\d.]+) m", p)
                for p in printed]
    missions = [m for m in missions if m]
    assert len(missions) == 2, printed
    for m in missions:
        assert 55 <= int(m.group(1)) <= 70 and float(m.group(2)) < 150 and float(m.group(3)) < 10.0, m.group(0)
    for name in ("tune.tlog", "tune.png", "tune.rrd", "tune_default.json", "tune_b.json", "boat.parm"):
        assert (tmp_path / name).stat().st_size > 0, name
    print("\n".join(m.group(0) for m in missions))


def test_ardurovers_own_log_is_read_with_its_gyro_and_gps_at_the_times_they_measured(tmp_path):
    """The BlueBoat driven by the real ArduRover in MANUAL, weaving, then ArduRover's own .BIN read as
    a user's log: its gyro, logged after Rover's 4-Hz INS_GYRO_FILTER, is read 0.056 s earlier and its
    GPS fixes by SITL's SIM_GPS1_LAG_MS, each said; so read, the heading and the gyro agree to 0.02 s,
    where as stamped the heading led the gyro by the filter's delay."""
    from twin.formats import read_recording
    from twin.prepare.timing import heading_lag

    with twin_sitl("blueboat", tmp_path) as (port, box):
        with ardupilot(port, box["params"], tmp_path) as rover:
            rover.wait_ekf(timeout_s=180)
            rover.set_mode("MANUAL")
            rover.arm()
            for k in range(12):  # weave: 6-s turns either way at part throttle, over a minute
                rover.wait_sim(6.0, every=lambda s=1200 + 600 * (k % 2): rover.sticks(s, 1750))
            rover.sticks(1500, 1500)
            rover.disarm()
    logs = sorted((tmp_path / "ardupilot" / "logs").glob("*.BIN"))
    assert logs, "ArduRover wrote no .BIN"
    rec = read_recording(logs[-1])
    assert rec.parameters["INS_GYRO_FILTER"] == 4.0 and rec.parameters["SIM_GPS1_LAG_MS"] == 100.0
    assert any(n.startswith("gyro: logged after ArduPilot's 4-Hz low-pass") and "read 0.056 s earlier" in n
               for n in rec.notes), rec.notes
    assert any(n.startswith("gnss: each fix read 0.100 s before it was logged") for n in rec.notes), rec.notes
    lag = heading_lag(rec)
    assert lag.lag_s is not None and abs(lag.lag_s) <= 0.02, lag.text()
    stamped = heading_lag(replace(rec, imu=rec.imu.shifted(-0.0563)))
    assert stamped.lag_s == pytest.approx(-0.06, abs=0.02), stamped.text()
