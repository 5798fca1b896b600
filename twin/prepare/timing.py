"""How late a log's heading is against its own gyro, from the two streams alone (no model).

A heading sample stamped t that was taken at t − L (an AHRS or compass filter: a first-order filter
of time constant τ lags a turn by about τ) is ψ(t) = ∫r up to t − L, where r is the gyro's yaw
rate, which no heading filter has touched. Cut into WINDOW_S pieces, each with its own starting
heading and a gyro bias of its own (the integral drifts), the L that lines the heading up with the
integrated gyro best (least squares, scanned on a 10 ms grid) is the heading's delay against the
gyro; the library's `heading_latency` is that delay against the GNSS and PWM, the same where the
gyro is stamped on time. The integral weighs the slow turning most, where a filter's delay is its
τ; a derivative of the heading weighs the fast wiggles, which a filter delays less (on the
independent simulator's heading_lag recordings, τ 0.31-0.59 s: 0.30-0.54 s this way, 0.27-0.47 s
from the derivative). A gyro's z axis is the yaw rate only while roll and pitch stay small, as on
a surface boat.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import cumulative_trapezoid

from ..formats.ardupilot import GYRO_FILTER, gyro_filter_delay_s
from ..recording import Recording
from .outliers import heading_spikes

MAX_LAG_S = 1.5
STEP_S = 0.01
WINDOW_S = 10.0
MAX_GAP_S = 0.5  # a piece with a longer silence in either stream is left out
MIN_TURNING_S = 30.0  # of samples at |r| ≥ TURNING_RAD_S: fewer, and the alignment is noise's
TURNING_RAD_S = 0.05
# below this share the heading's wiggles are mostly noise or a gyro's drift within a piece: the best
# lag is theirs (a ship model turning at 1-3°/s: 24-56 %, lags of either sign)
MIN_FIT = 0.9
TOLD_SIGMAS = 3.0  # a lag within this many σ of zero is not told from on time
# a slow ship's heading within 10 s is nearly a straight line: read on longer pieces and slower turning
SHIP_PIECE_S, SHIP_TURNING_RAD_S, SHIP_MIN_FIT = 60.0, 0.01, 0.5


@dataclass(frozen=True)
class GyroLag:
    """lag_s: how late the heading is against the gyro (s, > 0: the heading is late), None when it
    cannot be told; fit: the share of the heading's variance (each piece's offset and trend out) the shifted gyro's
    integral explains;
    turning_s: seconds of turning it rests on; note: why there is no lag."""

    lag_s: float | None
    fit: float | None = None
    turning_s: float = 0.0
    note: str = ""
    sigma_s: float | None = None  # the lag's 1-σ: each piece left out in turn (jackknife)
    cause: str = ""  # what can stamp the gyro late in this kind of log, said where the heading leads it

    def text(self) -> str:
        if self.lag_s is None:
            return f"heading against the gyro: not told ({self.note})"
        sigma = f" ± {self.sigma_s:.2f} s" if self.sigma_s else ""
        # a negative lag reads as early: "−0.22 s late" says the same less plainly
        when = f"+{self.lag_s:.2f} s late" if self.lag_s >= 0 else f"{-self.lag_s:.2f} s early"
        head = (f"heading against the gyro: {when}{sigma} (the shifted gyro's turning explains "
                f"{100 * self.fit:.0f} % of the heading's over {self.turning_s:.0f} s of turning)")
        if not self.sigma_s or abs(self.lag_s) < TOLD_SIGMAS * self.sigma_s:
            return f"{head}: not told from on time (within {TOLD_SIGMAS:g}σ)"
        if self.lag_s < 0:
            return (f"{head}: the heading leads its gyro, which no heading filter does, so the gyro's stamps trail "
                    "the heading's (two messages of one log stamped apart); the heading's timing is taken as logged"
                    + (f"; {self.cause}" if self.cause else ""))
        return f"{head}: `heading_latency={self.lag_s:.2f}` describes it if the gyro is on time"


def heading_lag_behind_gyro(rec: Recording, *, window_s: float = WINDOW_S, turning_rad_s: float = TURNING_RAD_S,
                            min_fit: float = MIN_FIT) -> GyroLag:
    """The heading's delay against the gyro of `rec` (module docstring); window_s: the pieces' length,
    turning_rad_s: the yaw rate that counts as turning, min_fit: the share of the heading's variance
    the shifted gyro must explain (a slow ship's turns need longer pieces and a lower rate: its
    heading within 10 s is a straight line whose offset and slope take any lag)."""
    if not len(rec.imu) or not len(rec.heading):
        return GyroLag(None, note="the log has no gyro" if not len(rec.imu) else "the log has no heading")
    psi = np.unwrap(rec.heading["psi_rad"])
    keep = ~heading_spikes(psi, rec.heading.t)
    t_h, psi = rec.heading.t[keep], psi[keep]
    t_g, r_g = rec.imu.t, np.asarray(rec.imu["yaw_rate_rads"], float)
    ok = np.isfinite(r_g)
    t_g, r_g = t_g[ok], r_g[ok]
    if len(t_h) < 3 or len(t_g) < 3:
        return GyroLag(None, note="too few heading or gyro samples")
    turned = np.r_[0.0, cumulative_trapezoid(r_g, t_g)]  # the heading the gyro alone gives (rad), from 0
    pieces = list(_pieces(t_h, t_g, window_s))
    if not pieces:  # a short log: its turning is not counted as none
        return GyroLag(None, note=f"no stretch of {window_s + 2 * MAX_LAG_S:g} s with the heading and the gyro "
                                  f"running; the log's heading spans {t_h[-1] - t_h[0]:.0f} s")
    spin = np.abs(np.interp(t_h, t_g, r_g)) >= turning_rad_s
    dt = float(np.median(np.diff(t_h)))
    turning_s = sum(float(np.sum(spin[m])) for m in pieces) * dt
    if turning_s < MIN_TURNING_S:
        return GyroLag(None, turning_s=turning_s,
                       note=f"{turning_s:.0f} s of turning beside a running gyro; {MIN_TURNING_S:.0f} s are needed")
    lags = np.round(np.arange(-MAX_LAG_S, MAX_LAG_S + STEP_S / 2, STEP_S), 4)
    per_piece, spread = [], 0.0
    for m in pieces:
        t = t_h[m]
        shifted = np.interp((t[None, :] - lags[:, None]).ravel(), t_g, turned).reshape(len(lags), len(t))
        per_piece.append(_detrended_squares(psi[m][None, :] - shifted, t))
        spread += float(_detrended_squares(psi[m][None, :], t)[0])
    cost = np.sum(per_piece, axis=0)
    if not (np.all(np.isfinite(cost)) and spread > 0.0):
        return GyroLag(None, turning_s=turning_s, note="the heading or the gyro has values that are not numbers")
    k = int(np.argmin(cost))
    fit = float(1.0 - cost[k] / spread)
    if fit < min_fit:  # before the edge: a gyro in deg/s or of the other sign fits nowhere, its best lag is noise's
        short = (f"the gyro's turning explains only {100 * fit:.0f} % of the heading's within {window_s:g}-s pieces; "
                 f"{100 * min_fit:.0f} % are needed")
        gain = _whole_log_gain(psi, t_h, np.interp(t_h, t_g, turned))
        if gain is not None and 0.8 <= gain <= 1.25:  # units and sign right: a slow turner's pieces are noise
            return GyroLag(None, fit, turning_s, f"{short}; over the whole log the gyro turns {gain:.2f} times as far "
                                                  "as the heading (units and sign right): the turning within a piece is "
                                                  "too slow beside the heading's noise for a delay to be told")
        told = f"; over the whole log the gyro turns {gain:.2f} times as far as the heading" if gain is not None else ""
        return GyroLag(None, fit, turning_s, f"{short}{told} (a gyro in rad/s, positive turning to starboard, "
                                              "is expected)")
    if k in (0, len(lags) - 1):
        return GyroLag(None, fit, turning_s, f"the best alignment is at the scan's edge (±{MAX_LAG_S:g} s)")
    return GyroLag(float(lags[k]), fit, turning_s, sigma_s=_jackknife(lags, per_piece), cause=_unstated_filter(rec))


def heading_lag(rec: Recording) -> GyroLag:
    """The heading's delay against the gyro as `twin info` and the diagnosis read it: a boat's on
    WINDOW_S pieces (its turns are quick), or, where those leave it untold for want of turning, on a
    ship's longer pieces and slower turning, which a propeller-and-rudder ship's is always read on."""
    if not len(rec.prop_rudder):
        lag = heading_lag_behind_gyro(rec)
        if lag.lag_s is not None or lag.turning_s >= MIN_TURNING_S:
            return lag
    return heading_lag_behind_gyro(rec, window_s=SHIP_PIECE_S, turning_rad_s=SHIP_TURNING_RAD_S, min_fit=SHIP_MIN_FIT)


def _unstated_filter(rec: Recording) -> str:
    """An ArduPilot log that does not state its gyro's low-pass, which its reader reads back by
    (formats.ardupilot): the filter's delay at the vehicles' default cut-offs."""
    stated = gyro_filter_delay_s(rec.parameters) or rec.parameters.get(GYRO_FILTER) == 0
    if rec.kind not in ("dataflash", "tlog") or stated:
        return ""
    rover, copter = gyro_filter_delay_s({GYRO_FILTER: 4.0}), gyro_filter_delay_s({GYRO_FILTER: 20.0})
    return (f"ArduPilot logs its gyro after a low-pass ({GYRO_FILTER}) whose delay this log's parameters do not "
            f"give (Rover's default 4 Hz: {rover:.3f} s; Copter's and Sub's 20 Hz: {copter:.3f} s)")


def _jackknife(lags: np.ndarray, per_piece: list[np.ndarray]) -> float | None:
    """The 1-σ of the best lag, each piece left out in turn (None from fewer than three pieces)."""
    n = len(per_piece)
    if n < 3:
        return None
    total = np.sum(per_piece, axis=0)
    left_out = np.array([lags[int(np.argmin(total - c))] for c in per_piece])
    return float(max(np.sqrt((n - 1) / n * np.sum((left_out - left_out.mean()) ** 2)), STEP_S))


def _whole_log_gain(psi: np.ndarray, t: np.ndarray, turned: np.ndarray) -> float | None:
    """How far the gyro's integral turns against the heading over the whole log (least squares with an
    offset and a gyro bias, as in a piece; about 1 for a gyro in rad/s of the heading's sign); None when
    the log barely turns."""
    if np.ptp(psi) < 0.5 or np.ptp(turned) <= 0.0:
        return None
    design = np.column_stack([turned, t - t[0], np.ones(len(t))])
    return float(np.linalg.lstsq(design, psi, rcond=None)[0][0])


def _detrended_squares(y: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Σ of squares of each row of y after its own offset and slope in t (a piece's starting heading
    and gyro bias) are taken out."""
    tc = t - t.mean()
    yc = y - y.mean(axis=1, keepdims=True)
    slope = (yc @ tc) / float(tc @ tc)
    return np.sum((yc - slope[:, None] * tc[None, :]) ** 2, axis=1)


def _pieces(t_h: np.ndarray, t_g: np.ndarray, window_s: float = WINDOW_S):
    """Masks of the heading samples in window_s pieces where neither stream (the gyro over the scan's
    reach too) is silent for more than MAX_GAP_S."""
    for a in np.arange(t_h[0] + MAX_LAG_S, t_h[-1] - MAX_LAG_S - window_s, window_s):
        m = (t_h >= a) & (t_h < a + window_s)
        if np.sum(m) < 10 or np.max(np.diff(t_h[m])) > MAX_GAP_S:
            continue
        g = (t_g >= a - MAX_LAG_S) & (t_g <= a + window_s + MAX_LAG_S)
        tg = t_g[g]
        if len(tg) < 10 or tg[0] > a - MAX_LAG_S + MAX_GAP_S or tg[-1] < a + window_s + MAX_LAG_S - MAX_GAP_S \
                or np.max(np.diff(tg)) > MAX_GAP_S:
            continue
        yield m
