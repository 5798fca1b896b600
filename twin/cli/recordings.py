"""`twin info`, `twin convert`, `twin view`: recordings read, converted and shown."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Optional

import typer

from ..drive import INPUT_WORDS, inputs_mismatch
from ..errors import TwinError
from ..files import RUNS, check_new, write_bytes_atomic
from ..recording import DROPOUTS, MOVED, check_no_shared_stretch, check_not_misread, format_summary
from ..viz.report import comparison_png
from .app import (REPORT_HELP, all_or_nothing_outputs, CHANNELS_HELP, FORCE_HELP, MODEL_HELP, VESSEL_HELP, app, channels_from, check_distinct, 
                  check_outputs, check_recordings_distinct,
                  check_wind_and_inputs, memory_for, note, positive, progress_bar, recordings_in, samples_fit, say,
                  vessel_from, warn_recordings)
from .ident import calibration_line

# a converted copy's grid is no finer than a tenth of the sample period of its fastest synchronised stream (finer
# repeats each sample on more than ten rows: rows, not information) and holds at most MAX_GRID_ROWS rows (a day's
# log on a 0.01 s grid is 8.6 million; a 30-s log on a 1 µs grid wrote 30 million rows, 1.5 GB, in over 90 s)
GRID_ROWS_PER_SAMPLE = 10
MAX_GRID_ROWS = 10_000_000

RECORDING_HELP = "recordings: ArduPilot .bin or .tlog, .csv (generic, BlueBoat or Esso Osaka layout), .mcap"
INFO_HELP = RECORDING_HELP + ", or folders of them"


def check_regular(path: Path) -> None:
    """Refuse a path that exists but is neither a file nor a folder (/dev/null, /dev/zero, a FIFO, a
    socket): the readers would call it missing, and a pipe would be read until a writer closed it."""
    if path.exists() and not path.is_dir() and not path.is_file():
        raise TwinError(f"{path}: not a regular file (a device, a pipe or a socket): give a recording file")


def _expanded(files: list[Path]) -> list:
    """The files given, a folder standing for the recordings in it (as for identify and diagnose); a
    folder without any, or a path that is no regular file, is its TwinError in the list, reported in
    its turn."""
    out: list = []
    for p in files:
        if not p.is_dir():
            try:
                check_regular(p)
                out.append(p)
            except TwinError as exc:
                out.append(exc)
            continue
        try:
            out += recordings_in([p])
        except TwinError as exc:
            out.append(exc)
    return out


@app.command()
def info(
    files: list[Path] = typer.Argument(..., metavar="FILES", help=INFO_HELP),
    channels: Optional[str] = typer.Option(None, help=CHANNELS_HELP),
    vessel: Optional[str] = typer.Option(None, help=VESSEL_HELP + " (with it: each log's compass calibration)"),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP + " (with it: each log's compass calibration)"),
):
    """Summarise recordings: duration, rates, signals, gaps, what was dropped and why, how late the heading
    is against the gyro (where the log has one); with --vessel or
    --model, each log's compass calibration from its kinematics (the logs read together, as identify,
    evaluate and diagnose read and apply it)."""
    # late: the command's stack (readers, twin.prepare, twin.fit.kinematic: 0.5 s) would be paid at every `twin --help`
    from ..formats import read_recording
    from ..prepare.outliers import describe
    from ..prepare.prepared import outlier_counts as counted
    from ..prepare.timing import heading_lag

    v = vessel_from(vessel, model) if vessel is not None or model is not None else None  # before any work
    mapping = channels_from(channels)
    failed, read = 0, []
    expanded = _expanded(files)
    # one log twice is refused as every command refuses it (with --vessel it would be calibrated twice)
    check_recordings_distinct([p for p in expanded if isinstance(p, Path) and p.is_file()])
    for path in expanded:  # one bad file must not hide the others' summaries
        try:
            if isinstance(path, TwinError):
                raise path
            rec = read_recording(path, channels=mapping)
        except TwinError as exc:
            typer.echo(f"error: {exc}", err=True)
            failed += 1
            continue
        typer.echo(f"== {path}")
        typer.echo(format_summary(rec.summary()))
        for line in describe(counted(rec)):
            typer.echo(f"  {line}")
        if len(rec.imu) and len(rec.heading):
            typer.echo(f"  {heading_lag(rec).text()}")
        read.append(rec)
    try:  # info describes each log; identify, evaluate and diagnose refuse a stretch given twice
        check_no_shared_stretch(read)
    except TwinError as exc:
        typer.echo(f"note: {exc}")
    if v is not None:
        failed += _calibrations(read, v)
    if failed:
        raise typer.Exit(2)


def _calibrations(recordings: list, vessel) -> int:
    """Print each log's kinematic compass calibration (twin.fit.calibrate); 1 when it cannot be made."""
    # late: the fitting stack (0.54 s) would be paid at every `twin --help`
    from ..ident.identify import calibrate, held_inputs
    from ..prepare import prepare

    usable, failed = [], 0
    wanted = vessel.thrusters.input_kind
    for r in recordings:
        name = Path(r.source).name
        held = held_inputs(r)
        if not (len(r.gnss) and len(r.heading)):
            typer.echo(f"calibration: {name}: no compass calibration (it needs GNSS and heading)")
        elif r.misread:  # identify, evaluate and diagnose refuse it: a calibration of it would apply to nothing
            typer.echo(f"calibration: {name}: none, as the log is read in a unit it is not in (its warning above)")
        elif held is not None and held != wanted:  # another kind of vessel's log: identify would refuse it too
            typer.echo(f"error: calibration: {name}: {inputs_mismatch(vessel.name, wanted, held)}", err=True)
            failed = 1
        else:
            try:  # one log that cannot be prepared must not hide the others' calibrations
                prepare(r)
                usable.append(r)
            except TwinError as exc:  # what the log holds is said above; that it gives no calibration is a finding
                typer.echo(f"calibration: {name}: no compass calibration ({str(exc).removeprefix(name + ': ')})")
    if not usable:
        return failed
    try:
        calibrated_vessel, calibrations = calibrate(usable, vessel)
    except TwinError as exc:
        typer.echo(f"error: calibration: {exc}", err=True)
        return 1
    typer.echo(f"== each log's compass calibration ({vessel.name}; identify, evaluate and diagnose apply it)")
    for c in calibrations:
        typer.echo(f"calibration: {calibration_line(c, twin=vessel)}")
    if wanted == "pwm":
        typer.echo(f"calibration: {_throttle_line(usable, calibrated_vessel, calibrations)}")
    return failed


def _throttle_line(recordings: list, vessel, calibrations) -> str:
    """Whether the compass error follows the throttle over these logs (twin.fit.calibrate.throttle_dependence)."""
    # late: the fitting stack (0.54 s) would be paid at every `twin --help`
    from ..fit.calibrate import MIN_THROTTLE_STRETCHES, throttle_dependence
    from ..ident.identify import prepared

    throttled = [k for k, r in enumerate(recordings) if len(r.pwm)]
    unthrottled = [Path(r.source).name for r in recordings if not len(r.pwm)]
    missing = (f"{', '.join(unthrottled)}: no thruster outputs logged (give --channels LEFT,RIGHT if its servo "
               "outputs drive the thrusters)") if unthrottled else ""
    if not throttled:
        return f"compass error following the throttle: not told ({missing})"
    dep = throttle_dependence(prepared([recordings[k] for k in throttled], vessel), vessel,
                              [calibrations[k].drift_ned_m_s for k in throttled])
    left_out = f"; left out: {missing}" if missing else ""
    if dep is None:
        return (f"compass error following the throttle: not told (fewer than {MIN_THROTTLE_STRETCHES} straight stretches "
                f"ahead, or too few pieces of them{left_out})")
    return dep.text() + (" (`twin diagnose` judges `compass_motor` on the dynamics; ArduPilot's compassmot "
                         "calibration measures it)" if dep.shown else "") + (f" ({left_out[2:]})" if missing else "")


def check_grid_rows(rec, grid_dt_s: float, name: str) -> None:
    """Refuse, before the conversion, a --grid-dt that would write an unreasonable number of rows for this
    log (GRID_ROWS_PER_SAMPLE, MAX_GRID_ROWS); a log whose streams keep their own times (no GNSS or no
    heading: twin.prepare.convert) has no grid and is not checked."""
    if not (len(rec.gnss) and len(rec.heading)):
        return
    rates_hz = [s.median_rate_hz() for s in (rec.gnss, rec.heading, rec.pwm, rec.prop_rudder)]
    fastest_hz = max((r for r in rates_hz if math.isfinite(r)), default=0.0)
    duration_s = rec.duration_s()
    by_rows_s = duration_s / MAX_GRID_ROWS
    by_rate_s = 1.0 / (GRID_ROWS_PER_SAMPLE * fastest_hz) if fastest_hz > 0 else 0.0
    finest_s = max(by_rows_s, by_rate_s)
    if grid_dt_s >= finest_s * 0.99:  # 1 %: the finest grid is told to 3 digits, and that figure is accepted
        return
    why = (f"a tenth of the {1 / fastest_hz:.3g} s sample period of its fastest synchronised stream: on a finer grid "
           "each sample fills more than ten rows" if by_rate_s >= by_rows_s else f"{MAX_GRID_ROWS:,} rows at most")
    raise TwinError(f"--grid-dt {grid_dt_s:g} on {name}: {duration_s / grid_dt_s + 1:,.0f} rows for its "
                    f"{duration_s:.1f} s; the finest grid for this log is {finest_s:.3g} s ({why})")


@app.command()
@all_or_nothing_outputs
def convert(
    src: Path = typer.Argument(..., metavar="SRC", help="input recording: .bin, .tlog, .csv, .mcap"),
    dst: Optional[Path] = typer.Argument(None, metavar="[DST]", help="output: .csv (generic layout), .mcap, .tlog or "
                                                                     ".bin (or give it as --out)"),
    out: Optional[Path] = typer.Option(None, "--out", help="the output, as every other command names it (or DST)"),
    channels: Optional[str] = typer.Option(None, help=CHANNELS_HELP),
    grid_dt: Optional[float] = typer.Option(None, help="put GNSS, heading and PWM on one grid of this period, s "
                                                       "[Morel-2024 §5.1], GNSS and PWM held until their next sample, "
                                                       "the heading interpolated (no finer "
                                                       "than a tenth of the fastest one's own); without it every "
                                                       "stream keeps its own times"),
    force: bool = typer.Option(False, "--force", help=FORCE_HELP),
):
    """Convert a recording to another format, every stream at its own times; with --grid-dt, GNSS,
    heading and PWM synchronised on one grid [Morel-2024 §5.1] when it has GNSS and heading."""
    # late: the command's stack (the readers and writers, twin.prepare: 0.1 s) would be paid at every `twin --help`
    from ..formats import read_recording, write_recording
    from ..formats.mcap import MCAP_DAMAGE
    from ..prepare.convert import for_conversion, not_kept

    if (dst is None) == (out is None):
        raise TwinError("give the output once: as DST after SRC, or as --out" if dst is not None else
                        "give the output: twin convert SRC DST (or --out DST)")
    dst = dst if dst is not None else out
    check_outputs([dst], (".csv", ".mcap", ".tlog", ".bin"), "output")
    check_distinct({"output": dst}, [src], keep_data=False)  # even with --force: the input is never replaced
    check_regular(src)
    recordings_in([src])  # an input that is no recording is the first thing to fix, before the output's
    check_new([dst], force, "output", RUNS)  # a converted copy must not silently replace a log
    if grid_dt is not None:
        positive(grid_dt, "--grid-dt")
    rec = read_recording(src, channels=channels_from(channels))
    check_not_misread([rec])  # a copy in another format would carry the error on without the word of it
    warn_recordings([rec])
    if grid_dt is None:
        conversion = for_conversion(rec)
    else:
        samples_fit(rec.duration_s(), grid_dt, f"--grid-dt on {src.name}")
        check_grid_rows(rec, grid_dt, src.name)
        with memory_for(f"--grid-dt {grid_dt:g} on {src.name}"):
            conversion = for_conversion(rec, grid_dt)
    write_recording(conversion.recording, dst)
    say(f"wrote {dst}: {conversion.recording.duration_s():.1f} s, {conversion.timing}")
    for reason, count in rec.dropped:  # what `twin info` lists as dropped is not in the copy either
        if DROPOUTS not in reason:
            note(f"note: not in the copy: {reason} ({count})")
    for line in rec.notes:  # a cut-short MCAP file: what it lost is not in the copy
        if line.startswith(MCAP_DAMAGE):
            note(f"note: not in the copy: {line}")
    for line in not_kept(conversion.recording, dst.suffix.lower()):
        note(f"note: {line}")
    moved = [line.split(":")[0] for line in rec.notes if line.startswith(MOVED)]
    if moved and dst.suffix.lower() in (".csv", ".mcap"):  # no parameters there to put the delays back by
        note(f"note: the copy holds the {' and '.join(moved)} as read (above), at the times they measured")


@app.command()
@all_or_nothing_outputs
def view(
    files: list[Path] = typer.Argument(..., metavar="FILES", help="recordings to show"),
    sim: bool = typer.Option(False, "--sim", help="replay the twin with the recorded inputs beside the real track"),
    vessel: Optional[str] = typer.Option(None, help=VESSEL_HELP + " (for --sim and the sensors' calibration)"),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP),
    out: Optional[Path] = typer.Option(None, help="rerun recording to write (default: ./STEM.view.rrd, STEM of the "
                                                  "first input, in the current folder)"),
    png: Optional[Path] = typer.Option(None, help=f"also write a PNG of the comparison {REPORT_HELP}"),
    channels: Optional[str] = typer.Option(None, help=CHANNELS_HELP),
    smoother: str = typer.Option("savgol", help="velocities: savgol [Morel-2024] or model (EKF+RTS on the vessel model)"),
    wind_measured: bool = typer.Option(False, "--wind-measured",
                                       help="--sim: take each recording's measured wind (its anemometer stream) as a "
                                            "known input of the replay"),
):
    """Real track and the twin's replay on one timeline, in rerun (and a PNG)."""
    # late: the command's stack (the readers, writers and replay: 0.3 s) would be paid at every `twin --help`
    from ..formats import read_recording
    from ..outputs import write
    from ..replay import RUN_ENVIRONMENT, in_its_environment, view_runs

    # the working folder, never beside the input (a shared data folder); .view.rrd, not the STEM.rrd that
    # `twin simulate --out STEM.csv --out STEM.rrd` may have written there
    out = out or Path(files[0].stem + ".view.rrd")
    check_outputs([out], (".rrd",), "--out")
    check_outputs([png], (".png",), "--png")
    check_distinct({"--out": out, "--png": png}, [*files, model])
    for path in files:
        check_regular(path)
    check_recordings_distinct(files)  # one log twice is two identical tracks: refused as identify refuses it
    v = vessel_from(vessel, model) if (vessel or model) else None
    if (sim or smoother == "model") and v is None:
        raise TwinError("--sim and --smoother model need --vessel NAME or --model FILE")
    if smoother == "model" and v.thrusters.input_kind != "pwm":  # before reading: the smoother's own check is late
        raise TwinError(f"the model-based smoother (--smoother model) drives the vessel model with the recorded "
                        f"thruster PWM, and vessel '{v.name}' is driven by "
                        f"{INPUT_WORDS.get(v.thrusters.input_kind, v.thrusters.input_kind)}: use --smoother savgol")
    if wind_measured and not sim:
        raise TwinError("--wind-measured is a known input of the twin's replay: give it with --sim")
    mapping = channels_from(channels)
    with progress_bar("view") as progress:
        recordings = []
        for k, path in enumerate(files):
            progress(f"reading {path.name}", k, len(files))
            recordings.append(read_recording(path, channels=mapping))
        warn_recordings(recordings)
        wind = "measured" if wind_measured else None
        check_wind_and_inputs(recordings, wind, v, replayed=sim)
        progress("preparing" + (" and replaying the twin" if sim else ""), len(files), len(files))
        runs = view_runs(recordings, v, sim=sim, smoother=smoother, wind=wind)
        progress(f"writing {out.name}")
        write(runs, out, vessel_name=v.name if v else "", mjcf=v.mjcf if v else None, view=True)
    say(f"wrote {out} (open with: rerun {out})")
    for rec in recordings if sim else []:
        kept = {k: rec.meta[k] for k in RUN_ENVIRONMENT if k in rec.meta}
        if kept and in_its_environment(v, rec) is not v:
            note(f"note: {Path(rec.source).name}: the twin replayed in the run's own "
                 + " and ".join(w for w, k in (("current", "current_speed_m_s"), ("wind", "wind_speed_m_s")) if k in kept)
                 + f" ({', '.join(f'{k} {x:g}' for k, x in kept.items())}, from its metadata)")
    if png is not None:
        write_bytes_atomic(png, comparison_png(runs, f"{', '.join(p.name for p in files)}"
                                                     + (f": recorded vs twin ({v.name}"
                                                        + (", measured wind" if wind else "") + ")" if sim else "")))
        say(f"wrote {png}")
