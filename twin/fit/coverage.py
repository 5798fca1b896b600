"""What a fit saw, so that a score on other runs can say where the twin extrapolates.

A twin identified on some runs is pinned by the states and manoeuvres those runs hold. Where a
new run goes further (faster, turning harder, a manoeuvre the fit saw only a few times) the twin
extrapolates, and a poor score there says less about missing physics than about missing data.
`Envelope` is what the fitted recordings held: the range of u, v and r between the 1st and 99th
percentiles of the samples of their free-run windows (a spike at either end does not widen it) and
those windows per manoeuvre (evaluate.MANOEUVRES, counted by `evaluate.fitted_envelope` as evaluate
counts a judged recording's, so the two compare). `twin identify`
writes it into the vessel file's uncertainty block as "fitted_on"; `evaluate.misfit_by_manoeuvre`
reads a judged recording against it: the share of its free-run samples outside that range (the
samples R² is pooled over: overlapping windows count a sample once per window) and the share of
1 − R² they carry. By that definition the fitted recordings themselves leave OWN_TAIL of their
samples beyond the range in each velocity: a judged recording is said to reach beyond what the fit
saw in a velocity where more than twice that share of its samples do, or where its farthest sample
lies half the span's width past the span. The envelope keeps the
fitted logs' file names, so that a score on one of them is said to be in-sample.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import TwinError
from .metrics import DOFS

RANGE_PERCENTILES = (1.0, 99.0)
OWN_TAIL = (RANGE_PERCENTILES[0] + 100.0 - RANGE_PERCENTILES[1]) / 100.0  # the fitted samples' share beyond, per DOF
FAR_SPANS = 0.5  # judged samples this many of the span's widths past its end reach beyond it, however few
DEFAULT_STRIDE_S = 2.0


@dataclass(frozen=True)
class Envelope:
    """ranges: {u, v, r: (low, high)} in m/s and rad/s; windows: the fitted logs' free-run windows
    per manoeuvre, counted as evaluate counts (horizon_s long, one every stride_s; not the fit's
    own windows, whose length and spacing are the fit's choice); logs: how many recordings;
    sources: their file names (empty for a record written without them)."""

    ranges: dict[str, tuple[float, float]]
    windows: dict[str, int]
    horizon_s: float
    logs: int
    stride_s: float = 2.0
    sources: tuple[str, ...] = ()

    def outside(self, states: np.ndarray) -> np.ndarray:
        """Boolean per sample of `states` (..., 3: u, v, r): beyond the range in any DOF (NaN: not)."""
        x = np.asarray(states, float)
        out = np.zeros(x.shape[:-1], bool)
        for k, d in enumerate(DOFS):
            lo, hi = self.ranges[d]
            with np.errstate(invalid="ignore"):
                out |= (x[..., k] < lo) | (x[..., k] > hi)
        return out

    def to_dict(self) -> dict:
        return {"ranges": {d: [float(a), float(b)] for d, (a, b) in self.ranges.items()},
                "windows": {k: int(n) for k, n in self.windows.items()}, "horizon_s": float(self.horizon_s),
                "stride_s": float(self.stride_s), "logs": int(self.logs), "percentiles": list(RANGE_PERCENTILES),
                **({"sources": list(self.sources)} if self.sources else {})}


# as printed: r in °/s, as every table of the CLI gives the yaw rate's error (the states are kept in rad/s)
UNITS = {"u": "m/s", "v": "m/s", "r": "°/s"}
SHOWN = {"u": 1.0, "v": 1.0, "r": 180.0 / math.pi}


def span_text(ranges: dict) -> str:
    """"u −0.10..+0.27 m/s, v …, r …" of a {dof: (low, high)} span (an Envelope's or its dict's)."""
    return ", ".join(f"{d} {_signed(SHOWN[d] * lo)}..{_signed(SHOWN[d] * hi)} {UNITS[d]}" for d, (lo, hi) in ranges.items())


def _signed(x: float) -> str:
    """Two decimals, or two significant digits where that shows a small span as more than 0.00."""
    return f"{x:+.2f}" if abs(x) >= 0.1 or x == 0 else f"{x:+.2g}"


def from_dict(data, where: str = "fitted_on") -> Envelope:
    """An Envelope from its to_dict form; TwinError naming `where` on anything else."""
    def number(x) -> float:
        if isinstance(x, bool) or not isinstance(x, (int, float)):
            raise TypeError
        return float(x)

    def count(x) -> int:
        if isinstance(x, bool) or not isinstance(x, int) or x < 0:
            raise ValueError
        return x

    try:
        ranges = {d: (number(data["ranges"][d][0]), number(data["ranges"][d][1])) for d in DOFS}
        windows = {str(k): count(n) for k, n in dict(data["windows"]).items()}
        sources = data.get("sources", [])
        if not isinstance(sources, list) or not all(isinstance(s, str) for s in sources):
            raise TypeError
        env = Envelope(ranges, windows, number(data["horizon_s"]), count(data["logs"]),
                       number(data.get("stride_s", DEFAULT_STRIDE_S)), tuple(sources))
    except (KeyError, TypeError, ValueError, IndexError):
        raise TwinError(f"{where}: needs ranges of u, v, r (low, high numbers), windows per manoeuvre (counts), "
                        "horizon_s, stride_s and logs (and sources, if any, a list of file names)") from None
    if any(not (np.isfinite(a) and np.isfinite(b) and a <= b) for a, b in env.ranges.values()):
        raise TwinError(f"{where}: each range needs finite low ≤ high")
    if not (env.horizon_s > 0 and env.stride_s > 0 and env.logs >= 1):
        raise TwinError(f"{where}: horizon_s and stride_s must be positive and logs at least 1")
    return env


def sample_ranges(states: np.ndarray) -> dict[str, tuple[float, float]]:
    """{u, v, r: (1st, 99th percentile)} of the finite samples of `states` (n, 3)."""
    x = np.asarray(states, float)
    out = {}
    for k, d in enumerate(DOFS):
        col = x[:, k][np.isfinite(x[:, k])]
        if not col.size:
            raise TwinError(f"no measured {d} to bound what the fit saw")
        lo, hi = np.percentile(col, RANGE_PERCENTILES)
        out[d] = (float(lo), float(hi))
    return out


def beyond(env: Envelope, meas: np.ndarray, sq: np.ndarray, total: np.ndarray) -> dict:
    """The judged samples outside `env` and their part of the misfit: meas (W, n, 3) the measured
    predicted samples, sq their squared errors (0 where none), total the pooled Σ(y − ȳ)² per DOF
    (evaluate._squares). {"samples", "outside", "share_of_samples", "share": {u, v, r} of 1 − R², "dofs":
    {each DOF the judged samples leave the span in: "share_of_samples", "below", "above": the farthest
    judged sample beyond the span's low and high end (None where none lies beyond that end), and
    "reaches": whether more than twice OWN_TAIL of the samples lie beyond (what the fitted samples
    themselves leave beyond by the span's definition), or the farthest lies FAR_SPANS of the span's
    width past its end}, "r2_beyond", "r2_within": {u, v, r} the score
    of the samples beyond the span and within it, each about its own mean}."""
    paired = np.isfinite(meas).any(axis=-1)
    out_mask = env.outside(meas) & paired
    n, k = int(paired.sum()), int(out_mask.sum())
    sse = sq[out_mask].sum(axis=0) if k else np.zeros(3)
    per_dof = {}
    for i, d in enumerate(DOFS):  # which way the judged data leaves the span, and how far: what to record next
        lo, hi = env.ranges[d]
        x = meas[..., i][paired]
        with np.errstate(invalid="ignore"):
            beyond_d = (x < lo) | (x > hi)
        if beyond_d.any():
            with np.errstate(invalid="ignore"):
                below, above = x[x < lo], x[x > hi]
            share = float(beyond_d.sum() / n)
            # how far past the span the farthest judged sample goes, in spans: a few samples well beyond it
            # are new ground as much as many just past its ends
            past = max(lo - float(below.min()) if below.size else 0.0, float(above.max()) - hi if above.size else 0.0)
            far = past > FAR_SPANS * (hi - lo)
            per_dof[d] = {"share_of_samples": share, "below": float(below.min()) if below.size else None,
                          "above": float(above.max()) if above.size else None,
                          "reaches": share > 2.0 * OWN_TAIL or far}
    return {"samples": n, "outside": k, "share_of_samples": k / n if n else None,
            "share": {d: float(sse[i] / total[i]) if total[i] > 0 else None for i, d in enumerate(DOFS)},
            "dofs": per_dof, "r2_beyond": _subset_r2(meas, sq, out_mask), "r2_within": _subset_r2(meas, sq, paired & ~out_mask)}


def _subset_r2(meas: np.ndarray, sq: np.ndarray, mask: np.ndarray) -> dict:
    """R² per DOF of the samples in `mask` about their own mean (None with fewer than 10 samples or no spread)."""
    out = {}
    for i, d in enumerate(DOFS):
        y = meas[..., i][mask]
        e = sq[..., i][mask]
        ok = np.isfinite(y)
        y, e = y[ok], e[ok]
        ss = float(np.sum((y - y.mean()) ** 2)) if y.size >= 10 else 0.0
        out[d] = 1.0 - float(e.sum()) / ss if ss > 0 else None
    return out
