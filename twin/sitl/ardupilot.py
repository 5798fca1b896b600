"""ArduPilot Rover SITL started beside the twin and flown over MAVLink (pymavlink): the pieces a
test or a script needs to fly the real autopilot against `twin sitl` without a ground station.

`start_ardurover` starts the SITL binary on the twin's UDP port with its MAVLink console on a
TCP port of its own, in a scratch folder (SITL writes eeprom.bin, logs/ and terrain/ where it
runs). `Rover` is the MAVLink side: wait for the EKF, arm, change mode, drive with RC overrides,
send a GUIDED target, upload and fly a mission, read the EKF's position.

The message and command names are MAVLink's common set and ArduPilot Rover's (mode numbers
from Rover's mode.h: MANUAL 0, HOLD 4, AUTO 10, GUIDED 15) [ArduPilot-Rover]. Positions are local
north/east metres from SITL's home, which is the twin's origin.
"""
from __future__ import annotations

import difflib
import math
import os
import signal
import socket
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from twin.errors import TwinError
from twin.geodesy import geodetic_from_ned, ned_from_geodetic

MODES = {"MANUAL": 0, "HOLD": 4, "AUTO": 10, "GUIDED": 15}
# EKF_STATUS_REPORT flags a GPS-aided EKF sets once it is usable for navigation: attitude,
# horizontal velocity, horizontal position relative and absolute (MAVLink ESTIMATOR_STATUS_FLAGS)
EKF_NAV_FLAGS = 0x01 | 0x02 | 0x08 | 0x10
ARMED_FLAG = 0x80  # MAV_MODE_FLAG_SAFETY_ARMED
GPS_FIX_3D = 3
# the --home a mission is given may differ from SITL's own by this much (m) and no more: beyond, every
# waypoint would be that far off and the boat would drive there
HOME_TOLERANCE_M = 100.0
# how long a mission waits for SITL's MAVLink console to appear (a SITL started after the mission is up
# within seconds; one that died is not waited for through a whole step's --timeout)
CONSOLE_WAIT_S = 120.0


class LinkClosed(TwinError):
    """ArduPilot closed (or reset) the MAVLink connection: nothing more will arrive on it."""


def free_tcp_port() -> int:
    """A TCP port nothing listens on now (the system's choice of an ephemeral one)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@dataclass
class ArduRover:
    """A running SITL process: its MAVLink TCP port and its scratch folder."""

    process: subprocess.Popen
    mavlink_port: int
    folder: Path
    log_path: Path

    def stop(self, timeout_s: float = 5.0) -> None:
        """End the process (SIGTERM, then SIGKILL: SITL may not answer SIGTERM while it waits for
        physics) and its process group."""
        if self.process.poll() is not None:
            return
        for sig in (signal.SIGTERM, signal.SIGKILL):
            try:
                os.killpg(self.process.pid, sig)
            except ProcessLookupError:
                return
            try:
                self.process.wait(timeout_s)
                return
            except subprocess.TimeoutExpired:
                continue

    def output(self) -> str:
        """What SITL printed so far (for error messages)."""
        try:
            return self.log_path.read_text(errors="replace")
        except OSError:
            return ""


def start_ardurover(binary: Path, physics_port: int, defaults: Sequence[Path], folder: Path, *,
                    home: tuple[float, float, float, float] = (37.4136, -5.9786, 0.0, 0.0),
                    speedup: float = 100.0, wipe: bool = True, instance: int | None = None) -> ArduRover:
    """Start ArduPilot Rover SITL with `--model JSON` sending its servo frames to 127.0.0.1:physics_port.

    defaults: parameter files, later ones winning (ArduPilot's rover.parm, rover-skid.parm, then the
    one `twin sitl --write-params` wrote). The MAVLink console (SERIAL0) goes to a free TCP port;
    SITL's other ports move with `instance` (-I adds 10 per instance), chosen from the process id
    when not given, so that two runs on one machine do not collide. wipe: start from a blank
    EEPROM (-w); without it SITL keeps the parameters of its last run in `folder`."""
    binary = Path(binary)
    if not (binary.is_file() and os.access(binary, os.X_OK)):
        raise TwinError(f"ArduPilot SITL binary '{binary}' not found or not executable")
    folder.mkdir(parents=True, exist_ok=True)
    if instance is None:
        instance = 1 + os.getpid() % 40
    mavlink_port = free_tcp_port()
    base_port = mavlink_port - 10 * instance  # SERIAL0 listens on base + 10·instance
    cmd = [str(binary), "--model", "JSON", "--speedup", f"{speedup:g}", "--home", ",".join(f"{x:g}" for x in home),
           "--defaults", ",".join(str(Path(d).resolve()) for d in defaults), "--sim-address", "127.0.0.1",
           "--sim-port-out", str(physics_port), "--base-port", str(base_port), "-I", str(instance),
           "--serial0", f"tcp:{mavlink_port}"] + (["-w"] if wipe else [])
    log_path = folder / "ardurover.log"
    with open(log_path, "ab") as out:
        process = subprocess.Popen(cmd, cwd=folder, stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                   start_new_session=True)
    return ArduRover(process, mavlink_port, folder, log_path)


def offset_position(lat_deg: float, lon_deg: float, north_m: float, east_m: float) -> tuple[float, float]:
    """The latitude/longitude (deg) north_m, east_m from a point (twin.geodesy's local tangent plane)."""
    lat, lon = geodetic_from_ned(north_m, east_m, lat_deg, lon_deg)
    return float(lat), float(lon)


class Rover:
    """ArduPilot Rover over MAVLink (pymavlink): connect, wait, arm, drive, fly missions.

    Every wait is bounded by a wall-clock timeout and raises TwinError saying what did not happen.
    `track` keeps every LOCAL_POSITION_NED received: (time_boot_s, north_m, east_m); `boot_s` is
    ArduPilot's clock (s since boot) in the last message that carried it, `yaw_rad` its heading in
    (−π, π] and `heading_rad` the same unwrapped (whole turns counted)."""

    def __init__(self, port: int, *, connect_timeout_s: float = 60.0, stream_hz: int = 10):
        # late: importing pymavlink sets MAVLINK_DIALECT in os.environ (tests/test_layout.py LATE_IMPORTS)
        from pymavlink import mavutil

        self.mavutil = mavutil
        deadline = time.monotonic() + connect_timeout_s
        while True:  # SITL opens its TCP port only once it has started: wait for it quietly
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1.0).close()
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise TwinError(f"no MAVLink console on tcp:127.0.0.1:{port} (is SITL running?)") from None
                time.sleep(0.2)
        self.port = port
        self.link = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=255, autoreconnect=False)
        self._raise_when_closed()
        try:
            heartbeat = self.link.wait_heartbeat(timeout=max(1.0, deadline - time.monotonic()))
        except LinkClosed as exc:
            self.link.close()
            raise TwinError(f"{exc} before its first heartbeat (is ArduPilot's console on that port?)") from None
        if heartbeat is None:
            self.link.close()
            raise TwinError("no heartbeat from ArduPilot")
        self.target = (self.link.target_system, self.link.target_component)
        self.track: list[tuple[float, float, float]] = []
        self.texts: list[str] = []
        self.text_times_s: list[float] = []  # ArduPilot's clock when each text arrived
        self.boot_s = 0.0
        self.yaw_rad = 0.0
        self.heading_rad = 0.0
        self.ekf_flags = 0
        self.gps_fix = 0
        self.global_deg: tuple[float, float] | None = None  # the last GLOBAL_POSITION_INT (lat, lon)
        self.armed = False
        self.mode = None
        self.reached: list[int] = []
        self.mission_current = -1
        self.params: dict[str, float] = {}  # PARAM_VALUE: what ArduPilot says it has
        self.param_count = 0
        self.link.mav.request_data_stream_send(*self.target, mavutil.mavlink.MAV_DATA_STREAM_ALL, stream_hz, 1)

    def _raise_when_closed(self) -> None:
        """Make a closed or reset connection raise LinkClosed. pymavlink's TCP link, without autoreconnect,
        prints "EOF on TCP socket" on every read of a socket its peer closed and returns no bytes, as when
        nothing has arrived yet: a wait would print that line hundreds of thousands of times until its
        timeout, then blame the autopilot's silence."""
        text = f"ArduPilot closed the MAVLink connection on tcp:127.0.0.1:{self.port}"

        def closed() -> None:
            raise LinkClosed(text)

        self.link.handle_eof = closed  # a read of no bytes on a readable socket: the peer's FIN
        self.link.handle_disconnect = closed  # ECONNRESET / EPIPE on a read or a write

    # ------------------------------------------------------------ receiving

    def pump(self, wait_s: float = 0.05) -> None:
        """Read what arrived (for up to wait_s when nothing has), keeping the state this class tracks."""
        first = True
        while True:
            msg = self.link.recv_match(blocking=first, timeout=wait_s if first else None)
            first = False
            if msg is None:
                return
            kind = msg.get_type()
            boot_ms = getattr(msg, "time_boot_ms", None)
            if boot_ms is not None and msg.get_srcSystem() == self.target[0]:
                self.boot_s = boot_ms * 1e-3
            if kind == "ATTITUDE":
                self.heading_rad += math.remainder(msg.yaw - self.yaw_rad, math.tau)  # unwrapped: turns add up
                self.yaw_rad = msg.yaw
            elif kind == "LOCAL_POSITION_NED":
                self.track.append((msg.time_boot_ms * 1e-3, msg.x, msg.y))
            elif kind == "HEARTBEAT" and msg.get_srcSystem() == self.target[0] and msg.type != 6:  # 6: a GCS
                self.armed = bool(msg.base_mode & ARMED_FLAG)
                self.mode = msg.custom_mode
            elif kind == "EKF_STATUS_REPORT":
                self.ekf_flags = msg.flags
            elif kind == "GLOBAL_POSITION_INT" and msg.get_srcSystem() == self.target[0]:
                self.global_deg = (msg.lat * 1e-7, msg.lon * 1e-7)
            elif kind == "GPS_RAW_INT":
                self.gps_fix = msg.fix_type
            elif kind == "STATUSTEXT":
                self.texts.append(msg.text)
                self.text_times_s.append(self.boot_s)
            elif kind == "MISSION_ITEM_REACHED":
                self.reached.append(msg.seq)
            elif kind == "MISSION_CURRENT":
                self.mission_current = msg.seq
            elif kind == "PARAM_VALUE":
                name = msg.param_id.decode() if isinstance(msg.param_id, bytes) else str(msg.param_id)
                self.params[name.rstrip("\x00")] = float(msg.param_value)
                self.param_count = max(self.param_count, int(msg.param_count))

    def wait(self, condition, what: str, timeout_s: float, every=None) -> None:
        """Pump messages until condition() holds; `every` is called on each pass (e.g. to resend)."""
        deadline = time.monotonic() + timeout_s
        clock_s = self.boot_s
        while not condition():
            if time.monotonic() > deadline:
                if clock_s > 0 and self.boot_s == clock_s:
                    # SITL steps in lockstep with its physics: a clock that stood still had no physics to step
                    raise TwinError(f"ArduPilot: {what} not within {timeout_s:g} s, and its clock stood at "
                                    f"{clock_s:.1f} s all that time: its physics (twin sitl) stopped answering")
                raise TwinError(f"ArduPilot: {what} not within {timeout_s:g} s; last messages: {self.texts[-5:]}")
            try:
                if every is not None:
                    every()
                self.pump()
            except LinkClosed as exc:  # nothing more will come: end the wait now, not at its timeout
                raise TwinError(f"{exc} before {what}") from None

    @property
    def position(self) -> tuple[float, float]:
        """The EKF's last local position (north, east, m)."""
        if not self.track:
            raise TwinError("ArduPilot has sent no position yet")
        return self.track[-1][1], self.track[-1][2]

    def wait_sim(self, seconds: float, timeout_s: float = 120.0, every=None) -> None:
        """Let `seconds` of ArduPilot's (simulated) time pass."""
        self.wait(lambda: self.boot_s > 0.0, "ArduPilot's clock", timeout_s)
        end = self.boot_s + seconds
        self.wait(lambda: self.boot_s >= end, f"{seconds:g} s of simulated time", timeout_s, every)

    # ------------------------------------------------------------ commanding

    def set_param(self, name: str, value: float) -> None:
        self.link.mav.param_set_send(*self.target, name.encode(), float(value),
                                     self.mavutil.mavlink.MAV_PARAM_TYPE_REAL32)

    def check_params(self, names, timeout_s: float = 60.0) -> None:
        """Refuse (TwinError, before any is set) names ArduPilot has no parameter of: it ignores a
        PARAM_SET of an unknown name without a word, so a typo would fly the mission on the default.
        Its own list is the table: asked for in full, and each name missing from it asked for alone
        (a list can lose a message) before it is called unknown."""
        names = list(names)
        if not names:
            return
        self.link.mav.param_request_list_send(*self.target)
        quiet = [time.monotonic(), len(self.params)]

        def listed() -> bool:  # all of them, or nothing new for two seconds
            if len(self.params) != quiet[1]:
                quiet[:] = [time.monotonic(), len(self.params)]
            return (self.param_count > 0 and len(self.params) >= self.param_count) or time.monotonic() - quiet[0] > 2.0

        self.wait(listed, "the parameter list", timeout_s)
        for name in [n for n in names if n not in self.params]:
            self.link.mav.param_request_read_send(*self.target, name.encode(), -1)
        end = time.monotonic() + 2.0
        try:
            while time.monotonic() < end and any(n not in self.params for n in names):
                self.pump()
        except LinkClosed as exc:
            raise TwinError(f"{exc} before it listed its parameters") from None
        unknown = [n for n in names if n not in self.params]
        if unknown:
            raise TwinError(unknown_params_text(unknown, self.params))

    def wait_ekf(self, timeout_s: float = 120.0) -> None:
        """Until the EKF navigates on GPS (position, velocity, attitude flags) with a 3-D fix."""
        self.wait(lambda: (self.ekf_flags & EKF_NAV_FLAGS) == EKF_NAV_FLAGS and self.gps_fix >= GPS_FIX_3D,
                  "an EKF navigating on GPS", timeout_s)

    def set_mode(self, name: str, timeout_s: float = 30.0) -> None:
        number = MODES[name]
        self.link.mav.set_mode_send(self.target[0], self.mavutil.mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, number)
        self.wait(lambda: self.mode == number, f"mode {name}", timeout_s)

    def arm(self, timeout_s: float = 60.0) -> None:
        """Arm, asking again every second of wall time until the pre-arm checks pass."""
        last = [0.0]

        def ask():
            if time.monotonic() - last[0] > 1.0:
                last[0] = time.monotonic()
                self.link.mav.command_long_send(*self.target, self.mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM,
                                                0, 1, 0, 0, 0, 0, 0, 0)

        self.wait(lambda: self.armed, "arming", timeout_s, ask)

    def disarm(self, timeout_s: float = 30.0) -> None:
        self.link.mav.command_long_send(*self.target, self.mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM,
                                        0, 0, 21196, 0, 0, 0, 0, 0)
        self.wait(lambda: not self.armed, "disarming", timeout_s)

    def sticks(self, steering_us: int = 1500, throttle_us: int = 1500) -> None:
        """RC override of channel 1 (steering) and 3 (throttle); the others left to the radio (0)."""
        self.link.mav.rc_channels_override_send(*self.target, steering_us, 0, throttle_us, 0, 0, 0, 0, 0)

    def drive(self, seconds: float, steering_us: int, throttle_us: int, timeout_s: float = 120.0) -> None:
        """MANUAL driving for `seconds` of simulated time, the override resent on every pass."""
        self.wait_sim(seconds, timeout_s, every=lambda: self.sticks(steering_us, throttle_us))
        self.sticks(1500, 1500)

    def goto(self, north_m: float, east_m: float) -> None:
        """A GUIDED target, local north/east (m) from the EKF origin."""
        m = self.mavutil.mavlink
        position_only = 0b110111111000
        self.link.mav.set_position_target_local_ned_send(0, *self.target, m.MAV_FRAME_LOCAL_NED, position_only,
                                                         north_m, east_m, 0, 0, 0, 0, 0, 0, 0, 0, 0)

    def distance_to(self, north_m: float, east_m: float) -> float:
        n, e = self.position
        return math.hypot(n - north_m, e - east_m)

    def upload_mission(self, home: tuple[float, float], waypoints_ne_m: Sequence[tuple[float, float]],
                       timeout_s: float = 30.0) -> None:
        """Waypoints (north, east m from home) as NAV_WAYPOINT items after item 0 (home), by MAVLink's
        mission protocol: count, the items it asks for, its acknowledgement."""
        items = [home] + [offset_position(home[0], home[1], n, e) for n, e in waypoints_ne_m]
        deadline = time.monotonic() + timeout_s
        try:
            self._upload(items, deadline)
        except LinkClosed as exc:
            raise TwinError(f"{exc} before the mission upload finished") from None

    def _upload(self, items: list[tuple[float, float]], deadline: float) -> None:
        """MAVLink's mission upload of `items` (lat, lon deg; item 0 home), until its acknowledgement."""
        m = self.mavutil.mavlink
        self.link.mav.mission_count_send(*self.target, len(items))
        while True:
            msg = self.link.recv_match(type=["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"], blocking=True,
                                       timeout=1.0)
            if time.monotonic() > deadline:
                raise TwinError("ArduPilot: the mission upload did not finish")
            if msg is None:
                continue
            if msg.get_type() == "MISSION_ACK":
                if msg.type != m.MAV_MISSION_ACCEPTED:
                    raise TwinError(f"ArduPilot refused the mission (MAV_MISSION_RESULT {msg.type})")
                return
            lat, lon = items[msg.seq]
            self.link.mav.mission_item_int_send(*self.target, msg.seq, m.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                                                m.MAV_CMD_NAV_WAYPOINT, 0, 1, 0, 0, 0, 0,
                                                int(round(lat * 1e7)), int(round(lon * 1e7)), 0.0)

    def check_home(self, home: tuple[float, float], timeout_s: float = 30.0) -> None:
        """Refuse a `home` (lat, lon deg) that is not SITL's: the vehicle's global position less its
        local one (north, east from the EKF's origin, SITL's home) must lie within HOME_TOLERANCE_M of it."""
        self.wait(lambda: self.global_deg is not None and bool(self.track), "a global position", timeout_s)
        north, east = ned_from_geodetic(self.global_deg[0], self.global_deg[1], home[0], home[1])
        local = self.position
        off = math.hypot(float(north) - local[0], float(east) - local[1])
        if off > HOME_TOLERANCE_M:
            raise TwinError(f"--home {home[0]:g},{home[1]:g} is {off / 1000:.1f} km from SITL's home: give the "
                            "--home SITL was started with (the waypoints are metres from it)")

    def stop(self, timeout_s: float = 5.0) -> None:
        """HOLD and disarm, as far as the link still answers within `timeout_s` each: the safe state
        after a failure, which must not raise over the error that led here."""
        for step in (lambda: self.set_mode("HOLD", timeout_s), lambda: self.disarm(timeout_s)):
            try:
                step()
            except (TwinError, OSError, KeyboardInterrupt):
                pass

    def close(self) -> None:
        self.link.close()


def path_deviation_m(track_ne_m, path_ne_m) -> np.ndarray:
    """Each point's distance (m) from a planned path: the polyline through `path_ne_m` (north, east
    m), the nearest of its legs. What a steering tune changes: how far the boat strays from the
    straight line between waypoints."""
    p = np.asarray(track_ne_m, dtype=float).reshape(-1, 2)
    legs = np.asarray(path_ne_m, dtype=float).reshape(-1, 2)
    if len(legs) < 2:
        raise TwinError("a path needs two points at least")
    a, b = legs[:-1], legs[1:]
    ab = b - a
    length2 = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12)
    s = np.clip(np.einsum("kij,ij->ki", p[:, None, :] - a[None], ab) / length2, 0.0, 1.0)
    nearest = a[None] + s[..., None] * ab[None]
    return np.min(np.linalg.norm(p[:, None, :] - nearest, axis=2), axis=1)


@dataclass(frozen=True)
class MissionResult:
    """How a mission flown by `fly_mission` went: its time on ArduPilot's clock (s), the planned
    path's length (m), how far the EKF's positions strayed from the straight legs (m), the
    parameters set before it, and the EKF track (time_boot_s, north_m, east_m rows)."""

    waypoints: int
    mission_s: float
    path_m: float
    deviation_max_m: float
    deviation_mean_m: float
    settings: dict
    track: np.ndarray

    @property
    def mean_speed_m_s(self) -> float:
        return self.path_m / self.mission_s

    def text(self) -> str:
        return (f"mission: {self.waypoints} waypoint{'' if self.waypoints == 1 else 's'}, {self.path_m:.0f} m in {self.mission_s:.1f} s (ArduPilot's "
                f"clock), mean speed {self.mean_speed_m_s:.2f} m/s; off the straight legs: largest "
                f"{self.deviation_max_m:.2f} m, mean {self.deviation_mean_m:.2f} m")

    def to_dict(self) -> dict:
        return {"waypoints": self.waypoints, "mission_s": self.mission_s, "path_m": self.path_m,
                "mean_speed_m_s": self.mean_speed_m_s, "deviation_max_m": self.deviation_max_m,
                "deviation_mean_m": self.deviation_mean_m, "set": dict(self.settings),
                "track": {"t_s": self.track[:, 0].tolist(), "north_m": self.track[:, 1].tolist(),
                          "east_m": self.track[:, 2].tolist()}}


def unknown_params_text(unknown: list[str], known) -> str:
    """One line naming the parameters ArduPilot does not have, each with its closest names (difflib)."""
    parts = []
    for name in unknown:
        # 0.7: a typo (WP_SPD for WP_SPEED, 0.71) is suggested, a name of another family (NOT_A_PARAM for
        # MAV3_PARAMS, 0.64) is not
        close = difflib.get_close_matches(name, list(known), n=3, cutoff=0.7)
        parts.append(f"{name}" + (f" (did you mean {', '.join(close)}?)" if close else ""))
    return f"--set: ArduPilot has no parameter {'; '.join(parts)}: nothing was set"


WAYPOINT_FILE_HEADER = "QGC WPL 110"  # the plain-text mission file Mission Planner and QGroundControl save
MAV_CMD_NAV_WAYPOINT = 16


def read_waypoint_file(path: Path, home: tuple[float, float]) -> tuple[list[tuple[float, float]], list[str]]:
    """The NAV_WAYPOINT items of a QGC WPL 110 mission file as (north, east) m from `home` (lat, lon
    deg), in the file's order, and notes on what was left out.

    A line is: index, current, frame, command, four parameters, latitude, longitude, altitude,
    autocontinue, separated by tabs [MAVLink mission file format]. Item 0 is the home a ground
    station wrote, not a waypoint; items of other commands (loiter, return to launch, jumps, speed
    changes) are left out and named in the notes: `twin mission` drives the legs between waypoints.

    Raises:
        TwinError: the file cannot be read, is not a QGC WPL 110 file, or holds no waypoint.
    """
    try:
        lines = Path(path).read_text(encoding="utf-8-sig", errors="replace").splitlines()  # a BOM, as some editors write
    except OSError as exc:
        raise TwinError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if not lines or not lines[0].startswith(WAYPOINT_FILE_HEADER):
        raise TwinError(f"{Path(path).name}: not a mission file (its first line is not '{WAYPOINT_FILE_HEADER}', as "
                        "Mission Planner and QGroundControl save one)")
    points, other = [], []
    for number, line in enumerate(lines[1:], start=2):
        cells = line.split()
        if not cells:
            continue
        try:
            index, command, lat, lon = int(cells[0]), int(cells[3]), float(cells[8]), float(cells[9])
        except (IndexError, ValueError):
            raise TwinError(f"{Path(path).name}: line {number} is not a mission item (index, current, frame, command, "
                            "4 parameters, latitude, longitude, altitude, autocontinue)") from None
        if index == 0:
            continue
        if command != MAV_CMD_NAV_WAYPOINT:
            other.append(f"item {index} (command {command})")
            continue
        if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0) or (lat == 0.0 and lon == 0.0):
            raise TwinError(f"{Path(path).name}: item {index} has no position (latitude {lat:g}, longitude {lon:g})")
        north, east = ned_from_geodetic(lat, lon, home[0], home[1])
        points.append((float(north), float(east)))
    if not points:
        raise TwinError(f"{Path(path).name}: no waypoint (command {MAV_CMD_NAV_WAYPOINT}) to drive to")
    notes = [f"{Path(path).name}: left out, as `twin mission` drives from waypoint to waypoint: {', '.join(other)}"] \
        if other else []
    return points, notes


def fly_mission(port: int, home: tuple[float, float], waypoints_ne_m: Sequence[tuple[float, float]], *,
                settings: dict | None = None, timeout_s: float = 600.0) -> MissionResult:
    """Connect to SITL's MAVLink console on tcp:127.0.0.1:port, wait until its EKF navigates on GPS,
    set `settings` (ArduPilot parameters), upload the waypoints (north, east m from `home`, which
    must be SITL's --home), arm, fly them in AUTO, then hold and disarm. The boat starts where it
    is: a second mission against the same SITL starts where the first ended."""
    if len(waypoints_ne_m) < 1:
        raise TwinError("a mission needs one waypoint at least")
    rover = Rover(port, connect_timeout_s=min(timeout_s, CONSOLE_WAIT_S))
    finished = False
    try:
        rover.wait_ekf(timeout_s=timeout_s)
        rover.check_home(home, timeout_s=timeout_s)
        rover.check_params(settings or {}, timeout_s=timeout_s)
        for name, value in (settings or {}).items():
            rover.set_param(name, value)
        rover.set_mode("HOLD")
        start = rover.position
        rover.upload_mission(home, waypoints_ne_m)
        rover.arm(timeout_s=timeout_s)
        rover.set_mode("AUTO")
        t0, first = rover.boot_s, len(rover.track)
        wanted = set(range(1, len(waypoints_ne_m) + 1))
        rover.wait(lambda: wanted <= set(rover.reached), "the mission", timeout_s)
        t1 = rover.boot_s
        rover.set_mode("HOLD")
        rover.disarm()
        finished = True
    finally:
        if not finished:  # a mission that failed or was interrupted must not leave the boat driving in AUTO
            rover.stop()
        rover.close()
    track = np.array(rover.track[first:], dtype=float).reshape(-1, 3)
    path = [tuple(start)] + [tuple(w) for w in waypoints_ne_m]
    off = path_deviation_m(track[:, 1:], path) if len(track) else np.zeros(1)
    length = float(sum(math.dist(a, b) for a, b in zip(path[:-1], path[1:])))
    return MissionResult(len(waypoints_ne_m), t1 - t0, length, float(off.max()), float(off.mean()),
                         dict(settings or {}), track)
