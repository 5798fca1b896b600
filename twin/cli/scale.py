"""`twin montecarlo`, `twin dataset-shards`, `twin fleet`: many twins, locally on every core or on
a Ray cluster (--ray); registered on the main CLI app."""
from __future__ import annotations

import math
import shutil
from pathlib import Path
from typing import Optional

import typer

from ..drive import read_inputs_csv
from ..errors import TwinError
from ..files import BAND, output_scope, write_text_atomic
from ..files import check_new
from ..vessel import load
from .app import (all_or_nothing_outputs, listed, FORCE_HELP, MODEL_HELP, PWM_VESSEL_HELP, VESSEL_HELP, app, at_least, check_distinct, 
                  check_outputs,
                  check_recordings_distinct, counted, draws_fit, effect_names, memory_bytes, memory_for, note, positive, progress_bar, recordings_in, samples_fit,
                  say, seed_from, sensor_noise, vessel_from, window_s, write_json)
from .run import SEA_HELP, sea_from

RAY_HELP = ("run on Ray: auto (the cluster this machine belongs to, `ray start --head`), local (a private Ray on "
            "this machine), ray://HOST:10001 or HOST:6379; default: this machine's cores, no Ray")
CPUS_HELP = "CPUs of a Ray node each task takes (its rollouts use as many threads)"
RETRIES_HELP = "times Ray runs a task again whose worker or node died"
VARY_HELP = "a coefficient (or mass) times a factor drawn log-uniformly, NAME=LO..HI (repeatable), e.g. Xu=0.5..2"
EFFECT_HELP = ("an effect with values fixed or drawn uniformly, NAME=V|LO..HI,... (repeatable; `twin effects`), "
               "e.g. current=0..0.3,0..360")
MC_OUTPUTS = (".csv", ".json", ".png", ".rrd")
# what one vessel's segment takes on disk (measured: 0.17 MB of .mcap with the realistic noise; a lower
# bound for the other formats) and one vessel in the index held in memory until it is written
SEGMENT_FILE_BYTES, VESSEL_INDEX_BYTES = 1.5e5, 2.0e3


def _executor(ray: Optional[str], cpus_per_task: int, retries: int):
    from ..scale.batches import executor_from  # late: 0.16 s more at every `twin --help`

    return executor_from(ray, cpus_per_task=cpus_per_task, retries=retries)


def _variation(vessel, vary: list[str], effect: list[str], covariance: bool, share: float = 1.0):
    from ..scale.draws import Variation, parse_effect_range, parse_factor  # late: 0.14 s more at every `twin --help`

    return Variation(covariance, tuple(parse_factor(v, vessel) for v in vary),
                     tuple(parse_effect_range(e) for e in effect), share)


@app.command("montecarlo")
@all_or_nothing_outputs
def montecarlo_command(
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP + "; its uncertainty block gives the draws"),
    vessel: Optional[str] = typer.Option(None, help=VESSEL_HELP + " (with --no-covariance and --vary/--effect)"),
    scenario: Optional[str] = typer.Option(None, help="step | turn | zigzag | spin | random (default zigzag): run "
                                                      "closed loop once by the nominal twin, its inputs replayed"),
    inputs: Optional[Path] = typer.Option(None, help="CSV: t + pwm_left,pwm_right (µs), thrust_left,"
                                                     "thrust_right (N) or, for a propeller-and-rudder ship, "
                                                     "prop_rps,rudder_deg (rps, deg); each row held until the "
                                                     "next, an empty cell holds its input's last value"),
    duration: Optional[float] = typer.Option(None, help="mission length, s (default 120, or the inputs' last time)"),
    draws: int = typer.Option(1000, help="number of twins drawn"),
    seed: int = typer.Option(0, help="root seed (batch i draws from its i-th child)"),
    level: float = typer.Option(0.9, help="central share of the band (0.9: 5th to 95th percentile)"),
    sample_dt: float = typer.Option(0.5, help="band sample period, s"),
    covariance: bool = typer.Option(True, "--covariance/--no-covariance",
                                    help="draw the identified coefficients from the vessel file's covariance"),
    vary: list[str] = typer.Option([], help=VARY_HELP),
    effect: list[str] = typer.Option([], help=EFFECT_HELP),
    out: list[Path] = typer.Option(..., help="output(s): .csv, .json (band), .png (plot), .rrd (rerun) (repeatable)"),
    batch_size: int = typer.Option(64, help="draws per batch (a batch is one rollout and one cluster task)"),
    ray: Optional[str] = typer.Option(None, help=RAY_HELP),
    cpus_per_task: int = typer.Option(1, help=CPUS_HELP),
    retries: int = typer.Option(3, help=RETRIES_HELP),
    sea: Optional[str] = typer.Option(None, help=SEA_HELP + "; every draw in its own realisation of the sea "
                                                 "(seeded from --seed)"),
    form_error: bool = typer.Option(True, "--form-error/--no-form-error",
                                    help="widen the band by the twin's error on runs left out of its fit, where "
                                         "the vessel file carries it (`twin identify` writes it); without it the "
                                         "band is the coefficients' spread alone"),
    force: bool = typer.Option(False, "--force", help=FORCE_HELP),
):
    """Prediction bands of an identified twin: draws from its covariance through a mission."""
    from ..scale import montecarlo as mc  # late: 0.3 s more at every `twin --help`

    check_outputs(out, MC_OUTPUTS, "--out")
    check_distinct({"--out": out}, [inputs, model], keep_data=False)
    check_new(out, force, "--out", (BAND,))  # a band over a band only
    if scenario is not None and inputs is not None:
        raise TwinError("give --scenario or --inputs, not both")
    if duration is not None:
        positive(duration, "--duration")
    positive(sample_dt, "--sample-dt")
    if draws < 2:  # a band's percentiles need a spread: one draw is a run, not a band
        raise TwinError(f"--draws must be a whole number of 2 or more, got {draws}")
    if not 0.0 < level < 1.0:  # the band's share (the library says "band level")
        raise TwinError(f"--level must lie between 0 and 1 (0.9: the 5th to the 95th percentile), got {level:g}")
    at_least(batch_size, 1, "--batch-size")
    seed_from(seed)
    v = vessel_from(vessel, model, "nominal")
    variation = _variation(v, vary, effect, covariance)
    mc.check_variation(v, variation)
    sea_state = _sea_for(v, sea, seed)
    executor = _executor(ray, cpus_per_task, retries)
    if inputs is not None:
        series = read_inputs_csv(inputs)
        length = duration if duration is not None else float(series.t[-1])
        if not length > 0:
            raise TwinError(f"{inputs.name}: give --duration (the inputs end at t = {series.t[-1]:g} s)")
        samples_fit(length, sample_dt, "--duration at --sample-dt")
        mission = mc.inputs_mission(series, length, sample_dt, source=f"inputs {inputs.name}", sea=sea_state)
    else:
        samples_fit(duration or 120.0, sample_dt, "--duration at --sample-dt")
        with memory_for(f"--duration {duration or 120.0:g} at --sample-dt {sample_dt:g}"):
            mission = mc.scenario_mission(v, scenario or "zigzag", duration or 120.0, sample_dt, seed, sea_state)
    # every draw's six states are kept for the band, then gathered and compared with the nominal: about
    # three copies of them
    draws_fit(draws, mission.duration_s / sample_dt + 1, 18, "--draws at --duration and --sample-dt")
    with progress_bar("montecarlo") as progress, memory_for("--draws at --duration and --sample-dt"):
        result = mc.run(v, mission, draws, seed=seed, variation=variation, level=level, batch_size=batch_size,
                        executor=executor, progress=progress, form_error=form_error)
    for path in out:
        _write_band(result, path)
    _report(result)


def _sea_for(vessel, text: Optional[str], seed: int):
    """--sea → physics.waves.Sea, refused on one line before any work when the vessel cannot run in it."""
    if text is None:
        return None
    from ..engine.sixdof import check_sea_for  # late: mujoco, 0.16 s more at every `twin --help`

    sea = sea_from(text, seed)
    check_sea_for(vessel, sea)
    return sea


def _write_band(result, path: Path) -> None:
    from ..scale import views  # late: 0.27 s more at every `twin --help`

    suffix = path.suffix.lower()
    if suffix == ".json":
        write_json(path, result.to_dict())
        return
    if suffix == ".csv":
        write_text_atomic(path, result.to_csv_text())
    elif suffix == ".png":
        views.write_png(result, path)
    else:
        views.write_rrd(result, path)
    say(f"wrote {path}" + (f" (open with: rerun {path})" if suffix == ".rrd" else ""))


def _report(result) -> None:
    from ..scale.montecarlo import level_percentiles  # late: 0.3 s more at every `twin --help`

    b = result.band
    lo_p, hi_p = level_percentiles(b.level)
    rate = result.simulated_s / result.seconds if result.seconds > 0 else float("nan")
    sea = result.mission.sea
    say(f"{result.vessel.name}: {result.draws} draws of {result.mission.duration_s:g} s ({result.mission.source}"
        f"{'' if sea is None else '; in ' + sea.text() + ', each draw its own realisation'}) "
        f"in {result.seconds:.1f} s on {result.executor}, {rate:.0f} simulated s/s; {len(result.diverged)} diverged "
        "(left out of the band: a twin that runs away predicts nothing), "
        f"{result.rejected} draws redrawn as unphysical (damping that stops dissipating, or a mass matrix not "
        "positive-definite)")
    if result.rejected > result.draws:
        say("more draws fell outside the physical range than were kept: the recordings pin the twin's coefficients "
            "loosely (few or short runs), and its band is wide for that; `twin identify` on more runs narrows it")
    k = 180.0 / math.pi
    dev = b.values["deviation"]
    psi = b.nominal["psi"][-1]
    say(f"at t = {b.t_s[-1]:g} s: distance from nominal median {dev[b.percentiles.index(50.0), -1]:.2f} m, "
        f"{100 * b.level:g} % within {b.interval('deviation')[1][-1]:.2f} m; heading "
        f"[{k * b.at('psi', lo_p)[-1]:.1f}, {k * b.at('psi', hi_p)[-1]:.1f}]° (nominal {k * psi:.1f}°), "
        f"u [{b.at('u', lo_p)[-1]:.3f}, {b.at('u', hi_p)[-1]:.3f}] m/s ({100 * b.level:g} % band)")
    if b.parameters_only is not None:
        alone = b.parameters_only["deviation"][b.percentiles.index(level_percentiles(b.level, True)[1]), -1]
        say(f"the band holds the twin's error on runs left out of its fit beside its coefficients' spread "
            f"(the coefficients' alone: {100 * b.level:g} % within {alone:.2f} m; --no-form-error for that band)")
    elif result.vessel.uncertainty and "form_error" not in result.vessel.uncertainty:
        say("the band is the coefficients' spread alone: the vessel file carries no error on left-out runs "
            "(`twin identify` writes one), and a twin is wrong in its form as well as in its numbers")


@app.command("dataset-shards")
def dataset_shards_command(
    vessel: Optional[str] = typer.Option(None, help=PWM_VESSEL_HELP),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP),
    out: Path = typer.Option(..., help="folder to write the shards and index.json/index.csv into (new or empty)"),
    vessels: int = typer.Option(100, help="number of randomised vessels (one recording each)"),
    per_shard: int = typer.Option(16, help="vessels per shard (a shard is one batch and one cluster task)"),
    segments: int = typer.Option(8, help="trajectory segments per vessel"),
    manoeuvres: str = typer.Option(",".join(("rc", "forward_constant", "forward_varying", "zigzag", "circle_constant",
                                             "circle_varying")), help="manoeuvres to cycle through (`twin dataset`)"),
    vary: list[str] = typer.Option([], help=VARY_HELP),
    effect: list[str] = typer.Option([], help=EFFECT_HELP),
    effect_share: float = typer.Option(1.0, help="chance that each --effect is present in a vessel at all"),
    covariance: bool = typer.Option(False, "--covariance/--no-covariance",
                                    help="also draw the coefficients from the vessel file's identified covariance"),
    noise: str = typer.Option("realistic", help="sensor noise: realistic | rtk | noisy | none | GNSS_M,HEADING_DEG"),
    fmt: str = typer.Option("mcap", "--format", help="recording format: mcap | tlog | bin | csv"),
    seed: int = typer.Option(0, help="root seed (shard i draws from its i-th child)"),
    resume: bool = typer.Option(False, "--resume", help="keep the shards a cut-short run with the same settings "
                                                        "completed in --out (a shard whose files changed since is "
                                                        "made again)"),
    sea: Optional[str] = typer.Option(None, help=SEA_HELP + "; every vessel in its own realisation of the sea "
                                                 "(seeded by its recording's seed)"),
    ray: Optional[str] = typer.Option(None, help=RAY_HELP),
    cpus_per_task: int = typer.Option(1, help=CPUS_HELP),
    retries: int = typer.Option(3, help=RETRIES_HELP),
):
    """Synthetic identification datasets at scale: randomised vessels, sharded files, one truth index."""
    from ..scale.datasets import Settings, generate_shards  # late: 0.26 s more at every `twin --help`

    seed_from(seed)
    if effect_share != 1.0 and not effect:  # it sets how often each --effect is drawn: without one it does nothing
        raise TwinError("--effect-share applies only with --effect")
    _shards_fit(vessels, per_shard, segments, out)
    v = vessel_from(vessel, model, "nominal")
    sensor_noise(noise)  # a bad profile fails now, not in every worker
    names = tuple(listed(manoeuvres, "--manoeuvres"))
    variation = _variation(v, vary, effect, covariance, effect_share)
    settings = Settings(vessels, per_shard, segments, names, noise, "." + fmt.lower().lstrip("."), seed, variation,
                        _sea_for(v, sea, seed))
    executor = _executor(ray, cpus_per_task, retries)
    with progress_bar("dataset-shards") as progress:
        result = generate_shards(v, settings, out, executor=executor, resume=resume, progress=progress)
    logged = sum(e["logged_s"] for e in result.entries)
    if result.reused:
        note(f"note: {counted(result.reused, 'shard')} {'was' if result.reused == 1 else 'were'} already complete in "
             f"{out} and kept")
    say(f"wrote {out}: {counted(len(result.entries), 'vessel')} in {counted(result.index['shards'], 'shard')} "
        f"({result.made} made now, "
        f"{result.bytes_written / 1e6:.1f} MB of recordings), {logged / 3600:.2f} h logged; index {out / 'index.json'}")


def _shards_fit(vessels: int, per_shard: int, segments: int, out: Path) -> None:
    """Refuse, before any work, a dataset whose index would not fit in half of this machine's memory
    or whose recordings would not fit on the disk --out is on (it grew for minutes, then failed)."""
    at_least(vessels, 1, "--vessels")
    at_least(per_shard, 1, "--per-shard")
    at_least(segments, 1, "--segments")
    memory = memory_bytes()
    if memory is not None and vessels * VESSEL_INDEX_BYTES > memory / 2:
        raise TwinError(f"--vessels {vessels}: their index alone holds about {vessels * VESSEL_INDEX_BYTES / 2**30:.3g} "
                        f"GiB, more than half of this machine's {memory / 2**30:.0f} GiB")
    folder = next((p for p in (out, *out.parents) if p.exists()), Path("."))
    free = shutil.disk_usage(folder).free
    need = vessels * segments * SEGMENT_FILE_BYTES
    if need > free:
        raise TwinError(f"--vessels {vessels} × --segments {segments}: at least {need / 2**30:.3g} GiB of recordings, "
                        f"more than the {free / 2**30:.3g} GiB free where --out is")


@app.command("fleet")
@output_scope()  # its reports land as they come: a summary's file that appears meanwhile is kept (files._put)
def fleet_command(
    recordings: list[Path] = typer.Argument(None, metavar="RECORDINGS", help="recordings: .tlog, .bin, .csv, .mcap, "
                                                                            "or folders of them (or --manifest)"),
    vessel: Optional[str] = typer.Option(None, help=VESSEL_HELP),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP),
    manifest: Optional[Path] = typer.Option(None, help="CSV with a recording column and optional vessel, day columns"),
    out: Path = typer.Option(..., help="folder for one report per log, fleet.json and fleet.md"),
    effects: Optional[str] = typer.Option(None, help="only these candidate effects (comma separated; `twin effects`)"),
    window: Optional[float] = typer.Option(None, help="free-run window length of the diagnoses, s"),
    html: bool = typer.Option(False, "--html", help="also an HTML report per log"),
    wind_measured: bool = typer.Option(False, "--wind-measured",
                                       help="take each log's measured wind (its anemometer stream) as a known input of "
                                            "its diagnosis, as `twin diagnose --wind-measured`"),
    batch_size: int = typer.Option(1, help="logs per batch (a batch is one cluster task)"),
    ray: Optional[str] = typer.Option(None, help=RAY_HELP),
    cpus_per_task: int = typer.Option(1, help=CPUS_HELP),
    retries: int = typer.Option(3, help=RETRIES_HELP),
    force: bool = typer.Option(False, "--force", help="replace the fleet summary (fleet.json, fleet.md) a "
                                                      "previous run left in --out"),
):
    """`twin diagnose` over many logs: one report per log and a fleet summary of the effects found."""
    # late: the command's stack (twin.diagnose, 0.6 s) would be paid at every `twin --help`
    from ..ident.identify import fitted_wind_note
    from ..scale.fleet import SUMMARY_FILES, Log, diagnose_fleet, format_summary, read_manifest

    # every option checked before any log is read or report written: a rerun into the same --out
    # with a bad option must not replace its reports by failure records
    library = effect_names(effects)
    if window is not None:
        window_s(window)
    at_least(batch_size, 1, "--batch-size")
    executor = _executor(ray, cpus_per_task, retries)
    default = str(model) if model is not None else vessel
    if manifest is not None:
        if recordings:
            raise TwinError("give recordings or --manifest, not both")
        logs = read_manifest(manifest, default)
        check_recordings_distinct([log.path for log in logs])  # as when the logs are given on the command line
    else:
        if not recordings:
            raise TwinError("give recordings to diagnose, or --manifest FILE")
        if default is None:
            raise TwinError("give --vessel NAME or --model FILE (or a manifest with a vessel column)")
        paths = recordings_in(recordings)
        check_recordings_distinct(paths)  # one log twice would count twice in the summary
        logs = [Log(p, default) for p in paths]
    wind = "measured" if wind_measured else None
    for name in sorted({log.vessel for log in logs}):
        wind_note = fitted_wind_note(load(name), wind)
        if wind_note:
            note(f"note: {Path(name).name}: {wind_note}")
    # the last check: every bad option comes first. Each file the summary writes: a user's own fleet.md is
    # not replaced because no fleet.json is beside it (the per-log reports: diagnose_fleet, before any work)
    check_new([out / name for name in SUMMARY_FILES], force, "--out's summary")
    with progress_bar("fleet") as progress:
        fleet = diagnose_fleet(logs, out, window_s=window, library=library, html=html, batch_size=batch_size,
                               executor=executor, progress=progress, wind=wind)
    typer.echo(format_summary(fleet.summary))
    failures = len(fleet.reports) - fleet.summary["diagnosed"]
    short = sum(1 for f in fleet.summary["failed"] if f.get("too_short"))
    why = ", ".join(part for part in (f"{short} too short" if short else "",
                                      counted(failures - short, "failure record") if failures > short else "") if part)
    say(f"wrote {counted(len(fleet.reports), 'report')}"
        + (f" ({fleet.summary['diagnosed']} diagnosed, {why})" if failures > 0 else "")
        + f", {out / 'fleet.json'} and {out / 'fleet.md'}")
    older = other_reports(out, {Path(r).name for r in fleet.reports.values()} | {"fleet.json"})
    if older:
        note(f"note: {out} also holds {len(older)} report{'' if len(older) == 1 else 's'} of logs not in this fleet "
             f"(kept, not in fleet.json): {', '.join(older[:3])}{' …' if len(older) > 3 else ''}")
    # a log too short to diagnose is listed, as a fleet of a month's logs has them; any other failure is a
    # fault a script must see in the exit code (the others' reports are written)
    failed = [f for f in fleet.summary["failed"] if not f.get("too_short")]
    if failed:
        raise TwinError(f"{len(failed)} of {fleet.summary['logs']} logs could not be diagnosed "
                        f"(their failure records are in {out}, the other reports are written)")


def other_reports(out: Path, written: set[str]) -> list[str]:
    """The names of the per-log reports in `out` this fleet did not write (another fleet's), not the
    other JSON files a user keeps there."""
    from ..scale.fleet import is_fleet_report  # late: 0.6 s more at every `twin --help`

    return sorted(q.name for q in out.glob("*.json") if q.name not in written and is_fleet_report(q))
