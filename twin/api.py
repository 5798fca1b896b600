"""The Python API: what the `twin` command does, as functions returning typed results with short
reprs (and `to_dict()` / `table()` where a table is what one wants to look at).

    import twin
    v = twin.load_vessel("blueboat")
    recs = [twin.read_recording(p) for p in paths]         # Recording (twin info)
    prep = twin.prepare(recs[0], v)                        # Prepared: as the vessel's sensors see it
    ident = twin.identify(recs[:7], v)                     # Identification (twin identify)
    score = twin.evaluate(ident.vessel, recs[7:])          # Evaluation (twin evaluate)
    found = twin.diagnose(recs[:7], ident.vessel)          # Diagnosis (twin diagnose)
    e = twin.judge(recs[:7], ident.vessel, "current=0.1,90")  # Evidence (twin diagnose --given)
    run = twin.simulate(ident.vessel, "zigzag", duration_s=120)
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

from .drive import InputSeries, get as get_scenario, read_inputs_csv
from .engine.limits import Limited, beyond_bounds
from .engine.mjcf import CompiledVessel, compile_vessel
from .engine.parameters import effective_parameters
from .engine.sim import simulate as _simulate
from .errors import TwinError
from .run import Run
from .verify.crosscheck import crosscheck
from .verify.validate import Validation, validate as _validate
from .vessel import Vessel, load as load_vessel, save as save_vessel

__all__ = ["Run", "Vessel", "InputSeries", "Validation", "Simulation", "Evaluation", "load_vessel", "save_vessel",
           "simulate", "simulate_run", "crosscheck", "effective_parameters", "compile_vessel", "validate",
           "read_recording", "prepare", "calibrate", "identify", "evaluate", "diagnose", "judge"]


def simulate(vessel: Vessel | str, drive="zigzag", duration_s: float = 120.0, **kwargs) -> Run:
    """Run the engine twin; `drive` is a scenario name, an InputSeries or a controller."""
    if isinstance(vessel, str):
        vessel = load_vessel(vessel)
    if isinstance(drive, str):
        drive = get_scenario(drive, kwargs.pop("seed", 0))
    return _simulate(compile_vessel(vessel), drive, duration_s, **kwargs)


@dataclass
class Simulation:
    """A run of the twin with what it was run on, and where its inputs went beyond the vessel
    file's bounds (`limits`: empty when they never did)."""

    run: Run
    compiled: CompiledVessel
    limits: list[Limited] = field(default_factory=list)

    def __repr__(self) -> str:
        r = self.run
        return (f"Simulation({self.compiled.vessel.name}, {r.t[-1] - r.t[0]:g} s, final position "
                f"({r.eta[-1, 0]:.2f}, {r.eta[-1, 1]:.2f}) m, {len(self.limits)} input limits hit)")

    def write(self, path, origin: tuple[float, float] | None = None) -> None:
        """The run as .csv, .mcap, .rrd, .tlog or .bin (map positions around `origin`, lat/lon deg)."""
        from .outputs import write

        v = self.compiled.vessel
        write({"twin": self.run}, Path(path), geometry=self.compiled.geometry, vessel_name=v.name, mjcf=v.mjcf,
              origin=origin)


def simulate_run(vessel: Vessel | str, *, scenario: str = "zigzag", inputs=None, duration_s: float = 120.0,
                 seed: int = 0, sample_dt_s: float = 0.1, current: tuple[float, float] | None = None,
                 wind: tuple[float, float] | None = None, sea=None, six_dof: bool = False) -> Simulation:
    """`twin simulate`: a scenario (or an inputs CSV path / InputSeries) with an optional current
    (speed m/s, direction deg it flows towards) and wind (speed m/s, direction deg it blows from);
    `sea` (a physics.waves.Sea, or its text 'HS,TP,DIR[,SPREAD]' / 'regular,H,T,DIR', drawn with
    `seed`) runs the 6-DOF hull in waves, `six_dof` the 6-DOF hull in calm water."""
    if isinstance(vessel, str):
        vessel = load_vessel(vessel)
    env = vessel.environment
    if current is not None:
        env = replace(env, current_speed_m_s=current[0], current_dir_deg=current[1])
    if wind is not None:
        env = replace(env, wind_speed_m_s=wind[0], wind_dir_deg=wind[1])
    vessel = vessel.with_environment(env)
    if inputs is not None and not isinstance(inputs, InputSeries):
        inputs = read_inputs_csv(inputs)
    drive = inputs if inputs is not None else get_scenario(scenario, seed)
    if isinstance(drive, InputSeries) and drive.kind == "pwm" and vessel.thrusters.kind != "t200":
        raise TwinError(f"vessel '{vessel.name}' has no PWM model: give thrust_left,thrust_right in N")
    if isinstance(sea, str):
        from .physics.waves import parse_sea

        sea = parse_sea(sea, seed)
    compiled = compile_vessel(vessel)
    run = _simulate(compiled, drive, duration_s, sample_dt_s=sample_dt_s, sea=sea, six_dof=six_dof)
    run.meta["scenario"] = "inputs" if inputs is not None else scenario
    limits = beyond_bounds(vessel, run.meta["inputs"], duration_s)
    run.meta["limits"] = [lim.to_dict() for lim in limits]
    return Simulation(run, compiled, limits)


def validate(vessel: Vessel | str, case: str | None = None) -> Validation:
    """`twin validate`: every quantity of one vessel and mass case side by side (`.quantities`, `.flagged()`)."""
    if isinstance(vessel, str):
        vessel = load_vessel(vessel)
    return _validate(vessel if case is None else vessel.with_case(case))


def _vessel(vessel: Vessel | str) -> Vessel:
    return load_vessel(vessel) if isinstance(vessel, str) else vessel


def _recordings(recordings) -> list:
    from .formats import read_recording as read
    from .recording import Recording

    items = [recordings] if isinstance(recordings, (str, Path, Recording)) else list(recordings)
    return [r if isinstance(r, Recording) else read(r) for r in items]


def read_recording(path, channels: dict | None = None):
    """`twin info`'s reader: an ArduPilot .bin/.tlog, a CSV (generic or a known dataset's layout) or
    an MCAP file → Recording."""
    from .formats import read_recording as read

    return read(path, channels=channels)


def prepare(recording, vessel: Vessel | str | None = None, calibrated: bool = True):
    """A recording made ready for fitting (seed 004 §5.1): with a vessel, as its sensors see it (lever
    arm, heading corrections) and, when `calibrated`, with the log's own compass offset estimated
    from its GNSS track; without one, the antenna's positions as logged."""
    from .ident.identify import calibrate as calibrate_logs, prepared
    from .prepare import prepare as bare

    rec = _recordings(recording)[0]
    if vessel is None:
        return bare(rec)
    v = _vessel(vessel)
    if calibrated:
        v, _ = calibrate_logs([rec], v)
    return prepared([rec], v)[0]


def calibrate(recordings, vessel: Vessel | str) -> list:
    """Each log's compass offset from its kinematics (twin.fit.calibrate.LogCalibration)."""
    from .ident.identify import calibrate as calibrate_logs

    return calibrate_logs(_recordings(recordings), _vessel(vessel))[1]


def identify(recordings, vessel: Vessel | str, **options):
    """`twin identify`: an Identification (.vessel is the identified twin; options as
    twin.ident.identify.identify)."""
    from .ident.identify import identify as run

    return run(_recordings(recordings), _vessel(vessel), **options)


class Table(list):
    """Rows (dicts with the same keys) that print as aligned columns; still a list for code."""

    def __str__(self) -> str:
        if not self:
            return "(no rows)"
        keys = list(self[0])
        cells = [[_cell(row.get(k)) for k in keys] for row in self]
        widths = [max(len(k), *(len(c[i]) for c in cells)) for i, k in enumerate(keys)]
        lines = ["  ".join(k.ljust(w) for k, w in zip(keys, widths))]
        lines += ["  ".join(c.rjust(w) for c, w in zip(row, widths)) for row in cells]
        return "\n".join(lines)

    __repr__ = __str__


def _cell(value) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


@dataclass
class Evaluation:
    """`twin evaluate`: R² and MAE per DOF and horizon, with and without each log's compass
    calibration, and the calibrations; by_manoeuvre: where the 10-s free runs miss
    (fit.evaluate.misfit_by_manoeuvre), read against what the twin's fit saw when identify wrote it."""

    vessel: str
    metrics: dict
    metrics_uncalibrated: dict
    calibrations: list
    by_manoeuvre: dict = field(default_factory=dict)

    def __repr__(self) -> str:
        m = self.metrics.get("free_run_10s", {})
        cells = ", ".join(f"{d} {m[d]['r2']:.3f}" for d in "uvr" if m.get(d, {}).get("r2") is not None)
        return f"Evaluation({self.vessel}: 10-s free runs R² {cells})"

    def table(self) -> Table:
        """One row per horizon and DOF: {horizon, dof, r2, mae, n, calibrated} (prints as columns)."""
        rows = Table()
        for calibrated, metrics in ((True, self.metrics), (False, self.metrics_uncalibrated)):
            for horizon, m in metrics.items():
                rows += [{"horizon": horizon, "dof": d, **{k: m[d].get(k) for k in ("r2", "mae", "n")},
                          "calibrated": calibrated} for d in "uvr"]
        return rows

    def to_dict(self) -> dict:
        return {"vessel": self.vessel, "metrics": self.metrics, "metrics_uncalibrated": self.metrics_uncalibrated,
                "calibrations": [c.to_dict() for c in self.calibrations], "by_manoeuvre_10s": self.by_manoeuvre}


def evaluate(vessel: Vessel | str, recordings, stride_s: float = 2.0) -> Evaluation:
    """How the twin predicts recordings (one step, 10-s and 30-s free runs, whole segments), and
    where its 10-s free runs miss, by manoeuvre and beyond what its fit saw."""
    from .fit.coverage import from_dict
    from .fit.evaluate import evaluate as run, misfit_by_manoeuvre
    from .ident.identify import calibrate as calibrate_logs, prepared

    v, recs = _vessel(vessel), _recordings(recordings)
    seen = from_dict(v.uncertainty["fitted_on"], f"{v.name}: uncertainty.fitted_on") \
        if "fitted_on" in v.uncertainty else None
    calibrated, calibrations = calibrate_logs(recs, v)
    preps = prepared(recs, calibrated)
    return Evaluation(v.name, run(calibrated, preps, stride_s=stride_s), run(v, prepared(recs, v), stride_s=stride_s),
                      calibrations, misfit_by_manoeuvre(calibrated, preps, 10.0, stride_s, fitted=seen))


def diagnose(recordings, vessel: Vessel | str, **options):
    """`twin diagnose`: a Diagnosis (.effects, .amended, .fit_before/.fit_after, .unexplained)."""
    from .diagnose.doctor import diagnose as run

    return run(_recordings(recordings), _vessel(vessel), **options)


def judge(recordings, vessel: Vessel | str, effects, **options):
    """`twin diagnose --given`: the effects at the values given (texts as `twin effects` lists them),
    nothing fitted, judged by the diagnosis's rule on the blocks a diagnosis of these recordings
    uses. An Evidence (.earns_its_place(), .z, .rel_excess, .blocks_for/.blocks_against, .to_dict());
    `str(twin.diagnose.doctor.given_text(effects, e))` says it in a sentence."""
    from .diagnose.doctor import given_evidence

    effects = [effects] if isinstance(effects, str) else list(effects)
    return given_evidence(_recordings(recordings), _vessel(vessel), effects, **options)
