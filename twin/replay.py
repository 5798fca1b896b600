"""Drive the twin with a recording's inputs and set it beside the measurements.

Each trajectory segment of a prepared recording is replayed from its first
measured state (η, ν) with the recorded PWM held between samples, so the
twin's free run and the real track share one timeline.
"""
from __future__ import annotations

import numpy as np

from .engine.mjcf import CompiledVessel, compile_vessel
from .engine.sim import simulate
from .errors import TwinError
from .inputs import InputSeries
from .recordings import Prepared
from .run import Run
from .vessel import Vessel


def measured_run(prep: Prepared, sl: slice | None = None) -> Run:
    """The prepared measurements as a Run (thrust unknown: NaN)."""
    sl = sl or slice(None)
    n = len(prep.t[sl])
    return Run(prep.t[sl].copy(), np.column_stack([prep.north[sl], prep.east[sl], prep.psi[sl]]),
               np.column_stack([prep.u[sl], prep.v[sl], prep.r[sl]]), prep.pwm[sl].astype(float),
               np.full((n, 2), np.nan), meta={"engine": "recording"})


def replay_segment(compiled: CompiledVessel, prep: Prepared, sl: slice) -> Run:
    """Free run of the twin over one segment from its first measured state."""
    t = prep.t[sl]
    if len(t) < 2:
        raise TwinError("segment too short to replay")
    if not np.all(np.isfinite(prep.pwm[sl])):
        raise TwinError("the recording has no thruster PWM to replay")
    dt = float(np.median(np.diff(t)))
    inputs = InputSeries(t - t[0], prep.pwm[sl].astype(float), "pwm")
    eta0 = (prep.north[sl][0], prep.east[sl][0], prep.psi[sl][0])
    nu0 = (prep.u[sl][0], prep.v[sl][0], prep.r[sl][0])
    return simulate(compiled, inputs, float(t[-1] - t[0]), sample_dt_s=dt, control_dt_s=dt, eta0=eta0, nu0=nu0,
                    start_s=float(t[0]))


def replay(vessel: Vessel, prep: Prepared) -> Run:
    """All segments replayed and concatenated on the recording's timeline."""
    compiled = compile_vessel(vessel)
    runs = [replay_segment(compiled, prep, seg.slice) for seg in prep.segments if seg.stop - seg.start >= 2]
    if not runs:
        raise TwinError("no segment long enough to replay")
    return Run(np.concatenate([r.t for r in runs]), np.concatenate([r.eta for r in runs]),
               np.concatenate([r.nu for r in runs]), np.concatenate([r.pwm_us for r in runs]),
               np.concatenate([r.thrust_n for r in runs]), meta={"engine": "twin", "vessel": vessel.name})
