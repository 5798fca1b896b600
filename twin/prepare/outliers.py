"""Single-sample outliers of the GNSS and heading streams: a fix that multipath threw off the track,
a heading sample that spiked, and came back.

A sample is an outlier when it lies far from where its neighbours put it: each of the four chords
through a neighbour before and one after (one or two samples away, at most MAX_SPAN_S apart)
predicts it by linear interpolation in time, and the sample is judged by the chord that explains
it best. A sample that no chord explains is off its track; one beside an outlier, or beside a
step (a heading that settles after start-up), still has a chord that avoids it. Far means beyond both the floor (FLOOR_GNSS_M,
FLOOR_HEADING_RAD: more than a boat's own motion can put between a sample and the chord of its
neighbours) and K_SCALE times the stream's robust spread of those deviations (1.4826 × the median
deviation). A chord's deviation from real motion is a·t₁·t₂/2: 0.12 m for 1.5 m/s² over
±0.4 s, 0.04 rad for a spin starting at 2 rad/s² over ±0.2 s, under the floors.

Only distinct samples are judged (a logger that repeats a fix at its own rate is not a jump), and a
repeated fix shares its first sample's verdict. Samples within two of either end are not judged.
Nothing is corrected: an outlier is left out of preparation (prepared.py) and counted there and in
`twin info`, so the user sees how many were.
"""
from __future__ import annotations

import numpy as np

FLOOR_GNSS_M = 0.5
FLOOR_HEADING_RAD = float(np.radians(5.0))
K_SCALE = 10.0
MAX_SPAN_S = 1.0
PAIRS = ((1, 1), (1, 2), (2, 1), (2, 2))
PASSES = 6


def spikes(t: np.ndarray, x: np.ndarray, floor: float) -> np.ndarray:
    """Mask of outlier samples of (t s, x (n,) or (n, d)) by the rule of the module docstring. A
    sample next to an outlier is pulled off its chords too: only the worst within two samples either
    side is flagged in a pass, and the deviations are taken again without it (at most PASSES): two
    outliers side by side leave no chord that avoids both of them for the samples between."""
    t = np.asarray(t, float)
    x = np.asarray(x, float).reshape(len(t), -1)
    first = _firsts(x)
    idx = np.flatnonzero(first)  # the first sample of each distinct value
    bad_distinct = np.zeros(len(idx), bool)
    limit = None
    for _ in range(PASSES):
        keep = np.flatnonzero(~bad_distinct)
        deviation = _deviations(t[idx[keep]], x[idx[keep]])
        judged = np.isfinite(deviation)
        if not judged.any():
            break
        if limit is None:  # the spread of the first pass, outliers and all: the median shrugs them off
            limit = max(floor, K_SCALE * 1.4826 * float(np.median(deviation[judged])))
        d = np.where(judged, deviation, -np.inf)
        padded = np.r_[np.full(2, -np.inf), d, np.full(2, -np.inf)]
        worst = np.max(np.stack([padded[k:k + len(d)] for k in range(5)]), axis=0)
        flag = judged & (d > limit) & (d >= worst)
        if not flag.any():
            break
        bad_distinct[keep[flag]] = True
    group = np.cumsum(first) - 1  # which distinct value each sample repeats
    return bad_distinct[group] if len(t) else np.zeros(0, bool)


def _deviations(ts: np.ndarray, xs: np.ndarray) -> np.ndarray:
    """Each sample's distance from the nearest of its four chords' predictions (NaN: not judged)."""
    n = len(ts)
    out = np.full(n, np.nan)
    if n < 5:
        return out
    i = np.arange(2, n - 2)
    predictions = []
    for a, b in PAIRS:
        lo, hi = i - a, i + b
        span = ts[hi] - ts[lo]
        w = ((ts[i] - ts[lo]) / np.where(span > 0, span, 1.0))[:, None]
        p = xs[lo] + w * (xs[hi] - xs[lo])
        p[span > MAX_SPAN_S] = np.nan
        predictions.append(p)
    distance = np.linalg.norm(np.stack(predictions) - xs[i][None], axis=2)  # (chords, samples), NaN: chord too long
    some = np.any(np.isfinite(distance), axis=0)  # a sample with no chord short enough is not judged
    out[i[some]] = np.nanmin(distance[:, some], axis=0)
    return out


def gnss_outliers(north_m: np.ndarray, east_m: np.ndarray, t: np.ndarray) -> np.ndarray:
    return spikes(t, np.column_stack([north_m, east_m]), FLOOR_GNSS_M)


def heading_spikes(psi_unwrapped_rad: np.ndarray, t: np.ndarray) -> np.ndarray:
    return spikes(t, psi_unwrapped_rad, FLOOR_HEADING_RAD)


def distinct_count(mask: np.ndarray, x: np.ndarray) -> int:
    """How many distinct samples (a logger's repeats counted once) `mask` flags."""
    return int(np.sum(mask & _firsts(np.asarray(x, float).reshape(len(mask), -1))))


def _firsts(x: np.ndarray) -> np.ndarray:
    """True at the first sample of each run of one repeated value of x (n, d)."""
    return np.r_[True, np.any(np.diff(x, axis=0) != 0, axis=1)] if len(x) else np.zeros(0, bool)


def describe(counts: dict[str, int]) -> list[str]:
    """`twin info`'s lines for prepared.outlier_counts()."""
    what = {"gnss": f"GNSS fixes off their neighbours' track by more than {FLOOR_GNSS_M:g} m",
            "heading": f"heading samples off their neighbours by more than {np.degrees(FLOOR_HEADING_RAD):.0f}°"}
    return [f"outliers: {what[k]} (left out by preparation): {n}" for k, n in counts.items() if n]
