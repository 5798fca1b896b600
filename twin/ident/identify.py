"""`twin identify`: from recordings to a vessel description the twin loads.

1. Seed 004 grey-box least squares (static or first-order dynamic thruster model),
   with its tables (MAE and R² per DOF over random splits, by training share:
   Tables 4-9 in shape) and the physical first guesses it implies.
2. Identification by simulation (simfit.py) of the physical parameters, started
   from whichever of the prior vessel and the grey-box guesses predicts the free
   runs better; parameters the recordings cannot pin down keep their prior value
   and are named with the reason.
3. The result: the vessel description with the identified values and their
   sources, ready for `twin simulate --model`, `twin evaluate --model`, `twin crosscheck`.
"""
from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..effects import coefficients
from ..engine.mjcf import compile_vessel
from ..errors import TwinError
from ..prepare import Prepared
from ..formats import read_recording
from ..fit.calibrate import prepare_for
from ..vessel import Vessel, check
from ..fit import simfit
from ..fit.objective import Objective
from ..fit.windows import ModelCache, make_windows
from .seed004.greybox import fit_dynamic, fit_static
from .seed004.physical import first_guesses
from .seed004.splits import render_split_table, render_training_table, split_method_table, training_size_table

GNSS_WINDOW_S = 1.0  # Savitzky-Golay window of the GNSS velocities (seed 004 §5.1)
HEADING_WINDOW_S = 0.5  # the AHRS at 50 Hz affords a shorter one for the yaw rate


def load(paths: list[Path], vessel: Vessel, channels: dict | None = None, window_s: float = GNSS_WINDOW_S,
         heading_window_s: float = HEADING_WINDOW_S) -> list[Prepared]:
    """Read and prepare recordings as the vessel's sensors see them."""
    compiled = compile_vessel(vessel)
    out = []
    for path in paths:
        rec = read_recording(path, channels=channels)
        if not len(rec.pwm):
            raise TwinError(f"{Path(path).name}: no thruster PWM: nothing can be identified without the inputs "
                            "(for an ArduPilot log, give the thruster channels with --channels LEFT,RIGHT)")
        out.append(prepare_for(rec, compiled, window_s=window_s, heading_window_s=heading_window_s))
    return out


@dataclass
class Report:
    vessel: Vessel
    greybox: dict = field(default_factory=dict)
    simfit: simfit.FitResult | None = None
    start: str = "prior"
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        return {"greybox": self.greybox, "simfit": self.simfit.to_dict() if self.simfit else None,
                "simfit_start": self.start, "notes": self.notes}


def greybox_stage(preps: list[Prepared], prior: Vessel, thruster: str, split: str, train: float, repeats: int,
                  seed: int) -> tuple[dict, dict | None, list[str]]:
    """Seed 004 tables and first guesses; a grey-box failure is a note, not the end."""
    fit = {"static": fit_static, "dynamic": fit_dynamic}[thruster]
    notes: list[str] = []
    out: dict = {"thruster": thruster}
    try:
        model = fit(preps)
        out["first_guesses"] = first_guesses(model, prior)
        out["model"] = model.to_dict()
    except TwinError as exc:
        notes.append(f"grey-box ({thruster}, seed 004): {exc}")
        return out, None, notes
    try:
        out["by_split_method"] = split_method_table(fit, preps, train=train, repeats=repeats, seed=seed)
        out["by_training_share"] = training_size_table(fit, preps, method=split)
    except TwinError as exc:
        notes.append(f"grey-box tables: {exc}")
    return out, out["first_guesses"], notes


def vessel_from_guesses(prior: Vessel, guesses: dict) -> Vessel | None:
    """The prior with the grey-box's physically admissible guesses put in (None if none is)."""
    rigid = compile_vessel(prior).geometry.rigid
    v = prior

    def value(key):
        entry = guesses.get(key) or {}
        x = entry.get("value")
        return float(x) if isinstance(x, (int, float)) and np.isfinite(x) else None

    changes = 0
    for name in ("Xu", "Xuu", "Nr", "Nrr"):
        x = value(name)
        if x is not None and x < 0:
            v = replace(v, damping=replace(v.damping, **{name: x}))
            changes += 1
    if (s := value("thrust_scale_forward")) is not None and 0.05 < s < 20:
        t = v.thrusters
        v = replace(v, thrusters=replace(t, gain_left=t.gain_left * s, gain_right=t.gain_right * s))
        changes += 1
    if (m33 := value("M33_eff")) is not None and m33 > rigid.Iz_kgm2:
        v = replace(v, added_mass=replace(v.added_mass, Nrdot=rigid.Iz_kgm2 - m33))
        changes += 1
    m22 = value("M22_from_sway")
    if m22 is not None and m22 > rigid.mass_kg:
        v = replace(v, added_mass=replace(v.added_mass, Yvdot=rigid.mass_kg - m22))
        changes += 1
    if (lag := value("lag_s")) is not None and 0.01 < lag < 3:
        v = replace(v, thrusters=replace(v.thrusters, lag_s=lag))
        changes += 1
    try:
        check(v)
    except TwinError:
        return None
    return v if changes else None


def identify(preps: list[Prepared], prior: Vessel, *, thruster: str = "static", split: str = "segments",
             train: float = 0.7, repeats: int = 20, seed: int = 0, params: tuple[str, ...] = simfit.DEFAULT,
             anchor: str = "mass", simulate: bool = True, window_s: float = 10.0, stride_s: float = 5.0,
             start: str = "free", sources: list[str] | None = None) -> Report:
    """The whole identification (module docstring). start: each free run's initial velocities
    "free" (estimated with the parameters: unbiased physics from noisy starts) or "measured"
    (the twin that predicts best from the starts as recorded, which is how it is judged)."""
    if start not in ("free", "measured"):
        raise TwinError(f"--start must be free or measured, got '{start}'")
    if thruster not in ("static", "dynamic"):
        raise TwinError(f"--thruster must be static or dynamic, got '{thruster}'")
    if split not in ("segments", "points"):
        raise TwinError(f"--split must be segments or points, got '{split}'")
    if not 0.1 <= train <= 0.9:
        raise TwinError(f"--train must lie in [0.1, 0.9], got {train}")
    table, guesses, notes = greybox_stage(preps, prior, thruster, split, train, repeats, seed)
    report = Report(prior, table, notes=notes)
    if not simulate:
        return report
    first, cache = prior, ModelCache()
    guessed = vessel_from_guesses(prior, guesses) if guesses else None
    if guessed is not None:
        costs = {name: _free_run_cost(v, preps, params, anchor, window_s, stride_s, cache)
                 for name, v in (("prior", prior), ("grey-box", guessed))}
        report.start = min(costs, key=costs.get)
        first = guessed if report.start == "grey-box" else prior
        notes.append("simulation fit started from the " + report.start + " (free-run cost " +
                     ", ".join(f"{k} {c:.4g}" for k, c in costs.items()) + ")")
    result = simfit.fit(first, preps, params, anchor=anchor, window_s=window_s, stride_s=stride_s, cache=cache,
                        free_start=start == "free")
    report.simfit = result
    report.vessel = _with_sources(result, sources or [])
    for e in result.estimates:
        if not e.identifiable:
            notes.append(f"{e.name} kept at its prior {e.prior:.4g} {e.unit}: {e.note}")
    return report


def _free_run_cost(vessel: Vessel, preps, params, anchor, window_s, stride_s, cache) -> float:
    windows = make_windows(preps, window_s, stride_s * 2, min_length_s=min(window_s, 3.0))
    table = coefficients(vessel)
    obj = Objective(vessel, [table[n] for n in params if n in table], preps, windows, cache)
    return 0.5 * float(np.sum(obj.residuals(obj.x_prior) ** 2))


def _with_sources(result: simfit.FitResult, sources: list[str]) -> Vessel:
    v = result.vessel
    names = ", ".join(f"{e.name}" for e in result.estimates if e.identifiable)
    kept = ", ".join(e.name for e in result.estimates if not e.identifiable)
    when = _dt.date.today().isoformat()
    files = ", ".join(Path(s).name for s in sources) or "recordings"
    text = (f"identified by `twin identify` on {when} from {files}: {names} by free-run windows of "
            f"{result.meta.get('window_s')} s (anchor: {result.meta.get('anchor')}, initial velocities "
            f"{'estimated' if result.meta.get('free_start') else 'as measured'}, residual RMS "
            f"{result.meta.get('residual_rms', float('nan')):.3f} σ)" + (f"; kept at the prior: {kept}" if kept else ""))
    return replace(v, sources={**v.sources, "identification": text})


def format_estimates(result: simfit.FitResult) -> str:
    """The simulation fit's parameters as a text table, ≤ 100 columns."""
    head = f"{'parameter':14s} {'unit':9s} {'prior':>11s} {'identified':>11s} {'± 1σ':>10s}  note"
    lines = [head, "-" * len(head)]
    for e in result.estimates:
        sigma = f"{e.sigma:10.3g}" if e.sigma is not None else f"{'-':>10s}"
        lines.append(f"{e.name:14s} {e.unit[:9]:9s} {e.prior:11.4g} {e.value:11.4g} {sigma}  {e.note[:40]}")
    lines.append(f"free-run cost {result.cost_before:.4g} → {result.cost_after:.4g} over {result.n_windows} windows "
                 f"({result.n_evaluations} candidate twins on each, {result.seconds:.1f} s)")
    return "\n".join(lines)


def format_greybox(table: dict) -> str:
    parts = []
    if "by_split_method" in table:
        parts.append(render_split_table(table["by_split_method"]))
    if "by_training_share" in table:
        parts.append(render_training_table(table["by_training_share"]))
    return "\n\n".join(parts)
