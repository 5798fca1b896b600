"""Judging a model by what it predicts ([Morel-2024 eqs. 40-41], R² and MAE per DOF):

  one_step       ν̂(k+1) from the measured state at k (what [Morel-2024] reports; the
                 persistence model ν(k+1) = ν(k) already scores R² ≈ 0.99 on it)
  free_run_10s   free runs of 10 s from measured states, driven by the recorded PWM
  free_run_30s   the same over 30 s
  full           each whole trajectory segment from its first measured state

Every model is a predictor with `predict_windows(prep, starts, n_steps) -> (W, n+1, 3)`
(ν̂ with index 0 the measured start): the grey-box models of [Morel-2024] implement it,
and `TwinPredictor` wraps a vessel description on the batch engine.

Where a model misses, beside how much: `error_growth` (how each window's error grows, with its
inputs: a missing force builds whenever the same inputs recur) and `misfit_by_manoeuvre` (each
manoeuvre's share of 1 − R²: idle, ahead, turning, spin, astern, read from the inputs alone).
"""
from __future__ import annotations

import math
import textwrap
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import numpy as np

from ..errors import TwinError
from ..prepare import Prepared
from ..threads import one_blas_thread
from ..vessel import Vessel
from .coverage import OWN_TAIL, SHOWN, UNITS, Envelope, beyond, sample_ranges, span_text
from .metrics import DOFS, RESOLUTION, r2_mae
from .windows import ModelCache, Window, make_windows, measured, predict

HORIZONS = {"one_step": None, "free_run_10s": 10.0, "free_run_30s": 30.0, "full": "segment"}


class Predictor(Protocol):
    def predict_windows(self, prep: Prepared, starts: np.ndarray, n_steps: int) -> np.ndarray: ...


@dataclass
class TwinPredictor:
    """A vessel description as a predictor: free runs on the batch engine."""

    vessel: Vessel
    cache: ModelCache | None = None
    wind: str | None = None  # "measured": each recording's wind stream a known input (windows.predict)

    def predict_windows(self, prep: Prepared, starts: np.ndarray, n_steps: int) -> np.ndarray:
        wins = [Window(0, int(s), _steps_in_segment(prep, int(s), n_steps)) for s in starts]
        out = np.full((len(wins), n_steps + 1, 3), np.nan)
        keep = [i for i, w in enumerate(wins) if w.n > 0]
        if keep:
            nu = predict(self.vessel, [prep], [wins[i] for i in keep], self.cache, wind=self.wind)[0].nu_failed_as_inf()
            out[keep, : nu.shape[1]] = nu
        return out


def _steps_in_segment(prep: Prepared, start: int, n_steps: int) -> int:
    seg = prep.segments[int(prep.segment[start])]
    return min(n_steps, seg.stop - 1 - start)


def horizon_windows(preps: list[Prepared], horizon, stride_s: float) -> list[Window]:
    if horizon is None:
        return make_windows(preps, 0.1, 0.1, min_length_s=0.1) if preps else []
    if horizon == "segment":
        return make_windows(preps, None)
    return make_windows(preps, float(horizon), stride_s, min_length_s=float(horizon))


@one_blas_thread
def evaluate(model: Predictor | Vessel, preps: list[Prepared], stride_s: float = 2.0,
             horizons: dict | None = None, wind: str | None = None) -> dict:
    """Metrics per horizon (see the module docstring): {horizon: {u, v, r: {r2, mae, n}}}.

    Only the predicted samples count (not the measured start of each window); a free
    run of a given horizon uses full-length windows only, so every horizon is what its
    name says. wind "measured": a vessel's free runs take each recording's measured wind."""
    if isinstance(model, Vessel):
        model = TwinPredictor(model, ModelCache(), wind)
    out = {}
    for name, horizon in (horizons or HORIZONS).items():
        wins = horizon_windows(preps, horizon, stride_s)
        if not wins:
            out[name] = {d: {"r2": None, "mae": None, "n": 0, "diverged": 0} for d in DOFS}
            continue
        pred, meas = _predictions(model, preps, wins)
        out[name] = r2_mae(pred[:, 1:], meas[:, 1:])
    return out


def error_growth(model: Predictor | Vessel, preps: list[Prepared], horizon_s: float, stride_s: float = 2.0,
                 wind: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """How the free-run error grows, window by window: (W, 2) mean inputs of each window (PWM µs, or
    n rps and δ rad) and (W, 3) the change of the prediction's error (predicted − measured) of u, v,
    r from its start to its end. An error that grows the same way whenever some input does the same
    is a force the twin lacks there (a start error decays; a missing force builds). `wind` applies
    to a Vessel given as the model (a Predictor carries its own)."""
    if isinstance(model, Vessel):
        model = TwinPredictor(model, ModelCache(), wind)
    wins = horizon_windows(preps, horizon_s, stride_s)
    if not wins:
        return np.zeros((0, 2)), np.zeros((0, 3))
    pred, meas = _predictions(model, preps, wins)
    err = pred - meas
    inputs = np.array([preps[w.rec].pwm[w.start:w.start + w.n + 1].mean(axis=0) for w in wins])
    growth = np.array([err[j, w.n] - err[j, 0] for j, w in enumerate(wins)])
    return inputs, growth


# what a window's inputs do, for `misfit_by_manoeuvre`
MANOEUVRES = ("idle", "ahead", "turning", "spin", "astern")
# a tenth of full thrust (or of the top propeller speed) moves a small boat at a few cm/s: below it
# the inputs hold the boat, they do not drive it
POWERED_SHARE = 0.1
# below 10° a rudder holds a course against small disturbances; beyond it the ship is turned
TURNING_RUDDER_DEG = 10.0
# twin thrusters steer by their difference: one at less than half the other's thrust turns the boat
# about as hard as its rudder-steered cousin beyond 10°
TURNING_THRUST_SHARE = 0.5


def _filled(vessel: Vessel, inputs: np.ndarray) -> np.ndarray:
    """The inputs as (n, 2) floats, a missing one (NaN) at what drives nothing: the PWM map's neutral
    pulse, or zero thrust, rps and rudder."""
    th = vessel.thrusters
    neutral = th.pwm_offset * th.pwm_scale_us if th.kind == "t200" else 0.0
    return np.nan_to_num(np.asarray(inputs, float).reshape(-1, 2), nan=neutral)


def input_scale(vessel: Vessel, inputs: np.ndarray) -> float:
    """What "full" means for `manoeuvres`: full thrust (N) of a thruster, or the top propeller speed
    (rps), from the vessel where it says, otherwise the largest in `inputs` (all the recordings
    judged, so that a window is classified the same way whatever else it holds)."""
    th = vessel.thrusters
    x = _filled(vessel, inputs)
    if th.kind == "propeller_rudder":
        return float(th.rps_max) if th.rps_max else float(np.max(np.abs(x[:, 0]), initial=0.0))
    bound = max((abs(b) for b in th.bounds() if np.isfinite(b)), default=0.0)
    thrust = th.thrust_from_pwm(x) if th.kind == "t200" else x
    return float(bound or (th.command_scale_n or 0.0) or np.max(np.abs(thrust), initial=0.0))


def manoeuvres(vessel: Vessel, inputs: np.ndarray, scale: float | None = None) -> np.ndarray:
    """What each sample's inputs (PWM µs per thruster, or n rps and δ rad) ask of the vessel: one of
    MANOEUVRES per row, from the thrust map alone (no state): idle (no thruster above POWERED_SHARE
    of full thrust), spin (both, opposite ways), astern (net thrust backwards), turning (one
    thruster below TURNING_THRUST_SHARE of the other; a rudder beyond TURNING_RUDDER_DEG), else
    ahead. A missing input (NaN) reads as idle. `scale`: input_scale's "full" (default: from these
    inputs)."""
    return np.array(MANOEUVRES)[_manoeuvre_codes(vessel, inputs, scale)]


def _manoeuvre_codes(vessel: Vessel, inputs: np.ndarray, scale: float | None) -> np.ndarray:
    x = _filled(vessel, inputs)
    full = input_scale(vessel, x) if scale is None else scale
    th = vessel.thrusters
    if th.kind == "propeller_rudder":
        idle = np.abs(x[:, 0]) <= POWERED_SHARE * full
        turning = np.abs(np.degrees(x[:, 1])) > TURNING_RUDDER_DEG
        return np.where(idle, 0, np.where(x[:, 0] < 0.0, 4, np.where(turning, 2, 1)))
    thrust = th.thrust_from_pwm(x) if th.kind == "t200" else x
    on = np.abs(thrust) > POWERED_SHARE * full
    left, right = thrust[:, 0], thrust[:, 1]
    spin = on.all(axis=1) & (np.sign(left) != np.sign(right))
    turning = np.minimum(np.abs(left), np.abs(right)) < TURNING_THRUST_SHARE * np.maximum(np.abs(left), np.abs(right))
    return np.where(~on.any(axis=1), 0, np.where(spin, 3, np.where(left + right < 0.0, 4, np.where(turning, 2, 1))))


def fitted_envelope(vessel: Vessel, preps: list[Prepared], horizon_s: float = 10.0, stride_s: float = 2.0) -> Envelope:
    """What the recordings `preps` give a fit (coverage.Envelope): the range of their measured u, v,
    r over the samples of their free-run windows of `horizon_s`, counted as `misfit_by_manoeuvre`
    counts a judged recording's (so the fit's own logs, judged, leave coverage.OWN_TAIL beyond in
    each velocity), and those windows per manoeuvre; every sample where no window fits."""
    wins = horizon_windows(preps, horizon_s, stride_s)
    if wins:
        states = measured(preps, wins)[1][:, 1:].reshape(-1, 3)
    else:
        states = np.vstack([np.column_stack([p.u, p.v, p.r]) for p in preps])
    kind = _window_manoeuvres(vessel, preps, wins) if wins else np.zeros(0, int)
    counts = {name: int(np.sum(kind == i)) for i, name in enumerate(MANOEUVRES) if np.any(kind == i)}
    sources = tuple(Path(p.settings.source).name for p in preps if p.settings.source)
    return Envelope(sample_ranges(states), counts, float(horizon_s), len(preps), float(stride_s), sources)


def misfit_by_manoeuvre(model: Predictor | Vessel, preps: list[Prepared], horizon_s: float, stride_s: float = 2.0,
                        wind: str | None = None, vessel: Vessel | None = None, fitted: Envelope | None = None) -> dict:
    """Where a free run's misfit lies: the windows of `horizon_s` grouped by what their inputs ask
    (each window's most frequent of `manoeuvres`; a tie goes to the first in MANOEUVRES), and per
    group its share of the pooled misfit of u, v, r: Σ(predicted − measured)² over its predicted
    samples divided by the pooled Σ(measured − mean)² of the windows that did not blow up, so the
    shares add up to 1 − R² of those windows (`r2`; evaluate's R², unless a window diverged, when
    evaluate has none). {"windows", "diverged", "r2": {u, v, r}, "groups": {manoeuvre: {"windows",
    "diverged", "samples", "share": {u, v, r}}}}. A group's windows are its share of the time; its
    share per window says where the twin misses most. `vessel` classifies the inputs (default: the
    model when it is a Vessel; for a grey-box predictor, the vessel whose thrusters drive it);
    `wind` applies to a Vessel given as the model (a Predictor carries its own). `fitted`: what the
    twin's fit saw (coverage.Envelope); then also "fitted_on" (its dict) and "beyond_fit": the
    judged samples outside its range and the share of 1 − R² they carry (coverage.beyond), with
    "fitted_logs_judged": the judged logs named as one the fit was on, in any format (their score is
    in-sample)."""
    if isinstance(model, Vessel):
        vessel = vessel or model
        model = TwinPredictor(model, ModelCache(), wind)
    if vessel is None:
        raise TwinError("misfit_by_manoeuvre needs the vessel whose thrusters drive the predictor")
    wins = horizon_windows(preps, horizon_s, stride_s)
    out: dict = {"horizon_s": float(horizon_s), "windows": len(wins), "diverged": 0, "r2": {d: None for d in DOFS},
                 "groups": {}}
    if not wins:
        return out
    pred, meas = _predictions(model, preps, wins)
    kind = _window_manoeuvres(vessel, preps, wins)
    finite = ~np.any(np.isinf(pred[:, 1:]), axis=(1, 2))
    out["diverged"] = int(np.sum(~finite))
    sq, total = _squares(pred[:, 1:], meas[:, 1:], finite)
    out["r2"] = {d: (1.0 - float(sq[:, :, k].sum() / total[k])) if total[k] > 0 else None for k, d in enumerate(DOFS)}
    if fitted is not None:
        out["fitted_on"] = fitted.to_dict()
        # by name less its suffix: a log converted to another format (`twin convert`) is the same log
        fitted_stems = {Path(s).stem for s in fitted.sources}
        judged = [Path(p.settings.source).name for p in preps]
        own = [n for n in judged if n and Path(n).stem in fitted_stems]
        # judged beside runs the fit did not see, the fit's own windows are left out of what lies beyond
        new = np.array([not (judged[w.rec] and Path(judged[w.rec]).stem in fitted_stems) for w in wins])
        keep = new if own and new.any() else np.ones(len(wins), bool)
        sq_b, total_b = (sq, total) if keep.all() else _squares(pred[keep, 1:], meas[keep, 1:], finite[keep])
        out["beyond_fit"] = beyond(fitted, np.where(finite[keep, None, None], meas[keep, 1:], np.nan), sq_b, total_b)
        out["beyond_fit"]["fitted_logs_judged"] = own
        out["beyond_fit"]["logs_judged"] = len(judged)
        out["beyond_fit"]["of_new_logs_only"] = not keep.all()
    for i, name in enumerate(MANOEUVRES):
        if np.any(kind == i):
            sel = (kind == i) & finite
            sse = sq[sel].sum(axis=(0, 1))
            out["groups"][name] = {"windows": int(np.sum(kind == i)), "diverged": int(np.sum((kind == i) & ~finite)),
                                   "samples": int(np.isfinite(meas[sel, 1:]).any(axis=2).sum()),
                                   "share": {d: float(sse[k] / total[k]) if total[k] > 0 else None
                                             for k, d in enumerate(DOFS)}}
    return out


def _window_manoeuvres(vessel: Vessel, preps: list[Prepared], wins: list[Window]) -> np.ndarray:
    """Each window's most frequent manoeuvre code, "full" scaled on every recording judged."""
    scale = input_scale(vessel, np.vstack([p.pwm for p in preps]))
    codes = [_manoeuvre_codes(vessel, preps[w.rec].pwm[w.start:w.start + w.n + 1], scale) for w in wins]
    return np.array([np.bincount(c, minlength=len(MANOEUVRES)).argmax() for c in codes])


@dataclass(frozen=True)
class StateBand:
    """The samples of free runs whose measured state lies in one band: their share of all samples,
    each DOF's share of 1 − R² (the shares of all bands add up to 1 − R²), the RMS error (m/s, m/s,
    rad/s), the gain: the measured on the predicted value by least squares through the origin (above
    1: the twin moves less than the vessel there), and the correlation of the two. A gain away from 1
    with a correlation near 1 is the twin's own shape at the wrong size (a coefficient's magnitude); a
    low correlation is a motion the twin's form does not make."""

    label: str
    samples: float
    share: dict[str, float | None]
    rms_error: dict[str, float | None]
    gain: dict[str, float | None]
    correlation: dict[str, float | None] = field(default_factory=dict)

    def __repr__(self) -> str:
        def each(values: dict, units: bool = False) -> str:
            return ", ".join(f"{d} " + ("-" if values.get(d) is None else
                                        f"{values[d]:.3g}" + (f" {RMS_UNITS[d]}" if units else "")) for d in DOFS)
        return (f"StateBand({self.label}: {100 * self.samples:.0f} % of the samples; RMS error {each(self.rms_error, True)}; "
                f"share of 1 − R² {each(self.share)}; gain {each(self.gain)})")


RMS_UNITS = {"u": "m/s", "v": "m/s", "r": "rad/s"}  # StateBand.rms_error's


# the measured states `misfit_by_state` bands the samples by (each on the recording's grid)
STATES = ("speed_m_s", "yaw_rate_rad_s", "drift_rad", "input_0", "input_1", "input_0_rest_s")
REST_INPUT = 1.0  # |input 0| at or below this counts as at rest for input_0_rest_s (a propeller's rps)


def state_display(state: str, input_kind: str = "pwm") -> tuple[str, str, float]:
    """(what the state is, the unit its bands are shown in, the factor from its own unit to that one),
    for a recording whose inputs are `input_kind` (Prepared.input_kind): a yaw rate and a rudder
    angle in degrees, as the rest of the reports give them."""
    ship = input_kind == "propeller_rudder"
    deg = 180.0 / np.pi
    return {"speed_m_s": ("speed over ground", "m/s", 1.0), "yaw_rate_rad_s": ("|yaw rate|", "°/s", deg),
            "drift_rad": ("drift angle |β|", "°", deg),
            "input_0": ("propeller speed", "rps", 1.0) if ship else ("left thruster's PWM", "µs", 1.0),
            "input_1": ("rudder angle", "°", deg) if ship else ("right thruster's PWM", "µs", 1.0),
            "input_0_rest_s": ("time the propeller has been stopped" if ship else "time input 0 has been at rest",
                               "s", 1.0)}[state]


def recording_states(prep: Prepared) -> dict[str, np.ndarray]:
    """Per grid sample: the speed √(u² + v²) of the prepared log (m/s, over ground), |r| (rad/s), the
    drift angle |β| = |atan2(v, |u|)| (rad, 0 running straight ahead or astern, π/2 broadside; at rest
    it is the direction of the GNSS velocity's noise), the logged inputs (PWM µs; or n rps and δ rad) and for how long input 0 has been at rest (|input 0| ≤
    REST_INPUT: a propeller stopped; s, counted within the segment)."""
    rest = np.abs(prep.pwm[:, 0]) <= REST_INPUT
    held = np.zeros(len(prep.t))
    for k in range(1, len(prep.t)):
        same_segment = prep.segment[k] == prep.segment[k - 1]
        held[k] = held[k - 1] + (prep.t[k] - prep.t[k - 1]) if rest[k] and rest[k - 1] and same_segment else 0.0
    return {"speed_m_s": np.hypot(prep.u, prep.v), "yaw_rate_rad_s": np.abs(prep.r),
            "drift_rad": np.abs(np.arctan2(prep.v, np.abs(prep.u))), "input_0": prep.pwm[:, 0].astype(float), "input_1": prep.pwm[:, 1].astype(float), "input_0_rest_s": held}


def misfit_by_state(model: Predictor | Vessel, preps: list[Prepared], horizon_s: float, state: str,
                    edges: tuple[float, ...], stride_s: float = 2.0, wind: str | None = None) -> list[StateBand]:
    """Where free runs of `horizon_s` miss, by the measured state of each predicted sample.

    Args:
        model: the twin (a Vessel, run on the batch engine with `wind`) or a Predictor.
        preps: the recordings judged.
        horizon_s: the free runs' length (s), every `stride_s`.
        state: one of STATES (recording_states).
        edges: the bands' inner edges, increasing: len(edges) + 1 bands.

    Returns:
        One StateBand per band with samples, labelled "< a", "a-b", "≥ z".
    """
    if state not in STATES:
        raise TwinError(f"unknown state '{state}' (known: {', '.join(STATES)})")
    if isinstance(model, Vessel):
        model = TwinPredictor(model, ModelCache(), wind)
    wins = horizon_windows(preps, horizon_s, stride_s)
    if not wins:
        return []
    pred, meas = _predictions(model, preps, wins)
    values = np.full(meas.shape[:2], np.nan)
    per_rec = {k: recording_states(p)[state] for k, p in enumerate(preps) if any(w.rec == k for w in wins)}
    for j, w in enumerate(wins):
        values[j, : w.n + 1] = per_rec[w.rec][w.start: w.start + w.n + 1]
    finite = ~np.any(np.isinf(pred[:, 1:]), axis=(1, 2))
    sq, total = _squares(pred[:, 1:], meas[:, 1:], finite)
    paired = np.isfinite(meas[:, 1:]) & np.isfinite(pred[:, 1:]) & finite[:, None, None]
    band = np.digitize(values[:, 1:], edges)
    _, unit, factor = state_display(state, preps[0].input_kind)
    # a PWM edge in whole µs (1750, not 1.75e+03); smaller states to 3 figures
    shown = [f"{factor * e:.0f}" if abs(factor * e) >= 100 else f"{factor * e:.3g}" for e in edges]
    labels = ([f"< {shown[0]} {unit}"] + [f"{a} to {b} {unit}" for a, b in zip(shown[:-1], shown[1:])]
              + [f"≥ {shown[-1]} {unit}"])
    n_all = int(paired.any(axis=2).sum())
    out = []
    for b, label in enumerate(labels):
        sel = (band == b) & np.isfinite(values[:, 1:])
        if not sel.any():
            continue
        share, rms, gain, corr = {}, {}, {}, {}
        for k, d in enumerate(DOFS):
            ok = sel & paired[..., k]
            y, x = meas[:, 1:, k][ok], pred[:, 1:, k][ok]
            share[d] = float(sq[..., k][ok].sum() / total[k]) if total[k] > 0 else None
            rms[d] = float(np.sqrt(np.mean((x - y) ** 2))) if y.size else None
            gain[d] = float(np.dot(x, y) / np.dot(x, x)) if y.size and np.dot(x, x) > 0 else None
            corr[d] = _correlation(x, y)
        out.append(StateBand(label, float((sel & paired.any(axis=2)).sum() / max(n_all, 1)), share, rms, gain,
                             corr))
    return out


# what `twin evaluate --by` calls each state
STATE_NAMES = {"speed": "speed_m_s", "yaw_rate": "yaw_rate_rad_s", "drift": "drift_rad", "input_0": "input_0", "input_1": "input_1",
               "rest": "input_0_rest_s"}


BAND_PERCENTILES = (50, 75, 90)  # the lower half of the samples, the next quarter, the next 15 %, the top 10 %


def percentile_edges(preps: list[Prepared], state: str, label: str | None = None) -> tuple[float, ...]:
    """The inner edges that cut the recordings' samples of `state` at BAND_PERCENTILES (fewer where
    values repeat, e.g. a propeller's time at rest, mostly zero). *Why these:* a missing force shows
    at the edge of what was recorded, so the top of the range gets bands of its own. TwinError
    where the state does not vary (`label`: its name in the message)."""
    values = np.concatenate([recording_states(p)[state] for p in preps])
    values = values[np.isfinite(values)]
    edges = np.unique(np.round(np.percentile(values, BAND_PERCENTILES), 4)) if values.size else np.zeros(0)
    edges = edges[edges > values.min()] if values.size else edges
    if not edges.size:
        raise TwinError(f"{label or state}: the same in every sample of these recordings, nothing to band by")
    return tuple(float(e) for e in edges)


def _correlation(x: np.ndarray, y: np.ndarray) -> float | None:
    """Pearson's correlation of x and y; None with fewer than three pairs, either (nearly) constant, or
    values too large to correlate."""
    if x.size < 3:
        return None
    sx, sy = np.std(x), np.std(y)
    if not (sx > 1e-12 * max(np.max(np.abs(x)), 1e-300) and sy > 1e-12 * max(np.max(np.abs(y)), 1e-300)):
        return None
    with np.errstate(over="ignore", invalid="ignore"):
        c = float(np.corrcoef(x, y)[0, 1])
    return c if np.isfinite(c) else None


def format_by_state(bands: list[StateBand], title: str = "") -> str:
    """misfit_by_state's bands as rows: the band, its share of the samples, each DOF's share of
    1 − R², the gain (measured on predicted) and the correlation per DOF; ≤ 100 columns with the
    default band width."""
    width = max([16] + [len(b.label) for b in bands])
    head = (f"{'band':>{width}s}{'samples':>8s}" + "".join(f"{'share ' + d:>9s}" for d in DOFS)
            + "".join(f"{'gain ' + d:>8s}" for d in DOFS) + "".join(f"{'corr ' + d:>8s}" for d in DOFS))
    lines = ([title] if title else []) + [head, "-" * len(head)]

    def num(x, width, fmt):
        return f"{'-':>{width}s}" if x is None else f"{x:>{width}{fmt}}"

    for b in bands:
        lines.append(f"{b.label:>{width}s}{b.samples:>8.0%}" + "".join(num(b.share[d], 9, ".3f") for d in DOFS)
                     + "".join(num(b.gain[d], 8, ".2f") for d in DOFS)
                     + "".join(num(b.correlation.get(d), 8, ".2f") for d in DOFS))
    return "\n".join(lines)


def _squares(pred: np.ndarray, meas: np.ndarray, finite: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Squared errors per sample (0 where no pair or the window diverged) and the pooled Σ(y − ȳ)²
    per DOF of the measured samples paired in the finite windows (0, no share to give, where their
    spread is under metrics.RESOLUTION)."""
    pairs = np.isfinite(meas) & ~np.isnan(pred) & finite[:, None, None]
    sq = np.where(pairs, (pred - meas) ** 2, 0.0)
    total = np.zeros(3)
    for k, dof in enumerate(DOFS):
        y = meas[..., k][pairs[..., k]]
        spread = float(np.sum((y - y.mean()) ** 2)) if y.size else 0.0
        total[k] = spread if y.size and np.sqrt(spread / y.size) > RESOLUTION[dof] else 0.0
    return sq, total


def _predictions(model: Predictor, preps: list[Prepared], wins: list[Window]) -> tuple[np.ndarray, np.ndarray]:
    n_max = max(w.n for w in wins)
    pred = np.full((len(wins), n_max + 1, 3), np.nan)
    by_rec: dict[int, list[int]] = {}
    for j, w in enumerate(wins):
        by_rec.setdefault(w.rec, []).append(j)
    for rec, rows in by_rec.items():
        # windows of one length at a time, so a predictor never runs past what is asked
        for n in sorted({wins[j].n for j in rows}):
            same = [j for j in rows if wins[j].n == n]
            got = model.predict_windows(preps[rec], np.array([wins[j].start for j in same]), n)
            pred[same, : n + 1] = got[:, : n + 1]
    _, meas = measured(preps, wins)
    return pred, meas


def format_by_manoeuvre(split: dict, title: str = "") -> str:
    """misfit_by_manoeuvre's groups as rows: windows (and their share of the time), each DOF's share
    of 1 − R², ≤ 100 columns; the R² they add up to below."""
    fit = split.get("fitted_on")
    fit_windows = fit["windows"] if fit else None
    head = (f"{'manoeuvre':10s}{'windows':>9s}{'of time':>9s}" + (f"{'in fit':>8s}" if fit else "")
            + "".join(f"{'share ' + d:>10s}" for d in DOFS))
    lines = ([title] if title else []) + [head, "-" * len(head)]
    for name in MANOEUVRES:
        g = split["groups"].get(name)
        if g is not None:
            shares = ["-" if g["share"][d] is None else f"{g['share'][d]:.3f}" for d in DOFS]
            lines.append(f"{name:10s}{g['windows']:9d}{g['windows'] / split['windows']:9.0%}"
                         + (f"{fit_windows.get(name, 0):8d}" if fit else "") + "".join(f"{x:>10s}" for x in shares))
    r2 = ["-" if split["r2"][d] is None else f"{1.0 - split['r2'][d]:.3f}" for d in DOFS]
    lines.append(f"{'1 - R2':{36 if fit else 28}s}" + "".join(f"{x:>10s}" for x in r2))
    if fit:
        lines += beyond_text(split)
    if split.get("diverged"):
        lines.append(f"{split['diverged']} windows diverged: counted in their group, in no share, and R² is of the "
                     "others")
    return "\n".join(lines)


def beyond_sentence(split: dict) -> str:
    """What the fit saw and how much of the judged data lies beyond it, with its misfit, in one sentence."""
    fit, b = split["fitted_on"], split.get("beyond_fit")
    spans = span_text(fit["ranges"])
    logs = f"{fit['logs']} log{'' if fit['logs'] == 1 else 's'}"
    tail = 100 * OWN_TAIL / 2
    text = (f"in fit: {fit['horizon_s']:g}-s windows, one every {fit.get('stride_s', 2.0):g} s, of the {logs} the "
            f"twin was fitted on, whose samples span {spans} (the span leaves {tail:g} % of them out at each end)")
    if b and b["samples"]:
        own = b.get("fitted_logs_judged") or []
        all_own = len(own) >= b.get("logs_judged", len(own) + 1)  # the fit's own logs: nothing beyond is new
        shares = ", ".join(f"{d} {b['share'][d]:.3f}" for d in DOFS if b["share"][d] is not None)
        which = "the free-run samples of the judged runs the fit did not see" if b.get("of_new_logs_only") else \
            "the judged free-run samples"
        text += (f"; beyond that span: {b['share_of_samples']:.0%} of {which}, holding {shares} of their 1 − R²"
                 + ("" if all_own else " (the twin extrapolates there)"))
        scores = [f"{d} {b['r2_beyond'][d]:.2f} beyond, {b['r2_within'][d]:.2f} within" for d in DOFS
                  if (b.get("r2_beyond") or {}).get(d) is not None and (b.get("r2_within") or {}).get(d) is not None]
        if scores:
            text += "; R² " + ", ".join(scores)
        dofs = b.get("dofs", {})
        beyond_in = [f"{d} ({_percent(x['share_of_samples'])} of the samples, {_reached(d, x)})" for d, x in dofs.items()]
        if beyond_in and not all_own:
            far = [d for d, x in dofs.items() if x.get("reaches", True)]
            text += ("; the judged runs go beyond it in " + ", ".join(beyond_in)
                     + (f": record runs that reach there in {', '.join(far)} to fit it" if far else
                        f" (near its ends, and at most twice the {100 * OWN_TAIL:g} % the fit's own runs leave beyond)"))
        if own:
            text += (f"; {', '.join(own)} {'bears the name of a log' if len(own) == 1 else 'bear the names of logs'} "
                     f"the twin was fitted on: {'its score is' if len(own) == 1 else 'their scores are'} in-sample")
    return text


def _reached(dof: str, x: dict) -> str:
    """How far a DOF's judged samples go beyond the fitted span, e.g. "to +0.19 m/s"."""
    ends = [f"{SHOWN[dof] * x[k]:+.2f}" for k in ("below", "above") if x.get(k) is not None]
    return f"to {' and '.join(ends)} {UNITS[dof]}" if ends else "beyond it"


def _percent(share: float) -> str:
    return f"{share:.0%}" if share >= 0.005 or share == 0 else "under 1 %"


def beyond_text(split: dict) -> list[str]:
    """beyond_sentence as lines of at most 100 columns."""
    return textwrap.wrap(beyond_sentence(split), 100, subsequent_indent="  ")


def format_metrics(metrics: dict, title: str = "") -> str:
    """Rows per horizon, R² and MAE per DOF, ≤ 100 columns; r's MAE in °/s, as the diagnosis and the
    Python API's tables print it (the metrics themselves are SI)."""
    head = f"{'horizon':14s}" + "".join(f"{'R2 ' + d:>9s}{'MAE ' + d:>10s}" for d in DOFS)
    head += "   (MAE: u, v m/s; r °/s)"
    lines = ([title] if title else []) + [head, "-" * len(head)]
    for name, m in metrics.items():
        cells = []
        for d in DOFS:
            r2, mae = m[d]["r2"], m[d]["mae"]
            shown = None if mae is None else (math.degrees(mae) if d == "r" else mae)
            cells.append(f"{'-' if r2 is None else f'{r2:.3f}':>9s}{'-' if shown is None else f'{shown:.4f}':>10s}")
        lines.append(f"{name:14s}" + "".join(cells))
    empty = [name for name, m in metrics.items() if all(m[d].get("n") == 0 for d in DOFS)]
    if empty:  # a dash with no reason reads as a failure of the twin
        lines.append(f"-: no window of {', '.join(empty)} fits in the recording: every stretch without a dropout "
                     "(or the whole log) is shorter")
    still = [d for d in DOFS if any(m[d]["r2"] is None and m[d].get("n") and not m[d].get("diverged")
                                    and m[d]["mae"] is not None for m in metrics.values())]
    if still:
        lines.append(f"R2 -: the measured {' and '.join(still)} do{'es' if len(still) == 1 else ''} not vary beyond "
                     "what a GNSS or compass resolves (a straight run's sway): no variance to explain")
    return "\n".join(lines)
