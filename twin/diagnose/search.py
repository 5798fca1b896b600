"""Which effects explain the mismatch: candidates fitted on training windows, judged on
held-out windows, added one at a time while one still earns its place.

Round by round, from the current twin (the prior plus the effects kept so far):
1. screen every candidate cheaply: from each of its starts, one Gauss-Newton step on
   the training windows (a scan for time shifts) and the training cost there;
2. fit the most promising few fully (bounded least squares);
3. judge each fitted candidate on the held-out windows: the per-window log cost ratio
   d_w = ln(c_w(current)/c_w(candidate)) must be significantly positive (the z of a
   Wilcoxon signed-rank test > Z_MIN, the windows as independent samples; logs, because
   windows differ in misfit by orders of magnitude) and the total misfit must drop by
   more than REL_MIN (or z > Z_LARGE for a drop of over REL_LARGE);
4. keep the best, refit all kept effects jointly, repeat.

One split wastes evidence: a third of the recording judges, two thirds only fit. A
candidate that looks promising on it but falls short of significance (z ≥ Z_PROMISING,
more than REL_MIN removed) is therefore refitted on the training part of each other
fold (blocks rotated, so that every window is held out exactly once) and judged on the
pooled held-out windows of all folds: about √3 times the z of one fold for a real
effect, and the same false-alarm rate for none, since every window is still judged by
a fit that did not see it. (After a first effect is kept, the other folds' base twin
carries that effect as fitted on the first fold's training windows, which include
theirs: their base looks better than it is, so the test errs on the cautious side.)

A candidate that does nearly as well on held-out data as the one kept (paired z of
their held-out costs < Z_SEPARABLE) is reported as not separable from it by this
recording. Uncertainty: the cluster-robust (sandwich) covariance of the joint fit,
windows as clusters, as in identification.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import wilcoxon

from ..errors import TwinError
from ..effects import Candidate
from ..fit.objective import Measurements, Objective, cluster_covariance
from ..fit.windows import ModelCache, Window
from ..vessel import Vessel

Z_MIN = 3.0  # one-sided p ≈ 0.001 per test: with ~20 candidates a round, about 2 % false alarms
REL_MIN = 0.02  # an effect that removes less than 2 % of the held-out misfit is not worth a parameter
# A large effect judged on few held-out windows: noise alone does not remove a sixth of the
# held-out misfit (null recordings: under 3 %), so a smaller z suffices there.
Z_LARGE, REL_LARGE = 2.0, 0.15
Z_PROMISING = 1.0  # worth the other folds' evidence
Z_SEPARABLE = 3.0  # a rival is told apart only when held-out data prefer the winner clearly
FULL_FITS = 3  # candidates fitted fully per round, after screening
SCREEN_WINDOWS = 32  # screening sees at most this many training windows, spread over the recording
# a candidate's own fit sees at most this many (spread): enough to fit two or three numbers; the
# kept effects' joint fit and every held-out judgement use all windows
REFINE_WINDOWS = 48
MAX_EFFECTS = 5


@dataclass
class Fitted:
    """A candidate fitted on the training windows, from the vessel `base`."""

    candidate: Candidate
    values: dict[str, float]
    vessel: Vessel
    train_cost: float
    held: np.ndarray | None = None  # per held-out window cost (first fold)
    folds: int = 1  # how many folds z, rel and dof_rel pool
    z: float = 0.0
    rel: float = 0.0
    dof_rel: dict[str, float] = field(default_factory=dict)


@dataclass
class Kept:
    fitted: Fitted
    rivals: list[dict]
    improvement: dict[str, float]


class Search:
    def __init__(self, prior: Vessel, data: Measurements, train: list[Window], held: list[Window],
                 cache: ModelCache, library: dict[str, Candidate], log=None,
                 other_folds: list[tuple[list[Window], list[Window]]] = (), screen_cache: ModelCache | None = None):
        """train, held: the first fold, which fits every effect kept; other_folds: more
        (train, held) splits of the same windows, for the pooled judgement; screen_cache:
        models at a coarser step for screening the candidates that are not scanned."""
        self.prior, self.data, self.train, self.held, self.cache = prior, data, train, held, cache
        self.screen_cache = screen_cache or cache
        self._screen_costs: dict = {}  # "base": the round's base twin; id(cache): its screening cost
        self.other_folds = list(other_folds)
        self._fold_base: dict = {}  # "base": the round's base twin; fold: its held-out costs there
        self.screening = _spread(train, SCREEN_WINDOWS)
        self.library = library
        self.log = log or (lambda msg: None)
        self.evaluations = 0
        self.values: dict[str, float] = {}
        self.sigma: dict[str, float | None] = {}
        self.cov: np.ndarray | None = None
        self.cov_names: list[str] = []

    # ------------------------------------------------------------ costs

    def _objective(self, base: Vessel, params, windows, cache: ModelCache | None = None) -> Objective:
        return Objective(base, list(params), self.data, windows, cache or self.cache)

    def held_costs(self, vessels: list[Vessel], held: list[Window] | None = None
                   ) -> list[tuple[np.ndarray, np.ndarray]]:
        """Per held-out window cost and per-DOF squared residual sums, for each vessel
        (on the first fold's held-out windows unless `held` is given)."""
        held = self.held if held is None else held
        obj = self._objective(self.prior, [], held)
        res = obj.residuals_of(vessels)
        self.evaluations += obj.evaluations * len(held)
        idx = obj.window_index()
        dof = np.broadcast_to(np.arange(3), obj.meas.shape)[obj.valid]
        out = []
        for r in res:
            out.append((np.bincount(idx, r * r, minlength=len(held)), np.bincount(dof, r * r, minlength=3)))
        return out

    # ------------------------------------------------------------ one candidate

    def screen(self, base: Vessel, cand: Candidate) -> list[Fitted]:
        """Cheap look on a spread subset of the training windows: a scan, or one Gauss-Newton
        step from each start."""
        obj = self._objective(base, cand.params, self.screening, self.cache if cand.time_shift else self.screen_cache)
        out = []
        base_cost = self._screen_base(base, obj.cache)
        if cand.scan:
            lo, hi = obj.bounds()
            xs = [np.clip(np.array(v, float) / obj.scale, lo, hi) for v in cand.scan]
            costs = [float(np.sum(r * r)) for r in obj.residuals_of([obj.vessel(x) for x in xs])]
            out.append(self._fitted(cand, obj, xs[_plateau_middle(costs)], min(costs)))
        else:
            starts = [np.clip(np.array(start, float) / obj.scale, *obj.bounds()) for start in cand.starts]
            if len(starts) > 1:  # one step, from the start the data like best
                costs = [float(np.sum(r * r)) for r in obj.residuals_of([obj.vessel(x) for x in starts])]
                starts = [starts[int(np.argmin(costs))]]
            for x0 in starts:
                J = obj.jacobian(x0)
                r0 = obj.residuals(x0)
                step = np.linalg.lstsq(J, -r0, rcond=None)[0]
                trials = [np.clip(x0 + f * step, *obj.bounds()) for f in (1.0, 0.5, 0.25)]
                costs = [float(np.sum(r * r)) for r in obj.residuals_of([obj.vessel(x) for x in trials])]
                best = int(np.argmin(costs))  # a short line search: one linearised step can overshoot
                c0 = float(np.sum(r0 ** 2))
                out.append(self._fitted(cand, obj, trials[best] if costs[best] < c0 else x0, min(c0, costs[best])))
        self.evaluations += obj.evaluations * len(self.screening)
        for f in out:  # relative to the base twin at the same step, so both steps rank together
            f.train_cost /= base_cost
        return out

    def _screen_base(self, base: Vessel, cache: ModelCache) -> float:
        """The base twin's cost on the screening windows at this cache's step (kept per round)."""
        if self._screen_costs.get("base") is not base:  # a new round: its base twin
            self._screen_costs = {"base": base}
        if id(cache) not in self._screen_costs:
            r = self._objective(base, [], self.screening, cache).residuals_of([base])[0]
            self._screen_costs[id(cache)] = max(float(np.sum(r * r)), 1e-300)
        return self._screen_costs[id(cache)]

    def refine(self, base: Vessel, fitted: Fitted, train: list[Window] | None = None) -> Fitted:
        """Bounded least squares from the screened point (a scanned candidate: finer scans),
        on the first fold's training windows unless `train` is given."""
        cand = fitted.candidate
        train = _spread(self.train if train is None else train, REFINE_WINDOWS)
        obj = self._objective(base, cand.params, train)
        x0 = np.array([fitted.values[n] for n in cand.names]) / obj.scale
        if cand.scan:
            x, cost = self._coordinate_scans(obj, cand, x0)
            best = self._fitted(cand, obj, x, cost)
        else:
            sol = least_squares(obj.residuals, np.clip(x0, *obj.bounds()), jac=obj.jacobian, bounds=obj.bounds(),
                                method="trf", x_scale="jac", max_nfev=6, xtol=1e-5, ftol=1e-5)
            best = self._fitted(cand, obj, sol.x, float(np.sum(sol.fun ** 2)))
        self.evaluations += obj.evaluations * len(train)
        return best

    @staticmethod
    def _coordinate_scans(obj: Objective, cand: Candidate, x0: np.ndarray) -> tuple[np.ndarray, float]:
        """Each parameter in turn on a grid of scan steps around the best point so far:
        one sweep of ±6 steps for one parameter; two sweeps of ±4 otherwise (the edges of
        a dead zone interact only through the few samples near both)."""
        lo, hi = obj.bounds()
        half, sweeps = (6, 1) if len(x0) == 1 else (4, 2)
        x, cost = x0.copy(), float("inf")
        for _ in range(sweeps):
            for i, step in enumerate(cand.scan_step):
                values = x[i] + np.arange(-half, half + 1) * step / obj.scale[i]
                values = values[(values >= lo[i] - 1e-12) & (values <= hi[i] + 1e-12)]
                trials = [np.where(np.arange(len(x)) == i, v, x) for v in values]
                costs = [float(np.sum(r * r)) for r in obj.residuals_of([obj.vessel(t) for t in trials])]
                k = _plateau_middle(costs)
                x, cost = trials[k], costs[k]
        return x, cost

    @staticmethod
    def _fitted(cand: Candidate, obj: Objective, x: np.ndarray, cost: float) -> Fitted:
        values = {p.name: float(xi * s) for p, xi, s in zip(cand.params, x, obj.scale)}
        return Fitted(cand, values, obj.vessel(x), cost)

    # ------------------------------------------------------------ rounds

    def round(self, base: Vessel, base_held: tuple[np.ndarray, np.ndarray], skip: set[str]) -> list[Fitted]:
        """Every remaining candidate screened, the best few fitted and judged on held-out data,
        best first."""
        screened = []
        for name, cand in self.library.items():
            if name in skip:
                continue
            try:
                screened.append(min(self.screen(base, cand), key=lambda f: f.train_cost))
            except TwinError as exc:
                self.log(f"candidate {name} skipped: {exc}")
        screened.sort(key=lambda f: f.train_cost)
        best = [self.refine(base, f) for f in screened[:FULL_FITS]]
        judged = self.held_costs([f.vessel for f in best])
        for f, (per_window, per_dof) in zip(best, judged):
            f.held = per_window
            _judge(f, [base_held], [(per_window, per_dof)])
            if self.other_folds and not _earns_its_place(f) and f.z >= Z_PROMISING and f.rel > REL_MIN:
                self._pool(base, base_held, f, per_dof)
        return sorted(best, key=lambda f: f.rel, reverse=True)

    def _pool(self, base: Vessel, base_held, f: Fitted, per_dof: np.ndarray) -> None:
        """z, rel and dof_rel of `f` over the held-out windows of every fold (module docstring)."""
        bases, cands = [base_held], [(f.held, per_dof)]
        if self._fold_base.get("base") is not base:
            self._fold_base = {"base": base}
        for k, (train, held) in enumerate(self.other_folds):
            if k not in self._fold_base:
                self._fold_base[k] = self.held_costs([base], held)[0]
            refit = self.refine(base, f, train)
            bases.append(self._fold_base[k])
            cands.append(self.held_costs([refit.vessel], held)[0])
        _judge(f, bases, cands)
        f.folds = len(bases)
        self.log(f"{f.candidate.name}: pooled over {f.folds} folds: z = {f.z:.2f}, held-out misfit "
                 f"{-100 * f.rel:+.1f} %")

    def joint(self, kept: list[Fitted]) -> tuple[Vessel, dict, dict]:
        """All kept effects refitted together from their values: the vessel, values and 1-σ."""
        params = [p for f in kept for p in f.candidate.params]
        base = self.prior
        obj = self._objective(base, params, self.train)
        x0 = np.clip(np.array([f.values[p.name] for f in kept for p in f.candidate.params]) / obj.scale,
                     *obj.bounds())
        sol = least_squares(obj.residuals, x0, jac=obj.jacobian, bounds=obj.bounds(), method="trf", x_scale="jac",
                            max_nfev=20, xtol=1e-7, ftol=1e-7)
        J = obj.jacobian(sol.x)
        cov = cluster_covariance(J, obj.residuals(sol.x), obj.window_index())
        self.evaluations += obj.evaluations * len(self.train)
        names = [f"{f.candidate.name}.{p.name}" for f in kept for p in f.candidate.params]
        values = {n: float(x * s) for n, x, s in zip(names, sol.x, obj.scale)}
        self.cov = None if cov is None else cov * np.outer(obj.scale, obj.scale)  # value units
        self.cov_names = names
        sigma = {n: (float(np.sqrt(self.cov[i, i])) if self.cov is not None and self.cov[i, i] >= 0 else None)
                 for i, n in enumerate(names)}
        return obj.vessel(sol.x), values, sigma

    def run(self) -> tuple[Vessel, list[Kept], list[dict]]:
        """Forward selection (module docstring). Returns the amended vessel, the kept effects
        and the record of every round."""
        current = self.prior
        base_held = self.held_costs([current])[0]
        kept: list[Kept] = []
        rounds: list[dict] = []
        for _ in range(MAX_EFFECTS):
            tried = self.round(current, base_held, {k.fitted.candidate.name for k in kept})
            rounds.append({"candidates": [{"name": f.candidate.name, "z": round(f.z, 2), "rel": round(f.rel, 4),
                                           "folds": f.folds, "values": f.values} for f in tried]})
            winner = next((f for f in tried if _earns_its_place(f)), None)
            if winner is None:
                break
            self.log(f"kept {winner.candidate.name}: held-out misfit −{100 * winner.rel:.1f} % (z = {winner.z:.1f})")
            kept.append(Kept(winner, self._rivals(winner, tried), winner.dof_rel))
            current, self.values, self.sigma = self.joint([k.fitted for k in kept])
            for k, f in zip(kept, self._split_values(kept, current)):
                k.fitted.values = f
            base_held = self.held_costs([current])[0]
        return current, kept, rounds

    def _rivals(self, winner: Fitted, tried: list[Fitted]) -> list[dict]:
        out = []
        for f in tried:
            if f is winner or f.held is None or f.rel < 0.5 * winner.rel:
                continue
            z = _paired_z(f.held, winner.held)
            out.append({"name": f.candidate.name, "z": round(z, 2), "separable": bool(z > Z_SEPARABLE),
                        "held_out_gain": round(f.rel, 4), "values": f.values,
                        "parameters": dict(f.candidate.to_effect(f.values).params)})
        return out

    @staticmethod
    def _split_values(kept: list[Kept], vessel: Vessel) -> list[dict]:
        return [{p.name: float(p.get(vessel)) for p in k.fitted.candidate.params} for k in kept]


def _spread(windows: list[Window], most: int) -> list[Window]:
    """At most `most` of the windows, evenly spread over the recording."""
    return windows[::max(1, int(np.ceil(len(windows) / most)))]


def _judge(f: Fitted, bases: list[tuple[np.ndarray, np.ndarray]],
           cands: list[tuple[np.ndarray, np.ndarray]]) -> None:
    """z, rel and dof_rel of `f` from (per window, per DOF) held-out costs of the base twin and
    of the candidate, one pair per fold, pooled."""
    base_w = np.concatenate([b[0] for b in bases])
    cand_w = np.concatenate([c[0] for c in cands])
    base_d, cand_d = sum(b[1] for b in bases), sum(c[1] for c in cands)
    f.z = _paired_z(base_w, cand_w)
    f.rel = float(np.sum(base_w - cand_w) / max(np.sum(base_w), 1e-12))
    f.dof_rel = {k: float((base_d[i] - cand_d[i]) / max(base_d[i], 1e-12)) for i, k in enumerate("uvr")}


def _earns_its_place(f: Fitted) -> bool:
    return (f.z > Z_MIN and f.rel > REL_MIN) or (f.z > Z_LARGE and f.rel > REL_LARGE)


def _plateau_middle(costs: list[float]) -> int:
    """Index of the middle of the run of equal lowest costs: a time shift finer than the
    engine step cannot change the cost, so the best estimate is the plateau's centre."""
    c = np.asarray(costs)
    best = int(np.argmin(c))
    flat = np.abs(c - c[best]) <= 1e-9 * max(abs(c[best]), 1e-30)
    lo = hi = best
    while lo > 0 and flat[lo - 1]:
        lo -= 1
    while hi < len(c) - 1 and flat[hi + 1]:
        hi += 1
    return (lo + hi) // 2


def _paired_z(worse: np.ndarray, better: np.ndarray) -> float:
    """z of the Wilcoxon signed-rank test of the per-window log cost ratios ln(worse/better)
    (> 0: `better` is better).

    Ranks, not a mean over its standard error: an effect that acts only in some regimes
    (a dead zone, a lag after input steps) leaves the other windows' costs exactly as
    they were, and its gains are heavy-tailed; zeros carry no evidence and are dropped,
    and one window's large gain cannot outvote many small losses."""
    d = np.log(np.maximum(worse, 1e-12) / np.maximum(better, 1e-12))
    d = d[np.abs(d) > 1e-9]
    if len(d) < 2:
        return 0.0
    return float(wilcoxon(d, zero_method="wilcox", alternative="greater", method="approx").zstatistic)
