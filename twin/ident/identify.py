"""`twin identify`: from recordings to a vessel description the twin loads, every choice judged
on runs left out of the fit.

1. Calibrate: each log's own compass offset from its kinematics (GNSS track against heading on
   straight runs under way, fit/calibrate.py), applied to every log that has enough straight
   running; the others keep the prior's calibration.
2. [Morel-2024] (optional, `greybox=True`): its grey-box least squares and Tables 4-9 in shape, as
   that paper reports them.
3. Fit by simulation (fit/simfit.py), maximum a posteriori: the coefficients of FIT_GROUPS, each
   with the belief its prior value deserves (effects/coefficients.py: a first-principles damping
   is right within a factor of 3, an added mass within 2, ...). A coefficient the recordings do
   not pin down stays at its prior with its prior's uncertainty. Each velocity's residual is scaled
   by its own misfit at a first, short fit (own_misfit_sigma), not by its measured spread alone.
4. Choose on left-out runs (fit/crossval.py; time blocks with fewer than three recordings): each
   run is predicted by a twin fitted on the runs that go less far than it does (time under way,
   time turning: crossval.beyond_folds), so every choice is judged where the twin extrapolates.
   How much the beliefs count (PRIOR_WEIGHTS); every group stays free (the beliefs hold what the
   recordings do not pin), unless the prior predicts the left-out runs better than every fit by
   DROP_GAIN or more: then the prior is written as it is. Each group's return to its prior is
   judged too, as a report of the physics the left-out runs need (Identification.needed), not as
   a choice. No choice looks at how well the fit matches its own data.
5. Refit with the choices and write the twin, with what to expect on a new run (the left-out
   runs' scores: median and range), the twin's error on the left-out runs' 30-s free runs (which
   widens its prediction bands: crossval.form_error), and a warning when it predicts the left-out
   runs worse than the prior did.
6. Measure when the hull answers the input steps of these runs, as the kinematics read it against
   the written twin (fit/kinematic.input_answers): the zero against which a diagnosis reads the
   timing of other runs (Sensors.input_answer_s).

A propeller-and-rudder ship (an MMG block) goes through the same steps with its own groups
(effects.coefficients.fit_groups: MMG hull derivatives, wake, rudder inflow, added mass) and
its recorded (n, δ) as the inputs; with wind="measured" every free run, of the fits and of the
judging alike, takes each recording's measured wind as a known input.
"""
from __future__ import annotations

import datetime as _dt
import math
import numbers
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..drive import InputSeries, inputs_mismatch
from ..effects.coefficients import fit_groups as groups_of
from ..engine.limits import beyond_bounds
from ..engine.mjcf import compile_vessel
from ..errors import TwinError
from ..fit import simfit
from ..fit.calibrate import LogCalibration, kinematic_calibrations, prepare_for, rate_windows, with_log_calibrations
from ..fit.crossval import (CrossValidation, beyond_folds, each_folds, form_error, held_out_groups,
                            jackknife_vessels, judge)
from ..fit.evaluate import fitted_envelope
from ..fit.kinematic import input_answers
from ..fit.windows import ModelCache, comfortable_timestep, make_windows
from ..formats import read_recording
from ..geodesy import ned_from_geodetic
from ..physics.mmg import NU_WATER_M2_S, friction_line_factor, ittc57_cf
from ..prepare import Prepared, supply_reference
from ..progress import Progress, steps
from ..recording import Recording, check_no_shared_stretch, check_not_misread
from ..threads import one_blas_thread
from ..vessel import Vessel
from .greybox.models import fit_dynamic, fit_static
from .greybox.physical import first_guesses
from .greybox.splits import render_split_table, render_training_table, split_method_table, training_size_table

PRIOR_WEIGHTS = (0.01, 0.1, 1.0, 10.0)  # a belief counts as this many windows' worth of data
START_WEIGHT = 1.0  # fitted first, from the prior; the other weights' fits start from it
SIDE_BY_SIDE = 3  # the other weights' fits at once, in threads (their rollouts take turns)
IDLE_PWM_US, IDLE_SPEED_M_S, IDLE_YAW_RAD_S = 35.0, 0.15, 0.05  # below all three a window is a drift
IDLE_RPS = 1.0  # a propeller turning slower than this drives a 3-m model at a few cm/s at most
FIT_H_LAMBDA, FIT_TIMESTEP_S = 1.5, 0.05  # the candidate twins' RK4 step (the final scores use the vessel's)
WINDOW_S = 10.0
SLOW_WINDOW_S = 30.0  # for a vessel whose surge time constant exceeds WINDOW_S
TYPICAL_SPEED_M_S = 1.0  # a small ASV's cruising speed, where its surge time constant is read
NEEDED_RATIO = 1.1  # a group whose return to the prior raises the left-out cost this much is physics the runs need
# The prior is written instead of a fit only when it predicts the left-out runs better by this share: a
# smaller difference is within the scatter of the judging itself.
DROP_GAIN = 0.02
# a velocity a first fit matches within this share of its spread is weighted as if it missed by it:
# the rest is the GNSS's noise and smoothing, not the twin's
MIN_MISFIT_SHARE = 0.1
TIED_CHOICES = 0.01  # options whose left-out costs differ by less than this share are not told apart
FORM_ERROR_HORIZON_S = 30.0  # the prediction band's free runs (twin evaluate --band)
FOLDS_LABEL = {"beyond": "each run predicted by the twin fitted on the runs that go less far (time under way, "
                         "turning)", "each": "each run predicted by the twin fitted on the other runs"}


def read(paths: list[Path], channels: dict | None = None) -> list[Recording]:
    """The recordings, each with thruster PWM or a propeller's and rudder's inputs (TwinError naming
    the one without), none read in a unit it is not in (recording.check_not_misread), no two sharing a
    stretch (recording.check_no_shared_stretch)."""
    out = []
    for path in paths:
        rec = read_recording(path, channels=channels)
        if not len(rec.pwm) and not len(rec.prop_rudder):
            # inputs logged but every sample dropped (out of range, not numbers) are not missing columns
            lost = [f"{reason}: {n}" for reason, n in rec.dropped if reason.split(":")[0] in ("pwm", "prop_rudder")]
            hint = (f"every input sample was dropped: {'; '.join(lost)}" if lost else
                    "columns pwm_left,pwm_right (or prop_rps,rudder_deg)" if Path(path).suffix.lower() == ".csv"
                    else "an ArduPilot log: give the thruster channels with --channels LEFT,RIGHT")
            raise TwinError(f"{Path(path).name}: no inputs (thruster PWM, or propeller and rudder): the twin cannot "
                            f"be run on it ({hint})")
        out.append(rec)
    check_not_misread(out)
    check_no_shared_stretch(out)
    return out


def prepared(recordings: list[Recording], vessel: Vessel) -> list[Prepared]:
    """The recordings prepared [Morel-2024 §5.1] as the vessel's sensors see them."""
    compiled = compile_vessel(vessel)
    return [prepare_for(r, compiled, **rate_windows(vessel)) for r in recordings]


def calibrate(recordings: list[Recording], vessel: Vessel) -> tuple[Vessel, list[LogCalibration]]:
    """Each log's compass offset from its kinematics, put into the vessel's per-log heading biases."""
    calibrations = kinematic_calibrations(recordings, compile_vessel(vessel))
    return with_log_calibrations(vessel, calibrations), calibrations


def load(paths: list[Path], vessel: Vessel, channels: dict | None = None, *, calibrated: bool = True
         ) -> list[Prepared]:
    """Read and prepare recordings as the vessel's sensors see them, each log's own compass offset
    applied unless `calibrated` is False."""
    recordings = read(paths, channels)
    if calibrated:
        vessel, _ = calibrate(recordings, vessel)
    return prepared(recordings, vessel)


@dataclass
class Choice:
    """One configuration judged on left-out runs."""

    label: str
    prior_weight: float
    free_groups: tuple[str, ...]
    cv: CrossValidation

    def to_dict(self) -> dict:
        return {"label": self.label, "prior_weight": self.prior_weight, "free_groups": list(self.free_groups),
                **self.cv.to_dict()}


@dataclass
class Identification:
    """What `twin identify` found: the twin it writes, the fit, the choices and what they were
    judged by, each log's calibration, and the expectation for a new run."""

    vessel: Vessel
    prior: Vessel
    fit: simfit.FitResult | None
    calibrations: list[LogCalibration] = field(default_factory=list)
    choices: list[Choice] = field(default_factory=list)
    chosen: Choice | None = None
    prior_cv: CrossValidation | None = None
    greybox: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    seconds: float = 0.0
    wind: str | None = None  # "measured": each recording's measured wind was a known input of the fit

    def __repr__(self) -> str:
        # a --params fit has one group of its own ("chosen"): its coefficients say more than the name
        groups = self.chosen.free_groups if self.chosen else ()
        free = ", ".join(e.name for e in self.fit.estimates) if groups == ("chosen",) and self.fit else \
            ", ".join(groups) or "-"
        n = len(self.calibrations)
        return (f"Identification({self.vessel.name}: {n} log{'' if n == 1 else 's'}, "
                f"{'free' if groups == ('chosen',) else 'free groups'} {free}"
                f"{', measured wind' if self.wind == 'measured' else ''}, {self.seconds:.0f} s)")

    def needed(self) -> list[tuple[str, float]]:
        """The groups the left-out runs need: (group, left-out cost without it ÷ with it) for each group
        whose return to its prior raises the left-out cost by NEEDED_RATIO or more (each refit
        linearised about the fit with every group free), largest first."""
        if not self.choices:
            return []
        full = max(len(c.free_groups) for c in self.choices)
        whole = [c for c in self.choices if len(c.free_groups) == full and "refitted" not in c.label]
        if not whole:
            return []
        base = min(whole, key=lambda c: c.cv.cost)
        out = []
        for c in self.choices:
            missing = set(base.free_groups) - set(c.free_groups)
            if (c.prior_weight == base.prior_weight and len(c.free_groups) == full - 1 and len(missing) == 1
                    and "refitted" not in c.label and c.cv.cost >= NEEDED_RATIO * base.cv.cost):
                out.append((missing.pop(), c.cv.cost / base.cv.cost))
        return sorted(out, key=lambda gr: -gr[1])

    @property
    def ran_away(self) -> bool:
        """Whether the chosen twin ran away (diverged) on every left-out run: it predicts none of them,
        so there is no twin to write, only a prior that does not fit these recordings."""
        runs = self.chosen.cv.runs if self.chosen else []
        return bool(runs) and all(any(m.get("diverged", 0) for m in r.metrics.values()) for r in runs)

    @property
    def worse_than_prior(self) -> bool:
        # a tenth of a per cent is the cost's own scatter between two fits, not a worse twin
        return bool(self.chosen and self.prior_cv and self.chosen.cv.cost > self.prior_cv.cost * (1.0 + 1e-3))

    def to_dict(self) -> dict:
        return {"vessel": self.vessel.name, "calibrations": [c.to_dict() for c in self.calibrations],
                "fit": self.fit.to_dict() if self.fit else None,
                "choices": [c.to_dict() for c in self.choices],
                "chosen": self.chosen.label if self.chosen else None,
                "expected_on_a_new_run": self.chosen.cv.to_dict() if self.chosen else None,
                "prior_on_left_out_runs": self.prior_cv.to_dict() if self.prior_cv else None,
                "needed_by_left_out_runs": [{"group": g, "cost_ratio_without": round(r, 3)} for g, r in self.needed()],
                "worse_than_prior": self.worse_than_prior, "greybox": self.greybox, "notes": self.notes,
                "wind": self.wind or "none", "seconds": round(self.seconds, 1)}


def greybox_stage(preps: list[Prepared], prior: Vessel, thruster: str, split: str, train: float, repeats: int,
                  seed: int) -> tuple[dict, list[str]]:
    """[Morel-2024] tables and the physical quantities they imply; a grey-box failure is a note."""
    fit = {"static": fit_static, "dynamic": fit_dynamic}[thruster]
    notes: list[str] = []
    out: dict = {"thruster": thruster}
    try:
        model = fit(preps)
        out["first_guesses"] = first_guesses(model, prior)
        out["model"] = model.to_dict()
    except TwinError as exc:
        notes.append(f"grey-box ({thruster}, [Morel-2024]): {exc}")
        return out, notes
    try:
        out["by_split_method"] = split_method_table(fit, preps, train=train, repeats=repeats, seed=seed)
        out["by_training_share"] = training_size_table(fit, preps, method=split)
    except TwinError as exc:
        notes.append(f"grey-box tables: {exc}")
    return out, notes


@one_blas_thread
def identify(recordings: list[Recording], prior: Vessel, *, groups: tuple[str, ...] | None = None,
             params: tuple[str, ...] | None = None, prior_weights: tuple[float, ...] = PRIOR_WEIGHTS,
             anchor: str = "mass", window_s: float | None = None, start: str = "free", calibrated: bool = True,
             greybox: bool = False, thruster: str = "static", split: str = "segments", train: float = 0.7,
             repeats: int = 20, seed: int = 0, max_evaluations: int = 20, sources: list[str] | None = None,
             progress: Progress | None = None, wind: str | None = None, judged_on: str = "beyond") -> Identification:
    """The whole identification (module docstring). groups: the vessel's fit groups to consider
    (default all), or params: an explicit list of coefficients (then no group is dropped); start:
    each window's initial velocities "free" (estimated with the fit) or "measured"; wind:
    "measured" to take each recording's measured wind as a known input; judged_on: "beyond" (each
    left-out run predicted by a twin fitted on the runs that go less far, crossval.beyond_folds) or
    "each" (leave one run out)."""
    started = time.time()
    say = steps(progress)
    window_s = default_window_s(prior) if window_s is None else window_s
    _check(start, thruster, split, train, prior_weights)
    _check_counts(window_s, max_evaluations=max_evaluations, repeats=repeats, seed=seed, params=params, groups=groups)
    if judged_on not in ("beyond", "each"):
        raise TwinError(f"judged_on must be 'beyond' or 'each', got {judged_on!r}")
    check_wind(recordings, wind, prior)
    simfit.check_kind(prior)
    supplied = bool(recordings) and all(len(r.battery) for r in recordings)
    names_by_group = _groups(groups, params, prior, supplied)
    all_names = tuple(n for names in names_by_group.values() for n in names)
    simfit.check_names(prior, all_names, anchor)
    say("calibrating each log's compass", 0, 4)
    vessel, calibrations = calibrate(recordings, prior) if calibrated else (prior, [])
    preps = prepared(recordings, vessel)
    if "supply_exponent" in all_names:
        vessel = _with_supply_reference(vessel, preps)
    # the logs' span and windows as evaluate counts them: free runs of the vessel's own window (10 s for a
    # small boat, 30 s for a slow ship), one of evaluate's horizons, whatever window this fit was given
    seen = {**fitted_envelope(vessel, preps, horizon_s=default_window_s(vessel)).to_dict(), "wind": wind or "none"}
    result = Identification(vessel, prior, None, calibrations, wind=wind)
    if greybox and prior.thrusters.kind != "t200":
        # the grey-box of [Morel-2024] is a model of PWM thrusters (dead zone, thrust gain, operating regions)
        result.notes.append("the [Morel-2024] grey-box models PWM thrusters: skipped for a propeller-and-rudder ship")
    elif greybox:
        say("[Morel-2024] grey-box tables", 1, 4)
        result.greybox, notes = greybox_stage(preps, vessel, thruster, split, train, repeats, seed)
        result.notes += notes
    cache = ModelCache(comfortable_timestep(compile_vessel(vessel), preps, FIT_H_LAMBDA, FIT_TIMESTEP_S),
                       keep_runs=True)
    every = make_windows(preps, window_s, window_s, min_length_s=window_s)
    if not every:
        longest = max((p.t[seg.stop - 1] - p.t[seg.start] for p in preps for seg in p.segments), default=0.0)
        raise TwinError(f"no stretch of {window_s:g} s to fit on: the longest without a dropout lasts {longest:.0f} s "
                        "(a shorter window, or longer recordings)")
    unused = sorted(set(range(len(preps))) - {w.rec for w in every})
    if unused:
        names = ", ".join(Path(recordings[i].source).name for i in unused)
        result.notes.append(f"{names}: no stretch of {window_s:g} s without a dropout, so not in the fit "
                            "(its compass calibration is of no consequence)")
    informative = [w for w in every if _informative(preps[w.rec], w)]
    if len(informative) < 3:
        raise TwinError(f"only {len(informative)} windows of {window_s:g} s with the thrusters working or the boat "
                        "moving: nothing to identify (record some driving)")
    weights = sorted(prior_weights, key=lambda w: abs(np.log(w / START_WEIGHT)))
    say(f"fit by simulation on {len(informative)} of {len(every)} windows: each velocity's misfit", 2, 4)
    short = max(6, max_evaluations // 3)
    scout = simfit.fit(vessel, preps, all_names, anchor=anchor, window_s=window_s, stride_s=window_s,
                       max_evaluations=short, cache=cache, free_start=start == "free", prior_weight=weights[0],
                       windows=informative, wind=wind)
    sigma = own_misfit_sigma(scout)
    def fit_at(weight: float, previous: simfit.FitResult | None) -> simfit.FitResult:
        # each later fit starts from the first, taking its runs there (only the weight differs); the first
        # starts from the scout's twin, whose runs were scaled otherwise
        return simfit.fit(vessel, preps, all_names, anchor=anchor, window_s=window_s, stride_s=window_s,
                          max_evaluations=max_evaluations if previous is None else short,
                          cache=cache, free_start=start == "free", prior_weight=weight,
                          start=scout.vessel if previous is None else previous, windows=informative,
                          wind=wind, dof_sigma=sigma)

    say(f"fit by simulation on {len(informative)} of {len(every)} windows, beliefs worth {weights[0]:g} windows",
        2, 4)
    first_fit = fit_at(weights[0], None)
    fits = {weights[0]: first_fit}
    if len(weights) > 1:
        others = ", ".join(f"{w:g}" for w in weights[1:])
        say(f"fit by simulation on {len(informative)} of {len(every)} windows, beliefs worth {others} windows "
            "side by side", 2, 4)
        # the later fits depend on the first alone: side by side, one's Python runs while another's
        # rollout steps (the results are the same as one after another)
        with ThreadPoolExecutor(min(len(weights) - 1, SIDE_BY_SIDE)) as pool:
            fits |= zip(weights[1:], pool.map(lambda w: fit_at(w, first_fit), weights[1:]))
    say("judging the choices on left-out runs", 3, 4)
    first = fits[START_WEIGHT] if START_WEIGHT in fits else next(iter(fits.values()))
    fit_groups, _ = held_out_groups(first.objective.windows, preps)
    judge_groups, group_names = held_out_groups(every, preps)
    folds = beyond_folds(every, preps, judge_groups) if judged_on == "beyond" else each_folds(judge_groups)
    configs = {"prior (no fit)": [vessel] * len(group_names)}
    weight_of = {f"beliefs ×{weight:g}": weight for weight in fits}  # _check: one label a weight
    for weight, f in fits.items():
        configs[f"beliefs ×{weight:g}"] = jackknife_vessels(f.objective, f.x, f.jacobian, f.objective.residuals(f.x),
                                                            fit_groups, fixed=_unpinned(f), folds=folds)
    judged = judge(configs, preps, every, judge_groups, group_names, first.objective.sigma, cache, wind)
    result.prior_cv = judged.pop("prior (no fit)")
    choices = [Choice(label, weight_of[label], tuple(names_by_group), cv) for label, cv in judged.items()]
    best = min(choices, key=lambda c: c.cv.cost)
    chosen_fit = fits[best.prior_weight]
    if params is None:  # a report of what the left-out runs need, not a choice (module docstring, step 4)
        choices += _without_each_group(chosen_fit, best, names_by_group, all_names, preps, every, fit_groups,
                                       judge_groups, group_names, cache, wind, folds)
    result.choices, result.chosen = choices, best
    fit_best = chosen_fit
    if params is None and result.prior_cv.cost < (1.0 - DROP_GAIN) * best.cv.cost:
        # every group back at its prior
        why = (f"the prior predicts the left-out runs better than any fit (cost {result.prior_cv.cost:.4g} against "
               f"{best.cv.cost:.4g}, {best.label})")
        fit_best, best = simfit.at_prior(fit_best, vessel, why), Choice("prior (no fit)", best.prior_weight, (),
                                                                        result.prior_cv)
        result.notes.append(f"{why}: the prior is written, as these recordings do not support moving it")
    result.fit, result.chosen = fit_best, best  # the choice whose twin is written, after any fallback
    stand_ins = [e for e in fit_best.estimates if e.identifiable and e.stand_in]
    if stand_ins:
        listed = ", ".join(f"{e.name} {e.value:.3g} {e.unit} (prior {e.prior:.3g}, {e.from_prior_sigmas:.1f} σ)"
                           for e in stand_ins)
        result.notes.append(f"moved beyond what their beliefs allow: {listed}: each stands in for something the "
                            "twin's form lacks, and carries the twin beyond its runs only as far as that lack does "
                            "(`twin diagnose` looks for what)")
    result.vessel = _with_sources(fit_best, best, sources or [r.source for r in recordings], wind)
    below = below_friction_line(result.vessel)
    if below:
        result.notes.append(below)
    if result.vessel.uncertainty:  # what the fit saw, so that evaluate can say where the twin extrapolates
        say("measuring the twin's error on left-out runs", 3, 4)
        folded = jackknife_vessels(fit_best.objective, fit_best.x, fit_best.jacobian,
                                   fit_best.objective.residuals(fit_best.x), fit_groups, fixed=_unpinned(fit_best),
                                   folds=folds)
        if not best.free_groups:  # the prior written: it is its own twin on every fold
            folded = [vessel] * len(folded)
        label = FOLDS_LABEL[judged_on]
        errors = form_error(folded, preps, label,
                            max(FORM_ERROR_HORIZON_S, window_s), cache=cache, wind=wind)
        result.vessel = replace(result.vessel, uncertainty={**result.vessel.uncertainty, "fitted_on": seen,
                                                            **({"form_error": errors} if errors else {})})
        if stand_ins:  # evaluate names them on runs beyond the fitted ones
            result.vessel = replace(result.vessel, uncertainty={**result.vessel.uncertainty, "stand_ins": [
                {"name": e.name, "value": e.value, "prior": e.prior, "unit": e.unit,
                 "from_prior_sigmas": e.from_prior_sigmas} for e in stand_ins]})
    say("timing the hull's answers to the input steps", 3, 4)
    result.vessel = replace(result.vessel, sensors=replace(
        result.vessel.sensors, input_answer_s=input_answers(recordings, result.vessel)))
    if result.worse_than_prior:
        result.notes.append(f"the identified twin predicts the left-out runs worse than the prior did (cost "
                            f"{best.cv.cost:.4g} against {result.prior_cv.cost:.4g}): more varied recordings "
                            "are needed before a fit can be trusted")
    result.seconds = time.time() - started
    say("done", 4, 4)
    return result


def below_friction_line(vessel: Vessel) -> str | None:
    """What a user running faster should know of an MMG hull whose R'_0 lies below its friction line
    at the reference speed (physics/mmg.py): the line carries it in proportion to C_F, at a smaller
    factor than the vessel file's. None where it does not (or the hull has no friction line)."""
    m = vessel.mmg
    if m is None or m.friction_factor <= 0.0:
        return None
    carried = friction_line_factor(m)
    if carried >= m.friction_factor:
        return None
    line = m.friction_factor * ittc57_cf(m.reference_speed_m_s * m.lpp_m / NU_WATER_M2_S)
    return (f"R'_0 {m.hull.R0:.3g} lies below its friction line at {m.reference_speed_m_s:g} m/s ({line:.3g}): "
            f"the line carries it in proportion to C_F (factor {carried:.3g}, the file's {m.friction_factor:.3g}), "
            "so faster runs keep its share of friction and no negative rest of the resistance")


def surge_time_constant_s(vessel: Vessel) -> float:
    """(m − X_u̇)/(∂R/∂u): how long the vessel takes to settle in surge, at a typical speed (a propeller-
    and-rudder ship's MMG reference speed, else TYPICAL_SPEED_M_S), R its surge resistance."""
    mass = compile_vessel(vessel).geometry.rigid.mass_kg - vessel.added_mass.Xudot
    if vessel.mmg is not None:
        m = vessel.mmg
        u = m.reference_speed_m_s or 0.5 * TYPICAL_SPEED_M_S
        slope = m.rho_kg_m3 * m.lpp_m * m.draft_m * m.hull.R0 * u
    else:
        slope = -(vessel.damping.Xu + 2.0 * vessel.damping.Xuu * TYPICAL_SPEED_M_S)
    return float(mass / slope) if slope > 0 else float("inf")


def default_window_s(vessel: Vessel) -> float:
    """The fit's free-run window: WINDOW_S, or SLOW_WINDOW_S for a vessel whose surge time constant
    exceeds WINDOW_S (a 10-s window of a slow ship is mostly its initial state)."""
    return WINDOW_S if surge_time_constant_s(vessel) <= WINDOW_S else SLOW_WINDOW_S


def manoeuvre_horizon_s(vessel: Vessel, fitted=None) -> float:
    """The free runs whose misfit `twin evaluate` splits by manoeuvre: as long as those the fit's
    envelope counted (`fitted`, a coverage.Envelope), else the vessel's own fit window (10 s for a
    small boat, 30 s for a slow ship): a slow ship's 10-s run is mostly its initial state."""
    return float(fitted.horizon_s) if fitted is not None else default_window_s(vessel)


def _check_counts(window_s, *, params, groups, **counts) -> None:
    """The numbers and names identify takes, checked before any work (the Python API passes them as
    given: a window of 0 s failed in the engine, 1.5 evaluations ran scipy's optimiser for minutes)."""
    if isinstance(window_s, bool) or not isinstance(window_s, numbers.Real) or not (math.isfinite(window_s)
                                                                                 and window_s > 0):
        raise TwinError(f"window_s must be a positive finite number of seconds, got {window_s!r}")
    for name, value in counts.items():
        least = 0 if name == "seed" else 1
        if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < least:
            raise TwinError(f"{name} must be a whole number ≥ {least}, got {value!r}")
    for name, value in (("params", params), ("groups", groups)):
        if value is not None and (not isinstance(value, (list, tuple)) or not value
                                  or not all(isinstance(v, str) for v in value)):
            raise TwinError(f"{name} must be None or a non-empty list of names, got {value!r}")


def _check(start: str, thruster: str, split: str, train: float, prior_weights) -> None:
    if start not in ("free", "measured"):
        raise TwinError(f"start must be free or measured, got '{start}'")
    if thruster not in ("static", "dynamic"):
        raise TwinError(f"thruster must be static or dynamic, got '{thruster}'")
    if split not in ("segments", "points"):
        raise TwinError(f"split must be segments or points, got '{split}'")
    if not 0.1 <= train <= 0.9:
        raise TwinError(f"train must lie in [0.1, 0.9], got {train}")
    if not prior_weights or any(not w > 0 for w in prior_weights):
        raise TwinError("the beliefs' weights must be positive numbers")
    shown = [f"{w:g}" for w in prior_weights]
    twice = sorted({s for s in shown if shown.count(s) > 1})
    if twice:  # each weight is a choice named by its weight to six digits
        raise TwinError(f"the beliefs' weights must differ in their first six digits: {', '.join(twice)} is given "
                        "more than once")


def check_wind(recordings: list[Recording], wind: str | None, vessel: Vessel | None = None) -> None:
    """wind None or "measured"; measured needs every recording's wind stream (TwinError naming one
    without) and, where `vessel` is given, a wind load model for it to act through."""
    if wind not in (None, "measured"):
        raise TwinError(f"wind must be None or 'measured', got {wind!r}")
    if wind == "measured" and vessel is not None:
        if not vessel.feels_wind():
            raise TwinError(f"vessel '{vessel.name}' has no wind load model (wind_load areas or wind_regression): "
                            "a measured wind would act on nothing")
    if wind == "measured":
        for rec in recordings:
            if not len(rec.wind):
                raise TwinError(f"{Path(rec.source).name}: no measured wind (the recording has no wind stream): "
                                "--wind-measured needs an anemometer's wind stream")


def held_inputs(rec: Recording) -> str | None:
    """The kind of inputs a recording holds: "propeller_rudder", "pwm", or None (neither)."""
    return "propeller_rudder" if len(rec.prop_rudder) else ("pwm" if len(rec.pwm) else None)


def check_inputs(recordings: list[Recording], vessel: Vessel) -> None:
    """TwinError naming the first recording whose inputs are not the kind that drives `vessel` (PWM
    against a propeller and rudder): before any work, and before any advice on how to run it."""
    wanted = vessel.thrusters.input_kind
    for rec in recordings:
        held = held_inputs(rec)
        if held is not None and held != wanted:
            raise TwinError(f"{Path(rec.source).name}: {inputs_mismatch(vessel.name, wanted, held)}")


def fitted_wind_note(vessel: Vessel, wind: str | None) -> str | None:
    """A note when `vessel` was identified with the measured wind as a known input and is now run
    without it (its uncertainty.fitted_on says how it was fitted)."""
    if wind is None and (vessel.uncertainty.get("fitted_on") or {}).get("wind") == "measured":
        return ("this twin was identified with the measured wind as a known input; add --wind-measured to run it "
                "the way it was fitted")
    return None


def beyond_command_bounds(recordings: list[Recording], vessel: Vessel) -> list[str]:
    """A note for each recording whose propeller speed or rudder angle goes beyond the vessel file's
    bounds (engine.limits.beyond_bounds): a replay takes them as logged (Vessel.as_logged), where the
    twin's own commands stop."""
    if vessel.thrusters.kind != "propeller_rudder":
        return []
    out = []
    for rec in recordings:
        if not len(rec.prop_rudder):
            continue
        t = np.asarray(rec.prop_rudder.t, float)
        inputs = InputSeries(t - t[0], np.column_stack([rec.prop_rudder["n_rps"], rec.prop_rudder["delta_rad"]]),
                             "propeller_rudder")
        for lim in beyond_bounds(vessel, inputs, float(t[-1] - t[0]) + 1.0):
            out.append(f"{Path(rec.source).name}: the {lim.thruster} {lim.quantity} reaches "
                       f"{lim.bound + lim.worst_excess:.3g} {lim.unit}, beyond the vessel file's {lim.bound:g} "
                       f"{lim.unit} (the bound of the twin's own commands): replayed as logged")
    return out


UNDER_WAY_M_S = 0.5  # a ground speed no drift gives a small hull: it is being driven


def idle_inputs_under_way(recordings: list[Recording]) -> list[str]:
    """A warning for each recording whose thruster PWM never leaves its neutral (IDLE_PWM_US) while its
    GNSS track goes faster than UNDER_WAY_M_S for a tenth of the log: the inputs that drove it are
    not the ones logged (other servo outputs, --channels, or another neutral)."""
    out = []
    for rec in recordings:
        if not len(rec.pwm) or len(rec.gnss) < 3:
            continue
        pwm = np.column_stack([rec.pwm["left_us"], rec.pwm["right_us"]]) - np.asarray(rec.pwm_neutral_us)
        if np.nanmax(np.abs(pwm)) > IDLE_PWM_US:
            continue
        north, east = ned_from_geodetic(rec.gnss["lat_deg"], rec.gnss["lon_deg"], rec.gnss["lat_deg"][0],
                                        rec.gnss["lon_deg"][0])[:2]
        t = np.asarray(rec.gnss.t, float)
        speed = np.hypot(np.diff(north), np.diff(east)) / np.maximum(np.diff(t), 1e-6)
        if np.nanpercentile(speed, 90) > UNDER_WAY_M_S:
            out.append(f"{Path(rec.source).name}: the thrusters' PWM stays within {IDLE_PWM_US:g} µs of neutral "
                       f"({', '.join(f'{n:g}' for n in rec.pwm_neutral_us)} µs) while the boat goes "
                       f"{np.nanpercentile(speed, 90):.1f} m/s over ground: the logged outputs are not the ones "
                       "that drove it (--channels LEFT,RIGHT names the servo outputs)")
    return out


MIN_WIND_COVER = 0.5


def unused_wind_note(recordings: list[Recording], wind: str | None, vessel: Vessel) -> str | None:
    """A note when recordings hold a measured wind that this run leaves out (no `wind`), on a vessel
    with wind areas for it to act on; None otherwise."""
    held = sum(bool(len(r.wind)) for r in recordings)
    if wind == "measured" or not held or not vessel.feels_wind():
        return None
    return (f"{held} of {len(recordings)} recording{'' if len(recordings) == 1 else 's'} "
            f"hold{'s' if held == 1 else ''} a measured wind, left "
            "out here (--wind-measured takes it as a known input)")


def wind_gaps(recordings: list[Recording]) -> list[str]:
    """A note for each recording whose measured wind covers under MIN_WIND_COVER of its GNSS time
    (gaps longer than three of its sample periods): the free runs hold the last wind across them."""
    out = []
    for rec in recordings:
        if not len(rec.wind) or len(rec.gnss) < 2:
            continue
        t = np.asarray(rec.wind.t, float)
        span = float(np.ptp(np.asarray(rec.gnss.t, float)))
        steps = np.diff(t)
        covered = float(steps[steps <= 3 * np.median(steps)].sum()) if len(steps) else 0.0
        if span > 0 and covered / span < MIN_WIND_COVER:
            out.append(f"{Path(rec.source).name}: the measured wind covers {100 * covered / span:.0f} % of the log; "
                       "the free runs hold its last value across the gaps")
    return out


def _with_supply_reference(vessel: Vessel, preps: list[Prepared]) -> Vessel:
    """The vessel with the voltage its thrust map holds at (the logs' fullest pack,
    prepare.supply_reference) where it states none: fitting the thrust's answer to the pack needs
    one. TwinError when a recording logs no battery."""
    if vessel.thrusters.supply_ref_v is not None:
        return vessel
    ref = supply_reference(preps)
    if ref is None:
        raise TwinError("supply_exponent (the thrust's answer to the pack voltage) needs every recording's battery "
                        "voltage, and one of them logs none")
    return replace(vessel, thrusters=replace(vessel.thrusters, supply_ref_v=ref))


def _groups(groups, params, prior: Vessel, supplied: bool = False) -> dict[str, tuple[str, ...]]:
    if params is not None:
        return {"chosen": tuple(params)}
    table = groups_of(prior, supplied)
    chosen = tuple(table) if groups is None else tuple(groups)
    if "pack voltage" in chosen and "pack voltage" not in table and prior.mmg is None:
        raise TwinError("group 'pack voltage' needs every recording's battery voltage, and one of them logs none")
    unknown = [g for g in chosen if g not in table]
    if unknown:
        raise TwinError(f"unknown group(s) {', '.join(unknown)} (known for '{prior.name}': {', '.join(table)})")
    return {g: table[g] for g in chosen}


def _labelled(cv: CrossValidation, label: str) -> CrossValidation:
    cv.label = label
    return cv


def _informative(prep: Prepared, w) -> bool:
    """A window in which the thrusters work or the boat moves: a drifting boat at rest says nothing
    about its hull or thrusters (only about the wind and current of that day)."""
    sl = slice(w.start, w.start + w.n + 1)
    if prep.input_kind == "propeller_rudder":  # (n rps, δ rad): the propeller is what drives
        thrust = np.any(np.abs(prep.pwm[sl, 0]) > IDLE_RPS)
    else:
        thrust = np.any(np.abs(prep.pwm[sl] - np.asarray(prep.pwm_neutral_us)) > IDLE_PWM_US)
    moving = np.any(np.hypot(prep.u[sl], prep.v[sl]) > IDLE_SPEED_M_S) or np.any(np.abs(prep.r[sl]) > IDLE_YAW_RAD_S)
    return bool(thrust or moving)


def _without_each_group(fit, start: Choice, names_by_group, all_names, preps, every, fit_groups, judge_groups,
                        group_names, cache, wind: str | None = None, folds=None) -> list[Choice]:
    """Each group back at its prior, the others free (refits linearised about the fit with every
    group free), judged on the left-out runs: what Identification.needed reads. Not a choice: on
    the BlueBoat's five least active runs, the left-out costs of such options differ by 2-10 %
    while every option's left-out R² of r is negative, so choosing among them picks by scatter
    (Method: identification)."""
    obj, x, J = fit.objective, fit.x, fit.jacobian
    r = obj.residuals(x)
    col = {n: i for i, n in enumerate(all_names)}
    held = _unpinned(fit)
    if len(start.free_groups) < 2:
        return []
    configs = {}
    for g in start.free_groups:
        fixed = np.ones(len(all_names), bool)
        for kept in start.free_groups:
            if kept != g:
                fixed[[col[n] for n in names_by_group[kept]]] = False
        configs[g] = jackknife_vessels(obj, x, J, r, fit_groups, fixed=fixed | held, folds=folds)
    judged = judge(configs, preps, every, judge_groups, group_names, obj.sigma, cache, wind)
    return [Choice(f"{start.label} without {g}", start.prior_weight, tuple(k for k in start.free_groups if k != g),
                   _labelled(cv, f"{start.label} without {g}")) for g, cv in judged.items()]


def own_misfit_sigma(fit: simfit.FitResult) -> np.ndarray:
    """Each velocity's residual scale (m/s, m/s, rad/s) for the fits: the RMS of its misfit at `fit`
    (a first fit, each velocity scaled by its measured spread), at least MIN_MISFIT_SHARE of that
    spread. The twin's form error is what its residuals mostly are, and it differs by velocity: a
    sway the GNSS reads through a compass and an antenna the twin does not know may stay half
    unexplained where surge and yaw are matched to a tenth, and scaled alike the fit bends the
    yaw's coefficients to answer the sway. Weighing each output by its own residual variance is the
    maximum-likelihood fit of several outputs whose noise variances are not known [Ljung-1999 §7.3],
    one step of it."""
    obj = fit.objective
    return obj.sigma * np.maximum(obj.dof_rms(fit.x), MIN_MISFIT_SHARE)


def _unpinned(fit: simfit.FitResult) -> np.ndarray:
    """The coordinates the fit kept at their prior (not pinned by the data): the twins that judge a
    fit on left-out runs hold them there too, as the twin written does."""
    return np.array([not e.identifiable for e in fit.estimates])


def _with_sources(fit: simfit.FitResult, choice: Choice, sources: list[str], wind: str | None = None) -> Vessel:
    v = fit.vessel
    moved = [e for e in fit.estimates if e.identifiable and not e.on_bound]
    pinned = ", ".join(e.name for e in moved if not e.held_by_belief and not e.disputed and not e.stand_in)
    held = ", ".join(e.name for e in moved if e.held_by_belief)
    disputed = ", ".join(e.name for e in moved if e.disputed)
    stand_in = ", ".join(e.name for e in fit.estimates if e.identifiable and e.stand_in)
    walled = ", ".join(e.name for e in fit.estimates if e.on_bound)
    kept = ", ".join(e.name for e in fit.estimates if not e.identifiable)
    when = _dt.date.today().isoformat()
    files = ", ".join(Path(s).name for s in sources) or "recordings"
    expected = choice.cv.summary()
    wind_text = ", each recording's measured wind a known input" if wind == "measured" else ""
    if not choice.free_groups:
        return replace(v, path=None, sources={**v.sources, "identification": (
            f"kept by `twin identify` on {when} from {files}{wind_text}: {fit.meta['kept_prior']}. {expected}")})
    text = (f"identified by `twin identify` on {when} from {files}{wind_text}: maximum a posteriori fit by free-run "
            f"windows of {fit.meta.get('window_s')} s, beliefs worth {choice.prior_weight:g} windows, free groups "
            f"{', '.join(choice.free_groups)} (chosen on left-out runs); pinned by the recordings: {pinned or 'none'}"
            + (f"; held by their beliefs (the recordings add little): {held}" if held else "")
            + (f"; moved by recordings whose windows pull them different ways: {disputed}" if disputed else "")
            + (f"; moved beyond what their beliefs allow, standing in for something the form lacks: {stand_in}"
               if stand_in else "")
            + (f"; on or within their σ of a bound of their physical range: {walled}"
               if walled else "")
            + (f"; kept at the prior with its uncertainty: {kept}" if kept else "") + f". {expected}")
    return replace(v, path=None, sources={**v.sources, "identification": text})


def format_estimates(result: simfit.FitResult) -> str:
    """The simulation fit's parameters as a text table; notes in full (a cut note hides why)."""
    width = max([9] + [len(e.unit) for e in result.estimates])
    name_width = max([14] + [len(e.name) for e in result.estimates])  # mmg_gamma_minus is 15 wide
    head = f"{'parameter':{name_width}s} {'unit':{width}s} {'prior':>11s} {'identified':>11s} {'± 1σ':>10s}  note"
    lines = [head, "-" * len(head)]
    for e in result.estimates:
        sigma = f"{e.sigma:10.3g}" if e.sigma is not None else f"{'-':>10s}"
        lines.append(f"{e.name:{name_width}s} {e.unit:{width}s} {e.prior:11.4g} {e.value:11.4g} {sigma}  {e.note}")
    window, stride = result.meta.get("window_s"), result.meta.get("stride_s")
    working = "the propeller working" if result.vessel.mmg is not None else "the thrusters working"
    which = (f" of {window:g} s{' back to back' if stride == window else ''} with {working} or the hull "
             "moving" if window else "")
    if "kept_prior" in result.meta:
        lines.append(f"the prior written, not the fit: {result.meta['kept_prior']}")
        return "\n".join(lines)
    lines.append(f"free-run cost {result.cost_before:.4g} → {result.cost_after:.4g} over {result.n_windows} windows"
                 f"{which} ({result.n_evaluations} candidate twins run on each, the fit took {result.seconds:.1f} s)")
    if "dof_sigma" in result.meta:
        su, sv, sr = result.meta["dof_sigma"]
        lines.append(f"each velocity's residual scaled by its misfit at a first fit: u {su:.3g} m/s, v {sv:.3g} m/s, "
                     f"r {sr:.3g} rad/s")
    return "\n".join(lines)


def format_needed(ident: Identification) -> str:
    """One line: the physics the left-out runs need most (Identification.needed)."""
    needed = ident.needed()
    if ident.chosen is not None and ident.chosen.free_groups == ("chosen",):
        return ""  # --params: no groups were judged
    if not needed:
        return f"no group is needed by the left-out runs (none raises their cost ×{NEEDED_RATIO:g} back at its prior)"
    return "the left-out runs need: " + ", ".join(f"{g} (left-out cost ×{r:.2f} without it)" for g, r in needed)


def format_choices(ident: Identification) -> str:
    """The choices and their left-out scores; labels in full (a cut label hides which groups were freed)."""
    rows = ([("prior (no fit)", ident.prior_cv)] if ident.prior_cv else []) + [(c.label, c.cv) for c in ident.choices]
    marked = [(label + (" *" if ident.chosen is not None and cv is ident.chosen.cv else ""), cv) for label, cv in rows]
    width = max([len("configuration")] + [len(label) for label, _ in marked])
    head = f"{'configuration':{width}s} {'cost':>9s} " + " ".join(f"{'R2 ' + d + ' med':>9s}" for d in "uvr")
    lines = [head, "-" * len(head)]
    for label, cv in marked:
        cells = " ".join(f"{s[0]:9.3f}" if (s := cv.spread(d)) else f"{'-':>9s}" for d in "uvr")
        ran_away = sum(any(m.get("diverged", 0) for m in r.metrics.values()) for r in cv.runs)
        note = f"  (ran away on {ran_away} of {len(cv.runs)} left-out runs)" if ran_away else ""
        lines.append(f"{label:{width}s} {cv.cost:9.4g} {cells}{note}")
    if ident.chosen is not None:
        by_groups = ident.chosen.free_groups != ("chosen",)  # --params: the coefficients given, no groups
        lines.append("* the twin written: the belief scale of lowest left-out cost" +
                     ("; every group free to move, and a coefficient the recordings do not pin kept at its prior (the rows "
                      "without a * are a report, not a choice: a group is not dropped where the left-out runs score "
                      "lower without it, as such scores differ within the scatter of the judging and did not carry "
                      "beyond the fitted runs; docs/method/identification.md)" if by_groups else "") +
                     (f"; the prior is written, as it predicts the left-out runs better by {100 * DROP_GAIN:g} % or "
                      "more" if by_groups and not ident.chosen.free_groups else ""))
    costs = [cv.cost for _, cv in rows if np.isfinite(cv.cost)]
    if len(costs) > 1 and min(costs) > 0 and max(costs) <= (1 + TIED_CHOICES) * min(costs):
        lines.append(f"the left-out runs tell these options apart by under {100 * TIED_CHOICES:g} %: they hold too little "
                     "manoeuvring to choose on, and the choice rests on nothing (more logs, with turns and changes "
                     "of speed, let it be made)")
    return "\n".join(lines)


def format_greybox(table: dict) -> str:
    parts = []
    if "by_split_method" in table:
        parts.append(render_split_table(table["by_split_method"]))
    if "by_training_share" in table:
        parts.append(render_training_table(table["by_training_share"]))
    return "\n\n".join(parts)
