"""`twin diagnose`: where the twin and a recording disagree, which physics is missing,
how much of it, and the amended twin, judged on data it did not fit.

0. Kinematics: what the recordings' own kinematics and timing tell of the sensors and clocks
   without a dynamic model (fit/kinematic.py: where the GNSS antenna sits, whether the input log
   or the heading is late). A finding told there is named with its kinematic evidence and put into
   the twin before anything is fitted, so the twin's form error does not have to carry it; an
   effect the kinematics tell is not there is not searched for. Some are never searched for in the
   dynamics (KINEMATIC_ONLY), as a dynamic fit of them takes up a form error the twin has: the
   antenna (its lever arm moves the point the twin's sway is read at), the GNSS fixes' latency (a
   fix taken τ before its stamp moves the measured sway by −u·r·τ and the surge by −τ·u̇, which a
   twin's sway-yaw coupling and added mass, off as any twin's are, imitate; the kinematics read it
   where the surge answers input steps later than the yaw does) and, where every log has a gyro,
   the heading's timing (the gyro is the direct reference; where it cannot tell the heading's
   lateness, a twin's dynamics, further from the truth than a gyro, cannot either).
1. Replay: the twin over 10-s free-run windows from measured states, driven by the
   recorded PWM, after each log's compass calibration. The noise of every signal is
   estimated so that "significant" has a scale.
2. Locate: where the residual of the twin as given concentrates (DOF, time, operating
   regime), whether it grows along a free run (dynamics) or is there from the start
   (measurement), and what it correlates with (locate.py). Locating fits nothing, so
   every window speaks.
3. Explain: the windows are grouped into blocks of consecutive windows of one log, dealt
   to folds; each candidate effect is fitted on the other folds and judged on each fold's
   blocks, kept only if it cuts the held-out misfit significantly, one at a time, rivals
   checked (search.py: BLOCK_WINDOWS, FOLDS).
4. Model it: the amended vessel description, fit before and after on held-out
   blocks, per DOF.
5. Honesty: what stays significant after the amendment is reported as unexplained,
   with where it is, how big, and which signals it follows.
"""
from __future__ import annotations

import datetime as _dt
import math
import time
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from ..effects import EFFECTS, apply_effects, candidates, effect
from ..effects.coefficients import fit_groups
from ..engine.mjcf import compile_vessel
from ..errors import TooShort, TwinError
from ..fit.metrics import RESOLUTION, r2_mae
from ..physics.sensors import log_name
from ..fit.objective import Measurements
from ..fit.windows import ModelCache, Window, as_measured, comfortable_timestep, make_windows, measured, predict
from ..prepare import Prepared, supply_reference
from ..prepare.prepared import supply_voltage
from ..prepare.timing import heading_lag
from ..recording import Recording
from ..threads import one_blas_thread
from ..fit.calibrate import kinematic_calibrations, prepare_for, rate_windows, with_log_calibrations
from ..fit.kinematic import kinematic_findings, with_findings
from ..fit.simfit import coordinates, map_start
from ..ident.identify import check_wind
from ..vessel import Vessel
from . import locate as loc
from .noise import estimate_noise
from .verdict import FOLLOWS_R
from .search import BLOCK_WINDOWS, Kept, Search, excess_shown
from .separate import comparable, separations

WINDOW_S = 10.0
# the effects a recording's measured wind, given as a known input, takes the place of (their constant
# wind acts on no free run then; `wind_shape` stays: it reshapes the load the measured wind makes)
MEASURED_WIND_REPLACES = ("wind", "wind_per_log")
# never searched in the dynamics, told from the kinematics alone (module docstring, step 0); the heading's
# timing joins it where every log has a gyro
KINEMATIC_ONLY = ("gnss_lever_arm", "gnss_latency")
SEARCH_TIMESTEP_S = 0.05  # RK4 step of the candidate runs (the final fit figures use the vessel's own)
# Screening only ranks candidates: it may step at the recording's grid where RK4 stays well
# inside its stability limit (|hλ| < 2.8) for the prior's fastest dynamics.
SCREEN_H_LAMBDA = 1.5


@dataclass
class Diagnosis:
    prior: Vessel
    amended: Vessel
    effects: list[dict]
    located: list[dict]
    growth: dict
    correlations: dict
    fit_before: dict
    fit_after: dict
    unexplained: list[dict]
    noise: dict
    rounds: list[dict] = field(default_factory=list)
    windows: dict = field(default_factory=dict)
    seconds: float = 0.0
    notes: list[str] = field(default_factory=list)
    replay: dict = field(default_factory=dict)  # window predictions for plots and rerun
    overall: dict = field(default_factory=dict)  # residual bias and RMS per DOF over every window
    calibrations: list = field(default_factory=list)  # each log's compass offset from its kinematics (applied)
    kinematic: list = field(default_factory=list)  # sensor and timing effects from kinematics (fit/kinematic.py)
    refit: dict = field(default_factory=dict)  # the core refitted with every candidate (search.py), if any

    def __repr__(self) -> str:
        found = ", ".join(e["text"] for e in self.effects) or "no effect named"
        return f"Diagnosis({self.prior.name}: {found}; {len(self.unexplained)} unexplained regions, {self.seconds:.0f} s)"

    def to_dict(self) -> dict:
        return {"vessel": self.prior.name, "effects": self.effects, "located": self.located, "growth": self.growth,
                "correlations": self.correlations, "fit_before": self.fit_before, "fit_after": self.fit_after,
                "unexplained": self.unexplained, "overall": self.overall, "noise": self.noise, "rounds": self.rounds,
                "windows": self.windows, "seconds": round(self.seconds, 1), "notes": self.notes,
                "calibrations": [c.to_dict() for c in self.calibrations],
                "kinematic": [k.to_dict() for k in self.kinematic],
                **({"refit": self.refit} if self.refit else {})}


def _check_library(prior: Vessel, recordings: list[Recording], library: list[str], wind: str | None = None) -> None:
    """Refuse, before any replay, a requested effect that is unknown or has nothing to act on in
    these recordings (the same offer `candidates` makes once they are prepared: a battery's
    effect only where every log has a voltage), and a wind where the measured one is a known input."""
    logs_battery = all(supply_voltage(r, r.battery.t) is not None for r in recordings)
    offered = candidates(prior, [log_name(r.source) for r in recordings], supply_ref_v=1.0 if logs_battery else None)
    if wind == "measured":
        offered = {k: v for k, v in offered.items() if k not in MEASURED_WIND_REPLACES}
        known = sorted(set(library) & set(MEASURED_WIND_REPLACES))
        if known:
            raise TwinError(f"effect(s) {', '.join(known)}: each recording's measured wind is a known input "
                            f"(--wind-measured), so no wind is fitted; these can: {', '.join(offered)}")
    unknown = set(library) - set(offered)
    if not unknown:
        return
    idle = sorted(unknown & set(EFFECTS))  # in the library, but with nothing to act on here
    if idle:
        raise TwinError(f"effect(s) {', '.join(idle)} cannot be fitted to these recordings (a per-log effect "
                        "needs two or more logs; a wind needs the vessel's wind load model; a battery effect needs "
                        "every log's voltage; a propeller-and-rudder ship is offered drift and sensor effects only); "
                        f"these can: {', '.join(offered)}")
    raise TwinError(f"unknown effect(s) {', '.join(sorted(unknown))} (known: {', '.join(offered)})")


@one_blas_thread
def diagnose(recordings: list[Recording], prior: Vessel, *, window_s: float = WINDOW_S, log=None,
             library: list[str] | None = None, calibrated: bool = True,
             refit: tuple[str, ...] | None = None, refit_weight: float = 1.0, kinematic: bool = True,
             wind: str | None = None) -> Diagnosis:
    """The whole diagnosis (module docstring); `library` restricts the candidates by name;
    `calibrated`: each log's compass offset estimated from its kinematics first (fit/calibrate.py);
    `kinematic`: sensor and timing effects told from the kinematics first (step 0, fit/kinematic.py);
    `refit`: identification groups (`twin identify`'s, e.g. "surge", "yaw") whose coefficients are
    refitted with every candidate (search.py, CORE), for a twin whose own coefficients are not yet
    identified; `refit_weight`: how many windows' worth of data each of their beliefs counts (as
    `twin identify`'s beliefs ×1); `wind` "measured": each recording's measured wind a known input of
    every free run, the twin's and every candidate's (`twin diagnose --wind-measured`): a constant wind
    is then not searched for, as the measured one takes its place."""
    started = time.time()
    check_wind(recordings, wind, prior)
    if refit is not None:
        _check_refit(prior, refit, refit_weight)
    if library:
        _check_library(prior, recordings, library, wind)
    log = log or (lambda msg: None)
    findings = []
    if kinematic:
        prior, findings = _kinematic(recordings, prior, calibrated, library, log)
    prior, calibrations, compiled, preps, data, every, noise = _prepared(recordings, prior, window_s, calibrated)
    exact = ModelCache(keep_runs=True)
    before = _residuals(prior, preps, every, exact, wind)  # locating fits nothing: every window may speak
    noise = noise | _replay_floor(prior, recordings, preps, every, exact, wind)
    located, growth, corr, overall = _locate(before, preps, every, noise)
    log(f"replayed {len(every)} windows of {window_s:g} s; {len(located)} significant residual regions")
    lib = candidates(prior, [log_name(r.source) for r in recordings], supply_ref_v=supply_reference(preps))
    if library:
        lib = {k: v for k, v in lib.items() if k in library}
    settled = not_searched(findings, recordings, calibrations)
    unsearched = sorted(k for k in lib if k in settled)
    replaced = sorted(k for k in lib if wind == "measured" and k in MEASURED_WIND_REPLACES)
    lib = {k: v for k, v in lib.items() if k not in settled and k not in replaced}
    noise_sd = np.array([noise.get(k, np.nan) for k in "uvr"])
    core, core_names, search_prior = _core(prior, refit)
    search = Search(search_prior, data, every, ModelCache(SEARCH_TIMESTEP_S, keep_runs=True), lib, noise_sd, log,
                    screen_cache=ModelCache(comfortable_timestep(compiled, preps, SCREEN_H_LAMBDA, SEARCH_TIMESTEP_S),
                                            keep_runs=True),
                    core=core, core_weight=refit_weight, wind=wind)
    if core and not search.library:
        raise TwinError(f"with {', '.join(refit)} refitted no candidate is left to judge (each one moves a refitted "
                        "coefficient itself)")
    amended, kept, rounds = search.run()
    amended_preps = data.for_vessel(amended)
    after = _residuals(amended, amended_preps, every, exact, wind)
    after_located, _, after_corr, after_overall = _locate(after, amended_preps, every, noise)
    held_before, held_after = _held_out_fits(search, prior, kept, data, exact, wind)
    yardstick = _yardstick(after_overall, noise)
    diagnosis = Diagnosis(
        prior, amended, [_kinematic_effect(f) for f in findings if f.told] + _effects(kept, search, yardstick, window_s),
        located,
        growth, corr, held_before, held_after,
        _unexplained(after_located, after_corr, after_overall), noise, rounds,
        {"length_s": window_s, "windows": len(every), "folds": len(search.folds), "blocks": int(search.blocks.max()) + 1},
        time.time() - started)
    diagnosis.overall = {"before": overall, "after": after_overall}
    diagnosis.calibrations = calibrations
    diagnosis.kinematic = findings
    diagnosis.replay = {"windows": every, "preps": preps, "amended_preps": amended_preps, "before": before,
                        "after": after}
    if not kept:
        diagnosis.notes.append("no candidate effect improves the held-out fit significantly")
    diagnosis.notes += [f.text() for f in findings if not f.told]
    told_or_absent = {f.effect for f in findings if f.told or f.absent}
    settled_here = [k for k in unsearched if k in told_or_absent or k.startswith("heading_bias")]
    only_kinematic = [k for k in unsearched if k not in settled_here]
    if settled_here:
        diagnosis.notes.append(f"not searched, as the kinematics settle them (step 0, each log's compass offset): "
                               f"{', '.join(settled_here)}")
    if only_kinematic:
        diagnosis.notes.append(f"not searched in the dynamics, told from the kinematics alone (a twin's form error "
                               f"would stand in for it there): {', '.join(only_kinematic)}")
    if replaced:
        diagnosis.notes.append(f"not searched, as each recording's measured wind is a known input: {', '.join(replaced)}")
    diagnosis.notes += _gyro_timing(recordings)
    if core:
        diagnosis.amended = replace(diagnosis.amended, uncertainty={})  # the prior's covariance is not the refit's
        diagnosis.refit = {"groups": list(refit), "coefficients": core_names, "beliefs_weight": refit_weight,
                           "not_offered": search.overlapping}
        diagnosis.notes.append(
            f"the twin's own coefficients of {', '.join(refit)} ({', '.join(core_names)}) were refitted with every "
            "candidate on the same training windows; the held-out fit 'before' is the twin with only them refitted "
            "(where the residual concentrates is located on the twin as given)"
            + (f"; not offered, as they move those coefficients themselves: {', '.join(search.overlapping)}"
               if search.overlapping else ""))
    _inert_constant_wind(diagnosis, {log_name(r.source) for r in recordings})
    if diagnosis.effects:  # the amended twin says what amended it, as an identified one says how it was fitted
        named = "; ".join(e["text"] for e in diagnosis.effects)
        files = ", ".join(log_name(r.source) for r in recordings)
        diagnosis.amended = replace(diagnosis.amended, path=None, sources={
            **diagnosis.amended.sources,
            "diagnosis": f"amended by `twin diagnose` on {_dt.date.today().isoformat()} from {files}: {named}"})
    return diagnosis


def not_searched(findings, recordings: list[Recording], calibrations) -> set[str]:
    """The effects the dynamic search leaves out: those the kinematic findings told or found absent,
    those the kinematics alone may tell (kinematic_only; with or without a kinematic step run), and a
    constant heading bias where every log's compass offset was measured from its own straight running
    (a heading bias has a kinematic signature, and where the kinematics show none the dynamics' would
    stand in for another term: a decay, a wind of another shape)."""
    settled = {f.effect for f in findings if f.told or f.absent} | kinematic_only(recordings)
    if calibrations and all(c.sigma_deg is not None and math.isfinite(c.sigma_deg) for c in calibrations):
        settled |= {"heading_bias", "heading_bias_per_log"}
    return settled


def kinematic_only(recordings: list[Recording]) -> set[str]:
    """The effects told from these recordings' kinematics alone, never searched in the dynamics
    (module docstring, step 0): KINEMATIC_ONLY, and the heading's timing where every log has a gyro."""
    return set(KINEMATIC_ONLY) | ({"heading_latency"} if recordings and all(len(r.imu) for r in recordings) else set())


def _kinematic(recordings: list[Recording], prior: Vessel, calibrated: bool, library, log):
    """Step 0 (module docstring): the findings, and the prior with the told ones put in. Read against
    the twin with each log's compass calibration, as everything after reads the logs."""
    seen = _calibrated(recordings, prior)[0] if calibrated else prior
    findings = [f for f in kinematic_findings(recordings, seen) if not library or f.effect in library]
    for f in findings:
        if f.told:
            log(f.text())
    return with_findings(prior, findings), findings


def _kinematic_effect(f) -> dict:
    """A kinematic finding as an entry of Diagnosis.effects: its values with 95 % intervals, its
    evidence the kinematics' own (no held-out blocks: nothing was fitted to the dynamics)."""
    eff = effect(f.effect, **f.values)
    ci = {k: [v - 1.96 * f.sigma[k2], v + 1.96 * f.sigma[k2]] for k, v in eff.flat().items()
          for k2 in [k] if f.sigma.get(k2)}
    z = max((abs(f.change[k]) / f.sigma[k] for k in f.change if f.sigma.get(k)), default=0.0)
    return {"name": f.effect, "parameters": eff.flat(), "ci": ci, "text": eff.text, "fitted": dict(f.values),
            "fitted_sigma": dict(f.sigma), "improvement": {}, "held_out_gain": 0.0, "excess_gain": 0.0,
            "z": round(float(z), 2), "evidence": {"kind": "kinematic", "why": f.why, "basis": f.basis},
            "kind": "kinematic", "rivals": [], "separable": True}


def _check_refit(prior: Vessel, refit: tuple[str, ...], weight: float) -> None:
    """Bad --refit input as one line, before any work."""
    if not math.isfinite(weight) or not weight > 0:
        raise TwinError(f"--refit-weight must be a positive finite number of windows, got {weight}")
    if not refit:
        raise TwinError("--refit needs one or more of the vessel's identification groups "
                        f"({', '.join(fit_groups(prior))})")
    unknown = [g for g in refit if g not in fit_groups(prior)]
    if unknown:
        raise TwinError(f"unknown group(s) to refit: {', '.join(unknown)} (this vessel's: "
                        f"{', '.join(fit_groups(prior))})")


def _core(prior: Vessel, refit: tuple[str, ...] | None) -> tuple[list, list[str], Vessel]:
    """The simfit coordinates of the refitted groups' coefficients, their names, and the prior the
    search starts from (a thrust lag of 0.1 s where a refitted prior has none: simfit.map_start)."""
    if not refit:
        return [], [], prior
    groups = fit_groups(prior)
    _check_refit(prior, refit, 1.0)
    names = list(dict.fromkeys(n for g in refit for n in groups[g]))
    start = map_start(prior, names)
    return coordinates(start, names), names, start


def _prepared(recordings: list[Recording], prior: Vessel, window_s: float, calibrated: bool):
    """The recordings as a diagnosis sees them: (prior with each log's compass calibration, the
    calibrations, compiled prior, prepared recordings, Measurements, windows, noise)."""
    calibrations = []
    if calibrated:
        prior, calibrations = _calibrated(recordings, prior)
    compiled = compile_vessel(prior)
    kwargs = rate_windows(prior)
    for rec in recordings:
        if not len(rec.pwm) and not len(rec.prop_rudder):
            raise TwinError(f"{rec.source}: no thruster PWM (nor propeller and rudder inputs): the twin cannot be "
                            "replayed without its inputs")
    preps = [prepare_for(r, compiled, **kwargs) for r in recordings]
    data = Measurements(preps, recordings, compiled, kwargs)
    every = make_windows(preps, window_s, window_s, min_length_s=window_s)
    if len(every) < 2 * BLOCK_WINDOWS * 2:
        raise TooShort(f"the recording gives {len(every)} windows of {window_s:g} s: too short to fit on one part "
                        "and judge on another (a diagnosis runs on 2 minutes of data with inputs or more; naming an "
                        "effect from the dynamics takes about 5, ten blocks of 30 s)")
    return prior, calibrations, compiled, preps, data, every, _noise(recordings, preps)


def given_evidence(recordings: list[Recording], prior: Vessel, effects=(), *, wind: str | None = None,
                   window_s: float = WINDOW_S, calibrated: bool = True, known_wind: str | None = None):
    """Physics given, not fitted: the effects at the values given (`apply_effects` texts) and, with
    wind="measured", the recordings' measured wind as a known input, judged by the diagnosis's rule
    against the twin without them (each log's compass calibration applied to both unless calibrated
    is False), on the blocks a diagnosis of these recordings judges on: what the recordings can
    prove of that physics as given, whatever a fit of it would find. known_wind "measured": the
    recordings' measured wind a known input of both (`twin diagnose --given ... --wind-measured`).
    An Evidence (search.py)."""
    check_wind(recordings, known_wind)
    prior, _, _, _, data, every, noise = _prepared(recordings, prior, window_s, calibrated)
    search = Search(prior, data, every, ModelCache(SEARCH_TIMESTEP_S, keep_runs=True), {}, np.array([noise.get(k, np.nan) for k in "uvr"]),
                    wind=known_wind)
    given = apply_effects(prior, effects)
    return search.evidence(search.held_costs([prior] * len(search.folds)),
                           search.held_costs([given] * len(search.folds), wind=wind))


def measured_wind_evidence(recordings: list[Recording], prior: Vessel, *, window_s: float = WINDOW_S):
    """The recordings' own measured wind (the anemometer through the vessel's wind load model, a known
    input: nothing fitted) judged by the diagnosis's rule against the twin without it, on the same
    blocks: what the recordings can prove of the wind as it blew. An Evidence (search.py)."""
    return given_evidence(recordings, prior, wind="measured", window_s=window_s)


def _inert_constant_wind(diagnosis, logs: set[str]) -> None:
    """Where every log has a wind of its own, the constant wind of a kept `wind` or `wind_shape` acts
    on no log: its speed and direction are not reported as findings (what `wind_shape` still changes
    is the superstructure's load coefficients cy, cn), and a note says so."""
    if not logs <= {n for n, _, _ in diagnosis.amended.environment.wind_by_log}:
        return
    for e in diagnosis.effects:
        inert = {k: e["parameters"].pop(k) for k in ("speed_m_s", "dir_deg")
                 if e["name"] in ("wind", "wind_shape") and k in e["parameters"]}
        if inert:
            e["inert"] = inert
            for k in inert:
                e["ci"].pop(k, None)
            diagnosis.notes.append(f"{e['name']}: every log has its own wind (wind_per_log), so its constant wind "
                                   f"({inert['speed_m_s']:.3g} m/s from {inert['dir_deg']:.0f}°) acts on no log" +
                                   ("; it changes the superstructure's load coefficients" if e["parameters"] else ""))


# ---------------------------------------------------------------- pieces

def _calibrated(recordings: list[Recording], prior: Vessel):
    calibrations = kinematic_calibrations(recordings, compile_vessel(prior))
    return with_log_calibrations(prior, calibrations), calibrations


def _noise(recordings: list[Recording], preps: list[Prepared]) -> dict:
    """Each noise figure's median over the logs that give one. The noise of u, v and r is every
    judgement's scale (a window votes where a candidate moves it by AFFECT_SIGMA of it): without it
    nothing could earn its place, and the diagnosis says so rather than name nothing unsaid."""
    per = [estimate_noise(r, p) for r, p in zip(recordings, preps)]
    keys = [k for k, v in per[0].items() if isinstance(v, (int, float))]
    out = {}
    for k in keys:
        values = np.array([p[k] for p in per], float)
        out[k] = float(np.median(values[np.isfinite(values)])) if np.isfinite(values).any() else float("nan")
    unknown = [k for k in "uvr" if k in out and not math.isfinite(out[k])]
    if unknown:
        raise TwinError(f"the noise of {', '.join(unknown)} cannot be estimated from "
                        f"{'this recording' if len(per) == 1 else 'any of these recordings'} (too few samples "
                        "between dropouts): the diagnosis has no scale to judge an effect by")
    return out | {"method": per[0].get("method", "")}


@dataclass
class _Replay:
    pred_nu: np.ndarray  # the free runs' velocities as the measurement's estimator sees them (as_measured)
    pred_eta: np.ndarray
    meas_nu: np.ndarray
    meas_eta: np.ndarray


def _residuals(vessel: Vessel, preps: list[Prepared], windows: list[Window], cache: ModelCache,
               wind: str | None = None) -> _Replay:
    pred = predict(vessel, preps, windows, cache, wind=wind)[0]
    eta, nu = measured(preps, windows)
    return _Replay(as_measured(pred.nu, preps, windows), pred.eta, nu, eta)


REPLAY_FLOOR_WINDOWS = 16


def _replay_floor(vessel: Vessel, recordings: list[Recording], preps: list[Prepared], windows: list[Window],
                  cache: ModelCache, wind: str | None) -> dict:
    """What a perfect twin leaves because the input log is sampled: a log stamped every dt places
    each change of the inputs anywhere within dt of its stamp, so the replay's timing is uncertain by
    a uniform ±dt/2 (RMS dt/√12). Per DOF (`replay_u`, `replay_v`, `replay_r`, and `input_period_s`):
    the RMS of the prediction's change over one sample period of the input log's clock, /√12, seen
    through the measurement's estimator. The residual is judged against this and the white noise
    together (`_locate`): on a noise-free log the sampling alone would otherwise read as the twin's form."""
    periods = [float(np.median(np.diff(np.unique(np.asarray(s.t, float))))) for r in recordings
               for s in (r.pwm if len(r.pwm) else r.prop_rudder,) if len(s) > 2]
    dt = float(max(periods)) if periods else 0.0
    if not dt > 0:
        return {"replay_u": 0.0, "replay_v": 0.0, "replay_r": 0.0, "input_period_s": 0.0}
    offset = vessel.sensors.pwm_clock_offset_s
    # an RMS: windows spread over the recordings tell it as well as all of them, at a fraction of the replays
    some = windows[::max(1, len(windows) // REPLAY_FLOOR_WINDOWS)]

    def shifted(by: float) -> np.ndarray:
        v = replace(vessel, sensors=replace(vessel.sensors, pwm_clock_offset_s=offset + by))
        return as_measured(predict(v, preps, some, cache, wind=wind)[0].nu, preps, some)[:, 1:]
    change = (shifted(dt / 2) - shifted(-dt / 2)).reshape(-1, 3) / math.sqrt(12.0)
    rms = np.sqrt(np.nanmean(change ** 2, axis=0))
    return {"replay_u": float(rms[0]), "replay_v": float(rms[1]), "replay_r": float(rms[2]), "input_period_s": dt}


def _held_out_fits(search: Search, prior: Vessel, kept, data: Measurements, cache: ModelCache,
                   wind: str | None = None) -> tuple[dict, dict]:
    """R² and MAE per DOF on every fold's held-out windows: the twin before (the prior, or with a
    core its core refitted without those windows) and the kept effects as fitted without those
    windows (each fold's own fit), pooled."""
    pred0, pred1, meas0, meas1 = [], [], [], []
    for start, base, (_, held) in zip(search.initial_bases, search.final_bases, search.folds):
        preps0, preps1 = data.for_vessel(start), data.for_vessel(base)
        # a twin that blew up on a window scores as failed there (r2_mae counts it), not as a gap
        pred0.append(predict(start, preps0, held, cache, wind=wind)[0].nu_failed_as_inf()[:, 1:])
        pred1.append(predict(base, preps1, held, cache, wind=wind)[0].nu_failed_as_inf()[:, 1:])
        meas0.append(measured(preps0, held)[1][:, 1:])
        meas1.append(measured(preps1, held)[1][:, 1:])
    n = max(a.shape[1] for a in pred0)
    pad = [lambda a: np.pad(a, ((0, 0), (0, n - a.shape[1]), (0, 0)), constant_values=np.nan)]
    stack = lambda arrs: np.concatenate([pad[0](a) for a in arrs])  # noqa: E731
    return r2_mae(stack(pred0), stack(meas0)), r2_mae(stack(pred1), stack(meas1))


def _context(preps: list[Prepared], windows: list[Window], n: int) -> tuple[dict, np.ndarray, np.ndarray]:
    """Per compared sample: the context signals locate.py bins by, the window id, time in window."""
    cols = {k: [] for k in ("u_m_s", "v_m_s", "r_rad_s", "heading_deg", "region", "pwm_mean_us", "pwm_diff_us",
                            "since_input_step_s", "near_zero_pwm", "run_time_s", "time_in_window_s",
                            "recording", "recording_name", "segment")}
    win, tiw = [], []
    names = [log_name(p.settings.source) for p in preps]
    # a file name where it tells the recording apart, else its number (from 1) beside it
    labels = [name if name and names.count(name) == 1 else f"{name} ({i + 1})" if name else str(i + 1)
              for i, name in enumerate(names)]
    for j, w in enumerate(windows):
        p = preps[w.rec]
        h = p.settings.grid_dt
        idx = np.arange(w.start + 1, w.start + n + 1)
        idx = np.minimum(idx, len(p.t) - 1)
        neutral = np.asarray(p.pwm_neutral_us, float)
        off = p.pwm - neutral
        change = np.r_[True, np.any(np.abs(np.diff(p.pwm, axis=0)) > 20.0, axis=1)]
        last_change = np.maximum.accumulate(np.where(change, np.arange(len(p.t)), 0))
        cols["u_m_s"].append(p.u[idx])
        cols["v_m_s"].append(p.v[idx])
        cols["r_rad_s"].append(p.r[idx])
        cols["heading_deg"].append(np.degrees(p.psi[idx]) % 360.0)
        cols["region"].append(p.region[idx])
        cols["pwm_mean_us"].append(off[idx].mean(axis=1))
        cols["pwm_diff_us"].append(off[idx, 0] - off[idx, 1])
        cols["since_input_step_s"].append((idx - last_change[idx]) * h)
        cols["near_zero_pwm"].append(p.in_deadband[idx].any(axis=1))
        cols["run_time_s"].append(p.t[idx] - p.t[0])
        cols["time_in_window_s"].append(np.arange(1, n + 1) * h)
        cols["recording"].append(np.full(n, w.rec))
        cols["recording_name"].append(np.full(n, labels[w.rec], dtype=object))
        cols["segment"].append(p.segment[idx])
        win.append(np.full(n, j))
        tiw.append(np.arange(1, n + 1) * h)
    return {k: np.concatenate(v) for k, v in cols.items()}, np.concatenate(win), np.concatenate(tiw)


def _gyro_timing(recordings: list[Recording]) -> list[str]:
    """Each log's heading against its own gyro, where it has one and it can be told (prepare/timing.py):
    a kinematic fact the dynamics cannot give, e.g. to settle `heading_latency` against a hull's
    sway-yaw coupling, which one log's blocks often cannot."""
    out = []
    for r in recordings:
        if len(r.imu) and len(r.heading):
            lag = heading_lag(r)
            if lag.lag_s is not None:
                out.append(f"{log_name(r.source)}: {lag.text()}")
    return out


def _locate(rep: _Replay, preps, windows, noise) -> tuple[list[dict], dict, dict, dict]:
    res_w = rep.pred_nu[:, 1:] - rep.meas_nu[:, 1:]
    n = res_w.shape[1]
    context, window, tiw = _context(preps, windows, n)
    res = res_w.reshape(-1, 3)
    # the white noise and the input log's sampling together (_replay_floor)
    sd = np.array([math.hypot(noise.get(k, np.nan), noise.get(f"replay_{k}", 0.0)) for k in "uvr"])
    located = loc.locate(res, sd, window, context)
    growth = loc.growth(res_w, tiw[:n], sd)
    psi = np.radians(context["heading_deg"])
    signals = {"u": context["u_m_s"], "v": context["v_m_s"], "r": context["r_rad_s"], "|r|": np.abs(context["r_rad_s"]),
               "sin ψ": np.sin(psi), "cos ψ": np.cos(psi), "pwm mean": context["pwm_mean_us"],
               "pwm diff": context["pwm_diff_us"], "u·r": context["u_m_s"] * context["r_rad_s"],
               "run time": context["run_time_s"], "time in window": context["time_in_window_s"]}
    judged = _estimator_exact(preps, tiw, n)
    return (located, growth, loc.correlations(res, window, signals),
            loc.overall(res[judged], sd, window[judged]))


def _estimator_exact(preps: list[Prepared], time_in_window_s: np.ndarray, n: int) -> np.ndarray:
    """The compared samples where as_measured models the measurement's estimator exactly: a free
    run starts from the estimator's smoothed state (its smoothing error decays over about a kernel's
    width) and near its end the kernel reaches past the prediction. On a noise-free log of the twin
    itself the first half second alone read as v 3× the noise off; the twin's form is judged on the
    rest (bins and growth still see every sample)."""
    s = preps[0].settings
    if s.smoother != "savgol":
        return np.ones(len(time_in_window_s), bool)
    lead_s = max(s.window_s, s.yaw_rate_window_s)
    tail_s = s.window_s / 2.0
    return (time_in_window_s > lead_s + 1e-9) & (time_in_window_s <= n * s.grid_dt - tail_s + 1e-9)


def _effects(kept: list[Kept], search: Search, yardstick: dict[str, float], window_s: float) -> list[dict]:
    """The kept effects as the answer gives them; `yardstick` (per velocity, what the amended twin still
    misses, never below the noise) and `window_s` judge the trials that would settle a rival."""
    out = []
    for k in kept:
        cand, e = k.trial.candidate, k.trial.evidence
        names = [f"{cand.name}.{p.name}" for p in cand.params]
        values = {p.name: search.values.get(n, k.trial.fits[0].values[p.name]) for p, n in zip(cand.params, names)}
        eff = cand.to_effect(values)
        ci = _effect_ci(cand, values, names, search)
        out.append({"name": cand.name, "parameters": eff.flat(), "ci": ci, "text": eff.text,
                    "fitted": values, "fitted_sigma": {p.name: search.sigma_values.get(n) for p, n in
                                                       zip(cand.params, names)},
                    "improvement": {d: round(v, 4) for d, v in e.dof_rel.items()},
                    "held_out_gain": round(e.rel, 4), "excess_gain": excess_shown(e.rel_excess), "z": round(e.z, 2),
                    "evidence": e.to_dict(), "rivals": k.rivals, "separable": all(r["separable"] for r in k.rivals),
                    "separations": _separations(k, yardstick, window_s, search.log)})
    return out


def _separations(k: Kept, yardstick: dict[str, float], window_s: float, log: Callable[[str], None]
                 ) -> dict[str, list[dict]]:
    """For each rival the recording could not tell from the kept effect, the trials that would
    (separate.py), where both act on what a trial runs (the hull, the thrusters)."""
    if not comparable(k.trial.name):
        return {}
    out = {}
    for name, rival in k.unsettled.items():
        if comparable(name):
            log(f"trials that would tell {k.trial.name} from {name}")
            out[name] = [s.to_dict() for s in separations(k.trial.fits[0].vessel, rival.fits[0].vessel, yardstick,
                                                         window_s, rival.candidate)]
    return out


def _yardstick(overall: dict, noise: dict) -> dict[str, float]:
    """Per velocity, what the amended twin still misses on the recording: its RMS misfit, never below
    the noise nor FORM_FLOOR (a noise-free log's estimated noise is zero)."""
    return {k: float(np.nanmax([overall[k]["rms"], noise.get(k, np.nan), FORM_FLOOR[k]])) for k in "uvr"}


def _effect_ci(cand, values: dict, names: list[str], search: Search) -> dict:
    """95 % intervals of the effect's own parameters by the delta method through to_effect."""
    if search.cov is None:
        return {}
    idx = [search.cov_names.index(n) for n in names]
    cov = search.cov[np.ix_(idx, idx)]
    base = cand.to_effect(values).flat()
    keys = list(base)
    J = np.zeros((len(keys), len(names)))
    for j, p in enumerate(cand.params):
        h = max(1e-6, 1e-4 * max(1.0, abs(values[p.name])))
        try:
            moved = cand.to_effect({**values, p.name: values[p.name] + h}).flat()
        except TwinError:  # a value on the upper bound of its range: the step the other way
            h = -h
            moved = cand.to_effect({**values, p.name: values[p.name] + h}).flat()
        for i, key in enumerate(keys):
            d = moved[key] - base[key]
            if key.endswith("dir_deg"):  # an angle: the short way round
                d = (d + 180.0) % 360.0 - 180.0
            J[i, j] = d / h
    var = np.einsum("ij,jk,ik->i", J, cov, J)
    # a value the fit holds (the supply effect's reference voltage) has no interval
    return {key: [base[key] - 1.96 * float(np.sqrt(max(v, 0.0))), base[key] + 1.96 * float(np.sqrt(max(v, 0.0)))]
            for key, v, row in zip(keys, var, J) if np.any(row)}


# a misfit under the sensors' resolution is the replay's own arithmetic on a noise-free log, whose
# estimated noise is zero and any ratio to it large
FORM_FLOOR = RESOLUTION


def _unexplained(located: list[dict], corr: dict, overall: dict) -> list[dict]:
    """Regions still significant after the amendment, well above the noise, with what they follow;
    and a DOF whose whole residual is still far above its noise (and above FORM_FLOOR)."""
    out = []
    for dof, o in overall.items():
        if (o.get("rms_over_noise") or 0) > 3.0 and (o.get("rms") or 0) > FORM_FLOOR[dof]:
            follows = [c for c in corr.get(dof, []) if abs(c.get("r", 0)) > FOLLOWS_R][:3]
            out.append({"dimension": "all", "bin": "every window", "dof": dof, "rms": o["rms"], "bias": o["bias"],
                        "rms_over_noise": o["rms_over_noise"], "z": o.get("z_bias"), "correlates_with": follows})
    for e in located:
        if e.get("z", 0) >= 3.0 and (e.get("rms_over_noise") or 0) > 1.5 and (e.get("rms") or 0) > FORM_FLOOR[e["dof"]]:
            follows = [c for c in corr.get(e["dof"], []) if abs(c.get("r", 0)) > FOLLOWS_R][:3]
            out.append({**e, "correlates_with": follows})
    return out[:10]
