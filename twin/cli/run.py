"""`twin simulate`, `twin crosscheck`, `twin params`, `twin validate`: the twin itself."""
from __future__ import annotations

import json
import math
from dataclasses import asdict
import textwrap
from pathlib import Path
from typing import Optional

import numpy as np
import typer
from rich.table import Table

from ..drive import read_inputs_csv
from ..effects.coefficients import DAMPING_UNITS
from ..errors import TwinError
from ..files import after_writes, write_text_atomic
from ..files import RUNS, check_new
from ..physics.seakeeping import known_table
from ..physics.waves import parse_sea
from ..vessel import save as save_vessel
from ..viz.report import report_figure, top_view_png, write_report
from .app import (REPORT_HELP, all_or_nothing_outputs, CASE_HELP, FORCE_HELP, MODEL_HELP, VESSEL_HELP, app, check_distinct, check_outputs,
                  memory_for, note, positive, print_table, progress_bar, samples_fit, say, seed_from, speed_direction, vessel_from, write_json)

RUN_OUTPUTS = (".csv", ".mcap", ".rrd", ".tlog", ".bin")
SEA_TEXT = ("HS,TP,DIR[,SPREAD]: JONSWAP significant height m, peak period s, direction the waves come from "
            "(deg), cosine-power spreading n (none: long-crested); or regular,H,T,DIR (one wave: height m, period s, "
            "direction deg)")
SEA_HELP = f"sea state {SEA_TEXT}; runs the 6-DOF hull"

MAX_MANOEUVRE_DRAWS = 100_000  # about three hours of trials on 2 cores


KNOWN_SEA_HELP = (f"the sea the recordings were made in, {SEA_TEXT}: its steady "
                  "drift at the hull (the waves' Stokes drift) is a known flow of every free run, so that a current "
                  "is only what lies beyond it")


def known_sea(vessel, text: Optional[str]):
    """`--sea` of identify, evaluate and diagnose → (the vessel with the sea's drift a known flow, a
    line saying so or None); refused on one line for a vessel without hull meshes."""
    if text is None:
        return vessel, None
    from ..engine.sixdof import check_sea_for, with_known_sea  # late: mujoco, 0.16 s more at every `twin --help`

    sea = sea_from(text, 0)
    check_sea_for(vessel, sea)
    known = with_known_sea(vessel, sea)
    n, e = known.environment.wave_drift_ned
    speeds, table = known_table(known.environment.wave_load)
    return known, (f"sea {sea.text()}: its Stokes drift at the hull, {math.hypot(n, e):.3f} m/s towards "
                   f"{math.degrees(math.atan2(e, n)) % 360:.0f}°, a known flow; its mean load on the hull "
                   f"(measured on its 6-DOF hull at up to {speeds[-1]:g} m/s), up to "
                   f"{np.max(np.abs(table[..., 0])):.2f} N in surge and {np.max(np.abs(table[..., 1])):.2f} N in "
                   "sway, a known force")


def sea_from(text: Optional[str], seed: int):
    """--sea text → physics.waves.Sea (checked: positive, not breaking), None without it."""
    if text is None:
        return None
    return parse_sea(text, seed)


def origin_from(text: Optional[str]) -> Optional[tuple[float, float]]:
    """--origin LAT,LON (degrees) of the local frame, for the formats that store latitude/longitude."""
    if text is None:
        return None
    try:
        lat, lon = (float(x) for x in text.split(","))
    except ValueError:
        raise TwinError(f"--origin expects LAT,LON in degrees, got '{text}'") from None
    if not (abs(lat) < 90 and abs(lon) <= 180):
        raise TwinError(f"--origin {text}: the latitude must lie in (−90, 90) and the longitude in [−180, 180]")
    return lat, lon


def check_run_length(duration: float, sample_dt: float) -> None:
    """--duration and --sample-dt of a run, before any work: positive, finite, and a sample count
    that fits in memory."""
    positive(duration, "--duration")
    positive(sample_dt, "--sample-dt")
    samples_fit(duration, sample_dt, "--duration at --sample-dt")


@app.command()
@all_or_nothing_outputs
def simulate(
    vessel: Optional[str] = typer.Option(None, help=VESSEL_HELP),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP),
    scenario: Optional[str] = typer.Option(None, help="step | turn | zigzag | spin | random (default zigzag; not "
                                                      "with --inputs)"),
    inputs: Optional[Path] = typer.Option(None, help="CSV: t + pwm_left,pwm_right (µs), thrust_left,thrust_right (N, "
                                                  "commands: the vessel's thruster gains scale them) or, for a "
                                                  "propeller-and-rudder ship, prop_rps,rudder_deg (rps, deg); each row "
                                                  "held until the next, an empty cell holds its input's last value"),
    duration: Optional[float] = typer.Option(None, help="simulated time, s (default 120, or the inputs' last time)"),
    out: list[Path] = typer.Option(..., help="output file(s): .csv, .mcap, .rrd, .tlog or .bin (repeatable)"),
    current: Optional[str] = typer.Option(None, help="water current SPEED,DIR_DEG (m/s, flowing towards)"),
    wind: Optional[str] = typer.Option(None, help="wind SPEED,DIR_DEG (m/s, coming from)"),
    origin: Optional[str] = typer.Option(None, help="LAT,LON (deg) of the start, for the map positions of .mcap, "
                                                   ".tlog and .bin (default 37.4136,-5.9786, Seville)"),
    case: Optional[str] = typer.Option(None, help=CASE_HELP),
    seed: int = typer.Option(0, help="random seed (scenario 'random', the sea's components)"),
    sample_dt: float = typer.Option(0.1, help="output sample period, s: a multiple of the vessel's physics time "
                                              "step (0.02 s; cybership1 0.01 s)"),
    sea: Optional[str] = typer.Option(None, help=SEA_HELP),
    six_dof: bool = typer.Option(False, "--six-dof", help="the 6-DOF hull (heave, roll, pitch) in calm water; "
                                                         "implied by --sea"),
    start_speed: Optional[float] = typer.Option(None, help="surge at t = 0, m/s (default: at rest; a ship's scenario "
                                                           "starts from its steady approach)"),
    force: bool = typer.Option(False, "--force", help=FORCE_HELP),
):
    """Run the twin headless and write the run."""
    from ..simulation import simulate_run  # late: the engine, 0.17 s more at every `twin --help`

    check_outputs(out, RUN_OUTPUTS, "--out")
    check_distinct({"--out": out}, [inputs, model], keep_data=False)
    check_new(out, force, "--out", RUNS)
    if scenario is not None and inputs is not None:  # which of the two drives the run cannot be known
        raise TwinError(f"give --scenario or --inputs, not both (--scenario {scenario} --inputs {inputs})")
    scenario = scenario or "zigzag"
    inputs_end_s = None
    if inputs is not None:  # read here too: the run's default length is the inputs' own
        inputs_end_s = float(read_inputs_csv(inputs).t[-1])
        if duration is None and not inputs_end_s > 0:
            raise TwinError(f"{inputs.name}: give --duration (the inputs end at t = {inputs_end_s:g} s)")
    cut = duration is not None and inputs_end_s is not None and duration < inputs_end_s
    duration = duration if duration is not None else inputs_end_s if inputs_end_s is not None else 120.0
    check_run_length(duration, sample_dt)
    seed_from(seed)
    start = origin_from(origin)
    v = vessel_from(vessel, model, case)
    lossy = [str(p) for p in out if p.suffix.lower() in (".tlog", ".bin", ".mcap")]
    if v.thrusters.kind == "propeller_rudder" and lossy:  # the run would be written without its inputs
        raise TwinError(f"{', '.join(lossy)}: a propeller-and-rudder ship's run keeps its propeller speed and rudder "
                        "angle in .csv only (and shows in .rrd): write .csv")
    if start_speed is not None and not (math.isfinite(start_speed) and abs(start_speed) <= 20.0):
        raise TwinError(f"--start-speed must be a speed in m/s within ±20, got {start_speed:g}")
    flows = speed_direction(current, "current"), speed_direction(wind, "wind")
    sea_state = sea_from(sea, seed)
    # a long run (hours of simulated time, an .rrd or .mcap of it) takes a while: say which part is running
    written = []
    try:
        with progress_bar("simulate") as progress:
            progress(f"simulating {duration:g} s of {v.name}")
            with memory_for(f"--duration {duration:g} at --sample-dt {sample_dt:g}"):
                result = simulate_run(v, scenario=scenario, inputs=inputs, duration_s=duration, seed=seed,
                                      sample_dt_s=sample_dt, current=flows[0], wind=flows[1], sea=sea_state,
                                      six_dof=six_dof, start_speed_m_s=start_speed)
            for k, path in enumerate(out):
                progress(f"writing {path.name}", k, len(out))
                result.write(path, origin=start, force=True)  # check_new asked already
                written.append(path)
    finally:  # after the bar (a line printed under it would be drawn over), and also when a later output fails
        for path in written:
            say(f"wrote {path}")
    for limit in result.limits:
        note(f"note: {limit.text()}")
    flowing = [what for what, flow in (("current", flows[0]), ("wind", flows[1])) if flow is not None and flow[0] > 0]
    lost = [p.name for p in written if p.suffix.lower() in (".csv", ".tlog", ".bin")]
    if flowing and lost:
        note(f"note: {', '.join(lost)} {'does' if len(lost) == 1 else 'do'} not hold the run's {' and '.join(flowing)} "
             "(an .mcap keeps them in its metadata, and `twin view --sim` replays it in them): a replay of it runs in "
             "still water and air")
    gains = v.thrusters.gains()
    if result.run.meta["inputs"].kind == "thrust" and inputs is not None and not np.allclose(gains, 1.0):
        note(f"note: thrust inputs are commands, which this vessel's thruster gains ({gains[0]:g}, {gains[1]:g}) "
             f"scale: 10 N commanded gives {10 * gains[0]:.3g} N (left) at rest; divide by the gain for a thrust")
    end = result.run.meta.get("inputs_end_s")
    if end is not None:
        note(f"note: the inputs end at {end:g} s: their last row is held to the end of the run ({duration:g} s)")
    if cut:
        note(f"note: the inputs run to {inputs_end_s:g} s: the run stops at --duration {duration:g} s")
    if v.sensors.errors():
        note(f"note: the run is written as the hull moved, without this twin's sensor errors "
             f"({', '.join(v.sensors.errors())}): a twin that carries them reads it through them; "
             f"`twin dataset` writes logs through the sensors")
    run = result.run
    say(f"{v.name}: {duration:g} s, final position ({run.eta[-1, 0]:.2f}, {run.eta[-1, 1]:.2f}) m, "
        f"heading {round(math.degrees(run.eta[-1, 2]), 1) % 360.0:.1f}°, u {run.nu[-1, 0]:.3f} m/s")
    six = run.meta.get("six_dof")
    if six is not None:
        deg = 57.29578
        say(f"6-DOF{'' if sea_state is None else ' in ' + sea_state.text()}: heave σ "
            f"{float(six['down_m'].std()) * 100:.1f} cm, roll σ {float(six['roll_rad'].std()) * deg:.2f}°, "
            f"pitch σ {float(six['pitch_rad'].std()) * deg:.2f}°")


@app.command()
@all_or_nothing_outputs
def crosscheck(
    vessel: Optional[str] = typer.Option(None, help=VESSEL_HELP),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP),
    duration: float = typer.Option(120.0, help="zig-zag duration, s"),
    case: Optional[str] = typer.Option(None, help=CASE_HELP),
    rrd: Optional[Path] = typer.Option(None, help="write engine and analytic trajectories to this .rrd"),
    json_out: Optional[Path] = typer.Option(None, "--json", help=f"write the errors as JSON {REPORT_HELP}"),
    six_dof: bool = typer.Option(False, "--six-dof", help="add the 6-DOF hull in calm water (a vessel with hull "
                                                         "meshes) against the 3-DOF model"),
):
    """Engine against the analytic 3-DOF model; exit 1 when over tolerance."""
    # late: the command's stack (the engine, the writers: 0.25 s) would be paid at every `twin --help`
    from ..engine.mjcf import compile_vessel
    from ..outputs import write
    from ..verify.crosscheck import HEADING_TOL_DEG, POSITION_TOL_M
    from ..verify.crosscheck import crosscheck as run_crosscheck

    check_outputs([rrd], (".rrd",), "--rrd")
    check_outputs([json_out], (".json",), "--json")
    check_distinct({"--rrd": rrd, "--json": json_out}, [model])
    positive(duration, "--duration")
    samples_fit(duration, 0.1, "--duration")  # the zig-zag's runs are sampled every 0.1 s
    v = vessel_from(vessel, model, case)
    with progress_bar("crosscheck") as progress:
        results = run_crosscheck(v, duration, progress=progress, six_dof=six_dof)
    table = Table(title=f"crosscheck {v.name}: engine (MuJoCo) vs analytic, {duration:g} s zig-zag")
    for col in ("case", "position err (m)", "heading err (deg)", "term effect (m)", "result"):
        table.add_column(col, justify="right" if "err" in col or "effect" in col else "left")
    idle = []
    for r in results:
        effect = "-" if r.effect_m is None else f"{r.effect_m:.3g}"
        untested = not r.exercised  # a pass there would say more than it knows
        idle += [r.case] if untested else []
        table.add_row(r.case, f"{r.position_err_m:.2e}", f"{r.heading_err_deg:.2e}", effect,
                      "[green]pass[/]" if r.passed and not untested else "[grey50]no effect[/]" if r.passed
                      else "[red]FAIL[/]")
    print_table(table)
    say(f"tolerance: position < {POSITION_TOL_M} m, heading < {HEADING_TOL_DEG}°")
    if idle:
        say(f"note: {', '.join(idle)}: the term moves this vessel less than the position tolerance over the run, so "
            "the case tests nothing here (no such load on it, or a run too short)")
    # a ramp's step means leave the thrust-alone case (no damping) and, through an advance loss without a
    # lag, any case off by more than the tolerance (docs/method/physics.md): say so for those cases only
    t = v.thrusters
    ramped = [r.case for r in results if t.ramping and not r.passed
              and (r.case == "thrust" or (t.advance_loss and not t.lag_s > 0))]
    if ramped:
        say(f"note: {', '.join(ramped)}: the engine holds a thrust ramp at its mean over each step (exact in "
            "impulse, not in its first moment, nor through an advance loss without a lag), which alone can take "
            "this case over the tolerance (docs/method/physics.md, 'What a ramp leaves')")
    write_json(json_out, {"vessel": v.name, "duration_s": duration, "cases": [r.to_dict() for r in results]})
    if rrd is not None:
        full = results[0]
        write({"engine": full.engine, "analytic": full.analytic}, rrd,
              geometry=compile_vessel(v).geometry, vessel_name=v.name, mjcf=v.mjcf, view=True)
        say(f"wrote {rrd}")
    if not all(r.passed for r in results):
        raise typer.Exit(1)


@app.command()
@all_or_nothing_outputs
def manoeuvres(
    vessel: Optional[str] = typer.Option(None, help=VESSEL_HELP),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP),
    case: Optional[str] = typer.Option(None, help=CASE_HELP),
    surge: float = typer.Option(0.5, help="the approach command, (0, 1]: a ship's share of rps_max; a twin-thruster "
                                          "boat's share of the PWM span from 1500 µs (0.5: 1700 µs; a share inside the "
                                          "dead zone, the BlueBoat's below about 0.1, does not get under way)"),
    turn_yaw: float = typer.Option(1.0, help="the turning circles' yaw command, (0, 1] (a ship: of rudder_max; a "
                                             "twin-thruster boat's thrusters get surge ± yaw, each held within full)"),
    zigzag_yaw: Optional[float] = typer.Option(None, help="the zig-zag's yaw command, (0, 1] (default: a ship's 10° "
                                                          "of rudder, a boat's 0.2; a ship's 20°/20° test: 20° over "
                                                          "its rudder_max)"),
    zigzag_switch: float = typer.Option(10.0, help="the heading change at which the zig-zag reverses, between 0 and "
                                                   "90°"),
    draws: int = typer.Option(0, help="with an identified twin (its uncertainty block): each measure's 90 % range "
                                      "over this many draws of its parameters (its form error is not in it)"),
    seed: int = typer.Option(0, help="the draws' random seed"),
    json_out: Optional[Path] = typer.Option(None, "--json", help=f"write the measures as JSON {REPORT_HELP}"),
):
    """The twin's turning circles, zig-zag and crash stop in calm water, as manoeuvring trials measure them."""
    # late: the engine, 0.25 s at every --help
    from ..fit.uncertainty import check_drawable
    from ..verify.manoeuvres import manoeuvre_bands, manoeuvres as run_manoeuvres

    check_outputs([json_out], (".json",), "--json")
    check_distinct({"--json": json_out}, [model])
    if draws < 0 or draws == 1:
        raise TwinError(f"--draws is 0 (no band) or at least 2, got {draws}")
    if draws > MAX_MANOEUVRE_DRAWS:  # kept measures are a few numbers a draw: the bound is the time, not memory
        raise TwinError(f"--draws is at most {MAX_MANOEUVRE_DRAWS}, got {draws}: each draw runs the turning circles, "
                        "zig-zag and crash stop (about 0.1 s on 2 cores), and a 90 % band settles within a few "
                        "hundred draws")
    if seed < 0:
        raise TwinError(f"--seed is a whole number ≥ 0, got {seed}")
    v = vessel_from(vessel, model, case)
    if draws:
        check_drawable(v)  # before the runs: a vessel without an uncertainty block has no band to draw
    options = dict(surge=surge, turn_yaw=turn_yaw, zigzag_yaw=zigzag_yaw, zigzag_switch_deg=zigzag_switch)
    m = run_manoeuvres(v, **options)
    for line in manoeuvre_lines(m):
        say(line)
    band = manoeuvre_bands(v, draws, seed, **options) if draws else None
    if band is not None:
        say(f"{100 * band.level:.0f} % of {band.draws} draws of its parameters (its form error is not in it"
            + (f"; {band.redrawn} unphysical draws redrawn, which narrows and shifts the band" if band.redrawn else "")
            + (f"; {band.diverged} diverged, left out" if band.diverged else "") + "):"
            + (" fewer than 20 draws say little of a 90 % range" if band.draws < 20 else ""))
        for b in band.bands:
            fmt, digits = (".2f", 2) if b.name.endswith("_m") else (".3g", 6)
            say(f"  {b.name:<36} " + ("reached by fewer than half the draws" if b.low is None else
                                      f"{_unsigned_zero(b.low, digits):{fmt}} to {_unsigned_zero(b.high, digits):{fmt}}") + (f" (reached by {100 * b.reached:.0f} %)"
                                                                              if b.reached < 1 else ""))
    write_json(json_out, asdict(m) | {"straight": None if m.straight is None else {
        "throttle": m.straight.throttle, "speed_m_s": m.straight.speed_m_s, "stable": m.straight.stable,
        "roots_per_s": [[r.real, r.imag] for r in m.straight.roots_per_s]},
        "bands": None if band is None else asdict(band), "seed": seed})


def manoeuvre_lines(m) -> list[str]:
    """The manoeuvres (verify.manoeuvres.Manoeuvres) as text: each length in m and in L."""
    L = m.length_m

    def length(x):
        if x is None:
            return "not reached"
        x = _unsigned_zero(x, 2)
        return f"{x:.2f} m ({_unsigned_zero(x / L, 2):.2f} L)"

    def value(x, unit, fmt=".3g"):
        return "not reached" if x is None else f"{x:{fmt}}{'' if unit == '°' else ' '}{unit}"

    def asked(name):
        kind, (a, b) = m.inputs[name]
        return {"pwm": f"PWM {a:.0f} | {b:.0f} µs", "thrust": f"thrust {a:.3g} | {b:.3g} N"}.get(
            kind, f"{a:.3g} rps, rudder {math.degrees(b):+.1f}°")

    lines = [f"[bold]{m.vessel}[/]: L {L:.3g} m; approach at surge {m.surge:g} ({asked('approach')}): "
             f"u {m.approach_speed_m_s:.3g} m/s"]
    if m.straight is not None:
        lines.append("  " + ("holds a straight course" if m.straight.stable else
                             f"COURSE-UNSTABLE: a deviation doubles every {m.straight.doubling_s:.3g} s") +
                     f" (sway-yaw roots {', '.join(f'{r.real:+.3g}' for r in m.straight.roots_per_s)} 1/s)")
    lines.append(f"turning circle, yaw {m.turn_yaw:g} (to starboard {asked('turn')}; starboard | port, transfer + to "
                 "starboard, drift atan2(−v, u): + with the bow to starboard of the track):")
    for label, key, kind in (("advance", "advance_m", "L"), ("transfer", "transfer_m", "L"),
                             ("tactical diameter", "tactical_diameter_m", "L"),
                             ("steady diameter", "steady_diameter_m", "L"), ("steady speed", "steady_speed_m_s", "m/s"),
                             ("steady rate", "steady_rate_deg_s", "°/s"), ("drift angle", "drift_deg", "°")):
        cells = [length(getattr(c, key)) if kind == "L" else value(getattr(c, key), kind, ".3g" if kind == "m/s" else ".1f")
                 for c in m.turns]
        lines.append(f"  {label:<18} {cells[0]:<22} | {cells[1]}")
    z = m.zigzag
    head = f"zig-zag, yaw {z.yaw:g} ({asked('zigzag')}) switched at {z.switch_deg:g}°: "
    if z.time_to_first_switch_s is None:
        lines.append(head + f"the heading never reached {z.switch_deg:g}°")
    elif z.first_overshoot_deg is None:
        lines.append(head + f"reversed after {z.time_to_first_switch_s:.1f} s, the turn is never checked (the heading "
                     f"never came back past −{z.switch_deg:g}°)")
    else:
        lines.append(head + f"first overshoot {z.first_overshoot_deg:.1f}°, second "
                     f"{value(z.second_overshoot_deg, '°', '.1f')}; first reversal after {z.time_to_first_switch_s:.1f} s")
    c = m.crash_stop
    if c is None:
        lines.append("crash stop: none (the thrusters have no astern)")
    else:
        lines.append(f"crash stop, full astern: track reach {length(c.track_reach_m)}, head reach "
                     f"{length(c.head_reach_m)}, lateral {length(c.lateral_m)}, in {value(c.time_s, 's', '.1f')}")
    return lines


@app.command()
@all_or_nothing_outputs
def params(
    vessel: Optional[str] = typer.Option(None, help=VESSEL_HELP),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP),
    case: Optional[str] = typer.Option(None, help=CASE_HELP),
    as_json: bool = typer.Option(False, "--json", help="print JSON instead of text (a flag: `> FILE` keeps it)"),
    first_principles: bool = typer.Option(False, "--first-principles",
                                          help="the hull and propulsor coefficients from the vessel's own geometry, "
                                               "each with its method (a vessel file with a design block: of the "
                                               "shipped ones, blueboat)"),
    write_model: Optional[Path] = typer.Option(None, "--write-model", help="write the vessel file (.json): with "
                                               "--first-principles with these estimates, each source saying so; "
                                               "without, as it is (a shipped vessel to start your own from)"),
    force: bool = typer.Option(False, "--force", help=FORCE_HELP),
):
    """Print the effective 3-DOF parameters of a vessel; --write-model writes its vessel file."""
    from ..engine.parameters import effective_parameters  # late: mujoco, 0.13 s more at every `twin --help`

    check_outputs([write_model], (".json",), "--write-model")
    check_distinct({"--write-model": write_model}, [model], keep_data=False)
    check_new([write_model], force, "--write-model", ("vessel file",))
    if first_principles:
        from ..verify.priors import first_principles as estimate  # late: 0.14 s, only for --first-principles

        v = vessel_from(vessel, model, case)
        fp = estimate(v)
        if write_model is not None:
            save_vessel(fp.applied(v), write_model)
            # on stderr with --json: standard output is the JSON a caller redirects
            line = f"wrote {write_model}: {v.name} with its first-principles coefficients"
            after_writes(lambda: typer.echo(line, err=as_json))
        if as_json:
            typer.echo(json.dumps({"vessel": fp.vessel, "estimates": [e.__dict__ for e in fp.estimates]}, indent=2))
        else:
            typer.echo(fp.table())
        return
    v = vessel_from(vessel, model, case)
    if write_model is not None:
        save_vessel(v, write_model)
        wrote = f"wrote {write_model}: {v.name} as {'given' if model is not None else 'shipped'}"
        after_writes(lambda: typer.echo(wrote, err=as_json))
    p = effective_parameters(v)
    if as_json:
        typer.echo(json.dumps(p, indent=2))
        return
    source = f"{model.name}: " if model is not None else ""
    say(f"[bold]{source}{p['vessel']}[/] ({p['case']}): m = {p['rigid_body']['mass_kg']:.3f} kg, "
        f"xg = {_unsigned_zero(p['rigid_body']['xg_m'] * 1e3, 1):.1f} mm, Iz = {p['rigid_body']['Iz_kgm2']:.3f} kg·m²")
    say("mass matrices, rows and columns u, v, r (kg, kg·m, kg·m²):")
    for key in ("M", "M_RB", "M_A"):
        say(f"{key:5s} = " + "  ".join("[" + ", ".join(f"{_unsigned_zero(x, 4):9.4f}" for x in row) + "]"
                                       for row in p[key]))
    for line in params_lines(p):
        say(line)


def _unsigned_zero(x: float, decimals: int) -> float:
    """x, with a value that rounds to zero printed as 0 rather than −0."""
    return 0.0 if round(float(x), decimals) == 0 else float(x)


def _dead_zones(t: dict) -> str:
    """'dead zone 0.0775 / -0.0925', or each thruster's where one has edges of its own."""
    shared = (t["deadzone_fwd"], t["deadzone_rev"])
    own = [t.get(f"deadzone_{side}") for side in ("left", "right")]
    if own == [None, None]:
        return f"dead zone {shared[0]:g} / {shared[1]:g}"
    left, right = (shared if edges is None else edges for edges in own)
    return f"dead zone left {left[0]:g} / {left[1]:g}, right {right[0]:g} / {right[1]:g}"


def _course_line(run: dict) -> str:
    """The calm-water straight run at full ahead and whether it holds its course."""
    roots = ", ".join(f"{re:+.3g}" + (f"{im:+.3g}j" if abs(im) > 1e-12 else "") for re, im in run["roots_per_s"])
    head = f"straight run at full ahead, calm water: u {run['speed_m_s']:.3g} m/s, sway-yaw roots {roots} 1/s: "
    if run["stable"]:
        return head + "holds its course"
    return head + (f"COURSE-UNSTABLE from {run['course_unstable_from_m_s']:.3g} m/s: it turns on its own (at full "
                   f"ahead a deviation doubles every {run['doubling_s']:.3g} s) unless steered")


def params_lines(p: dict) -> list[str]:
    """The damping and propulsion of effective_parameters' dict as text, each value with its unit:
    Fossen's damping (N and N·m per the velocities' powers), a PWM thruster's map scales, or a ship's
    MMG coefficients (non-dimensional, [MMG-2015])."""
    lines = []
    damping = [f"{k} {val:g} {DAMPING_UNITS.get(k, '')}".rstrip() for k, val in p["damping"].items() if val]
    if damping:
        lines.append("damping: " + ", ".join(damping))
    t = p["thrusters"]
    if t["kind"] == "propeller_rudder" and p.get("mmg"):
        m = p["mmg"]
        lines.append("MMG hull (non-dimensional): " + ", ".join(f"{k} {v:g}" for k, v in m["hull"].items()))
        lines.append("MMG propeller: " + ", ".join(f"{k} {v:g}" for k, v in m["propeller"].items()
                                                   if isinstance(v, (int, float))))
        lines.append("MMG rudder: " + ", ".join(f"{k} {v:g}" for k, v in m["rudder"].items()))
    else:
        lines.append(f"thrusters ({t['kind']}): gains left {t['gain_left']:g}, right {t['gain_right']:g} (× the map); "
                     f"lag {t['lag_s']:g} s, delay {t['delay_s']:g} s; advance loss {t['advance_loss']:g} √N s/m; "
                     f"{_dead_zones(t)} (of the PWM scale, {t['pwm_scale_us']:g} µs)")
    if "positions_m" in t:
        at = "; ".join(f"{side} ({', '.join(f'{x:+.3f}' for x in pos)})" for side, pos in t["positions_m"].items())
        lines.append(f"{'propulsor' if t['kind'] == 'propeller_rudder' else 'thruster'} sites (x fwd, y stbd, z down, m): {at}"
                     + (f"; thrust {t['Fu_min_n']:.4g} to {t['Fu_max_n']:.4g} N, yaw moment ±{t['tau_r_max_nm']:.4g} N m"
                        if t.get("tau_r_max_nm") is not None else ""))
    if p.get("straight_run"):
        lines.append(_course_line(p["straight_run"]))
    sites = [f"{what} ({', '.join(f'{x:+.3f}' for x in p[key])})" for what, key in
             (("GNSS", "gnss_antenna_m"), ("IMU", "imu_m")) if p.get(key) is not None]
    if sites:
        lines.append("sensor sites of the MJCF (m): " + "; ".join(sites))
    return lines


@app.command()
@all_or_nothing_outputs
def validate(
    vessel: Optional[str] = typer.Option(None, help=VESSEL_HELP),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP),
    case: Optional[str] = typer.Option(None, help=CASE_HELP),
    json_out: Optional[Path] = typer.Option(None, "--json", help=f"write one object per quantity {REPORT_HELP}"),
    report: Optional[Path] = typer.Option(None, help=f"write a report: .md (PNG beside it) or .html {REPORT_HELP}"),
):
    """Analytic formulas, published tables, engine, meshes and independent values, side by side."""
    # late: twin.verify.validate (mujoco) is 0.14 s more at every `twin --help`
    from ..verify.validate import format_table
    from ..verify.validate import validate as run_validation

    check_outputs([json_out], (".json",), "--json")
    check_outputs([report], (".md", ".html", ".htm"), "--report")
    figure = report_figure(report) if report is not None else None
    check_outputs([figure], (".png",), "--report's figure")  # written beside the page: a folder there fails late
    check_distinct({"--json": json_out, "--report": report, "--report's figure": figure}, [model])
    result = run_validation(vessel_from(vessel, model, case))
    rows = [q.to_dict() for q in result.quantities]
    typer.echo(format_table(result.vessel, result.case, rows))
    flagged = [r for r in rows if r["flag"]]
    if flagged:
        typer.echo("\nDifferences over 5 %:")
        for r in flagged:
            typer.echo(textwrap.fill(f"* {r['name']}: {r['explanation']}", 100, subsequent_indent="  "))
    title = f"twin validate: {result.vessel} ({result.case})"
    if json_out is not None:
        write_text_atomic(json_out, json.dumps({"vessel": result.vessel, "case": result.case,
                                                "quantities": rows}, indent=2) + "\n")
        say(f"wrote {json_out}")
    if report is not None:
        write_report(report, title, rows, top_view_png(result.drawing, title))
        say(f"wrote {report}")
        if figure is not None:
            say(f"wrote {figure}")
