"""`twin sitl`: the UDP loop that makes the twin ArduPilot SITL's physics backend.

ArduPilot sends a servo packet per frame and waits for the answer before its next
frame (SIM_JSON.cpp: output_servos, then a blocking recv_fdm), so in lock-step the
twin steps exactly once per frame and a session is deterministic at any SITL
speed-up. What the loop does with each datagram (twin.sitl.protocol has the bytes):

- not a servo packet (too short, too long, unknown magic, frame rate 0): ignored and
  counted by reason; the first of each kind is logged once;
- the frame just answered again (same frame_count): ArduPilot re-sends a frame when no
  answer came within about a second (SIM_JSON.cpp recv_fdm). The twin is never stepped
  twice. If the answer went out at least RESEND_AFTER_S before the copy arrived, it was
  lost, and it is sent again unchanged. If it went out just before, the copy crossed a
  late answer that ArduPilot is about to read: answering again would leave one answer
  too many in ArduPilot's socket, and since it reads one datagram per frame it would read
  every later answer one frame late; so the copy is counted (`crossed`) and not answered;
- frame_count lower than the last: ArduPilot restarted (the readme: "This count will be
  reset when SITL is re-started allowing the physics backend to reset the vehicle"): the
  twin is reset to the origin, at rest, clock 0 (ArduPilot takes a timestamp going
  backwards as a physics reset);
- frame_count jumping ahead: the missing frames are counted; the twin still steps once. A jump of
  more than MAX_GAP_S of frames at the frame's rate is no run of lost datagrams (in lock-step
  ArduPilot sends a frame only after the last answer, and re-sends it when none came): the count
  is taken from there as a new one, logged and counted apart (`count_jumps`), not as missed;
- a new frame_rate: the physics step follows (SitlTwin), logged.

`--realtime` instead paces the twin to the wall clock: a frame advances the twin by as
many frame periods as the wall clock has moved since the session started minus the
twin's time (at least one, and under ArduPilot's 0.1 s limit on one step, beyond which
the lost time is given up), and the answer waits until the wall clock reaches its
timestamp. Realtime sessions are not reproducible; lock-step ones are.

Stopping: SIGINT (Ctrl-C) and SIGTERM end a session cleanly, also when the process runs
in the background (a shell starts background jobs with SIGINT ignored): `run_sitl`, when
called from the main thread, installs handlers for both while it serves and restores the
previous ones after.

Recording (`record_paths`): every frame's state, PWM and thrust as a twin Run, written
with twin.outputs.write when the session ends, however it ends (frame limit, stop event,
SIGINT, SIGTERM, a diverged twin), each file atomically. The rows wait in an unnamed file in the
first recording's folder, not in memory (a session at 1200 frames a second records 4.3 million an
hour); each file is written a block of rows at a time.
"""
from __future__ import annotations

import contextlib
import errno
import math
import signal
import socket
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from threading import Event
from typing import Callable, Iterator, Sequence

from twin.errors import TwinError
from twin.files import link_target
from twin.outputs import FORMATS, write
from twin.physics.waves import Sea
from twin.sitl.backend import (DEFAULT_CHANNELS, ESC_ARM_S, SitlTwin, check_channels, check_esc_arm,
                               check_rate, sensor_amendments, with_environment)
from twin.sitl.protocol import (HEADER, MAGIC_16, PACKET_16, REASONS, PacketError, format_planar, format_six,
                                pair_reader, parse_servo_packet)
from twin.vessel import Vessel, load

Log = Callable[[str], None]
RECV_BYTES = 2048  # larger than any servo packet: a longer datagram is seen whole and refused
POLL_S = 0.1  # how often the watcher looks at the stop event (and the receive timeout outside the loop)
MAX_STEP_S = 0.09  # ArduPilot advances its clock only for timestamp steps under 0.1 s (SIM_JSON.cpp)
# ArduPilot re-sends after about 1 s without an answer: a copy arriving sooner after the answer went
# out was sent before the answer reached it (the answer was late, not lost)
RESEND_AFTER_S = 0.5
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
# a frame_count jumping further ahead than this many seconds of frames is a corrupt or foreign count, not
# datagrams lost: 0xffffffff after frame 1 would otherwise be reported as 4294967293 missed frames
MAX_GAP_S = 10.0


@dataclass
class Counters:
    """What a session did: frames stepped and answered, duplicates answered again (the answer was
    lost), duplicates not answered (they crossed a late answer), restarts, frames skipped by the
    frame counter, jumps of the frame counter too far ahead to be missed frames (MAX_GAP_S), frame
    rate changes, datagrams ignored by reason, and (real time only) wall-clock time given up because
    the twin fell too far behind."""

    frames: int = 0
    duplicates: int = 0
    crossed: int = 0
    restarts: int = 0
    missed: int = 0
    count_jumps: int = 0
    rate_changes: int = 0
    ignored: dict[str, int] = field(default_factory=lambda: dict.fromkeys(REASONS, 0))
    lag_dropped_s: float = 0.0

    def to_dict(self) -> dict:
        return {"frames": self.frames, "duplicates": self.duplicates, "crossed": self.crossed,
                "restarts": self.restarts,
                "missed": self.missed, "count_jumps": self.count_jumps, "rate_changes": self.rate_changes,
                "ignored": dict(self.ignored),
                "lag_dropped_s": self.lag_dropped_s}


@dataclass(frozen=True)
class SitlSummary:
    """How a `run_sitl` session ended: its counters, the twin's time over all ArduPilot sessions (s),
    the wall time (s), whether a signal ended it (and which: "SIGINT", "SIGTERM"), the files
    written, and the CPU time (s) the serving thread used while it answered frames."""

    counters: Counters
    physics_time_s: float
    wall_time_s: float
    interrupted: bool
    written: tuple[Path, ...]
    signal_name: str | None = None
    serve_cpu_s: float = 0.0

    def text(self) -> str:
        c = self.counters
        ignored = sum(c.ignored.values())
        why = ", ".join(f"{n} {reason}" for reason, n in c.ignored.items() if n)
        # told only when it happened: the usual line keeps its shape
        jumps = f"{c.count_jumps} frame_count jumps (taken as a new count, not as missed), " if c.count_jumps else ""
        return (f"{c.frames} frames, {self.physics_time_s:.2f} s of twin time in {self.wall_time_s:.2f} s; "
                f"{c.duplicates} duplicates answered, {c.crossed} not (crossed a late answer), "
                f"{c.missed} missed, {c.restarts} restarts, {jumps}"
                f"{c.rate_changes} frame rate changes, {ignored} datagrams ignored" + (f" ({why})" if why else "")
                + (f"; the twin's CPU {self.serve_cpu_s:.2f} s ({self.serve_cpu_s / c.frames * 1e6:.0f} µs a frame)"
                   if c.frames else ""))


def bind_udp(host: str, port: int) -> socket.socket:
    """The UDP socket the backend listens on; a port that is taken or not ours to use is a one-line
    TwinError. No SO_REUSEADDR: with it two backends could share the port and split the frames."""
    if not (isinstance(port, int) and 0 <= port <= 65535):
        raise TwinError(f"--port {port}: a UDP port number is 0..65535 (ArduPilot's JSON default is 9002)")
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.bind((host, port))
    except OSError as exc:
        sock.close()
        if exc.errno == errno.EADDRINUSE:
            raise TwinError(f"port {port} is in use (another SITL backend running?): choose --port") from None
        if exc.errno == errno.EACCES:
            raise TwinError(f"port {port}: permission denied (ports below 1024 need privileges): choose --port") \
                from None
        raise TwinError(f"cannot listen on {host}:{port} ({exc.strerror or exc}): check --host and --port") from None
    sock.settimeout(POLL_S)
    return sock


class SitlServer:
    """The frame loop over a bound socket and a twin (module docstring). `serve()` returns when
    `stop_after_frames` frames were stepped or `stop_event` is set; Ctrl-C raises through it."""

    def __init__(self, sock: socket.socket, twin: SitlTwin, *, realtime: bool = False, log: Log | None = None):
        self.sock = sock
        self.twin = twin
        self.realtime = realtime
        self.log = log or (lambda text: None)
        self.counters = Counters()
        self._last_count: int | None = None
        self._last_reply = b""
        self._sent_s = 0.0
        self._rate_hz: int | None = None
        self._peer = None
        self._wall0 = 0.0
        self._logged: set[str] = set()

    @property
    def address(self) -> tuple[str, int]:
        return self.sock.getsockname()

    def serve(self, stop_after_frames: int | None = None, stop_event: Event | None = None) -> Counters:
        """Answer frames until told to stop. The hot path is kept lean: one frame is one blocking
        receive, one unpack, one step, one formatted line, one send. A socket with a timeout would
        poll before every receive (a system call more per frame), so the receive blocks, and a
        watcher thread wakes it when `stop_event` is set (with an empty datagram to the socket)."""
        c = self.counters
        limit = math.inf if stop_after_frames is None else stop_after_frames
        if c.frames >= limit:
            return c
        halt = threading.Event()
        watcher = threading.Thread(target=self._watch, args=(stop_event, halt), daemon=True)
        watcher.start()
        self.sock.settimeout(None)
        try:
            self._loop(limit, halt)
        finally:
            halt.set()
            self.sock.settimeout(POLL_S)
            watcher.join()
        return c

    def _watch(self, stop_event: Event | None, halt: Event) -> None:
        """Until the loop ends: when stop_event is set, halt the loop and wake its receive."""
        while not halt.wait(POLL_S):
            if stop_event is not None and stop_event.is_set():
                halt.set()
                host, port = self.address[:2]
                with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as poke:
                    poke.sendto(b"", ("127.0.0.1" if host == "0.0.0.0" else host, port))
                return

    def _loop(self, limit: float, halt: Event) -> None:
        # what a frame touches, bound to locals once: the datagram lands in one preallocated buffer, the
        # usual packet (16 outputs) gives up only its header and the thrusters' two outputs, the twin is
        # stepped with those two, the reply is formatted by the template of its kind (planar or 6-DOF)
        recv_into, send = self.sock.recvfrom_into, self.sock.sendto
        buffer = bytearray(RECV_BYTES)
        twin = self.twin
        step, fmt = twin.step_pair, format_six if twin.six_dof else format_planar
        reader = pair_reader(*twin.channels)
        unpack, swapped = (reader[0].unpack_from, reader[1]) if reader else (None, False)
        size16 = PACKET_16.size
        outputs = (twin.channels[0] - 1, twin.channels[1] - 1)
        c = self.counters
        realtime = self.realtime
        clock = time.perf_counter
        last, last_reply, sent_s, frames = self._last_count, self._last_reply, self._sent_s, c.frames
        try:
            while True:  # the watcher halts the loop with an empty datagram, read below
                n, peer = recv_into(buffer)
                fields = unpack(buffer) if n == size16 and unpack is not None else None
                if fields is not None and fields[0] == MAGIC_16 and fields[1]:
                    _, rate, count, a, b = fields
                    if swapped:
                        a, b = b, a
                else:
                    if halt.is_set():  # the watcher's wake-up, not ArduPilot's
                        break
                    try:
                        rate, count, pwm = parse_servo_packet(bytes(buffer[:n]))
                    except PacketError as exc:
                        self._ignore(exc)
                        continue
                    a = pwm[outputs[0]] if outputs[0] < len(pwm) else 0
                    b = pwm[outputs[1]] if outputs[1] < len(pwm) else 0
                if last is None or count != last + 1:
                    if count == last:
                        if clock() - sent_s >= RESEND_AFTER_S:
                            c.duplicates += 1
                            send(last_reply, peer)
                        else:
                            c.crossed += 1
                        continue
                    self._last_count = last
                    self._irregular(count, rate, peer, (n - HEADER.size) // 2)
                if rate != self._rate_hz:
                    self._new_rate(rate)
                if realtime:
                    reply = step(a, b, rate, self._frames_due(rate))
                    self._wait_for(reply.timestamp_s)
                else:
                    reply = step(a, b, rate)
                last_reply = fmt(reply)
                send(last_reply, peer)
                sent_s = clock()
                last = count
                frames += 1
                if frames >= limit:
                    break
        finally:
            self._last_count, self._last_reply, self._sent_s, c.frames = last, last_reply, sent_s, frames

    # ------------------------------------------------------------ the rare cases, off the hot path

    def _ignore(self, exc: PacketError) -> None:
        self.counters.ignored[exc.reason] += 1
        if exc.reason not in self._logged:
            self._logged.add(exc.reason)
            self.log(f"ignoring datagrams that are not servo packets ({exc}); counted in the summary")

    def _irregular(self, count: int, rate: int, peer, n_outputs: int) -> None:
        """A first frame, a restart (frame_count went back), skipped frames, or a count jumping too far
        ahead to be skipped frames (more than MAX_GAP_S of them at the frame's rate)."""
        last = self._last_count
        if last is None:
            self._connected(peer, n_outputs)
        elif count < last:
            self.counters.restarts += 1
            self.twin.reset()
            self._wall0 = time.perf_counter()
            self._rate_hz = None
            self.log(f"ArduPilot restarted (frame_count {last} → {count}): twin reset to the origin, at rest")
        elif count - last - 1 > MAX_GAP_S * rate:
            self.counters.count_jumps += 1
            self.log(f"frame_count jumped {last} → {count}, more than {MAX_GAP_S:g} s of frames at {rate} Hz: "
                     "taken as a new count, not as missed frames")
        else:
            self.counters.missed += count - last - 1
        if peer != self._peer and last is not None:
            self._connected(peer, n_outputs)

    def _connected(self, peer, n_outputs: int) -> None:
        self._peer = peer
        self._wall0 = time.perf_counter() - self.twin.time_s
        self.log(f"ArduPilot connected from {peer[0]}:{peer[1]} ({n_outputs} servo outputs)")
        missing = [c for c in self.twin.channels if c > n_outputs]
        if missing:  # a thruster on an output the frames do not carry would sit at neutral all session
            several = len(missing) > 1
            self.log(f"warning: --channels {self.twin.channels[0]},{self.twin.channels[1]}: ArduPilot sends "
                     f"{n_outputs} servo outputs, so output{'s' if several else ''} "
                     f"{' and '.join(map(str, missing))} never arrive{'' if several else 's'} and "
                     f"{'their thrusters stay' if several else 'its thruster stays'} at neutral (give outputs it "
                     "sends, and the same in its SERVOn_FUNCTION)")

    def _new_rate(self, rate: int) -> None:
        if self._rate_hz is not None:
            self.counters.rate_changes += 1
        frame_s = 1.0 / rate
        substeps = max(1, math.ceil(frame_s * self.twin.min_rate_hz - 1e-9))
        self.log(f"frames at {rate} Hz: physics step {frame_s / substeps * 1e3:.4g} ms, {substeps} per frame")
        self._rate_hz = rate

    def _frames_due(self, rate: int) -> int:
        """Real time: the frame periods the wall clock is ahead of the twin, at least one. More than
        ArduPilot accepts in one step is given up (counted), not caught up in a burst."""
        frame_s = 1.0 / rate
        behind_s = time.perf_counter() - self._wall0 - self.twin.time_s
        n = max(1, int(behind_s / frame_s))
        cap = max(1, int(MAX_STEP_S / frame_s))
        if n > cap:
            self._wall0 += (n - cap) * frame_s
            self.counters.lag_dropped_s += (n - cap) * frame_s
            n = cap
        return n

    def _wait_for(self, timestamp_s: float) -> None:
        """Real time: hold the answer until the wall clock reaches the twin's time."""
        wait_s = self._wall0 + timestamp_s - time.perf_counter()
        if wait_s > 0:
            time.sleep(wait_s)


def run_sitl(
    vessel: Vessel | str,
    *,
    port: int = 9002,
    rate_hz: float = 400.0,
    record_paths: Sequence[str | Path] = (),
    realtime: bool = False,
    channels: tuple[int, int] = DEFAULT_CHANNELS,
    current: tuple[float, float] | None = None,
    wind: tuple[float, float] | None = None,
    log: Log | None = None,
    stop_after_frames: int | None = None,
    stop_event: Event | None = None,
    host: str = "127.0.0.1",
    heading_deg: float = 0.0,
    origin: tuple[float, float] | None = None,
    ready: Callable[[tuple[str, int]], None] | None = None,
    esc_arm_s: float = ESC_ARM_S,
    sea: Sea | None = None,
) -> SitlSummary:
    """Serve ArduPilot SITL's JSON interface with the vessel's twin until stopped (module docstring).

    vessel: a Vessel, a shipped vessel's name or a vessel file. port: UDP port (0: any free one,
    reported through `ready`). rate_hz: the least physics rate (Hz); frames are split into equal
    steps no longer than 1/rate_hz. channels: the servo outputs (1-based) of the left and right
    thrusters (SERVOn_FUNCTION 73/74). current / wind: (speed m/s, direction deg) in place of the
    vessel file's (current flowing towards, wind blowing from). heading_deg: the initial heading.
    origin: (lat, lon) deg of the twin's origin for the map positions of .mcap/.tlog/.bin
    recordings (set it to SITL's home). ready: called with the bound (host, port) once frames
    are answered. esc_arm_s: how long each ESC must see its stopped signal before it drives its
    thruster (twin.sitl.backend; 0: from the first frame). sea (physics.waves.Sea): the 6-DOF hull
    in that sea, heaving, rolling and pitching (twin.sitl.backend, "In a seaway"). SIGINT and SIGTERM
    end the session normally (`interrupted`, `signal_name`); what was recorded is written.
    """
    log = log or (lambda text: None)
    paths = check_record_paths(record_paths)
    check_channels(channels)
    check_esc_arm(esc_arm_s)
    check_rate(rate_hz)
    if stop_after_frames is not None and stop_after_frames < 0:
        raise TwinError("stop_after_frames must be ≥ 0")
    v = load(vessel) if isinstance(vessel, str) else vessel
    v = with_environment(v, current, wind)
    sock = bind_udp(host, port)  # first: a port in use fails before the twin is built
    started = time.perf_counter()
    stop = stop_event or threading.Event()
    caught: list[str] = []
    twin = server = None
    written: tuple[Path, ...] = ()
    cpu_s = 0.0
    # the handlers stay while the recordings are written: a second Ctrl-C does not cut the writing short
    with _stopped_by_signals(stop, caught):
        try:
            twin = SitlTwin(v, min_rate_hz=rate_hz, channels=channels, heading_deg=heading_deg,
                            record=bool(paths), esc_arm_s=esc_arm_s, sea=sea,
                            spool_dir=link_target(paths[0]).parent if paths else None)
            with twin.active():
                twin.warm_up()
                server = SitlServer(sock, twin, realtime=realtime, log=log)
                _announce(server, v, log)
                if ready is not None:
                    ready(server.address)
                cpu0 = time.thread_time()
                try:
                    server.serve(stop_after_frames, stop)
                except KeyboardInterrupt:  # SIGINT with Python's own handler (run_sitl off the main thread)
                    caught.append("SIGINT")
                cpu_s = time.thread_time() - cpu0
                if caught:
                    log(f"{caught[0]}: ending the session")
        finally:
            sock.close()
            if server is not None and paths:  # the session began: write what it did, however it ends
                written = write_recording(twin, paths, origin, log)
    summary = SitlSummary(server.counters, twin.total_time_s, time.perf_counter() - started,
                          bool(caught), written, caught[0] if caught else None, cpu_s)
    return summary  # not logged: the caller shows it once (the CLI on stdout)


@contextlib.contextmanager
def _stopped_by_signals(stop: Event, caught: list[str]) -> Iterator[None]:
    """SIGINT and SIGTERM set `stop` (and name themselves in `caught`) while the block runs, whatever
    their handlers were before (a background job starts with SIGINT ignored, SIGTERM would kill the
    process before it writes its recordings). Only the main thread can install handlers: elsewhere
    the block runs with the handlers as they are."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, _frame):
        caught.append(signal.Signals(signum).name)
        stop.set()

    previous = {s: signal.signal(s, handler) for s in STOP_SIGNALS}
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


def _announce(server: SitlServer, vessel: Vessel, log: Log) -> None:
    host, port = server.address
    twin = server.twin
    mode = "real time" if server.realtime else "lock-step"
    env = vessel.environment
    log(f"twin sitl: {vessel.name} on udp {host}:{port}, {mode}, thrusters on servo outputs "
        f"{twin.channels[0]} (left) and {twin.channels[1]} (right), physics ≥ {twin.min_rate_hz:g} Hz; "
        f"current {env.current_speed_m_s:g} m/s towards {env.current_dir_deg:g}°, "
        f"wind {env.wind_speed_m_s:g} m/s from {env.wind_dir_deg:g}°"
        + (f"; 6-DOF hull in {twin.sea.text()}" if twin.six_dof else ""))
    log("waiting for ArduPilot's first servo packet (sim_vehicle.py -v Rover --model JSON, or ardurover "
        "--model JSON:HOST); Ctrl-C ends the run")
    amended = sensor_amendments(vessel)
    if amended:
        log(f"note: the vessel file's sensor calibration ({', '.join(amended)}) is not applied: "
            "SITL simulates its own sensors (set SIM_MAG_*, SIM_GPS*_POS_* for that)")


def check_record_paths(paths: Sequence[str | Path]) -> tuple[Path, ...]:
    """Refuse, before listening, a recording path with an unknown extension or a missing folder."""
    out = []
    for p in paths:
        p = Path(p)
        if p.suffix.lower() not in FORMATS:
            raise TwinError(f"--record '{p}': unknown format '{p.suffix or '(none)'}' (use {', '.join(FORMATS)})")
        if not p.parent.is_dir():
            raise TwinError(f"--record '{p}': folder '{p.parent}' does not exist (create it first)")
        if p.is_dir():
            raise TwinError(f"--record '{p}' is a folder: give a file name")
        out.append(p)
    return tuple(out)


def write_recording(twin: SitlTwin, paths: Sequence[Path], origin: tuple[float, float] | None,
                    log: Log) -> tuple[Path, ...]:
    """The session as a twin Run to each path (outputs.write: atomic, format by extension)."""
    if twin.frames_recorded == 0:
        log("nothing recorded: no frame came from ArduPilot")
        return ()
    run = twin.recording()
    v = twin.vessel
    for path in paths:
        write({"sitl": run}, path, geometry=twin.compiled.geometry, vessel_name=v.name, mjcf=v.mjcf, origin=origin)
        # an autopilot log keeps what its sensors would have logged (formats/telemetry.py), not every state
        kept = ("as an ArduPilot boat's sensors log them: GNSS every 200 ms, heading every 20 ms, PWM every 100 ms"
                if Path(path).suffix.lower() in (".tlog", ".bin") else "one per physics step")
        log(f"wrote {path} (the run's {len(run.t)} twin states, {kept}; {run.t[-1] - run.t[0]:.2f} s)")
    return tuple(paths)
