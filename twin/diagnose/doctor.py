"""`twin diagnose`: where the twin and a recording disagree, which physics is missing,
how much of it, and the amended twin, judged on data it did not fit.

1. Replay: the twin over 10-s free-run windows from measured states, driven by the
   recorded PWM; the windows are split by time blocks into training (2/3) and
   held-out (1/3) sets. The noise of every signal is estimated so that "significant"
   has a scale.
2. Locate: where the held-out residual concentrates (DOF, time, operating regime),
   whether it grows along a free run (dynamics) or is there from the start
   (measurement), and what it correlates with (locate.py).
3. Explain: candidate effects fitted on the training windows, kept only if they cut
   the held-out misfit significantly, one at a time, rivals checked (search.py).
4. Model it: the amended vessel description, fit before and after on held-out
   windows, per DOF.
5. Honesty: what stays significant after the amendment is reported as unexplained,
   with where it is, how big, and which signals it follows.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..effects import candidates
from ..engine.mjcf import compile_vessel
from ..errors import TwinError
from ..fit.metrics import r2_mae
from ..physics.sensors import log_name
from ..fit.objective import Measurements
from ..fit.windows import ModelCache, Window, comfortable_timestep, make_windows, measured, predict
from ..prepare import Prepared
from ..recording import Recording
from ..fit.calibrate import prepare_for
from ..vessel import Vessel
from . import locate as loc
from .noise import estimate_noise
from .search import Search

WINDOW_S = 10.0
BLOCK_WINDOWS = 3  # held-out blocks of 3 windows (30 s): long enough that a block is not its neighbours' copy
GNSS_WINDOW_S, HEADING_WINDOW_S = 1.0, 0.5
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

    def to_dict(self) -> dict:
        return {"vessel": self.prior.name, "effects": self.effects, "located": self.located, "growth": self.growth,
                "correlations": self.correlations, "fit_before": self.fit_before, "fit_after": self.fit_after,
                "unexplained": self.unexplained, "overall": self.overall, "noise": self.noise, "rounds": self.rounds,
                "windows": self.windows, "seconds": round(self.seconds, 1), "notes": self.notes}


def split_windows(preps: list[Prepared], window_s: float = WINDOW_S) -> tuple[list[Window], list[Window]]:
    """Non-overlapping windows; every third block of BLOCK_WINDOWS windows is held out."""
    return folds(preps, window_s)[0]


def folds(preps: list[Prepared], window_s: float = WINDOW_S) -> list[tuple[list[Window], list[Window]]]:
    """Non-overlapping windows in blocks of BLOCK_WINDOWS, dealt to three folds in turn;
    (training, held-out) for each fold, the fold of the second block of every three first."""
    wins = make_windows(preps, window_s, window_s, min_length_s=window_s)
    out = []
    for fold in (1, 0, 2):
        train, held = [], []
        for k, w in enumerate(wins):
            (held if (k // BLOCK_WINDOWS) % 3 == fold else train).append(w)
        out.append((train, held))
    if len(out[0][1]) < 3 or len(out[0][0]) < 3:
        raise TwinError(f"the recording gives {len(wins)} windows of {window_s:g} s: too short to fit on one part "
                        "and judge on another (a diagnosis needs about 2 minutes of data with PWM)")
    return [(t, h) for t, h in out if len(h) >= 3 and len(t) >= 3]


def diagnose(recordings: list[Recording], prior: Vessel, *, window_s: float = WINDOW_S, log=None,
             library: list[str] | None = None) -> Diagnosis:
    """The whole diagnosis (module docstring); `library` restricts the candidates by name."""
    started = time.time()
    log = log or (lambda msg: None)
    compiled = compile_vessel(prior)
    kwargs = {"window_s": GNSS_WINDOW_S, "heading_window_s": HEADING_WINDOW_S}
    for rec in recordings:
        if not len(rec.pwm):
            raise TwinError(f"{rec.source}: no thruster PWM: the twin cannot be replayed without its inputs")
    preps = [prepare_for(r, compiled, **kwargs) for r in recordings]
    data = Measurements(preps, recordings, compiled, kwargs)
    (train, held), *other_folds = folds(preps, window_s)
    noise = _noise(recordings, preps)
    exact = ModelCache()
    every = train + held  # locating fits nothing: every window may speak
    before = _residuals(prior, preps, every, exact)
    located, growth, corr, overall = _locate(before, preps, every, noise)
    log(f"replayed {len(train) + len(held)} windows of {window_s:g} s ({len(held)} held out); "
        f"{len(located)} significant residual regions")
    lib = candidates(prior, [log_name(r.source) for r in recordings])
    if library:
        unknown = set(library) - set(lib)
        if unknown:
            raise TwinError(f"unknown effect(s) {', '.join(sorted(unknown))} (known: {', '.join(lib)})")
        lib = {k: v for k, v in lib.items() if k in library}
    search = Search(prior, data, train, held, ModelCache(SEARCH_TIMESTEP_S), lib, log, other_folds,
                    screen_cache=ModelCache(comfortable_timestep(compiled, preps, SCREEN_H_LAMBDA, SEARCH_TIMESTEP_S)))
    amended, kept, rounds = search.run()
    amended_preps = data.for_vessel(amended)
    after = _residuals(amended, amended_preps, every, exact)
    after_located, _, after_corr, after_overall = _locate(after, amended_preps, every, noise)
    n_train = len(train)
    diagnosis = Diagnosis(
        prior, amended, _effects(kept, search), located, growth, corr, _fit(_part(before, n_train)),
        _fit(_part(after, n_train)), _unexplained(after_located, after_corr, after_overall), noise, rounds,
        {"length_s": window_s, "train": len(train), "held_out": len(held)}, time.time() - started)
    diagnosis.overall = {"before": overall, "after": after_overall}
    diagnosis.replay = {"windows": every, "preps": preps, "amended_preps": amended_preps, "before": before,
                        "after": after, "held_from": n_train}
    if not kept:
        diagnosis.notes.append("no candidate effect improves the held-out fit significantly")
    return diagnosis


# ---------------------------------------------------------------- pieces

def _noise(recordings: list[Recording], preps: list[Prepared]) -> dict:
    per = [estimate_noise(r, p) for r, p in zip(recordings, preps)]
    keys = [k for k, v in per[0].items() if isinstance(v, (int, float))]
    return {k: float(np.median([p[k] for p in per])) for k in keys} | {"method": per[0].get("method", "")}


@dataclass
class _Replay:
    pred_nu: np.ndarray
    pred_eta: np.ndarray
    meas_nu: np.ndarray
    meas_eta: np.ndarray


def _residuals(vessel: Vessel, preps: list[Prepared], windows: list[Window], cache: ModelCache) -> _Replay:
    pred = predict(vessel, preps, windows, cache)[0]
    eta, nu = measured(preps, windows)
    return _Replay(pred.nu, pred.eta, nu, eta)


def _part(rep: _Replay, start: int) -> _Replay:
    """The held-out windows (they follow the training ones in `every`)."""
    return _Replay(rep.pred_nu[start:], rep.pred_eta[start:], rep.meas_nu[start:], rep.meas_eta[start:])


def _fit(rep: _Replay) -> dict:
    return r2_mae(rep.pred_nu[:, 1:], rep.meas_nu[:, 1:])


def _context(preps: list[Prepared], windows: list[Window], n: int) -> tuple[dict, np.ndarray, np.ndarray]:
    """Per compared sample: the context signals locate.py bins by, the window id, time in window."""
    cols = {k: [] for k in ("u_m_s", "v_m_s", "r_rad_s", "heading_deg", "region", "pwm_mean_us", "pwm_diff_us",
                            "since_input_step_s", "near_zero_pwm", "run_time_s", "time_in_window_s",
                            "recording", "segment")}
    win, tiw = [], []
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
        cols["segment"].append(p.segment[idx])
        win.append(np.full(n, j))
        tiw.append(np.arange(1, n + 1) * h)
    return {k: np.concatenate(v) for k, v in cols.items()}, np.concatenate(win), np.concatenate(tiw)


def _locate(rep: _Replay, preps, windows, noise) -> tuple[list[dict], dict, dict, dict]:
    res_w = rep.pred_nu[:, 1:] - rep.meas_nu[:, 1:]
    n = res_w.shape[1]
    context, window, tiw = _context(preps, windows, n)
    res = res_w.reshape(-1, 3)
    sd = np.array([noise.get("u", np.nan), noise.get("v", np.nan), noise.get("r", np.nan)])
    located = loc.locate(res, sd, window, context)
    growth = loc.growth(res_w, tiw[:n], sd)
    psi = np.radians(context["heading_deg"])
    signals = {"u": context["u_m_s"], "v": context["v_m_s"], "r": context["r_rad_s"], "|r|": np.abs(context["r_rad_s"]),
               "sin ψ": np.sin(psi), "cos ψ": np.cos(psi), "pwm mean": context["pwm_mean_us"],
               "pwm diff": context["pwm_diff_us"], "u·r": context["u_m_s"] * context["r_rad_s"],
               "run time": context["run_time_s"], "time in window": context["time_in_window_s"]}
    return located, growth, loc.correlations(res, window, signals), loc.overall(res, sd, window)


def _effects(kept, search: Search) -> list[dict]:
    out = []
    for k in kept:
        f = k.fitted
        names = [f"{f.candidate.name}.{p.name}" for p in f.candidate.params]
        values = {p.name: search.values.get(n, f.values[p.name]) for p, n in zip(f.candidate.params, names)}
        eff = f.candidate.to_effect(values)
        ci = _effect_ci(f.candidate, values, names, search)
        out.append({"name": f.candidate.name, "parameters": dict(eff.params), "ci": ci, "text": eff.text,
                    "fitted": values, "fitted_sigma": {p.name: search.sigma.get(n) for p, n in
                                                       zip(f.candidate.params, names)},
                    "improvement": {d: round(v, 4) for d, v in k.improvement.items()},
                    "held_out_gain": round(f.rel, 4), "z": round(f.z, 2), "rivals": k.rivals,
                    "separable": all(r["separable"] for r in k.rivals)})
    return out


def _effect_ci(cand, values: dict, names: list[str], search: Search) -> dict:
    """95 % intervals of the effect's own parameters by the delta method through to_effect."""
    if search.cov is None:
        return {}
    idx = [search.cov_names.index(n) for n in names]
    cov = search.cov[np.ix_(idx, idx)]
    base = cand.to_effect(values).params
    keys = list(base)
    J = np.zeros((len(keys), len(names)))
    for j, p in enumerate(cand.params):
        h = max(1e-6, 1e-4 * max(1.0, abs(values[p.name])))
        moved = cand.to_effect({**values, p.name: values[p.name] + h}).params
        for i, key in enumerate(keys):
            d = moved[key] - base[key]
            if "dir" in key:  # an angle: the short way round
                d = (d + 180.0) % 360.0 - 180.0
            J[i, j] = d / h
    var = np.einsum("ij,jk,ik->i", J, cov, J)
    return {key: [base[key] - 1.96 * float(np.sqrt(max(v, 0.0))), base[key] + 1.96 * float(np.sqrt(max(v, 0.0)))]
            for key, v in zip(keys, var)}


def _unexplained(located: list[dict], corr: dict, overall: dict) -> list[dict]:
    """Regions still significant after the amendment, well above the noise, with what they follow;
    and a DOF whose whole residual is still far above its noise."""
    out = []
    for dof, o in overall.items():
        if (o.get("rms_over_noise") or 0) > 3.0:
            follows = [c for c in corr.get(dof, []) if abs(c.get("r", 0)) > 0.3][:3]
            out.append({"dimension": "all", "bin": "every window", "dof": dof, "rms": o["rms"], "bias": o["bias"],
                        "rms_over_noise": o["rms_over_noise"], "z": o.get("z_bias"), "correlates_with": follows})
    for e in located:
        if e.get("z", 0) >= 3.0 and (e.get("rms_over_noise") or 0) > 1.5:
            follows = [c for c in corr.get(e["dof"], []) if abs(c.get("r", 0)) > 0.3][:3]
            out.append({**e, "correlates_with": follows})
    return out[:10]
