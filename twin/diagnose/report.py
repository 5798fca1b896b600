"""What a diagnosis shows: an HTML page (effects, fit before and after, where the misfit
was, what is left, with plots) and a rerun recording with the real run, the twin before
and the twin after on one timeline.

The twin's curves are its 10-s free runs from measured states, window after window (each
window restarts from the measurement, so the curves jump at window starts): exactly what
the diagnosis judged.
"""
from __future__ import annotations

import base64
import html
import io
from pathlib import Path

import numpy as np

from ..run import Run
from ..files import write_text_atomic
from ..replay import stitched_runs

DOF_UNITS = {"u": "m/s", "v": "m/s", "r": "rad/s"}


def runs(d) -> dict[str, Run]:
    """Real, twin before and twin after on the windows' samples, in time order."""
    rp = d.replay
    before, after = rp["before"], rp["after"]
    return stitched_runs(rp["windows"], {"real": (rp["preps"], before.meas_eta, before.meas_nu),
                                         "twin before": (rp["preps"], before.pred_eta, before.pred_nu),
                                         "twin after": (rp["amended_preps"], after.pred_eta, after.pred_nu)})


def write_rrd(d, path: Path) -> None:
    from ..engine.mjcf import compile_vessel
    from ..outputs import write

    write(runs(d), Path(path), geometry=compile_vessel(d.prior).geometry, vessel_name=d.prior.name,
          mjcf=d.prior.mjcf)


def _png(fig) -> str:
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode()


def series_png(d, max_windows: int = 12) -> str:
    """u, v, r of the first held-out windows: measured, twin before, twin after."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rp = d.replay
    start = rp.get("held_from", 0)
    wins = rp["windows"][start: start + max_windows]
    fig, axes = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    offset = 0.0
    for j, w in enumerate(wins, start=start):
        n = w.n + 1
        x = offset + np.arange(n) * 0.1
        for k, ax in enumerate(axes):
            ax.plot(x, rp["before"].meas_nu[j, :n, k], color="k", lw=1.2, label="measured" if j == start else None)
            ax.plot(x, rp["before"].pred_nu[j, :n, k], color="tab:red", lw=1, label="twin before" if j == start else None)
            ax.plot(x, rp["after"].pred_nu[j, :n, k], color="tab:green", lw=1, label="twin after" if j == start else None)
        offset = x[-1] + 1.0
    for ax, dof in zip(axes, "uvr"):
        ax.set_ylabel(f"{dof} ({DOF_UNITS[dof]})")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8, ncol=3)
    axes[-1].set_xlabel("held-out free runs of 10 s, one after another (s)")
    fig.suptitle(f"{d.prior.name}: held-out windows, measured vs twin before and after", fontsize=10)
    fig.tight_layout()
    return _png(fig)


def _table(head: list[str], rows: list[list]) -> str:
    th = "".join(f"<th>{html.escape(str(h))}</th>" for h in head)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><tr>{th}</tr>{body}</table>"


def _num(x, digits=3) -> str:
    return "-" if x is None else f"{x:.{digits}f}" if isinstance(x, float) else str(x)


def write_html(d, path: Path) -> None:
    eff_rows = []
    for e in d.effects:
        params = "; ".join(f"{k} = {v:.4g} [{e['ci'][k][0]:.4g}, {e['ci'][k][1]:.4g}]" if k in e["ci"] else
                           f"{k} = {v:.4g}" for k, v in e["parameters"].items())
        rivals = "; ".join(f"{r['name']}: {'told apart' if r['separable'] else 'not separable'} (z {r['z']})"
                           for r in e["rivals"]) or "-"
        gain = ", ".join(f"{k} {100 * v:.0f} %" for k, v in e["improvement"].items())
        eff_rows.append([e["name"], params, f"{100 * e['held_out_gain']:.1f} % (z {e['z']})", gain, rivals])
    fit_rows = [[name] + [f"{_num(fit[k]['r2'])} / {_num(fit[k]['mae'], 4)}" for k in "uvr"]
                for name, fit in (("before", d.fit_before), ("after", d.fit_after))]
    loc_rows = [[e["dimension"], e["bin"], e["dof"], e["kind"], e["n"], _num(e["rms"], 4), _num(e["bias"], 4),
                 _num(e.get("rms_over_noise"), 1), _num(e.get("z"), 1)] for e in d.located[:15]]
    grow_rows = [[k, v.get("verdict"), _num(v.get("rms_early"), 4), _num(v.get("rms_late"), 4)]
                 for k, v in d.growth.items()]
    corr_rows = [[k] + [f"{c['signal']} ({c['r']:+.2f})" for c in v[:3]] for k, v in d.correlations.items()]
    unexpl = [[u["dof"], u["dimension"], u["bin"], _num(u["rms"], 4), _num(u.get("rms_over_noise"), 1),
               ", ".join(f"{c['signal']} ({c['r']:+.2f})" for c in u.get("correlates_with", []))]
              for u in d.unexplained]
    noise = ", ".join(f"{k} {v:.4g}" for k, v in d.noise.items() if isinstance(v, float))
    parts = [
        f"<h1>twin diagnose: {html.escape(d.prior.name)}</h1>",
        f"<p>{d.windows.get('train')} training and {d.windows.get('held_out')} held-out free-run windows of "
        f"{d.windows.get('length_s')} s; {d.seconds:.0f} s. Noise: {html.escape(noise)}.</p>",
        "<h2>Effects found</h2>", _table(["effect", "parameters [95 % CI]", "held-out misfit removed",
                                          "per DOF", "rivals"], eff_rows) if eff_rows else "<p>none</p>",
        "<h2>Held-out fit (R² / MAE)</h2>", _table(["twin", "u", "v", "r"], fit_rows),
        f'<img src="data:image/png;base64,{series_png(d)}" alt="held-out windows">',
        "<h2>Where the twin before disagreed</h2>",
        _table(["dimension", "bin", "DOF", "kind", "n", "RMS", "bias", "RMS/noise", "z"], loc_rows)
        if loc_rows else "<p>no bin differs significantly from the rest</p>",
        _table(["DOF", "residual is", "RMS early", "RMS late"], grow_rows),
        _table(["DOF", "follows", "", ""], corr_rows),
        "<h2>Unexplained after the amendment</h2>",
        _table(["DOF", "dimension", "bin", "RMS", "RMS/noise", "follows"], unexpl) if unexpl else "<p>nothing</p>",
        "".join(f"<p>note: {html.escape(n)}</p>" for n in d.notes),
    ]
    style = ("<style>body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse;"
             "margin:8px 0}td,th{border:1px solid #ccc;padding:3px 6px;font-size:13px}img{max-width:100%}</style>")
    write_text_atomic(Path(path), f"<!doctype html><html><head><meta charset='utf-8'>{style}</head><body>"
                      + "\n".join(parts) + "</body></html>\n")
