"""What `twin convert` writes: the recording as read, every stream at its own times; on request
(a grid period), its navigation streams synchronised onto one grid.

A copy keeps each sample at the time the reader gave it: holding a 5-Hz GNSS fix onto a 0.1-s grid
puts it in two rows, 0-0.2 s after it was taken, which a fit then reads as a receiver about 0.1 s
late. Synchronised on request: where the recording has GNSS and heading, GNSS (as recorded:
lat/lon/alt or north/east, no lever arm), heading and PWM are put onto the grid of [Morel-2024
§5.1] (twin.prepare: causal zero-order hold, dropouts cut out), so every row of a CSV holds all
three (the heading interpolated, GNSS and PWM held). A log without GNSS or heading (an ROV, a
bench test, a broken receiver) cannot be put on a grid: asked for one, it is refused, and
converted without, it keeps its streams as they are. IMU and battery always keep their own times,
parameters and PWM neutral are carried, and the writer keeps what its format can hold
(twin.formats.write_recording). A propeller-and-rudder ship's inputs (prop_rudder) are held on the
grid like the PWM; a measured wind keeps its own times.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from ..errors import TwinError
from ..formats.ardupilot import gyro_filter_delay_s
from ..formats.tlog import recording_telemetry
from .prepared import hold, prepare
from ..recording import EXACT_ORIGIN, Recording, Stream


@dataclasses.dataclass
class Conversion:
    """The recording to write and one line saying how its streams were timed."""

    recording: Recording
    timing: str
    synchronised: bool


def for_conversion(rec: Recording, grid_dt: float | None = None) -> Conversion:
    """Every stream as read (grid_dt None), or GNSS, heading and PWM on one grid of grid_dt s
    (TwinError where the recording cannot be put on it: no GNSS or heading, or no stretch long
    enough for the grid)."""
    if grid_dt is None:
        return Conversion(rec, "every stream at its own times, as read", False)
    if not (np.isfinite(grid_dt) and grid_dt > 0):
        raise TwinError(f"--grid-dt must be a positive finite number of seconds, got {grid_dt}")
    if grid_dt * 2 > rec.duration_s() > 0:  # the grid asked for cannot be given: a file without it would not be it
        raise TwinError(f"--grid-dt {grid_dt:g} s leaves fewer than two samples in this {rec.duration_s():.1f}-s "
                        f"recording (give at most {rec.duration_s() / 2:.3g} s)")
    try:
        prep = prepare(rec, grid_dt=grid_dt)
    except TwinError as exc:  # why it cannot be synchronised: the recording's own name leads the message
        reason = str(exc).split(": ", 1)[-1]
        raise TwinError(f"--grid-dt {grid_dt:g}: {Path(rec.source).name} cannot be put on a grid ({reason}); "
                        "without --grid-dt every stream keeps its own times") from None
    t = prep.t
    gnss = Stream(t, {k: hold(rec.gnss.t, v, t) for k, v in rec.gnss.columns.items()})
    heading = Stream(t, {"psi_rad": np.angle(np.exp(1j * prep.psi))})
    pwm = Stream(t, {"left_us": prep.pwm[:, 0], "right_us": prep.pwm[:, 1]}) if len(rec.pwm) else rec.pwm
    prop_rudder = rec.prop_rudder
    if not len(rec.pwm) and len(rec.prop_rudder):
        prop_rudder = Stream(t, {"n_rps": prep.pwm[:, 0], "delta_rad": prep.pwm[:, 1]})
    held = [name for name, s in (("gnss", gnss), ("heading", heading), ("pwm", pwm), ("prop_rudder", prop_rudder))
            if len(s)]
    timing = (f"{', '.join(held)} synchronised on a {grid_dt:g} s grid ({len(t)} samples in "
              f"{len(prep.segments)} segment{'s' if len(prep.segments) != 1 else ''})")
    changed = [_rate_change(name, getattr(rec, name), grid_dt) for name in held]
    if any(changed):  # a reader of the file would otherwise take a held fix for a new one
        timing += ": " + "; ".join(c for c in changed if c)
    covered_s, whole_s = float(t[-1] - t[0]), rec.duration_s()
    if whole_s - covered_s > 2 * grid_dt:  # the grid runs where GNSS and heading both do
        timing += (f"; the grid covers {covered_s:.1f} s where the GNSS and the heading both run, of the "
                   f"recording's {whole_s:.1f} s: the samples outside it are left out")
    own = [name for name in ("imu", "battery", "wind") if len(getattr(rec, name))]
    if own:
        timing += f"; {', '.join(own)} at {'their' if len(own) > 1 else 'its'} own times"
    return Conversion(dataclasses.replace(rec, gnss=gnss, heading=heading, pwm=pwm, prop_rudder=prop_rudder),
                      timing, True)


def _rate_change(name: str, stream: Stream, grid_dt: float) -> str:
    """How putting a stream on the grid changed it: the heading interpolated (twin.prepare), the
    others held (each row the latest sample: repeated until the next, or thinned to the grid);
    "" where it was recorded at the grid's own rate."""
    if len(stream) < 2:
        return ""
    period = float(np.median(np.diff(stream.t)))
    if not period > 0 or abs(period - grid_dt) <= 0.05 * grid_dt:
        return ""
    if name == "heading":
        return f"heading recorded at {1 / period:.3g} Hz, interpolated at the grid's times"
    if period > grid_dt:
        return (f"{name} recorded at {1 / period:.3g} Hz, each sample held until the next (rows up to "
                f"{period:.2g} s after it was taken)")
    return (f"{name} recorded at {1 / period:.3g} Hz, thinned to the grid (each row the latest sample, up to "
            f"{grid_dt:.2g} s old)")


def not_kept(rec: Recording, suffix: str) -> list[str]:
    """What a format cannot hold of this recording, one line each."""
    out = []
    if suffix == ".csv" and rec.parameters:
        out.append(f"the CSV layout has no place for the {len(rec.parameters)} parameters (use .mcap, .tlog or .bin)")
    if suffix == ".tlog" and len(rec.imu) and not len(rec.heading):
        out.append("a .tlog carries the yaw rate in ATTITUDE with the heading: without heading the imu stream is lost")
    # where the parameters state the gyro's filter, the writer puts its delay back onto the heading's times
    gyro_t = rec.imu.t + gyro_filter_delay_s(rec.parameters)
    if suffix == ".tlog" and len(rec.imu) and len(rec.heading) and not (
            len(rec.imu) == len(rec.heading) and np.allclose(gyro_t, rec.heading.t, rtol=0.0, atol=5e-4)):
        carried = int(np.sum(np.isfinite(recording_telemetry(rec).r_rad_s)))
        gaps = (f", {carried} of them where the gyro covers them (none in its gaps or beyond its ends)"
                if carried < len(rec.heading) else "")
        out.append(f"a .tlog carries the yaw rate in ATTITUDE with the heading: the {len(rec.imu)} gyro samples are "
                   f"read at the heading's {len(rec.heading)} times{gaps} (.bin and .mcap keep them at their own)")
    if suffix in (".tlog", ".bin") and len(rec.gnss) and rec.meta.get("positions") == EXACT_ORIGIN:
        out.append(f"the positions are a twin run's track of the body origin; a {suffix} has no place to say so and "
                   "gives them as GNSS fixes, which a reader takes for the antenna's (read them with a vessel "
                   "whose antenna is at the origin, or keep the run as .csv or .mcap)")
    if suffix == ".csv" and len(rec.attitude):
        out.append(f"the CSV layout has no columns for roll and pitch: the {len(rec.attitude)} attitude samples are "
                   "left out (use .mcap, .tlog or .bin)")
    if suffix in (".tlog", ".bin") and len(rec.attitude) > len(rec.heading) > 0:
        out.append(f"a {suffix} carries roll and pitch with the heading (ATT, ATTITUDE): the {len(rec.attitude)} "
                   f"attitude samples are read at the heading's {len(rec.heading)} times (.mcap keeps them all)")
    return out
