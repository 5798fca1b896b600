"""`twin sitl`: the twin as ArduPilot SITL's physics backend (JSON interface)."""
from __future__ import annotations

import json
import math
import re
import socket
from pathlib import Path
from typing import Optional

import typer

from ..errors import TwinError
from ..files import kept_data_by_content, output_scope, write_text_atomic
from ..files import RUNS, check_new
from ..sitl.ardupilot import CONSOLE_WAIT_S, fly_mission, read_waypoint_file
from .app import (REPORT_HELP, CASE_HELP, FORCE_HELP, MODEL_HELP, TWIN_THRUSTER_SHIPPED, app, channels_from, check_distinct, 
                  check_outputs, note, positive, say, seed_from, speed_direction, vessel_from)
from .run import RUN_OUTPUTS, SEA_HELP, origin_from, sea_from


@app.command()
@output_scope()  # a recording that appears during the session at a path found free is kept (files._put)
def sitl(
    vessel: Optional[str] = typer.Option(None, help=f"vessel name (a twin-thruster one shipped with twin, as ArduPilot "
                                                    f"Rover's SITL drives two throttles: {TWIN_THRUSTER_SHIPPED})"),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP),
    case: Optional[str] = typer.Option(None, help=CASE_HELP),
    port: int = typer.Option(9002, help="UDP port ArduPilot sends its servo packets to"),
    host: str = typer.Option("127.0.0.1", help="address to listen on (0.0.0.0: every interface, for an ArduPilot "
                                               "on another machine)"),
    rate: float = typer.Option(400.0, help="least physics rate, Hz, at most 10000: frames (1200 Hz in Rover "
                                           "SITL) are split into equal steps no longer than 1/RATE"),
    esc_arm: float = typer.Option(2.0, help="seconds each ESC must see its stopped signal after power-up before "
                                           "it drives its thruster, as a Basic ESC does (0: at once)"),
    channels: Optional[str] = typer.Option(None, help="servo outputs LEFT,RIGHT of the thrusters (default 1,3: "
                                                     "SERVO1_FUNCTION=73, SERVO3_FUNCTION=74)"),
    current: Optional[str] = typer.Option(None, help="water current SPEED,DIR_DEG (m/s, flowing towards)"),
    wind: Optional[str] = typer.Option(None, help="wind SPEED,DIR_DEG (m/s, coming from)"),
    heading: float = typer.Option(0.0, help="initial heading, deg"),
    sea: Optional[str] = typer.Option(None, help=SEA_HELP),
    seed: int = typer.Option(0, help="random seed of the sea's components"),
    origin: Optional[str] = typer.Option(None, help="LAT,LON (deg) of the origin, SITL's home, for map positions"),
    record: list[Path] = typer.Option([], help="record the SITL session: .csv, .mcap, .rrd, .tlog or .bin (repeatable)"),
    realtime: bool = typer.Option(False, "--realtime/--lockstep", help="pace to the wall clock / one physics "
                                                                       "frame per servo frame"),
    write_params: Optional[Path] = typer.Option(None, help="write ArduPilot's parameter file for this vessel "
                                                           "and --channels (ardurover --defaults ...,FILE) "
                                                           "and exit"),
    force: bool = typer.Option(False, "--force", help=FORCE_HELP),
):
    """ArduPilot SITL physics backend (JSON interface): sim_vehicle.py -v Rover --model JSON."""
    # late: the server (mujoco, 0.22 s) would be paid at every `twin --help`
    from ..sitl.backend import check_channels, check_rate
    from ..sitl.server import run_sitl

    check_outputs(record, RUN_OUTPUTS, "--record")
    if write_params is not None:
        check_outputs([write_params], (".parm", ".param", ".txt"), "--write-params")
    check_distinct({"--record": record, "--write-params": [write_params] if write_params else []}, [model],
                   keep_data=False)  # a parameter file is no log; a recording there: check_new below
    # a SITL run ends with Ctrl-C: a recording already at that path would be found replaced only after it
    check_new(record, force, "--record", RUNS)
    check_new([write_params], force, "--write-params")
    if write_params is not None and force:
        # by its content, as every command reads a file named on the command line (a CSV log saved as .txt)
        kind = "recording" if _is_recording(write_params) else kept_data_by_content(write_params)
        if kind:
            raise TwinError(f"--write-params '{write_params}' exists and is a {kind}: it is kept, --force or not "
                            "(give another name, or remove it first)")
    if write_params is not None:  # it writes the file and exits: options of a SITL run would be dropped unsaid
        session = {"--port": port != 9002, "--host": host != "127.0.0.1", "--rate": rate != 400.0,
                   "--esc-arm": esc_arm != 2.0, "--current": current is not None, "--wind": wind is not None,
                   "--heading": heading != 0.0, "--sea": sea is not None, "--seed": seed != 0,
                   "--origin": origin is not None, "--record": bool(record), "--realtime": realtime}
        given = [name for name, on in session.items() if on]
        if given:
            raise TwinError(f"--write-params writes ArduPilot's parameter file and exits: {', '.join(given)} "
                            f"{'applies' if len(given) == 1 else 'apply'} to a SITL session (give "
                            f"{'it' if len(given) == 1 else 'them'} without --write-params)")
    check_rate(rate)
    pair = channels_from(channels)
    if pair:  # the parameter file and the server alike: two different servo outputs
        check_channels((pair["left"], pair["right"]))
    v = vessel_from(vessel, model, case)
    if write_params is not None:
        from ..sitl.params import boat_parameters  # late: 0.16 s, only for --write-params

        text = boat_parameters(v, (pair["left"], pair["right"]) if pair else (1, 3))
        write_text_atomic(write_params, text)
        say(f"wrote {write_params}: give it to ArduPilot last, e.g. ardurover --defaults "
            f"rover.parm,rover-skid.parm,{write_params} (or sim_vehicle.py --add-param-file {write_params})")
        return
    if v.thrusters.kind == "propeller_rudder":  # ArduPilot Rover's servo outputs are two thrusters' PWM
        raise TwinError(f"vessel '{v.name}' is a propeller-and-rudder ship: SITL supports twin-thruster vessels only")
    sea_state = sea_from(sea, seed_from(seed))
    summary = run_sitl(
        v, port=port, host=host, rate_hz=rate, record_paths=record,
        realtime=realtime, channels=(pair["left"], pair["right"]) if pair else (1, 3),
        current=speed_direction(current, "current"), wind=speed_direction(wind, "wind"),
        heading_deg=heading, origin=origin_from(origin), log=note, esc_arm_s=esc_arm, sea=sea_state,
    )
    say(summary.text())
    if record and not summary.written:  # a script must not read the session as recorded
        raise TwinError(f"--record: nothing written ({', '.join(str(p) for p in record)}): no frame came from ArduPilot "
                        "before the session ended")


def _is_recording(path: Path) -> bool:
    """Whether the file at `path` reads as a recording (twin.formats.read_recording, as `twin info` reads
    it), whatever its name says."""
    if not Path(path).is_file():
        return False
    from ..formats import read_recording  # late: 0.08 s, only for a file there

    try:
        read_recording(Path(path))
    except Exception:  # any failure to read it as one: not a recording
        return False
    return True


MAX_LEG_M = 50_000.0  # a small vessel's mission stays within tens of kilometres of home
PARAM_NAME = re.compile(r"[A-Z][A-Z0-9_]{0,15}")  # ArduPilot's names: 16 characters at most, upper case


def param_settings(items: list[str]) -> dict[str, float]:
    """--set NAME=VALUE items as {NAME: value}; a name that cannot be an ArduPilot parameter's is refused
    here (whether ArduPilot has it, only the running autopilot can say: sitl.ardupilot.Rover.check_params)."""
    settings = {}
    for item in items:
        name, _, value = item.partition("=")
        name = name.strip().upper()
        try:
            number = float(value)
        except ValueError:
            number = math.nan
        if not name or not math.isfinite(number):
            raise TwinError(f"--set expects NAME=VALUE with a finite number, got '{item}'")
        if not PARAM_NAME.fullmatch(name):
            raise TwinError(f"--set {name}: not an ArduPilot parameter name (letters, digits and _, starting with a "
                            "letter, 16 characters at most)")
        settings[name] = number
    return settings


@app.command()
def mission(
    home: str = typer.Option(..., help="LAT,LON (deg) of SITL's --home: the waypoints are metres from it"),
    waypoints: str = typer.Option(..., help='"N,E N,E ...": each waypoint in metres north and east of home; or a '
                                            'mission file (QGC WPL 110, as Mission Planner and QGroundControl save '
                                            'one): its waypoints'),
    port: int = typer.Option(5760, help="SITL's MAVLink TCP port (its SERIAL0: 5760, +10 per -I instance)"),
    set_: list[str] = typer.Option([], "--set", help="NAME=VALUE: an ArduPilot parameter set before the mission "
                                                   "(repeatable), e.g. --set ATC_STR_RAT_FF=0.5"),
    timeout: float = typer.Option(600.0, help="wall-clock seconds to wait for each step (for SITL's console to "
                                              "appear: at most 120)"),
    json_out: Optional[Path] = typer.Option(None, "--json", help=f"also write the figures and the EKF track (.json) {REPORT_HELP}"),
):
    """Fly a waypoint mission with ArduPilot SITL over MAVLink (AUTO), then hold and disarm; print its
    time, mean speed and how far the boat strayed from the straight legs."""

    positive(timeout, "--timeout")
    if not 1 <= port <= 65535:
        raise TwinError(f"--port {port}: a TCP port number is 1..65535 (SITL's MAVLink console: 5760)")
    if json_out is not None:
        check_outputs([json_out], (".json",), "--json")
        check_distinct({"--json": json_out})  # the figures never replace a log or a twin
    try:
        lat_lon = origin_from(home)
    except TwinError as exc:
        raise TwinError(str(exc).replace("--origin", "--home")) from None
    points = _waypoints(waypoints, lat_lon)
    far = [p for p in points if not (math.isfinite(p[0]) and math.isfinite(p[1]) and math.hypot(*p) <= MAX_LEG_M)]
    if far:  # NaN would be uploaded to the autopilot as it is; a waypoint 1000 km off is a unit (mm, or degrees)
        raise TwinError(f"--waypoints: {far[0][0]:g},{far[0][1]:g} is not a waypoint within {MAX_LEG_M / 1e3:g} km "
                        "of home (NORTH,EAST in m)")
    settings = param_settings(set_)
    if not _listening(port):  # SITL may be starting: say what is awaited rather than wait in silence
        note(f"note: waiting up to {min(timeout, CONSOLE_WAIT_S):g} s for SITL's MAVLink console on "
             f"tcp:127.0.0.1:{port}; start ArduPilot's SITL first (ardurover --model JSON, with `twin sitl` serving "
             "its physics): the console is ArduPilot's, not the twin's")
    result = fly_mission(port, lat_lon, points, settings=settings, timeout_s=timeout)
    say(result.text())
    if json_out is not None:
        write_text_atomic(json_out, json.dumps(result.to_dict(), indent=1) + "\n")
        say(f"wrote {json_out}")


def _waypoints(text: str, home: tuple[float, float]) -> list[tuple[float, float]]:
    """--waypoints: NORTH,EAST pairs (m), or a mission file's waypoints from `home` (its notes said)."""
    try:
        points = [tuple(float(x) for x in p.split(",")) for p in text.split()]
    except ValueError:
        points = []
    if points and all(len(p) == 2 for p in points):
        return points
    path = Path(text)
    if path.is_file():
        points, notes = read_waypoint_file(path, home)
        say(f"{path.name}: {len(points)} waypoint{'' if len(points) == 1 else 's'} read")
        for line in notes:
            note(f"note: {line}")
        return points
    if "," not in text and " " not in text.strip():
        raise TwinError(f"--waypoints {text}: no such mission file (give a QGC WPL 110 file, as Mission Planner saves, "
                        "or NORTH,EAST pairs in m separated by spaces)")
    raise TwinError(f"--waypoints expects NORTH,EAST pairs (m) separated by spaces, or a mission file, got '{text}'")


def _listening(port: int) -> bool:
    """Whether something accepts TCP connections on 127.0.0.1:port now."""
    try:
        socket.create_connection(("127.0.0.1", port), timeout=0.5).close()
        return True
    except OSError:
        return False
