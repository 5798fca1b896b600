"""`twin dataset`, `twin identify`, `twin evaluate`: registered on the main CLI app."""
from __future__ import annotations

import math

from dataclasses import asdict, replace
from pathlib import Path
from typing import TYPE_CHECKING, Optional

import typer
from rich.markup import escape

from ..effects import describe
from ..effects.coefficients import FIT_GROUPS, MMG_FIT_GROUPS
from ..errors import TwinError
from ..files import RUNS, check_new
from ..fit.coverage import from_dict as envelope_from, span_text
from ..fit.uncertainty import check_drawable
from ..vessel import Vessel, save
from .app import (REPORT_HELP, all_or_nothing_outputs, draws_fit, given_on_command_line, listed, CASE_HELP, CHANNELS_HELP, FORCE_HELP, MODEL_HELP, PWM_VESSEL_HELP, VESSEL_HELP, app, at_least,
                  channels_from, check_distinct, check_outputs, check_truth_beside_logs, memory_bytes, check_recordings_distinct, check_wind_and_inputs, console, counted,
                  floats, note, positive, progress_bar, recordings_in, say, say_unlogged_supply, seed_from, sensor_noise,
                  vessel_from, warn_recordings, window_s, write_json)
from .run import KNOWN_SEA_HELP, SEA_TEXT, known_sea, sea_from

if TYPE_CHECKING:  # for annotations only: twin.fit.calibrate is 0.2 s more at every `twin --help`
    from ..fit.calibrate import LogCalibration

RECORDING_FORMATS = (".tlog", ".bin", ".mcap", ".csv")
MAX_REPEATS = 1000  # --greybox --repeats: a million would run for days before a word


LARGE_OFFSET_DEG = 30.0  # a compass offset at least this large is said with what else gives one


def calibration_line(c: LogCalibration, applied: bool | None = None, twin: Vessel | None = None) -> str:
    """A log's compass calibration (twin.fit.calibrate.LogCalibration) as the commands print it, its
    caveat in brackets (one straight leg: an offset a current may share). `applied`: whether this
    command applied the offset found (None: a command that applies none, as `twin info`). `twin`: a
    twin that holds its own offset for this log (the one it was identified under) has it said beside
    the one read now, where they differ: the straight stretches are chosen by the twin's sway balance."""
    line = c.text()
    held = dict(twin.sensors.heading_bias_by_log_deg).get(c.log) if twin is not None else None
    if held is not None and (c.heading_bias_deg is None or abs(held - c.heading_bias_deg) >= 0.05):
        line += (f"; the twin was identified with {held:+.1f}° for this log (its straight stretches are "
                 "chosen by the sway balance of the twin that reads them)")
    if c.heading_bias_deg is None:  # its text says why it is not applied
        return line
    if applied is not None:
        line += "; offset applied" if applied else "; offset not applied (--no-calibration)"
    if abs(c.heading_bias_deg) >= LARGE_OFFSET_DEG:  # a compass error of a magnetometer mounted as meant is degrees
        line += (" (an offset this large is a compass mounted turned, or a track read wrongly: lat and lon "
                 "swapped, or a heading in another convention)")
    return line + (f" [{c.note}]" if c.note else "")


@app.command("dataset")
@all_or_nothing_outputs
def dataset_command(
    vessel: Optional[str] = typer.Option(None, help=PWM_VESSEL_HELP),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP),
    out: list[Path] = typer.Option(..., help="recording(s) to write: .tlog, .bin, .mcap, .csv (repeatable)"),
    truth: Optional[Path] = typer.Option(None, help="truth file (JSON; default: OUT.truth.json beside the first output)"),
    segments: int = typer.Option(8, help="number of trajectory segments"),
    manoeuvres: str = typer.Option(",".join(("rc", "forward_constant", "forward_varying", "zigzag", "circle_constant",
                                             "circle_varying")),
                                   show_default=False,  # the list is cut short in the help's column
                                   help="manoeuvres to cycle through, comma separated: rc, forward_constant, "
                                        "forward_varying, zigzag, circle_constant, circle_varying (these six by "
                                        "default), autopilot, astern_varying (backing), and the fixed trials from rest a "
                                        "diagnosis proposes to settle a rival: full_ahead_coast, throttle_steps, spins, "
                                        "turns, astern_stop"),
    effect: list[str] = typer.Option([], help="effect injected in the truth, NAME=V1,V2 (repeatable; "
                                              "`twin effects` lists them)"),
    noise: str = typer.Option("realistic", help="sensor noise: realistic | rtk | noisy | none | GNSS_M,HEADING_DEG"),
    seed: int = typer.Option(0, help="random seed (manoeuvres, start states, noise)"),
    case: Optional[str] = typer.Option(None, help=CASE_HELP),
    sea: Optional[str] = typer.Option(None, help=f"sea state {SEA_TEXT}: every segment runs the 6-DOF hull in it"),
    force: bool = typer.Option(False, "--force", help=FORCE_HELP),
):
    """Synthetic identification dataset from the twin, with its truth in a separate file."""
    # late: the command's stack (twin.synth, 0.18 s; the writers) would be paid at every `twin --help`
    from ..synth.dataset import generate
    from ..formats import write_recording

    check_outputs(out, RECORDING_FORMATS)
    truth_option = "--truth" if truth else "the truth beside the first --out"  # the option named is one given
    truth = truth or out[0].with_name(out[0].stem + ".truth.json")
    check_outputs([truth], (".json",), truth_option)
    check_distinct({"--out": out, truth_option: truth}, [model], keep_data=False)  # check_new: any file there
    check_new(out, force, "--out", RUNS, truth=truth)
    check_new([truth], force, truth_option, ("dataset's truth",))
    check_truth_beside_logs(truth, out, truth_option)
    segments_fit(segments)
    seed_from(seed)
    profile = sensor_noise(noise)  # before any work
    names = listed(manoeuvres, "--manoeuvres")
    if not names:
        raise TwinError("--manoeuvres names none: give one or more of the manoeuvres its help lists")
    with progress_bar("dataset") as progress:
        ds = generate(vessel_from(vessel, model, case), effects=effect, n_segments=segments, manoeuvres=names,
                      seed=seed, noise=profile, progress=progress, sea=sea_from(sea, seed))
        for k, path in enumerate(out):
            progress(f"writing {path.name}", k, len(out))
            write_recording(ds.recording, path)
    for path in out:
        say(f"wrote {path}")
    write_json(truth, ds.truth(truth, logs=out))
    total = sum(r.t[-1] - r.t[0] for r in ds.runs)
    span = ds.recording.duration_s()  # what `twin info` reports: the segments and the silent gaps between them
    made = ", ".join(m.name for m in ds.manoeuvres)
    console.print(f"{counted(len(ds.runs), 'segment')}, {total:.0f} s of manoeuvres in a log of {span:.0f} s ({made}); "
                  f"effects: {', '.join(e.text for e in ds.effects) or 'none'}", soft_wrap=True)


@app.command("effects")
def effects_command():
    """The effects a dataset can inject and a diagnosis can name."""
    typer.echo(describe())


# what one segment's runs and log hold in memory until the dataset is written (measured: 0.34 MB for
# the BlueBoat's default manoeuvres, 40-90 s each), with room for the formats' own copies
SEGMENT_BYTES = 1.0e6


def segments_fit(segments: int) -> None:
    """Refuse, before any work, a dataset whose segments are fewer than one or would not fit in half of
    this machine's memory (the run would fill it, then fail or swap, with nothing written)."""
    at_least(segments, 1, "--segments")
    memory = memory_bytes()
    if memory is not None and segments * SEGMENT_BYTES > memory / 2:
        raise TwinError(f"--segments {segments}: about {segments * SEGMENT_BYTES / 2**30:.3g} GiB held until the log "
                        f"is written, more than half this machine's memory ({memory / 2**30:.0f} GiB): fewer "
                        "segments, or `twin dataset-shards`, which writes them shard by shard")


def names_list(text: Optional[str], option: str, what: str) -> tuple[str, ...] | None:
    """A comma-separated list of names; None when the option is not given. Given empty it is refused:
    read as "all" it would fit what the user meant to leave out."""
    if text is None:
        return None
    names = tuple(listed(text, option))
    if not names:
        raise TwinError(f"{option} is empty: name at least one {what} (leave {option} out for the default)")
    return names


@app.command("identify")
@all_or_nothing_outputs
def identify_command(
    ctx: typer.Context,
    recordings: list[Path] = typer.Argument(..., metavar="RECORDINGS",
                                            help="recordings: .tlog, .bin, .csv, .mcap, or folders of them"),
    vessel: Optional[str] = typer.Option(None, help=VESSEL_HELP + " (the prior)"),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP),
    out: Path = typer.Option(..., help="identified vessel description to write (.json)"),
    groups: Optional[str] = typer.Option(None, help="groups of coefficients to free, comma separated "
                                                   "(default: all of " + ", ".join(FIT_GROUPS) + ", and pack voltage "
                                                   "where every recording logs its battery; for a "
                                                   "propeller-and-rudder ship: " + ", ".join(MMG_FIT_GROUPS)
                                                   + "; _ for a space: thrust_curve); the others "
                                                   "stay at their prior"),
    params: Optional[str] = typer.Option(None, help="fit exactly these coefficients instead of groups, "
                                                   "comma separated (e.g. Xu,Nr,thrust_gain)"),
    beliefs: str = typer.Option("0.01,0.1,1,10", help="how much the prior's beliefs count, in windows of data each: "
                                                 "the values tried (chosen on left-out runs)"),
    anchor: str = typer.Option("mass", help="absolute scale: mass (M11 from the vessel) | thrust (thrust curve)"),
    window: Optional[float] = typer.Option(None, help="free-run window of the simulation fit, s (default: 10, or "
                                                     "30 for a vessel whose surge time constant exceeds 10 s)"),
    start: str = typer.Option("free", help="initial velocities of each free run: free (estimated with the "
                                            "parameters) | measured (as the recording gives them)"),
    calibration: bool = typer.Option(True, "--calibration/--no-calibration",
                                     help="estimate each log's compass offset from its own GNSS track"),
    greybox: bool = typer.Option(False, "--greybox", help="also run [Morel-2024] grey-box least squares and tables"),
    thruster: str = typer.Option("static", help="[Morel-2024] thruster model (with --greybox): static | dynamic"),
    split: str = typer.Option("segments", help="[Morel-2024] tables (with --greybox): split by segments | points"),
    train: float = typer.Option(0.7, help="training share of the [Morel-2024] splits (with --greybox)"),
    repeats: int = typer.Option(20, help="random splits for the [Morel-2024] tables (with --greybox)"),
    seed: int = typer.Option(0, help="random seed of the [Morel-2024] splits"),
    max_evaluations: int = typer.Option(20, help="cost evaluations of the first fit (later ones take a third)"),
    channels: Optional[str] = typer.Option(None, help=CHANNELS_HELP),
    json_out: Optional[Path] = typer.Option(None, "--json", help=f"write the full report as JSON {REPORT_HELP}"),
    wind_measured: bool = typer.Option(False, "--wind-measured",
                                       help="take each recording's measured wind (its anemometer stream) as a known "
                                            "input of every free run"),
    sea: Optional[str] = typer.Option(None, help=KNOWN_SEA_HELP),
    force: bool = typer.Option(False, "--force", help=FORCE_HELP),
):
    """Identify a vessel from recordings: each log's compass calibration, a fit by simulation with the
    prior's beliefs, every choice judged on runs left out of the fit."""
    # late: the command's stack (the fitting, 0.54 s) would be paid at every `twin --help`
    from ..engine.sixdof import without_known_sea
    from ..fit import simfit
    from ..ident import identify as ident

    check_outputs([json_out], (".json",), "--json")
    check_outputs([out], (".json",), "--out")
    recordings = recordings_in(recordings) if any(p.is_dir() for p in recordings) else recordings
    check_distinct({"--out": out, "--json": json_out}, [*recordings, model], keep_data=False)
    check_distinct({"--json": json_out})  # a report never replaces a log or a twin, --force or not
    check_recordings_distinct(recordings)
    if params is not None and groups is not None:
        raise TwinError("--params names the coefficients to fit itself: --groups does not apply with it")
    lone = given_on_command_line(ctx, "thruster", "split", "train", "repeats", "seed") if not greybox else []
    if lone:  # they set the [Morel-2024] tables, which only --greybox makes
        raise TwinError(f"{', '.join(lone)} appl{'ies' if len(lone) == 1 else 'y'} only with --greybox")
    if window is not None:
        window_s(window)
    at_least(max_evaluations, 1, "--max-evaluations")
    if greybox:
        at_least(repeats, 1, "--repeats")
        if repeats > MAX_REPEATS:  # each repeat is a grey-box fit of every split method
            raise TwinError(f"--repeats {repeats}: at most {MAX_REPEATS} (each is a fit of every split method; "
                            "the default is 20)")
    seed_from(seed)
    prior, sea_line = known_sea(vessel_from(vessel, model, "nominal"), sea)
    weights = tuple(floats(beliefs, "beliefs"))
    if not weights or any(w <= 0 for w in weights):
        raise TwinError(f"--beliefs must be positive numbers, got '{beliefs}'")
    if anchor not in ("mass", "thrust"):
        raise TwinError(f"--anchor must be mass or thrust, got '{anchor}'")
    chosen_params = names_list(params, "--params", "coefficient")
    # a group's name may hold a space ("thrust curve"), which a shell splits unless quoted: _ stands for it
    chosen_groups = names_list(None if groups is None else groups.replace("_", " "), "--groups", "group")
    if chosen_params:
        simfit.check_names(prior, chosen_params, anchor)  # before any work
    check_new([out], force, "--out", ("vessel file",))  # after the options: a bad option is the first thing to fix
    recs = ident.read(recordings, channels_from(channels))
    warn_recordings(recs)
    wind = "measured" if wind_measured else None
    check_wind_and_inputs(recs, wind, prior)  # before any work
    with progress_bar("identify") as progress:
        result = ident.identify(recs, prior, groups=chosen_groups, params=chosen_params, prior_weights=weights,
                                anchor=anchor, window_s=window, start=start, calibrated=calibration,
                                greybox=greybox, thruster=thruster, split=split, train=train, repeats=repeats,
                                seed=seed, max_evaluations=max_evaluations,
                                sources=[str(r) for r in recordings], progress=progress, wind=wind)
    if sea_line:
        say(sea_line)
    for c in result.calibrations:  # made only to be applied (none with --no-calibration)
        say(escape(f"calibration: {calibration_line(c, applied=True)}"))  # its [caveat] is no rich markup
    say_unlogged_supply(recs, prior)
    text = ident.format_greybox(result.greybox)
    if text:
        console.print(f"[bold][Morel-2024] grey-box ({thruster} thruster model), one-step predictions[/]")
        typer.echo(text)
    console.print(f"[bold]choices, judged on left-out runs ({result.fit.meta.get('window_s', 10.0):g}-s free runs "
                  "from measured states)[/]")
    typer.echo(ident.format_choices(result))
    needed = ident.format_needed(result)
    if needed:
        say(needed)
    console.print("[bold]identification by simulation[/]")
    typer.echo(ident.format_estimates(result.fit))
    say(f"on a new run expect{' (with its measured wind)' if wind else ''}: {result.chosen.cv.summary()}")
    seen = result.vessel.uncertainty.get("fitted_on")
    if seen:  # where that expectation holds: beyond this span the twin extrapolates
        windows = ", ".join(f"{k} {n}" for k, n in seen["windows"].items())
        say(f"fitted on: {span_text(seen['ranges'])} (1st-99th percentile of the samples of its "
            f"{seen['horizon_s']:g}-s windows, one every {seen.get('stride_s', 2.0):g} s: {windows}): "
            "beyond these the twin extrapolates")
    for text in result.notes:
        note(f"note: {text}")
    if result.ran_away:  # before any file is written: a model that cannot predict must not replace one that may
        runs = len(result.chosen.cv.runs)
        raise TwinError(f"the identified twin ran away (diverged) on all {runs} left-out runs: nothing written (check "
                        f"the prior '{model or vessel}' — its thrust, damping and masses — against the recordings)")
    if result.worse_than_prior:
        note("warning: the twin written predicts runs left out of the fit worse than the prior did")
    save(without_known_sea(result.vessel), out)  # the twin, not the sea these recordings were made in
    say(f"wrote {out} (use: twin simulate --model {out}, twin evaluate --model {out} ...)")
    write_json(json_out, result.to_dict())


def stand_in_text(entries: list[dict] | None) -> str:
    """The uncertainty block's stand_ins (twin identify; vessel.py checks their shape) as "Nrdot ×7.8 of
    its prior, ..."; "" when there are none."""
    parts = []
    for e in entries or []:
        ratio = e["value"] / e["prior"] if e["prior"] else None
        parts.append(f"{e['name']} ×{ratio:.3g} of its prior" if ratio and ratio > 0
                     else f"{e['name']} {e['value']:.3g} {e['unit']} against its prior's {e['prior']:.3g}")
    return ", ".join(parts)


def recorded_turn_lines(held) -> list[str]:
    """Each recorded turn (verify.manoeuvres.RecordedTurn), recorded against predicted, as text."""
    if not held:
        return ["turns: none held (the inputs never held while the heading turned 90° or more)"]
    lines = ["turns held in the recordings, recorded | predicted (m, m/s, °/s, °; the recorded u, v from the log's "
             "prepared velocities; – where the heading never turned 90°, 180° or 360°):"]

    def pair(a, b, fmt):
        return " | ".join("–" if x is None else format(x, fmt) for x in (a, b))

    for t in held:
        kind, (a, b) = t.inputs
        asked = (f"PWM left {a:.0f}, right {b:.0f} µs as the twin reads them" if kind == "pwm"
                 else f"{a:.3g} rps, rudder {math.degrees(b):+.1f}°")
        p = t.predicted
        lines.append(f"  {t.log} at {t.start_s:.1f} s for {t.held_s:.1f} s ({asked}, u {t.speed_m_s:.3g} m/s)"
                     + ("" if p is not None else ": the twin's run diverged"))
        if p is None:
            continue
        m = t.measured
        lines.append(f"    advance {pair(m.advance_m, p.advance_m, '.2f')}, transfer "
                     f"{pair(m.transfer_m, p.transfer_m, '.2f')}, tactical diameter "
                     f"{pair(m.tactical_diameter_m, p.tactical_diameter_m, '.2f')}; steady diameter "
                     f"{pair(m.steady_diameter_m, p.steady_diameter_m, '.2f')}, speed "
                     f"{pair(m.steady_speed_m_s, p.steady_speed_m_s, '.3g')}, rate "
                     f"{pair(m.steady_rate_deg_s, p.steady_rate_deg_s, '+.2f')}, drift "
                     f"{pair(m.drift_deg, p.drift_deg, '+.1f')}")
    return lines


@app.command("evaluate")
@all_or_nothing_outputs
def evaluate_command(
    recordings: list[Path] = typer.Argument(..., metavar="RECORDINGS", help="recordings to evaluate on (.tlog, .bin, "
                                                                             ".csv, .mcap, or folders of them)"),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP),
    vessel: Optional[str] = typer.Option(None, help=VESSEL_HELP),
    channels: Optional[str] = typer.Option(None, help=CHANNELS_HELP),
    stride: float = typer.Option(2.0, help="free-run windows start every STRIDE s"),
    calibration: bool = typer.Option(True, "--calibration/--no-calibration",
                                     help="apply each log's compass offset estimated from its own GNSS track"),
    json_out: Optional[Path] = typer.Option(None, "--json", help=f"write the metrics as JSON {REPORT_HELP}"),
    rrd: Optional[Path] = typer.Option(None, help="write the recording and the twin's 10-s free runs to rerun"),
    band: bool = typer.Option(False, "--band", help="also: how often the recording falls inside the Monte Carlo band "
                                                    "of the identified uncertainty (30-s free runs)"),
    draws: Optional[int] = typer.Option(None, help="--band: parameter draws from the identification's covariance "
                                                   "(default 200)"),
    level: Optional[float] = typer.Option(None, help="--band: the band's level (default 0.9)"),
    seed: Optional[int] = typer.Option(None, help="--band: random seed of the draws (default 0)"),
    ray: Optional[str] = typer.Option(None, help="--band: run the draws on Ray (auto, local or an address)"),
    wind_measured: bool = typer.Option(False, "--wind-measured",
                                       help="take each recording's measured wind (its anemometer stream) as a known "
                                            "input of every free run"),
    sea: Optional[str] = typer.Option(None, help=KNOWN_SEA_HELP),
    turns: bool = typer.Option(False, "--turns", help="also: each turn the recordings hold (inputs held while the "
                                                      "heading turns 90° or more) measured as a manoeuvring trial "
                                                      "measures it, recorded against the twin's free run of it "
                                                      "(advance, transfer, tactical diameter, steady turn)"),
    by: Optional[str] = typer.Option(None, "--by", help="also: where the free runs miss by a state measured at each "
                                                        "sample, in bands of the samples (the lower half, the next "
                                                        "quarter, the next 15 %, the top 10 %): speed, yaw_rate, "
                                                        "drift (the drift angle |β|), input_0, input_1 (the logged inputs) or rest (how long input "
                                                        "0, a propeller, has been stopped)"),
):
    """R² and MAE per DOF: one step, 10-s and 30-s free runs, whole segments; with each log's own
    compass calibration (and without it where an offset was applied); where the free runs miss, by manoeuvre (idle, ahead, turning,
    spin, astern: each one's share of 1 − R²), and for a twin written by `twin identify` how many
    windows of each its fit saw and how much of the misfit lies beyond the speeds and turn rates it
    was fitted on; with --by, by a measured state (each band's share of 1 − R², and the gain of the
    measured on the predicted value: above 1, the vessel moves more than the twin); with --band, the
    share of the recording inside the prediction band of the identified uncertainty."""
    # late: the command's stack (the fitting, 0.54 s) would be paid at every `twin --help`
    from ..api import evaluate
    from ..fit.calibrate import with_log_calibrations
    from ..fit.evaluate import STATE_NAMES, format_by_manoeuvre, format_by_state, format_metrics, state_display
    from ..ident.identify import manoeuvre_horizon_s, prepared, read

    if by is not None and by not in STATE_NAMES:
        raise TwinError(f"--by {by}: unknown state (known: {', '.join(STATE_NAMES)})")
    check_outputs([json_out], (".json",), "--json")
    check_outputs([rrd], (".rrd",), "--rrd")
    recordings = recordings_in(recordings) if any(p.is_dir() for p in recordings) else recordings
    check_distinct({"--json": json_out, "--rrd": rrd}, [*recordings, model])
    check_recordings_distinct(recordings)
    positive(stride, "--stride")
    given = [o for o, x in (("--draws", draws), ("--level", level), ("--seed", seed), ("--ray", ray)) if x is not None]
    if given and not band:  # they would be ignored without a word
        raise TwinError(f"{', '.join(given)} appl{'ies' if len(given) == 1 else 'y'} only with --band")
    draws, level, seed = (200 if draws is None else draws, 0.9 if level is None else level,
                          seed_from(0 if seed is None else seed))  # --band's draws: refused before the run
    v, sea_line = known_sea(vessel_from(vessel, model, "nominal"), sea)
    if band and not v.uncertainty:  # said before any work is done
        raise TwinError(f"--band needs a vessel file with the identification's uncertainty ('{v.name}' has none: "
                        f"write one with twin identify)")
    if band and (draws < 2 or not 0.0 < level < 1.0):
        raise TwinError("--band needs --draws of at least 2 and a --level between 0 and 1")
    if band:
        from ..scale.batches import executor_from  # late: 0.16 s, only for --band

        check_drawable(v)
        executor = executor_from(ray)  # an unreachable --ray address is refused before the work
    fitted = (envelope_from(v.uncertainty["fitted_on"], f"{model or v.name}: uncertainty.fitted_on")
              if "fitted_on" in v.uncertainty else None)  # a bad block is refused before the work
    recs = read(recordings, channels_from(channels))
    if band:  # every draw's samples (a second apart, u, v, r, position and heading) are kept for the band
        draws_fit(draws, sum(r.duration_s() for r in recs), 6, "--draws of --band on these recordings")
    warn_recordings(recs)
    wind = "measured" if wind_measured else None
    check_wind_and_inputs(recs, wind, v)  # before any work
    if by == "rest" and any(r.pwm.has("left_us") for r in recs):  # said before the work, in the option's words
        raise TwinError("--by rest bands by how long a propeller-and-rudder ship's propeller has been stopped; "
                        "these recordings log thruster PWM (band a boat's by speed, yaw_rate, drift or input_0)")
    with progress_bar("evaluate") as progress:
        ev = evaluate(v, recs, stride_s=stride, wind=wind, by=by, calibrated=calibration, progress=progress)
    calibrations = ev.calibrations
    out = {"vessel": v.name, "model": str(model) if model else None, "recordings": [str(p) for p in recordings],
           "calibrations": [c.to_dict() for c in calibrations], "wind": wind or "none",
           "sea_drift_ned_m_s": list(v.environment.wave_drift_ned),
           "metrics_uncalibrated": ev.metrics_uncalibrated,
           # --no-calibration: the scores as logged, as the splits are
           "metrics": ev.metrics, "by_manoeuvre": ev.by_manoeuvre}  # --no-calibration: as logged
    if by:
        out["by_state"] = {"state": STATE_NAMES[by], "bands": [asdict(b) for b in ev.by_state]}
    names = ", ".join(p.name for p in recordings) + (", with the measured wind" if wind else "")
    twin_name = f"{model.name} ({v.name})" if model is not None else v.name
    # as logged: without the offsets the twin holds for logs of these names either (twin.evaluate)
    used = with_log_calibrations(v, calibrations) if calibration else \
        replace(v, sensors=replace(v.sensors, heading_bias_by_log_deg=()))
    horizon = manoeuvre_horizon_s(v, fitted)
    if sea_line:
        say(sea_line)
    for c in calibrations:
        say(escape(f"calibration: {calibration_line(c, applied=calibration, twin=v)}"))
    say_unlogged_supply(recs, v)
    applied = calibration and any(c.heading_bias_deg is not None for c in calibrations)
    typer.echo(format_metrics(out["metrics_uncalibrated"], f"{twin_name} on {names}, as logged"
                              + ("" if applied or not calibration else " (no log's compass offset was applied)")))
    if applied:
        typer.echo(format_metrics(out["metrics"], f"{twin_name} on {names}, each log's compass calibration applied"))
    typer.echo(format_by_manoeuvre(out["by_manoeuvre"], f"where the {horizon:g}-s free runs miss, by what the inputs "
                                                        "ask (each group's share of 1 − R²)"))
    out["stand_ins"] = list(v.uncertainty.get("stand_ins", [])) if v.uncertainty else []
    stand_ins = stand_in_text(out["stand_ins"])
    if stand_ins:
        note(f"note: this twin carries coefficients its fit moved beyond what their beliefs allow ({stand_ins}): "
             "each stands in for something its form lacks, and holds beyond the runs it was fitted on only as far "
             "as that lack does")
    preps_used = prepared(recs, used)
    if turns:
        from ..verify.manoeuvres import recorded_turns  # late: only for --turns

        held = recorded_turns(used, preps_used, wind)
        out["turns"] = [asdict(t) for t in held]
        for line in recorded_turn_lines(held):
            say(line)
    longest = max((p.t[seg.stop - 1] - p.t[seg.start] for p in preps_used for seg in p.segments), default=0.0)
    short = [f"{h:g}-s" for h in (10.0, 30.0) if longest < h]
    if short:  # said, not left to a table of dashes
        note(f"note: the longest stretch without a dropout lasts {longest:.1f} s: the {' and '.join(short)} free runs "
             "have nothing to score")
    if by:
        what = state_display(STATE_NAMES[by], "propeller_rudder" if used.thrusters.kind == "propeller_rudder" else "pwm")[0]
        title = (f"where the {horizon:g}-s free runs miss, by {what} (share of 1 − R²; gain: measured on "
                 "predicted; corr: their correlation)")
        typer.echo(format_by_state(ev.by_state, title))
    if rrd is not None:
        # late: the writers and replay (0.3 s) only for --rrd
        from ..engine.mjcf import compile_vessel
        from ..outputs import write
        from ..replay import free_run_views

        write(free_run_views(used, prepared(recs, used)), rrd, geometry=compile_vessel(v).geometry,
              vessel_name=v.name, mjcf=v.mjcf, view=True)
        say(f"wrote {rrd} (open with: rerun {rrd})")
    if band:
        from ..scale.montecarlo import band_coverage  # late: 0.3 s, only for --band

        with progress_bar("band") as progress:
            coverage = band_coverage(used, prepared(recs, used), draws=draws, seed=seed, level=level,
                                     executor=executor, progress=progress, wind=wind)
        typer.echo(coverage.text())
        out["band"] = coverage.to_dict()
    write_json(json_out, out)
