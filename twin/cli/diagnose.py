"""`twin diagnose`: registered on the main CLI app."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer
from rich.markup import escape

from ..effects import apply_effects, named_twice
from ..errors import TwinError
from ..files import write_text_atomic
from ..files import check_new
from ..recording import check_no_shared_stretch, check_not_misread
from ..vessel import save
from .app import (REPORT_HELP, all_or_nothing_outputs, listed, CHANNELS_HELP, FORCE_HELP, MODEL_HELP, VESSEL_HELP, app, channels_from, check_distinct, check_outputs,
                  check_recordings_distinct, check_wind_and_inputs, effect_names, json_text, positive, progress_bar,
                  recordings_in, say, say_unlogged_supply, vessel_from, warn_recordings, window_s, write_json)
from .ident import calibration_line
from .run import KNOWN_SEA_HELP, known_sea


@app.command("diagnose")
@all_or_nothing_outputs
def diagnose_command(
    recordings: list[Path] = typer.Argument(..., metavar="RECORDINGS",
                                            help="recordings: .tlog, .bin, .csv, .mcap, or folders of them"),
    vessel: Optional[str] = typer.Option(None, help=VESSEL_HELP),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP),
    json_out: Optional[Path] = typer.Option(None, "--json", help=f"write the diagnosis as JSON {REPORT_HELP}"),
    report: Optional[Path] = typer.Option(None, help=f"write an HTML report with plots {REPORT_HELP}"),
    rrd: Optional[Path] = typer.Option(None, help="write real, twin-before and twin-after to a rerun recording"),
    write_model: Optional[Path] = typer.Option(None, "--write-model", help="write the amended vessel description"),
    effects: Optional[str] = typer.Option(None, help="only these candidate effects (comma separated; "
                                                     "default: the whole library, see `twin effects`)"),
    channels: Optional[str] = typer.Option(None, help=CHANNELS_HELP),
    window: float = typer.Option(10.0, help="free-run window length, s"),
    calibration: bool = typer.Option(True, "--calibration/--no-calibration",
                                     help="apply each log's compass offset estimated from its own GNSS track first"),
    refit: Optional[str] = typer.Option(None, help="identification groups whose coefficients are refitted with every "
                                                   "candidate, for a twin not yet identified (comma separated, "
                                                   "`twin identify`'s groups, e.g. surge,yaw,thrust_curve: _ for a space)"),
    refit_weight: float = typer.Option(1.0, help="with --refit: windows of data each refitted coefficient's belief "
                                                 "counts as (as `twin identify`'s beliefs ×1)"),
    given: Optional[list[str]] = typer.Option(None, help="instead of a search: judge this effect at these values "
                                                        "(`twin effects` syntax, e.g. current=0.2,90; repeat for "
                                                        "several, judged together) by the same rule on the same "
                                                        "blocks: can these recordings prove it?"),
    sea: Optional[str] = typer.Option(None, help=KNOWN_SEA_HELP),
    wind_measured: bool = typer.Option(False, "--wind-measured",
                                       help="take each recording's measured wind (its anemometer stream) as a known "
                                            "input of every free run, the twin's and every candidate's"),
    force: bool = typer.Option(False, "--force", help=FORCE_HELP),
):
    """Where the twin and a recording disagree, which physics is missing, the amended twin."""
    # late: the command's stack (twin.diagnose, 0.6 s) would be paid at every `twin --help`
    from ..diagnose.doctor import diagnose, given_evidence
    from ..diagnose.locate import format_located
    from ..diagnose.report import as_json, format_text, given_text, write_html, write_rrd
    from ..engine.sixdof import without_known_sea
    from ..formats import read_recording

    for path, formats, option in ((json_out, (".json",), "--json"), (report, (".html", ".htm"), "--report"),
                                  (rrd, (".rrd",), "--rrd"), (write_model, (".json",), "--write-model")):
        check_outputs([path], formats, option)
    recordings = recordings_in(recordings) if any(p.is_dir() for p in recordings) else recordings
    check_distinct({"--json": json_out, "--report": report, "--rrd": rrd, "--write-model": write_model},
                   [*recordings, model], keep_data=False)
    check_distinct({"--json": json_out, "--report": report, "--rrd": rrd})  # reports: never over data, --force or not
    check_new([write_model], force, "--write-model", ("vessel file",))  # a twin over a twin only
    check_recordings_distinct(recordings)
    window_s(window)
    positive(refit_weight, "--refit-weight")
    if refit is None and refit_weight != 1.0:  # it weighs the refitted coefficients' beliefs, and none are
        raise TwinError("--refit-weight weighs the beliefs of the coefficients --refit names: give --refit GROUPS")
    if given:
        clash = [o for o, v in (("--report", report), ("--rrd", rrd), ("--write-model", write_model),
                                ("--effects", effects), ("--refit", refit)) if v is not None]
        if clash:
            raise TwinError(f"--given judges the effects as given, without a search: {', '.join(clash)} does not "
                            "apply (use --json for the figures)")
    library = effect_names(effects)
    prior, sea_line = known_sea(vessel_from(vessel, model, "nominal"), sea)
    if sea_line:
        say(sea_line)
    if given:
        apply_effects(prior, given)  # a bad effect text is refused before the recordings are read
        twice = named_twice(given)
        if twice:
            raise TwinError(f"--given names {', '.join(twice)} twice: give each effect once, with its values")
    recs = [read_recording(p, channels=channels_from(channels)) for p in recordings]
    check_not_misread(recs)
    check_no_shared_stretch(recs)
    warn_recordings(recs)
    wind = "measured" if wind_measured else None
    check_wind_and_inputs(recs, wind, prior)  # before any work
    if given:
        e = given_evidence(recs, prior, given, window_s=window, calibrated=calibration, known_wind=wind)
        typer.echo(given_text(given, e))
        write_json(json_out, {"given": list(given), "earns_its_place": bool(e.earns_its_place()), **e.to_dict()})
        return
    # a group's name may hold a space ("thrust curve"), which a shell splits unless quoted: _ stands for it
    groups = tuple(g.replace("_", " ") for g in listed(refit, "--refit")) if refit is not None else None
    with progress_bar("diagnose") as progress:
        result = diagnose(recs, prior, window_s=window, library=library, calibrated=calibration, refit=groups,
                          refit_weight=refit_weight, log=lambda m: progress(m), wind=wind)
    for c in result.calibrations:
        say(escape(f"calibration: {calibration_line(c, applied=calibration, twin=prior)}"))
    say_unlogged_supply(recs, result.amended)
    typer.echo(format_text(result))
    typer.echo("\nwhere the residual concentrates (every window, twin before):")
    typer.echo(format_located(result.located[:12]))
    # every output's content first, so a result that cannot be written leaves no output half replaced
    figures = json_text(as_json(result)) if json_out is not None else None
    if write_model is not None:
        save(without_known_sea(result.amended), write_model)  # the twin, not the recordings' sea
        say(f"wrote {write_model}" + ("" if result.effects else " (nothing named: the twin unchanged)"))
    if figures is not None:
        write_text_atomic(json_out, figures)
        say(f"wrote {json_out}")
    if report is not None:
        write_html(result, report)
        say(f"wrote {report}")
    if rrd is not None:
        write_rrd(result, rrd)
        say(f"wrote {rrd} (open with: rerun {rrd})")
