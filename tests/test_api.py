"""The Python API: no exported name is replaced by a subpackage once every part of the package is
imported, every exported function checks its input as the command does, results are typed with
short reprs."""
import importlib
import pkgutil

import numpy as np
import pytest

import twin

# each export called with small arguments, and a figure of what it gave: the same on every call
FAST_CALLS = {
    "load_vessel": (lambda: twin.load_vessel("blueboat"), lambda v: v.name),
    "simulate": (lambda: twin.simulate("blueboat", "step", duration_s=2.0), lambda r: (r.t[-1], *r.eta[-1])),
    "simulate_run": (lambda: twin.simulate_run("blueboat", scenario="turn", duration_s=2.0),
                     lambda s: (s.run.t[-1], *s.run.eta[-1])),
    "validate": (lambda: twin.validate("cybership1"), lambda v: (len(v.quantities), len(v.flagged()))),
    "effective_parameters": (lambda: twin.effective_parameters("blueboat"), lambda e: e["rigid_body"]["mass_kg"]),
    "compile_vessel": (lambda: twin.compile_vessel(twin.load_vessel("blueboat")), lambda c: (c.model.nv, c.vessel.name)),
}
EXPECTED = {"load_vessel": "blueboat", "effective_parameters": 15.0, "compile_vessel": (3, "blueboat"),
            "validate": (9, 0)}


@pytest.fixture(scope="module")
def everything_imported():
    for m in pkgutil.walk_packages(twin.__path__, "twin."):
        if not m.name.endswith("__main__"):
            importlib.import_module(m.name)
    return twin


@pytest.fixture(scope="module")
def log(tmp_path_factory):
    path = tmp_path_factory.mktemp("api") / "run.csv"
    twin.simulate_run("blueboat", scenario="zigzag", duration_s=40.0).write(path)
    return path


def test_no_export_is_a_subpackage_or_module(everything_imported):
    for name in twin.__all__ if hasattr(twin, "__all__") else twin.api.__all__:
        value = getattr(twin, name)
        assert not isinstance(value, type(twin)), f"twin.{name} is a module"
    for name in twin.api.__all__:
        assert not isinstance(getattr(twin, name), type(twin)), f"twin.{name} is a module"


@pytest.mark.parametrize("name", sorted(FAST_CALLS))
def test_each_exported_function_works_twice_after_every_subpackage_is_imported(name, everything_imported):
    call, figure = FAST_CALLS[name]
    first, second = figure(call()), figure(call())
    assert first == second
    if name in EXPECTED:
        assert first == EXPECTED[name]
    else:  # a run of 2 s that went ahead, and not sideways
        assert first[0] == pytest.approx(2.0) and first[1] > 0.5 and abs(first[2]) < 1e-6


def test_recording_functions_work_twice_after_every_subpackage_is_imported(everything_imported, log):
    for _ in range(2):
        rec = twin.read_recording(log)
        prep = twin.prepare_recording(rec, "blueboat")
        assert len(prep.t) == 401 and prep.t[-1] == pytest.approx(40.0)
        assert np.array_equal(twin.prepare_recording(rec).u, prep.u)  # the vessel's own antenna is at CO
        calibrations = twin.calibrate([rec], "blueboat")
        assert len(calibrations) == 1 and calibrations[0].heading_bias_deg is None  # the twin's own run
        assert twin.evaluate("blueboat", [rec]).score("u").r2 > 0.9


def test_one_name_is_a_name_not_its_letters(log):
    rec = twin.read_recording(log)
    with pytest.raises(twin.TwinError) as err:
        twin.identify([rec], "blueboat", params="no_such_term")
    assert "no_such_term" in str(err.value) and "n, o" not in str(err.value)


def test_every_export_is_covered_by_a_call():
    slow = {"identify", "diagnose_recordings", "judge", "crosscheck", "save_vessel", "manoeuvres", "manoeuvre_bands"}  # tested in their own files
    called = set(FAST_CALLS) | {"read_recording", "prepare_recording", "calibrate", "evaluate"} | slow
    functions = {n for n in twin.api.__all__ if callable(getattr(twin, n)) and not isinstance(getattr(twin, n), type)}
    assert functions <= called, functions - called


_HELD = np.full((2, 2), 1600.0)


@pytest.mark.parametrize("series, says", [
    (twin.InputSeries(np.array([]), np.zeros((0, 2)), "pwm"), "at least one time"),
    (twin.InputSeries(np.arange(3.0), _HELD, "pwm"), r"shape \(3, 2\), got \(2, 2\)"),
    (twin.InputSeries(np.array([0.0, 1.0]), np.array([1500.0, 1600.0]), "pwm"), r"got \(2,\)"),
    (twin.InputSeries(np.array([0.0, 1.0]), _HELD, "volts"), "kind is one of"),
    (twin.InputSeries(np.array([0.0, 1.0]), np.array([[1500.0, np.nan], [1600.0, 1600.0]]), "pwm"), "values: NaN"),
    (twin.InputSeries(np.array([0.0, np.inf]), _HELD, "pwm"), "t: NaN"),
    (twin.InputSeries(np.array([1.0, 0.0]), _HELD, "pwm"), "backwards"),
    (twin.InputSeries(np.array([0.0, 1.0]), _HELD, "pwm", supply_v=np.array([16.0])), "one voltage per time"),
    (twin.InputSeries(np.array([0.0, 1.0]), np.full((2, 2), "a"), "pwm"), "arrays of numbers"),
    (twin.InputSeries(np.array([0.0, 1.0]), _HELD, "propeller_rudder"), "is driven by"),
])
def test_an_input_series_built_by_hand_is_checked_before_it_drives_a_run(series, says):
    for call in (lambda: twin.simulate("blueboat", series, 5.0),
                 lambda: twin.simulate_run("blueboat", inputs=series, duration_s=5.0)):
        with pytest.raises(twin.TwinError, match=says):
            call()


def test_an_input_series_of_lists_runs_as_its_arrays():
    given = twin.simulate("blueboat", twin.InputSeries([0.0, 1.0], [[1500, 1500], [1600, 1600]], "pwm"), 3.0)
    arrays = twin.simulate("blueboat", twin.InputSeries(np.array([0.0, 1.0]), np.array([[1500.0] * 2, [1600.0] * 2]),
                                                        "pwm"), 3.0)
    assert np.array_equal(given.nu, arrays.nu) and given.nu[-1, 0] > 0.3


@pytest.mark.parametrize("call, says", [
    (lambda: twin.evaluate("blueboat", []), "no recordings"),
    (lambda: twin.identify([], "blueboat"), "no recordings"),
    (lambda: twin.diagnose_recordings([], "blueboat"), "no recordings"),
    (lambda: twin.calibrate([], "blueboat"), "no recordings"),
    (lambda: twin.judge([], "blueboat", "current=0.1,90"), "no recordings"),
    (lambda: twin.simulate_run("blueboat", duration_s=5.0, sample_dt_s=10.0), "longer than the run"),
    (lambda: twin.simulate("blueboat", duration_s=-1.0), "positive"),
    (lambda: twin.evaluate(42, []), "expected a vessel"),
    (lambda: twin.effective_parameters("titanic"), "unknown vessel 'titanic'"),
    (lambda: twin.load_vessel(""), "got an empty name"),
    (lambda: twin.crosscheck("titanic"), "unknown vessel 'titanic'"),
    (lambda: twin.crosscheck("blueboat", duration_s=0.0), "positive"),
    (lambda: twin.identify([], "blueboat", params="thrust_gain"), "no recordings"),
    (lambda: twin.diagnose_recordings(["a.csv"], "blueboat", effects="thrust_gain,current"),
     r"as a list, \['thrust_gain', 'current'\]"),
])
def test_bad_input_is_a_twin_error_saying_so(call, says):
    with pytest.raises(twin.TwinError, match=says):
        call()


def test_a_recording_of_another_kind_of_vessel_is_refused(log):
    with pytest.raises(twin.TwinError, match="another kind of vessel"):
        twin.evaluate("esso_osaka", [log])
    with pytest.raises(twin.TwinError, match="another kind of vessel"):
        twin.identify([log], "esso_osaka")


def test_results_are_typed_with_short_rounded_reprs(log):
    ev = twin.evaluate("blueboat", [log])
    assert len(repr(ev)) < 120 and "0.9" in repr(ev)
    s = ev.score("r", "free_run_10s")
    assert isinstance(s, twin.Score) and s.unit == "°/s" and s.n > 0
    assert not any(len(tok) > 8 for tok in repr(s).replace(",", " ").split() if tok[:1].isdigit())
    table = ev.table()
    assert table.title and "horizon" in str(table).splitlines()[1] and table.to_dict()["rows"]
    # "calibrated" says whether a log's compass offset was applied, never merely that one was looked for
    # the twin's own run: no offset to apply, and no row says otherwise
    assert not ev.applied and not any(r["calibrated"] for r in table.to_dict()["rows"])
    assert "no log's compass offset was applied" in table.title
    assert ev.to_dict()["vessel"] == "blueboat" and ev.by_state == [] and ev.stand_ins == []
    by_speed = twin.evaluate("blueboat", [log], by="speed")
    shares = sum(b.share["u"] for b in by_speed.by_state)
    assert shares == pytest.approx(1.0 - by_speed.score("u").r2, rel=1e-6) and len(by_speed.by_state) >= 2
    with pytest.raises(twin.TwinError, match="unknown state"):
        twin.evaluate("blueboat", [log], by="heave")


def test_an_effect_has_parameters_with_units_and_evidence():
    e = twin.Effect({"name": "current", "text": "current=0.1,90", "parameters": {"speed_m_s": 0.1, "dir_deg": 90.0},
                     "ci": {"speed_m_s": [0.08, 0.12]}, "z": 4.2, "evidence": {"z": 4.2, "held_out_gain": 0.1,
                                                                               "blocks_for": 9, "blocks_against": 1}})
    units = {p.name: p.unit for p in e.parameters}
    assert units["speed_m_s"] and units["dir_deg"]
    assert e.parameters[0].ci95 == (0.08, 0.12)
    assert e.evidence.z == 4.2 and e.evidence.blocks_for == 9
    assert e["text"] == "current=0.1,90" and "current" in repr(e) and len(repr(e)) < 120


def test_the_api_refuses_a_negative_current_and_a_recording_that_is_no_path():
    """A negative speed is a flow the other way said twice (the direction carries the sense), and a
    reader given None says what it wants: TwinError, not a TypeError from deep inside."""
    from twin.api import read_recording, simulate_run
    from twin.errors import TwinError

    with pytest.raises(TwinError, match=r"current_speed_m_s must be a finite number ≥ 0, got -0.5"):
        simulate_run("yellowfish", duration_s=1.0, current=(-0.5, 10.0))
    with pytest.raises(TwinError, match=r"a recording is read from a file path \(str or Path\), got NoneType"):
        read_recording(None)


@pytest.mark.parametrize("kwargs,message", [
    ({"current": "abc"}, r"current must be \(speed m/s, direction deg\), two numbers, got 'abc'"),
    ({"current": (0.1,)}, r"current must be \(speed m/s, direction deg\), two numbers"),
    ({"wind": "5,45"}, r"wind must be \(speed m/s, direction deg\)"),
    ({"wind": (5, 45, 1)}, r"wind must be \(speed m/s, direction deg\), two numbers, got \(5, 45, 1\)"),
    ({"wind": ("5", 45)}, r"wind's speed must be a number, got '5'"),
    ({"seed": "x"}, r"the seed must be a whole number, got 'x'"),
    ({"duration_s": "10"}, r"the duration must be a number, got '10'"),
])
def test_simulate_run_refuses_arguments_of_the_wrong_kind_with_a_twin_error(kwargs, message):
    from twin.api import simulate_run
    from twin.errors import TwinError

    with pytest.raises(TwinError, match=message):
        simulate_run("yellowfish", **{"duration_s": 1.0, **kwargs})


def test_simulate_takes_a_sea_as_its_text_as_simulate_run_does():
    calm = twin.simulate("blueboat", "zigzag", duration_s=3.0)
    waves = twin.simulate("blueboat", "zigzag", duration_s=3.0, sea="0.3,2.5,30")
    assert len(waves.t) == len(calm.t) and not np.allclose(waves.eta[:, :2], calm.eta[:, :2], atol=1e-3)
    with pytest.raises(twin.TwinError, match="^sea expects HS,TP,DIR"):
        twin.simulate("blueboat", "zigzag", duration_s=3.0, sea="0.3,2.5")


def test_diagnose_recordings_takes_the_clis_option_names(monkeypatch):
    """`effects` (the CLI's --effects) reaches the diagnosis as its candidate list, the window as
    window_s; a keyword the CLI does not have is Python's TypeError, before any work."""
    import twin.api
    import twin.diagnose.doctor as doctor

    seen = {}

    def fake(recordings, prior, **kwargs):
        seen.update(kwargs)
        raise twin.TwinError("stop")

    monkeypatch.setattr(doctor, "diagnose", fake)
    monkeypatch.setattr(twin.api, "_recordings", lambda recordings, vessel=None: list(recordings))
    rec = object()
    with pytest.raises(twin.TwinError, match="stop"):
        twin.diagnose_recordings([rec], "yellowfish", effects="current", window_s=8.0)
    assert seen["library"] == ["current"] and seen["window_s"] == 8.0 and seen["wind"] is None
    with pytest.raises(TypeError):
        twin.diagnose_recordings([rec], "yellowfish", library=["current"])


def test_validation_and_crosscheck_results_have_short_reprs():
    """print() of a result says what it found in a line, not every point of the hull outline or run."""
    val = twin.validate("blueboat")
    assert len(repr(val)) < 160 and "blueboat" in repr(val) and "flagged" in repr(val)
    results = twin.crosscheck("yellowfish", duration_s=5.0, only=["full"])
    assert results and all(len(repr(r)) < 100 and r.case in repr(r) for r in results)


@pytest.mark.parametrize("call, said", [
    (lambda v: twin.simulate(v, None, duration_s=5), "drive is a scenario name"),
    (lambda v: twin.simulate(3, "zigzag"), "expected a vessel"),
    (lambda v: twin.simulate(v, "zigzag", duration_s=5, sea=3), "sea is a twin.physics.waves.Sea"),
    (lambda v: twin.simulate(v, "zigzag", duration_s=5, nu0=[1, 2]), r"nu0 must be 3 finite numbers"),
    (lambda v: twin.simulate(v, "zigzag", duration_s=float("inf")), "positive, finite number of seconds"),
    (lambda v: twin.evaluate(v, None), "recordings are a path, a twin.Recording or a list"),
    (lambda v: twin.evaluate(v, [1, 2]), "recordings are a path, a twin.Recording or a list"),
    (lambda v: twin.crosscheck(v, duration_s=float("inf")), "duration_s must be a positive, finite"),
    (lambda v: twin.diagnose_recordings("r.csv", v, effects=[]), "effects: give one or more names"),
    (lambda v: twin.judge("r.csv", v, 5), "effects: give one or more names"),
    (lambda v: twin.identify("r.csv", v, params="Xu", max_evaluations=1.5), "max_evaluations must be a whole number"),
    (lambda v: twin.identify("r.csv", v, params="Xu", window_s=0), "window_s must be a positive finite number"),
    (lambda v: twin.identify("r.csv", v, params=[]), "params must be None or a non-empty list"),
    (lambda v: twin.load_vessel(None), "a vessel is a shipped vessel's name"),
])
def test_the_api_says_what_a_wrong_argument_should_be(tmp_path, monkeypatch, call, said):
    """A wrong argument is a TwinError saying what it should be, never an error from inside numpy, MuJoCo
    or scipy (TypeError, IndexError, OverflowError) nor a run of scipy's optimiser on 1.5 evaluations."""
    monkeypatch.chdir(tmp_path)
    twin.simulate_run("blueboat", scenario="random", duration_s=20).write("r.csv")
    with pytest.raises(twin.TwinError, match=said):
        call(twin.load_vessel("blueboat"))


def test_wrong_arguments_found_by_calling_every_export_are_twin_errors(tmp_path, log):
    """Each of these is a TwinError, not an error from deep inside nor a silent run: a list of
    recordings given where one is expected, a crosscheck of no case or of one sample, an empty
    `only` (not every case), a stride of True or inf."""
    rec = twin.read_recording(log)
    sim = twin.simulate_run("blueboat", duration_s=2.0)
    calls = [
        (lambda: twin.compile_vessel(None), "expected a vessel"),
        (lambda: twin.save_vessel("blueboat", None), r"a file path \(str or Path\), got None"),
        (lambda: sim.write(42), r"a file path \(str or Path\), got 42"),
        (lambda: sim.write(""), r"a file path \(str or Path\), got ''"),
        (lambda: twin.simulate("blueboat", "zigzag", duration_s=2.0, foo=1), "simulate: unknown option foo"),
        (lambda: twin.simulate("blueboat", "zigzag", duration_s=2.0, control_dt_s="x"), "control period must be a"),
        (lambda: twin.simulate_run("blueboat", duration_s=2.0, inputs=rec), "inputs is an inputs CSV's path"),
        (lambda: twin.crosscheck("blueboat", duration_s=2.0, only=3), "only: give one or more names"),
        (lambda: twin.crosscheck("blueboat", duration_s=2.0, only=[]), "only: give one or more names"),
        (lambda: twin.crosscheck("blueboat", duration_s=0.01, only="full"), "at least one sample"),
        (lambda: twin.read_recording(log, channels={"reversed": 5}), r"channels\['reversed'\] must be a dict"),
        (lambda: twin.read_recording(log, channels={"trim": {"left": "x"}}), r"channels\['trim'\] must be a dict"),
        (lambda: twin.prepare_recording([rec, rec], "blueboat"), "prepares one recording, got 2"),
        (lambda: twin.evaluate("blueboat", rec, stride_s=float("inf")), "stride_s must be a positive finite number"),
        (lambda: twin.evaluate("blueboat", rec, stride_s=True), "stride_s must be a positive finite number"),
        (lambda: twin.evaluate("blueboat", rec, stride_s=None), "stride_s must be a positive finite number"),
        (lambda: twin.identify(rec, "blueboat", progress=3), "progress is a callable"),
        (lambda: twin.identify(rec, "blueboat", prior_weights=3), "prior_weights must be a non-empty list"),
        (lambda: twin.diagnose_recordings(rec, "blueboat", window_s=True), "window_s must be a positive finite number"),
        (lambda: twin.diagnose_recordings(rec, "blueboat", refit="surge", refit_weight="x"), "refit_weight must be"),
        (lambda: twin.diagnose_recordings(rec, "blueboat", log=3), "log is a callable"),
        (lambda: twin.judge(rec, "blueboat", "current=0.1,90", window_s=float("nan")), "window_s must be a positive"),
        (lambda: twin.judge(rec, "blueboat", "current=0.1,90", window_s="x"), "window_s must be a positive"),
    ]
    for call, says in calls:
        with pytest.raises(twin.TwinError, match=says):
            call()
    assert twin.compile_vessel("blueboat").vessel.name == "blueboat"  # a name, as every other export takes it
    # a list of one is still one recording
    assert np.array_equal(twin.prepare_recording([rec], "blueboat").u, twin.prepare_recording(rec, "blueboat").u)


def test_a_flag_given_as_text_and_a_controller_returning_nonsense_are_twin_errors(log):
    """A flag must be a bool: the text "no" is true to Python, and calibrated="no" would apply the
    calibration it means to skip. A controller returning text, one number or NaN is refused before the
    engine runs on it."""
    rec = twin.read_recording(log)
    flags = [
        (lambda: twin.prepare_recording(rec, "blueboat", calibrated="no"), "calibrated must be True or False"),
        (lambda: twin.compile_vessel("blueboat", "false"), "wind_inputs must be True or False"),
        (lambda: twin.crosscheck("blueboat", duration_s=2.0, six_dof=1), "six_dof must be True or False"),
        (lambda: twin.save_vessel("blueboat", "v.json", force="yes"), "force must be True or False"),
        (lambda: twin.diagnose_recordings(rec, "blueboat", kinematic="off"), "kinematic must be True or False"),
        (lambda: twin.identify(rec, "blueboat", calibrated="no"), "identify: calibrated must be True or False"),
        (lambda: twin.judge(rec, "blueboat", "current=0.1,90", calibrated=0), "calibrated must be True or False"),
        (lambda: twin.simulate_run("blueboat", duration_s=2.0, six_dof="no"), "six_dof must be True or False"),
        (lambda: twin.evaluate("blueboat", rec, calibrated="no"), "evaluate: calibrated must be True or False"),
        (lambda: twin.simulate("blueboat", "zigzag", duration_s=2.0, terms="all"), "terms is a .*Terms"),
        (lambda: twin.simulate_run("blueboat", duration_s=2.0, start_speed_m_s=float("nan")),
         "start speed must be a finite number, got nan"),
        (lambda: twin.judge(rec, "blueboat", ["thrust_gain=0.8", "thrust_gain=0.9"]),  # the gains would multiply
         "effects name thrust_gain twice"),
    ]
    for call, says in flags:
        with pytest.raises(twin.TwinError, match=says):
            call()
    for output in ("x", (1.0,), (float("nan"), 0.0), None, (0.5, float("inf"))):
        with pytest.raises(twin.TwinError, match=r"the controller gave .* at t = 0\.00 s: it must return two finite"):
            twin.simulate("blueboat", lambda t, eta, nu, out=output: out, duration_s=1.0)
    held = twin.simulate("blueboat", lambda t, eta, nu: (5.0, 0.0), duration_s=3.0)  # beyond ±1: held at full
    assert held.nu[-1, 0] > 0.5
