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

import math
import numbers
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

from .drive import InputSeries, inputs_mismatch
from .engine.mjcf import CompiledVessel, compile_vessel as _compile_vessel
from .engine.parameters import effective_parameters as _effective_parameters
from .engine.sixdof import check_sea_for, with_known_sea, without_known_sea
from .diagnose import doctor as _doctor
from .diagnose.doctor import WINDOW_S, Diagnosis as _Found, given_evidence
from .diagnose.report import as_json, given_text
from .diagnose.search import Z_MIN, excess_shown
from .effects import EFFECTS, named_twice, parse_effect
from .errors import TwinError
from .files import check_new, same_file
from .fit.coverage import from_dict
from .fit.evaluate import STATE_NAMES, TwinPredictor, evaluate as _evaluate, misfit_by_manoeuvre, misfit_by_state, \
    percentile_edges
from .fit.windows import ModelCache
from .formats import read_recording as _read_recording
from .physics.waves import Sea, parse_sea
from .prepare import Prepared, prepare as _prepare
from .recording import Recording, check_no_shared_stretch, check_not_misread
from .run import Run
from .simulation import Simulation, check_flags, known_options, simulate, simulate_run
from .verify.crosscheck import cases, crosscheck as _crosscheck
from .verify.manoeuvres import ManoeuvreBands, Manoeuvres, manoeuvre_bands as _manoeuvre_bands, \
    manoeuvres as _manoeuvres
from .ident.identify import Identification as _Identification, calibrate as _calibrate, check_wind, \
    identify as _identify, manoeuvre_horizon_s, prepared
from .verify.validate import Validation as _Validation, validate as _validate
from .vessel import Vessel, load as load_vessel, save as _save

__all__ = ["Run", "Vessel", "InputSeries", "Validation", "Identification", "Simulation", "Evaluation", "Score", "Effect",
           "Parameter", "Judgement", "Diagnosis", "Table", "TwinError", "load_vessel", "save_vessel", "simulate",
           "simulate_run",
           "crosscheck", "manoeuvres", "Manoeuvres", "manoeuvre_bands", "ManoeuvreBands", "effective_parameters", "compile_vessel", "validate", "read_recording",
           "prepare_recording", "calibrate", "identify", "evaluate", "diagnose_recordings", "judge"]


def save_vessel(vessel: Vessel | str, path, *, force: bool = False) -> Path:
    """Write a vessel as a vessel file, as `--out` of `twin identify` writes the twin it identified.

    A file already at `path` is kept unless `force`, as the command keeps it: it may be a log or a
    twin the user made.

    Args:
        vessel: the vessel to write: a twin.Vessel, a shipped vessel's name or a vessel file's path.
        path (str | Path): where to write it, a .json file.
        force: replace a file already at `path`.

    Returns:
        The path written, resolved.

    Raises:
        TwinError: `path` is not a file path or does not end in .json; a file is there and `force`
            is False, or it is data of another kind (a dataset's truth, a Monte Carlo band: kept even
            with `force`, as the command keeps them); or `vessel` is neither a twin.Vessel nor the name of a shipped vessel or a
            readable vessel file.
    """
    check_flags("save_vessel", force=force)
    _new_output(path, (".json",), force, ("vessel file",))
    return _save(_vessel(vessel), path)


def _new_output(path, formats: tuple[str, ...], force: bool, writes: tuple[str, ...]) -> None:
    """An output path the API writes, checked as the commands check theirs: its format, and a file
    already there kept unless `force` (it may be a log or a twin the user made), and data of another
    kind than `writes` (files.kept_data: a log, a dataset's truth, a band) kept even with `force`."""
    if not isinstance(path, (str, Path)) or not str(path):
        raise TwinError(f"an output is written to a file path (str or Path), got {path!r:.60}")
    p = Path(path)
    if p.suffix.lower() not in formats:
        raise TwinError(f"'{p}': unknown format '{p.suffix or '(none)'}' (use {', '.join(formats)})")
    check_new([p], force, "path", writes, force_name="force=True")


class Validation(_Validation):
    """What `twin validate` finds: every quantity of one vessel and mass case side by side.

    Each column is a way of obtaining the quantity (`.quantities`, `.flagged()`, `table()`,
    `to_dict()`). A difference over 5 % between the columns is flagged, with the assumption behind
    it and the value the twin uses.

    Attributes:
        vessel (str): the vessel's name.
        case (str): the mass case validated ("nominal" or one of the vessel file's cases).
        quantities (list[Quantity]): one per quantity (inertia, added mass, thrust bounds,
            hydrostatics): `name`, `unit` and its columns `analytic` (the report's hand formulas),
            `table` (the report's printed tables), `engine` (the compiled MuJoCo model), `mesh`
            (the hull meshes) and `independent` (an independent computation), None where a way
            does not give it; `rel_diff`, the largest relative difference from the reference
            column; `flag`, whether that exceeds 5 %; `explanation`, why.
        drawing (dict): positions for the top-view figure of `twin validate --report`.
    """

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
    """Every quantity of one vessel and mass case side by side, as `twin validate` lists them.

    Each quantity (inertia, added mass, thrust bounds, hydrostatics) is obtained every way there is:
    the report's hand formulas, its printed tables, the compiled MuJoCo model, the hull meshes and
    an independent computation. Printed values that cannot be reproduced from their own table's
    inputs are reported as such; no input is adjusted to agree.

    Args:
        vessel: a twin.Vessel, a shipped vessel's name or a vessel file's path.
        case: the mass case ("nominal" or one the vessel file lists; `--case`); None: the vessel's
            own (a vessel loaded by name is "nominal").

    Returns:
        The quantities (`.quantities`, `.flagged()` for those over 5 %, `table()`, `to_dict()`).

    Raises:
        TwinError: `vessel` is neither a twin.Vessel nor the name of a shipped vessel or a readable
            vessel file, or it has no mass case `case`.
    """
    v = _vessel(vessel)
    found = _validate(v if case is None else v.with_case(case))
    return Validation(**{f.name: getattr(found, f.name) for f in fields(found)})


def compile_vessel(vessel: Vessel | str, wind_inputs: bool = False) -> CompiledVessel:
    """The vessel's MuJoCo model, with its geometry, as the engine runs it.

    Args:
        vessel: a twin.Vessel, a shipped vessel's name or a vessel file's path.
        wind_inputs: with the wind as controls.

    Returns:
        (twin.engine.mjcf.CompiledVessel): `vessel`, the MuJoCo `model` and its `geometry`.

    Raises:
        TwinError: `vessel` is neither a twin.Vessel nor the name of a shipped vessel or a readable
            vessel file, or its model does not compile.
    """
    check_flags("compile_vessel", wind_inputs=wind_inputs)
    return _compile_vessel(_vessel(vessel), wind_inputs)


def effective_parameters(vessel: Vessel | str) -> dict:
    """The parameters the engine runs a vessel with, as `twin params --json` prints them.

    Args:
        vessel: a twin.Vessel, a shipped vessel's name or a vessel file's path.

    Returns:
        In SI units: "M", "M_RB" and "M_A" (3 × 3, surge, sway, yaw), "rigid_body", "added_mass"
        and "damping" (the [Morel-2024 eq. 7] names, Fossen signs), "thrusters" (positions in m,
        input and force bounds, a twin-thruster boat's allocation matrix), "gnss_antenna_m" and
        "gnss_lever_arm_OP_m" (the GNSS lever arm), "imu_m", "wind_load", "environment",
        "frames", "sources"; a propeller-and-rudder ship's "mmg" coefficients; and, where full ahead
        has a bound, "straight_run": the calm-water straight run at full ahead (speed, sway-yaw
        roots, whether it holds its course, from which speed it does not).

    Raises:
        TwinError: `vessel` is neither a twin.Vessel nor the name of a shipped vessel or a readable
            vessel file.
    """
    return _effective_parameters(_vessel(vessel))


def manoeuvres(vessel: Vessel | str, surge: float = 0.5, turn_yaw: float = 1.0, zigzag_yaw: float | None = None,
               zigzag_switch_deg: float = 10.0) -> Manoeuvres:
    """The twin's turning circles, zig-zag and crash stop in calm water, as `twin manoeuvres` runs them:
    the measures of manoeuvring trials [IMO-MSC137] from a steady straight approach.

    Args:
        vessel: a twin.Vessel, a shipped vessel's name or a vessel file's path.
        surge: the approach command, (0, 1] (`--surge`): a ship's share of rps_max; a twin-thruster
            boat's share of the PWM span from 1500 µs (0.5: 1700 µs).
        turn_yaw: the turning circles' yaw command, (0, 1] (`--turn-yaw`): a ship's share of
            rudder_max; a twin-thruster boat's thrusters get surge ± yaw, each held within full.
        zigzag_yaw: the zig-zag's yaw command, (0, 1]; None: a ship's 10° of rudder, a boat's 0.2.
        zigzag_switch_deg: the heading change (°) at which the zig-zag reverses (default 10).

    Returns:
        twin.verify.manoeuvres.Manoeuvres: `length_m` (L), `approach_speed_m_s`, `straight` (the
        straight run's course stability: `throttle`, its mean thrust's share of full ahead, `speed_m_s`,
        `roots_per_s`, `stable`, `doubling_s`), `inputs` (what the approach, turn and zig-zag ask of
        the thrusters or propeller and rudder), `turns` (starboard, port: advance, transfer + to starboard,
        tactical and steady diameters in m, steady speed m/s, rate °/s + to starboard, drift angle
        atan2(−v, u) in °), `zigzag` (first and second overshoot °, time to the first reversal s) and
        `crash_stop` (track and head reach, lateral deviation in m, time in s).

    Raises:
        TwinError: a command outside (0, 1], a switch angle outside (0, 90)°, or a vessel that is not
            one or does not get under way at the approach command.
    """
    return _manoeuvres(_vessel(vessel), surge, turn_yaw, zigzag_yaw, zigzag_switch_deg)


def manoeuvre_bands(vessel: Vessel | str, draws: int = 50, seed: int = 0, surge: float = 0.5, turn_yaw: float = 1.0,
                    zigzag_yaw: float | None = None, zigzag_switch_deg: float = 10.0) -> ManoeuvreBands:
    """Each measure of `manoeuvres` as its 90 % range over draws of an identified twin's parameters, as
    `twin manoeuvres --draws` prints them (parameters only: the form error is not in them).

    Args:
        vessel: an identified twin (a twin.Vessel or a vessel file with an uncertainty block).
        draws: how many twins to draw (≥ 2; `--draws`).
        seed: the draws' random seed (≥ 0; `--seed`).
        surge: the approach command, as `manoeuvres` takes it.
        turn_yaw: the turning circles' yaw command, as `manoeuvres` takes it.
        zigzag_yaw: the zig-zag's yaw command, as `manoeuvres` takes it.
        zigzag_switch_deg: the zig-zag's switch angle (°), as `manoeuvres` takes it.

    Returns:
        twin.verify.manoeuvres.ManoeuvreBands: `bands` (per measure `name`, `low`, `high`, `reached`),
        `draws`, `redrawn` (unphysical draws drawn again), `diverged` (left out), `level`.

    Raises:
        TwinError: as `manoeuvres`; fewer than 2 draws or a negative seed; a vessel without an
            uncertainty block; more than half the draws diverging.
    """
    return _manoeuvre_bands(_vessel(vessel), draws, seed, surge=surge, turn_yaw=turn_yaw, zigzag_yaw=zigzag_yaw,
                            zigzag_switch_deg=zigzag_switch_deg)


def crosscheck(vessel: Vessel | str, duration_s: float = 120.0, only: list[str] | None = None,
               six_dof: bool = False) -> list:
    """The engine against the analytic 3-DOF model over a zig-zag, as `twin crosscheck` runs it.

    One case per force term: each case runs the MuJoCo engine and the analytic model with the same
    terms switched on over the same inputs (those of the full-physics case, which therefore always
    runs) and compares the trajectories; a case passes within 0.01 m of position and 0.1° of
    heading.

    Args:
        vessel: a twin.Vessel, a shipped vessel's name or a vessel file's path.
        duration_s: the zig-zag's length, s (`--duration`; default 120).
        only: the cases to run besides "full" (one name, or a list), e.g. "damping" or ["thrust",
            "current"]; None: every case of the vessel's kind (a propeller-and-rudder ship has
            its own).
        six_dof: also the 6-DOF hull in calm water against the 3-DOF model ("six_dof_calm";
            `--six-dof`), for a vessel with hull meshes.

    Returns:
        One twin.verify.crosscheck.Result per case: `case`, `position_err_m` (m),
        `heading_err_deg` (deg), `effect_m` (how far the term moves the vessel, m), `passed`,
        `exercised` (False where the term moves it less than the tolerance, so the pass checks
        nothing), `engine` and `analytic` (the two Runs); `to_dict()`.

    Raises:
        TwinError: `duration_s` is not a positive, finite number of seconds of at least one sample
            (0.1 s); `only` is not one or more names, or names a case
            the vessel's kind does not have (a case not run would read as passed); `vessel` is
            neither a twin.Vessel nor the name of a shipped vessel or a readable vessel file; or
            `six_dof` for a vessel without hull meshes.
    """
    check_flags("crosscheck", six_dof=six_dof)
    if isinstance(duration_s, bool) or not isinstance(duration_s, (int, float)) or not (
            math.isfinite(duration_s) and duration_s > 0):
        raise TwinError(f"duration_s must be a positive, finite number of seconds, got {duration_s!r}")
    if duration_s < SAMPLE_DT_S:  # one sample: every case would compare the start alone, and pass
        raise TwinError(f"duration_s must be at least one sample ({SAMPLE_DT_S:g} s) for the cases to compare "
                        f"anything, got {duration_s!r}")
    v = _vessel(vessel)
    only = None if only is None else list(_names(only, "only", "the crosscheck cases, e.g. 'damping'"))
    known = [c.name for c in cases(v)]
    unknown = [n for n in only or () if n not in known]
    if unknown:  # a case not run would read as passed
        raise TwinError(f"only={unknown}: unknown crosscheck case (the force terms checked one by one: "
                        f"{', '.join(known)})")
    return _crosscheck(v, duration_s, only, six_dof=six_dof)


def _names(given, what: str, which: str, texts: bool = False) -> tuple[str, ...]:
    """One name or a non-empty list of names (a name alone is a name, not its letters); `texts`: each
    may hold commas (an effect with its values), else a comma says several names in one text."""
    if isinstance(given, str) and "," in given and not texts:
        raise TwinError(f"{what}: give several names as a list, {[n.strip() for n in given.split(',')]!r:.80}, "
                        f"not one text {given!r:.60}")
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
    recs = [r if isinstance(r, Recording) else _read_recording(r) for r in items]
    seen: dict[int, int] = {}
    for i, r in enumerate(recs):
        if id(r) in seen:
            raise TwinError(f"recording {i} is recording {seen[id(r)]} again ('{r.source}'): give each recording once")
        seen[id(r)] = i
    check_not_misread(recs)
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


def read_recording(path, channels: dict | None = None) -> Recording:
    """Read a recording from a file, as `twin info` reads it.

    Args:
        path (str | Path): an ArduPilot DataFlash .bin or telemetry .tlog, a CSV (the generic layout or
            a known dataset's) or an MCAP file.
        channels: which servo outputs drive the thrusters of an ArduPilot log, as
            `{"left": 1, "right": 3}` with optional "reversed" ({"left": True, ...}) and "trim"
            (µs) (`--channels LEFT,RIGHT`; default: from its SERVOn_FUNCTION parameters); for a CSV,
            only "reversed" and "trim".

    Returns:
        (twin.recording.Recording): the streams as logged (GNSS, heading, PWM in µs or propeller and
            rudder, yaw rate, battery, wind), with what the reader skipped (`dropped`), its
            `notes` and `warnings`.

    Raises:
        TwinError: `path` is not a path, is a folder, is missing or empty, is not a recognised
            recording, or holds nothing usable; or `channels` is malformed or does not apply to
            the file (LEFT,RIGHT for a CSV or MCAP recording).
    """
    for key, to in (("reversed", "True or False"), ("trim", "the PWM of zero thrust in µs")):
        given = channels.get(key) if isinstance(channels, dict) else None  # a wrong shape would fail inside the readers
        if given is not None and (not isinstance(given, dict) or set(given) - {"left", "right"} or key == "trim"
                                  and not all(_finite(x, positive=False) for x in given.values())):
            raise TwinError(f"channels[{key!r}] must be a dict of 'left' and/or 'right' to {to}, got {given!r:.60}")
    return _read_recording(path, channels=channels)


def _finite(value, positive: bool = True) -> bool:
    """A finite real number given as an argument (not text, not a flag), positive where asked."""
    return (not isinstance(value, bool) and isinstance(value, numbers.Real) and math.isfinite(value)
            and (value > 0 or not positive))


def prepare_recording(recording, vessel: Vessel | str | None = None, calibrated: bool = True) -> Prepared:
    """A recording made ready for fitting [Morel-2024 §5.1]: on one time grid, with body velocities.

    The samples are synchronised on one time grid, with the body velocities and yaw rate. With a
    vessel, the recording is prepared as its sensors see it (GNSS lever arm, heading corrections),
    as `twin identify` and `twin evaluate` prepare theirs; without one, the positions are the
    antenna's as logged.

    Args:
        recording (str | Path | Recording): one recording: a path or a Recording (twin.read_recording).
        vessel: a twin.Vessel, a shipped vessel's name or a vessel file's path; None: prepared
            without a vessel.
        calibrated: with a vessel, first estimate the log's own compass offset from its GNSS track
            and apply it (False: as `--no-calibration`).

    Returns:
        (twin.prepare.Prepared): on the grid `t` (s), the position north, east (m), heading `psi`
            (rad), `u`, `v` (m/s), `r` (rad/s), the inputs (`pwm`: PWM in µs, or propeller
            speed in rps and rudder angle in rad) and the `segments` between dropouts.

    Raises:
        TwinError: more than one recording is given; the recording cannot be read, or its inputs
            cannot drive the vessel (PWM for a propeller-and-rudder ship, a ship's propeller and
            rudder for a PWM boat); or `vessel` is neither a twin.Vessel nor the name of a shipped
            vessel or a readable vessel file.
    """
    if isinstance(recording, (list, tuple)) and len(recording) > 1:  # the others were silently dropped
        raise TwinError(f"prepare_recording prepares one recording, got {len(recording)}: prepare each on its own")
    check_flags("prepare_recording", calibrated=calibrated)
    if vessel is None:
        return _prepare(_recordings(recording)[0])
    v = _vessel(vessel)
    rec = _recordings(recording, v)[0]
    if calibrated:
        v, _ = _calibrate([rec], v)
    return prepared([rec], v)[0]


def calibrate(recordings, vessel: Vessel | str) -> list:
    """Each log's compass offset, estimated from its own kinematics as `twin identify` does.

    Going straight under way, the GNSS track over ground follows the hull's true heading, so the
    angle between the track and the logged heading is the compass's error; no dynamic model is
    involved.

    Args:
        recordings (str | Path | Recording | list): one recording or a list of them: paths or Recordings
            (twin.read_recording), each at most once.
        vessel: a twin.Vessel, a shipped vessel's name or a vessel file's path.

    Returns:
        One twin.fit.calibrate.LogCalibration per recording, in order: `heading_bias_deg` (logged
        minus true heading, deg) and its 1-σ `sigma_deg`, the straight `stretches` and `seconds`
        it was taken from, the ground drift `drift_ned_m_s` (m/s, reported, not applied); the
        offset is None where the log has too little straight running (why: `note`).

    Raises:
        TwinError: no recordings, one given twice or mostly a stretch of another, one that cannot
            be read or whose inputs cannot drive the vessel; or `vessel` is neither a twin.Vessel
            nor the name of a shipped vessel or a readable vessel file.
    """
    v = _vessel(vessel)
    return _calibrate(_recordings(recordings, v), v)[1]


def _in_sea(vessel: Vessel, sea) -> Vessel:
    """The vessel with the steady drift of `sea` (a Sea, `--sea` text or None) a known flow."""
    if sea is None:
        return vessel
    sea = sea if isinstance(sea, Sea) else parse_sea(str(sea))
    check_sea_for(vessel, sea)
    return with_known_sea(vessel, sea)


def identify(recordings, vessel: Vessel | str, sea=None, **options) -> Identification:
    """Identify a vessel from recordings, as `twin identify` does.

    Each log's compass calibration, a fit by simulation with the prior's beliefs, and every choice
    judged on runs left out of the fit.

    Args:
        recordings (str | Path | Recording | list): one recording or a list of them: paths or Recordings
            (twin.read_recording), each at most once, each with inputs that can drive the vessel.
        vessel: the prior: a twin.Vessel, a shipped vessel's name or a vessel file's path.
        sea (Sea | str | None): the sea the recordings were made in, a twin.physics.waves.Sea or `--sea`
            text such as "0.3,2.5,30,4" (Hs m, Tp s, direction the waves come from in deg, spreading):
            its Stokes drift is a known flow and its mean load on the hull a known force of every free
            run (`twin identify --sea`); the identified `.vessel` carries neither. None: calm water.
        **options (Any): the keywords of twin.ident.identify.identify, documented there: among them
            `groups` (the fit groups to free, one name or several; `--groups`), `params` (exactly
            these coefficients instead; `--params`), `window_s` (the free-run window, s;
            `--window`), `start` ("free" or "measured"), `calibrated` (False: `--no-calibration`),
            `greybox` (also the [Morel-2024] grey-box tables; `--greybox`), `wind` ("measured":
            `--wind-measured`), `prior_weights` (the beliefs' weights in windows to choose among, a
            list of positive numbers; `--beliefs`), `judged_on` ("beyond" or "each"),
            `max_evaluations` and `progress`.

    Returns:
        (Identification): `.vessel` is the identified twin (what `--out` writes), with the fit, the
            choices and what they were judged by, and each log's calibration; `table()` lists
            each coefficient, its prior and what was identified.

    Raises:
        TwinError: an option identify does not take, or one of the wrong kind or out of its range;
            no recordings, one given twice, one that cannot be read or cannot drive the vessel; a sea given wrongly or
            one the vessel cannot run in; too few windows with the thrusters working to identify
            anything; or `vessel` is neither a twin.Vessel nor the name of a shipped vessel or a
            readable vessel file.
    """
    known_options(_identify, options, "identify")
    if options.get("progress") is not None and not callable(options["progress"]):
        raise TwinError(f"progress is a callable taking (text, step, steps) or None, got {options['progress']!r:.60}")
    weights = options.get("prior_weights", (1.0,))
    if isinstance(weights, (str, bytes, dict)) or not hasattr(weights, "__len__") or not len(weights) or not all(
            _finite(w) for w in weights):
        raise TwinError(f"prior_weights must be a non-empty list of positive numbers, got {weights!r:.60}")
    v = _in_sea(_vessel(vessel), sea)
    for name in ("params", "groups"):  # one name alone is a name, not its letters
        if isinstance(options.get(name), str):
            options[name] = (options[name],)
    result = _identify(_recordings(recordings, v), v, **options)
    result = replace(result, vessel=without_known_sea(result.vessel)) if sea is not None else result
    return Identification(**{f.name: getattr(result, f.name) for f in fields(result)})


class Identification(_Identification):
    """What `twin identify` found: the twin it writes (`.vessel`), the fit and what it was judged by.

    The fit, the choices and what they were judged by, each log's calibration (`table()`: each
    coefficient, its prior and what was identified; `to_dict()`: the JSON `twin identify --json`
    writes).

    Attributes:
        vessel (Vessel): the identified twin, what `--out` writes; its `uncertainty` holds what the
            fit saw and its error on the left-out runs, which `evaluate` reads.
        prior (Vessel): the vessel the fit started from.
        fit (twin.fit.simfit.FitResult | None): the fit written; its `estimates` give each
            coefficient's unit, prior, identified value, 1-σ and a note.
        calibrations (list[LogCalibration]): each log's compass offset from its kinematics.
        choices (list[Choice]): every configuration judged on the left-out runs (how much the
            beliefs count, which groups are free) with its cross-validation.
        chosen (Choice | None): the choice whose twin is written ("prior (no fit)" where the prior
            predicts the left-out runs better than any fit).
        prior_cv (CrossValidation | None): how the prior predicts the left-out runs.
        greybox (dict): the [Morel-2024] grey-box tables, with `greybox=True`.
        notes (list[str]): one-line remarks (a log left out of the fit, coefficients moved beyond
            what their beliefs allow, a twin worse than its prior).
        seconds (float): how long the identification took, s.
        wind (str | None): "measured" where each recording's measured wind was a known input.
    """

    def table(self) -> Table:
        """One row per coefficient of the fit: unit, prior, identified, its 1-σ, and how the recordings
        moved it (the note `twin identify` prints)."""
        rows = [{"coefficient": e.name, "unit": e.unit, "prior": e.prior, "identified": e.value, "sigma": e.sigma,
                 "note": e.note} for e in (self.fit.estimates if self.fit else [])]
        return Table(rows, f"{self.vessel.name}: the coefficients identified")


class Table(list):
    """Rows (dicts with the same keys) under a title, printed as aligned columns.

    Numbers are printed to 4 significant figures; still a list of dicts for code (`to_dict()` for
    JSON).

    What the results' `table()` methods return: `print(t)` to read it, `t[0]["r2"]` or
    `pandas.DataFrame(t)` to use it.

    Attributes:
        title (str): what the rows are, printed above them ("" for none).
    """

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


SAMPLE_DT_S = 0.1  # the engine's default output sample period, which crosscheck's runs are sampled at

# units of the velocities and the yaw rate in every score: r in degrees per second, as in the reports
UNITS = {"u": "m/s", "v": "m/s", "r": "°/s"}


@dataclass(frozen=True)
class Score:
    """How well the twin predicts one velocity at one horizon: R² and the mean absolute error.

    The error is in `unit` (m/s for u and v, °/s for r), over `n` samples; `calibrated`: with each
    log's compass offset applied.

    Attributes:
        horizon (str): "one_step", "free_run_10s", "free_run_30s" or "full" (whole segments).
        dof (str): "u" (surge), "v" (sway) or "r" (yaw rate).
        r2 (float | None): the coefficient of determination; None where no sample was predicted.
        mae (float | None): the mean absolute error, m/s for u and v, °/s for r.
        n (int): the samples predicted.
        calibrated (bool): each log's compass offset applied.
        unit (str): the unit of `mae`.
    """

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
    """What `twin evaluate` finds: R² and MAE per DOF and horizon, and where the free runs miss.

    R² and MAE per DOF and horizon (`scores`; `score("u")`), with and without each log's compass
    calibration, and the calibrations; where the free runs miss, by manoeuvre and by a measured
    state; the coefficients that stand in for something the twin lacks.

    Attributes:
        vessel (str): the twin's name.
        metrics (dict): with each log's compass calibration, {horizon: {u, v, r: {r2, mae, n}}}
            for the horizons one_step, free_run_10s, free_run_30s and full, in SI (r's MAE in
            rad/s, where `scores` and `table()` give °/s).
        metrics_uncalibrated (dict): the same without the calibrations.
        calibrations (list[LogCalibration]): each log's compass offset from its kinematics.
        by_manoeuvre (dict): where the free runs of the fit's window (10 s for a small boat, 30 s
            for a slow ship: its `horizon_s`) miss, each manoeuvre's share of 1 − R²
            (fit.evaluate.misfit_by_manoeuvre), read against what the twin's fit saw when identify
            wrote it.
        by_state (list[StateBand]): where they miss by a measured state, when one was asked for
            (fit.evaluate.StateBand); empty otherwise.
        stand_ins (list[dict]): the coefficients the twin's fit moved beyond what their beliefs
            allow (name, unit, value, prior, from_prior_sigmas), which hold beyond the fitted runs
            only as far as what they stand in for.
        calibrated (bool): whether each log's compass offset was asked for (`calibrated=` of
            `evaluate`); False: `metrics` are the scores as logged, and the offsets found are
            reported, not applied.
    """

    vessel: str
    metrics: dict
    metrics_uncalibrated: dict
    calibrations: list
    by_manoeuvre: dict = field(default_factory=dict)
    by_state: list = field(default_factory=list)
    stand_ins: list = field(default_factory=list)
    calibrated: bool = True  # False: asked as logged (`--no-calibration`), the offsets found reported, not applied

    @property
    def applied(self) -> bool:
        """Whether any log's compass offset was applied (else the scores are the log's as logged)."""
        return self.calibrated and any(c.heading_bias_deg is not None for c in self.calibrations)

    @property
    def scores(self) -> list[Score]:
        """Every score: calibrated first, then without the calibrations; where no log's compass
        offset was applied, the scores as logged alone (calibrated False)."""
        if not self.applied:
            return _scores(self.metrics_uncalibrated, False)
        return _scores(self.metrics, True) + _scores(self.metrics_uncalibrated, False)

    def score(self, dof: str, horizon: str = "free_run_10s", calibrated: bool = True) -> Score:
        """One score: one velocity at one horizon.

        Args:
            dof: "u", "v" or "r".
            horizon: "one_step", "free_run_10s", "free_run_30s" or "full".
            calibrated: each log's compass calibration applied (where none was, the score as
                logged).

        Returns:
            The score: `r2`, `mae` (m/s; r in °/s) and `n`.

        Raises:
            TwinError: no score for that DOF and horizon.
        """
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
             sea=None, by: str | None = None, calibrated: bool = True, progress=None) -> Evaluation:
    """How the twin predicts recordings, and where its free runs miss, as `twin evaluate` finds.

    One step, 10-s and 30-s free runs and whole segments; where the free runs miss, by manoeuvre and
    beyond what the twin's fit saw. Every score is given with each log's compass offset, estimated
    from its own kinematics, applied and without it.

    Args:
        vessel: the twin: a twin.Vessel, a shipped vessel's name or a vessel file's path (one
            `twin identify` wrote says where its fit saw the vessel).
        recordings (str | Path | Recording | list): one recording or a list of them: paths or Recordings
            (twin.read_recording), each at most once, each with inputs that can drive the vessel; runs
            the fit did not see, for a fair score.
        stride_s: the free-run windows start every `stride_s`, s (`--stride`; default 2).
        wind: "measured": each recording's measured wind a known input of every free run
            (`twin evaluate --wind-measured`); None: the vessel's own wind.
        sea (Sea | str | None): the sea the recordings were made in, a twin.physics.waves.Sea or `--sea`
            text such as "0.3,2.5,30,4": its Stokes drift a known flow and its mean load on the hull a
            known force (`--sea`). None: calm water.
        by: also where the free runs miss by a measured state (`--by`), in bands of the samples
            (the lower half, the next quarter, the next 15 %, the top 10 %): "speed" (over
            ground, m/s), "yaw_rate" (|r|, rad/s), "drift" (the drift angle |β|, rad), "input_0"
            or "input_1" (the logged inputs: PWM in µs, or propeller rps and rudder angle) or
            "rest" (how long input 0, a propeller, has been stopped, s).
        calibrated: the splits by manoeuvre and by state with each log's compass calibration
            applied (default); False: as logged (`--no-calibration`). The scores come both ways.
        progress (Callable[[str, int, int], None] | None): told each stage (text, step, steps).

    Returns:
        The scores (`scores`, `score("u")`, `table()`), `by_manoeuvre`, `by_state`, `stand_ins`
        and the calibrations.

    Raises:
        TwinError: `stride_s` not a positive, finite number of seconds; `by` not a known state, or
            "rest" on recordings of thruster PWM; `wind` neither None nor "measured", or "measured"
            for a recording without a wind stream or a vessel without a wind load model; no
            recordings, one given twice, one that cannot be read or cannot drive the vessel; a sea
            given wrongly or one the vessel cannot run in; nothing to score (no horizon has a
            velocity that varies); or `vessel` is neither a twin.Vessel nor the name of a shipped
            vessel or a readable vessel file.
    """
    if not _finite(stride_s):
        raise TwinError(f"stride_s must be a positive finite number of seconds, got {stride_s!r}")
    check_flags("evaluate", calibrated=calibrated)
    if progress is not None and not callable(progress):
        raise TwinError(f"progress is a callable taking (text, step, steps) or None, got {progress!r:.60}")
    told = progress or (lambda what, done=None, total=None: None)
    v = _in_sea(_vessel(vessel), sea)
    recs = _recordings(recordings, v)
    check_wind(recs, wind, v)
    seen = from_dict(v.uncertainty["fitted_on"], f"{v.name}: uncertainty.fitted_on") \
        if "fitted_on" in v.uncertainty else None
    if by is not None and by not in STATE_NAMES:
        raise TwinError(f"by={by!r}: unknown state (known: {', '.join(STATE_NAMES)})")
    if by == "rest" and any(r.pwm.has("left_us") for r in recs):
        raise TwinError("by rest bands by how long a propeller-and-rudder ship's propeller has been stopped; "
                        "these recordings log thruster PWM (band a boat's by speed, yaw_rate, drift or input_0)")
    with_offsets, calibrations = _calibrate(recs, v)
    # as logged: no log's compass offset, neither one read now nor one the twin holds for a log of that name
    logged = replace(v, sensors=replace(v.sensors, heading_bias_by_log_deg=()))
    used = with_offsets if calibrated else logged
    preps = prepared(recs, used)
    edges = percentile_edges(preps, STATE_NAMES[by], f"by {by}") if by else ()  # a flat state: before the work
    steps = 4 if by else 3
    told("without calibration", 0, steps)
    as_logged = _evaluate(logged, prepared(recs, logged), stride_s=stride_s, wind=wind)
    told("with each log's calibration", 1, steps)
    cache = ModelCache()  # the compiled twin shared by the scores and the splits
    # no log's offset applied: the calibrated twin is the twin, and its scores are the ones as logged
    scored = as_logged if with_offsets.sensors == logged.sensors else \
        _evaluate(TwinPredictor(with_offsets, cache, wind), prepared(recs, with_offsets), stride_s=stride_s)
    if not any(_scored(m) for m in as_logged.values()):
        names = ", ".join(Path(r.source).name for r in recs)
        raise TwinError(f"{names}: nothing to score: no horizon has a velocity that varies beyond what a sensor "
                        "resolves (the boat lies still or holds one speed and turn, or every stretch without a "
                        "dropout is shorter than a free run)")
    told("by manoeuvre", 2, steps)
    predictor, horizon = TwinPredictor(used, cache, wind), manoeuvre_horizon_s(v, seen)
    split = misfit_by_manoeuvre(predictor, preps, horizon, stride_s, vessel=used, fitted=seen)
    bands = []
    if by:
        told(f"by {by}", 3, steps)
        bands = misfit_by_state(predictor, preps, horizon, STATE_NAMES[by], edges, stride_s)
    told("done", steps, steps)
    return Evaluation(v.name, scored if calibrated else as_logged, as_logged, calibrations, split, bands,
                      list(v.uncertainty.get("stand_ins", [])), calibrated)


def _scored(horizon: dict) -> bool:
    """Whether a horizon's metrics hold an R² for some velocity (R² needs the velocity to vary)."""
    return any(m.get("r2") is not None and math.isfinite(m["r2"]) for m in horizon.values())


@dataclass(frozen=True)
class Parameter:
    """One value of a named effect, with its unit and 95 % interval.

    Its name, value, unit and 95 % interval (None where the fit holds it).

    Attributes:
        name (str): the parameter's name in the effect, e.g. "speed_m_s" of a current (with the
            log's name in front for a per-log effect).
        value (float): its value, in `unit`.
        unit (str): e.g. "m/s", "deg", "s"; "×" for a factor on a coefficient; "" for none.
        ci95 (tuple[float, float] | None): its 95 % interval, in `unit`.
    """

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
    """How the held-out blocks judge a change of the twin, by the diagnosis's rule.

    The `verdict` in words ("earns its place", "does not earn its place", "contradicted"), z of the
    blocks' votes, the share of the held-out misfit removed (`held_out_gain`) and of the misfit
    above the noise (`excess_gain`), the blocks for and against, the windows it changed
    (`affected`), parameters fitted to an unphysical edge; `str()` says it in a sentence. The
    diagnosis's own Evidence is `evidence` (its other figures, e.g. `dof_rel`, are read through).

    A change earns its place where z ≥ 3, it removes at least 5 % of the held-out misfit above the
    noise and no parameter sits at an unphysical edge; it is contradicted where z ≤ −3.

    Attributes:
        effects (tuple[str, ...]): the change judged, as effect texts ("current=0.1,90").
        verdict (str): "earns its place", "does not earn its place" or "contradicted".
        z (float): z of the held-out blocks' votes (positive: the change predicts them better).
        held_out_gain (float): the share of the held-out misfit the change removes.
        excess_gain (float): the share of the held-out misfit above the noise it removes.
        blocks_for (int): the held-out blocks it predicts better.
        blocks_against (int): the held-out blocks it predicts worse.
        affected (int): the windows whose prediction it changes.
        at_edge (tuple[str, ...]): parameters fitted to an unphysical edge.
        sentence (str): the judgement in one sentence (`str()`).
        evidence (Evidence | None): the diagnosis's own twin.diagnose.search.Evidence, from
            `judge`; None for an Effect's, read from the diagnosis's JSON.
    """

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
    """An effect a diagnosis named, with its values, their units and 95 % intervals, and its evidence.

    `name`, `parameters` (with units and 95 % intervals), `evidence` (a Judgement) and `text` (as
    `twin effects` and `--given` take it). It is also the dict of the diagnosis's JSON (`e["text"]`,
    `to_dict()`): what a script reads from a `--json` file it reads the same way here.

    Attributes:
        name (str): the effect's name in the library `twin effects` lists, e.g. "current".
        text (str): the effect at its values, as `twin effects` and `--given` take it (so
            `judge(..., e.text)` judges it again).
        parameters (list[Parameter]): its values, with units and 95 % intervals.
        evidence (Judgement): how the held-out blocks judged it ("earns its place": a diagnosis
            names no other).
    """

    @property
    def name(self) -> str:
        return self["name"]

    @property
    def text(self) -> str:
        return self["text"]

    @property
    def parameters(self) -> list[Parameter]:
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
    """What `twin diagnose` finds: the effects named, the amended twin and what stays unexplained.

    The effects named (`effects`, each an Effect), the amended twin (`amended`), the fit before and
    after, what stays unexplained and where (`unexplained`); `to_dict()` is the JSON
    `twin diagnose --json` writes.

    Attributes:
        prior (Vessel): the twin as given.
        amended (Vessel): the twin with the effects named (what `--write-model` writes).
        effects (list[Effect]): the effects named, each with its values, intervals and evidence;
            empty when none earns its place.
        located (list[dict]): where the residual of the twin as given concentrates (DOF, time,
            operating regime).
        growth (dict): whether the residual grows along a free run (dynamics) or is there from
            the start (measurement).
        correlations (dict): what the residual follows, per DOF.
        fit_before (dict): R² and MAE per DOF on the held-out blocks, the twin as given
            ({"u": {"r2", "mae"}, ...}; the MAE in SI units: u, v in m/s, r in rad/s, where `table()`
            and the report show r in °/s).
        fit_after (dict): the same with the effects named, each fitted without those blocks.
        unexplained (list[dict]): what stays well above the noise after the amendment: where it
            is, how big, and which signals it follows.
        noise (dict): the noise estimated for each signal: what "significant" is measured against.
        rounds (list[dict]): the candidates judged in each round of the search.
        windows (dict): the free-run windows: their length (s), number, folds and blocks.
        seconds (float): how long the diagnosis took, s.
        notes (list[str]): one-line remarks (what was not searched, and why).
        calibrations (list[LogCalibration]): each log's compass offset from its kinematics, applied.
        kinematic (list): the sensor and timing findings told from the kinematics before any fit.
        overall (dict): the residual's bias and RMS per DOF over every window, "before" and
            "after" the amendment.
        refit (dict): the twin's own coefficients refitted with every candidate, with `refit`.
    """

    def __repr__(self) -> str:
        named = "; ".join(repr(e) for e in self.effects) or "nothing named"
        return f"Diagnosis({self.prior.name}: {named}; {len(self.unexplained)} unexplained regions)"

    def to_dict(self) -> dict:
        """The JSON `twin diagnose --json` writes: the figures and the answer as the report words it."""
        return as_json(self)

    def table(self) -> Table:
        """One row per parameter of every effect named (no rows when nothing is named)."""
        rows = [{"effect": e.name, "parameter": p.name, "value": p.value, "unit": p.unit,
                 "ci95_low": p.ci95[0] if p.ci95 else None, "ci95_high": p.ci95[1] if p.ci95 else None,
                 "z": e.evidence.z} for e in self.effects for p in e.parameters]
        return Table(rows, f"{self.prior.name}: effects named by the diagnosis" + ("" if rows else " (nothing named)"))


def diagnose_recordings(recordings, vessel: Vessel | str, sea=None, *, effects=None, window_s: float | None = None,
                        wind: str | None = None, calibrated: bool = True, kinematic: bool = True,
                        refit=None, refit_weight: float = 1.0, log=None) -> Diagnosis:
    """Which physics the twin lacks, how much of it, and the amended twin, as `twin diagnose` finds.

    The twin is replayed over free-run windows; each candidate effect is fitted on some blocks of
    windows and judged on the others, and named only where the held-out blocks say it earns its
    place (Judgement). What stays significant after the amendment is reported as unexplained.

    Args:
        recordings (str | Path | Recording | list): one recording or a list of them, diagnosed together:
            paths or Recordings (twin.read_recording), each at most once, each with inputs that can
            drive the vessel.
        vessel: the twin: a twin.Vessel, a shipped vessel's name or a vessel file's path.
        sea (Sea | str | None): a twin.physics.waves.Sea or `--sea` text such as "0.3,2.5,30,4": the sea
            the recordings were made in, its Stokes drift a known flow and its mean load a known force
            (`--sea`; `.amended` is the twin without them). None: calm water.
        effects (str | list[str] | None): only these candidate effects: one name or several, as
            `twin effects` lists them (`--effects`); None: the whole library.
        window_s: the free-run window, s (`--window`; default 10).
        wind: "measured": each recording's measured wind a known input of every free run, the
            twin's and every candidate's (`--wind-measured`); a constant wind is then not searched
            for.
        calibrated: each log's compass offset from its own kinematics first (`--no-calibration`:
            False).
        kinematic: sensor and timing effects (GNSS lever arm, latencies) told from the kinematics
            first, before any dynamic fit.
        refit (str | list[str] | None): identification groups refitted beside every candidate
            (`--refit`; one name or several, e.g. "surge", "yaw"), for a twin not yet identified; None:
            none.
        refit_weight: with `refit`, how many windows of data each refitted coefficient's belief
            counts as (`--refit-weight`; default 1, as `twin identify`'s beliefs ×1).
        log (Callable[[str], None] | None): a callable taking progress lines (str); None: silent.

    Returns:
        (Diagnosis): `.effects` (Effect objects with their Parameters and units), `.amended`,
            `.fit_before` / `.fit_after`, `.unexplained`, `.notes`; `table()` one row per
            parameter named.

    Raises:
        TwinError: `window_s` not a positive number of seconds; `effects` or `refit` not names,
            an effect unknown or with nothing to act on in these recordings, a group the vessel
            has not, or `refit_weight` not positive; `log` not callable; `wind` neither None nor "measured", or
            "measured" without a wind stream or a wind load model; no recordings, one given twice,
            one that cannot be read or has no inputs to drive the vessel, or recordings too short
            to fit on one part and judge on another (about 2 minutes with inputs at least); a sea
            given wrongly or one the vessel cannot run in; or `vessel` is neither a twin.Vessel nor
            the name of a shipped vessel or a readable vessel file.
    """
    check_flags("diagnose_recordings", calibrated=calibrated, kinematic=kinematic)
    if window_s is not None and not _finite(window_s):
        raise TwinError(f"window_s must be a positive finite number of seconds, got {window_s!r}")
    if not _finite(refit_weight):
        raise TwinError(f"refit_weight must be a positive finite number of windows, got {refit_weight!r}")
    if log is not None and not callable(log):
        raise TwinError(f"log is a callable taking progress lines (str) or None, got {log!r:.60}")
    v = _in_sea(_vessel(vessel), sea)
    library = None if effects is None else list(_names(effects, "effects", "`twin effects` lists them"))
    refit = None if refit is None else _names(refit, "refit", "surge, sway, yaw, ...: the vessel's fit groups")
    found = _doctor.diagnose(_recordings(recordings, v), v, window_s=WINDOW_S if window_s is None else window_s,
                             log=log, library=library, calibrated=calibrated, refit=refit,
                             refit_weight=refit_weight, kinematic=kinematic, wind=wind)
    typed = Diagnosis(**{f.name: getattr(found, f.name) for f in fields(found)})
    if sea is not None:
        typed.amended = without_known_sea(typed.amended)
    typed.effects = [Effect(e) for e in found.effects]
    return typed


def judge(recordings, vessel: Vessel | str, effects, **options) -> Judgement:
    """Judge effects at the values given, nothing fitted, as `twin diagnose --given` does.

    Can these recordings prove that physics as given? The twin with the effects and the twin without
    them are judged by the diagnosis's rule on the blocks a diagnosis of these recordings uses, each
    log's compass calibration applied to both.

    Args:
        recordings (str | Path | Recording | list): one recording or a list of them: paths or Recordings
            (twin.read_recording), each at most once, each with inputs that can drive the vessel.
        vessel: the twin: a twin.Vessel, a shipped vessel's name or a vessel file's path.
        effects (str | list[str]): one effect text or several, judged together, as `twin effects` lists
            them (e.g. "current=0.1,90": 0.1 m/s flowing towards 90°).
        **options (Any): the keywords of twin.diagnose.doctor.given_evidence, documented there:
            `window_s` (the free-run window, s; default 10), `calibrated` (False:
            `--no-calibration`), `wind` ("measured": the recordings' measured wind is the physics
            judged) and `known_wind` ("measured": their measured wind a known input of both twins,
            `--given ... --wind-measured`).

    Returns:
        The judgement (`earns_its_place()`, `verdict`, `z`, `held_out_gain`, ...; `str()` says it
        in a sentence).

    Raises:
        TwinError: `effects` not texts, or one that is unknown, malformed or named twice (told before
            the recordings are read); an option `given_evidence` does not take, or `window_s` not a
            positive number of seconds; no recordings, one
            given twice, one that cannot be read or cannot drive the vessel, or recordings too
            short to fit on one part and judge on another; or `vessel` is neither a twin.Vessel nor
            the name of a shipped vessel or a readable vessel file.
    """
    effects = list(_names(effects, "effects", "texts such as 'current=0.1,90'; `twin effects` lists them", texts=True))
    known_options(given_evidence, options, "judge")
    if "window_s" in options and not _finite(options["window_s"]):
        raise TwinError(f"window_s must be a positive finite number of seconds, got {options['window_s']!r}")
    for text in effects:  # an unknown effect is told before the recordings are read
        if isinstance(text, str):
            parse_effect(text)
    twice = named_twice(effects)
    if twice:
        raise TwinError(f"effects name {', '.join(twice)} twice: give each effect once, with its values")
    v = _vessel(vessel)
    e = given_evidence(_recordings(recordings, v), v, effects, **options)
    verdict = ("earns its place" if e.earns_its_place() else "contradicted" if e.z <= -Z_MIN
               else "does not earn its place")
    return Judgement(tuple(effects), verdict, float(e.z), float(e.rel), float(e.rel_excess), int(e.blocks_for),
                     int(e.blocks_against), int(e.affected), tuple(e.at_edge), str(given_text(effects, e)), e)
