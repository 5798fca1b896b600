"""Single-sample outliers of the GNSS and heading streams: a fix that multipath threw off the track,
a heading sample that spiked, and came back.

A sample is an outlier when it lies far from where its neighbours put it: each of the four chords
through a neighbour before and one after (one or two samples away, at most MAX_SPAN_S apart)
predicts it by linear interpolation in time, and the sample is judged by the chord that explains
it best. A sample that no chord explains is off its track; one beside an outlier, or beside a
step (a heading that settles after start-up), still has a chord that avoids it. Far means beyond
both the floor (FLOOR_GNSS_M, FLOOR_HEADING_RAD: more than a boat's own motion can put between a
sample and the chord of its neighbours) and K_SCALE times the stream's robust spread of those
deviations (1.4826 × the median deviation). A chord's deviation from real motion is a·t₁·t₂/2:
0.12 m for 1.5 m/s² over ±0.4 s, 0.04 rad for a spin starting at 2 rad/s² over ±0.2 s, under the
floors.

A sample that no such chord can judge, next to a stall or a gap, is judged by the chords through
its next two samples on either side instead (extrapolated back to it, the far one at most
MAX_SPAN_S/2 away, so that a·t₁·t₂/2 stays within a centred chord's). A logger that stalls repeats
its last record for seconds (the Esso Osaka's tests: 0.6-6 % of their records, up to 2.5 s), and
its first fresh record can be a partial one (turn_14-Oct-2020_14_08_51 at 210.1 s: 0.56 m short of
the track, a 6 m/s jump to the next fix); no chord across the stall is short enough to judge it,
the next two fixes are. Only there, and only after the centred passes have left out what they
find: a one-sided chord through an outlier misses its neighbour by twice the outlier's offset (the
first fix after a dropout, on its track, would be flagged so if the one-sided chords came first).

A receiver can also hold its fix for a second or two, with a few millimetres of dither, while the
vessel moves on, and then jump to where the vessel is (the Esso Osaka's turn_14-Oct-2020_15_21_57
at 79.4 s: 1.9 s within 7 mm, then a 0.74-m jump; the track before, after and across it all at
0.37 m/s). Each fix of such a stand is near its neighbours, so no chord rejects it, and the
velocity read from them falls to zero and then spikes. `held_fixes` finds it by what a vessel
cannot do: stand still for HOLD_MIN_S and yet cover, across the stand, the distance its speed
before and after the stand would (within HOLD_SPEED_SHARE), at least HOLD_JUMP_M. A vessel that
really stops and goes on covers less across the stop than its speed would, and one moving slowly
moves its fixes out of the stand. Like a repeated fix, a held one is no new fix: preparation takes
its velocities from the fresh fixes around it (not a dropout: the receiver kept logging).

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
PAIRS = ((1, 1), (1, 2), (2, 1), (2, 2))  # neighbours (before, after) of a centred chord
SIDES = ((1, 2), (-1, -2))  # the next two samples after, or before: a one-sided chord (near, far)
PASSES = 6
HOLD_SPREAD_M = 0.01  # a stand: every fix within this of its first (dither, not motion)
HOLD_MIN_S = 0.4  # ... for at least this long (four fixes at 10 Hz)
HOLD_JUMP_M = 0.2  # the jump across it: several times a GNSS fix's noise
HOLD_SPEED_SHARE = 0.3  # the speed across the stand within this share of the speed before and after it
HOLD_SPEED_SPAN_S = 1.0  # the speeds before and after: over this long


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
    for sided in (False, True):  # centred chords first; then, on the samples they leave, one-sided ones
        for _ in range(PASSES):
            keep = np.flatnonzero(~bad_distinct)
            deviation = _deviations(t[idx[keep]], x[idx[keep]], sided)
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


def _deviations(ts: np.ndarray, xs: np.ndarray, sided: bool = False) -> np.ndarray:
    """Each sample's distance from the nearest of its centred chords' predictions, or with `sided`
    of its one-sided chords' for the samples no centred chord can judge (NaN: not judged)."""
    n = len(ts)
    out = np.full(n, np.nan)
    if n < 5:
        return out
    i = np.arange(2, n - 2)
    centred = np.stack([_chord_distance(ts, xs, i, i - a, i + b, ts[i + b] - ts[i - a] > MAX_SPAN_S)
                        for a, b in PAIRS])
    by_centred = np.isfinite(centred).any(axis=0)
    if not sided:
        out[i[by_centred]] = np.nanmin(centred[:, by_centred], axis=0)
        return out
    one_sided = []
    for near, far in SIDES:  # extrapolated: −1 on a regular grid
        t_near, t_far = np.abs(ts[i + near] - ts[i]), np.abs(ts[i + far] - ts[i])
        # the far end within half a centred chord's span, and no further out than the pair is long
        # (1e-9 s: clock rounding)
        too_far = (t_far > MAX_SPAN_S / 2 + 1e-9) | (t_near > t_far - t_near + 1e-9)
        one_sided.append(_chord_distance(ts, xs, i, i + near, i + far, too_far))
    one_sided = np.stack(one_sided)
    by_side = ~by_centred & np.isfinite(one_sided).any(axis=0)
    out[i[by_side]] = np.nanmin(one_sided[:, by_side], axis=0)
    return out


def _chord_distance(ts, xs, i, lo, hi, too_long) -> np.ndarray:
    """Distance of samples i from the line through samples lo and hi, read at their times (NaN where
    too_long)."""
    span = ts[hi] - ts[lo]
    w = ((ts[i] - ts[lo]) / np.where(span != 0, span, 1.0))[:, None]
    out = np.linalg.norm(xs[lo] + w * (xs[hi] - xs[lo]) - xs[i], axis=1)
    return np.where(too_long, np.nan, out)


def held_fixes(north_m: np.ndarray, east_m: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Mask of the fixes a receiver held while the vessel moved on (module docstring): each stand's
    fixes after its first, which is the fix it holds."""
    t = np.asarray(t, float)
    x = np.column_stack([north_m, east_m]).astype(float)
    held = np.zeros(len(t), bool)
    a = 1
    while a < len(t) - 2:
        b = a
        while b + 1 < len(t) and np.linalg.norm(x[b + 1] - x[a]) <= HOLD_SPREAD_M:
            b += 1
        if t[b] - t[a] >= HOLD_MIN_S - 1e-9 and b + 1 < len(t) and _moved_on(t, x, a, b + 1):
            held[a + 1:b + 1] = True
        a = b + 1
    return held


def _moved_on(t: np.ndarray, x: np.ndarray, first: int, after: int) -> bool:
    """Whether the chord from a stand's first fix to the fix after it runs at the speed of the
    track before the stand and after it (HOLD_SPEED_SPAN_S each)."""
    jump = float(np.linalg.norm(x[after] - x[first]))
    if jump < HOLD_JUMP_M:
        return False
    before = int(np.searchsorted(t, t[first] - HOLD_SPEED_SPAN_S))
    beyond = int(np.searchsorted(t, t[after] + HOLD_SPEED_SPAN_S, side="right")) - 1
    if t[first] - t[before] < HOLD_SPEED_SPAN_S / 2 or t[beyond] - t[after] < HOLD_SPEED_SPAN_S / 2:
        return False  # too near an end to know the speeds around it
    across = jump / (t[after] - t[first])
    speeds = (np.linalg.norm(x[first] - x[before]) / (t[first] - t[before]),
              np.linalg.norm(x[beyond] - x[after]) / (t[beyond] - t[after]))
    return all(abs(across - v) <= HOLD_SPEED_SHARE * v for v in speeds)


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
            "gnss_held": "GNSS fixes held while the vessel moved on (velocities taken across them)",
            "heading": f"heading samples off their neighbours by more than {np.degrees(FLOOR_HEADING_RAD):.0f}°"}
    lines = [f"{'held' if k == 'gnss_held' else 'outliers'}: {what[k]}"
             f"{'' if k == 'gnss_held' else ' (left out by preparation)'}: {n}" for k, n in counts.items() if n]
    # said when there are none too, so that a reader knows the check ran
    return lines or [f"outliers: none ({what['gnss']}, or {what['heading']})"]
