"""Which effects explain the mismatch: candidates fitted on some of the data, judged on the rest,
kept only while each earns its place, and dropped again when it no longer does.

The evidence respects how the data hang together. Windows (10-s free runs) are grouped in
blocks of BLOCK_WINDOWS consecutive windows of one log (30 s: long enough that a block is not
its neighbours' copy); the blocks are dealt to FOLDS folds in turn, and every candidate is fitted
on the other folds and judged on each fold's blocks, so every block is judged once by a fit that
did not see it. The unit of evidence is the block, not the window: the windows of one block
share their conditions and would inflate the count. A block votes with the relative change of
the misfit of its AFFECTED windows only: those in which the candidate moves the residual by more
than AFFECT_SIGMA noise σ, RMS over u, v and r each in its own noise (_moved). Idle windows where both
twins agree do not vote, so a mostly idle log neither dilutes a real effect nor lets noise decide.
The test is the Wilcoxon signed-rank test [Wilcoxon-1945] of the blocks' votes (one-sided, z).

A candidate earns its place when z ≥ Z_MIN AND it removes at least REL_EXCESS of the held-out
misfit IN EXCESS OF THE NOISE (the misfit a perfect twin would still show, from the noise
estimated in the recording). Measured against the excess, not against the noise alone: when the
twin's form is wrong, many candidates remove a little of that wrong form's misfit on held-out
data too, and such small shares are what compensating terms look like. Nor does a candidate
whose fit ends on an unphysical edge of its range on every fold (a coefficient ×20 or ×0.05 of the
prior, a wind's side force beyond a flat plate's: at_unphysical_edge): the data then want more of it
than any vessel has, which is how a term
standing in for another form shows; the report says the form is off where it acts. The best
candidate that earns its place is kept, every kept effect is refitted together (per fold), and each kept effect
is checked again: put back to the prior, does the fit get significantly worse (z ≥ Z_MIN on the
blocks)? An effect that no longer earns its place is dropped (backward elimination): a term that
compensated for a wrong form gives way once the right form is in.

Which candidates a round judges: each remaining one is first screened (its scan, or
SCREEN_STEPS Gauss-Newton steps, on at most SCREEN_WINDOWS of the first fold's training windows)
and ranked by the cost those steps reach on at most SCREEN_WINDOWS of that fold's held-out windows, relative to
the base twin's there. Ranked by the cost on the windows the step fitted, a candidate with more
quantities ranks first for the freedom alone (three damping scales take up noise and form error a
single thrust scale cannot), and the effect the recording holds may not be judged at all. Two
steps, not one: a free run's answer to a large effect is far from linear in it (a thrust loss
with speed of 3.2 reached in one step nearly three times the cost of two, and ranked fifth). The
first FULL_FITS are fitted on every fold and judged as above, and beside them the
best earth-fixed candidate (a current, a wind: acts_on "environment") where none of them is one and
no earth-fixed effect is kept yet (once one is, the others compete as every candidate does).
A twin's form error beyond its own runs moves with the hull, so a hull or thrust term takes part of
it up in screening and ranks first whatever else the logs hold, while an effect that acts by the
heading is one the form error cannot stand in for. A library of at most JUDGED_WHOLE candidates is
judged whole. A fold's fit starts from the screened point, but for a scanned candidate (a time shift, a
dead zone) its coarse grid is scanned again on the fold's own training windows: its fine scans reach a
step or so around their start, and the screening windows are the other folds' held-out ones, whose
blocks would then have chosen the value they judge. The screening leader's near ties are not judged
as well: more near-equal stand-ins give one of them more chances to be preferred by chance (the
evidence: docs/method/decisions.md).

Every cost is a sum of squared residuals, each DOF's in units of a scale of its own (dof_scale). For
a twin identified on other runs (it carries its form error), the scale is what its residual on the
recordings diagnosed is, √(noise² + its RMS misfit there), so that every DOF costs about as much per
sample: on runs beyond a twin's own, a DOF it predicts poorly (a catamaran's sway, at R² 0.1-0.2 on
the BlueBoat's most active runs) would otherwise carry most of every cost, and a block's vote would
follow that DOF's misfit, which no candidate removes, rather than the DOFs where an effect shows. For
a prior (no form error) the scale is the spread of each measured signal.

When nothing earns its place but the misfit stays well above the noise, the diagnosis says that
the twin's form is off (doctor.py: where, how much, what it follows) instead of naming small
compensating effects.

With a CORE (`twin diagnose --refit GROUPS`), the twin's own coefficients of those identification
groups (fit/simfit.coordinates: the vessel's beliefs about each) are refitted with every candidate,
maximum a posteriori, on the same training windows, and the base each candidate is judged against
is the core refitted alone on them. A candidate then competes with the twin as the data would
identify it, not with an untuned twin whose coefficients are off by factors: judged against an
untuned twin, every small effect competes with that, and an effect the core then refits away
(it only stood in for a wrong coefficient) gains nothing. Candidates with a quantity the core already
moves (a damping scale when the damping is refitted) are not offered: the core's refit would write
over it. Every fit with the core (alone, with a candidate, with the kept effects) sees all of the
fold's training windows and the same number of solver steps (CORE_NFEV), so a candidate gains
nothing from a better-fitted core; screening compares a candidate's steps with the core's
own steps on the same windows. Scanned candidates (time
shifts, dead zones) are scanned with the core held, then the core is refitted around the scanned
value; backward elimination refits the core without the effect put back.

A constant thrust scale (thrust_gain) is judged beside the thrust loss with advance speed
(thrust_speed_loss) whenever it is judged at all, and where it wins but, refitted on each fold's
faster half of the training windows, wants at least SPEED_SHARE less thrust than on the slower half
on every fold, the loss with speed is kept in its place if it earns its place itself: a thrust that
falls with speed is what such a scale stands in for, and the speed dependence is what tells them apart.

A candidate that does nearly as well as the one kept (the blocks' votes between the two: z <
Z_SEPARABLE) is reported as not separable from it by this recording. Which of two such candidates
is kept, of those that earn their place: the one the blocks lean to (z ≥ Z_PREFER between the
two); where they lean to neither, the one with fewer quantities; at equal numbers, the round's
winner (the larger share of the held-out excess). A constant thrust scale so chosen is checked for
a loss with speed as a winner is. Two effects that explain the same misfit gain nearly the same over the
pooled windows, and the pooled sum then decides on a few windows' worth, where a term of three
quantities takes up more of the noise than one of one: a thrust scale of 0.83 lost to a linear
damping that scaled Xu ×5.6, Yv ×1.5 and Nr ×1.6 (blocks between the two z 0.14). The blocks' vote is
the test the rule trusts everywhere else, and the fewer quantities the reading that claims less
where the recording cannot tell. The blocks' lean was chosen on the
diagnosis proof's library recordings (docs/results/diagnosis_proof.md): wherever the kept effect was the truth's, its rivals had
z ≥ −0.7; the rivals at z ≤ −1.8 were the truth beside a stand-in (a u³ drag kept as
thrust_speed_loss, z −1.8; a slew limit kept as input_delay, z −2.7) or nearer it (input_delay
rather than added mass for a slew limit, z −2.0). Uncertainty: the
cluster-robust (sandwich) covariance of the final joint fit on all windows, windows as clusters.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields, is_dataclass, replace

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import norm, wilcoxon

from ..effects import EFFECTS, Candidate
from ..errors import TwinError
from ..fit.objective import Measurements, Objective, cluster_covariance
from ..fit.windows import ModelCache, Window
from ..physics.sensors import log_name
from ..vessel import Vessel

Z_MIN = 3.0  # one-sided p ≈ 0.0013 per test over the blocks
REL_EXCESS = 0.05  # share of the held-out misfit above the noise a term must remove
Z_SEPARABLE = 3.0  # a rival is told apart only when the blocks prefer the winner clearly
Z_PREFER = 1.5  # a rival the blocks prefer this much (one-sided p ≈ 0.07) is kept instead (module docstring)
AFFECT_SIGMA = 0.5  # a window votes when the candidate moves its residuals by this many noise σ (RMS)
BLOCK_WINDOWS = 3
FOLDS = 3
FULL_FITS = 3  # candidates fitted on every fold per round, after screening
JUDGED_WHOLE = 8  # a library this short (a propeller-and-rudder ship's: drift and sensors) skips the screening cut
SCREEN_STEPS = 2  # Gauss-Newton steps of a candidate's screening (module docstring)
SCREEN_WINDOWS = 32  # screening sees at most this many training windows, spread over the recording
# a candidate's own fit sees at most this many (spread): enough to fit two or three numbers; one of
# more numbers (a wind or compass offset per log: two or one for each log) sees REFINE_PER_NUMBER
# windows for each, or a log's own numbers would be fitted on a handful of its windows
REFINE_WINDOWS = 48
REFINE_PER_NUMBER = 12
MAX_EFFECTS = 5
T_PIN = 3.0  # a separable candidate's quantity is fitted when its training windows move it this many σ
MIN_CLUSTERS = 8  # training blocks that σ must come from for T_PIN to decide
CORE_NFEV = 20  # solver steps of every fit with the core (module docstring)
# a constant thrust scale that a loss growing with the speed could stand in for (module docstring)
SPEED_STAND_INS = {"thrust_gain": "thrust_speed_loss"}
SPEED_SHARE = 0.10  # the scale fitted on the fast half of the windows this much below the slow half's, on every fold


def _earth_fixed(name: str) -> bool:
    """An effect that acts by the heading (the registry's "environment": a current, a wind)."""
    return name in EFFECTS and EFFECTS[name].acts_on == "environment"


@dataclass
class Fitted:
    """A candidate fitted on training windows from the vessel `base`."""

    candidate: Candidate
    values: dict[str, float]
    vessel: Vessel
    train_cost: float
    fixed: tuple[str, ...] = ()  # a separable candidate's quantities left at the base's value (_pinned_only)
    screen_cost: float = float("nan")  # cost on windows its fit did not see, relative to the base's (Search.screen)


def excess_shown(share: float) -> float:
    """A share of the held-out misfit above the noise as a report or a JSON file gives it: within ±1.
    Past 1 the twin fitted the held-out blocks closer than the noise estimated for the recording, and
    the ratio to that small excess (10⁷ on a noise-free simulation) says nothing more than "all"."""
    return round(max(-1.0, min(1.0, share)), 4)


@dataclass
class Evidence:
    """A change of the twin judged on every fold's held-out blocks: z of the blocks' votes, the
    share of the held-out misfit removed (all windows), of the misfit above the noise, per DOF,
    how many blocks voted for and against, and the values fitted on each fold."""

    z: float
    rel: float
    rel_excess: float
    dof_rel: dict[str, float]
    blocks_for: int
    blocks_against: int
    affected: int
    votes: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    fold_values: list[dict] = field(default_factory=list)
    at_edge: list[str] = field(default_factory=list)  # parameters fitted to an unphysical edge on every fold

    def earns_its_place(self) -> bool:
        return self.z >= Z_MIN and self.rel_excess >= REL_EXCESS and not self.at_edge

    def to_dict(self) -> dict:
        return {"z": round(self.z, 2), "held_out_gain": round(self.rel, 4), "excess_gain": excess_shown(self.rel_excess),
                "dof_gain": {k: round(v, 4) for k, v in self.dof_rel.items()}, "blocks_for": self.blocks_for,
                "blocks_against": self.blocks_against, "affected_windows": self.affected,
                "fold_values": self.fold_values, **({"at_edge": self.at_edge} if self.at_edge else {})}


@dataclass
class Trial:
    """One candidate of one round: fitted per fold, and its evidence."""

    candidate: Candidate
    fits: list[Fitted]
    evidence: Evidence
    costs: "_Costs | None" = field(default=None, repr=False)  # the fits' held-out costs the evidence judged

    @property
    def name(self) -> str:
        return self.candidate.name


@dataclass
class Kept:
    """An effect kept, the rivals judged beside it, and the trials of those the recording cannot tell
    from it (their `fits[0]` fitted on the same fold's training windows as the kept one's)."""

    trial: Trial
    rivals: list[dict]
    unsettled: dict[str, Trial] = field(default_factory=dict)


@dataclass
class _Costs:
    """Per held-out window: cost, per-DOF squared residual sums, and the residuals (for the
    affected test), pooled over the folds in window order."""

    per_window: np.ndarray
    per_dof: np.ndarray  # (W, 3)
    residuals: list[np.ndarray]  # one flat array per window, in units of each sample's DOF noise σ
    dofs: list[np.ndarray]  # the DOF (0 u, 1 v, 2 r) of each of those residuals
    noise: np.ndarray  # per window: the cost a perfect twin would still have (the measurement noise)


class Search:
    """The diagnosis's search over one set of recordings (module docstring): the windows split into
    blocks and folds, each candidate effect fitted on some folds and judged on the held-out blocks,
    round after round until nothing more earns its place; `run` returns what was kept."""

    def __init__(self, prior: Vessel, data: Measurements, windows: list[Window], cache: ModelCache,
                 library: dict[str, Candidate], noise_sd: np.ndarray, log=None,
                 screen_cache: ModelCache | None = None, core: list | None = None, core_weight: float = 1.0,
                 wind: str | None = None):
        """windows: every (non-overlapping) window of the recordings, in time order per log;
        noise_sd: the measurement noise of u, v, r (m/s, m/s, rad/s) estimated from the recordings;
        screen_cache: models at a coarser step for screening the candidates that are not scanned;
        core: simfit Coordinates of the twin's own coefficients refitted with every candidate (module
        docstring), their beliefs counted as core_weight windows' worth of data each; wind "measured":
        each recording's measured wind a known input of every free run (windows.predict)."""
        self.prior, self.data, self.windows, self.cache = prior, data, windows, cache
        self.wind = wind
        self.screen_cache = screen_cache or cache
        self.core, self.core_weight = list(core or []), core_weight
        self.overlapping = sorted(n for n, c in library.items() if self.core and _moves_core(c, self.core, prior))
        self.library = {n: c for n, c in library.items() if n not in self.overlapping}
        self.log = log or (lambda msg: None)
        self.evaluations = 0
        self.blocks = blocks_of(windows)
        fold = self.blocks % FOLDS
        self.folds = [([w for w, f in zip(windows, fold) if f != k], [w for w, f in zip(windows, fold) if f == k])
                      for k in range(FOLDS)]
        self.folds = [(t, h) for t, h in self.folds if t and h]
        if len(self.folds) < 2:
            raise TwinError(f"{len(windows)} windows: too few to fit on some and judge on others "
                            "(a diagnosis runs on 2 minutes of data with inputs or more; naming an effect from the "
                            "dynamics takes about 5, ten blocks of 30 s)")
        self.held_order = [w for _, held in self.folds for w in held]  # pooled held-out windows, fold by fold
        index = {id(w): i for i, w in enumerate(windows)}
        self.held_blocks = np.array([self.blocks[index[id(w)]] for w in self.held_order])
        self.sigma = dof_scale(prior, Objective(prior, [], data, windows, cache, wind=wind), np.asarray(noise_sd, float))
        self.noise_var = (np.asarray(noise_sd, float) / self.sigma) ** 2
        self.screening = _spread(self.folds[0][0], SCREEN_WINDOWS)
        self.screening_held = _spread_per_log(self.folds[0][1], SCREEN_WINDOWS)
        self._screen_costs: dict = {}
        self.values: dict[str, float] = {}
        self.sigma_values: dict[str, float | None] = {}
        self.cov: np.ndarray | None = None
        self.cov_names: list[str] = []

    # ------------------------------------------------------------ costs

    def _objective(self, base: Vessel, params, windows, cache: ModelCache | None = None,
                   wind: str | None = None, with_core: bool = False) -> Objective:
        """The objective of `params` on `windows` from `base`; with_core: the core's coordinates
        after them, with their beliefs (the params before them have none: an effect is either
        there or not, and its size is the data's to say)."""
        params = list(params)
        core = self.core if with_core else []
        obj = Objective(base, params + [c.quantity for c in core], self.data, windows, cache or self.cache,
                        wind=wind or self.wind)
        obj.sigma = self.sigma
        if core:
            mean = np.r_[np.zeros(len(params)), [c.mean for c in core]]
            sigma = np.r_[np.full(len(params), np.inf), [c.belief.sigma for c in core]]
            obj.believe(mean, sigma, self.core_weight * obj.n_data / max(len(windows), 1))
        return obj

    def _core_fit(self, base: Vessel, train: list[Window]) -> Vessel:
        """The core refitted alone on `train` from `base` (the candidate, if any, held as it is)."""
        obj = self._objective(base, [], train, with_core=True)
        x0 = np.clip(np.array([c.quantity.get(base) for c in self.core]) / obj.scale, *obj.bounds())
        sol = least_squares(obj.residuals, x0, jac=obj.jacobian, bounds=obj.bounds(), method="trf", x_scale="jac",
                            max_nfev=CORE_NFEV, xtol=1e-5, ftol=1e-5)
        self.evaluations += obj.evaluations * len(obj.windows)
        return obj.vessel(sol.x)

    def held_costs(self, per_fold: list[Vessel], wind: str | None = None) -> _Costs:
        """Every fold's vessel on that fold's held-out windows, pooled (held_order); wind="measured":
        with the recordings' measured wind as a known input (windows.predict)."""
        costs, dofs, residuals, noise, dof_of = [], [], [], [], []
        for vessel, (_, held) in zip(per_fold, self.folds):
            obj = self._objective(self.prior, [], held, wind=wind)
            r = obj.residuals_of([vessel])[0]
            self.evaluations += len(held)
            idx = obj.window_index()
            dof = np.broadcast_to(np.arange(3), obj.meas.shape)[obj.valid]
            costs.append(np.bincount(idx, r * r, minlength=len(held)))
            per = np.zeros((len(held), 3))
            np.add.at(per, (idx, dof), r * r)
            dofs.append(per)
            counts = np.zeros((len(held), 3))
            np.add.at(counts, (idx, dof), 1.0)
            noise.append(counts @ self.noise_var)
            in_noise = r / np.sqrt(self.noise_var)[dof]
            residuals += [in_noise[idx == j] for j in range(len(held))]
            dof_of += [dof[idx == j] for j in range(len(held))]
        return _Costs(np.concatenate(costs), np.vstack(dofs), residuals, dof_of, np.concatenate(noise))

    def evidence(self, base: _Costs, cand: _Costs, fold_values: list[dict] | None = None) -> Evidence:
        """`cand` against `base` on the pooled held-out windows (module docstring)."""
        affected = np.array([_moved(a, b, d, self.noise_var)
                             for a, b, d in zip(base.residuals, cand.residuals, base.dofs)], bool)
        votes = []
        for b in np.unique(self.held_blocks):
            sel = (self.held_blocks == b) & affected
            if sel.any():
                c0 = float(base.per_window[sel].sum())
                votes.append((c0 - float(cand.per_window[sel].sum())) / max(c0, 1e-12))
        votes = np.array(votes)
        total = float(base.per_window.sum())
        gain = total - float(cand.per_window.sum())
        excess = max(total - float(base.noise.sum()), 1e-9 * max(total, 1e-300))
        dof0, dof1 = base.per_dof.sum(axis=0), cand.per_dof.sum(axis=0)
        return Evidence(_signed_rank_z(votes), gain / max(total, 1e-12), gain / excess,
                        {k: float((dof0[i] - dof1[i]) / max(dof0[i], 1e-12)) for i, k in enumerate("uvr")},
                        int(np.sum(votes > 0)), int(np.sum(votes < 0)), int(affected.sum()), votes,
                        fold_values or [])

    # ------------------------------------------------------------ one candidate
    def screen(self, base: Vessel, cand: Candidate) -> list[Fitted]:
        """Cheap look on a spread subset of the training windows: a scan, or SCREEN_STEPS
        Gauss-Newton steps from each start; each judged on held-out windows (screen_cost)."""
        obj = self._objective(base, cand.params, self.screening, self.cache if cand.time_shift else self.screen_cache)
        out = []
        base_cost = self._screen_base(base, obj.cache)
        if cand.scan:
            out.append(self._fitted(cand, obj, *self._coarse_scan(obj, cand)))
        else:
            if self.core:  # the steps of the candidate and the core together (module docstring)
                obj = self._objective(base, cand.params, self.screening, obj.cache, with_core=True)
            core_x = [c.quantity.get(base) for c in self.core]
            starts = [np.clip(np.r_[np.array(start, float), core_x] / obj.scale, *obj.bounds())
                      for start in cand.starts]
            if len(starts) > 1:  # the steps from the start the data like best
                residuals = obj.residuals_at(starts)
                if cand.log_of_param:
                    starts = [self._start_per_log(obj, cand, starts, residuals, base)]
                else:
                    starts = [starts[int(np.argmin([float(np.sum(r * r)) for r in residuals]))]]
            for x0 in starts:
                x, cost = self._steps(obj, x0)
                out.append(self._fitted(cand, obj, x, cost))
            if self.core:  # against the core's own steps on these windows, not against the core held
                base_cost = self._screen_base(base, obj.cache, stepped=True)
        self.evaluations += obj.evaluations * len(self.screening)
        stepped = bool(self.core) and not cand.scan
        held = self._objective(self.prior, [], self.screening_held, obj.cache)
        costs = [float(np.sum(r * r)) for r in held.residuals_of([f.vessel for f in out])]
        self.evaluations += len(out) * len(self.screening_held)
        held_base = self._screen_base(base, obj.cache, stepped=stepped, held=True)
        for f, c in zip(out, costs):  # relative to the base twin at the same step, so both steps rank together
            f.train_cost /= base_cost
            f.screen_cost = c / held_base
        return out

    @staticmethod
    def _steps(obj: Objective, x0: np.ndarray) -> tuple[np.ndarray, float]:
        """SCREEN_STEPS Gauss-Newton steps from x0, each with a short line search (a linearised step
        can overshoot), kept only while they lower the data's cost (the prior's rows only steer the
        steps): the point reached and that cost."""
        x, cost = x0, None
        for _ in range(SCREEN_STEPS):
            r = obj.residuals(x)
            if cost is None:
                cost = float(np.sum(r[: obj.n_data] ** 2))
            step = np.linalg.lstsq(obj.jacobian(x), -r, rcond=None)[0]
            trials = [np.clip(x + f * step, *obj.bounds()) for f in (1.0, 0.5, 0.25)]
            costs = [float(np.sum(t * t)) for t in obj.residuals_at(trials)]
            best = int(np.argmin(costs))
            if costs[best] >= cost:
                break
            x, cost = trials[best], costs[best]
        return x, cost

    def _start_per_log(self, obj: Objective, cand: Candidate, starts: list[np.ndarray],
                       residuals: list[np.ndarray], base: Vessel) -> np.ndarray:
        """Each log's quantities from the start its own windows like best (costs summed per log); a
        log none of the windows screened keeps the base's values (no start would be its data's)."""
        idx = obj.window_index()
        logs = np.array([log_name(self.data.preps[w.rec].settings.source) for w in obj.windows])
        per_window = np.array([np.bincount(idx, r * r, minlength=len(obj.windows)) for r in residuals])
        owner = np.array(list(cand.log_of_param) + [""] * (len(starts[0]) - len(cand.log_of_param)))  # core: no log
        out = np.array(starts[0], float)
        for log in set(cand.log_of_param):
            if not np.any(logs == log):
                out[owner == log] = [q.get(base) / sc for q, sc, o in zip(obj.params, obj.scale, owner) if o == log]
                continue
            best = int(np.argmin(per_window[:, logs == log].sum(axis=1)))
            out[owner == log] = np.asarray(starts[best])[owner == log]
        return np.clip(out, *obj.bounds())

    def _screen_base(self, base: Vessel, cache: ModelCache, stepped: bool = False, held: bool = False) -> float:
        """The base twin's cost on the screening windows at this cache's step (kept per round);
        stepped: after the core's own steps alone (the steps a candidate's screening takes);
        held: that twin's cost on the screening's held-out windows instead."""
        if self._screen_costs.get("base") is not base:  # a new round: its base twin
            self._screen_costs = {"base": base}
        key = (id(cache), stepped)
        if key not in self._screen_costs:
            twin = base
            if stepped:
                obj = self._objective(base, [], self.screening, cache, with_core=True)
                x0 = np.clip(np.array([c.quantity.get(base) for c in self.core]) / obj.scale, *obj.bounds())
                x, cost = self._steps(obj, x0)
                self.evaluations += obj.evaluations * len(self.screening)
                twin = obj.vessel(x)
            else:
                r = self._objective(base, [], self.screening, cache).residuals_of([base])[0]
                cost = float(np.sum(r * r))
            r = self._objective(self.prior, [], self.screening_held, cache).residuals_of([twin])[0]
            self.evaluations += len(self.screening_held)
            self._screen_costs[key] = (max(cost, 1e-300), max(float(np.sum(r * r)), 1e-300))
        return self._screen_costs[key][1 if held else 0]

    def refine(self, base: Vessel, fitted: Fitted, train: list[Window] | None = None) -> Fitted:
        """Bounded least squares from the screened point (a scanned candidate: finer scans),
        on the first fold's training windows unless `train` is given."""
        cand = fitted.candidate
        train = self.folds[0][0] if train is None else train
        if self.core:
            return self._refine_with_core(base, fitted, train)
        train = _spread(train, max(REFINE_WINDOWS, REFINE_PER_NUMBER * len(cand.params)))
        obj = self._objective(base, cand.params, train)
        x0 = np.array([fitted.values[n] for n in cand.names]) / obj.scale
        if cand.scan:  # from its own coarse scan (module docstring)
            x, cost = self._coordinate_scans(obj, cand, self._coarse_scan(obj, cand)[0])
            best = self._fitted(cand, obj, x, cost)
        else:
            sol = least_squares(obj.residuals, np.clip(x0, *obj.bounds()), jac=obj.jacobian, bounds=obj.bounds(),
                                method="trf", x_scale="jac", max_nfev=6, xtol=1e-5, ftol=1e-5)
            best = self._fitted(cand, obj, sol.x, float(np.sum(sol.fun ** 2)))
            if cand.separable and len(cand.params) > 1:
                best = self._pinned_only(base, best, obj, sol)
        self.evaluations += obj.evaluations * len(train)
        return best

    def _pinned_only(self, base: Vessel, fitted: Fitted, obj: Objective, sol) -> Fitted:
        """A separable candidate refitted with only the quantities its training windows pin free
        (moved from the base's value by at least T_PIN cluster-robust σ, the training blocks as
        clusters) and the others at the base's value; as fitted when all or none are pinned. A scale
        the data do not need moves the prediction of every window it acts in by its noise, and those
        windows then vote against the effect on held-out blocks."""
        n = obj.n_data
        index = {id(w): i for i, w in enumerate(self.windows)}
        blocks = np.array([self.blocks[index[id(w)]] for w in obj.windows])[obj.window_index()]
        clusters = np.unique(blocks, return_inverse=True)[1]
        cov = cluster_covariance(sol.jac[:n], sol.fun[:n], clusters) if clusters.max() + 1 >= MIN_CLUSTERS else None
        if cov is None:  # a sandwich over a handful of blocks understates σ: nothing is left out on it
            return fitted
        cand = fitted.candidate
        null = np.array([p.get(base) for p in cand.params]) / obj.scale
        pinned = np.abs(sol.x - null) >= T_PIN * np.sqrt(np.maximum(np.diag(cov), 1e-300))
        if pinned.all() or not pinned.any():
            return fitted
        free = [p for p, k in zip(cand.params, pinned) if k]
        sub = self._objective(base, free, obj.windows)
        x0 = np.clip(sol.x[pinned] * obj.scale[pinned] / sub.scale, *sub.bounds())
        sol = least_squares(sub.residuals, x0, jac=sub.jacobian, bounds=sub.bounds(), method="trf", x_scale="jac",
                            max_nfev=6, xtol=1e-5, ftol=1e-5)
        self.evaluations += sub.evaluations * len(sub.windows)
        values = {p.name: float(p.get(base)) for p in cand.params}
        values.update({p.name: float(xi * s) for p, xi, s in zip(free, sol.x, sub.scale)})
        fixed = tuple(p.name for p, k in zip(cand.params, pinned) if not k)
        return Fitted(cand, values, sub.vessel(sol.x), float(np.sum(sol.fun ** 2)), fixed)

    def _refine_with_core(self, base: Vessel, fitted: Fitted, train: list[Window]) -> Fitted:
        """The candidate and the core fitted together (module docstring); a scanned candidate is
        scanned with the core held, then the core refitted around it."""
        cand = fitted.candidate
        if cand.scan:
            obj = self._objective(base, cand.params, _spread(train, max(REFINE_WINDOWS, REFINE_PER_NUMBER *
                                                                          len(cand.params))))
            x, cost = self._coordinate_scans(obj, cand, self._coarse_scan(obj, cand)[0])
            self.evaluations += obj.evaluations * len(obj.windows)
            scanned = self._fitted(cand, obj, x, cost)
            return Fitted(cand, scanned.values, self._core_fit(scanned.vessel, train), cost)
        obj = self._objective(base, cand.params, train, with_core=True)
        x0 = np.r_[[fitted.values[n] for n in cand.names], [c.quantity.get(base) for c in self.core]] / obj.scale
        sol = least_squares(obj.residuals, np.clip(x0, *obj.bounds()), jac=obj.jacobian, bounds=obj.bounds(),
                            method="trf", x_scale="jac", max_nfev=CORE_NFEV, xtol=1e-5, ftol=1e-5)
        self.evaluations += obj.evaluations * len(obj.windows)
        return self._fitted(cand, obj, sol.x, float(np.sum(sol.fun[: obj.n_data] ** 2)))

    @staticmethod
    def _coarse_scan(obj: Objective, cand: Candidate) -> tuple[np.ndarray, float]:
        """The best point of the candidate's coarse grid (cand.scan) on obj's windows (the middle of a
        plateau of equal costs) and the lowest cost."""
        lo, hi = obj.bounds()
        xs = [np.clip(np.array(v, float) / obj.scale, lo, hi) for v in cand.scan]
        costs = [float(np.sum(r * r)) for r in obj.residuals_at(xs)]
        return xs[_plateau_middle(costs)], min(costs)

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
                costs = [float(np.sum(r * r)) for r in obj.residuals_at(trials)]
                k = _plateau_middle(costs)
                x, cost = trials[k], costs[k]
        return x, cost

    @staticmethod
    def _fitted(cand: Candidate, obj: Objective, x: np.ndarray, cost: float) -> Fitted:
        values = {p.name: float(xi * s) for p, xi, s in zip(cand.params, x, obj.scale)}
        return Fitted(cand, values, obj.vessel(x), cost)


    # ------------------------------------------------------------ rounds

    def trial(self, bases: list[Vessel], base_costs: _Costs, screened: Fitted) -> Trial:
        """The candidate fitted on each fold's training windows from that fold's base, judged on
        its held-out blocks."""
        fits = [self.refine(base, screened, train) for base, (train, _) in zip(bases, self.folds)]
        cand_costs = self.held_costs([f.vessel for f in fits])
        evidence = self.evidence(base_costs, cand_costs, [f.values for f in fits])
        cand = screened.candidate
        unpinned = set.intersection(*(set(f.fixed) for f in fits))
        if unpinned:  # left at the base's value on every fold: kept effects are refitted without them
            free = [i for i, p in enumerate(cand.params) if p.name not in unpinned]
            cand = replace(cand, params=tuple(cand.params[i] for i in free),
                           starts=tuple(tuple(s[i] for i in free) for s in cand.starts))
        return Trial(cand, fits, replace(evidence, at_edge=at_unphysical_edge(screened.candidate, fits)), cand_costs)

    def round(self, bases: list[Vessel], base_costs: _Costs, skip: set[str], earth_slot: bool = True) -> list[Trial]:
        """Every remaining candidate screened, the best few fitted on every fold and judged,
        best evidence first; earth_slot: the best earth-fixed candidate judged beside them (module
        docstring), while no earth-fixed effect is kept."""
        screened = []
        for name, cand in self.library.items():
            if name in skip:
                continue
            try:
                screened.append(min(self.screen(bases[0], cand), key=lambda f: f.screen_cost))
            except TwinError as exc:
                self.log(f"candidate {name} skipped: {exc}")
        screened.sort(key=lambda f: f.screen_cost)
        # a short library (a vessel few effects apply to, or --effects) is judged whole: screening is
        # a two-step look, and it is only worth its risk of passing over an effect when it saves much
        # (a wind of each log's own, offered when several logs are diagnosed, does not lengthen it)
        length = sum(not f.candidate.log_of_param for f in screened)
        shortlist = screened if length <= JUDGED_WHOLE else screened[:FULL_FITS]
        # a constant thrust scale is judged beside the loss with speed it may stand in for
        names = {f.candidate.name for f in shortlist}
        shortlist += [f for f in screened if f.candidate.name not in names and
                      f.candidate.name in {SPEED_STAND_INS[n] for n in names if n in SPEED_STAND_INS}]
        # and the best earth-fixed effect beside whatever leads: a twin's form error moves with the hull,
        # so hull and thrust terms take it up in screening and lead it, while a current or a
        # wind, which acts by the heading, is what no such term stands in for
        if earth_slot and not any(_earth_fixed(f.candidate.name) for f in shortlist):
            shortlist += [f for f in screened if _earth_fixed(f.candidate.name)][:1]
        trials = [self.trial(bases, base_costs, f) for f in shortlist]
        return sorted(trials, key=lambda t: (t.evidence.earns_its_place(), t.evidence.rel_excess), reverse=True)

    def grows_with_speed(self, trial: Trial, bases: list[Vessel]) -> list[tuple[float, float]] | None:
        """(slow, fast) scales of a constant-scale trial refitted on each fold's slower and faster half
        of its training windows (by the window's mean |u|), when every fold's fast half wants at least
        SPEED_SHARE less than its slow half; else None."""
        pairs = []
        for fit, base, (train, _) in zip(trial.fits, bases, self.folds):
            speed = np.array([np.nanmean(np.abs(self.data.preps[w.rec].u[w.start:w.start + w.n])) for w in train])
            order = np.argsort(speed)
            half = len(train) // 2
            if half < 4:
                return None
            slow, fast = ([train[i] for i in sorted(order[:half])], [train[i] for i in sorted(order[half:])])
            scale = trial.candidate.names[0]
            pairs.append(tuple(self.refine(base, fit, part).values[scale] for part in (slow, fast)))
        if all(s > 0 and (s - f) / s >= SPEED_SHARE for s, f in pairs):
            return pairs
        return None

    def joint(self, kept: list[Kept], windows: list[Window], start: Vessel | None = None,
              max_nfev: int = 12) -> tuple[Vessel, Objective, np.ndarray]:
        """Every kept effect refitted together on `windows`, from the prior (values from `start`
        or each effect's last fit): the vessel, the objective and its solution."""
        params = [p for k in kept for p in k.trial.candidate.params]
        obj = self._objective(self.prior, params, windows, with_core=True)
        source = start or kept[-1].trial.fits[0].vessel
        x0 = np.clip(np.array([p.get(source) for p in obj.params]) / obj.scale, *obj.bounds())
        sol = least_squares(obj.residuals, x0, jac=obj.jacobian, bounds=obj.bounds(), method="trf", x_scale="jac",
                            max_nfev=max(max_nfev, CORE_NFEV) if self.core else max_nfev, xtol=1e-7, ftol=1e-7)
        self.evaluations += obj.evaluations * len(windows)
        return obj.vessel(sol.x), obj, sol.x

    def fold_bases(self, kept: list[Kept], previous: list[Vessel]) -> list[Vessel]:
        """The kept effects refitted together on each fold's training windows."""
        if not kept:
            if self.core:
                return [self._core_fit(self.prior, train) for train, _ in self.folds]
            return [self.prior] * len(self.folds)
        return [self.joint(kept, train, start=prev)[0] for prev, (train, _) in zip(previous, self.folds)]

    def run(self) -> tuple[Vessel, list[Kept], list[dict]]:
        """Forward selection with backward elimination (module docstring). Returns the amended
        vessel (every kept effect fitted together on all windows), the kept effects and the
        record of every round."""
        kept: list[Kept] = []
        bases = self.fold_bases(kept, [])
        self.initial_bases = bases  # each fold's twin before any effect (the prior, or its core refitted)
        base_costs = self.held_costs(bases)
        rounds: list[dict] = []
        dropped: set[str] = set()
        for _ in range(MAX_EFFECTS):
            superseded = {n for k in kept for n in k.trial.candidate.supersedes}
            trials = self.round(bases, base_costs, {k.trial.name for k in kept} | dropped | superseded,
                                earth_slot=not any(_earth_fixed(k.trial.name) for k in kept))
            rounds.append({"candidates": [{"name": t.name, **t.evidence.to_dict()} for t in trials]})
            winner = next((t for t in trials if t.evidence.earns_its_place()), None)
            if winner is None:
                break
            winner, rivals = self._choose(winner, trials, bases, base_costs)
            e = winner.evidence
            self.log(f"kept {winner.name}: held-out misfit −{100 * e.rel:.1f} % (−{100 * e.rel_excess:.1f} % of "
                     f"the excess over the noise), z = {e.z:.1f} over {e.blocks_for + e.blocks_against} blocks")
            by_name = {t.name: t for t in trials}
            kept.append(Kept(winner, rivals, {r["name"]: by_name[r["name"]] for r in rivals
                                              if not r["separable"] and by_name[r["name"]].fits}))
            kept, outdone = without_superseded(kept, winner)
            for name in sorted(outdone):
                self.log(f"dropped {name}: {winner.name} supersedes it (it can do nothing more beside it)")
            bases = self.fold_bases(kept, [winner.fits[f].vessel for f in range(len(self.folds))])
            base_costs = self.held_costs(bases)
            kept, bases, base_costs, gone = self._backward(kept, bases, base_costs)
            dropped |= gone | outdone
            rounds[-1]["dropped"] = sorted(gone | outdone)
        self.final_bases = bases  # each fold's fit of the kept effects, for the held-out scores
        if not kept:
            return (self._core_fit(self.prior, self.windows) if self.core else self.prior), kept, rounds
        amended, obj, x = self.joint(kept, self.windows, start=bases[0], max_nfev=20)
        self._covariance(kept, obj, x)
        return amended, kept, rounds

    def _choose(self, winner: Trial, trials: list[Trial], bases: list[Vessel],
                base_costs: _Costs) -> tuple[Trial, list[dict]]:
        """The effect a round keeps and its rivals: the winner in its speed form (_speed_form), or
        the rival _preferred puts in its place, in its own speed form (module docstring)."""
        winner = self._speed_form(winner, trials, bases)
        rivals = self._rivals(winner, trials, base_costs)
        preferred = self._preferred(winner, trials, rivals)
        if preferred is winner:
            return winner, rivals
        z = -next(r['z'] for r in rivals if r['name'] == preferred.name)
        self.log(f"the blocks prefer {preferred.name} to {winner.name} (z {z:.1f}): kept instead" if z >= Z_PREFER
                 else f"{preferred.name} and {winner.name} cannot be told apart (z {z:.1f}): the one with "
                 f"fewer quantities ({len(preferred.candidate.params)} against "
                 f"{len(winner.candidate.params)}) kept")
        winner = self._speed_form(preferred, trials, bases)
        return winner, self._rivals(winner, trials, base_costs)

    def _backward(self, kept: list[Kept], bases: list[Vessel], base_costs: _Costs):
        """Each kept effect put back to the prior in every fold's fit: dropped when the fit does not
        get significantly worse without it."""
        gone: set[str] = set()
        while len(kept) > 1:
            worst, worst_e = None, None
            for k in kept:
                without = ([_reset(b, k.trial.candidate, self.prior) for b in bases] if not self.core else
                           self.fold_bases([o for o in kept if o is not k], bases))
                e = self.evidence(self.held_costs(without), base_costs)
                if not e.earns_its_place() and (worst_e is None or e.rel_excess < worst_e.rel_excess):
                    worst, worst_e = k, e
            if worst is None:
                break
            self.log(f"dropped {worst.trial.name}: with the others refitted it no longer earns its place "
                     f"(z = {worst_e.z:.1f}, −{100 * worst_e.rel_excess:.1f} % of the excess)")
            gone.add(worst.trial.name)
            kept = [k for k in kept if k is not worst]
            bases = self.fold_bases(kept, bases)
            base_costs = self.held_costs(bases)
        return kept, bases, base_costs, gone

    def _covariance(self, kept: list[Kept], obj: Objective, x: np.ndarray) -> None:
        J = obj.jacobian(x)
        r = obj.residuals(x)[: obj.n_data]
        cov = cluster_covariance(J[: obj.n_data], r, obj.window_index(), J[obj.n_data:])
        names = [f"{k.trial.name}.{p.name}" for k in kept for p in k.trial.candidate.params]
        self.values = {n: float(xi * s) for n, xi, s in zip(names, x, obj.scale)}
        m = len(names)  # the core's coordinates, if any, follow the effects' own
        self.cov = None if cov is None else (cov * np.outer(obj.scale, obj.scale))[:m, :m]  # value units
        self.cov_names = names
        self.sigma_values = {n: (float(np.sqrt(self.cov[i, i])) if self.cov is not None and self.cov[i, i] >= 0
                                 else None) for i, n in enumerate(names)}

    def _speed_form(self, winner: Trial, trials: list[Trial], bases: list[Vessel]) -> Trial:
        """The loss with speed in place of a constant thrust scale that wants less thrust the faster the
        boat goes (grows_with_speed), where that loss earns its place itself."""
        other = SPEED_STAND_INS.get(winner.name)
        rival = next((t for t in trials if t.name == other), None)
        if rival is None or not rival.evidence.earns_its_place():
            return winner
        pairs = self.grows_with_speed(winner, bases)
        if pairs is None:
            return winner
        self.log(f"{winner.name} wants less thrust the faster the boat goes (slow, fast per fold: "
                 + ", ".join(f"{a:.2f}/{b:.2f}" for a, b in pairs) + f"): {other} kept instead")
        return rival

    @staticmethod
    def _preferred(winner: Trial, trials: list[Trial], rivals: list[dict]) -> Trial:
        """Of the winner and the rivals the recording cannot tell from it that earn their place
        themselves: the rival the blocks prefer to the winner by Z_PREFER or more (the most
        preferred); where the blocks lean to neither by that much, the one with the fewest
        quantities; else the winner (module docstring)."""
        by_name = {t.name: t for t in trials}
        earning = [r for r in rivals if not r["separable"] and by_name[r["name"]].evidence.earns_its_place()]
        leaning = [r for r in earning if r["z"] <= -Z_PREFER]
        if leaning:
            return by_name[min(leaning, key=lambda r: r["z"])["name"]]
        level = [by_name[r["name"]] for r in earning if abs(r["z"]) < Z_PREFER
                 and len(by_name[r["name"]].candidate.params) < len(winner.candidate.params)]
        return min(level, key=lambda t: (len(t.candidate.params), -t.evidence.rel)) if level else winner

    def _rivals(self, winner: Trial, trials: list[Trial], base_costs: _Costs) -> list[dict]:
        """Candidates that did at least half as well: told apart from the winner only when the
        blocks prefer the winner clearly."""
        out = []
        def costs(t: Trial) -> _Costs:
            return t.costs if t.costs is not None else self.held_costs([f.vessel for f in t.fits])

        win = costs(winner)
        for t in trials:
            if t is winner or t.evidence.rel < 0.5 * winner.evidence.rel:
                continue
            e = self.evidence(costs(t), win)
            z = e.z  # positive: the winner is better (the rival is the base here)
            out.append({"name": t.name, "z": round(z, 2), "separable": bool(z > Z_SEPARABLE),
                        "held_out_gain": round(t.evidence.rel, 4),
                        "parameters": t.candidate.to_effect(t.fits[0].values).flat()})
        return out


def without_superseded(kept: list[Kept], winner: Trial) -> tuple[list[Kept], set[str]]:
    """The kept effects less those the new winner supersedes (`Candidate.supersedes`: a constant wind
    acts on no log once every log has its own), and their names: kept, they would be refitted to
    nothing and reported as if they mattered."""
    gone = {k.trial.name for k in kept if k.trial.name in winner.candidate.supersedes}
    return [k for k in kept if k.trial.name not in gone], gone


EDGE_TOLERANCE = 1e-3  # relative distance from a bound that counts as on it


def at_unphysical_edge(candidate: Candidate, fits: list[Fitted]) -> list[str]:
    """The candidate's parameters whose fit ends on an unphysical edge of their range
    (Quantity.edges_unphysical: yaw added inertia ×20 of the prior) on every fold. Such a fit does
    not measure the effect: the data want more (or less) of it than any real vessel has, which is what a
    term compensating for another form looks like (a slower thruster read as yaw inertia), so the
    candidate is not named; the report says the form is off where it acts."""
    def on_edge(q, x: float) -> bool:  # these ranges are multiples (lo > 0) or start at none (lo 0): relative distance
        low = q.lo * (1 + EDGE_TOLERANCE) if q.lo > 0 else EDGE_TOLERANCE * q.hi
        return x >= q.hi * (1 - EDGE_TOLERANCE) or x <= low

    return [p.name for p in candidate.params
            if p.edges_unphysical and fits and all(p.name in f.values and on_edge(p, f.values[p.name]) for f in fits)]


def blocks_of(windows: list[Window]) -> np.ndarray:
    """Block number of each window: BLOCK_WINDOWS consecutive windows of one recording."""
    out, block, last_rec, count = [], -1, None, 0
    for w in windows:
        if w.rec != last_rec or count == BLOCK_WINDOWS:
            block, count, last_rec = block + 1, 0, w.rec
        out.append(block)
        count += 1
    return np.array(out, int)


def _moves_core(candidate: Candidate, core: list, prior: Vessel) -> bool:
    """Whether the core already moves one of the candidate's quantities: some direction in which the
    candidate moves the vessel description lies in the span of the core's (a damping scale when the
    damping is refitted; the sway and yaw scales of an added-mass effect when those added masses are).
    Such a quantity would be written over by the core's refit and fitted to nothing; one thruster's gain
    when both gains' mean is refitted lies outside it."""
    base = _numbers(prior)

    def direction(q, v) -> np.ndarray | None:
        value = q.get(v)
        step = 1e-3 * max(abs(value), q.typical, 1e-6)
        moved = _numbers(q.put(v, value + step))
        return None if len(moved) != len(base) else (moved - base) / step

    core_dirs = [d for d in (direction(c.quantity, prior) for c in core) if d is not None]
    if not core_dirs:
        return False
    D = np.column_stack(core_dirs)
    for q in candidate.params:
        d = direction(q, prior)
        if d is None or not np.any(d):
            continue
        coef = np.linalg.lstsq(D, d, rcond=None)[0]
        if np.linalg.norm(D @ coef - d) <= 1e-3 * np.linalg.norm(d):  # finite differences of curved puts: 1e-3
            return True
    return False


def _numbers(obj) -> np.ndarray:
    """Every number of a vessel description, flattened in a fixed order (names, paths, sources and the
    identification's uncertainty left out): what a quantity's put() changes."""
    out: list[float] = []

    def walk(x) -> None:
        if is_dataclass(x):
            for f in fields(x):
                if f.name not in ("name", "mjcf", "path", "sources", "uncertainty"):
                    walk(getattr(x, f.name))
        elif isinstance(x, dict):
            for k in sorted(x):
                walk(x[k])
        elif isinstance(x, (list, tuple)):
            for item in x:
                walk(item)
        elif isinstance(x, (bool, int, float)):
            out.append(float(x))
    walk(obj)
    return np.array(out)


def _reset(vessel: Vessel, candidate: Candidate, prior: Vessel) -> Vessel:
    """`vessel` with the candidate's quantities back at the prior's values."""
    for p in candidate.params:
        vessel = p.put(vessel, p.get(prior))
    return vessel


def _moved(base: np.ndarray, cand: np.ndarray, dof: np.ndarray, noise_var: np.ndarray) -> bool:
    """A window is affected when the candidate moves its residuals by more than AFFECT_SIGMA noise σ,
    RMS over the window's samples of u, v and r, each velocity in its own noise (residuals in noise
    units). Not in the fit's scale with the noise pooled over the velocities: there the velocity
    whose noise is largest beside its signal (a catamaran's sway) set the bar for all three, and a
    20 % thrust asymmetry that moved u and r by 2-6 noise σ in every window of a library dataset
    moved 2 of its 43 windows past it."""
    if len(base) != len(cand):
        return True
    if not len(base):
        return False
    return bool(np.sqrt(np.mean((base - cand) ** 2)) > AFFECT_SIGMA)


def dof_scale(prior: Vessel, whole: Objective, noise_sd: np.ndarray) -> np.ndarray:
    """The scale of each DOF's residual (u, v, r) in every cost of the search. For a twin identified
    on other runs (it carries the form error `twin identify` measured: Vessel.uncertainty), what its
    residual on these recordings is, √(noise² + the twin's RMS misfit²) over every window (`whole`);
    else the spread of the measured signal. Residuals scaled by what is expected of them count
    every DOF by what it can tell: on runs beyond a twin's own a DOF it predicts poorly (a
    catamaran's sway, a misfit no candidate removes) would otherwise outweigh the DOFs where an
    effect shows, and each block's vote would follow that DOF's misfit."""
    if not (prior.uncertainty or {}).get("form_error"):
        return whole.sigma
    dof = np.broadcast_to(np.arange(3), whole.meas.shape)[whole.valid]
    r = whole.residuals_of([prior])[0] * whole.sigma[dof]  # m/s, m/s, rad/s
    misfit = np.array([np.sqrt(np.mean(r[dof == k] ** 2)) if np.any(dof == k) else np.nan for k in range(3)])
    scale = np.sqrt(np.nan_to_num(noise_sd) ** 2 + misfit ** 2)
    return np.where(np.isfinite(scale) & (scale > 1e-9), scale, whole.sigma)


def _signed_rank_z(votes: np.ndarray) -> float:
    """z of the one-sided Wilcoxon signed-rank test on the side the votes lean to: positive, the
    test that they are positive; negative, minus that of the test that they are negative (0 without
    votes). Ranks, not a mean over its standard error: one block's large gain cannot outvote many
    small losses, and an effect that acts only in some regimes leaves the other blocks untouched."""
    d = votes[np.abs(votes) > 1e-9]
    if len(d) < 2:
        return 0.0
    # few blocks: the exact null distribution (the normal approximation understates how unlikely ten
    # blocks out of ten are by chance: z 2.8 instead of 3.1)
    method = "exact" if len(d) <= 50 else "approx"
    greater = float(wilcoxon(d, zero_method="wilcox", alternative="greater", method=method).pvalue)
    less = float(wilcoxon(d, zero_method="wilcox", alternative="less", method=method).pvalue)
    # each side from its own tail: the far end of the one is the near end of the other a rank away
    # (every block against gives p = 1 for 'greater', which would read as z −7 on five blocks)
    if greater <= less:
        return float(norm.isf(min(max(greater, 1e-300), 1.0 - 1e-12)))  # finite (JSON)
    return float(-norm.isf(min(max(less, 1e-300), 1.0 - 1e-12)))


def _spread(windows: list[Window], most: int) -> list[Window]:
    """At most `most` of the windows, evenly spread over the recording."""
    return windows[::max(1, int(np.ceil(len(windows) / most)))]


def _spread_per_log(windows: list[Window], most: int) -> list[Window]:
    """About `most` of the windows, evenly spread within each recording and every recording kept:
    a log's own quantities (a wind of each log's own) are judged on that log's windows, and a
    stride over all logs together can step over a short one."""
    stride = max(1, int(np.ceil(len(windows) / most)))
    out = []
    for rec in dict.fromkeys(w.rec for w in windows):
        mine = [w for w in windows if w.rec == rec]
        out += mine[(len(mine) % stride) // 2::stride]
    return out


def _plateau_middle(costs: list[float]) -> int:
    """Index of the middle of the run of equal lowest costs: a staircase cost (a dead zone's edge
    moved between two logged PWM values changes nothing) is best estimated by its plateau's centre."""
    c = np.asarray(costs)
    best = int(np.argmin(c))
    flat = np.abs(c - c[best]) <= 1e-9 * max(abs(c[best]), 1e-30)
    lo = hi = best
    while lo > 0 and flat[lo - 1]:
        lo -= 1
    while hi < len(c) - 1 and flat[hi + 1]:
        hi += 1
    return (lo + hi) // 2


