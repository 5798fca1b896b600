"""`twin iso` (identification by self-oscillations) and `twin dp` (the I-PD controller tuned
from it), [Relay-ISO] — registered on the main CLI app."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Optional

import typer
from rich.markup import escape
from rich.table import Table

from ..errors import TwinError
from ..files import write_bytes_atomic
from ..ident.relay import ipd, iso
from ..ident.relay.ipd import (HEADING_OMEGA_RAD_S, SHIP_HEADING_OMEGA_RAD_S, SHIP_RPS,  # why these: that module
                                  SURGE_OMEGA_RAD_S)
from ..ident.relay.iso import CONTROL_DT_S, DEFAULT_DURATION_S, SHIP_CONTROL_DT_S, SHIP_DURATION_S, UNITS
from .app import (REPORT_HELP, all_or_nothing_outputs, CASE_HELP, MODEL_HELP, VESSEL_HELP, app, check_distinct, check_outputs, console, floats, note,
                  positive, print_table, progress_bar, samples_fit, say, vessel_from, write_json)


# IS-O reads Table I from whole relay periods after the run's first third, its transient: three at least
# (iso.measure_oscillation wants four rising switches). A sampled relay switches at most once a control step,
# so a period lasts two steps at least: 3·2 steps in the last two thirds, 9 steps in all, is the least run
ISO_PERIODS = 3
# a heading step's model function (s/ω_n + 1)⁻³ reaches 90 % of the step at x = ω_n·t = 5.32, the root of
# 1 − e^(−x)(1 + x + x²/2) = 0.9: a shorter run's IAE ratio compares the twin with a step hardly begun
RISE_90_X = 5.3223


def least_iso_duration_s(control_dt_s: float) -> float:
    """The shortest relay experiment that can hold ISO_PERIODS whole periods after its first third (s)."""
    return 1.5 * ISO_PERIODS * 2 * control_dt_s


def check_iso_duration(duration_s: float, control_dt_s: float, default: str) -> None:
    """Refuse, before any run, a --duration no relay experiment could read Table I from."""
    least = least_iso_duration_s(control_dt_s)
    if duration_s < least - 1e-9:
        raise TwinError(f"--duration {duration_s:g} s is too short for a relay experiment: Table I is read from "
                        f"{ISO_PERIODS} whole periods after the run's first third (its transient), and a relay "
                        f"switching every {control_dt_s:g} s at most takes {2 * control_dt_s:g} s a period: at least "
                        f"{least:g} s, and a few of the boat's own periods in practice (default {default})")


def _write_png(path: Optional[Path], data_fn) -> None:
    if path is not None:
        write_bytes_atomic(path, data_fn())
        say(f"wrote {path}")


def _sweep_table(result) -> Table:
    u = UNITS[result.dof]
    ship = any(r.rudder_deg is not None for r in result.rows)
    table = Table(title=f"IS-O {result.vessel} {result.dof}{' with the rudder as the relay' if ship else ''} "
                        "([Relay-ISO Table I]; Table II layout)")
    if ship:
        for col in ("n [rps]", "δ_c [°]"):
            table.add_column(escape(col), justify="right")
    for col in (f"C [{u['C']}]", f"Xm [{u['x']}]", "ω [rad/s]", f"x0 [{u['x']}]", f"α [{u['alpha']}]",
                f"β_ν [{u['beta_lin']}]", f"β_νν [{u['beta_quad']}]", f"Δ [{u['C']}]"):
        table.add_column(escape(col), justify="right")
    pad = ["", ""] if ship else []
    for r in result.rows:
        o, e = r.oscillation, r.estimate
        table.add_row(*([f"{r.rps:g}", f"{r.rudder_deg:g}"] if ship else []), f"{r.relay_c:.2f}", f"{o.amplitude_xm:.4f}", f"{o.frequency_rad_s:.3f}", f"{o.bias_x0:+.1e}",
                      f"{e.alpha:.3f}", f"{e.beta_lin:.3f}", f"{e.beta_quad:.3f}", f"{e.disturbance:+.3f}")
    s, t = result.spreads(), result.twin
    table.add_row(*pad, "σ/mean", "", "", "", f"{s['alpha'].cv_percent:.1f} %", f"{s['beta_lin'].cv_percent:.1f} %",
                  f"{s['beta_quad'].cv_percent:.1f} %", "")
    table.add_row(*pad, "twin", "", "", "", f"{t.alpha:.3f}", f"{t.drag_lin:.3f}", f"{t.drag_quad:.3f}", "0")
    return table


def iso_command(
    vessel: Optional[str] = typer.Option(None, help=VESSEL_HELP),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP),
    dof: str = typer.Option("yaw", help="yaw (heading feedback, [Relay-ISO Fig. 4]) | surge (integrator of u, "
                                        "Fig. 5); the paper's sway is refused: these twins have no sway thruster"),
    xa: Optional[float] = typer.Option(None, help="relay hysteresis: switches at e = ±xa; degrees for yaw, metres "
                                                  "for surge (default 1° / 0.25 m)"),
    amplitudes: Optional[str] = typer.Option(None, help="relay outputs C, comma-separated, N·m for yaw, N for surge "
                                                        "(default: 7 from 20 % to 100 % of what the thrusters give); "
                                                        "for a propeller-and-rudder ship rudder angles in degrees "
                                                        "(default 10,15,20,25,30,35)"),
    rps: Optional[str] = typer.Option(None, help="a propeller-and-rudder ship's propeller speeds, rps, comma-separated "
                                                 "(default 8,10)"),
    duration: Optional[float] = typer.Option(None, help="length of each relay experiment, s "
                                                        "(default 30 yaw, 150 surge; 900 for a ship)"),
    case: Optional[str] = typer.Option(None, help=CASE_HELP),
    json_out: Optional[Path] = typer.Option(None, "--json", help=f"write the table, CVs and the twin's values as JSON {REPORT_HELP}"),
    png: Optional[Path] = typer.Option(None, help=f"write α, β_ν, β_νν against C as PNG {REPORT_HELP}"),
):
    """Identification by self-oscillations in the twin: a relay with hysteresis, Table I for the
    constant-drag and linear-drag models at several relay outputs, compared with the twin's own
    uncoupled inertia and drag. The controller tuned from it runs with `twin dp`."""
    from ..engine.mjcf import compile_vessel  # late: mujoco, 0.17 s more at every `twin --help`

    check_outputs([json_out], (".json",), "--json")
    check_outputs([png], (".png",), "--png")
    check_distinct({"--json": json_out, "--png": png}, [model])
    v = vessel_from(vessel, model, case)
    iso.check_dof(v.name, dof, v.thrusters.kind)
    if duration is not None:
        samples_fit(positive(duration, "--duration"), CONTROL_DT_S, "--duration")  # the relay's samples
        ship = v.thrusters.kind == "propeller_rudder"
        check_iso_duration(duration, SHIP_CONTROL_DT_S if ship else CONTROL_DT_S,
                           f"{SHIP_DURATION_S if ship else DEFAULT_DURATION_S[dof]:g} s")  # check_dof: yaw or surge
    if xa is not None:
        positive(xa, "--xa")
    xa_si = None if xa is None else (math.radians(xa) if dof == "yaw" else xa)
    if v.thrusters.kind != "propeller_rudder" and rps is not None:
        raise TwinError("--rps applies to a propeller-and-rudder ship only")
    with progress_bar("iso") as progress:
        if v.thrusters.kind == "propeller_rudder":
            result = iso.ship_sweep(compile_vessel(v), floats(amplitudes, "amplitudes"), floats(rps, "rps"), xa_si,
                                    duration, progress=progress)
        else:
            result = iso.sweep(compile_vessel(v), dof, floats(amplitudes, "amplitudes"), xa_si, duration,
                               progress=progress)
    print_table(_sweep_table(result))
    s = result.spreads()
    console.print(f"α: {s['alpha'].mean:.4g} vs the twin's {result.twin.alpha:.4g} "
                  f"({result.alpha_error_percent():+.1f} %), "
                  f"CV {s['alpha'].cv_percent:.1f} % ([Relay-ISO]: ~10 %); drag CV {s['beta_lin'].cv_percent:.1f} % "
                  f"(β_ν) / {s['beta_quad'].cv_percent:.1f} % (β_νν): {result.better_drag_model()} fits better.")
    if v.thrusters.kind == "propeller_rudder":
        console.print("C is the rudder's yaw moment at ±δ_c in straight running (u₀ at n). The ship's yaw is coupled "
                      "with its sway (rudder side force, N'_v), so α and β are effective values: the twin's uncoupled "
                      "M33 and −∂N/∂r at u₀ are shown for scale.")
    else:
        console.print("The twin's drag has a linear and a quadratic term, so neither one-term model is exact: "
                      "each β is the describing-function equivalent at the experiment's speed amplitude.")
    write_json(json_out, result.to_dict())
    _write_png(png, lambda: iso.sweep_png(result))


MAX_TARGET_M = 1000.0


def _target(text: str) -> tuple[float, float]:
    values = floats(text, "target")
    if len(values) != 2 or not 0.5 <= math.hypot(*values) <= MAX_TARGET_M:
        raise TwinError(f"--target expects NORTH,EAST in m, 0.5 to {MAX_TARGET_M:g} m away (a station to hold, "
                        f"not a passage), got '{text}'")
    return values[0], values[1]


def tuned_models(compiled, omega_heading: float, omega_surge: float | None, rps: float | None = None,
                 progress=None):
    """IS-O sweeps with the default settings → (yaw, surge) DofModels for the I-PD (surge None if not asked);
    a ship's yaw from its rudder relay at the propeller speed `rps`. `progress` hears each relay run."""
    for w in (omega_heading, omega_surge):
        if w is not None and not (w > 0 and math.isfinite(w)):
            raise TwinError(f"model-function frequencies must be positive and finite, got {w:g} rad/s")
    if iso.is_ship(compiled):
        sweep = iso.ship_sweep(compiled, rps=[rps], progress=progress)
        return ipd.DofModel(*iso.linear_model(sweep, rps), ipd.binomial(omega_heading)), None
    damping = compiled.vessel.damping  # the hull's linear drag at rest, where a move ends
    yaw = ipd.DofModel(*iso.linear_model(iso.sweep(compiled, "yaw", progress=progress)), ipd.binomial(omega_heading),
                       beta_rest=max(-damping.Nr, 0.0))
    if omega_surge is None:
        return yaw, None
    return yaw, ipd.DofModel(*iso.linear_model(iso.sweep(compiled, "surge", progress=progress)),
                             ipd.binomial(omega_surge), beta_rest=max(-damping.Xu, 0.0))


DEFAULT_TARGET = "10,10"


def dp_command(
    vessel: Optional[str] = typer.Option(None, help=VESSEL_HELP),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP),
    run: str = typer.Option("heading", help="heading (a heading step, [Relay-ISO Figs. 8-9]) | point (move to --target)"),
    step: float = typer.Option(45.0, help="heading step, degrees (45 stays inside the thrusters, 90 saturates)"),
    target: str = typer.Option(DEFAULT_TARGET, help="point to reach, NORTH,EAST in m from the start (heading 0)"),
    omega_heading: Optional[float] = typer.Option(None, help=f"ω_n of the binomial heading model function, rad/s "
                                                            f"(default {HEADING_OMEGA_RAD_S:g}; a propeller-and-rudder "
                                                            f"ship {SHIP_HEADING_OMEGA_RAD_S:g})"),
    rps: Optional[float] = typer.Option(None, help=f"a propeller-and-rudder ship's constant propeller speed, rps "
                                                  f"(default {SHIP_RPS:g})"),
    omega_surge: float = typer.Option(SURGE_OMEGA_RAD_S, help="ω_n of the binomial surge model function, rad/s"),
    no_anti_windup: bool = typer.Option(False, "--no-anti-windup", help="switch the anti-windup off (to compare)"),
    duration: Optional[float] = typer.Option(None, help="length of the run, s (default: the model functions' "
                                                        "settling time; a point move, both loops')"),
    case: Optional[str] = typer.Option(None, help=CASE_HELP),
    json_out: Optional[Path] = typer.Option(None, "--json", help=f"write gains, IS-O models and IAE ratios as JSON {REPORT_HELP}"),
    png: Optional[Path] = typer.Option(None, help=f"write the response against the model function as PNG {REPORT_HELP}"),
):
    """I-PD control [Relay-ISO eqs. 9-11] tuned from IS-O run in the twin first (`twin iso` defaults,
    constant-drag model), with anti-windup on the saturated thrust, run in the twin against the
    binomial model function; prints the IAE ratio (twin / model function). Point moves turn to the
    bearing first, then surge along the line (the vessel has no sway thruster). A propeller-and-rudder ship
    steers its heading step with the rudder at a constant propeller speed (--rps); it has no point move."""
    from ..engine.mjcf import compile_vessel  # late: mujoco, 0.17 s more at every `twin --help`

    if run not in ("heading", "point"):
        raise TwinError(f"unknown run '{run}' (heading or point)")
    if not math.isfinite(step) or step == 0 or abs(step) > 180:
        raise TwinError("--step must be a non-zero angle within ±180°")
    goal = _target(target)  # a bad --target is refused whichever run is asked for
    if run == "heading" and target != DEFAULT_TARGET:
        raise TwinError("--target is the point of --run point; a heading step (--run heading) has none")
    check_outputs([json_out], (".json",), "--json")
    check_outputs([png], (".png",), "--png")
    check_distinct({"--json": json_out, "--png": png}, [model])
    if duration is not None:
        samples_fit(positive(duration, "--duration"), CONTROL_DT_S, "--duration")
    for option, w in (("--omega-heading", omega_heading), ("--omega-surge", omega_surge)):  # whichever run
        if w is not None and not (math.isfinite(w) and w > 0):
            raise TwinError(f"{option}: model-function frequencies must be positive and finite, got {w:g} rad/s")
    cv = compile_vessel(vessel_from(vessel, model, case))
    ship = cv.vessel.thrusters.kind == "propeller_rudder"
    period = SHIP_CONTROL_DT_S if ship else CONTROL_DT_S  # the heading loop's
    for option, w in (("--omega-heading", omega_heading), ("--omega-surge", omega_surge)):
        if w is not None and w * period > 0.5:  # a loop sampled every `period` cannot follow faster
            raise TwinError(f"{option} {w:g} rad/s: the controller runs every {period:g} s, so at most "
                            f"{0.5 / period:g} rad/s")
    if not ship and rps is not None:
        raise TwinError("--rps applies to a propeller-and-rudder ship only")
    rps = SHIP_RPS if rps is None else rps
    if ship and run == "point":
        raise TwinError(f"--run point: vessel '{cv.vessel.name}' is a propeller-and-rudder ship without sway or "
                        "astern control for a point move; run a heading step")
    if ship:
        (_, n_max), _ = cv.vessel.thrusters.channel_bounds()
        if not 0 < rps <= n_max:
            raise TwinError(f"--rps must lie in (0, {n_max:g}] rps")
    omega_heading = omega_heading if omega_heading is not None else (SHIP_HEADING_OMEGA_RAD_S if ship
                                                                     else HEADING_OMEGA_RAD_S)
    rise_s = RISE_90_X / omega_heading
    if run == "heading" and duration is not None and duration < rise_s:
        # one control step gave an IAE of 0 for the model function too, read as "no step asked of it"
        raise TwinError(f"--duration {duration:g} s ends before the heading model function has made 90 % of the "
                        f"{step:g}° step, at {rise_s:.3g} s ({RISE_90_X:.2f}/ω_n): the IAE ratio compares the twin "
                        f"with that step; give a longer one, or none for the settling time ({14 / omega_heading:.3g} s)")
    if run == "point" and duration is not None and duration <= 8 / omega_heading:
        # the surge loop starts once the turn to the bearing has had eight of its time constants (ipd.point_move)
        raise TwinError(f"--duration {duration:g} s ends before the point move's surge starts, at {8 / omega_heading:.3g} s "
                        "after the turn to the bearing: give a longer one, or none for the settling time")
    with progress_bar("dp") as progress:
        yaw, surge = tuned_models(cv, omega_heading, omega_surge if run == "point" else None, rps if ship else None,
                                  progress=progress)
        progress(f"I-PD: {'point move' if run == 'point' else 'heading step'} in the twin")
        if ship:
            dp = ipd.ship_heading_step(cv, yaw, step, rps, duration, anti_windup=not no_anti_windup)
        else:
            dp = ipd.heading_step(cv, yaw, step, duration, anti_windup=not no_anti_windup) if run == "heading" \
                else ipd.point_move(cv, yaw, surge, goal, duration)
    summary = dp.summary()
    for name, m in (("heading", yaw), ("surge", surge)):
        if m is not None and m.gains.kd != m.gains.kd_eq11:
            note(f"note: {name} K_D {m.gains.kd:.3g}, the hull's linear drag at rest, where [Relay-ISO eq. 11] gives "
                 f"{m.gains.kd_eq11:.3g}: below it the loop has negative damping at rest and swings about the target")
    for name, m in (("heading", yaw), ("surge", surge)):
        if m is not None:  # the gains are what a user carries to the autopilot
            unit = "N·m" if name == "heading" else "N"
            per = "rad" if name == "heading" else "m"
            console.print(f"{name} I-PD from IS-O: α {m.alpha:.4g}, β {m.beta:.4g}, ω_n {m.model.omega_n_rad_s:.3g} rad/s; "
                          f"K_I {m.gains.ki:.4g} {unit}/({per}·s), K_P {m.gains.kp:.4g} {unit}/{per}, "
                          f"K_D {m.gains.kd:.4g} {unit}·s/{per}")
    for lp in summary["loops"]:
        paper = " ([Relay-ISO]: ~1.02 for a 45° heading step)" if lp["dof"] == "yaw" else ""
        ratio = "– (no step asked of it)" if lp["iae_ratio"] is None else f"{lp['iae_ratio']:.3f}{paper}"
        console.print(f"{dp.name}, {lp['dof']}: IAE ratio {ratio}, "
                      f"max |twin − model| {lp['max_deviation_from_model']:.3g} {lp['unit']}, "
                      f"saturated {lp['saturated_percent_of_time']:.0f} % of the time")
    if "final_distance_to_target_m" in summary:  # a point move's; a heading step has no target
        lo, hi = summary["last_quarter_distance_m"]
        console.print(f"final distance to the target {summary['final_distance_to_target_m']:.3f} m"
                      + ("" if summary["settled"] else f": NOT SETTLED, the run's last quarter {lo:.2f}-{hi:.2f} m "
                                                       "from it (a longer --duration, or gains that damp it)"))
    models = {"yaw": yaw, "surge": surge}
    write_json(json_out, {"vessel": cv.vessel.name, **summary, "tuning": {
        k: {"alpha": m.alpha, "beta": m.beta, "omega_n_rad_s": m.model.omega_n_rad_s,
            "ki": m.gains.ki, "kp": m.gains.kp, "kd": m.gains.kd} for k, m in models.items() if m is not None}})
    _write_png(png, lambda: ipd.response_png(dp, f"{cv.vessel.name}: {dp.name}, I-PD tuned from IS-O"))


app.command("iso")(all_or_nothing_outputs(iso_command))
app.command("dp")(all_or_nothing_outputs(dp_command))
