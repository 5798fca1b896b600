"""The twin's standard manoeuvres, from a steady straight approach in calm water: the turning circle to
each side, a zig-zag and a crash stop, with the measures of full-scale manoeuvring trials [IMO-MSC137],
in metres and in lengths L:

- turning circle: the turning command held from the execute; advance and transfer where the heading
  has changed 90°, the tactical diameter where it has changed 180°, and the steady turn (its diameter
  2U/|r|, speed, rate and drift angle) once the heading has changed 360°;
- zig-zag: the yaw command reversed each time the heading passes the switch angle from the approach
  heading; the first and second overshoot angles (how far the heading runs past the switch angle after
  the first and second reversal) and the time to the first reversal;
- crash stop: full astern from the approach; the track reach (the path run until the surge speed is
  zero), the head reach (along the approach heading), the lateral deviation and the time it takes.

Positions are those of the body origin (the MJCF's CO), where the standards take the midship point.

A command is the twin's normalised (surge, yaw) pair, as `twin simulate`'s scenarios give it: a
propeller and rudder's n = surge·rps_max and δ = yaw·rudder_max; a twin-thruster boat's per-thruster
command surge ± yaw, each held within full ahead and astern (full yaw at half throttle puts one
thruster full ahead and the other at half astern). The approach starts at the straight run's speed
(`analytic.straight_run`) and runs APPROACH_S before the execute, so a thrust lag has settled. A
course-unstable twin would turn on its own during the approach; nothing holds it straight, and
its straight run says so (`stable`).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from ..analytic import StraightRun, straight_run, straight_speed
from ..drive import to_thruster_inputs
from ..engine.mjcf import CompiledVessel, compile_vessel
from ..engine.sim import simulate
from ..errors import TwinError
from ..fit.uncertainty import draw
from ..fit.windows import Window, predict
from ..physics.environment import Environment
from ..run import Run
from ..vessel import Vessel

APPROACH_S = 10.0
TURN_TO_DEG = 400.0  # a steady turn is read after 360° (its mean from there to the run's end): run past it
LONGEST_S = 1800.0  # a turn that never gets round (too little yaw for the speed) stops here


@dataclass(frozen=True)
class TurningCircle:
    """One turning circle (side +1 to starboard, −1 to port). Lengths in m, transfer + to starboard
    of the approach track, rate + to starboard; the drift angle atan2(−v, u) in ° (+: the bow to
    starboard of the track, inside a starboard turn's circle). None where the heading never changed
    that much within LONGEST_S."""

    side: int
    advance_m: float | None
    transfer_m: float | None
    tactical_diameter_m: float | None
    steady_diameter_m: float | None
    steady_speed_m_s: float | None
    steady_rate_deg_s: float | None
    drift_deg: float | None


@dataclass(frozen=True)
class ZigZagTest:
    """A zig-zag of yaw command `yaw` (normalised; a ship's rudder angle δ = yaw·rudder_max) switched at
    `switch_deg` from the approach heading. Angles in °, times in s; None where not reached."""

    yaw: float
    switch_deg: float
    first_overshoot_deg: float | None
    second_overshoot_deg: float | None
    time_to_first_switch_s: float | None


@dataclass(frozen=True)
class CrashStop:
    """Full astern from the approach until the surge speed is zero (None: it never stopped)."""

    track_reach_m: float | None
    head_reach_m: float | None
    lateral_m: float | None
    time_s: float | None


@dataclass(frozen=True)
class Manoeuvres:
    """The standard manoeuvres of one twin at one approach command.

    Attributes:
        vessel: the vessel's name.
        length_m: L, the ship's Lpp or, for a boat, its hull meshes' length overall (m).
        surge: the approach command (normalised).
        turn_yaw: the turning circles' yaw command (normalised).
        approach_speed_m_s: the surge speed at the execute (m/s).
        straight: the straight run's course stability at the approach thrust (None: a ship without
            rps_max).
        turns: the turning circles to starboard and to port, at the full turning command.
        zigzag: the zig-zag.
        crash_stop: the crash stop (None where the vessel has no astern: thrust bounds of zero).
        inputs: what the approach, the starboard turn and the zig-zag's first leg ask of the vessel:
            each (kind, (left, right)) as `drive.to_thruster_inputs` gives it ("pwm" µs, "thrust" N,
            or "propeller_rudder" n rps and δ rad).
    """

    vessel: str
    length_m: float
    surge: float
    turn_yaw: float
    approach_speed_m_s: float
    straight: StraightRun | None
    turns: tuple[TurningCircle, TurningCircle]
    zigzag: ZigZagTest
    crash_stop: CrashStop | None
    inputs: dict[str, tuple[str, tuple[float, float]]]


def manoeuvres(vessel: Vessel, surge: float = 0.5, turn_yaw: float = 1.0, zigzag_yaw: float | None = None,
               zigzag_switch_deg: float = 10.0) -> Manoeuvres:
    """The turning circles, zig-zag and crash stop of the twin in calm water.

    Args:
        vessel: the twin (its current and wind are removed: calm water).
        surge: the approach command, (0, 1] of full ahead (normalised, as the scenarios give it).
        turn_yaw: the turning circles' yaw command (0, 1] (default 1: full rudder, or full differential).
        zigzag_yaw: the zig-zag's yaw command (0, 1]; default a ship's 10° of rudder, a boat's 0.2.
        zigzag_switch_deg: the heading change (°) at which the zig-zag reverses (default 10).

    Returns:
        The Manoeuvres, lengths in m and angles in °.

    Raises:
        TwinError: a command outside (0, 1], a switch angle outside (0, 90), or a vessel that does not
            get under way at the approach command.
    """
    for what, command in (("approach (surge)", surge), ("turning yaw", turn_yaw), ("zig-zag yaw", zigzag_yaw)):
        if (command is not None or what != "zig-zag yaw") and not (_number(command) and 0 < command <= 1):
            raise TwinError(f"the {what} command lies in (0, 1] of full, got {command!r}")
    if not (_number(zigzag_switch_deg) and 0 < zigzag_switch_deg < 90):
        raise TwinError(f"the zig-zag's switch angle lies between 0 and 90°, got {zigzag_switch_deg!r}")
    calm = vessel.with_environment(Environment())
    compiled = compile_vessel(calm)
    ship = calm.thrusters.kind == "propeller_rudder"
    if zigzag_yaw is None:
        zigzag_yaw = min(1.0, 10.0 / calm.thrusters.rudder_max_deg) if ship and calm.thrusters.rudder_max_deg else 0.2
    u0, straight = _approach(compiled, surge)
    if not u0 > 0:
        raise TwinError(f"vessel '{vessel.name}' does not get under way at an approach command of {surge:g}")
    length_m = _length_m(compiled)
    (starboard, u_execute), (port, _) = (_turning_circle(compiled, surge, side * turn_yaw, u0, length_m)
                                         for side in (1, -1))
    inputs = {name: _as_tuple(to_thruster_inputs(calm.thrusters, surge, yaw))
              for name, yaw in (("approach", 0.0), ("turn", turn_yaw), ("zigzag", zigzag_yaw))}
    return Manoeuvres(vessel.name, length_m, surge, turn_yaw, u_execute, straight, (starboard, port),
                      _zigzag(compiled, surge, zigzag_yaw, zigzag_switch_deg, u0, length_m),
                      _crash_stop(compiled, surge, u0, length_m), inputs)


def _as_tuple(kind_values) -> tuple[str, tuple[float, float]]:
    kind, values = kind_values
    return kind, (float(values[0]), float(values[1]))


def _number(x) -> bool:
    """A real number (not a bool, a text or NaN)."""
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool) and bool(np.isfinite(x))


def _approach(compiled: CompiledVessel, surge: float) -> tuple[float, StraightRun | None]:
    """The straight run's speed (m/s) at the approach command, and its course stability."""
    t = compiled.vessel.thrusters
    kind, held = to_thruster_inputs(t, surge, 0.0)
    if kind == "propeller_rudder":
        return straight_speed(compiled, float(held[0])), straight_run(compiled, surge)
    raw = t.thrust_from_pwm(held) if kind == "pwm" else held
    run = straight_run(compiled, static_n=t.gains() * np.asarray(raw, float))
    return run.speed_m_s, run


def _length_m(compiled: CompiledVessel) -> float:
    """L: a ship's Lpp, else the length overall of the hull meshes (of every geom without meshes)."""
    mmg = compiled.vessel.mmg
    if mmg is not None and mmg.lpp_m > 0:
        return float(mmg.lpp_m)
    model = compiled.model
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    meshes = np.flatnonzero(model.geom_type == mujoco.mjtGeom.mjGEOM_MESH)
    xs = []
    for g in meshes if len(meshes) else np.flatnonzero(model.geom_bodyid > 0):
        centre, half = data.geom_xpos[g], model.geom_rbound[g]
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH:
            mid = model.geom_dataid[g]
            v0, nv = model.mesh_vertadr[mid], model.mesh_vertnum[mid]
            x = (model.mesh_vert[v0:v0 + nv] @ data.geom_xmat[g].reshape(3, 3).T + centre)[:, 0]
            xs += [float(x.min()), float(x.max())]
        else:
            xs += [float(centre[0] - half), float(centre[0] + half)]
    return max(xs) - min(xs)


def _run(compiled: CompiledVessel, controller, duration_s: float, u0: float) -> Run:
    """A run from the straight approach at u0; the controller sees the time since the execute."""
    return simulate(compiled, lambda t, eta, nu: controller(t - APPROACH_S, eta, nu), APPROACH_S + duration_s,
                    nu0=np.array([u0, 0.0, 0.0]), sample_dt_s=0.1)


def _after_execute(run: Run) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(t s, x m along the approach heading, y m to its starboard, heading change rad) from the execute."""
    i0 = int(np.searchsorted(run.t, run.t[0] + APPROACH_S - 1e-9))
    return in_execute_frame(run.t[i0:], run.eta[i0:, 0], run.eta[i0:, 1], run.eta[i0:, 2])


def in_execute_frame(t_s, north_m, east_m, psi_rad) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A track from its first sample (the execute) in that sample's heading frame: (t s from the
    execute, x m along the heading then, y m to its starboard, heading change rad, unwrapped)."""
    psi = np.unwrap(np.asarray(psi_rad, float))
    c, s = np.cos(psi[0]), np.sin(psi[0])
    dn, de = np.asarray(north_m, float) - north_m[0], np.asarray(east_m, float) - east_m[0]
    return np.asarray(t_s, float) - t_s[0], c * dn + s * de, -s * dn + c * de, psi - psi[0]


def turning_measures(t_s, north_m, east_m, psi_rad, nu, side: int) -> TurningCircle:
    """A turning circle's measures read from a track that starts at its execute: a twin's run, or a
    recorded turning test (its midship or body-origin track, heading and body velocities).

    Args:
        t_s, north_m, east_m, psi_rad: the track from the execute (s, m, m, rad).
        nu: (n, 3) u, v (m/s) and r (rad/s) at the same samples.
        side: +1 for a turn to starboard, −1 to port.

    Returns:
        The TurningCircle: advance and transfer at 90° of heading change, the tactical diameter at
        180°, the steady turn (2U/|r|, U, r, drift angle) as the mean after 360°; None where the
        heading never turned that far.
    """
    _, x, y, heading = in_execute_frame(t_s, north_m, east_m, psi_rad)
    turned = side * heading
    at90, at180, at360 = (_first(turned >= np.radians(a)) for a in (90.0, 180.0, 360.0))
    advance, transfer = _crossing(turned, np.radians(90.0), at90, x), _crossing(turned, np.radians(90.0), at90, y)
    tactical = _crossing(turned, np.radians(180.0), at180, y)
    steady = dict(steady_diameter_m=None, steady_speed_m_s=None, steady_rate_deg_s=None, drift_deg=None)
    if at360 is not None:
        u, v, r = (float(np.mean(np.asarray(nu, float)[at360:, k])) for k in range(3))
        speed = float(np.hypot(u, v))
        steady = dict(steady_diameter_m=2.0 * speed / abs(r), steady_speed_m_s=speed,
                      steady_rate_deg_s=float(np.degrees(r)), drift_deg=float(np.degrees(np.arctan2(-v, u))))
    return TurningCircle(side, advance, transfer, None if tactical is None else abs(tactical), **steady)


def _crossing(turned: np.ndarray, angle_rad: float, at: int | None, series: np.ndarray) -> float | None:
    """`series` where the heading change `turned` crosses `angle_rad`, linear between the samples
    about the first sample `at` past it (None: never crossed)."""
    if at is None:
        return None
    if at == 0:
        return float(series[0])
    share = (angle_rad - turned[at - 1]) / (turned[at] - turned[at - 1])
    return float(series[at - 1] + share * (series[at] - series[at - 1]))


def _first(mask: np.ndarray) -> int | None:
    hits = np.flatnonzero(mask)
    return int(hits[0]) if len(hits) else None


def _turning_circle(compiled: CompiledVessel, surge: float, yaw: float, u0: float,
                    length_m: float) -> tuple[TurningCircle, float]:
    """The turning circle under yaw command `yaw` (> 0 to starboard), and the surge speed (m/s) at its
    execute."""
    side = 1 if yaw > 0 else -1
    # long enough for 400° at a tenth of the approach speed round a circle of 5 L, within LONGEST_S
    duration_s = min(LONGEST_S, TURN_TO_DEG / 360.0 * np.pi * 5.0 * length_m / (0.1 * u0))
    run = _run(compiled, lambda t, eta, nu: (surge, yaw if t >= 0 else 0.0), duration_s, u0)
    i0 = int(np.searchsorted(run.t, run.t[0] + APPROACH_S - 1e-9))
    circle = turning_measures(run.t[i0:], run.eta[i0:, 0], run.eta[i0:, 1], run.eta[i0:, 2], run.nu[i0:], side)
    return circle, float(run.nu[i0, 0])


def _zigzag(compiled: CompiledVessel, surge: float, yaw: float, switch_deg: float, u0: float,
            length_m: float) -> ZigZagTest:
    """The zig-zag: the yaw command reversed each time the heading passes ±switch_deg from the heading at
    the execute (the controller's own reversals, read back from the track at the same samples)."""
    state = {"sign": 1.0}

    def controller(t, eta, nu):
        if t < 0:
            return surge, 0.0
        if "psi0" not in state:
            state["psi0"] = float(eta[2])
        if state["sign"] * np.degrees(eta[2] - state["psi0"]) >= switch_deg:
            state["sign"] = -state["sign"]
        return surge, state["sign"] * yaw

    duration_s = min(LONGEST_S, 40.0 * length_m / u0)
    run = _run(compiled, controller, duration_s, u0)
    t, _, _, heading = _after_execute(run)
    change_deg = np.degrees(heading)
    switches = _switch_indices(change_deg, switch_deg)
    overshoots = []
    for k, i in enumerate(switches[:2]):
        end = switches[k + 1] if k + 1 < len(switches) else None
        if end is None:
            break
        sign = 1.0 if k % 2 == 0 else -1.0
        overshoots.append(float(np.max(sign * change_deg[i:end]) - switch_deg))
    overshoots += [None] * (2 - len(overshoots))
    return ZigZagTest(yaw, switch_deg, overshoots[0], overshoots[1],
                      float(t[switches[0]]) if switches else None)


def _switch_indices(change_deg: np.ndarray, switch_deg: float) -> list[int]:
    """Where the heading first passes +switch, then −switch, then + … (the reversals), in samples."""
    out, sign, i = [], 1.0, 0
    while True:
        hit = _first(sign * change_deg[i:] >= switch_deg)
        if hit is None:
            return out
        i += hit
        out.append(i)
        sign = -sign


def _crash_stop(compiled: CompiledVessel, surge: float, u0: float, length_m: float) -> CrashStop | None:
    """Full astern from the approach, the stop where the surge speed first reaches zero (None: a vessel
    with no astern thrust)."""
    t_min = compiled.vessel.thrusters.bounds()[0]
    if compiled.vessel.thrusters.kind != "propeller_rudder" and not t_min < 0:
        return None
    duration_s = min(LONGEST_S, 40.0 * length_m / u0)
    run = _run(compiled, lambda t, eta, nu: (surge if t < 0 else -1.0, 0.0), duration_s, u0)
    t, x, y, _ = _after_execute(run)
    i0 = len(run.t) - len(x)
    u = run.nu[i0:, 0]
    stop = _first(u <= 0.0)
    if stop is None:
        return CrashStop(None, None, None, None)
    # the stop lies between two samples: where u, linear between them, is zero
    share = u[stop - 1] / (u[stop - 1] - u[stop]) if stop > 0 else 0.0
    path = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(x), np.diff(y)))])

    def at(series):
        return float(series[stop - 1] + share * (series[stop] - series[stop - 1])) if stop > 0 else float(series[0])

    return CrashStop(at(path), at(x), at(y), at(t))


@dataclass(frozen=True)
class MeasureBand:
    """One measure over the draws of an identified twin's parameters: its `level` central range
    (None where fewer than half the draws reached it) and the share of draws that reached it."""

    name: str
    low: float | None
    high: float | None
    reached: float


@dataclass(frozen=True)
class ManoeuvreBands:
    """The measures' ranges over draws of an identified twin's parameters (parameters only: the form
    error a recording shows is not in them).

    Attributes:
        bands: one MeasureBand per measure (`manoeuvre_measures` names).
        draws: the draws asked for; `redrawn` of them were unphysical (the vessel checks refuse them,
            e.g. a non-dissipative damping) and drawn again, which narrows and shifts the band
            toward the accepted region; `diverged` ran unstably (a thrust lag far below the physics
            step) and are left out.
        level: the central share each range holds.
    """

    bands: list[MeasureBand]
    draws: int
    redrawn: int
    diverged: int
    level: float


def manoeuvre_bands(vessel: Vessel, draws: int, seed: int = 0, level: float = 0.9, **options) -> ManoeuvreBands:
    """The measures of `manoeuvres` over `draws` twins drawn from the vessel's uncertainty block (an
    identified twin's): each measure's central `level` range. Parameters only: the form error a
    recording shows is not in it.

    Args:
        vessel: an identified twin (a vessel file with an uncertainty block).
        draws: how many twins to draw (≥ 2).
        seed: the draws' random seed (≥ 0).
        level: the central share each range holds (default 0.9).
        **options: manoeuvres' own (surge, turn_yaw, zigzag_yaw, zigzag_switch_deg).

    Returns:
        The ManoeuvreBands.

    Raises:
        TwinError: fewer than 2 draws, a negative seed, a vessel without an uncertainty block, or more
            than half the draws diverging.
    """
    if not (_number(draws) and int(draws) == draws and draws >= 2):
        raise TwinError(f"a band needs a whole number of at least 2 draws, got {draws!r}")
    if not (_number(seed) and int(seed) == seed and seed >= 0):
        raise TwinError(f"the draws' seed is a whole number ≥ 0, got {seed!r}")
    twins, redrawn = draw(vessel, int(draws), np.random.default_rng(int(seed)))
    values, diverged = [], 0
    for t in twins:
        try:
            values.append(manoeuvre_measures(manoeuvres(t, **options)))
        except TwinError as exc:
            if "diverged" not in str(exc):
                raise
            diverged += 1
    if len(values) < 0.5 * draws:
        raise TwinError(f"{diverged} of {draws} drawn twins diverged: its uncertainty spans unstable twins (a "
                        "thrust lag far below the physics step); no band")
    bands = []
    for name in values[0]:
        got = np.array([v[name] for v in values if v[name] is not None], float)
        enough = len(got) >= 0.5 * len(values)
        q = np.quantile(got, [(1 - level) / 2, (1 + level) / 2]) if enough else (None, None)
        bands.append(MeasureBand(name, None if q[0] is None else float(q[0]), None if q[1] is None else float(q[1]),
                                 len(got) / len(values)))
    return ManoeuvreBands(bands, int(draws), redrawn, diverged, level)


def manoeuvre_measures(m: Manoeuvres) -> dict[str, float | None]:
    """Every measure of the manoeuvres by one name each (turn_starboard.advance_m, zigzag.first_overshoot_deg,
    crash_stop.track_reach_m, …)."""
    out = {}
    for circle in m.turns:
        side = "starboard" if circle.side > 0 else "port"
        out |= {f"turn_{side}.{k}": v for k, v in circle.__dict__.items() if k != "side"}
    out |= {f"zigzag.{k}": v for k, v in m.zigzag.__dict__.items() if k not in ("yaw", "switch_deg")}
    if m.crash_stop is not None:
        out |= {f"crash_stop.{k}": v for k, v in m.crash_stop.__dict__.items()}
    return out


# a held input: PWM within this of the stretch's first sample (an RC log's jitter is a few µs), or the
# propeller within HELD_RPS and the rudder within HELD_RUDDER_DEG; a turn: the rudder off amidships by
# TURNING_RUDDER_DEG or the two PWMs apart by TURNING_PWM_US, the heading turning TURNED_DEG over it
HELD_PWM_US, HELD_RPS, HELD_RUDDER_DEG = 10.0, 0.3, 1.0
TURNING_PWM_US, TURNING_RUDDER_DEG, TURNED_DEG = 20.0, 5.0, 90.0


@dataclass(frozen=True)
class RecordedTurn:
    """A turn a recording holds, measured from the log and from the twin's free run of it.

    Attributes:
        log: the recording's name.
        start_s: the execute (s, the recording's clock): the first sample of the held inputs.
        held_s: how long the inputs hold (s).
        inputs: the held pair at the execute: (kind, (left, right)), PWM µs or n rps and δ rad.
        speed_m_s: the measured surge speed at the execute (m/s).
        measured: the TurningCircle read from the prepared recording.
        predicted: the TurningCircle of the twin's free run from the measured state at the execute,
            driven by the logged inputs (None: the run diverged).
    """

    log: str
    start_s: float
    held_s: float
    inputs: tuple[str, tuple[float, float]]
    speed_m_s: float
    measured: TurningCircle
    predicted: TurningCircle | None


def held_turns(prep, turned_deg: float = TURNED_DEG) -> list[tuple[int, int]]:
    """(first, last) grid samples of each stretch, within one segment, over which the inputs hold
    (HELD_PWM_US, or HELD_RPS and HELD_RUDDER_DEG), asking for a turn (TURNING_PWM_US apart, or the
    rudder TURNING_RUDDER_DEG off amidships), while the heading turns `turned_deg` or more."""
    x = np.asarray(prep.pwm, float)
    ship = prep.input_kind == "propeller_rudder"
    tol = np.array([HELD_RPS, np.radians(HELD_RUDDER_DEG)] if ship else [HELD_PWM_US, HELD_PWM_US])
    out, i, n = [], 0, len(prep.t)
    while i < n:
        j = i
        while j + 1 < n and prep.segment[j + 1] == prep.segment[i] and np.all(np.abs(x[j + 1] - x[i]) < tol):
            j += 1
        turning = (abs(x[i, 1]) >= np.radians(TURNING_RUDDER_DEG) if ship
                   else abs(x[i, 0] - x[i, 1]) >= TURNING_PWM_US)
        if turning and np.all(np.isfinite(x[i])) and abs(prep.psi[j] - prep.psi[i]) >= np.radians(turned_deg):
            out.append((i, j))
        i = j + 1
    return out


def recorded_turns(vessel: Vessel, preps: list, wind: str | None = None,
                   turned_deg: float = TURNED_DEG) -> list[RecordedTurn]:
    """Every held turn of the prepared recordings (`held_turns`), measured from the log and from the
    twin's free run of it: from the measured state at the execute, never corrected, driven by the
    logged inputs as `twin evaluate` drives its free runs (fit.windows.predict).

    Args:
        vessel: the twin, calibrated to the recordings (ident.identify.calibrate).
        preps: the recordings prepared for it (ident.identify.prepared).
        wind: None, or "measured": each recording's measured wind a known input.
        turned_deg: how far the heading must turn over a held stretch for it to count (°).

    Returns:
        One RecordedTurn per held turn, in the recordings' order.
    """
    out = []
    for prep in preps:
        for i0, i1 in held_turns(prep, turned_deg):
            side = 1 if prep.psi[i1] > prep.psi[i0] else -1
            nu = np.column_stack([prep.u, prep.v, prep.r])
            measured = turning_measures(prep.t[i0:i1 + 1], prep.north[i0:i1 + 1], prep.east[i0:i1 + 1],
                                        prep.psi[i0:i1 + 1], nu[i0:i1 + 1], side)
            run = predict(vessel, [prep], [Window(0, i0, i1 - i0)], wind=wind)[0]
            predicted = None if run.diverged else turning_measures(
                prep.t[i0:i1 + 1], run.eta[0, :, 0], run.eta[0, :, 1], run.eta[0, :, 2], run.nu[0], side)
            held = (prep.input_kind, (float(prep.pwm[i0, 0]), float(prep.pwm[i0, 1])))
            out.append(RecordedTurn(Path(prep.settings.source).name, float(prep.t[i0]),
                                    float(prep.t[i1] - prep.t[i0]), held, float(prep.u[i0]), measured, predicted))
    return out
