"""Drive the twin with a recording's inputs and set it beside the measurements.

Each trajectory segment of a prepared recording is replayed from its first
measured state (η, ν) with the recorded PWM held between samples, so the
twin's free run and the real track share one timeline.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from .engine.mjcf import CompiledVessel, compile_vessel
from .engine.sim import delivered_thrust, simulate
from .errors import TwinError
from .inputs import InputSeries
from .physics.sensors import antenna_body_m, true_heading
from .recordings import Prepared, Recording, prepare
from .recordings.prepare import Segment
from .recordings.recording import Stream
from .run import Run
from .vessel import Vessel


def lever_arm_OP_m(compiled: CompiledVessel) -> tuple[float, float]:
    """OP = (dx, dy) from the real antenna to CO (seed 000 eq. 28): minus the antenna's
    body position, the MJCF gnss site plus the vessel's surveyed offset."""
    a = antenna_body_m(compiled.geometry.gnss_pos_m, compiled.vessel.sensors)
    return float(-a[0]), float(-a[1])


def calibrated(rec: Recording, vessel: Vessel) -> Recording:
    """The recording with the vessel's heading-sensor error, for this log, taken out (physics/sensors.py)."""
    sensors = vessel.sensors.for_log(rec.source)
    if not sensors.has_heading_error or not len(rec.heading):
        return rec
    psi = true_heading(sensors, np.unwrap(rec.heading["psi_rad"]))
    return replace(rec, heading=Stream(rec.heading.t, {**rec.heading.columns, "psi_rad": psi}))


def prepare_for(rec: Recording, compiled: CompiledVessel, **kwargs) -> Prepared:
    """Seed 004 §5.1 preparation as this vessel's sensors see the recording: heading
    corrected, lever arm from its antenna. (The PWM clock offset acts where the
    PWM drives the twin: twin.ident.windows.)"""
    return prepare(calibrated(rec, compiled.vessel), lever_arm_OP_m=lever_arm_OP_m(compiled), **kwargs)


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
                    tuple(neutral_us), settings={"grid_dt": round(dt, 9), "source": "run"})


def measured_run(prep: Prepared, sl: slice | None = None) -> Run:
    """The prepared measurements as a Run (thrust unknown: NaN)."""
    sl = sl or slice(None)
    n = len(prep.t[sl])
    return Run(prep.t[sl].copy(), np.column_stack([prep.north[sl], prep.east[sl], prep.psi[sl]]),
               np.column_stack([prep.u[sl], prep.v[sl], prep.r[sl]]), prep.pwm[sl].astype(float),
               np.full((n, 2), np.nan), meta={"engine": "recording"})


def thrust_from_recorded_pwm(compiled: CompiledVessel, prep: Prepared) -> np.ndarray:
    """(n, 2) thrust (N) the twin's thruster map gives for the recorded PWM, segment by segment:
    the PWM held delay_s before, seed 000 eq. 27 and the decay, then the range, the left/right
    gains and the loss with the measured advance speed, as the twin delivers it, without the
    first-order lag (that is the twin's own state). NaN without PWM or a PWM thruster model."""
    out = np.full((len(prep.t), 2), np.nan)
    vessel = compiled.vessel
    if vessel.thrusters.kind != "t200":
        return out
    for seg in prep.segments:
        sl = seg.slice
        t = prep.t[sl]
        if not np.all(np.isfinite(prep.pwm[sl])):
            continue
        command = InputSeries(t - t[0], prep.pwm[sl].astype(float), "pwm").commanded_thrust(
            vessel.thrusters, t - t[0], float(t[0]))
        nu = np.column_stack([prep.u[sl], prep.v[sl], prep.r[sl]])
        out[sl] = delivered_thrust(vessel, compiled.geometry.thruster_y_m, command, nu)
    return out


def _source_name(prep: Prepared) -> str:
    return Path(str(prep.settings.get("source", "the recording"))).name


def replay_segment(compiled: CompiledVessel, prep: Prepared, sl: slice) -> Run:
    """Free run of the twin over one segment from its first measured state."""
    t = prep.t[sl]
    if len(t) < 2:
        raise TwinError(f"{_source_name(prep)}: segment too short to replay")
    if not np.all(np.isfinite(prep.pwm[sl])):
        raise TwinError(f"{_source_name(prep)}: the recording has no thruster PWM to replay "
                        "(`twin info` says why; --channels LEFT,RIGHT maps a log's servo outputs)")
    dt = float(np.median(np.diff(t)))
    inputs = InputSeries(t - t[0], prep.pwm[sl].astype(float), "pwm")
    eta0 = (prep.north[sl][0], prep.east[sl][0], prep.psi[sl][0])
    nu0 = (prep.u[sl][0], prep.v[sl][0], prep.r[sl][0])
    try:
        return simulate(compiled, inputs, float(t[-1] - t[0]), sample_dt_s=dt, control_dt_s=dt, eta0=eta0, nu0=nu0,
                        start_s=float(t[0]))
    except TwinError as exc:  # a divergence: say which recording (its time is on the recording's clock)
        raise TwinError(f"{_source_name(prep)}: replay: {exc}") from None


def replay(vessel: Vessel, prep: Prepared) -> Run:
    """All segments replayed and concatenated on the recording's timeline."""
    compiled = compile_vessel(vessel)
    runs = [replay_segment(compiled, prep, seg.slice) for seg in prep.segments if seg.stop - seg.start >= 2]
    if not runs:
        raise TwinError(f"{_source_name(prep)}: no segment long enough to replay")
    return Run(np.concatenate([r.t for r in runs]), np.concatenate([r.eta for r in runs]),
               np.concatenate([r.nu for r in runs]), np.concatenate([r.pwm_us for r in runs]),
               np.concatenate([r.thrust_n for r in runs]), meta={"engine": "twin", "vessel": vessel.name})
