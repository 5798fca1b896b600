"""`twin dataset`, `twin identify`, `twin evaluate`: registered on the main CLI app."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from ..effects.coefficients import DEFAULT_FIT
from ..errors import TwinError
from .app import (CHANNELS_HELP, MODEL_HELP, VESSEL_HELP, app, channels_from, check_outputs, console, progress_bar,
                  say, vessel_from, write_json)

RECORDING_FORMATS = (".tlog", ".bin", ".mcap", ".csv")


@app.command("dataset")
def dataset_command(
    vessel: Optional[str] = typer.Option(None, help=VESSEL_HELP),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP),
    out: list[Path] = typer.Option(..., help="recording(s) to write: .tlog, .bin, .mcap, .csv (repeatable)"),
    truth: Optional[Path] = typer.Option(None, help="truth file (JSON; default: OUT.truth.json beside the first output)"),
    segments: int = typer.Option(8, help="number of trajectory segments"),
    manoeuvres: str = typer.Option(",".join(("rc", "forward_constant", "forward_varying", "zigzag", "circle_constant",
                                             "circle_varying")),
                                   help="manoeuvres to cycle through: rc, forward_constant, forward_varying, zigzag, "
                                        "circle_constant, circle_varying, autopilot"),
    effect: list[str] = typer.Option([], help="effect injected in the truth, NAME=V1,V2 (repeatable; "
                                              "`twin effects` lists them)"),
    noise: str = typer.Option("realistic", help="sensor noise: realistic | rtk | noisy | none | GNSS_M,HEADING_DEG"),
    seed: int = typer.Option(0, help="random seed (manoeuvres, start states, noise)"),
    case: str = typer.Option("nominal", help="mass case"),
):
    """Synthetic identification dataset from the twin, with its truth in a separate file."""
    from ..synth.dataset import generate, noise_profile
    from ..formats import write_recording

    check_outputs(out, RECORDING_FORMATS)
    truth = truth or out[0].with_name(out[0].stem + ".truth.json")
    check_outputs([truth], (".json",))
    names = [m.strip() for m in manoeuvres.split(",") if m.strip()]
    ds = generate(vessel_from(vessel, model, case), effects=effect, n_segments=segments, manoeuvres=names, seed=seed,
                  noise=noise_profile(noise))
    for path in out:
        write_recording(ds.recording, path)
        console.print(f"wrote {path}")
    write_json(truth, ds.truth())
    total = sum(r.t[-1] - r.t[0] for r in ds.runs)
    console.print(f"{len(ds.runs)} segments, {total:.0f} s logged ({', '.join(m.name for m in ds.manoeuvres)}); "
                  f"effects: {', '.join(e.text for e in ds.effects) or 'none'}")


@app.command("effects")
def effects_command():
    """The effects a dataset can inject and a diagnosis can name."""
    from ..effects import describe

    typer.echo(describe())


@app.command("identify")
def identify_command(
    recordings: list[Path] = typer.Argument(..., help="recordings: .tlog, .bin, .csv, .mcap"),
    vessel: Optional[str] = typer.Option(None, help=VESSEL_HELP + " (the prior)"),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP),
    out: Path = typer.Option(..., help="identified vessel description to write (.json)"),
    thruster: str = typer.Option("static", help="seed 004 thruster model: static | dynamic"),
    split: str = typer.Option("segments", help="seed 004 tables: split by segments | points"),
    train: float = typer.Option(0.7, help="training share of the seed 004 splits"),
    repeats: int = typer.Option(20, help="random splits for the seed 004 tables"),
    params: Optional[str] = typer.Option(None, help="parameters of the simulation fit, comma separated "
                                                   "(default: " + ",".join(DEFAULT_FIT) + ")"),
    anchor: str = typer.Option("mass", help="absolute scale: mass (M11 from the vessel) | thrust (thrust curve)"),
    window: float = typer.Option(10.0, help="free-run window of the simulation fit, s"),
    start: str = typer.Option("free", help="initial velocities of each free run: free (estimated with the "
                                            "parameters) | measured (as the recording gives them)"),
    no_simulation: bool = typer.Option(False, "--no-simulation", help="only the seed 004 least squares"),
    channels: Optional[str] = typer.Option(None, help=CHANNELS_HELP),
    seed: int = typer.Option(0, help="random seed of the splits"),
    json_out: Optional[Path] = typer.Option(None, "--json", help="write the full report as JSON"),
):
    """Identify a vessel from recordings: seed 004 grey-box, then simulation fit."""
    from ..fit import simfit
    from ..ident import identify as ident
    from ..vessel import save

    check_outputs([out], (".json",))
    if json_out is not None:
        check_outputs([json_out], (".json",))
    prior = vessel_from(vessel, model, "nominal")
    names = tuple(p.strip() for p in params.split(",")) if params else DEFAULT_FIT
    simfit.check_names(prior, names, anchor)  # before any work
    if start not in ("free", "measured"):
        raise TwinError(f"--start must be free or measured, got '{start}'")
    preps = ident.load(recordings, prior, channels_from(channels))
    report = ident.identify(preps, prior, thruster=thruster, split=split, train=train, repeats=repeats, seed=seed,
                            params=names, anchor=anchor, simulate=not no_simulation, window_s=window,
                            start=start, sources=[str(r) for r in recordings])
    text = ident.format_greybox(report.greybox)
    if text:
        console.print(f"[bold]seed 004 grey-box ({thruster} thruster model), one-step predictions[/]")
        typer.echo(text)
    if report.simfit is not None:
        console.print("[bold]identification by simulation[/]")
        typer.echo(ident.format_estimates(report.simfit))
    for note in report.notes:
        typer.echo(f"note: {note}")
    if report.simfit is None:
        raise TwinError("no vessel written: the simulation fit was switched off (--no-simulation)")
    save(report.vessel, out)
    console.print(f"wrote {out} (use: twin simulate --model {out}, twin evaluate --model {out} ...)")
    write_json(json_out, report.to_dict())


@app.command("evaluate")
def evaluate_command(
    recordings: list[Path] = typer.Argument(..., help="recordings to evaluate on"),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP),
    vessel: Optional[str] = typer.Option(None, help=VESSEL_HELP),
    channels: Optional[str] = typer.Option(None, help=CHANNELS_HELP),
    stride: float = typer.Option(2.0, help="free-run windows start every STRIDE s"),
    json_out: Optional[Path] = typer.Option(None, "--json", help="write the metrics as JSON"),
    rrd: Optional[Path] = typer.Option(None, help="write the recording and the twin's 10-s free runs to rerun"),
):
    """R² and MAE per DOF: one step, 10-s and 30-s free runs, whole segments."""
    from ..fit.evaluate import evaluate, format_metrics
    from ..ident.identify import load

    if json_out is not None:
        check_outputs([json_out], (".json",))
    if rrd is not None:
        check_outputs([rrd], (".rrd",))
    v = vessel_from(vessel, model, "nominal")
    preps = load(recordings, v, channels_from(channels))
    metrics = evaluate(v, preps, stride_s=stride)
    if rrd is not None:
        _write_free_runs(v, preps, rrd)
    typer.echo(format_metrics(metrics, f"{v.name} on {', '.join(p.name for p in recordings)}"))
    write_json(json_out, {"vessel": v.name, "model": str(model) if model else None,
                           "recordings": [str(p) for p in recordings], "metrics": metrics})


def _write_free_runs(vessel, preps, path: Path) -> None:
    """The recording and the twin's back-to-back 10-s free runs on one rerun timeline."""
    from ..diagnose.report import stitched_runs
    from ..engine.mjcf import compile_vessel
    from ..fit.windows import make_windows, measured, predict
    from ..outputs import write

    wins = make_windows(preps, 10.0, 10.0)
    pred = predict(vessel, preps, wins)[0]
    eta, nu = measured(preps, wins)
    runs = stitched_runs(wins, {"real": (preps, eta, nu), "twin": (preps, pred.eta, pred.nu)})
    write(runs, path, geometry=compile_vessel(vessel).geometry, vessel_name=vessel.name, mjcf=vessel.mjcf)
    console.print(f"wrote {path} (open with: rerun {path})")
