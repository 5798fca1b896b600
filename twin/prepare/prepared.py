"""Data preparation of [Morel-2024 §5.1]: a Recording → synchronised kinematics and inputs.

1. Synchronisation onto one time grid (step grid_dt): each stream is held
   (zero-order hold) at its latest sample at or before the grid time, never a
   later one. [Morel-2024] extrapolates causally with splines; a hold is the simplest
   causal choice and adds no overshoot. The heading is the exception: it is read
   between its two samples around the grid time (`between`), as the velocities are
   read at the grid time (step 4); held, it would turn them into the body frame by
   the heading of up to one heading period earlier, a sway of u·r·lag in every turn.
2. GNSS latitude/longitude → local NED, flat earth around the first fix with the
   WGS-84 meridian and prime-vertical radii of curvature at that latitude.
3. Lever arm [Yellowfish-TR appendix]: the antenna O is not the body origin CO;
   OP = (dx, dy) points from O to CO in body axes, x_CO = x_O + R2(ψ)·OP (eqs. 30-32),
   V_CO = V_O + r·S·R2(ψ)·OP (eqs. 33-34), (u, v) = R2(ψ)ᵀ·V_CO (eqs. 35-36).
4. Velocities: V_O and r = dψ/dt by Savitzky-Golay derivatives ([Morel-2024 §5.1],
   scipy.signal.savgol_filter, ψ unwrapped first), or plain central differences
   (smoother="none"). Each is taken on the stream's own samples (GNSS at its rate,
   a fix repeated by a faster logger counted once; heading at its rate) and read
   at the grid times, not on the held grid values, whose steps would add ripple and
   half a GNSS period of lag. Savitzky-Golay is a centred window: the smoothing
   looks ahead by window/2, like the offline filtering of [Morel-2024]; only step 1 is causal.
   With yaw_rate_source="gyro" (a vessel's `sensors.yaw_rate_source`), r is the log's rate gyro
   read at the grid times instead, less its median offset from the heading's slope (a gyro's
   bias); a log without a gyro keeps the heading's slope.
5. Segments: the grid is cut wherever a needed stream (GNSS, heading, PWM if any)
   falls silent for more than max_gap_s; no hold bridges such a dropout and
   derivatives never cross a cut. Segments shorter than min_segment_s are dropped.
6. Operating region of each sample [Morel-2024 §4.2.1]: "ff", "fr", "rf", "rr" with
   the left letter for the left thruster; f when pwm ≥ neutral (forward thrust),
   r when pwm < neutral. A sample in the dead band ([Yellowfish-TR Table VII]: no thrust
   for δ̃ in (−0.0925, 0.0775), i.e. about −37..+31 µs around the neutral) is
   still classified by its sign, and flagged in `in_deadband` so that an
   identification can leave it out. Region "" when the recording has no PWM.
7. Inputs: a recording holds PWM (µs) or a propeller-and-rudder ship's inputs (the prop_rudder
   stream: n rps, δ rad). Either is held on the grid as the two input channels `pwm` (n, 2), and
   `input_kind` ("pwm" or "propeller_rudder", as drive.InputSeries and ThrusterModel.command
   name them) says which, so windows, replays and fits take them through the vessel's own
   thruster model unchanged. A propeller and rudder has no operating regions of [Morel-2024]
   (region "") and no dead band.
8. GNSS and heading latency (`gnss_latency_s` L > 0: a fix stamped t was taken at t − L;
   `heading_latency_s` likewise for the heading): the grid and its segments are those of the
   streams as logged, so a calibration that tries several latencies keeps every window valid; the
   position and velocity at grid time t are read from the GNSS stream at t + L (the heading and
   yaw rate from the heading stream at t + L_heading), but never outside the segment: within |L|
   of a segment's edge the edge's reading is held. Read across the edge, a negative latency after
   a dropout took fixes from before it (u off by 2.4 m/s for 0.3 s at L = −0.43 s); held, the
   error is the motion of |L| seconds at the edge.
0. Outliers (outliers.py): GNSS fixes off their neighbours' track and heading spikes are left out
   of their streams before anything else, and counted in `dropped` (heading spikes found on the
   heading as logged, before a compass calibration, which moves samples smoothly and makes or removes
   none). Fixes a receiver held while
   the vessel moved on (outliers.held_fixes) stay in the stream, so they open no dropout, but the
   velocities are taken across them, from the fresh fixes, as across a repeated fix (step 4).
9. A measured wind (the wind stream) is held on the grid as the air's velocity over ground
   (`wind_ned`, north, east m/s where the air goes; NaN before its first sample), carried for
   whoever asks for it (fit.windows.predict(..., wind="measured")) and used by nothing else.
10. The battery's terminal voltage (the battery stream) is held on the grid (`supply_v`, V;
   the first sample's value before it: a pack's voltage moves slowly and its first reading is
   the best guess of the minutes before), for a thruster model whose thrust follows it
   (physics/thrusters.py, `supply_exponent`); None without a battery stream.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..drive import WindSeries
from ..errors import TwinError
from ..formats.csv import NEEDED_COLUMNS
from ..geodesy import ned_from_geodetic as geodetic_to_ned
from ..recording import EXACT_ORIGIN, Recording, Stream
from ..run import Run
from ..threads import BoundedStore
from .outliers import distinct_count, gnss_outliers, heading_spikes, held_fixes

DEADBAND_US = (-37.0, 31.0)  # [Yellowfish-TR Table VII] (experimental): 400·(3.75 + δ̃) − 1500
_EPS_S = 1e-6  # a grid time within this of a sample time counts as "at" the sample


@dataclass
class Segment:
    """A run of grid samples without dropouts: Prepared arrays [start:stop]."""

    index: int
    start: int
    stop: int
    t0: float
    t1: float

    @property
    def slice(self) -> slice:
        return slice(self.start, self.stop)


@dataclass(frozen=True)
class Preparation:
    """How a recording was prepared (prepare()'s settings; module docstring) and from which source."""

    grid_dt: float = 0.1
    smoother: str = "savgol"
    window_s: float = 1.0
    heading_window_s: float | None = None
    polyorder: int = 2
    max_gap_s: float = 1.0
    min_segment_s: float = 1.0
    deadband_us: tuple[float, float] = DEADBAND_US
    lever_arm_OP_m: tuple[float, float] | None = None
    source: str = ""
    gnss_latency_s: float = 0.0
    heading_latency_s: float = 0.0
    yaw_rate_source: str = "heading"  # where r was read: the heading's slope, or the log's rate gyro

    @property
    def yaw_rate_window_s(self) -> float:
        """The yaw rate's Savitzky-Golay window (s): its own, else the GNSS one."""
        return self.window_s if self.heading_window_s is None else self.heading_window_s


@dataclass
class Prepared:
    """Synchronised samples at the grid times t (s, recording origin), segments
    concatenated: CO position north, east (m), heading psi (rad, unwrapped),
    body velocities u, v (m/s) and yaw rate r (rad/s), thruster PWM (n, 2) µs
    (left, right; forward = higher) or, when input_kind is "propeller_rudder", the
    propeller speed (rps) and rudder angle (rad), segment id (n,), region (n,) and
    in_deadband (n, 2); the measured wind (n, 2) when the recording has one (step 8)."""

    t: np.ndarray
    north: np.ndarray
    east: np.ndarray
    psi: np.ndarray
    u: np.ndarray
    v: np.ndarray
    r: np.ndarray
    pwm: np.ndarray
    segment: np.ndarray
    region: np.ndarray
    in_deadband: np.ndarray
    segments: list[Segment]
    pwm_neutral_us: tuple[float, float] = (1500.0, 1500.0)
    origin: dict = field(default_factory=dict)
    settings: Preparation = field(default_factory=Preparation)
    dropped: list[tuple[str, int]] = field(default_factory=list)
    input_kind: str = "pwm"  # what the two input channels `pwm` hold (step 7)
    wind_ned: np.ndarray | None = None  # (n, 2) measured wind, the air's NED velocity m/s (step 8)
    supply_v: np.ndarray | None = None  # (n,) battery terminal voltage V held on the grid (step 10)

    def __repr__(self) -> str:
        return (f"Prepared({Path(self.settings.source).name or '?'}: {len(self.t)} samples every "
                f"{self.settings.grid_dt:g} s in {len(self.segments)} segments, {self.settings.smoother} velocities)")


def _csv_hint(rec: Recording, missing: list[str]) -> str:
    """Why the `missing` streams ("GNSS", "heading") have no samples: every sample read was dropped
    (the reasons and counts the reader kept), else, for a generic CSV, the columns that give them (a
    user who wrote the file can add them; other formats log them under names of their own)."""
    lost = [f"{reason.split(': ', 1)[1]}: {n}" for reason, n in rec.dropped
            if reason.split(":")[0] in {m.lower() for m in missing} and "dropouts" not in reason]
    if lost:
        return f" (every sample read was dropped: {'; '.join(lost)})"
    if rec.kind != "csv":
        return ""
    return f" (a CSV gives {' and '.join(NEEDED_COLUMNS[m] for m in missing)})"


def prepare(rec: Recording, *, lever_arm_OP_m: tuple[float, float] | None = None, grid_dt: float = 0.1,
            smoother: str = "savgol", window_s: float = 1.0, polyorder: int = 2, max_gap_s: float = 1.0,
            heading_window_s: float | None = None,
            min_segment_s: float = 1.0, deadband_us: tuple[float, float] = DEADBAND_US,
            gnss_latency_s: float = 0.0, heading_latency_s: float = 0.0,
            logged_heading: Stream | None = None, yaw_rate_source: str = "heading") -> Prepared:
    """[Morel-2024 §5.1] data preparation of `rec` (see the module docstring).

    lever_arm_OP_m: (dx, dy) m from the GNSS antenna to the body origin, body axes
    (the Yellowfish: (0.275, −0.2625)); None when the positions already are the
    body origin's, and not applied to a simulated run's exact track (meta "positions" =
    EXACT_ORIGIN), whatever antenna the vessel has. window_s: Savitzky-Golay window (s) of the GNSS velocities, polyorder
    its degree; heading_window_s: the yaw rate's window (default window_s), which a
    fast AHRS can afford shorter. gnss_latency_s, heading_latency_s: step 8 of the module docstring.
    logged_heading: the heading as logged, where `rec`'s has been calibrated (same stamps): its
    spikes are the sensor's, found there (step 0). yaw_rate_source "gyro": r is the log's rate gyro
    where it has one (_gyro_rate), else the heading's slope; Prepared.settings says which was read."""
    _check_settings(grid_dt, smoother, window_s, polyorder, max_gap_s)
    if yaw_rate_source not in ("heading", "gyro"):
        raise TwinError(f"yaw_rate_source must be heading or gyro, got {yaw_rate_source!r}")
    for what, latency in (("gnss_latency_s", gnss_latency_s), ("heading_latency_s", heading_latency_s)):
        if not np.isfinite(latency):
            raise TwinError(f"{what} must be a finite number of seconds, got {latency}")
    name = Path(rec.source).name
    if rec.meta.get("positions") == EXACT_ORIGIN:
        # moved by the antenna's arm, the track would turn every r into a sway of r·dx
        lever_arm_OP_m = None
    if not len(rec.gnss) or not len(rec.heading):
        missing = [s for s in ("GNSS", "heading") if not len(getattr(rec, s.lower()))]
        raise TwinError(f"{name}: no {' and '.join(missing)} samples, from which the track and the velocities are "
                        f"read{_csv_hint(rec, missing)}")
    north_o, east_o, origin = local_ned(rec.gnss)
    psi_h = np.unwrap(rec.heading["psi_rad"])
    off_track = _flagged(gnss_outliers, north_o, east_o, rec.gnss.t)
    # a spike is the sensor's: a calibration moves every sample by a smooth function of the heading,
    # which makes or removes none, so spikes are found on the heading as logged (one mask for every
    # calibration a diagnosis tries) and on a bias's heading less its first sample
    logged = psi_h
    if logged_heading is not None and np.array_equal(logged_heading.t, rec.heading.t):
        logged = np.unwrap(logged_heading["psi_rad"])
    spiked = _flagged(heading_spikes, logged, rec.heading.t, key=(_offset_free(logged), rec.heading.t))
    if off_track.all() or spiked.all():
        raise TwinError(f"{name}: every GNSS fix or heading sample is an outlier of its neighbours")
    outliers = [(why, n) for why, n in (
        ("GNSS fixes off their neighbours' track (outliers)", distinct_count(off_track, np.column_stack([north_o, east_o]))),
        ("heading spikes (outliers)", distinct_count(spiked, psi_h))) if n]
    pos = Stream(rec.gnss.t[~off_track], {"north": north_o[~off_track], "east": east_o[~off_track]})
    hdg = Stream(rec.heading.t[~spiked], {"psi": psi_h[~spiked]})
    north_o, east_o = pos["north"], pos["east"]
    held = _flagged(held_fixes, north_o, east_o, pos.t)  # no new fixes, yet not a dropout (step 0)
    if held.any():
        outliers.append(("GNSS fixes held while the vessel moved on (velocities taken across them)", int(held.sum())))
    fresh = Stream(pos.t[~held], {"north": north_o[~held], "east": east_o[~held]})
    inputs = rec.pwm if len(rec.pwm) else rec.prop_rudder
    gyro = _gyro(rec) if yaw_rate_source == "gyro" else None
    needed = [pos, hdg] + ([inputs] if len(inputs) else []) + ([gyro] if gyro is not None else [])
    grid = _grid(needed, grid_dt, name)
    if grid is None:
        raise TwinError(f"{name}: the GNSS, heading and {'PWM' if inputs is rec.pwm else 'input'} streams "
                        "do not overlap in time")
    valid = np.ones(len(grid), bool)
    for s in needed:
        valid &= _fresh(s.t, grid, max_gap_s)
    runs = _runs(valid, int(np.ceil(min_segment_s / grid_dt - 1e-9)))
    if not runs:
        span = float(grid[-1] - grid[0]) if len(grid) else 0.0
        if span < min_segment_s:  # a truncated log: the streams overlap for less than one stretch
            raise TwinError(f"{name}: too short: its GNSS, heading and input streams overlap for {span:.1f} s, "
                            f"less than the {min_segment_s:g} s a stretch needs")
        raise TwinError(f"{name}: no stretch of {min_segment_s:g} s without a dropout > {max_gap_s:g} s")
    dropped = outliers + _dropped_runs(valid, runs)
    idx = np.concatenate([np.arange(a, b) for a, b in runs])
    t = grid[idx]
    seg_id = np.concatenate([np.full(b - a, k) for k, (a, b) in enumerate(runs)])
    segments = _segments(runs, t)
    t_fix = read_times(t, segments, gnss_latency_s)  # the fix that describes grid time t (step 8)
    n_o, e_o = hold(pos.t, north_o, t_fix), hold(pos.t, east_o, t_fix)
    psi = between(hdg.t, hdg["psi"], read_times(t, segments, heading_latency_s))
    heading_window_s = window_s if heading_window_s is None else heading_window_s
    _check_settings(grid_dt, smoother, heading_window_s, polyorder, max_gap_s)
    rates = _stream_rates(fresh, hdg, t, segments, smoother, (window_s, heading_window_s), polyorder,
                          (gnss_latency_s, heading_latency_s))
    if gyro is not None:
        rates = (rates[0], rates[1], _gyro_rate(gyro, t, rates[2]))
    north, east, u, v, r = _kinematics(n_o, e_o, psi, rates, lever_arm_OP_m)
    pwm, region, dead, input_kind = _inputs(rec, t, deadband_us)
    settings = Preparation(grid_dt, smoother, window_s, heading_window_s, polyorder, max_gap_s, min_segment_s,
                           tuple(deadband_us), None if lever_arm_OP_m is None else tuple(map(float, lever_arm_OP_m)),
                           rec.source, float(gnss_latency_s), float(heading_latency_s),
                           "heading" if gyro is None else "gyro")
    return Prepared(t, north, east, psi, u, v, r, pwm, seg_id, region, dead, segments,
                    tuple(rec.pwm_neutral_us), origin, settings, dropped, input_kind, measured_wind(rec, t),
                    supply_voltage(rec, t))


def _gyro(rec: Recording) -> Stream | None:
    """The log's rate gyro, its finite samples; None without one (fewer than 3)."""
    if not len(rec.imu):
        return None
    rate = np.asarray(rec.imu["yaw_rate_rads"], float)
    ok = np.isfinite(rate)
    return Stream(np.asarray(rec.imu.t, float)[ok], {"r": rate[ok]}) if ok.sum() >= 3 else None


def _gyro_rate(gyro: Stream, t: np.ndarray, heading_rate: np.ndarray) -> np.ndarray:
    """The gyro's yaw rate at the grid times t (read on time: a heading's lateness is measured against
    it), less its offset from the heading's slope (the median over the samples: a rate gyro's bias,
    which the heading does not have)."""
    r = np.interp(t, gyro.t, gyro["r"])
    both = np.isfinite(r) & np.isfinite(heading_rate)
    return r - (float(np.median(r[both] - heading_rate[both])) if both.any() else 0.0)


_FLAGGED: BoundedStore[np.ndarray] = BoundedStore(64)  # outlier masks by content: a calibration that leaves a stream as
# it was (the GNSS under a compass calibration) leaves its outliers as they were


def _flagged(rule, *arrays: np.ndarray, key: tuple | None = None) -> np.ndarray:
    """rule(*arrays), kept by the content of `key` (default: the arrays themselves)."""
    key = (rule.__name__, *(_digest(a) for a in (arrays if key is None else key)))
    return _FLAGGED.get(key, lambda: rule(*arrays)).copy()


def outlier_counts(rec: Recording) -> dict[str, int]:
    """How many GNSS fixes and heading samples of `rec` preparation leaves out as outliers (step 0)."""
    out = {}
    if len(rec.gnss):
        n, e, _ = local_ned(rec.gnss)
        off = gnss_outliers(n, e, rec.gnss.t)
        out["gnss"] = distinct_count(off, np.column_stack([n, e]))
        out["gnss_held"] = int(held_fixes(n[~off], e[~off], rec.gnss.t[~off]).sum())
    if len(rec.heading):
        psi = np.unwrap(rec.heading["psi_rad"])
        out["heading"] = distinct_count(heading_spikes(psi, rec.heading.t), psi)
    return out


def _check_settings(grid_dt, smoother, window_s, polyorder, max_gap_s) -> None:
    if not (np.isfinite(grid_dt) and grid_dt > 0):
        raise TwinError(f"grid_dt must be a positive finite number of seconds, got {grid_dt}")
    if smoother not in ("savgol", "none"):
        raise TwinError(f"smoother must be 'savgol' or 'none', got {smoother!r}")
    if smoother == "savgol" and not (window_s > 0 and 0 <= polyorder <= 5):
        raise TwinError(f"savgol needs window_s > 0 and polyorder 0..5, got {window_s}, {polyorder}")
    if not max_gap_s > 0:
        raise TwinError(f"max_gap_s must be positive, got {max_gap_s}")


# ---------------------------------------------------------------- geodesy

def local_ned(gnss: Stream) -> tuple[np.ndarray, np.ndarray, dict]:
    """Antenna north, east (m) from a gnss stream: lat/lon (deg) projected around
    the first fix, or the stream's own north_m/east_m."""
    if gnss.has("lat_deg", "lon_deg"):
        lat0, lon0 = float(gnss["lat_deg"][0]), float(gnss["lon_deg"][0])
        h0 = float(gnss["alt_m"][0]) if gnss.has("alt_m") and np.isfinite(gnss["alt_m"][0]) else 0.0
        n, e = geodetic_to_ned(gnss["lat_deg"], gnss["lon_deg"], lat0, lon0, h0)
        return n, e, {"lat_deg": lat0, "lon_deg": lon0, "alt_m": h0}
    if gnss.has("north_m", "east_m"):
        return np.asarray(gnss["north_m"], float), np.asarray(gnss["east_m"], float), {}
    raise TwinError("the gnss stream has neither lat_deg/lon_deg nor north_m/east_m")


# ---------------------------------------------------------------- synchronisation

MAX_GRID_SAMPLES = 5e7  # 58 days at 0.1 s: a longer span is a unit (ns read as s), and would not fit in memory

def _grid(streams: list[Stream], dt: float, name: str = "the recording") -> np.ndarray | None:
    """Grid from the time every stream has a first sample to the end of the
    earliest-ending stream (`name`: the recording's, for a message)."""
    t0 = max(s.t[0] for s in streams)
    t1 = min(s.t[-1] for s in streams)
    if t1 < t0:
        return None
    n = (t1 - t0) / dt
    if n > MAX_GRID_SAMPLES:
        raise TwinError(f"{name}: the streams span {t1 - t0:.3g} s, {n:.3g} samples at {dt:g} s: more than any outing (are "
                        "the time stamps in another unit, ms or ns for s?)")
    return t0 + dt * np.arange(int(np.floor(n + 1e-9)) + 1)


def hold(ts: np.ndarray, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Zero-order hold: the latest value at or before each time t (causal: no
    later sample is used). NaN before the first sample."""
    i = np.searchsorted(ts, t + _EPS_S, side="right") - 1
    out = np.asarray(values, float)[np.clip(i, 0, None)]
    return np.where(i >= 0, out, np.nan)


def between(ts: np.ndarray, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The value at each time t read linearly between the samples around it (the last sample's
    past the end, NaN before the first). For the heading: held, it would lag the velocities,
    which are read at the grid times, by up to a heading period, and turn them into the body
    frame by a stale ψ: a sway of u·r·lag in every turn (0.09 s of lag at 10 Hz made v read
    +0.034 m/s at 0.2 rad/s and 1.5 m/s, which a diagnosis took for a GNSS lever arm)."""
    out = np.interp(t, ts, np.asarray(values, float))
    return np.where(t >= ts[0] - _EPS_S, out, np.nan)


def _fresh(ts: np.ndarray, t: np.ndarray, max_gap_s: float) -> np.ndarray:
    """True where the held sample is not inside a dropout: the interval from the
    held sample to the next one is ≤ max_gap_s (or t is at the sample itself)."""
    i = np.searchsorted(ts, t + _EPS_S, side="right") - 1
    ok = i >= 0
    ic = np.clip(i, 0, len(ts) - 1)
    nxt = np.where(ic + 1 < len(ts), ts[np.minimum(ic + 1, len(ts) - 1)], np.inf)
    at_sample = np.abs(t - ts[ic]) <= _EPS_S
    return ok & ((nxt - ts[ic] <= max_gap_s) | at_sample)


def _runs(valid: np.ndarray, min_len: int) -> list[tuple[int, int]]:
    """[start, stop) index pairs of the runs of True at least min_len long."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], valid.astype(np.int8), [0]])))
    pairs = list(zip(edges[::2].tolist(), edges[1::2].tolist()))
    return [(a, b) for a, b in pairs if b - a >= max(min_len, 2)]


def _dropped_runs(valid: np.ndarray, runs: list[tuple[int, int]]) -> list[tuple[str, int]]:
    kept = sum(b - a for a, b in runs)
    out = []
    if np.sum(~valid):
        out.append(("grid samples inside dropouts", int(np.sum(~valid))))
    if int(np.sum(valid)) - kept:
        out.append(("grid samples in segments too short", int(np.sum(valid)) - kept))
    return out


def read_times(t: np.ndarray, segments: list[Segment], latency_s: float) -> np.ndarray:
    """The stream times that describe grid times t for a stream stamped latency_s late: t + latency_s,
    held inside each segment (step 8)."""
    if not latency_s:
        return t
    out = t + latency_s
    for seg in segments:
        out[seg.slice] = np.clip(out[seg.slice], seg.t0, seg.t1)
    return out


def _segments(runs: list[tuple[int, int]], t: np.ndarray) -> list[Segment]:
    out, start = [], 0
    for k, (a, b) in enumerate(runs):
        stop = start + (b - a)
        out.append(Segment(k, start, stop, float(t[start]), float(t[stop - 1])))
        start = stop
    return out


# ---------------------------------------------------------------- kinematics

def _stream_rates(pos: Stream, hdg: Stream, t: np.ndarray, segments: list[Segment], smoother: str,
                  windows_s: tuple[float, float], polyorder: int, latencies_s: tuple[float, float] = (0.0, 0.0)
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Antenna velocity north, east (m/s) and yaw rate (rad/s) at the grid times t, each
    differentiated on its own stream inside each segment (windows: GNSS, heading); each stream read
    its latency later, inside the segment (step 8; latencies: GNSS, heading)."""
    vn, ve, r = (np.full(len(t), np.nan) for _ in range(3))
    # content keys, each array hashed once (a diagnosis prepares one recording hundreds of times)
    # (a yaw rate is the same for every constant heading bias: the heading is keyed less its first sample)
    keys = {k: _digest(a) for k, a in (("gnss_t", pos.t), ("north", pos["north"]), ("east", pos["east"]),
                                        ("hdg_t", hdg.t), ("psi", _offset_free(hdg["psi"])), ("grid", t))}
    lat_g, lat_h = map(float, latencies_s)
    read_g, read_h = read_times(t, segments, lat_g), read_times(t, segments, lat_h)
    for seg in segments:
        grid = (keys["grid"], seg.start, seg.stop)
        vn[seg.slice], ve[seg.slice] = (
            _rate_at(pos.t, pos[k], read_g[seg.slice], smoother, windows_s[0], polyorder, True,
                     (keys["gnss_t"], keys[k], grid, lat_g)) for k in ("north", "east"))
        r[seg.slice] = _rate_at(hdg.t, hdg["psi"], read_h[seg.slice], smoother, windows_s[1], polyorder, False,
                                (keys["hdg_t"], keys["psi"], grid, lat_h))
    return vn, ve, r


# _rate_at by content: a diagnosis re-prepares a recording for every heading or antenna calibration
# it tries, and those leave the GNSS velocities as they were. Bounded by size, not count: a 30-min log
# of one segment is 144 kB a stream
_RATES: BoundedStore[np.ndarray] = BoundedStore(max_bytes=256 * 2**20)


def _digest(a: np.ndarray) -> tuple:
    a = np.ascontiguousarray(a)
    return a.shape, a.dtype.str, hash(a.tobytes())


def _offset_free(x: np.ndarray) -> np.ndarray:
    """x less its first value, rounded to 1e-9 (a bias added and taken away differs in the last bits),
    for keys of results that a constant offset leaves as they were."""
    x = np.asarray(x, float)
    return np.round(x - x[0], 9) if len(x) else x


def _rate_at(ts: np.ndarray, x: np.ndarray, tg: np.ndarray, smoother: str, window_s: float, polyorder: int,
             drop_repeats: bool, content: tuple) -> np.ndarray:
    """dx/dt at the grid times tg from the samples (ts, x) of one stream over tg's span
    (the sample held at tg[0] included): resampled at the stream's own median period,
    differentiated, interpolated at tg. `content` identifies (ts, x, tg) for the cache."""
    key = (content, smoother, window_s, polyorder, drop_repeats)
    return _RATES.get(key, lambda: _rate_uncached(ts, x, tg, smoother, window_s, polyorder, drop_repeats)).copy()


def _rate_uncached(ts: np.ndarray, x: np.ndarray, tg: np.ndarray, smoother: str, window_s: float, polyorder: int,
                   drop_repeats: bool) -> np.ndarray:
    lo = max(int(np.searchsorted(ts, tg[0] + _EPS_S, side="right")) - 1, 0)
    hi = int(np.searchsorted(ts, tg[-1] + _EPS_S, side="right"))
    ts, x = ts[lo:hi], x[lo:hi]
    if drop_repeats and len(x) > 2:  # a fix logged again by a faster logger carries no new time
        new = np.r_[True, np.diff(x) != 0]
        new[-1] = True
        ts, x = ts[new], x[new]
    if len(ts) < 2:
        return np.zeros(len(tg))
    dt = float(np.median(np.diff(ts)))
    tu = ts[0] + dt * np.arange(int(np.floor((ts[-1] - ts[0]) / dt + 1e-9)) + 1)
    rate = derivative(np.interp(tu, ts, x), dt, smoother, window_s, polyorder)
    return np.interp(tg, tu, rate)


def _kinematics(n_o, e_o, psi, rates, lever_arm):
    """CO position (eq. 32), body velocities (eqs. 33-36) and yaw rate."""
    c, s = np.cos(psi), np.sin(psi)
    dx, dy = (0.0, 0.0) if lever_arm is None else map(float, lever_arm)
    arm_n, arm_e = c * dx - s * dy, s * dx + c * dy  # R2(ψ)·OP, eq. 31
    north, east = n_o + arm_n, e_o + arm_e  # eq. 32
    vn, ve, r = rates
    vn, ve = vn - r * arm_e, ve + r * arm_n  # eqs. 33-34: V_CO = V_O + r·S·R2·OP, S = [[0, −1], [1, 0]]
    u, v = c * vn + s * ve, -s * vn + c * ve  # eqs. 35-36: (u, v) = R2ᵀ·V_CO
    return north, east, u, v, r


def derivative(x: np.ndarray, dt: float, smoother: str, window_s: float, polyorder: int) -> np.ndarray:
    """dx/dt of one segment sampled every dt: Savitzky-Golay (window shrunk to the
    segment if needed) or central differences."""
    n = len(x)
    if smoother == "savgol":
        # imported here, not at the top: scipy.signal adds about 0.3 s to importing twin.prepare, which
        # twin montecarlo loads without preparing a recording (tests/test_layout.py, LATE_IMPORTS)
        from scipy.signal import savgol_filter
        w = min(int(round(window_s / dt)) | 1, n if n % 2 else n - 1)
        if w > polyorder:
            return savgol_filter(x, w, polyorder, deriv=1, delta=dt, mode="interp")
    return np.gradient(x, dt) if n > 1 else np.zeros(n)


# ---------------------------------------------------------------- inputs

def _inputs(rec: Recording, t: np.ndarray, deadband_us) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """PWM held on the grid (n, 2), region ("ff", "fr", "rf", "rr"; "" without PWM)
    and the dead-band flags (n, 2), and the input kind; a propeller and rudder's (n, δ) in
    place of the PWM (step 7)."""
    if not len(rec.pwm):
        pr = rec.prop_rudder
        if len(pr):
            held = np.column_stack([hold(pr.t, pr["n_rps"], t), hold(pr.t, pr["delta_rad"], t)])
            return held, np.full(len(t), "", dtype="<U2"), np.zeros((len(t), 2), bool), "propeller_rudder"
        nan = np.full((len(t), 2), np.nan)
        return nan, np.full(len(t), "", dtype="<U2"), np.zeros((len(t), 2), bool), "pwm"
    pwm = np.column_stack([hold(rec.pwm.t, rec.pwm["left_us"], t), hold(rec.pwm.t, rec.pwm["right_us"], t)])
    offset = pwm - np.asarray(rec.pwm_neutral_us, float)
    letters = np.where(offset >= 0, "f", "r")  # by sign, dead band included (module docstring)
    region = np.char.add(letters[:, 0], letters[:, 1]).astype("<U2")
    dead = (offset > deadband_us[0]) & (offset < deadband_us[1])
    return pwm, region, dead, "pwm"


def wind_series(prep: Prepared, sl: slice):
    """The measured wind of the grid samples `sl` as a drive.WindSeries on their own clock (t − t[0]),
    for sim.simulate(..., wind=...) and analytic.simulate; TwinError without a measured wind."""
    if prep.wind_ned is None:
        raise TwinError(f"{Path(prep.settings.source or 'the recording').name}: no measured wind")
    t, air = prep.t[sl], prep.wind_ned[sl]
    ok = np.all(np.isfinite(air), axis=1)
    if not ok.any():
        raise TwinError(f"{Path(prep.settings.source or 'the recording').name}: no measured wind in these samples")
    return WindSeries(t[ok] - t[0], air[ok])


def measured_wind(rec: Recording, t: np.ndarray) -> np.ndarray | None:
    """The wind stream held on the grid as the air's NED velocity (m/s; step 8), None without one."""
    w = rec.wind
    if not w.has("speed_m_s", "from_deg"):
        return None
    a = np.radians(w["from_deg"])
    north, east = -w["speed_m_s"] * np.cos(a), -w["speed_m_s"] * np.sin(a)
    return np.column_stack([hold(w.t, north, t), hold(w.t, east, t)])


def supply_voltage(rec: Recording, t: np.ndarray) -> np.ndarray | None:
    """The battery voltage held on the grid (V; step 10), None without a battery stream."""
    b = rec.battery
    if not len(b) or not b.has("voltage_v"):
        return None
    ok = np.isfinite(b["voltage_v"]) & (b["voltage_v"] > 0)
    if not ok.any():
        return None
    ts, volt = b.t[ok], b["voltage_v"][ok]
    held = hold(ts, volt, t)
    return np.where(np.isfinite(held), held, volt[0])


def supply_reference(preps) -> float | None:
    """The voltage (V) the thrust map is taken to hold at when every log has a battery stream: the
    99th percentile of all their grid samples, the pack at its fullest and least loaded (a thrust
    map is measured on a fresh pack; the highest reading, robust to a spike), so the supply factor
    (V/V_ref)^k stays at or below 1 and the map's bounds keep meaning full thrust. A map measured
    at another voltage shows as a level the exponent takes up: k then says how far below its map
    the boat ran, not only how the thrust follows the pack. None when a log has no voltage."""
    if not preps or any(p.supply_v is None for p in preps):
        return None
    return float(np.round(np.percentile(np.concatenate([p.supply_v for p in preps]), 99), 3))


def prepared_from_run(run: Run, neutral_us: tuple[float, float] = (1500.0, 1500.0)) -> Prepared:
    """A run's true states as a one-segment Prepared recording (for tests and truth)."""
    n = len(run.t)
    offset = run.pwm_us - np.asarray(neutral_us)
    letters = np.where(offset >= 0, "f", "r")
    region = np.char.add(letters[:, 0], letters[:, 1]).astype("<U2")
    dt = float(np.median(np.diff(run.t))) if n > 1 else 0.1
    return Prepared(run.t.copy(), run.eta[:, 0].copy(), run.eta[:, 1].copy(), run.eta[:, 2].copy(),
                    run.nu[:, 0].copy(), run.nu[:, 1].copy(), run.nu[:, 2].copy(), run.pwm_us.astype(float),
                    np.zeros(n, int), region, np.zeros((n, 2), bool), [Segment(0, 0, n, float(run.t[0]),
                                                                                 float(run.t[-1]))],
                    tuple(neutral_us), settings=Preparation(grid_dt=round(dt, 9), smoother="none", source="run"))
