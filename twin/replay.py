"""Drive the twin with a recording's inputs and set it beside the measurements.

Each trajectory segment of a prepared recording is replayed from its first
measured state (η, ν) with the recorded PWM held between samples, so the
twin's free run and the real track share one timeline.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from .drive import InputSeries, inputs_mismatch
from .engine.mjcf import CompiledVessel, compile_vessel
from .engine.sim import delivered_thrust, simulate
from .errors import TwinError
from .fit.calibrate import prepare_for, rate_windows
from .fit.windows import make_windows, measured, predict
from .prepare import Prepared, prepare
from .prepare.prepared import hold, wind_series
from .prepare.smoother import model_smoothed
from .recording import EXACT_ORIGIN
from .run import Run
from .vessel import Vessel


def logged_pwm(vessel: Vessel, prep: Prepared, sl: slice) -> InputSeries:
    """The segment's logged PWM (or a propeller and rudder's (n, δ): prep.input_kind) on the segment's
    clock, moved by the vessel's PWM clock offset (sensors.pwm_clock_offset_s > 0: the stamps are
    late), as the fit windows apply it; with the battery voltage on the segment's own clock
    (unshifted), for thrusters that follow it."""
    t = prep.t[sl]
    series = InputSeries(t - t[0] - vessel.sensors.pwm_clock_offset_s, prep.pwm[sl].astype(float), prep.input_kind)
    if prep.supply_v is None or not vessel.thrusters.follows_supply:
        return series
    if vessel.sensors.pwm_clock_offset_s:  # the voltage is held on the grid's own stamps, not the PWM's
        shifted = hold(t - t[0], prep.supply_v[sl], np.clip(series.t, 0.0, t[-1] - t[0]))
        return replace(series, supply_v=shifted)
    return replace(series, supply_v=prep.supply_v[sl].astype(float))


def measured_run(prep: Prepared, sl: slice | None = None) -> Run:
    """The prepared measurements as a Run (thrust unknown: NaN)."""
    sl = sl or slice(None)
    t = prep.t[sl].copy()
    n = len(t)
    meta = {"engine": "recording"}
    pwm = prep.pwm[sl].astype(float)
    if prep.input_kind != "pwm" and n:  # a ship's propeller speed and rudder angle are no PWM
        meta |= {"inputs": InputSeries(t - t[0], pwm, prep.input_kind), "start_s": float(t[0])}
        pwm = np.full((n, 2), np.nan)
    return Run(t, np.column_stack([prep.north[sl], prep.east[sl], prep.psi[sl]]),
               np.column_stack([prep.u[sl], prep.v[sl], prep.r[sl]]), pwm, np.full((n, 2), np.nan), meta=meta)


def thrust_from_recorded_pwm(compiled: CompiledVessel, prep: Prepared) -> np.ndarray:
    """(n, 2) thrust (N) the twin's thruster map gives for the recorded PWM, segment by segment:
    the PWM held delay_s before, [Yellowfish-TR eq. 27] and the decay, then the range, the left/right
    gains and the loss with the measured advance speed, as the twin delivers it, through a thrust
    ramp's slew limit on the recording's grid, without the first-order lag (that is the twin's own
    state). NaN without PWM or a PWM thruster model."""
    out = np.full((len(prep.t), 2), np.nan)
    vessel = compiled.vessel
    if vessel.thrusters.kind != "t200":
        return out
    for seg in prep.segments:
        sl = seg.slice
        t = prep.t[sl]
        if not np.all(np.isfinite(prep.pwm[sl])):
            continue
        # at each sample, what acts there: the PWM held delay_s before (not the mean over the next interval)
        held = logged_pwm(vessel, prep, sl).commanded_thrust(
            vessel.thrusters, np.arange(len(t)) * prep.settings.grid_dt, float(t[0]))
        command = vessel.thrusters.slewed(held, prep.settings.grid_dt)[0] if vessel.thrusters.ramping else held
        nu = np.column_stack([prep.u[sl], prep.v[sl], prep.r[sl]])
        out[sl] = delivered_thrust(vessel, compiled.geometry.thruster_y_m, command, nu)
    return out


def _source_name(prep: Prepared) -> str:
    return Path(str(prep.settings.source or "the recording")).name


def replay_segment(compiled: CompiledVessel, prep: Prepared, sl: slice, wind: str | None = None) -> Run:
    """Free run of the twin over one segment from its first measured state; `wind` "measured": the
    recording's measured wind a known input (in place of the vessel's constant wind)."""
    t = prep.t[sl]
    if len(t) < 2:
        raise TwinError(f"{_source_name(prep)}: segment too short to replay")
    if not np.all(np.isfinite(prep.pwm[sl])):
        raise TwinError(f"{_source_name(prep)}: the recording has no thruster PWM to replay "
                        "(`twin info` says why; --channels LEFT,RIGHT maps a log's servo outputs)")
    dt = float(np.median(np.diff(t)))
    inputs = logged_pwm(compiled.vessel, prep, sl)
    eta0 = (prep.north[sl][0], prep.east[sl][0], prep.psi[sl][0])
    nu0 = (prep.u[sl][0], prep.v[sl][0], prep.r[sl][0])
    try:
        return simulate(compiled, inputs, float(t[-1] - t[0]), sample_dt_s=dt, control_dt_s=dt, eta0=eta0, nu0=nu0,
                        start_s=float(t[0]), wind=wind_series(prep, sl) if wind == "measured" else None)
    except TwinError as exc:  # a divergence: say which recording (its time is on the recording's clock)
        raise TwinError(f"{_source_name(prep)}: replay: {exc}") from None


def replay(vessel: Vessel, prep: Prepared, wind: str | None = None) -> Run:
    """All segments replayed and concatenated on the recording's timeline, in the recording's own
    environment (its wind, where the vessel holds one per log; with `wind` "measured", the wind it
    measured)."""
    compiled = compile_vessel(replace(vessel, environment=vessel.environment.for_log(prep.settings.source)).as_logged())
    runs = [replay_segment(compiled, prep, seg.slice, wind) for seg in prep.segments if seg.stop - seg.start >= 2]
    if not runs:
        raise TwinError(f"{_source_name(prep)}: no segment long enough to replay")
    return Run(np.concatenate([r.t for r in runs]), np.concatenate([r.eta for r in runs]),
               np.concatenate([r.nu for r in runs]), np.concatenate([r.pwm_us for r in runs]),
               np.concatenate([r.thrust_n for r in runs]), meta={"engine": "twin", "vessel": vessel.name})


def view_runs(recordings: list, vessel: Vessel | None = None, *, sim: bool = False,
              smoother: str = "savgol", wind: str | None = None) -> dict[str, Run]:
    """What `twin view` shows: each recording prepared as the vessel's sensors see it (the same
    calibration identify, evaluate and diagnose use: heading corrections, antenna position), its
    thrust through the vessel's thruster map, and with `sim` the twin's replay of each segment.
    Without a vessel the positions are the antenna's (no lever arm is known)."""
    if (sim or smoother == "model") and vessel is None:
        raise TwinError("--sim and --smoother model need --vessel NAME or --model FILE")
    if smoother not in ("savgol", "model"):
        raise TwinError(f"unknown smoother '{smoother}' (savgol or model)")
    vessel = vessel.as_logged() if vessel is not None else None
    compiled = compile_vessel(vessel) if vessel is not None else None
    runs: dict[str, Run] = {}
    for rec in recordings:
        name = Path(rec.source).stem
        if compiled is None:
            prep = prepare(rec)
        elif rec.meta.get("positions") == EXACT_ORIGIN:  # no antenna; read with the vessel's yaw-rate settings
            prep = prepare(rec, **rate_windows(vessel))
        else:
            prep = prepare_for(rec, compiled, **rate_windows(vessel))  # as identify and diagnose see it
        if smoother == "model":
            own = replace(vessel, environment=vessel.environment.for_log(rec.source))
            prep = model_smoothed(compiled if own == vessel else compile_vessel(own), prep)
        if compiled is not None and prep.input_kind != vessel.thrusters.input_kind:
            raise TwinError(f"{Path(rec.source).name}: "
                            f"{inputs_mismatch(vessel.name, vessel.thrusters.input_kind, prep.input_kind)}")
        label = name if len(recordings) > 1 else "recorded"
        runs[label] = measured_run(prep)
        # u, v, r are not logged but estimated from the track and heading, over a window centred on each
        # sample: a step's answer starts before the step by half that window, which the plot should not hide
        half = {"u": prep.settings.window_s / 2, "v": prep.settings.window_s / 2, "r": prep.settings.yaw_rate_window_s / 2}
        runs[label].meta["series_labels"] = {
            q: f"{label} {q}: " + ("a model smoother (EKF + RTS)" if smoother == "model" else
                                   f"the {'heading' if q == 'r' else 'track'}'s slope over ±{half[q]:g} s, centred")
            for q in ("u", "v", "r")}
        if compiled is not None:  # the logged PWM's thrust as the twin would make it: twin against log, as u, v, r
            runs[label].thrust_n = thrust_from_recorded_pwm(compiled, prep)
            runs[label].meta["series_labels"] |= {q: f"{label} ({vessel.name} thrust map on the recorded PWM)"
                                                  for q in ("thrust_left", "thrust_right")}
        if sim:
            runs[f"twin {name}" if len(recordings) > 1 else "twin"] = replay(in_its_environment(vessel, rec), prep, wind)
    return runs


def in_its_environment(vessel: Vessel, rec) -> Vessel:
    """The vessel in the current and wind a twin run was made in, where its file keeps them (an .mcap
    of `twin simulate`: meta current_speed_m_s, current_towards_deg, wind_speed_m_s, wind_from_deg); as
    it is for any other recording."""
    m = rec.meta
    if m.get("positions") != EXACT_ORIGIN or not any(k in m for k in RUN_ENVIRONMENT):
        return vessel
    env = vessel.environment
    if "current_speed_m_s" in m:
        env = replace(env, current_speed_m_s=float(m["current_speed_m_s"]),
                      current_dir_deg=float(m.get("current_towards_deg", 0.0)))
    if "wind_speed_m_s" in m:
        env = replace(env, wind_speed_m_s=float(m["wind_speed_m_s"]), wind_dir_deg=float(m.get("wind_from_deg", 0.0)))
    return vessel.with_environment(env)


RUN_ENVIRONMENT = ("current_speed_m_s", "current_towards_deg", "wind_speed_m_s", "wind_from_deg")


def stitched_runs(windows, series: dict) -> dict[str, Run]:
    """{label: (preps, eta (W, n+1, 3), nu (W, n+1, 3))} → one Run per label over the windows' samples,
    in time order (recordings one after another on one clock)."""
    out = {}
    for label, (preps, eta, nu) in series.items():
        t, e, v, pwm = [], [], [], []
        for j, w in enumerate(windows):
            p = preps[w.rec]
            sl = slice(w.start, w.start + w.n + 1)
            t.append(p.t[sl] + 1e5 * w.rec)
            e.append(eta[j, : w.n + 1])
            v.append(nu[j, : w.n + 1])
            pwm.append(p.pwm[sl] if p.input_kind == "pwm" else np.full((len(p.t[sl]), 2), np.nan))
        order = np.argsort(np.concatenate(t), kind="stable")
        tt = np.concatenate(t)[order]
        out[label] = Run(tt, np.concatenate(e)[order], np.concatenate(v)[order], np.concatenate(pwm)[order],
                         np.full((len(tt), 2), np.nan), meta={"engine": label})
    return out


def free_run_views(vessel: Vessel, preps: list[Prepared], window_s: float = 10.0) -> dict[str, Run]:
    """The recordings and the twin's back-to-back free runs of window_s from measured states, as
    two runs on one timeline (what `twin evaluate --rrd` shows)."""
    wins = make_windows(preps, window_s, window_s)
    pred = predict(vessel, preps, wins)[0]
    eta, nu = measured(preps, wins)
    return stitched_runs(wins, {"recorded": (preps, eta, nu), "twin": (preps, pred.eta, pred.nu)})
