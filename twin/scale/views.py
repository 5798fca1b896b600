"""A Monte Carlo band to look at: a PNG (the track with the band around it, and each state's
band over time) and a rerun recording (the nominal twin moving along its track inside the
band, some draws around it, the bands as time series).

Rerun entities: world/nominal/path and world/nominal/vessel (the nominal twin, as `twin
simulate` draws a run), world/band/edge_port and edge_starboard (the band across the nominal
heading at its level), world/draws (positions of the first draws over time), plots/<q>/nominal,
plots/<q>/p<N> (percentiles over time) for heading (deg), u, v, r and the distance from nominal.
"""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from ..files import RRD_BAND, write_bytes_atomic
from .montecarlo import ONE_SIDED, MonteCarlo

PLOTTED = (("deviation", "distance from nominal (m)", 1.0), ("psi", "heading (deg)", 180.0 / np.pi),
           ("u", "u (m/s)", 1.0), ("v", "v (m/s)", 1.0), ("r", "r (deg/s)", 180.0 / np.pi))
# the PNG shows each state's band as its offset from the nominal: an identified twin's band is a
# few per cent of the state, invisible around the state itself


def band_edges(mc: MonteCarlo) -> tuple[np.ndarray, np.ndarray]:
    """(S, 2) north, east of the band's port and starboard edges: the nominal position moved
    across its heading by the band's low and high cross-track percentiles."""
    lo, hi = mc.band.interval("cross")
    n, e, psi = mc.nominal[:, 0], mc.nominal[:, 1], mc.nominal[:, 2]
    side = np.column_stack([-np.sin(psi), np.cos(psi)])  # starboard, in (north, east)
    base = np.column_stack([n, e])
    return base + lo[:, None] * side, base + hi[:, None] * side


def png_bytes(mc: MonteCarlo, title: str = "") -> bytes:
    """The track panel and one panel per state over time, the band at its level shaded."""
    # late: matplotlib (0.21 s) only for a PNG band
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    b = mc.band
    fig, axes = plt.subplots(2, 3, figsize=(13, 7.5))
    ax = axes[0, 0]
    for track in mc.sample_tracks:
        ax.plot(track[:, 1], track[:, 0], color="0.75", lw=0.5)
    port, starboard = band_edges(mc)
    ax.plot(port[:, 1], port[:, 0], "--", color="tab:blue", lw=1, label=f"{100 * b.level:g} % across track")
    ax.plot(starboard[:, 1], starboard[:, 0], "--", color="tab:blue", lw=1)
    ax.plot(mc.nominal[:, 1], mc.nominal[:, 0], color="k", lw=1.5, label="nominal")
    ax.set(xlabel="east (m)", ylabel="north (m)", title="track")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=8)
    for ax, (q, label, k) in zip(axes.flat[1:], PLOTTED):
        lo, hi = b.interval(q)
        ref = b.nominal[q]
        ax.fill_between(b.t_s, k * (lo - ref), k * (hi - ref), color="tab:blue", alpha=0.25, lw=0,
                        label=f"{100 * b.level:g} % band")
        ax.fill_between(b.t_s, k * (b.at(q, 25.0) - ref), k * (b.at(q, 75.0) - ref), color="tab:blue", alpha=0.35,
                        lw=0, label="quartiles")
        ax.plot(b.t_s, np.zeros_like(b.t_s), color="k", lw=1, label="nominal")
        ax.set(xlabel="t (s)", ylabel=label if q in ONE_SIDED else f"{label}: draw − nominal")
    axes[0, 1].legend(fontsize=8)
    fig.suptitle(title or f"{mc.vessel.name}: {mc.draws} draws, {mc.mission.source}", fontsize=10)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return buf.getvalue()


def write_png(mc: MonteCarlo, path: Path) -> None:
    write_bytes_atomic(path, png_bytes(mc))


def write_rrd(mc: MonteCarlo, path: Path) -> None:
    """The band as a rerun recording (module docstring), written atomically."""
    # late: rerun (0.26 s, twin.viz.rerun_log with it) only for an .rrd band
    import rerun as rr
    import rerun.blueprint as rrb

    from ..viz.rerun_log import rrd_file

    plots = [rrb.TimeSeriesView(origin=f"plots/{q}", name=label) for q, label, _ in PLOTTED]
    blueprint = rrb.Blueprint(rrb.Horizontal(rrb.Spatial3DView(origin="world", name="water"), rrb.Grid(*plots)))
    with rrd_file(path, RRD_BAND, blueprint) as rec:
        _log_world(rr, rec, mc)
        _log_plots(rr, rec, mc)


def _xyz(ne: np.ndarray) -> np.ndarray:
    return np.column_stack([ne[:, 0], ne[:, 1], np.zeros(len(ne))])


def _log_world(rr, rec, mc: MonteCarlo) -> None:
    from ..viz.rerun_log import BOX_CENTER_M, BOX_SIZE_M  # late: rerun, as in write_rrd

    b = mc.band
    times = [rr.TimeColumn("time", duration=b.t_s)]
    rec.log("world/nominal/path", rr.LineStrips3D([_xyz(mc.nominal[:, :2])], colors=[(20, 20, 20)], radii=[0.03]),
            static=True)
    port, starboard = band_edges(mc)
    for name, edge in (("edge_port", port), ("edge_starboard", starboard)):
        rec.log(f"world/band/{name}", rr.LineStrips3D([_xyz(edge)], colors=[(31, 119, 180)], radii=[0.02]),
                static=True)
    half = mc.nominal[:, 2] / 2
    quat = np.column_stack([np.zeros_like(half), np.zeros_like(half), np.sin(half), np.cos(half)])
    rec.send_columns("world/nominal/vessel", indexes=times,
                     columns=rr.Transform3D.columns(translation=_xyz(mc.nominal[:, :2]), quaternion=quat))
    rec.log("world/nominal/vessel/hull", rr.Boxes3D(sizes=[BOX_SIZE_M], centers=[BOX_CENTER_M],
                                                    colors=[(242, 204, 26)]), static=True)
    if len(mc.sample_tracks):
        for k, t in enumerate(b.t_s):  # the draws' cloud at each sample time
            rec.set_time("time", duration=float(t))
            rec.log("world/draws", rr.Points3D(_xyz(mc.sample_tracks[:, k, :2]), radii=[0.04],
                                               colors=[(150, 150, 150)]))


def _log_plots(rr, rec, mc: MonteCarlo) -> None:
    b = mc.band
    times = [rr.TimeColumn("time", duration=b.t_s)]
    for q, _, k in PLOTTED:
        series = {"nominal": b.nominal[q]} | {f"p{p:02g}": b.values[q][i] for i, p in enumerate(b.percentiles)}
        for name, values in series.items():
            entity = f"plots/{q}/{name}"
            color = (20, 20, 20) if name == "nominal" else (31, 119, 180)
            rec.log(entity, rr.SeriesLines(colors=[color], names=[name]), static=True)
            rec.send_columns(entity, indexes=times, columns=rr.Scalars.columns(scalars=k * np.asarray(values)))
