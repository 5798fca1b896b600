"""Monte Carlo of an identified twin: what the identification left uncertain, carried through a
mission as prediction bands.

Each draw is a twin whose coefficients come from the covariance `twin identify` stored in the
vessel file (`fit.uncertainty.draw`), optionally with factors and effects drawn from ranges
(`scale.draws`). Every draw is driven by the same open-loop input series from the same start
state on the batch engine; the band at each sample time is the percentiles over the draws of
north, east, heading, u, v, r, and of the position relative to the nominal twin's (along its
heading, across it, and the distance).

A closed-loop scenario (zig-zag, an autopilot) cannot run in `mujoco.rollout`, which is open
loop. It is run once, closed loop, by the nominal twin, and the inputs its controller applied
become the mission's input series, replayed open loop by every draw. That measures what the
band should measure, the model's uncertainty under given inputs: the same question `twin
evaluate` asks of a recording, whose PWM is also given. Closing the loop per draw would let
the controller hide the model error it corrects (a heading hold keeps every heading band
narrow), and would need the single-run path, at half the batch engine's speed.

In a sea (`Mission.sea`) every twin runs the 6-DOF hull in it (engine/sixdof.py), each draw in
its own realisation of the sea (the mission's sea drawn from a seed of the draw's own, from the
batch's seed): the band then holds what the waves do to the mission beside what the
identification left uncertain. The nominal twin runs in the mission's own realisation.

`recording_coverage` asks the same of real data: free runs of every draw from a recording's
measured states, driven by its PWM; the share of the measured samples inside the band.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import mujoco
import numpy as np

from ..drive import InputSeries, get as get_scenario
from ..engine import batch as engine
from ..engine import native, sixdof
from ..engine.callbacks import _joint_indices
from ..engine.mjcf import CompiledVessel, compile_vessel
from ..engine.sim import initial_state, simulate
from ..effects import coefficients
from ..errors import TwinError
from ..fit.windows import ModelCache, Window, as_measured, make_windows, measured, predict
from ..fit.crossval import form_error_at
from ..fit.uncertainty import check_drawable
from ..physics.kinematics import wrap_angle
from ..physics.waves import N_COMPONENTS
from ..prepare import Prepared
from ..progress import Progress
from ..vessel import Vessel
from .batches import Batch, Executor, LocalExecutor, gather, plan
from .draws import Variation

STATE = ("north", "east", "psi", "u", "v", "r")
UNITS = {"north": "m", "east": "m", "psi": "rad", "u": "m_s", "v": "m_s", "r": "rad_s", "along": "m",
         "cross": "m", "deviation": "m"}
QUANTITIES = tuple(UNITS)
ONE_SIDED = ("deviation",)  # a distance: its band is [0, the level's percentile]
# what the band's position quantities are, where their names do not say it
BAND_MEANING = {"deviation": "(distance from the nominal twin's track: inside its one-sided band)"}
CHUNK_BYTES = 64 << 20  # the largest block of engine states one rollout call returns


# ---------------------------------------------------------------- the mission

@dataclass(frozen=True)
class Mission:
    """What every draw is driven through: an open-loop input series (its own clock from 0) for
    duration_s from η0 = (north m, east m, ψ rad) moving with ν0 = (u, v m/s, r rad/s), sampled
    every sample_dt_s."""

    inputs: InputSeries
    duration_s: float
    sample_dt_s: float = 0.5
    eta0: tuple[float, float, float] = (0.0, 0.0, 0.0)
    nu0: tuple[float, float, float] = (0.0, 0.0, 0.0)
    source: str = ""
    sea: object = None  # physics.waves.Sea: every twin in its own realisation of it

    def __post_init__(self):
        if not (self.duration_s > 0 and self.sample_dt_s > 0 and math.isfinite(self.duration_s)):
            raise TwinError("the mission needs a positive duration and sample period")
        if self.sample_dt_s > self.duration_s:
            raise TwinError(f"sample period {self.sample_dt_s:g} s is longer than the mission ({self.duration_s:g} s)")

    def to_dict(self) -> dict:
        return {"source": self.source, "duration_s": self.duration_s, "sample_dt_s": self.sample_dt_s,
                "eta0": list(self.eta0), "nu0": list(self.nu0), "inputs": self.inputs.kind,
                "input_samples": len(self.inputs.t), "sea": None if self.sea is None else self.sea.to_dict()}


def scenario_mission(vessel: Vessel, scenario: str, duration_s: float, sample_dt_s: float = 0.5,
                     seed: int = 0, sea=None) -> Mission:
    """A scenario run once closed loop by the nominal twin (in `sea`, a physics.waves.Sea, when
    given); its applied inputs become the mission (module docstring: why open loop for the draws)."""
    run = simulate(compile_vessel(vessel), get_scenario(scenario, seed, vessel.thrusters.kind, vessel.name), duration_s,
                   sample_dt_s=sample_dt_s, sea=sea)
    return Mission(run.meta["inputs"], duration_s, sample_dt_s,
                   source=f"scenario {scenario} (closed loop by the nominal twin, its inputs replayed open loop)",
                   sea=sea)


def inputs_mission(series: InputSeries, duration_s: float, sample_dt_s: float = 0.5, source: str = "",
                   sea=None) -> Mission:
    return Mission(series, duration_s, sample_dt_s, source=source or "inputs", sea=sea)


# ---------------------------------------------------------------- many twins through it

def simulate_tracks(vessels: list[Vessel], mission: Mission, cache: ModelCache | None = None,
                    seas: list | None = None) -> tuple[np.ndarray, list[int]]:
    """(n, samples, 6) north, east, ψ, u, v, r of every twin at the mission's sample times, and
    the indices of the twins that diverged (their samples NaN). Batch engine, in chunks of time
    so that memory stays bounded however long the mission. In the mission's sea, twin i runs the
    6-DOF hull in seas[i] (default: the mission's sea itself)."""
    cache = cache or ModelCache()
    if mission.sea is None:
        models = [cache.model(v) for v in vessels]
        states0 = _start_states(models, mission)
    else:
        models, states0 = _sea_twins(vessels, seas or [mission.sea] * len(vessels), mission, cache)
    h = models[0].opt.timestep
    if any(m.opt.timestep != h for m in models):
        raise TwinError("the twins of one Monte Carlo must share the time step")
    nstep = int(round(mission.duration_s / h))
    every = int(round(mission.sample_dt_s / h))
    if every < 1 or abs(every * h - mission.sample_dt_s) > 1e-9:
        raise TwinError(f"sample period {mission.sample_dt_s:g} s is not a multiple of the time step {h:g} s")
    nstep -= nstep % every
    controls = _controls(vessels, mission, nstep, h)
    n_samples = nstep // every + 1
    out = np.full((len(vessels), n_samples, len(STATE)), np.nan)
    diverged: list[int] = []
    for rows in _by_state_size(states0).values():
        sub = [models[i] for i in rows]
        traj, bad = _sampled_rollout(sub, np.array([states0[i] for i in rows]), controls[rows], every)
        out[rows] = _eta_nu(sub[0], traj)
        diverged += [rows[j] for j in bad]
    return out, sorted(diverged)


def _controls(vessels: list[Vessel], mission: Mission, nstep: int, h: float) -> np.ndarray:
    """(n, nstep, 2) thrust commands; computed once per distinct thrust curve (the gains act in
    the engine, after the command: a draw of thrust_gain shares its curve)."""
    done: dict = {}
    out = np.empty((len(vessels), nstep, 2))
    for i, v in enumerate(vessels):
        key = replace(v.thrusters, gain_left=1.0, gain_right=1.0)
        if key not in done:
            done[key] = mission.inputs.thrust_on_steps(v.thrusters, nstep, h, 0.0)
        out[i] = done[key]
    return out


def _start_states(models, mission: Mission) -> list[np.ndarray]:
    """Each twin's full-physics start state: one per model layout, since it holds the state
    (time, joints, thrust lag) and not the parameters."""
    layouts: dict[tuple[int, int, int], np.ndarray] = {}
    out = []
    for m in models:
        key = (m.nq, m.nv, m.na)
        if key not in layouts:
            layouts[key] = engine.initial_state(m, mission.eta0, mission.nu0)
        out.append(layouts[key])
    return out


_six_bases: dict[tuple, object] = {}  # per worker process: 6-DOF models by structure and hull


def _sea_twins(vessels: list[Vessel], seas: list, mission: Mission, cache: ModelCache
               ) -> tuple[list[mujoco.MjModel], list[np.ndarray]]:
    """Each twin's 6-DOF model in its own sea and its start at rest on its hull's equilibrium: a
    model compiled once per structure (room for every component a sea may have), copied per twin
    with its sea, its parameters and its thrusters' gains, range and lag (as ModelCache sets them)."""
    models, states = [], []
    for v, sea in zip(vessels, seas):
        cv = cache.compiled(v)
        key = (id(cv), str(v.mjcf), v.case, repr(v.cases.get(v.case)), tuple(v.cg_offset_m), sea.regular,
               mission.eta0, mission.nu0)
        if key not in _six_bases:
            if len(_six_bases) > 64:
                _six_bases.pop(next(iter(_six_bases)))
            six = sixdof.compile_six(cv, sea, slots=1 if sea.regular else N_COMPONENTS)
            data = mujoco.MjData(six.model)
            initial_state(six.model, data, mission.eta0, mission.nu0, six.initial_qpos(mission.eta0))
            state = np.empty(engine.state_size(six.model))
            mujoco.mj_getState(six.model, data, state, engine.FULL)
            _six_bases[key] = (six, state)
        six, state = _six_bases[key]
        own = CompiledVessel(v, cv.model, cv.geometry)
        m = sixdof.reseeded(six, own, sea)
        native.set_params(m, own.hydro())
        three = cache.model(v)
        m.actuator_gainprm[:2] = three.actuator_gainprm[:2]
        m.actuator_ctrlrange[:2] = three.actuator_ctrlrange[:2]
        m.actuator_dynprm[:2] = three.actuator_dynprm[:2]
        models.append(m)
        states.append(state)
    return models, states


def _by_state_size(states: list[np.ndarray]) -> dict[int, list[int]]:
    """A lagged twin carries actuator states, a plain one does not: one rollout per size."""
    out: dict[int, list[int]] = {}
    for i, s in enumerate(states):
        out.setdefault(len(s), []).append(i)
    return out


def _sampled_rollout(models, states0: np.ndarray, controls: np.ndarray, every: int
                     ) -> tuple[np.ndarray, list[int]]:
    """The full states at step 0, every, 2·every, ...: rollouts of whole sample periods in chunks
    (each chunk starts from the full-physics state the last one ended in, so the result is the
    one long rollout's, bit for bit), and the twins that diverged."""
    n, nstep, nstate = len(models), controls.shape[1], states0.shape[1]
    per_chunk = max(every, (CHUNK_BYTES // max(1, n * nstate * 8)) // every * every)
    out = np.empty((n, nstep // every + 1, nstate))
    out[:, 0] = states0
    current, bad = states0.copy(), set()
    for k0 in range(0, nstep, per_chunk):
        k1 = min(nstep, k0 + per_chunk)
        traj, diverged = engine.rollout(models, current, controls[:, k0:k1])
        out[:, k0 // every + 1: k1 // every + 1] = traj[:, every - 1::every]
        bad |= {i for i, _ in diverged}
        current = traj[:, -1].copy()
        for i in bad:  # a blown-up twin restarts harmlessly; its samples are blanked below
            current[i] = states0[i]
    for i in bad:
        out[i, 1:] = np.nan
    return out, sorted(bad)


def _eta_nu(model: mujoco.MjModel, states: np.ndarray) -> np.ndarray:
    """(n, S, 6) η, ν from full-physics states (n, S, nstate)."""
    qpos, dof = _joint_indices(model)
    eta = states[..., [1 + q for q in qpos]]
    w = states[..., [1 + model.nq + d for d in dof]]
    c, s = np.cos(eta[..., 2]), np.sin(eta[..., 2])
    nu = np.stack([c * w[..., 0] + s * w[..., 1], -s * w[..., 0] + c * w[..., 1], w[..., 2]], axis=-1)
    return np.concatenate([eta, nu], axis=-1)


# ---------------------------------------------------------------- batches

@dataclass(frozen=True)
class _Job:
    """What every batch of a Monte Carlo shares."""

    vessel: Vessel
    mission: Mission
    variation: Variation


@dataclass(frozen=True)
class BatchResult:
    """One batch: tracks (n, S, 6), diverged (indices in the batch), covariance draws rejected,
    the drawn coordinates (n, k) of the uncertainty block."""

    tracks: np.ndarray
    diverged: tuple[int, ...]
    rejected: int
    coordinates: np.ndarray


_caches: dict[int, ModelCache] = {}  # per worker process: compiled models outlive a batch


def _cache(job: _Job) -> ModelCache:
    key = hash((str(job.vessel.mjcf), job.vessel.name))
    if key not in _caches:
        _caches.clear()
        _caches[key] = ModelCache()
    return _caches[key]


def sea_draws(sea, b: Batch) -> list:
    """The batch's realisations of `sea`, one per draw, each from a seed of its own (a stream of the
    batch's seed apart from the one the draws of the parameters take)."""
    rng = np.random.default_rng(np.random.SeedSequence(b.seed, spawn_key=(b.index, 1)))
    return [replace(sea, seed=int(s)) for s in rng.integers(0, 2 ** 31 - 1, size=b.size)]


def run_batch(job: _Job, b: Batch, extra=None) -> BatchResult:
    """A batch of draws through the mission (the task a worker runs)."""
    drawn, rejected = job.variation.draw(job.vessel, b.size, b.rng())
    seas = None if job.mission.sea is None else sea_draws(job.mission.sea, b)
    tracks, diverged = simulate_tracks([d.truth() for d in drawn], job.mission, _cache(job), seas)
    names = job.vessel.uncertainty.get("coordinates", []) if job.variation.covariance else []
    known = coefficients(job.vessel)
    coords = np.array([d.coordinates(names, known) for d in drawn], float).reshape(len(drawn), len(names))
    return BatchResult(tracks, tuple(diverged), rejected, coords)


# ---------------------------------------------------------------- bands

@dataclass(frozen=True)
class Band:
    """Percentiles over the draws at every sample time: values[q] (P, S) for the percentiles
    (%, ascending) of each quantity q of QUANTITIES (SI units: UNITS), and the nominal twin's
    nominal[q] (S,). `level` is the central share the band is read at (0.9: p5 to p95)."""

    t_s: np.ndarray
    percentiles: tuple[float, ...]
    values: dict[str, np.ndarray]
    nominal: dict[str, np.ndarray]
    level: float
    # the draws' own percentiles where `values` were widened by the twin's form error (widen_band); None if not
    parameters_only: dict[str, np.ndarray] | None = None

    def at(self, q: str, p: float) -> np.ndarray:
        return self.values[q][self.percentiles.index(p)]

    def interval(self, q: str, level: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) of the band at `level` (default: its own): a central interval, or
        [0, percentile] of a distance."""
        lo_p, hi_p = level_percentiles(level or self.level, q in ONE_SIDED)
        lo = np.zeros_like(self.nominal[q]) if q in ONE_SIDED else self.at(q, lo_p)
        return lo, self.at(q, hi_p)


def level_percentiles(level: float, one_sided: bool = False) -> tuple[float, float]:
    if not 0.0 < level < 1.0:
        raise TwinError(f"band level must lie in (0, 1), got {level}")
    if one_sided:
        return 0.0, round(100.0 * level, 6)
    return round(50.0 * (1.0 - level), 6), round(50.0 * (1.0 + level), 6)


def band_percentiles(level: float) -> tuple[float, ...]:
    """The percentiles a band keeps: its central interval, the quartiles, the median and the
    one-sided level (for the distance from nominal)."""
    lo, hi = level_percentiles(level)
    return tuple(sorted({lo, 25.0, 50.0, 75.0, hi, level_percentiles(level, True)[1]}))


def relative(tracks: np.ndarray, nominal: np.ndarray) -> dict[str, np.ndarray]:
    """Every quantity of tracks (..., S, 6) against the nominal track (S, 6): the state, the
    heading unwrapped onto the nominal's, and the position along the nominal heading, across it
    (to starboard) and the distance."""
    dn, de = tracks[..., 0] - nominal[:, 0], tracks[..., 1] - nominal[:, 1]
    c, s = np.cos(nominal[:, 2]), np.sin(nominal[:, 2])
    out = {q: tracks[..., i] for i, q in enumerate(STATE)}
    out["psi"] = nominal[:, 2] + wrap_angle(tracks[..., 2] - nominal[:, 2])
    out.update(along=c * dn + s * de, cross=-s * dn + c * de, deviation=np.hypot(dn, de))
    return out


def band_of(tracks: np.ndarray, nominal: np.ndarray, t_s: np.ndarray, level: float) -> Band:
    """The band of tracks (n, S, 6) (NaN rows: diverged draws, left out) around nominal (S, 6)."""
    ok = np.all(np.isfinite(tracks), axis=(1, 2))
    if not ok.any():
        raise TwinError("every draw diverged: no band")
    pcts = band_percentiles(level)
    rel = relative(tracks[ok], nominal)
    nom = relative(nominal[None], nominal)
    return Band(np.asarray(t_s, float), pcts, {q: np.percentile(rel[q], pcts, axis=0) for q in QUANTITIES},
                {q: nom[q][0] for q in QUANTITIES}, level)


# the form error's quantity that bounds a band's quantity where they differ: a distance off the track bounds
# each of its components
FORM_QUANTITY = {"along": "deviation", "cross": "deviation"}


def widen_band(band: Band, block: dict) -> Band:
    """The band widened by the twin's form error (`block`: uncertainty["form_error"], written by identify:
    crossval.form_error), in quadrature with the draws' spread at each percentile's own level, at the
    mission's time as the horizon (crossval.form_error_at: a velocity's error holds beyond the measured
    horizons, a position's grows on). The median stays the draws'.

    Args:
        band: the draws' band (its `parameters_only` None).
        block: the form-error block; quantities it lacks stay as drawn.

    Returns:
        A Band whose `values` are widened and whose `parameters_only` keeps the draws' own percentiles.
    """
    values = {}
    for q in QUANTITIES:
        fq = FORM_QUANTITY.get(q, q)
        drawn, nom = band.values[q], band.nominal[q]
        if fq not in block.get("quantiles", {}):
            values[q] = drawn
            continue
        out = drawn.copy()
        for i, p in enumerate(band.percentiles):
            if q in ONE_SIDED:  # a distance: its percentile p holds the form error's |error| at level p
                if p > 0.0:
                    out[i] = np.sqrt(drawn[i] ** 2 + form_error_at(block, fq, p / 100.0, band.t_s) ** 2)
                continue
            level, side = abs(2.0 * p / 100.0 - 1.0), np.sign(p - 50.0)
            if level == 0.0:
                continue
            half = form_error_at(block, fq, level, band.t_s)
            out[i] = nom + side * np.sqrt(np.clip(side * (drawn[i] - nom), 0.0, None) ** 2 + half ** 2)
        values[q] = out
    return replace(band, values=values, parameters_only=dict(band.values))


def coverage(band: Band, tracks: np.ndarray, level: float | None = None) -> dict[str, float]:
    """Share of the samples of tracks (m, S, 6) (e.g. truths drawn apart from the band's draws)
    inside the band, per quantity; the start (where every twin is the same) left out."""
    nominal = np.column_stack([band.nominal[q] for q in STATE])
    rel = relative(tracks, nominal)
    out = {}
    for q in QUANTITIES:
        lo, hi = band.interval(q, level)
        x = rel[q][:, 1:]
        ok = np.isfinite(x)
        out[q] = float(np.mean(((x >= lo[1:]) & (x <= hi[1:]))[ok])) if ok.any() else float("nan")
    return out


# ---------------------------------------------------------------- the whole Monte Carlo

@dataclass
class MonteCarlo:
    """A Monte Carlo's band, its nominal track, some draws' tracks (for plots) and what it cost."""

    vessel: Vessel
    mission: Mission
    band: Band
    nominal: np.ndarray  # (S, 6)
    sample_tracks: np.ndarray  # (k, S, 6): the first draws, for plots and rerun
    coordinates: np.ndarray  # (n, k) drawn coordinates of the uncertainty block
    draws: int
    diverged: list[int]
    rejected: int
    seed: int
    batch_size: int
    variation: Variation
    executor: str = "local"
    seconds: float = 0.0
    extra: dict = field(default_factory=dict)

    @property
    def simulated_s(self) -> float:
        return self.draws * self.mission.duration_s

    def to_dict(self) -> dict:
        b = self.band
        names = [c["name"] for c in self.vessel.uncertainty.get("coordinates", [])] if self.variation.covariance else []
        ok = np.all(np.isfinite(self.coordinates), axis=1) if len(self.coordinates) else np.zeros(0, bool)
        return {
            "vessel": self.vessel.name, "mission": self.mission.to_dict(), "draws": self.draws,
            "diverged": len(self.diverged), "diverged_draws": self.diverged[:100], "rejected": self.rejected,
            "seed": self.seed, "batch_size": self.batch_size, "variation": self.variation.to_dict(),
            "executor": self.executor, "seconds": round(self.seconds, 3),
            "simulated_s_per_s": round(self.simulated_s / self.seconds, 1) if self.seconds > 0 else None,
            "level": b.level, "percentiles": list(b.percentiles), "units": dict(UNITS), "t_s": b.t_s,
            "nominal": {q: b.nominal[q] for q in QUANTITIES},
            "band": {q: {_tag(p): b.values[q][i] for i, p in enumerate(b.percentiles)} for q in QUANTITIES},
            "final": {q: {_tag(p): float(b.values[q][i, -1]) for i, p in enumerate(b.percentiles)}
                      for q in QUANTITIES},
            "widened_by_form_error": b.parameters_only is not None,
            **({"final_parameters_only": {q: {_tag(p): float(b.parameters_only[q][i, -1])
                                              for i, p in enumerate(b.percentiles)} for q in QUANTITIES}}
               if b.parameters_only is not None else {}),
            "coordinates": {"names": names,
                            "mean": np.mean(self.coordinates[ok], axis=0) if ok.any() and names else [],
                            "sd": np.std(self.coordinates[ok], axis=0) if ok.any() and names else []},
            **self.extra,
        }

    def to_csv_text(self) -> str:
        """One row per sample time: t_s, then per quantity its nominal and its percentiles."""
        b = self.band
        head, cols = ["t_s"], [b.t_s]
        for q in QUANTITIES:
            head.append(f"{q}_{UNITS[q]}_nominal")
            cols.append(b.nominal[q])
            for i, p in enumerate(b.percentiles):
                head.append(f"{q}_{UNITS[q]}_{_tag(p)}")
                cols.append(b.values[q][i])
        rows = np.column_stack(cols)
        return ",".join(head) + "\n" + "".join(",".join(f"{x:.9g}" for x in row) + "\n" for row in rows)


def _tag(p: float) -> str:
    return f"p{p:02g}"


def check_variation(vessel: Vessel, variation: Variation) -> None:
    """TwinError unless the draws of `variation` can differ, and the vessel has what they draw from."""
    if not variation.varies:
        raise TwinError("nothing varies between the draws: give a vessel file with an uncertainty block "
                        "(twin identify writes one) or --vary / --effect ranges")
    if variation.covariance and not vessel.uncertainty:
        raise TwinError(f"vessel '{vessel.name}' carries no identification uncertainty: use a vessel file "
                        "written by `twin identify`, or give --vary / --effect ranges with --no-covariance")
    if variation.covariance:
        check_drawable(vessel)


def run(vessel: Vessel, mission: Mission, draws: int, *, seed: int = 0, variation: Variation | None = None,
        level: float = 0.9, batch_size: int = 64, executor: Executor | None = None, keep_tracks: int = 50,
        progress: Progress | None = None, form_error: bool = True) -> MonteCarlo:
    """`draws` twins of `vessel` through `mission` (module docstring), in batches of batch_size
    seeded from `seed`; the same numbers whichever executor runs them. Default variation: the
    vessel file's covariance (TwinError without one). Where the vessel file carries the twin's error
    on runs left out of its fit (uncertainty["form_error"]), the band is widened by it (widen_band)
    unless `form_error` is False: the draws spread the coefficients only, and a twin is wrong in its
    form as well as in its numbers."""
    variation = variation or Variation(covariance=True)
    check_variation(vessel, variation)
    level_percentiles(level)
    batches = plan(draws, batch_size, seed)
    executor = executor or LocalExecutor()
    started = time.perf_counter()
    job = _Job(vessel, mission, variation)
    results = gather(executor, run_batch, job, batches, progress=progress)
    tracks = np.concatenate([r.tracks for r in results])
    diverged = [b.start + i for b, r in zip(batches, results) for i in r.diverged]
    nominal, bad = simulate_tracks([vessel], mission, _cache(job))
    if bad:
        raise TwinError(f"the nominal twin of '{vessel.name}' diverges on this mission")
    t_s = np.arange(tracks.shape[1]) * mission.sample_dt_s
    band = band_of(tracks, nominal[0], t_s, level)
    block = vessel.uncertainty.get("form_error") if form_error else None
    if block and block.get("quantiles"):
        band = widen_band(band, block)
    coords = np.concatenate([r.coordinates for r in results])
    return MonteCarlo(vessel, mission, band, nominal[0], tracks[:keep_tracks], coords, draws, diverged,
                      sum(r.rejected for r in results), seed, batch_size, variation, executor.name,
                      time.perf_counter() - started)


# ---------------------------------------------------------------- against a recording

@dataclass(frozen=True)
class _RecordingJob:
    vessel: Vessel
    preps: list
    windows: list
    variation: Variation
    every: int
    wind: str | None = None


@dataclass
class RecordingCoverage:
    """The band of free runs from a recording's measured states against what it measured.

    inside[q]: share of the measured samples (after each window's start) inside the band at
    `level`; inside_by_horizon[q][k]: the same at horizon_s[k] into the windows. lo, hi,
    measured: (W, S) per quantity (SI units), for plots."""

    level: float
    inside: dict[str, float]
    horizon_s: np.ndarray
    inside_by_horizon: dict[str, np.ndarray]
    windows: int
    window_s: float
    draws: int
    diverged: int
    rejected: int
    lo: dict[str, np.ndarray] = field(repr=False, default_factory=dict)
    hi: dict[str, np.ndarray] = field(repr=False, default_factory=dict)
    measured: dict[str, np.ndarray] = field(repr=False, default_factory=dict)
    # the share inside the parameters' spread alone, where the band was widened by the twin's form error
    inside_parameters_only: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"level": self.level, "inside": self.inside, "inside_parameters_only": self.inside_parameters_only,
                "horizon_s": self.horizon_s,
                "inside_by_horizon": self.inside_by_horizon, "windows": self.windows, "window_s": self.window_s,
                "draws": self.draws, "diverged": self.diverged, "rejected": self.rejected}

    def text(self) -> str:
        """One line per quantity: how often the recording is inside the band (should be ≈ level)."""
        widened = bool(self.inside_parameters_only)
        dropped = (f" ({self.diverged} more diverged on the recording and "
                   f"{'is' if self.diverged == 1 else 'are'} left out)" if self.diverged else "") + \
            (f" ({self.rejected} redrawn as unphysical: damping that stops dissipating, or a mass matrix not "
             "positive-definite)" if self.rejected else "")
        lines = [f"band of {self.draws} draws{dropped}, {self.windows} free runs of {self.window_s:g} s from measured "
                 f"states: share of the recording inside the {100 * self.level:g} % band"
                 + (" (the parameters' spread widened by the twin's error on left-out runs; in brackets the "
                    "parameters' spread alone)" if widened else "")]
        for q, share in self.inside.items():
            alone = f"  ({100 * self.inside_parameters_only[q]:5.1f} %)" if widened else ""
            what = f"  {BAND_MEANING[q]}" if q in BAND_MEANING else ""
            lines.append(f"  {q:10s} {100 * share:5.1f} %{alone}{what}")
        return "\n".join(lines)


RECORDING_QUANTITIES = ("north", "east", "psi", "u", "v", "r", "deviation")


def run_recording_batch(job: _RecordingJob, b: Batch, extra=None) -> BatchResult:
    """A batch of draws as free runs over the recording's windows: tracks (n, W, S, 6)."""
    drawn, rejected = job.variation.draw(job.vessel, b.size, b.rng())
    tracks = np.stack([_free_runs(d.truth(), job, _recording_cache(job)) for d in drawn])
    diverged = tuple(i for i in range(len(drawn)) if not np.all(np.isfinite(tracks[i])))
    return BatchResult(tracks, diverged, rejected, np.zeros((len(drawn), 0)))


_recording_caches: dict[int, ModelCache] = {}


def _recording_cache(job: _RecordingJob) -> ModelCache:
    key = hash((str(job.vessel.mjcf), job.vessel.name, "recording"))
    if key not in _recording_caches:
        _recording_caches.clear()
        _recording_caches[key] = ModelCache()
    return _recording_caches[key]


def _free_runs(vessel: Vessel, job: _RecordingJob, cache: ModelCache) -> np.ndarray:
    """(W, S, 6) one twin's free runs, velocities as the recording's smoother sees them, every
    `every`-th grid sample; a diverged window is NaN throughout."""
    pred = predict(vessel, job.preps, job.windows, cache, wind=job.wind)[0]
    nu = as_measured(pred.nu, job.preps, job.windows)
    out = np.concatenate([pred.eta, nu], axis=-1)[:, ::job.every]
    for j, _ in pred.diverged:
        out[j] = np.nan
    return out


def band_coverage(vessel: Vessel, preps: list[Prepared], *, draws: int = 200, seed: int = 0, level: float = 0.9,
                  window_s: float = 30.0, sample_dt_s: float = 1.0, variation: Variation | None = None,
                  batch_size: int = 16, executor: Executor | None = None,
                  progress: Progress | None = None, wind: str | None = None,
                  form_error: bool = True) -> RecordingCoverage:
    """How often prepared recordings fall inside the Monte Carlo band of free runs of window_s
    from their measured states, driven by their inputs (non-overlapping windows); `vessel` as the
    recordings' sensors see it (e.g. with each log's compass calibration); wind "measured": each
    recording's measured wind a known input.

    The draws spread the identified parameters only. Where the vessel file carries the twin's
    error on runs left out of its fit (uncertainty["form_error"], written by identify:
    crossval.form_error), the band is widened by it, in quadrature at each horizon, unless
    `form_error` is False: a twin is wrong in its form as well as in its numbers, and a band without
    that covers new runs far less often than its level says."""
    variation = variation or Variation(covariance=True)
    if variation.covariance:
        check_drawable(vessel)
    level_percentiles(level)
    windows = make_windows(preps, window_s, window_s, min_length_s=window_s)
    if not windows:
        raise TwinError(f"the recordings have no segment of {window_s:g} s with PWM for a free run")
    grid = preps[0].settings.grid_dt
    every = max(1, int(round(sample_dt_s / grid)))
    job = _RecordingJob(vessel, preps, windows, variation, every, wind)
    results = gather(executor or LocalExecutor(), run_recording_batch, job, plan(draws, batch_size, seed),
                     progress=progress)
    tracks = np.concatenate([r.tracks for r in results])  # (n, W, S, 6)
    nominal = _free_runs(vessel, job, ModelCache())
    eta, nu = measured(preps, windows)
    meas = np.concatenate([eta, nu], axis=-1)[:, ::every]
    widen = vessel.uncertainty.get("form_error") if form_error else None
    return _recording_coverage(tracks, nominal, meas, level, windows, window_s, every * grid,
                               sum(len(r.diverged) for r in results), sum(r.rejected for r in results), widen)


def nominal_q(nominal: np.ndarray, q: str) -> np.ndarray:
    """(W, S) the nominal free runs' own value of quantity q (0 for the distance from them)."""
    if q == "deviation":
        return np.zeros(nominal.shape[:2])
    return nominal[..., STATE.index(q)]


def _widened(lo: np.ndarray, hi: np.ndarray, nom: np.ndarray, half: np.ndarray, one_sided: bool
             ) -> tuple[np.ndarray, np.ndarray]:
    """The band [lo, hi] around nom widened by a form-error half-width (per horizon), in quadrature
    on each side."""
    up = nom + np.sqrt(np.clip(hi - nom, 0.0, None) ** 2 + half ** 2)
    if one_sided:
        return lo, up
    return nom - np.sqrt(np.clip(nom - lo, 0.0, None) ** 2 + half ** 2), up


def _recording_coverage(tracks: np.ndarray, nominal: np.ndarray, meas: np.ndarray, level: float,
                        windows: list[Window], window_s: float, dt_s: float, diverged: int,
                        rejected: int, widen: dict | None = None) -> RecordingCoverage:
    ok = np.all(np.isfinite(tracks) | np.isnan(nominal)[None], axis=(1, 2, 3))
    if not ok.any():
        raise TwinError("every draw diverged on the recording: no band")
    W, S = nominal.shape[:2]
    lo, hi, got = {}, {}, {}
    per_window = [(relative(tracks[ok][:, j], nominal[j]), relative(meas[j][None], nominal[j])) for j in range(W)]
    for q in RECORDING_QUANTITIES:
        lo_p, hi_p = level_percentiles(level, q in ONE_SIDED)
        draws_q = np.stack([d[q] for d, _ in per_window], axis=1)  # (n, W, S)
        lo[q] = np.zeros((W, S)) if q in ONE_SIDED else np.percentile(draws_q, lo_p, axis=0)
        hi[q] = np.percentile(draws_q, hi_p, axis=0)
        got[q] = np.stack([m[q][0] for _, m in per_window])
    parameters_only = {q: _share_inside(got[q], lo[q], hi[q])[0] for q in RECORDING_QUANTITIES} if widen else {}
    for q in RECORDING_QUANTITIES:
        if widen and q in widen.get("quantiles", {}):
            lo[q], hi[q] = _widened(lo[q], hi[q], nominal_q(nominal, q), form_error_at(widen, q, level, dt_s *
                                                                                      np.arange(S)), q in ONE_SIDED)
    inside, by_horizon = {}, {}
    for q in RECORDING_QUANTITIES:
        inside[q], by_horizon[q] = _share_inside(got[q], lo[q], hi[q])
    return RecordingCoverage(level, inside, dt_s * np.arange(1, S), by_horizon, W, window_s, int(ok.sum()),
                             diverged, rejected, lo, hi, got, parameters_only)


def _share_inside(got: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[float, np.ndarray]:
    """The share of the measured samples after each window's start inside [lo, hi], and per horizon."""
    x = got[:, 1:]
    hit = (x >= lo[:, 1:]) & (x <= hi[:, 1:])
    known = np.isfinite(x) & np.isfinite(lo[:, 1:]) & np.isfinite(hi[:, 1:])
    share = float(np.mean(hit[known])) if known.any() else float("nan")
    return share, np.array([float(np.mean(hit[:, k][known[:, k]])) if known[:, k].any() else np.nan
                            for k in range(x.shape[1])])


def recording_coverage(vessel: Vessel, recordings, *, calibrated: bool = True, **options) -> RecordingCoverage:
    """`band_coverage` of recordings (twin.recording.Recording) prepared as `twin evaluate`
    prepares them: each log's compass offset from its own GNSS track unless `calibrated` is
    False. Options: those of band_coverage. What `twin evaluate --band` calls."""
    # late: the fitting stack, 0.28 s on top of this module (`twin montecarlo`), only for `twin evaluate --band`
    from ..ident.identify import calibrate, prepared

    if calibrated:
        vessel, _ = calibrate(recordings, vessel)
    return band_coverage(vessel, prepared(recordings, vessel), **options)
