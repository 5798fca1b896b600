"""The `twin` command: a thin layer over the Python API."""
from __future__ import annotations

import json
import os
import sys
from pathlib import Path
from typing import Optional

import typer
from rich.console import Console
from rich.table import Table

from .errors import TwinError

app = typer.Typer(add_completion=False, pretty_exceptions_enable=False, no_args_is_help=True,
                  help="MuJoCo digital twin of twin-thruster surface vessels.")
console = Console(width=None if sys.stdout.isatty() else 100)
VESSEL_HELP = "vessel name (model/NAME.json)"
MODEL_HELP = "vessel description file (e.g. written by identification); overrides --vessel"


def _vessel(vessel: Optional[str], model: Optional[Path], case: str):
    from . import vessel as vessel_mod

    if model is not None:
        return vessel_mod.load(str(model), case)
    if vessel is None:
        raise TwinError("give --vessel NAME or --model FILE")
    return vessel_mod.load(vessel, case)


def _pair(text: Optional[str], what: str) -> Optional[tuple[float, float]]:
    if text is None:
        return None
    try:
        a, b = (float(x) for x in text.split(","))
    except ValueError:
        raise TwinError(f"--{what} expects SPEED,DIR_DEG, got '{text}'") from None
    if a < 0:
        raise TwinError(f"--{what}: speed must be ≥ 0")
    return a, b


@app.command()
def simulate(
    vessel: Optional[str] = typer.Option(None, help=VESSEL_HELP),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP),
    scenario: str = typer.Option("zigzag", help="step | turn | zigzag | spin | random"),
    inputs: Optional[Path] = typer.Option(None, help="CSV: t + pwm_left,pwm_right (µs) or thrust_left,thrust_right (N)"),
    duration: float = typer.Option(120.0, help="simulated time, s"),
    out: list[Path] = typer.Option(..., help="output file(s): .csv, .mcap, .rrd, .tlog or .bin (repeatable)"),
    current: Optional[str] = typer.Option(None, help="water current SPEED,DIR_DEG (m/s, flowing towards)"),
    wind: Optional[str] = typer.Option(None, help="wind SPEED,DIR_DEG (m/s, coming from)"),
    case: str = typer.Option("nominal", help="mass case: min | nominal | max"),
    seed: int = typer.Option(0, help="random seed (scenario 'random')"),
    sample_dt: float = typer.Option(0.1, help="output sample period, s"),
):
    """Run the twin headless and write the run."""
    from dataclasses import replace

    from . import scenarios
    from .engine.mjcf import compile_vessel
    from .engine.sim import simulate as run_sim
    from .inputs import read_inputs_csv
    from .outputs import check_paths, write

    check_paths(out)
    v = _vessel(vessel, model, case)
    env = v.environment
    if (c := _pair(current, "current")) is not None:
        env = replace(env, current_speed_m_s=c[0], current_dir_deg=c[1])
    if (w := _pair(wind, "wind")) is not None:
        env = replace(env, wind_speed_m_s=w[0], wind_dir_deg=w[1])
    v = v.with_environment(env)
    drive = read_inputs_csv(inputs) if inputs else scenarios.get(scenario, seed)
    if inputs and drive.kind == "pwm" and v.thrusters.kind != "t200":
        raise TwinError(f"vessel '{v.name}' has no PWM model: give thrust_left,thrust_right in N")
    cv = compile_vessel(v)
    run = run_sim(cv, drive, duration, sample_dt_s=sample_dt)
    run.meta["scenario"] = "inputs:" + inputs.name if inputs else scenario
    for path in out:
        write({"twin": run}, path, geometry=cv.geometry, vessel_name=v.name, mjcf=v.mjcf)
        console.print(f"wrote {path}")
    console.print(f"{v.name}: {duration:g} s, final position ({run.eta[-1, 0]:.2f}, {run.eta[-1, 1]:.2f}) m, "
                  f"heading {run.eta[-1, 2] * 57.29578:.1f}°, u {run.nu[-1, 0]:.3f} m/s")


@app.command()
def crosscheck(
    vessel: Optional[str] = typer.Option(None, help=VESSEL_HELP),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP),
    duration: float = typer.Option(120.0, help="zig-zag duration, s"),
    case: str = typer.Option("nominal", help="mass case"),
    rrd: Optional[Path] = typer.Option(None, help="write engine and analytic trajectories to this .rrd"),
    json_out: Optional[Path] = typer.Option(None, "--json", help="write the errors as JSON"),
):
    """Engine against the analytic 3-DOF model; exit 1 when over tolerance."""
    from .crosscheck import HEADING_TOL_DEG, POSITION_TOL_M
    from .crosscheck import crosscheck as run_crosscheck
    from .outputs import check_paths, write
    from .vessel import write_text_atomic

    if rrd is not None:
        check_paths([rrd])
    v = _vessel(vessel, model, case)
    results = run_crosscheck(v, duration)
    table = Table(title=f"crosscheck {v.name}: engine (MuJoCo) vs analytic, {duration:g} s zig-zag")
    for col in ("case", "position err (m)", "heading err (deg)", "term effect (m)", "result"):
        table.add_column(col, justify="right" if "err" in col or "effect" in col else "left")
    for r in results:
        effect = "-" if r.effect_m is None else f"{r.effect_m:.3g}"
        table.add_row(r.case, f"{r.position_err_m:.2e}", f"{r.heading_err_deg:.2e}", effect,
                      "[green]pass[/]" if r.passed else "[red]FAIL[/]")
    console.print(table)
    console.print(f"tolerance: position < {POSITION_TOL_M} m, heading < {HEADING_TOL_DEG}°")
    if json_out is not None:
        rows = [{"case": r.case, "position_err_m": r.position_err_m, "heading_err_deg": r.heading_err_deg,
                 "effect_m": r.effect_m, "passed": r.passed} for r in results]
        write_text_atomic(json_out, json.dumps({"vessel": v.name, "duration_s": duration, "cases": rows},
                                               indent=2) + "\n")
    if rrd is not None:
        full = results[0]
        from .engine.mjcf import compile_vessel

        write({"engine": full.engine, "analytic": full.analytic}, rrd,
              geometry=compile_vessel(v).geometry, vessel_name=v.name, mjcf=v.mjcf)
        console.print(f"wrote {rrd}")
    if not all(r.passed for r in results):
        raise typer.Exit(1)


@app.command()
def params(
    vessel: Optional[str] = typer.Option(None, help=VESSEL_HELP),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP),
    case: str = typer.Option("nominal", help="mass case"),
    as_json: bool = typer.Option(False, "--json", help="print JSON"),
):
    """Print the effective 3-DOF parameters of a vessel."""
    from .params import effective_parameters

    p = effective_parameters(_vessel(vessel, model, case))
    if as_json:
        typer.echo(json.dumps(p, indent=2))
        return
    console.print(f"[bold]{p['vessel']}[/] ({p['case']}): m = {p['rigid_body']['mass_kg']:.3f} kg, "
                  f"xg = {p['rigid_body']['xg_m'] * 1e3:.1f} mm, Iz = {p['rigid_body']['Iz_kgm2']:.3f} kg·m²")
    for key in ("M", "M_RB", "M_A"):
        console.print(f"{key:5s} = " + "  ".join("[" + ", ".join(f"{x:9.4f}" for x in row) + "]" for row in p[key]))
    console.print("damping: " + ", ".join(f"{k}={val:g}" for k, val in p["damping"].items() if val))


@app.command()
def validate(
    vessel: Optional[str] = typer.Option(None, help=VESSEL_HELP),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP),
    case: str = typer.Option("nominal", help="mass case: min | nominal | max"),
    json_out: Optional[Path] = typer.Option(None, "--json", help="write one object per quantity"),
    report: Optional[Path] = typer.Option(None, help="write a report: .md (PNG beside it) or .html"),
):
    """Analytic formulas, seed tables, engine, meshes and independent values, side by side."""
    import textwrap

    from .validate import validate as run_validation
    from .vessel import write_text_atomic
    from .viz.report import top_view_png, write_report

    for p in (json_out, report):
        if p is not None and not p.parent.exists():
            raise TwinError(f"output '{p}': folder '{p.parent}' does not exist")
    if report is not None and report.suffix.lower() not in (".md", ".html", ".htm"):
        raise TwinError(f"report '{report}': use .md or .html")
    result = run_validation(_vessel(vessel, model, case))
    rows = [q.to_dict() for q in result.quantities]
    typer.echo(validation_table(result.vessel, result.case, rows))
    flagged = [r for r in rows if r["flag"]]
    if flagged:
        typer.echo("\nDifferences over 5 %:")
        for r in flagged:
            typer.echo(textwrap.fill(f"* {r['name']}: {r['explanation']}", 100, subsequent_indent="  "))
    title = f"twin validate: {result.vessel} ({result.case})"
    if json_out is not None:
        write_text_atomic(json_out, json.dumps({"vessel": result.vessel, "case": result.case,
                                                "quantities": rows}, indent=2) + "\n")
    if report is not None:
        write_report(report, title, rows, top_view_png(result.drawing, title))
        typer.echo(f"wrote {report}")


def validation_table(name: str, case: str, rows: list[dict]) -> str:
    """Plain-text table that fits 100 columns."""
    def cell(x):
        return f"{'-':>9s}" if x is None else f"{x:9.4g}"

    head = f"{'quantity':30s} {'unit':5s} {'analytic':>9s} {'table':>9s} {'engine':>9s} {'mesh':>9s} " \
           f"{'indep.':>9s} {'diff':>7s}"
    lines = [f"validate {name} ({case})", head, "-" * len(head)]
    for r in rows:
        rel = f"{'-':>7s}" if r["rel_diff"] is None else f"{100 * r['rel_diff']:6.1f}%"
        lines.append(f"{r['name'][:30]:30s} {r['unit'][:5]:5s} " + " ".join(cell(r[c]) for c in (
            "analytic", "table", "engine", "mesh", "independent")) + f" {rel}" + (" !" if r["flag"] else ""))
    return "\n".join(lines)


def _lever_arm(vessel_obj) -> tuple[float, float] | None:
    """OP = (dx, dy) from the antenna to CO (seed 000 eq. 28) from the vessel's GNSS site."""
    if vessel_obj is None:
        return None
    from .engine.mjcf import compile_vessel

    g = compile_vessel(vessel_obj).geometry
    return float(-g.gnss_pos_m[0]), float(-g.gnss_pos_m[1])


def _channels(text: Optional[str]) -> Optional[dict]:
    if text is None:
        return None
    try:
        left, right = (int(x) for x in text.split(","))
    except ValueError:
        raise TwinError(f"--channels expects LEFT,RIGHT servo numbers, got '{text}'") from None
    return {"left": left, "right": right}


@app.command()
def info(
    files: list[Path] = typer.Argument(..., help="recordings: .bin, .tlog, .csv, .mcap"),
    channels: Optional[str] = typer.Option(None, help="thruster servo channels LEFT,RIGHT (else from the log)"),
):
    """Summarise recordings: duration, rates, signals, gaps, what was dropped and why."""
    from .recordings import format_summary, read_recording

    mapping = _channels(channels)
    failed = 0
    for path in files:  # one bad file must not hide the others' summaries
        try:
            rec = read_recording(path, channels=mapping)
        except TwinError as exc:
            typer.echo(f"error: {exc}", err=True)
            failed += 1
            continue
        typer.echo(f"== {path}")
        typer.echo(format_summary(rec.summary()))
    if failed:
        raise typer.Exit(2)


@app.command()
def convert(
    src: Path = typer.Argument(..., help="input recording: .bin, .tlog, .csv, .mcap"),
    dst: Path = typer.Argument(..., help="output: .csv (generic layout), .mcap, .tlog or .bin"),
    channels: Optional[str] = typer.Option(None, help="thruster servo channels LEFT,RIGHT"),
    grid_dt: float = typer.Option(0.1, help="sample period of the synchronised GNSS, heading and PWM, s"),
):
    """Convert a recording to another format: GNSS, heading and PWM synchronised on one grid
    (seed 004 §5.1) when it has GNSS and heading, else every stream at its own times."""
    from .recordings import read_recording, write_recording
    from .recordings.convert import for_conversion, not_kept

    suffix = dst.suffix.lower()
    if suffix not in (".csv", ".mcap", ".tlog", ".bin"):
        raise TwinError(f"output '{dst}': unknown format (use .csv, .mcap, .tlog or .bin)")
    if not dst.parent.exists():
        raise TwinError(f"output '{dst}': folder '{dst.parent}' does not exist")
    rec = read_recording(src, channels=_channels(channels))
    conversion = for_conversion(rec, grid_dt)
    write_recording(conversion.recording, dst)
    typer.echo(f"wrote {dst}: {conversion.recording.duration_s():.1f} s, {conversion.timing}")
    for line in not_kept(conversion.recording, suffix):
        typer.echo(f"note: {line}")


@app.command()
def view(
    files: list[Path] = typer.Argument(..., help="recordings to show"),
    sim: bool = typer.Option(False, "--sim", help="replay the twin with the recorded inputs beside the real track"),
    vessel: Optional[str] = typer.Option(None, help=VESSEL_HELP + " (for --sim and the GNSS lever arm)"),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP),
    out: Optional[Path] = typer.Option(None, help="rerun recording to write (default: ./STEM.rrd, STEM of the first "
                                                  "input, in the current folder)"),
    png: Optional[Path] = typer.Option(None, help="also write a PNG of the comparison"),
    channels: Optional[str] = typer.Option(None, help="thruster servo channels LEFT,RIGHT"),
    smoother: str = typer.Option("savgol", help="velocities: savgol (seed 004) or model (EKF+RTS on the vessel model)"),
):
    """Real track and the twin's replay on one timeline, in rerun (and a PNG)."""
    from .outputs import check_paths, write
    from .recordings import prepare, read_recording
    from .replay import measured_run, replay, thrust_from_recorded_pwm
    from .viz.report import comparison_png

    v = _vessel(vessel, model, "nominal") if (vessel or model) else None
    if (sim or smoother == "model") and v is None:
        raise TwinError("--sim and --smoother model need --vessel NAME or --model FILE")
    if smoother not in ("savgol", "model"):
        raise TwinError(f"unknown smoother '{smoother}' (savgol or model)")
    out = out or Path(files[0].stem + ".rrd")  # the working folder: never beside the input (a shared data folder)
    check_paths([out])
    compiled = None
    if v is not None:
        from .engine.mjcf import compile_vessel

        compiled = compile_vessel(v)
    runs = {}
    for path in files:
        rec = read_recording(path, channels=_channels(channels))
        at_body_origin = rec.meta.get("positions") == "body origin"  # a twin's run: no antenna to correct
        prep = prepare(rec, lever_arm_OP_m=None if at_body_origin else _lever_arm(v))
        if smoother == "model":
            from .smoother import model_smoothed

            prep = model_smoothed(compiled, prep)
        label = path.stem if len(files) > 1 else "real"
        runs[label] = measured_run(prep)
        if compiled is not None:  # the real thrust as the twin would make it: sim against real, as u, v, r
            runs[label].thrust_n = thrust_from_recorded_pwm(compiled, prep)
            runs[label].meta["series_labels"] = {q: f"{label} ({v.name} thrust map on the recorded PWM)"
                                                 for q in ("thrust_left", "thrust_right")}
        if sim:
            runs[f"twin {path.stem}" if len(files) > 1 else "twin"] = replay(v, prep)
    write(runs, out, vessel_name=v.name if v else "", mjcf=v.mjcf if v else None)
    typer.echo(f"wrote {out} (open with: rerun {out})")
    if png is not None:
        from .files import write_bytes_atomic

        write_bytes_atomic(png, comparison_png(runs, f"{', '.join(p.name for p in files)}"
                                                     + (f": real vs twin ({v.name})" if sim else "")))
        typer.echo(f"wrote {png}")


# commands that live in their own modules register themselves on `app`
from . import cli_diagnose, cli_ident, cli_iso  # noqa: E402,F401


def main() -> None:
    try:
        # without standalone mode Click returns the code of typer.Exit(code) instead of raising it
        code = app(standalone_mode=False)
    except TwinError as exc:
        typer.echo(f"error: {exc}", err=True)
        sys.exit(2)
    except typer.Exit as exc:
        sys.exit(exc.exit_code)
    except (typer.Abort, KeyboardInterrupt):
        typer.echo("aborted", err=True)
        sys.exit(130)
    except Exception as exc:  # click usage errors and anything unexpected: one line, never a traceback
        import click

        # recent typer raises its own copy of click's exceptions, whose base is TyperException
        usage = (click.exceptions.ClickException, getattr(typer.exceptions, "TyperException", click.ClickException))
        if isinstance(exc, usage):
            if exc.format_message():  # `twin` alone has printed the help and has nothing to add
                typer.echo(f"error: {exc.format_message()}", err=True)
            sys.exit(2)
        if os.environ.get("TWIN_DEBUG"):
            raise
        typer.echo(f"error: {type(exc).__name__}: {exc}".splitlines()[0], err=True)
        sys.exit(3)
    if isinstance(code, int) and not isinstance(code, bool) and code != 0:
        sys.exit(code)


if __name__ == "__main__":
    # run the imported twin.cli, whose app the command modules registered on, not this __main__ copy
    from twin.cli import main as _main

    _main()
