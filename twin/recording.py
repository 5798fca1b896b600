"""The Recording type: time-stamped sensor streams of a real (or replayed) run.

Each stream has its own time base t (s, strictly increasing) measured from one
common origin (`Recording.origin_s`, in the source's own clock), because real
sensors are not sampled together: GNSS at 1-10 Hz, heading at 10-50 Hz, PWM at
10 Hz. Synchronising them onto one grid is `twin.prepare`'s job, not the reader's.

Streams and their columns (SI units, NED, ψ from north towards east):
  gnss     lat_deg, lon_deg, alt_m (geodetic, antenna)   and/or   north_m, east_m (local)
  heading  psi_rad
  pwm      left_us, right_us  (already mirrored so that forward thrust = higher PWM)
  imu      yaw_rate_rads (gyro z, body FRD)
  battery  voltage_v
  prop_rudder  n_rps, delta_rad: a propeller-and-rudder ship's inputs (propeller speed, > 0
           ahead; rudder angle, > 0 turns to starboard). A recording holds them or PWM: they are
           the two input channels a twin replays (prepare() puts either into Prepared.pwm and
           says which in Prepared.input_kind)
  wind     speed_m_s, from_deg (true wind over ground: speed, direction it blows FROM, degrees
           clockwise from north) and, where measured, relative_speed_m_s, relative_from_deg
           (the apparent wind on board: direction FROM, degrees clockwise from the bow). A
           measured stream that nothing uses unless asked (fit.windows.predict(..., wind="measured"))
The last two are summarised only when present, so other recordings read as before.

  attitude roll_rad, pitch_rad (ArduPilot ATTITUDE / ATT, a 6-DOF hull's): read, summarised and
           written to .tlog, .bin and .mcap, not one of the STREAMS (prepare and the fits take the
           horizontal model's streams; the 6-DOF hull's roll and pitch can be compared with it)
"""
from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .errors import TwinError

GAP_S = 1.0  # a silence longer than this in a stream is reported as a dropout
DROPOUTS = f"dropouts > {GAP_S:g} s"  # the `dropped` reason (after "STREAM: ") that counts a stream's gaps
LOST_SHARE = 0.01  # a stream that lost this share of its samples on reading is named by the commands that use it
STREAMS = ("gnss", "heading", "pwm", "imu", "battery", "prop_rudder", "wind")
# how the notes of a reader that read a stream earlier than stamped begin (formats.ardupilot): every
# command that uses the log says them
MOVED = ("gyro: logged after", "gnss: each fix read")
# meta["positions"]: the GNSS stream's north, east are a simulated run's exact track of the body origin
# (no antenna), or a measured track the log gives as the body origin's (a model ship's tracking in a
# pond), which no MJCF antenna site applies to but a sensor offset found later (a point tracked off
# where the log says) does; without either, a receiver's fixes at the vessel's antenna.
EXACT_ORIGIN = "body origin"
TRACKED_ORIGIN = "tracked body origin"
OPTIONAL_STREAMS = ("prop_rudder", "wind")  # summarised only when they have samples
# values no sensor can report: a sample holding one is corrupt, dropped and counted
PLAUSIBLE = {
    "lat_deg": (-90.0, 90.0, "latitude outside ±90°"),
    "lon_deg": (-180.0, 180.0, "longitude outside ±180°"),
    # local positions: half the earth's circumference is as far as a point on it can be
    "north_m": (-2.0e7, 2.0e7, "position beyond 20 000 km"),
    "east_m": (-2.0e7, 2.0e7, "position beyond 20 000 km"),
    "left_us": (500.0, 2500.0, "PWM outside 500-2500 µs"),  # servo outputs span about 800-2200 µs
    "right_us": (500.0, 2500.0, "PWM outside 500-2500 µs"),
    # a compass reads within a turn; a million degrees is no heading, even one unwrapped over a long log
    "psi_rad": (-np.radians(1e6), np.radians(1e6), "heading beyond ±1e6°"),
    "n_rps": (-500.0, 500.0, "propeller speed beyond ±500 rps"),
    "delta_rad": (-np.pi / 2, np.pi / 2, "rudder angle beyond ±90°"),
    "speed_m_s": (0.0, 100.0, "wind speed outside 0-100 m/s"),
    "relative_speed_m_s": (0.0, 100.0, "wind speed outside 0-100 m/s"),
}


@dataclass
class Stream:
    """One sensor stream: sample times t (s from the recording origin) and named columns."""

    t: np.ndarray
    columns: dict[str, np.ndarray] = field(default_factory=dict)

    @classmethod
    def empty(cls, *names: str) -> "Stream":
        return cls(np.zeros(0), {n: np.zeros(0) for n in names})

    def __len__(self) -> int:
        return len(self.t)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def has(self, *names: str) -> bool:
        """True if the stream has samples and all the named columns."""
        return len(self.t) > 0 and all(n in self.columns for n in names)

    def shifted(self, dt: float) -> "Stream":
        """The same samples with t − dt (used to move the origin)."""
        return Stream(self.t - dt, self.columns)

    def median_rate_hz(self) -> float:
        """The sampling rate (Hz): 1 / the mean of the intervals within 1 % of the median one (gaps and
        doubled samples left out; times rounded to a file's resolution, 833 and 834 µs at 1200 Hz,
        averaged back); 0 with fewer than two samples or most stamped alike."""
        if len(self.t) < 2:
            return 0.0
        d = np.diff(self.t)
        typical = float(np.median(d))
        if not typical > 0:  # most samples stamped twice: no rate to tell
            return 0.0
        near = d[np.abs(d - typical) <= 0.01 * typical]
        # an even count of intervals of two kinds has its median between them, near none
        return float(1.0 / (np.mean(near) if near.size else typical))

    def gaps(self, threshold_s: float = GAP_S) -> np.ndarray:
        """Lengths (s) of the intervals between samples longer than threshold_s."""
        d = np.diff(self.t)
        return d[d > threshold_s]


@dataclass
class Recording:
    """Streams of one recording plus what the reader learnt and what it skipped.

    `dropped` lists (reason, count) of what the reader skipped or found missing
    (bad-CRC packets, NaN rows, backwards time, GNSS without fix, dropouts > 1 s);
    `notes` are one-line remarks (no GNSS in this log, how the thrusters were mapped); `warnings`
    say the data may be misread (two columns of one quantity, one read); `misread` that they are read
    in a unit they are not in (a heading_deg column in radians, a time in milliseconds): a command that
    fits or scores a log refuses it (`check_not_misread`), `twin info` and `twin view` show it.
    `pwm_neutral_us` is the (left, right) PWM of zero thrust after mirroring.
    """

    source: str
    kind: str
    gnss: Stream = field(default_factory=lambda: Stream.empty("lat_deg", "lon_deg", "alt_m"))
    heading: Stream = field(default_factory=lambda: Stream.empty("psi_rad"))
    pwm: Stream = field(default_factory=lambda: Stream.empty("left_us", "right_us"))
    imu: Stream = field(default_factory=lambda: Stream.empty("yaw_rate_rads"))
    battery: Stream = field(default_factory=lambda: Stream.empty("voltage_v"))
    prop_rudder: Stream = field(default_factory=lambda: Stream.empty("n_rps", "delta_rad"))
    wind: Stream = field(default_factory=lambda: Stream.empty("speed_m_s", "from_deg"))
    attitude: Stream = field(default_factory=lambda: Stream.empty("roll_rad", "pitch_rad"))
    parameters: dict[str, float] = field(default_factory=dict)
    pwm_neutral_us: tuple[float, float] = (1500.0, 1500.0)
    channels: dict = field(default_factory=dict)
    origin_s: float = 0.0
    dropped: list[tuple[str, int]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)  # the data may be misread: every command says so
    misread: list[str] = field(default_factory=list)  # read in a unit they are not in: fits and scores refuse
    meta: dict = field(default_factory=dict)

    def streams(self) -> dict[str, Stream]:
        return {name: getattr(self, name) for name in STREAMS}

    def __repr__(self) -> str:
        have = ", ".join(f"{n} {len(s)}" for n, s in self.streams().items() if len(s))
        return f"Recording({Path(self.source).name}, {self.kind}, {self.duration_s():.1f} s: {have})"

    def heavy_losses(self, share: float = LOST_SHARE) -> list[str]:
        """One line per stream that lost at least `share` of its samples on reading (dropouts, which are
        gaps and not samples discarded, aside), e.g. "heading: 5000 of 11000 samples dropped (samples with
        time going backwards 5000)": a command that fits or scores a log says so, as `twin info` does."""
        lost: dict[str, list[tuple[str, int]]] = {}
        for reason, n in self.dropped:
            stream, _, why = reason.partition(": ")
            if why and not why.endswith(DROPOUTS):
                lost.setdefault(stream, []).append((why, n))
        lines = []
        for stream, reasons in lost.items():
            kept = getattr(self, stream, None)
            if not isinstance(kept, Stream):  # the reader's own count (a tlog's bad packets, bytes): no stream's samples
                continue
            gone = sum(n for _, n in reasons)
            total = gone + len(kept)
            if total and gone >= share * total:
                listed = "; ".join(f"{why} {n}" for why, n in reasons)
                rest = "; the rest is used" if len(kept) else "; none is left"
                lines.append(f"{stream}: {gone} of {total} samples dropped ({listed}){rest}")
        return lines

    def duration_s(self) -> float:
        """Time from the first to the last sample of any stream (s)."""
        ts = [s.t for s in self.streams().values() if len(s)]
        if not ts:
            return 0.0
        return float(max(t[-1] for t in ts) - min(t[0] for t in ts))

    def summary(self) -> dict:
        """Plain-data description for `twin info`: duration, per-stream counts,
        median rates and dropouts (> 1 s), what was dropped, notes."""
        streams = {}
        for name, s in self.streams().items():
            if name in OPTIONAL_STREAMS and not len(s):
                continue
            gaps = s.gaps()
            streams[name] = {
                "samples": len(s),
                "rate_hz": round(s.median_rate_hz(), 3),
                "t_first_s": round(float(s.t[0]), 3) if len(s) else None,
                "t_last_s": round(float(s.t[-1]), 3) if len(s) else None,
                "gaps": len(gaps),
                "longest_gap_s": round(float(gaps.max()), 3) if len(gaps) else 0.0,
            }
        if len(self.attitude):  # read beside the heading, summarised like the streams
            s, gaps = self.attitude, self.attitude.gaps()
            streams["attitude"] = {
                "samples": len(s), "rate_hz": round(s.median_rate_hz(), 3), "t_first_s": round(float(s.t[0]), 3),
                "t_last_s": round(float(s.t[-1]), 3), "gaps": len(gaps),
                "longest_gap_s": round(float(gaps.max()), 3) if len(gaps) else 0.0,
                "roll_max_deg": round(float(np.degrees(np.max(np.abs(s["roll_rad"])))), 3),
                "pitch_max_deg": round(float(np.degrees(np.max(np.abs(s["pitch_rad"])))), 3)}
        if len(self.battery):  # how far the pack sagged: what a thrust that follows it would feel
            volt = self.battery["voltage_v"]
            streams["battery"].update({"voltage_first_v": round(float(volt[0]), 3),
                                       "voltage_last_v": round(float(volt[-1]), 3),
                                       "voltage_min_v": round(float(volt.min()), 3),
                                       "voltage_max_v": round(float(volt.max()), 3)})
        return {
            "source": self.source,
            "kind": self.kind,
            "duration_s": round(self.duration_s(), 3),
            "streams": streams,
            "channels": self.channels,
            "pwm_neutral_us": list(self.pwm_neutral_us),
            "parameters": len(self.parameters),
            "dropped": [[reason, int(n)] for reason, n in self.dropped],
            "notes": list(self.notes),
            "warnings": list(self.warnings),
            "misread": list(self.misread),
            **({"sea": dict(self.meta["sea"])} if isinstance(self.meta.get("sea"), dict) else {}),
        }


def format_summary(summary: dict) -> str:
    """The summary as a few human-readable lines (what `twin info` prints)."""
    # only a log that carries the autopilot's parameters (a DataFlash .bin, an MCAP) says how many
    params = f", {summary['parameters']} parameters" if summary["parameters"] else ""
    lines = [f"{summary['source']} ({summary['kind']}): {summary['duration_s']:.1f} s{params}"]
    for name, s in summary["streams"].items():
        if s["samples"]:
            gap = (f", {s['gaps']} gap{'s' if s['gaps'] != 1 else ''} > {GAP_S:g} s (longest {s['longest_gap_s']:.1f} s)"
                   if s["gaps"] else "")
            volt = (f", {s['voltage_first_v']:.2f} → {s['voltage_last_v']:.2f} V (range {s['voltage_min_v']:.2f}-"
                    f"{s['voltage_max_v']:.2f})" if "voltage_first_v" in s else "")
            tilt = ("" if "roll_max_deg" not in s else ", level throughout" if not (s["roll_max_deg"] or s["pitch_max_deg"])
                    else f", roll within ±{s['roll_max_deg']:.1f}°, pitch within ±{s['pitch_max_deg']:.1f}°")
            lines.append(f"  {name:8s} {s['samples']:7d} samples at {s['rate_hz']:.2f} Hz{gap}{volt}{tilt}")
        else:
            lines.append(f"  {name:8s}       - none")
    # a dropout is a gap between samples, not data discarded: the stream's line above counts it
    lines += [f"  dropped: {reason}: {n}" for reason, n in summary["dropped"] if not reason.endswith(DROPOUTS)]
    if "sea" in summary:  # a synthetic log made in waves keeps the sea it was made in
        lines.append(f"  sea      {sea_text(summary['sea'])}")
    lines += [f"  note: {note}" for note in summary["notes"]]
    lines += [f"  warning: {text}" for text in summary.get("warnings", [])]
    lines += [f"  warning: {text} (identify, evaluate and diagnose refuse the log as it is)"
              for text in summary.get("misread", [])]
    return "\n".join(lines)


def sea_text(sea: dict) -> str:
    """A sea's description (physics.waves.Sea.to_dict) in words."""
    if sea.get("regular"):
        return f"regular waves, H {sea['hs_m']:g} m, T {sea['tp_s']:g} s, from {sea['dir_deg']:g}°"
    spread = f", spreading cos^{sea['spread']:g}" if sea.get("spread") else ", long-crested"
    return (f"JONSWAP, Hs {sea['hs_m']:g} m, Tp {sea['tp_s']:g} s, from {sea['dir_deg']:g}°{spread} "
            f"(seed {sea.get('seed')})")


def clean_stream(name: str, t, columns: dict, dropped: list) -> Stream:
    """A Stream from raw samples, dropping (and recording in `dropped`) samples with
    non-finite time or values, values no sensor can report (PLAUSIBLE), samples
    repeating the previous time and samples whose time goes backwards.

    For the time order the longest strictly increasing run of samples is kept, so
    one wild timestamp (forwards or backwards) costs one sample, not the rest of
    the file; a clock reset keeps the longer part."""
    t = np.asarray(t, dtype=float)
    cols = {k: np.asarray(v, dtype=float) for k, v in columns.items()}
    ok = np.isfinite(t)
    for v in cols.values():
        ok &= np.isfinite(v)
    _note(dropped, f"{name}: samples with NaN or missing values", int(np.sum(~ok)))
    t, cols = t[ok], {k: v[ok] for k, v in cols.items()}
    ok = _plausible(name, len(t), cols, dropped)
    t, cols = t[ok], {k: v[ok] for k, v in cols.items()}
    again = np.zeros(len(t), bool)
    again[1:] = np.diff(t) == 0  # the same sample sent twice (e.g. a 5 Hz fix at 10 Hz)
    _note(dropped, f"{name}: samples repeating the previous time", int(np.sum(again)))
    t, cols = t[~again], {k: v[~again] for k, v in cols.items()}
    keep = increasing_subsequence(t)
    _note(dropped, f"{name}: samples with time going backwards", len(t) - len(keep))
    t, cols = t[keep], {k: v[keep] for k, v in cols.items()}
    stream = Stream(t, cols)
    if name in ("gnss", "heading", "pwm", "prop_rudder"):
        _note(dropped, f"{name}: {DROPOUTS}", len(stream.gaps()))
    return stream


def _plausible(name: str, n: int, cols: dict[str, np.ndarray], dropped: list) -> np.ndarray:
    """Mask of the n samples whose values are all within PLAUSIBLE; the others counted by reason."""
    ok = np.ones(n, bool)
    reasons: dict[str, np.ndarray] = {}
    for col, v in cols.items():
        if col in PLAUSIBLE:
            lo, hi, reason = PLAUSIBLE[col]
            out = (v < lo) | (v > hi)
            reasons[reason] = reasons.get(reason, np.zeros(len(v), bool)) | out
            ok &= ~out
    for reason, out in reasons.items():
        _note(dropped, f"{name}: {reason}", int(np.sum(out)))
    return ok


def increasing_subsequence(t: np.ndarray) -> np.ndarray:
    """Indices of a longest strictly increasing subsequence of t (O(n log n)); of several, the one
    that keeps the earliest rows: a stamp that jumps back is the row dropped, not the one before it."""
    n = len(t)
    if n < 2 or np.all(np.diff(t) > 0):
        return np.arange(n)
    values = t.tolist()
    # longest[i]: the longest increasing run starting at row i (from the end: increasing in −t)
    longest = [0] * n
    tails: list[float] = []
    for i in range(n - 1, -1, -1):
        k = bisect.bisect_left(tails, -values[i])
        if k == len(tails):
            tails.append(-values[i])
        else:
            tails[k] = -values[i]
        longest[i] = k + 1
    need = len(tails)
    out, last = [], -math.inf
    for i in range(n):  # the earliest row that still completes a longest run
        if need and longest[i] == need and values[i] > last:
            out.append(i)
            last, need = values[i], need - 1
    return np.array(out, dtype=int)


def _note(dropped: list, reason: str, count: int) -> None:
    if count:
        dropped.append((reason, int(count)))


def check_usable(rec: Recording, name: str) -> None:
    """TwinError (one line) unless some stream has two samples or more: one sample has no
    duration, rate or motion, so a file reduced to that (reversed time, one row) is not a
    recording."""
    if any(len(s) >= 2 for s in rec.streams().values()):
        return
    why = "; ".join(f"{reason}: {n}" for reason, n in rec.dropped[:3])
    raise TwinError(f"{name}: nothing usable: no stream has two samples with increasing time"
                    + (f" (dropped {why})" if why else ""))


def with_common_origin(rec: Recording) -> Recording:
    """Shift all streams so that the earliest sample of any stream is at t = 0."""
    firsts = [s.t[0] for s in rec.streams().values() if len(s)]
    if firsts:
        t0 = float(min(firsts))
        for name, s in rec.streams().items():
            setattr(rec, name, s.shifted(t0))
        rec.attitude = rec.attitude.shifted(t0)
        rec.origin_s += t0
    return rec


def within(rec: Recording, t0_s: float, t1_s: float, source: str) -> Recording:
    """The samples of `rec` at t0_s ≤ t ≤ t1_s (s on its clock) as a recording named `source`: a
    stretch of a log fitted or judged on its own. The clock and origin stay the log's."""
    if not t1_s > t0_s:
        raise TwinError(f"{source}: a stretch must end after it starts ({t0_s:g} s to {t1_s:g} s)")
    cut = {}
    for name in (*STREAMS, "attitude"):
        s = getattr(rec, name)
        keep = (s.t >= t0_s) & (s.t <= t1_s)
        cut[name] = Stream(s.t[keep], {k: v[keep] for k, v in s.columns.items()})
    return replace(rec, source=source, parameters=dict(rec.parameters), channels=dict(rec.channels),
                   dropped=list(rec.dropped), notes=list(rec.notes),
                   warnings=list(rec.warnings), misread=list(rec.misread), meta={**rec.meta, "stretch_of": rec.source,
                                                      "stretch_s": [float(t0_s), float(t1_s)]}, **cut)


SHARED_FIXES = 20  # consecutive fresh GNSS fixes two recordings must share, bit for bit, to share a stretch
SHARED_SHARE = 0.5  # of the shorter recording's span: one log cut from another, not two runs that met briefly
_WINDOW_WEIGHTS = np.random.default_rng(20).integers(1, 2 ** 63 - 1, SHARED_FIXES, dtype=np.uint64) | np.uint64(1)


def _fresh_fixes(rec: Recording) -> tuple[np.ndarray, np.ndarray]:
    """(t, positions (n, 2)) of the GNSS fixes that moved from the one before (a repeated fix is a
    logger's, not a new measurement)."""
    g = rec.gnss
    names = ("lat_deg", "lon_deg") if g.has("lat_deg", "lon_deg") else ("north_m", "east_m")
    if not g.has(*names):
        return np.zeros(0), np.zeros((0, 2))
    pos = np.ascontiguousarray(np.column_stack([np.asarray(g[n], float) for n in names]))
    fresh = np.r_[True, np.any(np.diff(pos, axis=0) != 0, axis=1)] if len(pos) else np.zeros(0, bool)
    return np.asarray(g.t, float)[fresh], pos[fresh]


def _window_keys(pos: np.ndarray, fixes: int = SHARED_FIXES) -> np.ndarray:
    """One 64-bit key per run of `fixes` consecutive fixes (a weighted sum of the fixes' bits, wrapping):
    equal runs have equal keys; a key met twice is then compared bit for bit."""
    if len(pos) < fixes:
        return np.zeros(0, np.uint64)
    bits = np.ascontiguousarray(pos).view(np.uint64)
    per_fix = bits[:, 0] * np.uint64(0x9E3779B97F4A7C15) ^ bits[:, 1]
    n = len(per_fix) - fixes + 1
    keys = np.zeros(n, np.uint64)
    for k in range(fixes):  # twenty vector passes: a month of logs in seconds, eight bytes a fix
        keys += per_fix[k: k + n] * _WINDOW_WEIGHTS[k]
    return keys


def shared_stretch_s(a: Recording, b: Recording, fixes: int = SHARED_FIXES) -> float:
    """How long (s) `b` runs through the same GNSS fixes as `a`, in runs of `fixes` consecutive fresh
    fixes or more, bit for bit: one log cut from another, or the same stretch exported twice (0 for
    recordings of their own)."""
    pa = _fresh_fixes(a)[1]
    tb, pb = _fresh_fixes(b)
    ka, kb = _window_keys(pa, fixes), _window_keys(pb, fixes)
    first_in_a = dict(zip(ka[::-1].tolist(), range(len(ka) - 1, -1, -1)))
    covered = np.zeros(len(pb), bool)
    for i in np.flatnonzero(np.isin(kb, ka)):
        j = first_in_a[int(kb[i])]
        if np.array_equal(pa[j: j + fixes], pb[i: i + fixes]):
            covered[i: i + fixes] = True
    return float(np.sum(np.diff(tb)[covered[1:] & covered[:-1]])) if covered.any() else 0.0


def check_not_misread(recordings: list[Recording]) -> None:
    """TwinError (one line) for the first recording read in a unit its data are not in
    (Recording.misread): a twin fitted or scored on it would be of other data."""
    for rec in recordings:
        if rec.misread:
            raise TwinError(f"{Path(rec.source).name}: {rec.misread[0]}")


def check_no_shared_stretch(recordings: list[Recording]) -> None:
    """TwinError (one line) where one recording is mostly a stretch of another (shared_stretch_s over
    SHARED_SHARE of the shorter one's span): its windows would count twice, and a run judged "left
    out" would hold samples fitted on. Two runs that pass through a few seconds alike (simulated
    runs from one start) are not refused."""
    fixes = [_fresh_fixes(r) for r in recordings]
    keys = [_window_keys(p) for _, p in fixes]
    for j, b in enumerate(recordings):
        for i, a in enumerate(recordings[:j]):
            if not len(keys[i]) or not len(keys[j]) or not np.isin(keys[j], keys[i]).any():
                continue
            seconds = max(shared_stretch_s(a, b), shared_stretch_s(b, a))
            shorter = min(float(np.ptp(fixes[i][0])), float(np.ptp(fixes[j][0])))
            if seconds >= SHARED_SHARE * shorter:
                first, second = Path(a.source).name, Path(b.source).name
                if first == second:  # two folders' logs of one name (an ArduPilot boot's first is 00000001.BIN)
                    first, second = str(a.source), str(b.source)
                raise TwinError(f"'{second}' and '{first}' share {seconds:.0f} s of the same GNSS fixes (one cut "
                                "from the other?): give each stretch of a recording once (leave one of them out)")
