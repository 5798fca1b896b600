"""Validation reports: a top-view PNG of the vessel and a Markdown or HTML page."""
from __future__ import annotations

import base64
import html
import io
from pathlib import Path

import numpy as np

from ..files import write_bytes_atomic, write_text_atomic


def top_view_png(drawing: dict, title: str) -> bytes:
    """Hull outlines, CO, CG (analytic and engine), thrusters and GNSS antenna, seen from above.

    Plotted with north/forward (x) up and starboard (y) to the right, as a chart.
    """
    # late: matplotlib (0.26 s) only for a figure; `twin --help` loads this module
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 7), dpi=110)
    for hull in drawing.get("hulls", []):
        xy = list(zip(*hull["outline_xy"]))
        ax.fill(xy[1], xy[0], color="#f2cc1a", alpha=0.6, lw=1, ec="k", label=None)
    ax.plot(0, 0, "k+", ms=14, mew=2, label="CO (IMU)")
    ax.plot(drawing["cg_engine"][1], drawing["cg_engine"][0], "o", color="tab:red", ms=8, mfc="none", mew=2,
            label=f"CG engine (x = {drawing['cg_engine'][0] * 1e3:.1f} mm)")
    if drawing.get("cg_analytic"):
        ax.plot(drawing["cg_analytic"][1], drawing["cg_analytic"][0], "x", color="tab:blue", ms=9, mew=2,
                label=f"CG eq. 17 (x = {drawing['cg_analytic'][0] * 1e3:.1f} mm)")
    for (x, y), side in zip(drawing["thrusters"], ("left", "right")):
        ax.annotate("", xy=(y, x + 0.12), xytext=(y, x), arrowprops={"arrowstyle": "->", "lw": 2, "color": "tab:green"})
        ax.plot(y, x, "s", color="tab:green", ms=7, label="thrusters" if side == "left" else None)
    ax.plot(drawing["gnss"][1], drawing["gnss"][0], "^", color="tab:purple", ms=9, label="GNSS antenna")
    ax.set_xlabel("y, starboard (m)")
    ax.set_ylabel("x, forward (m)")
    ax.set_aspect("equal")
    ax.grid(alpha=0.3)
    ax.set_title(title, fontsize=10)
    ax.legend(loc="lower center", fontsize=8, bbox_to_anchor=(0.5, -0.32), ncol=2)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    return buf.getvalue()


def _fmt(x) -> str:
    return "" if x is None else f"{x:.4g}"


def _rows(rows: list[dict]) -> list[list[str]]:
    out = []
    for r in rows:
        rel = "" if r["rel_diff"] is None else f"{100 * r['rel_diff']:.1f} %"
        out.append([r["name"], r["unit"], *(_fmt(r[c]) for c in ("analytic", "table", "engine", "mesh",
                                                                     "independent")), rel, "⚑" if r["flag"] else ""])
    return out


HEADER = ["quantity", "unit", "analytic", "table", "engine", "mesh", "independent", "rel. diff", "flag"]


def report_figure(path: Path) -> Path | None:
    """The PNG a Markdown report at `path` writes beside it (None for HTML, which embeds it)."""
    return None if path.suffix.lower() in (".html", ".htm") else path.with_name(path.stem + "_topview.png")


def write_report(path: Path, title: str, rows: list[dict], png: bytes) -> None:
    """Markdown (PNG written beside it, report_figure) or HTML (PNG embedded), by extension; atomic."""
    flagged = [r for r in rows if r["flag"]]
    if path.suffix.lower() in (".html", ".htm"):
        img = base64.b64encode(png).decode()
        table = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>" for row in _rows(rows))
        notes = "".join(f"<li><b>{html.escape(r['name'])}</b>: {html.escape(r['explanation'])}</li>" for r in flagged)
        text = (f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
                "<style>body{font-family:sans-serif;max-width:1000px;margin:auto}td,th{padding:2px 8px;"
                "border-bottom:1px solid #ddd}td:nth-child(n+3){text-align:right}</style></head><body>"
                f"<h1>{html.escape(title)}</h1><img src='data:image/png;base64,{img}'>"
                "<table><tr>" + "".join(f"<th>{h}</th>" for h in HEADER) + f"</tr>{table}</table>"
                f"<h2>Differences over 5 %</h2><ul>{notes}</ul></body></html>\n")
        write_text_atomic(path, text)
        return
    png_path = report_figure(path)
    write_bytes_atomic(png_path, png)
    lines = [f"# {title}", "", f"![top view]({png_path.name})", "",
             "| " + " | ".join(HEADER) + " |", "|" + "---|" * len(HEADER)]
    lines += ["| " + " | ".join(row) + " |" for row in _rows(rows)]
    lines += ["", "## Differences over 5 %", ""] + [f"- **{r['name']}**: {r['explanation']}" for r in flagged]
    write_text_atomic(path, "\n".join(lines) + "\n")


INPUT_KEYS = {"pwm": ("PWM (µs)", "left", "right"), "ship": ("rudder °, propeller rps", "rudder (°)", "propeller (rps)")}


def comparison_png(runs: dict, title: str) -> bytes:
    """Track on the water (east vs north) and u, r against time, one colour per run."""
    # late: matplotlib (0.26 s) only for a figure; `twin --help` loads this module
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    ship = False
    fig = plt.figure(figsize=(11, 6), dpi=100)
    grid = fig.add_gridspec(3, 2, width_ratios=(1.1, 1.4))
    track = fig.add_subplot(grid[:, 0])
    axes = [fig.add_subplot(grid[i, 1]) for i in range(3)]
    for (name, run), colour in zip(runs.items(), ("k", "tab:orange", "tab:blue", "tab:green")):
        track.plot(run.eta[:, 1], run.eta[:, 0], color=colour, lw=1.2, label=name)
        track.plot(run.eta[0, 1], run.eta[0, 0], "o", color=colour, ms=4)
        for ax, (k, q, label, scale) in zip(axes, ((0, "u", "u (m/s)", 1.0), (2, "r", "r (°/s)", 180.0 / np.pi))):
            # a velocity estimated from the track says how (its meta's series label)
            ax.plot(run.t, scale * run.nu[:, k], color=colour, lw=1, label=run.meta.get("series_labels", {}).get(q, name))
            ax.set_ylabel(label)
        held = run.propeller_rudder()
        if held is not None:  # a ship: rudder (deg) and propeller speed (rps) share the panel
            ship = True
            axes[2].plot(run.t, np.rad2deg(held[:, 1]), color=colour, lw=0.8, ls="-")
            axes[2].plot(run.t, held[:, 0], color=colour, lw=0.8, ls="--")
        elif np.any(np.isfinite(run.pwm_us)):
            axes[2].plot(run.t, run.pwm_us[:, 0], color=colour, lw=0.8, ls="-")
            axes[2].plot(run.t, run.pwm_us[:, 1], color=colour, lw=0.8, ls="--")
    label, solid, dashed = INPUT_KEYS["ship" if ship else "pwm"]
    axes[2].set_ylabel(label)
    if axes[2].lines:  # the line styles' key, in grey: the colours already name the runs
        axes[2].legend([Line2D([], [], color="grey", ls="-"), Line2D([], [], color="grey", ls="--")],
                       [solid, dashed], fontsize=8, loc="best")
    else:  # an empty panel would look like a drawing that failed
        axes[2].text(0.5, 0.5, "no inputs in this log", transform=axes[2].transAxes, ha="center", va="center",
                     color="grey")
    axes[2].set_xlabel("t (s)")
    track.set_xlabel("east (m)")
    track.set_ylabel("north (m)")
    track.set_aspect("equal", adjustable="datalim")
    track.legend(fontsize=8)
    # where it covers the fewest samples: a fixed corner covered a run's steady speed (its labels can be
    # long, and a row of them above the panel squeezed the figure)
    axes[0].legend(fontsize=7, loc="best", framealpha=0.8)
    for ax in (track, *axes):
        ax.grid(alpha=0.3)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    return buf.getvalue()
