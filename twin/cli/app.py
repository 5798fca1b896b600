"""The `twin` command's app: the typer app the command modules register on, the one place
errors become one line and an exit code, the checks every output path goes through before
any work is done, and the progress bar long commands show.

Exit codes: 0 done; 1 a check failed (crosscheck over tolerance); 2 bad input (usage, an
unreadable or unwritable path, a bad file, an inconsistent vessel); 3 an unexpected error
(one line; TWIN_DEBUG=1 shows the traceback); 130 interrupted.
"""
from __future__ import annotations

import contextlib
import csv
import functools
import hashlib
import inspect
import json
import math
import os
import sys
import tempfile
import warnings
from importlib import resources
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Iterator, Optional

import typer
from rich.console import Console
from rich.measure import Measurement
from rich.progress import BarColumn, Progress as Bar, TextColumn, TimeElapsedColumn
from rich.table import Column

from .. import __version__
from ..effects import EFFECTS
from ..errors import TwinError
from ..files import (KEPT, after_writes, all_or_nothing, finite_json, kept_data, link_target, read_only, same_file,
                     truth_logs, write_text_atomic)
from ..progress import Progress
from ..recording import MOVED
from ..threads import limit_process_blas_threads
from ..vessel import load

app = typer.Typer(add_completion=False, pretty_exceptions_enable=False, no_args_is_help=True,
                  help="MuJoCo digital twin of small surface vessels: simulate, identify from logs, evaluate, "
                       "diagnose.")
# stdout is None where the command was started with it closed (`twin info x.csv >&-`): main() refuses that
console = Console(width=None if sys.stdout is not None and sys.stdout.isatty() else 100)
# listed from the package's model folder so that a vessel added there is offered without an edit here
SHIPPED = ", ".join(sorted(p.name[:-5] for p in resources.files("twin").joinpath("model").iterdir()
                           if p.name.endswith(".json")))
VESSEL_HELP = f"vessel name (one shipped with twin: {SHIPPED})"
# a synthetic log records PWM: the shipped vessels whose thrusters take it
PWM_SHIPPED = ", ".join(sorted(p.name[:-5] for p in resources.files("twin").joinpath("model").iterdir()
                               if p.name.endswith(".json")
                               and json.loads(p.read_text()).get("thrusters", {}).get("kind") == "t200"))
# the shipped vessels ArduPilot Rover's two throttle outputs can drive: any but a propeller and rudder
TWIN_THRUSTER_SHIPPED = ", ".join(sorted(p.name[:-5] for p in resources.files("twin").joinpath("model").iterdir()
                                         if p.name.endswith(".json") and json.loads(p.read_text()).get(
                                             "thrusters", {}).get("kind") != "propeller_rudder"))
PWM_VESSEL_HELP = f"vessel name (one shipped with twin whose thrusters take PWM, as a dataset logs it: {PWM_SHIPPED})"
MODEL_HELP = "vessel description file (e.g. written by `twin identify`), instead of --vessel"
CASE_HELP = ("mass case: min | nominal | max (min and max where the vessel file has them, e.g. yellowfish; default: "
             "the file's own, nominal unless it was written in another)")
CHANNELS_HELP = "thruster servo output channels LEFT,RIGHT (for a log without SERVOn_FUNCTION 73/74)"
_settings = {"quiet": False}


QUIET = ("--quiet", "-q")
# one line each for `twin --help`; the command's docstring is its description
SUMMARIES = {
    "simulate": "Run the twin headless and write the run (CSV, MCAP, rerun, tlog, bin).",
    "view": "Show a recording and the twin's replay of it in rerun.",
    "info": "Summarise recordings; with a vessel, each log's compass calibration.",
    "convert": "Convert a recording to another format.",
    "validate": "Check a vessel's masses, inertia, added mass and meshes against their sources.",
    "crosscheck": "Check the engine against the analytic 3-DOF model (exit 1 over tolerance).",
    "params": "Print a vessel's effective 3-DOF parameters.",
    "identify": "Identify a vessel from recordings and write its twin.",
    "evaluate": "Score how well a twin predicts recordings (R², MAE per velocity).",
    "diagnose": "Find what a twin lacks against recordings and write the amended twin.",
    "dataset": "Write a synthetic recording with a known truth.",
    "effects": "List the effects a dataset can inject and a diagnosis can name.",
    "iso": "Identify by self-oscillation (relay with hysteresis) in the twin.",
    "dp": "Run the I-PD controller tuned from the self-oscillation in the twin.",
    "sitl": "Serve the twin as ArduPilot SITL's physics (JSON interface).",
    "mission": "Fly a waypoint mission with ArduPilot SITL and say how it went.",
    "montecarlo": "Prediction bands of an identified twin by Monte Carlo.",
    "dataset-shards": "Write many synthetic recordings of randomised vessels, sharded.",
    "fleet": "Diagnose every log of a fleet: a report per log and a summary.",
}
# the order `twin --help` lists the commands in: the order of the work they do
WORKFLOW = ("simulate", "view", "info", "convert", "validate", "crosscheck", "params", "identify", "evaluate",
            "diagnose", "dataset", "effects", "iso", "dp", "sitl", "mission", "montecarlo", "dataset-shards", "fleet")


def package_version() -> str:
    """The installed distribution's version; the package's own where it is run from a checkout that was
    never installed."""

    try:
        return version("asv-twin")
    except PackageNotFoundError:
        return __version__


def _show_version(shown: bool) -> None:
    if shown:
        typer.echo(f"twin {package_version()}")
        raise typer.Exit(0)


@app.callback()
def _options(quiet: bool = typer.Option(False, *QUIET, help="no progress bars or notes on stderr (also after "
                                                            "the command); what is written is still said"),
             version: bool = typer.Option(False, "--version", is_eager=True, callback=_show_version,
                                          help="print the version and exit")) -> None:
    """MuJoCo digital twin of small surface vessels: simulate, identify from logs, evaluate, diagnose."""
    _settings["quiet"] = _settings["quiet"] or quiet
    limit_process_blas_threads()


# ---------------------------------------------------------------- arguments

def vessel_from(vessel: Optional[str], model: Optional[Path], case: Optional[str] = None):
    """The vessel of --vessel NAME or --model FILE; both at once is refused (which one was meant
    cannot be known)."""
    if model is not None and vessel is not None:
        raise TwinError(f"give --vessel NAME or --model FILE, not both (--vessel {vessel} --model {model})")
    if model is not None:
        if Path(model).is_dir():  # else taken for a shipped vessel's name and called unknown
            raise TwinError(f"--model '{model}' is a folder, not a vessel file: give the .json file")
        return load(str(model), case)
    if vessel is None:
        raise TwinError(f"give --vessel NAME ({SHIPPED}) or --model FILE")
    return load(vessel, case)


def speed_direction(text: Optional[str], option: str) -> Optional[tuple[float, float]]:
    """SPEED,DIR_DEG of --current / --wind."""
    if text is None:
        return None
    try:
        speed, direction = (float(x) for x in text.split(","))
    except ValueError:
        raise TwinError(f"--{option} expects SPEED,DIR_DEG (m/s, degrees), got '{text}'") from None
    if not (math.isfinite(speed) and math.isfinite(direction)) or speed < 0:
        raise TwinError(f"--{option}: the speed must be a number ≥ 0 and the direction a number of degrees")
    return speed, direction


def channels_from(text: Optional[str]) -> Optional[dict]:
    """--channels LEFT,RIGHT as the readers' mapping."""
    if text is None:
        return None
    try:
        left, right = (int(x) for x in text.split(","))
    except ValueError:
        raise TwinError(f"--channels expects two servo output numbers LEFT,RIGHT (e.g. 1,3), got '{text}'") from None
    return {"left": left, "right": right}


def effect_names(text: Optional[str], option: str = "--effects") -> Optional[list[str]]:
    """--effects A,B: names of the effect library, refused before any work when one is no effect at
    all (which of them fit a given recording and vessel only the diagnosis can tell)."""
    if text is None:
        return None
    names = listed(text, option)
    if not names:  # an empty list is not "every effect": that is leaving the option out
        raise TwinError(f"{option} is empty: name at least one effect (leave {option} out for the whole library)")
    unknown = [e for e in names if e not in EFFECTS]
    valued = [e for e in unknown if "=" in e and e.split("=", 1)[0].strip() in EFFECTS]
    if valued:  # a value belongs to a judgement, not to the list of effects searched
        raise TwinError(f"{option} takes effect names, got {', '.join(valued)}: an effect at given values is "
                        f"judged by `twin diagnose LOG --given {valued[0]}`")
    if unknown:
        raise TwinError(f"{option}: unknown effect(s) {', '.join(unknown)} (known: {', '.join(EFFECTS)})")
    return names


def listed(text: str, option: str) -> list[str]:
    """The items of a comma-separated list, stripped; an item left empty between others ("5,,6",
    "Xu,,Nr") is refused as the typo it is (a trailing comma is not: nothing follows it)."""
    items = [x.strip() for x in text.split(",")]
    kept = [x for x in items if x]
    if kept and not all(items[:-1]):  # a list of nothing at all is the caller's to call empty
        raise TwinError(f"{option} '{text}': an empty item in the list")
    return kept


def floats(text: Optional[str], option: str) -> Optional[list[float]]:
    """A comma-separated list of finite numbers."""
    if text is None:
        return None
    items = listed(text, f"--{option}")
    try:
        values = [float(x) for x in items]
    except ValueError:
        raise TwinError(f"--{option} expects comma-separated numbers, got '{text}'") from None
    if not values or not all(math.isfinite(x) for x in values):
        raise TwinError(f"--{option} expects comma-separated finite numbers, got '{text}'")
    return values


MOST_GNSS_NOISE_M, MOST_HEADING_NOISE_DEG = 100.0, 90.0


def sensor_noise(text: str):
    """--noise: a profile's name or GNSS_M,HEADING_DEG, finite levels ≥ 0 (a NaN level would only fail once
    the recording is being written, as NaN positions)."""
    from ..synth.dataset import PROFILES, noise_profile  # late: twin.synth is 0.18 s more at every `twin --help`

    if text not in PROFILES:
        parts = text.split(",")
        try:
            levels = [float(x) for x in parts]
        except ValueError:
            levels = []
        if len(levels) != 2 or not all(math.isfinite(x) and x >= 0 for x in levels):
            raise TwinError(f"--noise expects {', '.join(PROFILES)} or GNSS_M,HEADING_DEG (two finite numbers ≥ 0: "
                            f"m, degrees), got '{text}'")
        if levels[0] > MOST_GNSS_NOISE_M or levels[1] > MOST_HEADING_NOISE_DEG:
            # past these a fix lands off the globe and a heading is noise alone: no receiver or compass a log
            # would be worth reading from
            raise TwinError(f"--noise {text}: a GNSS noise above {MOST_GNSS_NOISE_M:g} m or a heading noise above "
                            f"{MOST_HEADING_NOISE_DEG:g}° describes no usable sensor")
    return noise_profile(text)


# ---------------------------------------------------------------- numbers

def positive(value: float, option: str) -> float:
    """A finite number > 0 (a period, a duration, a window): 0, negative, nan or inf is refused
    before any work, where the computation would otherwise fail deep inside or loop forever."""
    if not (math.isfinite(value) and value > 0):
        raise TwinError(f"{option} must be a positive finite number, got {value:g}")
    return value


MIN_WINDOW_S = 1.0  # a free run of a few grid samples (0.1 s) shows no dynamics to judge


def window_s(value: float, option: str = "--window") -> float:
    """A free-run window length (s): positive and at least MIN_WINDOW_S."""
    positive(value, option)
    if value < MIN_WINDOW_S:
        raise TwinError(f"{option} must be at least {MIN_WINDOW_S:g} s (a free run of a few samples shows no "
                        f"dynamics), got {value:g}")
    return value


def counted(n: int, noun: str) -> str:
    """'1 segment', '3 segments'."""
    return f"{n} {noun}{'' if n == 1 else 's'}"


def at_least(value: int, least: int, option: str) -> int:
    """A count of at least `least` (evaluations, draws)."""
    if value < least:
        raise TwinError(f"{option} must be at least {least}, got {value}")
    return value


def seed_from(seed: int, option: str = "--seed") -> int:
    """A random seed: numpy's generators take only seeds ≥ 0."""
    if seed < 0:
        raise TwinError(f"{option} must be a whole number ≥ 0, got {seed}")
    return seed


def memory_bytes() -> int | None:
    """This machine's physical memory (bytes), None where the system does not say."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):  # not a POSIX system: the allocation itself will say
        return None


def samples_fit(duration_s: float, period_s: float, what: str) -> None:
    """Refuse a run whose sample count (duration / period) could not be held in this machine's memory
    even at one 8-byte number per sample: the arrays would fail to allocate only once the work began."""
    n = duration_s / period_s
    memory = memory_bytes()
    if memory is not None and n * 8 > memory:
        raise TwinError(f"{what}: {duration_s:g} s at {period_s:g} s is {n:.3g} samples, more than this machine's "
                        f"memory ({memory / 2**30:.0f} GiB) holds")


def draws_fit(draws: int, samples: float, numbers_per_sample: int, what: str) -> None:
    """Refuse, before any work, `draws` runs of `samples` samples whose states (numbers_per_sample
    8-byte numbers each) are all kept for the band and could not be held in this machine's memory:
    the run would otherwise work for hours and fail at the end."""
    need = float(draws) * samples * numbers_per_sample * 8
    memory = memory_bytes()
    if memory is not None and need > memory:
        raise TwinError(f"{what}: {draws} draws of {samples:.0f} samples keep {need / 2**30:.3g} GiB, more than this "
                        f"machine's memory ({memory / 2**30:.0f} GiB) holds (fewer draws, a shorter run or a longer "
                        "sample period)")


@contextlib.contextmanager
def memory_for(what: str) -> Iterator[None]:
    """A run too large for the memory left (a long --duration, a fine sample period) as one line
    naming the options, not an exception name."""
    try:
        yield
    except MemoryError:
        raise TwinError(f"{what}: not enough memory for this many samples (shorten it or use a longer "
                        "sample period)") from None


# ---------------------------------------------------------------- outputs

def check_outputs(paths, formats: tuple[str, ...], option: str = "output") -> None:
    """Refuse, before any work is done, an output whose extension is not one of `formats`, whose
    folder does not exist or cannot be written, or that is a folder itself."""
    for p in paths:
        if p is None:
            continue
        p = Path(p)
        if p.is_dir():
            raise TwinError(f"{option} '{p}' is a folder: give a file name")
        if link_target(p).exists() and not link_target(p).is_file():  # a device or a pipe, through a link or not
            raise TwinError(f"{option} '{p}' is not a regular file: give a file's name")
        if p.suffix.lower() not in formats:
            raise TwinError(f"{option} '{p}': unknown format '{p.suffix or '(none)'}' (use {', '.join(formats)})")
        folder = link_target(p).parent  # a link is written through: its target's folder is written
        if folder.exists() and not folder.is_dir():
            raise TwinError(f"{option} '{p}': '{folder}' is a file, not a folder")
        if not folder.is_dir():
            raise TwinError(f"{option} '{p}': folder '{folder}' does not exist (create it first)")
        if read_only(p):
            raise TwinError(f"{option} '{p}' is read-only: it is kept (give another output name)")
        if not os.access(folder, os.W_OK) or (p.exists() and not os.access(p, os.W_OK)) or not _can_create(folder):
            raise TwinError(f"{option} '{p}': cannot write there (choose another folder)")


FORCE_HELP = "replace an output that exists (never an input, nor data of another kind)"
REPORT_HELP = "(a report: replaces a file of its name, never a log or a twin)"


def check_truth_beside_logs(truth: Path, outputs, option: str = "--truth") -> None:
    """Refuse to replace a dataset's truth that describes a recording which this run does not write
    (beside it under its name's stem with a recording's suffix, or among the logs it names): the log
    would stay under a truth of another."""
    if kept_data(Path(truth)) != "dataset's truth":
        return
    stem = Path(truth).name.removesuffix(".truth.json")
    named = [Path(truth).with_name(stem + suffix) for suffix in RECORDING_SUFFIXES]
    listed = [log for log in truth_logs(Path(truth)) if kept_data(log) == "recording"]
    for log in named + listed:
        if log.is_file() and not any(same_file(log, Path(o)) for o in outputs):
            raise TwinError(f"{option} '{truth}' describes the recording '{log}', which this run does not "
                            "write: replaced, it would describe another log (move or remove the two first, or "
                            "write elsewhere)")


def check_distinct(outputs: dict[str, object], inputs=(), keep_data: bool = True) -> None:
    """Refuse, before any work is done, two outputs at one path (the second would replace the
    first), an output that is one of the inputs (the run would replace the data it read), and,
    with keep_data, an output that would replace a recording or a vessel file (kept_data: a report
    written over a user's log or twin loses it; a command whose outputs are data refuses any
    existing file itself, check_new, and passes keep_data=False). `outputs`: option -> path or list
    of paths (None skipped); `inputs`: the paths read."""
    named = [(option, Path(p)) for option, given in outputs.items()
             for p in (given if isinstance(given, (list, tuple)) else [given]) if p is not None]
    read = [Path(p) for p in inputs if p is not None]
    for k, (option, path) in enumerate(named):
        for source in read:
            if same_file(path, source):
                raise TwinError(f"{option} '{path}' is the input '{source}': writing it would replace the input "
                                "(give another output name)")
        for other_option, other in named[:k]:
            if same_file(path, other):
                raise TwinError(f"{option} '{path}' and {other_option} '{other}' are the same file: one output "
                                "would replace the other")
    for option, path in named if keep_data else ():
        kind = kept_data(path)
        if kind:
            raise TwinError(f"{option} '{path}' exists and is a {kind}: {KEPT.format(force='--force')}")


RECORDING_SUFFIXES = (".tlog", ".bin", ".csv", ".mcap")


def recordings_in(paths: list[Path]) -> list[Path]:
    """The recordings given, a folder standing for the recordings in it (an empty one is an error)."""
    out = []
    for p in paths:
        if p.is_dir():
            found = sorted(q for q in p.iterdir() if q.is_file() and q.suffix.lower() in RECORDING_SUFFIXES)
            if not found:
                below = " (its subfolders are not searched: give them, e.g. FOLDER/*)" if any(
                    q.is_dir() for q in p.iterdir()) else ""
                raise TwinError(f"'{p}' is a folder with no recordings in it ({', '.join(RECORDING_SUFFIXES)}){below}")
            out += found
        elif not p.is_file():
            raise TwinError(f"{p}: no such file" + (" or folder" if not p.suffix else ""))
        elif p.suffix.lower() not in RECORDING_SUFFIXES and not _reads_as_recording(p):  # before any log is diagnosed
            raise TwinError(f"'{p}': not a recognised recording (expected .tlog, DataFlash .bin, .csv or .mcap)")
        else:
            out.append(p)
    return out


def _reads_as_recording(path: Path) -> bool:
    """Whether a file named otherwise than a recording is one by its content (a CSV log saved as .txt):
    a file named on the command line is read by what it holds, as every command reads it; a folder's
    files by their names. Read whole: a first line with a comma in it is no log yet."""
    # late: twin.formats costs 0.08 s more at every `twin --help`, and only an oddly named file needs it
    from ..formats import read_recording
    try:
        read_recording(path)
    except TwinError:
        return False
    return True


def check_recordings_distinct(recordings) -> None:
    """Refuse one recording given twice (the same file, or a copy with the same bytes): its windows would
    count twice, and a run judged "left out" would be a copy of one fitted on."""

    seen: dict[str, Path] = {}
    paths = [Path(p) for p in recordings]
    for k, path in enumerate(paths):
        if not path.exists():  # said as the reader says it: a missing file is not one given twice
            raise TwinError(f"{path}: no such file")
        for earlier in paths[:k]:
            if same_file(path, earlier):
                again = "" if str(path) == str(earlier) else f" (as '{earlier}')"
                raise TwinError(f"'{path}' is given twice{again}: give each recording once")
        if not path.is_file() or path.stat().st_size == 0:
            continue  # the reader says what is wrong with it (two empty files are not one log twice)
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
        if digest in seen:
            raise TwinError(f"'{path}' holds the same bytes as '{seen[digest]}': give each recording once")
        seen[digest] = path


def _can_create(folder: Path) -> bool:
    """Whether a file can really be created in `folder` (permissions alone do not say: /proc)."""

    try:
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".twin-probe-"):
            return True
    except OSError:
        return False


def json_text(data: dict) -> str:
    """`data` as the JSON text write_json writes (non-finite numbers as null)."""
    return json.dumps(finite_json(data), indent=2, allow_nan=False) + "\n"


def write_json(path: Optional[Path], data: dict) -> None:
    """`data` as JSON, atomically; numpy numbers and arrays become plain JSON."""
    if path is not None:
        write_text_atomic(path, json_text(data))
        say(f"wrote {path}")


def print_table(table) -> None:
    """A rich table whole: on a terminal at its width; piped or in a file, as wide as its columns need
    (a cell cut to the page's 100 columns would hide a number's exponent)."""
    if sys.stdout.isatty():
        console.print(table)
        return
    page = console.width
    console.width = max(page, Measurement.get(console, console.options.update(width=10_000), table).maximum)
    try:
        console.print(table)
    finally:
        console.width = page


def say(text: str) -> None:
    """A line for the user (what was written, what was found): always shown; "wrote …" once the
    command's files are in place (all_or_nothing_outputs)."""
    if text.startswith("wrote "):
        after_writes(lambda: console.print(text, highlight=False, soft_wrap=True))
    else:
        console.print(text, highlight=False, soft_wrap=True)


def given_on_command_line(ctx: typer.Context, *names: str) -> list[str]:
    """Of the options `names` (parameter names), those the user wrote, as --their-spelling: an option
    that does nothing without another is refused rather than silently ignored."""
    # by the source's name: typer carries a click of its own, whose enum is not click's
    return ["--" + n.replace("_", "-") for n in names
            if getattr(ctx.get_parameter_source(n), "name", None) == "COMMANDLINE"]


def all_or_nothing_outputs(command):
    """A command whose files all land, or none (files.all_or_nothing): one that fails after writing its
    first output leaves no output written and nothing replaced. Its own exit code (typer.Exit) is a
    success for its files."""
    @functools.wraps(command)
    def run(*args, **kwargs):
        with all_or_nothing(keep_on=(typer.Exit,)):
            return command(*args, **kwargs)
    return run


def say_unlogged_supply(recordings, vessel) -> None:
    """For a twin whose thrust follows the supply voltage: which recordings log none (their thrust is
    then the map's at the reference voltage), so no one reads that as a fit of the pack."""
    t = vessel.thrusters
    if not t.follows_supply:
        return
    for rec in recordings:
        if not len(rec.battery):
            say(f"{Path(rec.source).name}: no battery voltage logged: the twin's thrust follows none there "
                f"(its map as at {t.supply_ref_v:g} V)")


def warn_recordings(recordings) -> None:
    """Each recording's warnings (Recording.warnings: data that may be misread), its streams read
    earlier than stamped (an ArduPilot log's gyro and GPS) and those that lost a share of their samples
    on reading (Recording.heavy_losses), named by file, before the work that would take the data as read."""
    for rec in recordings:
        for text in [*rec.misread, *rec.warnings]:  # misread: only `twin view` gets this far with one
            note(f"warning: {Path(rec.source).name}: {text}")
        for text in rec.notes:  # a stream read earlier than its stamps: the work takes it so
            if text.startswith(MOVED):
                note(f"note: {Path(rec.source).name}: {text}")
        for text in rec.heavy_losses():
            note(f"note: {Path(rec.source).name}: {text} (`twin info` lists what was dropped)")


def check_wind_and_inputs(recordings: list, wind: str | None, vessel, replayed: bool = True) -> None:
    """Before any work: the measured wind's checks (twin.ident.identify.check_wind) and, where the
    vessel's twin is run (`replayed`), that the logs hold its kind of inputs; then the notes: inputs
    beyond the vessel file's bounds (replayed as logged), the wind's gaps, and a twin identified with
    the wind that is run without it."""
    # late: the fitting stack (twin.ident.identify) is 0.54 s more at every `twin --help`
    from ..drive import inputs_mismatch
    from ..ident.identify import (beyond_command_bounds, check_inputs, check_wind, fitted_wind_note, held_inputs,
                                  idle_inputs_under_way, unused_wind_note, wind_gaps)

    check_wind(recordings, wind, vessel)
    if replayed:
        check_inputs(recordings, vessel)
        wanted = vessel.thrusters.input_kind
        for rec in recordings:  # check_inputs passes a log of none: the twin would have nothing to be run with
            if held_inputs(rec) is None:
                words = {"pwm": "thruster PWM", "propeller_rudder": "propeller speed and rudder angle"}.get(wanted, wanted)
                hint = ("; --channels LEFT,RIGHT maps a log's servo outputs" if wanted == "pwm" else
                        f"; {inputs_mismatch(vessel.name, wanted, None)}" if wanted == "thrust" else "")
                raise TwinError(f"{Path(rec.source).name}: the recording has no {words} to replay (`twin info` says "
                                f"why{hint})")
        for line in beyond_command_bounds(recordings, vessel):
            note(f"note: {line}")
        for line in idle_inputs_under_way(recordings):
            note(f"warning: {line}")
    for line in wind_gaps(recordings) if wind else []:
        say(f"note: {line}")
    wind_note = fitted_wind_note(vessel, wind) if replayed else None
    if wind_note:
        note(f"note: {wind_note}")
    elif replayed and (unused := unused_wind_note(recordings, wind, vessel)):
        note(f"note: {unused}")


def note(text: str) -> None:
    """A side remark on stderr: hidden by --quiet."""
    if not _settings["quiet"]:
        typer.echo(text, err=True)


BAR_WIDTH = 16


@contextlib.contextmanager
def progress_bar(title: str) -> Iterator[Progress]:
    """A progress callable for package functions: a rich bar on stderr when it is a terminal
    and --quiet is off; otherwise nothing (logs and pipes stay clean)."""
    if _settings["quiet"] or not sys.stderr.isatty():
        yield lambda what, done=None, total=None: None
        return
    console = Console(stderr=True)
    # the step's text is what gives way on a narrow terminal (cut with an ellipsis), never the
    # command's name, the bar, the count or the time
    room = max(20, console.width - len(title) - BAR_WIDTH - 24)  # a count of 9 and the time of 7, with spaces
    with Bar(TextColumn("{task.description}", table_column=Column(no_wrap=True, min_width=len(title))),
             BarColumn(bar_width=BAR_WIDTH), TextColumn("{task.fields[count]}", table_column=Column(no_wrap=True)),
             TextColumn("{task.fields[what]}", table_column=Column(no_wrap=True, overflow="ellipsis", max_width=room)),
             TimeElapsedColumn(), console=console, transient=True) as bar:
        task = bar.add_task(title, total=None, what="", count="")

        def update(what: str, done: int | None = None, total: int | None = None) -> None:
            # the count beside the bar: how far in numbers, not only as a bar's length
            count = f"{done}/{total}" if done is not None and total else ""
            bar.update(task, what=what, count=count, completed=done if done is not None else 0, total=total)

        yield update


def flow_help() -> None:
    """Each command's help from its docstring: its first sentence is the one-line summary of
    `twin --help`, the rest its description (paragraphs kept, lines within one joined: rich prints
    a docstring's line breaks as they stand); commands in the order of the workflow; options
    shown with a plain word for their value (none for a flag) instead of type tags."""

    for info in app.registered_commands:
        doc = info.help or inspect.getdoc(info.callback) or ""
        paragraphs = [" ".join(part.split()) for part in doc.split("\n\n")]
        paragraphs = [p for p in paragraphs if p]
        name = info.name or info.callback.__name__.replace("_", "-")
        info.short_help = SUMMARIES.get(name, _first_sentence(paragraphs[0]) if paragraphs else "")
        info.help = "\n\n".join(paragraphs)
    order = {name: i for i, name in enumerate(WORKFLOW)}
    app.registered_commands.sort(key=lambda info: order.get(info.name or info.callback.__name__, len(order)))


def _first_sentence(text: str) -> str:
    """Up to the first full stop followed by a space (not one inside a parenthesis or an abbreviation)."""
    depth = 0
    for i, ch in enumerate(text):
        depth += (ch == "(") - (ch == ")")
        if ch in ".;:" and depth == 0 and text[i + 1:i + 2] == " " and not text[max(0, i - 3):i].endswith(
                ("e.g", "i.e", "eq", "eqs", "vs", "Fig", "cf")):
            return text[:i] if ch != "." else text[:i + 1]
    return text


def _plain_types() -> None:
    """Typer 0.2x's rich help puts a type tag (`<bool>`, `<float>`) beside every option and has no
    setting to leave it out: a flag gets none, a value a plain word (FLOAT, PATH). Older Typer
    shows no such tags and has no `display_type_rich`, so nothing is changed there."""
    for kind in ("TyperOption", "TyperArgument"):
        cls = getattr(getattr(typer, "core", None), kind, None)
        shown = getattr(cls, "display_type_rich", None)
        if shown is None or getattr(shown, "_plain", False):
            continue

        def display_type_rich(self, ctx, shown=shown):
            if getattr(self, "is_flag", False) and not getattr(self, "count", False):
                return None
            tag = shown(self, ctx)
            if isinstance(tag, str) and tag.startswith("<"):
                tag = tag.replace("<list[", "<").replace("]>", ">").replace(">...", "...>")
                return tag.strip("<>").upper()
            return tag

        display_type_rich._plain = True
        cls.display_type_rich = display_type_rich


_plain_types()


def quiet_anywhere(argv: list[str]) -> list[str]:
    """The command line with --quiet/-q taken out wherever it stands before a `--` (the app's
    option, accepted after the command too), the setting made."""
    out, passed = [], False
    for arg in argv:
        if not passed and arg in QUIET:
            _settings["quiet"] = True
            continue
        passed = passed or arg == "--"
        out.append(arg)
    return out


def refuse_repeated_options(argv: list[str]) -> None:
    """TwinError for an option of one value given twice (`--png a.png --png b.png`): the command line
    parser would take the last without a word, where a repeatable one (`--out`) takes each."""
    command = getattr(typer.main.get_command(app), "commands", {}).get(argv[0]) if argv else None
    if command is None:
        return
    counts: dict[str, int] = {}
    for arg in argv[1:]:
        if arg == "--":
            break
        name = arg.split("=", 1)[0] if arg.startswith("--") else arg
        counts[name] = counts.get(name, 0) + 1
    for param in command.params:
        if getattr(param, "param_type_name", "") != "option" or param.multiple or param.is_flag:
            continue
        given = sum(counts.get(name, 0) for name in param.opts)
        if given > 1:
            raise TwinError(f"{param.opts[0]} given {given} times: it takes one value")


FILE_SUFFIXES = (".csv", ".mcap", ".rrd", ".tlog", ".bin", ".json", ".png", ".md", ".html", ".txt", ".waypoints")


def refuse_files_named_as_folders(argv: list[str]) -> None:
    """TwinError for a file's name ending in a slash (`--out run.csv/`): the path parser drops the
    slash and the file would be written where a folder was meant."""
    for arg in argv:
        if arg == "--":
            break
        value = arg.split("=", 1)[1] if arg.startswith("--") and "=" in arg else arg
        if (value.endswith(("/", os.sep)) and Path(value.rstrip("/" + os.sep)).suffix.lower() in FILE_SUFFIXES
                and not Path(value).is_dir()):  # a folder of that name is one
            raise TwinError(f"'{value}' ends with a slash, as a folder does: give the file's name without it")


# ---------------------------------------------------------------- errors

def _is_usage_error(exc: Exception) -> bool:
    """A bad command line. Typer ≥ 0.29 raises its own copy of Click's exceptions (TyperException
    subclasses); older ones raise Click's. Both carry format_message and exit_code, so the test is
    by shape: importing click here would add a dependency newer Typer no longer brings."""
    return callable(getattr(exc, "format_message", None)) and isinstance(getattr(exc, "exit_code", None), int)


def _os_error(exc: OSError) -> str:
    """One line for a file the command could not read or write."""
    where = f" '{exc.filename}'" if exc.filename else ""
    return f"cannot use{where}: {exc.strerror or exc}"


class _OutputFailed(Exception):
    """A write to stdout or stderr failed for a reason other than its reader leaving (a full disk, /dev/full)."""


class _ReaderMayLeave:
    """sys.stdout or sys.stderr for one run of the command: once the reader of its pipe has gone (`twin identify
    ... | head`), what it prints goes to the null device and the command goes on to write its files.
    *Why:* otherwise the first print after the reader left raises BrokenPipeError, and a command that
    prints its summary before it writes would end with its results unwritten."""

    def __init__(self, stream, name: str = "standard output") -> None:
        self._stream = stream
        self._name = name

    def _reader_gone(self) -> None:
        with contextlib.suppress(OSError, ValueError):
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, self._stream.fileno())  # the stream's own descriptor: its buffer drains there
            os.close(null)

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            self._reader_gone()
            return len(text)
        except OSError as exc:
            raise _OutputFailed(f"cannot write to {self._name}: {exc.strerror or exc}") from None

    def flush(self) -> None:
        try:
            self._stream.flush()
        except BrokenPipeError:
            self._reader_gone()
            with contextlib.suppress(OSError, ValueError):
                self._stream.flush()
        except OSError as exc:
            raise _OutputFailed(f"cannot write to {self._name}: {exc.strerror or exc}") from None

    def __getattr__(self, name: str):
        return getattr(self._stream, name)


def main() -> None:
    """Run the app; every failure ends in one line on stderr and an exit code (module docstring)."""
    _settings["quiet"] = False  # each run's own: a caller may run the command more than once
    if sys.stdout is None or sys.stderr is None:  # started with it closed (`>&-`): where would its results go?
        closed = "standard output" if sys.stdout is None else "standard error"
        if sys.stderr is not None:
            sys.stderr.write(f"error: {closed} is closed: the command prints there (redirect it, e.g. to "
                             "/dev/null, instead of closing it)\n")
            sys.stderr.flush()
        sys.exit(2)
    streams = sys.stdout, sys.stderr
    sys.stdout, sys.stderr = _ReaderMayLeave(sys.stdout), _ReaderMayLeave(sys.stderr, "standard error")
    failed = None
    try:
        _run()
    except _OutputFailed as exc:  # stderr itself failing while the command said what went wrong
        failed = exc
    finally:
        for guarded in (sys.stdout, sys.stderr):  # output still buffered when its reader has gone drains too
            try:
                guarded.flush()
            except _OutputFailed as exc:
                failed = failed or exc
        sys.stdout, sys.stderr = streams
        if failed is not None:  # the command's last lines could not be written: it did not say what it did
            _say_failed(failed)
            sys.exit(2)


def _say_failed(exc: Exception) -> None:
    """One line on stderr for output that could not be written (itself, where stderr cannot take it, unsaid)."""
    with contextlib.suppress(OSError, ValueError):
        sys.stderr.write(f"error: {exc}\n")
        sys.stderr.flush()


def _run() -> None:
    try:
        with warnings.catch_warnings():
            if not os.environ.get("TWIN_DEBUG"):
                # numpy's overflow and invalid-value warnings on wild samples (a fix at 1e308 m) speak
                # of arrays, not of the log: the outlier rules and the notes say what was wrong
                warnings.simplefilter("ignore", RuntimeWarning)
            # without standalone mode typer returns the code of typer.Exit(code) instead of raising it
            args = quiet_anywhere(sys.argv[1:])
            refuse_repeated_options(args)
            refuse_files_named_as_folders(args)
            code = app(args=args, prog_name="twin", standalone_mode=False)
    except TwinError as exc:
        typer.echo(f"error: {exc}", err=True)
        sys.exit(2)
    except typer.Exit as exc:
        sys.exit(exc.exit_code)
    except (typer.Abort, KeyboardInterrupt):
        typer.echo("aborted", err=True)
        sys.exit(130)
    except OSError as exc:
        typer.echo(f"error: {_os_error(exc)}", err=True)
        sys.exit(2)
    except _OutputFailed as exc:
        _say_failed(exc)
        sys.exit(2)
    except csv.Error as exc:  # a CSV read with the csv module: a quoted field run on past its 128 kB limit
        typer.echo(f"error: a CSV file cannot be read ({exc}): a stray quote character, or a field that large?",
                   err=True)
        sys.exit(2)
    except Exception as exc:  # usage errors and anything unexpected: one line, never a traceback
        if _is_usage_error(exc):
            if not exc.format_message():  # `twin` alone: the help it asked for is printed, nothing failed
                sys.exit(0)
            typer.echo(f"error: {exc.format_message()}", err=True)
            sys.exit(2)
        if os.environ.get("TWIN_DEBUG"):
            raise
        typer.echo(f"error: {type(exc).__name__}: {exc}".splitlines()[0], err=True)
        sys.exit(3)
    if isinstance(code, int) and not isinstance(code, bool) and code != 0:
        if code == 130:  # typer's own answer to a Ctrl-C inside a command, returned as its exit code
            typer.echo("aborted", err=True)
        sys.exit(code)
