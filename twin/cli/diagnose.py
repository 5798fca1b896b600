"""`twin diagnose`: registered on the main CLI app."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from .app import (CHANNELS_HELP, MODEL_HELP, VESSEL_HELP, app, channels_from, check_outputs, console, progress_bar,
                  say, vessel_from, write_json)


@app.command("diagnose")
def diagnose_command(
    recordings: list[Path] = typer.Argument(..., help="recordings: .tlog, .bin, .csv, .mcap"),
    vessel: Optional[str] = typer.Option(None, help=VESSEL_HELP),
    model: Optional[Path] = typer.Option(None, help=MODEL_HELP),
    json_out: Optional[Path] = typer.Option(None, "--json", help="write the diagnosis as JSON"),
    report: Optional[Path] = typer.Option(None, help="write an HTML report with plots"),
    rrd: Optional[Path] = typer.Option(None, help="write real, twin-before and twin-after to a rerun recording"),
    write_model: Optional[Path] = typer.Option(None, "--write-model", help="write the amended vessel description"),
    effects: Optional[str] = typer.Option(None, help="only these candidate effects (comma separated; "
                                                     "default: the whole library, see `twin effects`)"),
    channels: Optional[str] = typer.Option(None, help=CHANNELS_HELP),
    window: float = typer.Option(10.0, help="free-run window length, s"),
):
    """Where the twin and a recording disagree, which physics is missing, the amended twin."""
    from ..diagnose.doctor import diagnose
    from ..diagnose.locate import format_located
    from ..formats import read_recording
    from ..vessel import save

    for path, formats in ((json_out, (".json",)), (report, (".html", ".htm")), (rrd, (".rrd",)),
                          (write_model, (".json",))):
        if path is not None:
            check_outputs([path], formats)
    prior = vessel_from(vessel, model, "nominal")
    recs = [read_recording(p, channels=channels_from(channels)) for p in recordings]
    library = [e.strip() for e in effects.split(",") if e.strip()] if effects else None
    result = diagnose(recs, prior, window_s=window, library=library, log=lambda m: console.print(f"[dim]{m}[/]"))
    typer.echo(format_diagnosis(result))
    typer.echo("\nwhere the residual concentrates (every window, twin before):")
    typer.echo(format_located(result.located[:12]))
    if write_model is not None:
        save(result.amended, write_model)
        console.print(f"wrote {write_model}")
    write_json(json_out, result.to_dict())
    if report is not None:
        from ..diagnose.report import write_html

        write_html(result, report)
        console.print(f"wrote {report}")
    if rrd is not None:
        from ..diagnose.report import write_rrd

        write_rrd(result, rrd)
        console.print(f"wrote {rrd} (open with: rerun {rrd})")


def format_diagnosis(d) -> str:
    """Effects, fit before/after and what is left, ≤ 100 columns."""
    lines = [f"diagnosis of {d.prior.name}: {d.windows.get('train')} training and {d.windows.get('held_out')} held-out "
             f"windows of {d.windows.get('length_s')} s, {d.seconds:.0f} s"]
    noise = d.noise
    lines.append(f"noise: GNSS {noise.get('gnss_m', float('nan')):.3f} m, heading {noise.get('heading_deg', float('nan')):.2f}°"
                 f" → u {noise.get('u', float('nan')):.3f} m/s, v {noise.get('v', float('nan')):.3f} m/s, "
                 f"r {noise.get('r', float('nan')):.4f} rad/s")
    if not d.effects:
        lines.append("effects found: none")
    for e in d.effects:
        params = ", ".join(f"{k} {v:.3g} [{d_ci[0]:.3g}, {d_ci[1]:.3g}]" if (d_ci := e['ci'].get(k)) else f"{k} {v:.3g}"
                           for k, v in e["parameters"].items())
        lines.append(f"effect {e['name']}: {params}; held-out misfit −{100 * e['held_out_gain']:.1f} % "
                     f"(z {e['z']:.1f})")
        for r in e["rivals"]:
            verdict = "told apart" if r["separable"] else "NOT separable by this recording"
            lines.append(f"    rival {r['name']}: {verdict} (held-out z {r['z']:.1f})")
    lines.append(f"{'held-out fit':14s}" + "".join(f"{'R2 ' + k:>9s}{'MAE ' + k:>10s}" for k in "uvr"))
    for name, fit in (("before", d.fit_before), ("after", d.fit_after)):
        cells = "".join(f"{_num(fit[k]['r2'], 3):>9s}{_num(fit[k]['mae'], 4):>10s}" for k in "uvr")
        lines.append(f"{name:14s}{cells}")
    for u in d.unexplained:
        follows = ", ".join(f"{c['signal']} ({c['r']:+.2f})" for c in u.get("correlates_with", []))
        lines.append(f"unexplained: {u['dof']} in {u['dimension']} {u['bin']}: RMS {u['rms']:.3g} "
                     f"({u.get('rms_over_noise', float('nan')):.1f}× noise)" + (f", follows {follows}" if follows else ""))
    lines += [f"note: {n}" for n in d.notes]
    return "\n".join(lines)


def _num(x, digits: int) -> str:
    return "-" if x is None else f"{x:.{digits}f}"
