"""The Python API: what the `twin` command does, as functions returning typed results with short,
rounded reprs, `to_dict()` for JSON and a titled `table()` where a table is what one looks at.

    import twin
    v = twin.load_vessel("blueboat")
    recs = [twin.read_recording(p) for p in paths]            # Recording (twin info)
    prep = twin.prepare_recording(recs[0], v)                 # Prepared: as the vessel's sensors see it
    ident = twin.identify(recs[:7], v)                        # Identification (twin identify)
    score = twin.evaluate(ident.vessel, recs[7:])             # Evaluation (twin evaluate)
    found = twin.diagnose_recordings(recs[:7], ident.vessel)  # Diagnosis (twin diagnose)
    j = twin.judge(recs[:7], ident.vessel, "current=0.1,90")  # Judgement (twin diagnose --given)
    run = twin.simulate(ident.vessel, "zigzag", duration_s=120)

Every function checks its input as the command does and raises `twin.TwinError` with one
sentence saying what is wrong (no recordings, a recording the vessel cannot be driven by, ...).
No exported name is also the name of a subpackage (`twin.prepare`, `twin.diagnose` are
packages), so importing any part of the package never replaces a function.
"""
from __future__ import annotations

import inspect
import math
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

from .drive import InputSeries, inputs_mismatch
from .engine.mjcf import compile_vessel
from .engine.parameters import effective_parameters as _effective_parameters
from .diagnose.doctor import Diagnosis as _Found
from .diagnose.search import excess_shown
from .errors import TwinError
from .files import same_file
from .run import Run
from .simulation import Simulation, simulate, simulate_run
from .verify.crosscheck import crosscheck as _crosscheck
from .ident.identify import Identification as _Identification
from .verify.validate import Validation as _Validation, validate as _validate
from .vessel import Vessel, load as load_vessel, save as _save

__all__ = ["Run", "Vessel", "InputSeries", "Validation", "Identification", "Simulation", "Evaluation", "Score", "Effect",
           "Parameter", "Judgement", "Diagnosis", "Table", "TwinError", "load_vessel", "save_vessel", "simulate",
           "simulate_run",
           "crosscheck", "effective_parameters", "compile_vessel", "validate", "read_recording",
           "prepare_recording", "calibrate", "identify", "evaluate", "diagnose_recordings", "judge"]


def save_vessel(vessel: Vessel | str, path, *, force: bool = False) -> Path:
    """`--out` of `twin identify`: a vessel (a twin.Vessel, a shipped vessel's name or a vessel file)
    written as a vessel file at `path` (.json); a file there is kept unless `force`, as the command
    keeps it."""
    _new_output(path, (".json",), force)
    return _save(_vessel(vessel), path)


def _new_output(path, formats: tuple[str, ...], force: bool) -> None:
    """An output path the API writes, checked as the commands check theirs: its format, and a file
    already there kept unless `force` (it may be a log or a twin the user made)."""
    p = Path(path)
    if p.suffix.lower() not in formats:
        raise TwinError(f"'{p}': unknown format '{p.suffix or '(none)'}' (use {', '.join(formats)})")
    if p.exists() and not force:
        raise TwinError(f"'{p}' exists: it is kept (force=True replaces it)")


def _known_options(function, options: dict, what: str) -> None:
    """Refuse, in one sentence, an option `function` does not take (a typo would otherwise surface as
    a TypeError from deep inside)."""
    known = [n for n, p in inspect.signature(inspect.unwrap(function)).parameters.items()
             if p.kind is p.KEYWORD_ONLY or (p.kind is p.POSITIONAL_OR_KEYWORD and p.default is not p.empty)]
    unknown = sorted(set(options) - set(known))
    if unknown:
        raise TwinError(f"{what}: unknown option{'s' if len(unknown) > 1 else ''} {', '.join(unknown)} "
                        f"(known: {', '.join(known)})")


class Validation(_Validation):
    """`twin validate`: every quantity of one vessel and mass case side by side, each column a way of
    obtaining it (`.quantities`, `.flagged()`, `table()`, `to_dict()`)."""

    def table(self) -> Table:
        """One row per quantity: its columns as obtained (analytic, the vessel file's table, the engine,
        the mesh, an independent estimate), the largest relative difference from the reference, flag."""
        rows = [{"quantity": q.name, "unit": q.unit, "analytic": q.analytic, "table": q.table, "engine": q.engine,
                 "mesh": q.mesh, "independent": q.independent, "rel_diff": q.rel_diff, "flag": q.flag or ""}
                for q in self.quantities]
        return Table(rows, f"{self.vessel} ({self.case}): each quantity by every way of obtaining it")

    def to_dict(self) -> dict:
        return {"vessel": self.vessel, "case": self.case, "quantities": [dict(r) for r in self.table()]}


def validate(vessel: Vessel | str, case: str | None = None) -> Validation:
    """`twin validate`: every quantity of one vessel and mass case side by side (`.quantities`, `.flagged()`,
    `table()`)."""
    v = _vessel(vessel)
    found = _validate(v if case is None else v.with_case(case))
    return Validation(**{f.name: getattr(found, f.name) for f in fields(found)})


def effective_parameters(vessel: Vessel | str) -> dict:
    """`twin params --json`: M, M_RB, M_A, damping (Fossen signs), thrusters, GNSS lever arm of a vessel
    (a twin.Vessel, a shipped vessel's name or a vessel file)."""
    return _effective_parameters(_vessel(vessel))


def crosscheck(vessel: Vessel | str, duration_s: float = 120.0, only: list[str] | None = None,
               six_dof: bool = False) -> list:
    """`twin crosscheck`: the engine against the analytic 3-DOF model over a zig-zag, one Result per case
    (`.passed`, `.position_err_m`, `.heading_err_deg`; `to_dict()`)."""
    from .verify.crosscheck import cases

    if isinstance(duration_s, bool) or not isinstance(duration_s, (int, float)) or not (
            math.isfinite(duration_s) and duration_s > 0):
        raise TwinError(f"duration_s must be a positive, finite number of seconds, got {duration_s!r}")
    v = _vessel(vessel)
    only = [only] if isinstance(only, str) else only
    known = [c.name for c in cases(v)]
    unknown = [n for n in only or () if n not in known]
    if unknown:  # a case not run would read as passed
        raise TwinError(f"only={unknown}: unknown crosscheck case (the force terms checked one by one: "
                        f"{', '.join(known)})")
    return _crosscheck(v, duration_s, only, six_dof=six_dof)


def _names(given, what: str, which: str) -> tuple[str, ...]:
    """One name or a non-empty list of names (a name alone is a name, not its letters)."""
    names = (given,) if isinstance(given, str) else given
    if not isinstance(names, (list, tuple)) or not names or not all(isinstance(n, str) for n in names):
        raise TwinError(f"{what}: give one or more names ({which}), got {given!r:.60}")
    return tuple(names)


def _vessel(vessel: Vessel | str) -> Vessel:
    if isinstance(vessel, (str, Path)):
        return load_vessel(str(vessel))
    if not isinstance(vessel, Vessel):
        raise TwinError(f"expected a vessel (a twin.Vessel, a shipped vessel's name or a vessel file), "
                        f"got {type(vessel).__name__}")
    return vessel


def _recordings(recordings, vessel: Vessel | None = None) -> list:
    """Recordings from paths or Recording objects, checked as the command checks them: at least one,
    each one at most once, and each one able to drive `vessel`."""
    from .formats import read_recording as read
    from .recording import Recording, check_no_shared_stretch

    kinds = (str, Path, Recording)
    if isinstance(recordings, kinds):
        items = [recordings]
    elif isinstance(recordings, (list, tuple)) and all(isinstance(r, kinds) for r in recordings):
        items = list(recordings)
    else:
        raise TwinError(f"recordings are a path, a twin.Recording or a list of them, got {recordings!r:.80}")
    if not items:
        raise TwinError("no recordings given: give one or more recordings (paths or twin.read_recording(...))")
    paths = [Path(r) for r in items if not isinstance(r, Recording)]
    for k, p in enumerate(paths):  # one log twice would be judged against itself as a left-out run
        if any(same_file(p, q) for q in paths[:k]):
            raise TwinError(f"'{p}' is given twice: give each recording once")
    recs = [r if isinstance(r, Recording) else read(r) for r in items]
    seen: dict[int, int] = {}
    for i, r in enumerate(recs):
        if id(r) in seen:
            raise TwinError(f"recording {i} is recording {seen[id(r)]} again ('{r.source}'): give each recording once")
        seen[id(r)] = i
    check_no_shared_stretch(recs)
    if vessel is not None:
        for r in recs:
            _drivable(r, vessel)
    return recs


def _drivable(rec, vessel: Vessel) -> None:
    """A recording whose inputs cannot drive the vessel (PWM for a propeller-and-rudder ship, a
    ship's propeller and rudder for a PWM boat) is refused, as `twin identify` refuses it."""
    kind = "pwm" if len(rec.pwm) else ("propeller_rudder" if len(rec.prop_rudder) else None)
    wants = {"t200": "pwm", "propeller_rudder": "propeller_rudder"}.get(vessel.thrusters.kind)
    if kind is not None and wants is not None and kind != wants:
        raise TwinError(f"'{rec.source}' is a recording of another kind of vessel: "
                        f"{inputs_mismatch(vessel.name, wants, kind)}")


def read_recording(path, channels: dict | None = None):
    """`twin info`'s reader: an ArduPilot .bin/.tlog, a CSV (generic or a known dataset's layout) or
    an MCAP file → Recording."""
    from .formats import read_recording as read

    return read(path, channels=channels)


def prepare_recording(recording, vessel: Vessel | str | None = None, calibrated: bool = True):
    """A recording made ready for fitting [Morel-2024 §5.1]: with a vessel, as its sensors see it (lever
    arm, heading corrections) and, when `calibrated`, with the log's own compass offset estimated
    from its GNSS track; without one, the antenna's positions as logged."""
    from .ident.identify import calibrate as calibrate_logs, prepared
    from .prepare import prepare as bare

    if vessel is None:
        return bare(_recordings(recording)[0])
    v = _vessel(vessel)
    rec = _recordings(recording, v)[0]
    if calibrated:
        v, _ = calibrate_logs([rec], v)
    return prepared([rec], v)[0]


def calibrate(recordings, vessel: Vessel | str) -> list:
    """Each log's compass offset from its kinematics (twin.fit.calibrate.LogCalibration)."""
    from .ident.identify import calibrate as calibrate_logs

    v = _vessel(vessel)
    return calibrate_logs(_recordings(recordings, v), v)[1]


def _in_sea(vessel: Vessel, sea) -> Vessel:
    """The vessel with the steady drift of `sea` (a Sea, `--sea` text or None) a known flow."""
    from .engine.sixdof import check_sea_for, with_known_sea
    from .physics.waves import Sea, parse_sea

    if sea is None:
        return vessel
    sea = sea if isinstance(sea, Sea) else parse_sea(str(sea))
    check_sea_for(vessel, sea)
    return with_known_sea(vessel, sea)


def identify(recordings, vessel: Vessel | str, sea=None, **options):
    """`twin identify`: an Identification (.vessel is the identified twin; options as
    twin.ident.identify.identify); sea (a physics.waves.Sea or `--sea` text such as
    "0.3,2.5,30,4"): the sea the recordings were made in, its Stokes drift a known flow and its mean
    load on the hull a known force (`twin identify --sea`; .vessel carries neither)."""
    from .engine.sixdof import without_known_sea
    from .ident.identify import identify as run

    _known_options(run, options, "identify")
    v = _in_sea(_vessel(vessel), sea)
    for name in ("params", "groups"):  # one name alone is a name, not its letters
        if isinstance(options.get(name), str):
            options[name] = (options[name],)
    result = run(_recordings(recordings, v), v, **options)
    result = replace(result, vessel=without_known_sea(result.vessel)) if sea is not None else result
    return Identification(**{f.name: getattr(result, f.name) for f in fields(result)})


class Identification(_Identification):
    """`twin identify`: the twin it writes (`.vessel`), the fit, the choices and what they were judged
    by, each log's calibration (`table()`: each coefficient, its prior and what was identified)."""

    def table(self) -> Table:
        """One row per coefficient of the fit: unit, prior, identified, its 1-σ, and how the recordings
        moved it (the note `twin identify` prints)."""
        rows = [{"coefficient": e.name, "unit": e.unit, "prior": e.prior, "identified": e.value, "sigma": e.sigma,
                 "note": e.note} for e in (self.fit.estimates if self.fit else [])]
        return Table(rows, f"{self.vessel.name}: the coefficients identified")


class Table(list):
    """Rows (dicts with the same keys) under a title, printed as aligned columns with numbers to 4
    significant figures; still a list of dicts for code (`to_dict()` for JSON)."""

    def __init__(self, rows=(), title: str = ""):
        super().__init__(rows)
        self.title = title

    def __str__(self) -> str:
        head = [self.title] if self.title else []
        if not self:
            return "\n".join(head + ["(no rows)"])
        keys = list(self[0])
        cells = [[_cell(row.get(k)) for k in keys] for row in self]
        widths = [max(len(k), *(len(c[i]) for c in cells)) for i, k in enumerate(keys)]
        # numbers right-aligned under a right-aligned head, words left-aligned under theirs
        numeric = [all(isinstance(row.get(k), (int, float)) or row.get(k) is None for row in self) for k in keys]
        lines = head + ["  ".join(k.rjust(w) if n else k.ljust(w) for k, w, n in zip(keys, widths, numeric)).rstrip()]
        lines += ["  ".join(c.rjust(w) if n else c.ljust(w) for c, w, n in zip(row, widths, numeric)).rstrip()
                  for row in cells]
        return "\n".join(lines)

    __repr__ = __str__

    def to_dict(self) -> dict:
        return {"title": self.title, "rows": [dict(r) for r in self]}


def _cell(value) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


# units of the velocities and the yaw rate in every score: r in degrees per second, as in the reports
UNITS = {"u": "m/s", "v": "m/s", "r": "°/s"}


@dataclass(frozen=True)
class Score:
    """How well the twin predicts one velocity at one horizon: R² and the mean absolute error (in
    `unit`: m/s for u and v, °/s for r) over `n` samples; `calibrated`: with each log's compass
    offset applied."""

    horizon: str
    dof: str
    r2: float | None
    mae: float | None
    n: int
    calibrated: bool = True

    @property
    def unit(self) -> str:
        return UNITS[self.dof]

    def __repr__(self) -> str:
        r2 = "-" if self.r2 is None else f"{self.r2:.3f}"
        mae = "-" if self.mae is None else f"{self.mae:.3g} {self.unit}"
        return f"Score({self.horizon} {self.dof}: R² {r2}, MAE {mae}, n {self.n})"

    def to_dict(self) -> dict:
        return {"horizon": self.horizon, "dof": self.dof, "r2": self.r2, "mae": self.mae, "unit": self.unit,
                "n": self.n, "calibrated": self.calibrated}


def _scores(metrics: dict, calibrated: bool) -> list[Score]:
    import math

    out = []
    for horizon, m in metrics.items():
        for d in "uvr":
            row = m.get(d) or {}
            mae = row.get("mae")
            if mae is not None and d == "r":
                mae = math.degrees(mae)
            out.append(Score(horizon, d, row.get("r2"), mae, int(row.get("n") or 0), calibrated))
    return out


@dataclass
class Evaluation:
    """`twin evaluate`: R² and MAE per DOF and horizon (`scores`; `score("u")`), with and without
    each log's compass calibration, and the calibrations; by_manoeuvre: where the free runs of the
    fit's window (10 s for a small boat, 30 s for a slow ship: its `horizon_s`) miss
    (fit.evaluate.misfit_by_manoeuvre), read against what the twin's fit saw when identify wrote it;
    by_state: where they miss by a measured state, when one was asked for (fit.evaluate.StateBand);
    stand_ins: the coefficients the twin's fit moved beyond what their beliefs allow (name, unit, value,
    prior, from_prior_sigmas), which hold beyond the fitted runs only as far as what they stand in for."""

    vessel: str
    metrics: dict
    metrics_uncalibrated: dict
    calibrations: list
    by_manoeuvre: dict = field(default_factory=dict)
    by_state: list = field(default_factory=list)
    stand_ins: list = field(default_factory=list)

    @property
    def applied(self) -> bool:
        """Whether any log's compass offset was applied (else the scores are the log's as logged)."""
        return any(c.heading_bias_deg is not None for c in self.calibrations)

    @property
    def scores(self) -> list[Score]:
        """Every score: calibrated first, then without the calibrations; where no log's compass
        offset was applied, the scores as logged alone (calibrated False)."""
        if not self.applied:
            return _scores(self.metrics_uncalibrated, False)
        return _scores(self.metrics, True) + _scores(self.metrics_uncalibrated, False)

    def score(self, dof: str, horizon: str = "free_run_10s", calibrated: bool = True) -> Score:
        """One score: `dof` u, v or r; `horizon` one_step, free_run_10s, free_run_30s or full; with
        `calibrated`, each log's compass calibration applied (where none was, the score as logged)."""
        for s in self.scores:
            if (s.dof, s.horizon, s.calibrated) == (dof, horizon, calibrated and self.applied):
                return s
        raise TwinError(f"no score for {dof} at {horizon} (horizons: {', '.join(self.metrics)}; dof u, v, r)")

    def __repr__(self) -> str:
        cells = ", ".join(f"{s.dof} {s.r2:.3f}" for s in self.scores
                          if s.horizon == "free_run_10s" and s.r2 is not None and s.calibrated == self.applied)
        return f"Evaluation({self.vessel}: 10-s free runs R² {cells or '-'})"

    def table(self) -> Table:
        """One row per horizon and DOF with samples: horizon, dof, r2, mae (m/s; r in °/s), n,
        calibrated; the rows without each log's compass calibration only where it changed a score."""
        rows = [{k: v for k, v in s.to_dict().items() if k != "unit"} for s in self.scores if s.n]
        calibrated = {(r["horizon"], r["dof"]): (r["r2"], r["mae"]) for r in rows if r["calibrated"]}
        if all(calibrated.get((r["horizon"], r["dof"])) == (r["r2"], r["mae"]) for r in rows if not r["calibrated"]):
            rows = [r for r in rows if r["calibrated"]]
        applied = "" if self.applied else ", as logged: no log's compass offset was applied"
        return Table(rows, f"{self.vessel}: how the twin predicts the recordings (MAE in m/s, r in °/s){applied}")

    def to_dict(self) -> dict:
        # the metrics as fit.evaluate gives them, in SI (r's MAE in rad/s, where table() shows °/s)
        return {"vessel": self.vessel, "units": {"u": "m/s", "v": "m/s", "r": "rad/s"},
                "metrics": self.metrics, "metrics_uncalibrated": self.metrics_uncalibrated,
                "calibrations": [c.to_dict() for c in self.calibrations], "by_manoeuvre": self.by_manoeuvre,
                "by_state": [asdict(b) for b in self.by_state], "stand_ins": self.stand_ins}


def evaluate(vessel: Vessel | str, recordings, stride_s: float = 2.0, wind: str | None = None,
             sea=None, by: str | None = None) -> Evaluation:
    """How the twin predicts recordings (one step, 10-s and 30-s free runs, whole segments), and
    where its free runs miss, by manoeuvre and beyond what its fit saw; wind "measured": each
    recording's measured wind a known input (`twin evaluate --wind-measured`); sea (a
    physics.waves.Sea or `--sea` text): the sea they were made in, its Stokes drift a known flow and
    its mean load on the hull a known force (`--sea`); by (speed, yaw_rate, input_0, input_1 or
    rest): also where they miss by that measured state (`--by`)."""
    from .fit.coverage import from_dict
    from .fit.evaluate import STATE_NAMES, TwinPredictor, evaluate as run, misfit_by_manoeuvre, misfit_by_state, \
        percentile_edges
    from .fit.windows import ModelCache
    from .ident.identify import calibrate as calibrate_logs, check_wind, manoeuvre_horizon_s, prepared

    v = _in_sea(_vessel(vessel), sea)
    recs = _recordings(recordings, v)
    check_wind(recs, wind, v)
    if not stride_s > 0:
        raise TwinError(f"stride_s must be a positive number of seconds, got {stride_s:g}")
    seen = from_dict(v.uncertainty["fitted_on"], f"{v.name}: uncertainty.fitted_on") \
        if "fitted_on" in v.uncertainty else None
    if by is not None and by not in STATE_NAMES:
        raise TwinError(f"by={by!r}: unknown state (known: {', '.join(STATE_NAMES)})")
    calibrated, calibrations = calibrate_logs(recs, v)
    preps = prepared(recs, calibrated)
    edges = percentile_edges(preps, STATE_NAMES[by], f"by={by!r}") if by else ()
    predictor, horizon = TwinPredictor(calibrated, ModelCache(), wind), manoeuvre_horizon_s(v, seen)
    bands = misfit_by_state(predictor, preps, horizon, STATE_NAMES[by], edges, stride_s) if by else []
    return Evaluation(v.name, run(calibrated, preps, stride_s=stride_s, wind=wind),
                      run(v, prepared(recs, v), stride_s=stride_s, wind=wind), calibrations,
                      misfit_by_manoeuvre(predictor, preps, horizon, stride_s, vessel=calibrated, fitted=seen), bands,
                      list(v.uncertainty.get("stand_ins", [])))


@dataclass(frozen=True)
class Parameter:
    """One value of a named effect: name, value, unit and its 95 % interval (None where the fit
    holds it)."""

    name: str
    value: float
    unit: str
    ci95: tuple[float, float] | None = None

    def __repr__(self) -> str:
        unit = f" {self.unit}" if self.unit else ""
        ci = f" [{self.ci95[0]:.3g}, {self.ci95[1]:.3g}]" if self.ci95 else ""
        return f"{self.name} {self.value:.4g}{unit}{ci}"


@dataclass(frozen=True)
class Judgement:
    """How the held-out blocks judge a change of the twin (the diagnosis's rule): `verdict` in words
    ("earns its place", "does not earn its place", "contradicted"), z of the blocks' votes, the share
    of the held-out misfit removed (`held_out_gain`) and of the misfit above the noise
    (`excess_gain`), the blocks for and against, the windows it changed (`affected`), parameters
    fitted to an unphysical edge; `str()` says it in a sentence. The diagnosis's own Evidence is
    `evidence` (its other figures, e.g. `dof_rel`, are read through)."""

    effects: tuple[str, ...]
    verdict: str
    z: float
    held_out_gain: float
    excess_gain: float
    blocks_for: int
    blocks_against: int
    affected: int = 0
    at_edge: tuple[str, ...] = ()
    sentence: str = ""
    evidence: object = field(default=None, repr=False, compare=False)

    def earns_its_place(self) -> bool:
        return self.verdict == "earns its place"

    def __getattr__(self, name):
        if name == "evidence" or self.__dict__.get("evidence") is None:
            raise AttributeError(name)
        return getattr(self.__dict__["evidence"], name)

    def __repr__(self) -> str:
        return (f"Judgement({', '.join(self.effects) or 'no change'}: {self.verdict}; z {self.z:.2f}, held-out gain "
                f"{100 * self.held_out_gain:.1f} %, blocks {self.blocks_for} for / {self.blocks_against} against)")

    def __str__(self) -> str:
        return self.sentence or repr(self)

    def to_dict(self) -> dict:
        return {"effects": list(self.effects), "verdict": self.verdict, "z": round(self.z, 2),
                "held_out_gain": round(self.held_out_gain, 4), "excess_gain": excess_shown(self.excess_gain),
                "blocks_for": self.blocks_for, "blocks_against": self.blocks_against, "affected": self.affected,
                "at_edge": list(self.at_edge), "sentence": self.sentence}


class Effect(dict):
    """An effect a diagnosis named: `name`, `parameters` (with units and 95 % intervals), `evidence`
    (a Judgement) and `text` (as `twin effects` and `--given` take it). Still the dict of the
    diagnosis's JSON (`e["text"]`, `to_dict()`), so code written against the JSON keeps working."""

    @property
    def name(self) -> str:
        return self["name"]

    @property
    def text(self) -> str:
        return self["text"]

    @property
    def parameters(self) -> list[Parameter]:
        from .effects import EFFECTS

        spec = EFFECTS.get(self["name"])
        units = {v.name: v.unit for v in spec.values} if spec else {}
        ci = self.get("ci") or {}
        out = []
        for key, value in self.get("parameters", {}).items():
            unit = units.get(key.split(" ")[-1], units.get(key, "×" if spec and spec.keys else ""))
            interval = tuple(ci[key]) if key in ci else None
            out.append(Parameter(key, float(value), unit, interval))
        return out

    @property
    def evidence(self) -> Judgement:
        e = self.get("evidence", {})
        return Judgement((self["text"],), "earns its place", float(e.get("z", self.get("z", 0.0))),
                         float(e.get("held_out_gain", self.get("held_out_gain", 0.0))),
                         float(e.get("excess_gain", self.get("excess_gain", 0.0))),
                         int(e.get("blocks_for", 0)), int(e.get("blocks_against", 0)),
                         int(e.get("affected_windows", 0)), tuple(e.get("at_edge", ())))

    def __repr__(self) -> str:
        return f"Effect({self.name}: {', '.join(map(repr, self.parameters))}; z {self.evidence.z:.2f})"

    def to_dict(self) -> dict:
        return dict(self)


class Diagnosis(_Found):
    """`twin diagnose`: the effects named (`effects`, each an Effect), the amended twin (`amended`),
    the fit before and after, what stays unexplained and where (`unexplained`); `to_dict()` is the
    JSON `twin diagnose --json` writes."""

    def __repr__(self) -> str:
        named = "; ".join(repr(e) for e in self.effects) or "nothing named"
        return f"Diagnosis({self.prior.name}: {named}; {len(self.unexplained)} unexplained regions)"

    def table(self) -> Table:
        """One row per parameter of every effect named (no rows when nothing is named)."""
        rows = [{"effect": e.name, "parameter": p.name, "value": p.value, "unit": p.unit,
                 "ci95_low": p.ci95[0] if p.ci95 else None, "ci95_high": p.ci95[1] if p.ci95 else None,
                 "z": e.evidence.z} for e in self.effects for p in e.parameters]
        return Table(rows, f"{self.prior.name}: effects named by the diagnosis" + ("" if rows else " (nothing named)"))


def diagnose_recordings(recordings, vessel: Vessel | str, sea=None, *, effects=None, window_s: float | None = None,
                        wind: str | None = None, calibrated: bool = True, kinematic: bool = True,
                        refit=None, refit_weight: float = 1.0, log=None):
    """`twin diagnose`: which physics the twin lacks, how much of it, and the amended twin.

    Args:
        recordings: paths or Recording objects, diagnosed together.
        vessel: a Vessel or a shipped vessel's name.
        sea: a physics.waves.Sea or `--sea` text: the sea the recordings were made in, its Stokes drift
            a known flow and its mean load a known force (`--sea`; .amended is the twin without them).
        effects: only these candidate effects (names, as `twin effects` lists them; `--effects`).
        window_s: the free-run window, s (`--window`; default 10).
        wind: "measured": each recording's measured wind a known input (`--wind-measured`).
        calibrated: each log's compass offset from its own kinematics first (`--no-calibration`: False).
        kinematic: sensor and timing effects told from the kinematics first.
        refit: identification groups refitted beside every candidate (`--refit`), with `refit_weight`.
        log: a callable taking progress lines.

    Returns:
        A Diagnosis: .effects (Effect objects with their Parameters and units), .amended,
        .fit_before / .fit_after, .unexplained, .notes.
    """
    from dataclasses import fields

    from .diagnose.doctor import WINDOW_S, diagnose as run
    from .engine.sixdof import without_known_sea

    if window_s is not None and not (isinstance(window_s, (int, float)) and math.isfinite(window_s) and window_s > 0):
        raise TwinError(f"window_s must be a positive number of seconds, got {window_s}")
    v = _in_sea(_vessel(vessel), sea)
    library = None if effects is None else list(_names(effects, "effects", "`twin effects` lists them"))
    refit = None if refit is None else _names(refit, "refit", "surge, sway, yaw, ...: the vessel's fit groups")
    found = run(_recordings(recordings, v), v, window_s=WINDOW_S if window_s is None else window_s, log=log,
                library=library, calibrated=calibrated, refit=refit,
                refit_weight=refit_weight, kinematic=kinematic, wind=wind)
    typed = Diagnosis(**{f.name: getattr(found, f.name) for f in fields(found)})
    if sea is not None:
        typed.amended = without_known_sea(typed.amended)
    typed.effects = [Effect(e) for e in found.effects]
    return typed


def judge(recordings, vessel: Vessel | str, effects, **options) -> Judgement:
    """`twin diagnose --given`: the effects at the values given (texts as `twin effects` lists them),
    nothing fitted, judged by the diagnosis's rule on the blocks a diagnosis of these recordings
    uses: a Judgement (`earns_its_place`, `z`, `held_out_gain`, ...; `str()` says it in a sentence)."""
    from .diagnose.doctor import given_evidence, given_text
    from .diagnose.search import Z_MIN
    from .effects import parse_effect

    effects = list(_names(effects, "effects", "texts such as 'current=0.1,90'; `twin effects` lists them"))
    _known_options(given_evidence, options, "judge")
    for text in effects:  # an unknown effect is told before the recordings are read
        if isinstance(text, str):
            parse_effect(text)
    v = _vessel(vessel)
    e = given_evidence(_recordings(recordings, v), v, effects, **options)
    verdict = ("earns its place" if e.earns_its_place() else "contradicted" if e.z <= -Z_MIN
               else "does not earn its place")
    return Judgement(tuple(effects), verdict, float(e.z), float(e.rel), float(e.rel_excess), int(e.blocks_for),
                     int(e.blocks_against), int(e.affected), tuple(e.at_edge), str(given_text(effects, e)), e)
