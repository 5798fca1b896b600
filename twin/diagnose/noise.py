"""Measurement noise of a recording, so that "significant" means something.

The white noise σ of the raw GNSS position and heading streams comes from their
scatter about a local polynomial fit: the trajectory is smooth over about a second,
sensor noise is not. The σ this leaves in the prepared velocities u, v, r follows
from the derivative filter prepare() used. Slow errors (GNSS wander, a heading
bias, a lever-arm error) are not white and are not seen here: they are what the
diagnosis looks for.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import savgol_coeffs

from ..prepare.prepared import Prepared, local_ned
from ..recording import Recording

FIT_SPAN_S = 1.0  # over this the motion of a small boat is a quadratic to well below GNSS noise
MAD_TO_SIGMA = 1.4826  # σ / median|x| of a normal distribution
RUN_BREAK = 3.0  # a silence of more than this many median periods ends a gap-free run


@dataclass(frozen=True)
class WhiteNoise:
    """White σ per sample (stream units) from n fit residuals; dt_s the median period
    of the stream with exact repeats dropped."""

    sigma: float
    dt_s: float
    n: int


def distinct(t: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The samples that differ from their predecessor in some column: a fix logged
    again by a faster logger is one measurement, and its copy has zero scatter."""
    x2 = x.reshape(len(t), -1)
    new = np.r_[True, np.any(np.diff(x2, axis=0) != 0, axis=1)] if len(t) else np.zeros(0, bool)
    return t[new], x[new]


def white_noise(t: np.ndarray, x: np.ndarray, span_s: float = FIT_SPAN_S) -> WhiteNoise:
    """σ of the white noise on the samples (t, x) (x: (n,) or (n, k), columns pooled).

    Every gap-free run is cut into consecutive blocks of about span_s (at least 7
    samples); a quadratic (a cubic when the stream is too slow for a short block) is
    fitted to each by least squares on the true sample times. A residual e_i of such
    a fit has variance σ²(1 − h_ii), h the hat matrix, so e_i/√(1 − h_ii) is the
    unbiased per-point correction for the degrees of freedom the fit takes; σ is the
    MAD of these, robust to fix jumps and outliers. Call on distinct() samples."""
    t = np.asarray(t, float)
    x = np.asarray(x, float).reshape(len(t), -1)
    if len(t) < 3:
        return WhiteNoise(float("nan"), float("nan"), 0)
    dt = float(np.median(np.diff(t)))
    degree = 2
    m = max(degree + 5, int(round(span_s / dt)) + 1)
    if (m - 1) * dt > 2 * span_s:  # a slow stream: the block is long, the motion in it less simple
        degree = 3
        m = degree + 5
    cuts = np.flatnonzero(np.diff(t) > RUN_BREAK * dt) + 1
    starts = [s + m * k for s, e in zip(np.r_[0, cuts], np.r_[cuts, len(t)]) for k in range((e - s) // m)]
    if not starts:
        return WhiteNoise(float("nan"), dt, 0)
    idx = np.asarray(starts)[:, None] + np.arange(m)
    tb = t[idx] - t[idx].mean(axis=1, keepdims=True)
    tb = tb / max(float(np.max(np.abs(tb))), 1e-12)  # conditioning only: the fit is scale-free
    q, _ = np.linalg.qr(tb[..., None] ** np.arange(degree + 1))
    hat = np.sum(q ** 2, axis=2)  # (blocks, m) leverages
    y = x[idx]  # (blocks, m, k)
    e = y - q @ (np.swapaxes(q, 1, 2) @ y)
    z = e / np.sqrt(np.clip(1.0 - hat, 1e-9, None))[..., None]
    return WhiteNoise(float(MAD_TO_SIGMA * np.median(np.abs(z))), dt, int(z.size))


def derivative_coeffs(dt_s: float, smoother: str, window_s: float, polyorder: int) -> np.ndarray:
    """The weights prepare.derivative() applies to the samples around each point
    (interior of a segment)."""
    w = int(round(window_s / dt_s)) | 1
    if smoother == "savgol" and w > polyorder:
        return savgol_coeffs(w, polyorder, deriv=1, delta=dt_s)
    return np.array([-0.5, 0.0, 0.5]) / dt_s


def rate_sigma(sigma: float, dt_s: float, smoother: str, window_s: float, polyorder: int,
               fractions: np.ndarray | None = None) -> float:
    """σ of the derivative of white noise σ sampled every dt_s: σ·√Σc².

    prepare() reads the derivative at the grid times by linear interpolation between
    the stream's samples; at a fraction f of the way the variance is
    (1−f)² + f² + 2f(1−f)ρ₁ times the sample's, ρ₁ the lag-one correlation of the
    filter. `fractions` (grid points' f) averages that in; None: at the samples."""
    if not (np.isfinite(sigma) and np.isfinite(dt_s) and dt_s > 0):
        return float("nan")
    c = derivative_coeffs(dt_s, smoother, window_s, polyorder)
    ss = float(np.sum(c ** 2))
    factor = 1.0
    if fractions is not None and len(fractions):
        rho1 = float(np.sum(c[:-1] * c[1:])) / ss
        f = np.clip(fractions, 0.0, 1.0)
        factor = float(np.mean((1 - f) ** 2 + f ** 2 + 2 * f * (1 - f) * rho1))
    return float(sigma * np.sqrt(ss * factor))


def _fractions(ts: np.ndarray, tg: np.ndarray) -> np.ndarray:
    """Where each grid time falls between two stream samples (0 = on a sample)."""
    i = np.clip(np.searchsorted(ts, tg, side="right") - 1, 0, max(len(ts) - 2, 0))
    if len(ts) < 2:
        return np.zeros(0)
    inside = (tg >= ts[0]) & (tg <= ts[-1])
    return ((tg - ts[i]) / (ts[i + 1] - ts[i]))[inside]


def estimate_noise(rec: Recording, prep: Prepared) -> dict:
    """White-noise σ of the GNSS position (gnss_m, per axis) and heading (heading_deg)
    streams of `rec`, and the σ they imply for the prepared u, v (m/s) and r (rad/s)
    through prepare()'s derivative (settings of `prep`), plus the streams' rates and a
    one-sentence `method`. NaN where a stream is too short to tell.

    u and v carry the GNSS rate noise; on top, what prepare() adds: the lever arm
    moves yaw-rate noise into them (u − r·dy, v + r·dx) and the held heading's noise
    rotates the velocity (δv = −u·δψ, δu = v·δψ), counted at the recording's mean
    square speeds. `gnss_rate_m_s` is the GNSS part alone. r's is the heading slope's even where
    prepare() read r from a rate gyro: a gyro stream may come smoothed at its source (the Esso
    Osaka's steps by 0.004-0.012 °/s between samples), and its scatter about local fits then says
    nothing of its error (it read 1e-6 rad/s there)."""
    s = prep.settings
    smoother, polyorder = s.smoother, s.polyorder
    window_s, heading_window_s = s.window_s, s.yaw_rate_window_s
    north, east, _ = local_ned(rec.gnss) if len(rec.gnss) else (np.zeros(0), np.zeros(0), {})
    tg, pos = distinct(np.asarray(rec.gnss.t, float), np.column_stack([north, east]))
    th, psi = distinct(np.asarray(rec.heading.t, float),
                       np.unwrap(rec.heading["psi_rad"]) if len(rec.heading) else np.zeros(0))
    g, h = white_noise(tg, pos), white_noise(th, psi)
    sg = rate_sigma(g.sigma, g.dt_s, smoother, window_s, polyorder, _fractions(tg, prep.t))
    sr = rate_sigma(h.sigma, h.dt_s, smoother, heading_window_s, polyorder, _fractions(th, prep.t))
    dx, dy = s.lever_arm_OP_m or (0.0, 0.0)
    ms_u = float(np.nanmean(prep.u ** 2)) if len(prep.u) else 0.0
    ms_v = float(np.nanmean(prep.v ** 2)) if len(prep.v) else 0.0
    su = np.sqrt(sg ** 2 + (sr * dy) ** 2 + h.sigma ** 2 * ms_v)
    sv = np.sqrt(sg ** 2 + (sr * dx) ** 2 + h.sigma ** 2 * ms_u)
    rate = lambda w: float(1.0 / w.dt_s) if np.isfinite(w.dt_s) and w.dt_s > 0 else 0.0  # noqa: E731
    return {
        "gnss_m": g.sigma,
        "heading_deg": float(np.degrees(h.sigma)),
        "u": float(su), "v": float(sv), "r": sr,
        "gnss_rate_m_s": sg,
        "gnss_rate_hz": rate(g), "heading_rate_hz": rate(h),
        "gnss_samples": g.n, "heading_samples": h.n,
        "method": (f"MAD of the residuals (corrected for the fit's degrees of freedom) of quadratic fits "
                   f"over ~{FIT_SPAN_S:g} s blocks of each gap-free run, exact repeats dropped, carried "
                   f"through the {smoother} derivative of prepare() "
                   f"({window_s:g} s GNSS / {heading_window_s:g} s heading window, order {polyorder})"),
    }
