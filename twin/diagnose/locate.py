"""Where the twin's free-run residual ν̂ − ν concentrates, what kind it is, and what
it correlates with: pure functions on flat arrays, no twin, no MuJoCo.

Samples of one free-run window are strongly correlated (the residual of a free run
is smooth), so every standard error here is cluster-robust with the windows as the
clusters (CR1 sandwich), and Student t with (clusters − 1) degrees of freedom turns
it into a p-value (for a bin against the rest, the fewer clusters of the two), so a
bin seen in three windows cannot look certain and one seen in one window never does. Each function
tests many things at once; its z is the normal quantile of the Bonferroni-adjusted
p-value over everything that call tested, so z ≥ 3 means pure noise would give any
such entry in the whole table with probability < 0.13 %: a test of a difference either way (a bias,
a correlation) counts both tails, one of an excess (a larger spread, a residual that grows) one.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.special import ndtri_exp
from scipy.stats import t as student_t

DOFS = ("u", "v", "r")
Z_MIN = 3.0  # below this an entry is what noise alone produces now and then
TOP = 20
ABOVE_NOISE = 2.0  # a residual RMS over this many σ is more than the measurement's own noise
GROWS = 1.3  # a late RMS this much above the early one: the residual grows along the free run


# ---------------------------------------------------------------- statistics

def _family_z(t: np.ndarray | float, df: np.ndarray | float, n_tests: int, two_sided: bool = False) -> np.ndarray:
    """z of the Bonferroni-adjusted upper tail P(T > t)·n_tests (two_sided: t is |t| of a test
    of a difference either way, and the tail is doubled), via logs (no underflow); 0 where there
    is no evidence (df < 1)."""
    t, df = np.broadcast_arrays(np.asarray(t, float), np.asarray(df, float))
    z = np.zeros(t.shape)
    ok = (df >= 1) & np.isfinite(t)
    if np.any(ok):
        tails = np.log(max(n_tests, 1)) + (np.log(2.0) if two_sided else 0.0)
        logp = np.minimum(tails + student_t.logsf(t[ok], df[ok]), 0.0)
        z[ok] = np.maximum(-ndtri_exp(logp), 0.0)
    return z


def _contrast(y: np.ndarray, inside: np.ndarray, cluster: np.ndarray) -> tuple[float, float, int]:
    """Difference of means (inside − outside), its cluster-robust t and degrees of
    freedom min(clusters inside, clusters outside) − 1: both means need their own
    spread of clusters to be trusted. cluster: ids 0..G−1."""
    n1, n0 = int(inside.sum()), int((~inside).sum())
    if n1 == 0 or n0 == 0:
        return float("nan"), 0.0, 0
    m1, m0 = float(y[inside].mean()), float(y[~inside].mean())
    psi = np.where(inside, (y - m1) / n1, -(y - m0) / n0)  # influence of each sample on m1 − m0
    s = np.bincount(cluster, psi)
    g = len(np.unique(cluster))
    df = min(len(np.unique(cluster[inside])), len(np.unique(cluster[~inside]))) - 1
    var = float(np.sum(s ** 2)) * g / max(g - 1, 1)
    if df < 1 or var <= 0:
        return m1 - m0, 0.0, 0
    return m1 - m0, (m1 - m0) / np.sqrt(var), df


def _mean_t(y: np.ndarray, cluster: np.ndarray) -> tuple[float, float, int]:
    """Mean, its cluster-robust t against zero and clusters − 1 degrees of freedom."""
    if not len(y):
        return float("nan"), 0.0, 0
    m = float(y.mean())
    s = np.bincount(cluster, (y - m) / len(y))
    g = len(np.unique(cluster))
    var = float(np.sum(s ** 2)) * g / max(g - 1, 1)
    return (m, m / np.sqrt(var), g - 1) if g > 1 and var > 0 else (m, 0.0, 0)


def _ids(window: np.ndarray) -> np.ndarray:
    return np.unique(np.asarray(window), return_inverse=True)[1].ravel()


# ---------------------------------------------------------------- bins

def _cut(x, edges: list[float], labels: list[str]) -> np.ndarray:
    x = np.asarray(x, float)
    out = np.asarray(labels, dtype=object)[np.digitize(np.nan_to_num(x), edges)]
    out[~np.isfinite(x)] = ""
    return out


def _per_recording(ctx: dict, n: int) -> np.ndarray:
    return np.asarray(ctx.get("recording", np.zeros(n, int)))


def _run_third(ctx: dict) -> np.ndarray:
    t = np.asarray(ctx["run_time_s"], float)
    rec = _per_recording(ctx, len(t))
    frac = np.full(len(t), np.nan)
    for k in np.unique(rec):
        m = (rec == k) & np.isfinite(t)
        if np.any(m):
            span = np.ptp(t[m])
            frac[m] = (t[m] - t[m].min()) / span if span > 0 else np.nan
    return _cut(frac, [1 / 3, 2 / 3], ["first", "middle", "last"])


def _time_block(ctx: dict, block_s: float = 60.0) -> np.ndarray:
    t = np.asarray(ctx["run_time_s"], float)
    rec = _per_recording(ctx, len(t))
    several = len(np.unique(rec)) > 1
    block = np.floor(np.nan_to_num(t) / block_s).astype(int)
    keys, inv = np.unique(np.column_stack([rec.astype(int), block]), axis=0, return_inverse=True)
    names = [f"{f'rec{r} ' if several else ''}{b * block_s:g}-{(b + 1) * block_s:g} s" for r, b in keys.tolist()]
    out = np.asarray(names, dtype=object)[inv.ravel()] if len(t) else np.zeros(0, object)
    out[~np.isfinite(t)] = ""
    return out


def _heading(ctx: dict) -> np.ndarray:
    h = np.asarray(ctx["heading_deg"], float)
    k = np.floor(np.mod(np.nan_to_num(h), 360.0) / 45.0).astype(int)
    out = np.array([f"{45 * i}-{45 * i + 45}°" for i in range(8)], dtype=object)[np.clip(k, 0, 7)]
    out[~np.isfinite(h)] = ""
    return out


def _labels(ctx: dict, key: str) -> np.ndarray:
    x = np.asarray(ctx[key])
    if x.dtype == bool:
        return np.where(x, "yes", "no").astype(object)
    return np.array([str(v) for v in x.tolist()], dtype=object)


# Fixed physical bins: a bin boundary means the same on every boat and recording, and
# the table reads without a legend. Yaw rate is binned with its sign, so a residual that
# depends on the turn direction (lever arm, asymmetry) is not averaged away.
DIMENSIONS: dict[str, tuple[str, Callable[[dict], np.ndarray]]] = {
    "speed": ("u_m_s", lambda c: _cut(c["u_m_s"], [0.0, 0.2, 0.6, 1.2],
                                      ["u<0", "u 0-0.2", "u 0.2-0.6", "u 0.6-1.2", "u>1.2"])),
    "yaw_rate": ("r_rad_s", lambda c: _cut(np.degrees(np.asarray(c["r_rad_s"], float)), [-10.0, -3.0, 3.0, 10.0],
                                           ["r<-10°/s", "r -10..-3°/s", "|r|<3°/s", "r 3..10°/s", "r>10°/s"])),
    "region": ("region", lambda c: _labels(c, "region")),
    "heading": ("heading_deg", _heading),
    "since_step": ("since_input_step_s", lambda c: _cut(c["since_input_step_s"], [1.0, 3.0],
                                                         ["<1 s", "1-3 s", ">3 s"])),
    "near_zero_pwm": ("near_zero_pwm", lambda c: _labels(c, "near_zero_pwm")),
    "pwm_diff": ("pwm_diff_us", lambda c: _cut(c["pwm_diff_us"], [-100.0, -20.0, 20.0, 100.0],
                                               ["<-100µs", "-100..-20µs", "|Δ|<20µs", "20..100µs", ">100µs"])),
    "run_third": ("run_time_s", _run_third),
    "time_block": ("run_time_s", _time_block),
    # by the log's file name where the context has it (the index counts from 0, which a reader need not know)
    "recording": ("recording", lambda c: _labels(c, "recording_name" if "recording_name" in c else "recording")),
}


# ---------------------------------------------------------------- locate

@dataclass
class _Cell:
    dimension: str
    bin: str
    dof: str
    n: int
    windows: int
    rms: float
    bias: float
    rms_over_noise: float
    share_of_residual: float
    share_of_samples: float
    t_spread: float
    df_spread: int
    t_bias: float
    df_bias: int
    excess_spread: float
    excess_bias: float
    shift_sq: float  # (bias − rest's)²: how much of the bin's excess mean square its bias explains
    var_change: float  # bin's variance − rest's


def locate(res: np.ndarray, noise, window: np.ndarray, context: dict, *, top: int = TOP,
           z_min: float = Z_MIN) -> list[dict]:
    """Bins of every dimension (DIMENSIONS) where a DOF's residual differs from the rest.

    Per dimension, DOF and bin: n, windows, rms, bias (mean), rms_over_noise,
    share_of_residual (of the DOF's Σres² in that dimension's labelled samples) against
    share_of_samples, and two cluster-robust contrasts against the rest of the labelled
    samples: "spread" (mean square larger, one-sided) and "bias" (mean different).
    An entry is a "bias" when that contrast is significant and the bin's mean shift
    explains at least as much of its excess mean square as a change of variance would
    (shift² ≥ Δvariance), else a "spread". Its size is the squared residual it accounts
    for: n·(MS_bin − MS_all) for a spread, the between-group n_b·n_rest/n·shift² for a
    bias (positive also when the bins' biases cancel overall). Entries with z ≥ z_min,
    largest first, at most `top`. Dimensions whose context key is missing are skipped;
    NaN residuals and unlabelled samples are left out."""
    res = np.asarray(res, float).reshape(-1, 3)
    noise = np.asarray(noise, float).reshape(3)
    cluster = _ids(window)
    cells: list[_Cell] = []
    for dim, (key, labeller) in DIMENSIONS.items():
        if key not in context:
            continue
        labels = np.asarray(labeller(context), dtype=object)
        for d, dof in enumerate(DOFS):
            ok = np.isfinite(res[:, d]) & (labels != "")
            cells += _cells(dim, dof, res[ok, d], labels[ok], cluster[ok], noise[d])
    n_tests = sum(c.df_spread >= 1 for c in cells) + sum(c.df_bias >= 1 for c in cells)
    z_s = _family_z([c.t_spread for c in cells], [c.df_spread for c in cells], n_tests)
    z_b = _family_z([abs(c.t_bias) for c in cells], [c.df_bias for c in cells], n_tests, two_sided=True)
    out = []
    for c, zs, zb in zip(cells, z_s, z_b):
        if zb >= z_min and c.shift_sq >= c.var_change:
            kind, z, size = "bias", zb, c.excess_bias
        elif zs >= z_min:
            kind, z, size = "spread", zs, c.excess_spread
        else:
            continue
        out.append({"dimension": c.dimension, "bin": c.bin, "dof": c.dof, "n": c.n, "windows": c.windows,
                    "rms": c.rms, "bias": c.bias, "rms_over_noise": c.rms_over_noise,
                    "share_of_residual": c.share_of_residual, "share_of_samples": c.share_of_samples,
                    "z": float(z), "kind": kind, "excess": float(size)})
    out.sort(key=lambda e: (-e["excess"], -e["z"]))
    return out[:top]


def _cells(dim: str, dof: str, y: np.ndarray, labels: np.ndarray, cluster: np.ndarray,
           sigma: float) -> list[_Cell]:
    n = len(y)
    if n < 2:
        return []
    y2 = y ** 2
    ss, ms_all = float(y2.sum()), float(y2.mean())
    cells = []
    for b in np.unique(labels):
        inside = labels == b
        nb = int(inside.sum())
        if nb == n:  # the whole dimension is one bin: nothing to contrast
            continue
        _, ts, dfs = _contrast(y2, inside, cluster)
        shift, tb, dfb = _contrast(y, inside, cluster)
        ms_b, mean_b = float(y2[inside].mean()), float(y[inside].mean())
        var_change = float(y[inside].var() - y[~inside].var())
        cells.append(_Cell(
            dim, str(b), dof, nb, len(np.unique(cluster[inside])), float(np.sqrt(ms_b)), mean_b,
            float(np.sqrt(ms_b) / sigma) if sigma > 0 else float("nan"),
            float(y2[inside].sum() / ss) if ss > 0 else 0.0, nb / n, ts, dfs, tb, dfb,
            nb * (ms_b - ms_all), nb * (n - nb) / n * shift ** 2, shift ** 2, var_change))
    return cells


def overall(res: np.ndarray, noise, window: np.ndarray) -> dict:
    """Per DOF over all compared samples: n, rms, bias, rms_over_noise and z of the bias
    against zero (cluster-robust, adjusted over the three DOFs)."""
    res = np.asarray(res, float).reshape(-1, 3)
    noise = np.asarray(noise, float).reshape(3)
    cluster = _ids(window)
    out = {}
    for d, dof in enumerate(DOFS):
        ok = np.isfinite(res[:, d])
        y = res[ok, d]
        m, t, df = _mean_t(y, _ids(cluster[ok]))
        rms = float(np.sqrt(np.mean(y ** 2))) if len(y) else float("nan")
        out[dof] = {"n": int(len(y)), "rms": rms, "bias": m,
                    "rms_over_noise": float(rms / noise[d]) if noise[d] > 0 else float("nan"),
                    "z_bias": float(_family_z(abs(t), df, 3, two_sided=True))}
    return out


# ---------------------------------------------------------------- growth along the free run

def growth(res_w: np.ndarray, time_in_window_s: np.ndarray, noise=None, *, early_s: float = 2.0,
           late_s: float = 3.0, z_min: float = Z_MIN) -> dict:
    """Does the residual grow along the free runs? res_w (W, n, 3); time_in_window_s
    (n,) or (W, n). Per DOF: rms_early over the first early_s after each window's
    first compared sample, rms_late over its last late_s, ratio late/early, z of
    "late mean square > early" (paired per window, t over the W windows, adjusted over
    the three DOFs), n_windows, verdict, offset_at_start.

    The twin starts each window from the measured state, so:
    - "dynamics": the residual grows along the run (z ≥ z_min, ratio ≥ 1.5, late RMS
      above noise): a force or acceleration the twin lacks integrates into velocity.
    - "measurement": it is already above noise early and does not grow that way: an
      offset between what the sensors report and the state (heading error, antenna
      position, timing) that no amount of free run makes worse.
    - "unsettled": above noise and growing (late/early ≥ GROWS) without significance: this
      recording cannot tell the two apart.
    - "none": neither early nor late RMS is above noise.
    "Above noise" is RMS > 2σ (noise: σ of u, v, r; the residual of a correct twin is
    about √2σ at most: the measurement's noise plus the start state's). Without noise,
    anything counts as above it. offset_at_start: early RMS above noise even when the
    verdict is "dynamics" (both at once)."""
    res_w = np.asarray(res_w, float).reshape(np.shape(res_w)[0], -1, 3)
    t = np.broadcast_to(np.asarray(time_in_window_s, float), res_w.shape[:2])
    sigma = np.zeros(3) if noise is None else np.asarray(noise, float).reshape(3)
    out = {}
    for d, dof in enumerate(DOFS):
        y = res_w[..., d]
        ok = np.isfinite(y) & np.isfinite(t)
        t_first = np.min(np.where(ok, t, np.inf), axis=1, keepdims=True)
        t_last = np.max(np.where(ok, t, -np.inf), axis=1, keepdims=True)
        early = ok & (t <= t_first + early_s)
        late = ok & (t >= t_last - late_s) & (t > t_first + early_s)
        y2 = np.where(ok, y, 0.0) ** 2
        ne, nl = early.sum(axis=1), late.sum(axis=1)
        paired = (ne > 0) & (nl > 0)
        ms_e = (y2 * early).sum(axis=1)[paired] / ne[paired]
        ms_l = (y2 * late).sum(axis=1)[paired] / nl[paired]
        rms_e = float(np.sqrt((y2 * early).sum() / early.sum())) if early.any() else float("nan")
        rms_l = float(np.sqrt((y2 * late).sum() / late.sum())) if late.any() else float("nan")
        dif, w = ms_l - ms_e, int(paired.sum())
        sd = float(np.std(dif, ddof=1)) if w > 1 else 0.0
        z = float(_family_z(dif.mean() / (sd / np.sqrt(w)), w - 1, 3)) if w > 1 and sd > 0 else 0.0
        ratio = rms_l / rms_e if rms_e > 0 else (float("inf") if rms_l > 0 and rms_e == 0 else float("nan"))
        floor = ABOVE_NOISE * sigma[d]
        early_above, late_above = bool(rms_e > floor), bool(rms_l > floor)
        if z >= z_min and ratio >= 1.5 and late_above:
            verdict = "dynamics"
        elif early_above and not ratio >= GROWS:
            verdict = "measurement"
        elif early_above or late_above:
            verdict = "unsettled"  # above the noise and growing, but not significantly: too few windows to say
        else:
            verdict = "none"
        out[dof] = {"rms_early": rms_e, "rms_late": rms_l, "ratio": float(ratio), "z": z, "n_windows": w,
                    "verdict": verdict, "offset_at_start": early_above}
    return out


# ---------------------------------------------------------------- correlations

def correlations(res: np.ndarray, window: np.ndarray, signals: dict[str, np.ndarray]) -> dict[str, list[dict]]:
    """Pearson r of each DOF's residual with each signal, over the samples where both are
    finite, with a cluster-robust z (windows as clusters, the delta-method influence of
    each sample on r, adjusted over all DOF × signal pairs, two-sided). Sorted by |r|;
    a constant signal gets r = z = 0."""
    res = np.asarray(res, float).reshape(-1, 3)
    cluster = _ids(window)
    raw: dict[str, list[tuple[str, float, float, int]]] = {}
    for d, dof in enumerate(DOFS):
        raw[dof] = [(name, *_correlation(res[:, d], np.asarray(x, float), cluster)) for name, x in signals.items()]
    n_tests = sum(df >= 1 for rows in raw.values() for *_, df in rows)
    out = {}
    for dof, rows in raw.items():
        z = _family_z([abs(t) for _, _, t, _ in rows], [df for *_, df in rows], n_tests, two_sided=True) if rows else []
        out[dof] = sorted(({"signal": name, "r": r, "z": float(zi)} for (name, r, _, _), zi in zip(rows, z)),
                          key=lambda e: -abs(e["r"]))
    return out


def _correlation(y: np.ndarray, x: np.ndarray, cluster: np.ndarray) -> tuple[float, float, int]:
    ok = np.isfinite(y) & np.isfinite(x)
    y, x, g = y[ok], x[ok], cluster[ok]
    if len(y) < 3:
        return 0.0, 0.0, 0
    sx, sy = float(x.std()), float(y.std())
    if sx <= 1e-12 * max(1.0, float(np.abs(x).max())) or sy == 0:
        return 0.0, 0.0, 0
    xs, ys = (x - x.mean()) / sx, (y - y.mean()) / sy
    r = float(np.mean(xs * ys))
    psi = (xs * ys - r * (xs ** 2 + ys ** 2) / 2) / len(y)
    s = np.bincount(_ids(g), psi)
    k = len(s)
    var = float(np.sum(s ** 2)) * k / max(k - 1, 1)
    return (r, r / np.sqrt(var), k - 1) if k > 1 and var > 0 else (r, 0.0, 0)


# ---------------------------------------------------------------- text

def format_located(entries: list[dict]) -> str:
    """The entries as a text table of at most 100 columns (u, v in m/s, r in °/s)."""
    if not entries:
        return "no bin where the residual differs significantly from the rest"
    head = (f"{'#':>2} {'dimension':13} {'bin':15} {'dof':3} {'kind':6} {'n':>6} {'rms':>8} {'bias':>8} "
            f"{'rms/σ':>6} {'%res':>5} {'%n':>5} {'z':>6}")
    lines = [head, "-" * len(head)]
    for i, e in enumerate(entries, 1):
        k = np.degrees(1.0) if e["dof"] == "r" else 1.0
        lines.append(f"{i:2d} {e['dimension'][:13]:13} {str(e['bin'])[:15]:15} {e['dof']:3} {e['kind']:6} "
                     f"{e['n']:6d} {e['rms'] * k:8.3g} {e['bias'] * k:8.3g} {e['rms_over_noise']:6.3g} "
                     f"{100 * e['share_of_residual']:5.1f} {100 * e['share_of_samples']:5.1f} "
                     f"{min(e['z'], 999.0):6.1f}")
    lines.append("u, v in m/s, r in °/s; z: cluster-robust, Bonferroni-adjusted over the table's tests")
    if any(e["dimension"] == "region" for e in entries):
        lines.append("region: the thrusters left, right: f ahead, r astern (rf: the left astern, the right ahead)")
    return "\n".join(lines)
