"""The `twin` command end to end, including bad input."""
import json
import sys
from dataclasses import replace

import numpy as np
import pytest

import twin.vessel as vessel_mod
from twin.engine.mjcf import compile_vessel
from twin.errors import TwinError
from twin.cli.run import params_lines
from twin.drive import read_inputs_csv
from twin.engine.parameters import effective_parameters
from twin.run import read_csv
import twin_command

MODEL = vessel_mod.MODEL_DIR


def twin(*args, cwd=None):
    return twin_command.twin(*args, cwd=cwd)


def test_simulate_writes_csv(tmp_path):
    out = tmp_path / "run.csv"
    p = twin("simulate", "--vessel", "yellowfish", "--scenario", "turn", "--duration", "20", "--out", out)
    assert p.returncode == 0, p.stderr
    run = read_csv(out)
    assert run.t[-1] == pytest.approx(20.0)
    assert run.nu[-1, 2] > 0.05  # positive yaw command: turning to starboard
    assert np.all(run.pwm_us[:, 0] >= run.pwm_us[:, 1])


def test_simulate_inputs_file_and_current(tmp_path):
    inputs = tmp_path / "in.csv"
    inputs.write_text("t,thrust_left,thrust_right\n0,0,0\n5,0,0\n")
    out = tmp_path / "drift.csv"
    p = twin("simulate", "--vessel", "yellowfish", "--inputs", inputs, "--duration", "60", "--current", "0.3,90",
             "--out", out)
    assert p.returncode == 0, p.stderr
    run = read_csv(out)
    assert run.nu[-1, 1] == pytest.approx(0.3, abs=0.01)  # drifts east with the water


def test_params_text_gives_every_value_its_unit():
    boat = twin("params", "--vessel", "blueboat")
    assert boat.returncode == 0, boat.stderr
    assert "(kg, kg·m, kg·m²)" in boat.stdout and "Xuu -3.0288 N s2/m2" in boat.stdout
    assert "thrusters (t200): gains left 1.605" in boat.stdout and "dead zone 0.0775 / -0.0925" in boat.stdout
    assert "straight run at full ahead, calm water: u 3 m/s" in boat.stdout and "holds its course" in boat.stdout
    ship = twin("params", "--vessel", "esso_osaka")
    assert "MMG hull (non-dimensional): R0 0.022" in ship.stdout and "MMG rudder: area_m2 0.01063" in ship.stdout


def test_params_text_gives_a_thrusters_own_dead_zone():
    boat = vessel_mod.load("blueboat")
    own = replace(boat, thrusters=replace(boat.thrusters, deadzone_left=(0.2, -0.2)))
    text = "\n".join(params_lines(effective_parameters(own)))
    assert "dead zone left 0.2 / -0.2, right 0.0775 / -0.0925" in text


def test_params_json():
    p = twin("params", "--vessel", "yellowfish", "--json")
    assert p.returncode == 0, p.stderr
    data = json.loads(p.stdout)
    M = np.array(data["M"])
    np.testing.assert_allclose(M, M.T, atol=1e-9)
    assert np.all(np.linalg.eigvalsh(M) > 0)
    np.testing.assert_allclose(np.array(data["M_RB"]) + np.array(data["M_A"]), M)
    # [Morel-2024 eq. 7]'s names, plus the speed-proportional sway and yaw terms and the astern excess (physics/damping.py)
    assert set(data["damping"]) == {"Xu", "Xuu", "Yv", "Yvv", "Yrv", "Yr", "Yvr", "Yrr", "Nv", "Nvv", "Nrv", "Nr",
                                    "Nvr", "Nrr", "Yuv", "Nur", "Yur", "Nuv", "astern_excess"}
    assert data["gnss_lever_arm_OP_m"] == pytest.approx([0.275, -0.2625])
    assert data["thrusters"]["Fu_max_n"] == pytest.approx(57.40, abs=0.01)


def _vessel_file(tmp_path, **changes):
    data = json.loads((MODEL / "yellowfish.json").read_text())
    data["mjcf"] = str(MODEL / "yellowfish.xml")
    for key, value in changes.items():
        data[key] = value
    path = tmp_path / "v.json"
    path.write_text(json.dumps(data))
    return path


@pytest.mark.parametrize("make_args,message", [
    (lambda tmp: ["--vessel", "no_such_boat"], "unknown vessel"),
    (lambda tmp: ["--vessel", "yellowfish", "--scenario", "loop"], "unknown scenario"),
    (lambda tmp: ["--model", _bad_mjcf(tmp)], "malformed MJCF"),
    (lambda tmp: ["--model", _vessel_file(tmp, cases={"min": {"geom_mass_kg": {"battery": -2.0}}}),
                  "--case", "min"], "mass"),
    (lambda tmp: ["--model", _vessel_file(tmp, added_mass={"Xudot": -1, "Yvdot": -10, "Nrdot": 30})],
     "added_mass.Nrdot is 30"),
    (lambda tmp: ["--model", _vessel_file(tmp, added_mass={"Xudot": -1, "Yvdot": -10, "Nrdot": -1, "Yrdot": 300,
                                                           "Nvdot": 300})], "positive-definite"),
    (lambda tmp: ["--vessel", "yellowfish", "--inputs", _inputs(tmp, "t,pwm_left\n0,1500\n")], "has pwm_left but no pwm_right column"),
    (lambda tmp: ["--vessel", "yellowfish", "--inputs", _inputs(tmp, "t,pwm_left,pwm_right\n0,1500,1500\n"
                                                              "2,1600,1600\n1,1500,1500\n")], "backwards"),
    (lambda tmp: ["--vessel", "yellowfish", "--current", "fast"], "SPEED,DIR_DEG"),
    (lambda tmp: ["--model", _vessel_file(tmp, damping={"Xu": "abc"})], 'damping.Xu must be a number, got "abc"'),
    (lambda tmp: ["--vessel", "yellowfish", "--inputs", _inputs(tmp, "t,pwm_left,pwm_right\n5,1600,1600\n"
                                                              "10,1500,1500\n")], "first row is at t = 5 s"),
])
def test_bad_input_one_line_exit_2_no_output(tmp_path, make_args, message):
    out = tmp_path / "out.csv"
    p = twin("simulate", *make_args(tmp_path), "--duration", "5", "--out", out)
    assert p.returncode == 2
    assert message in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1, p.stderr
    assert "Traceback" not in p.stderr
    assert not out.exists()


@pytest.mark.parametrize("changes,message", [
    ({"thrusters": {"forward": [14.35, "14.97", -0.6218]}}, "thrusters.forward[1] must be a number"),
    ({"thrusters": {"forward": [14.35, 14.97]}}, "thrusters.forward must be a list of 3 values, got 2"),
    ({"cases": {"min": {"geom_mass_kg": {"battery": "2"}}}}, "cases.min.geom_mass_kg.battery must be a number"),
    ({"cg_offset_m": [0.01, None]}, "cg_offset_m[1] must be a number, got null"),
    ({"wind_load": {"cx": True}}, "wind_load.cx must be a number, got true"),
    ({"thrusters": {"kind": 200}}, "thrusters.kind must be a string"),
    ({"cases": [1]}, "cases must be an object"),
])
def test_vessel_file_fields_are_type_checked(tmp_path, changes, message):
    with pytest.raises(TwinError) as exc:
        vessel_mod.load(_vessel_file(tmp_path, **changes))
    assert message in str(exc.value) and "\n" not in str(exc.value)


@pytest.mark.parametrize("xml,where", [
    ("<mujoco>\n  <worldbody>\n    <body>\n</mujoco>\n",
     "bad.xml, line 3: malformed MJCF (XML_ERROR_MISMATCHED_ELEMENT: XMLElement name=body)"),
    ('<mujoco>\n  <worldbody>\n    <body>\n      <geom type="box" size="1 a 1"/>\n    </body>\n  </worldbody>\n'
     "</mujoco>\n", "bad.xml, line 4, element 'geom': malformed MJCF (bad format in attribute 'size')"),
])
def test_malformed_mjcf_says_where_and_why(tmp_path, xml, where):
    with pytest.raises(TwinError) as exc:
        compile_vessel(vessel_mod.load(_bad_mjcf(tmp_path, xml)))
    assert str(exc.value) == where


@pytest.mark.parametrize("text,message", [
    ("t,pwm_left,pwm_right,thrust_left,thrust_right\n0,1600,1600,10,10\n", "both PWM and thrust"),
    ("t,pwm_left,pwm_right,thrust_left\n0,1600,1600,10\n", "both PWM and thrust"),
    ("t,pwm_left,pwm_right\n0.5,1600,1600\n", "first row is at t = 0.5 s"),
    ("t,pwm_left,pwm_right\n\n", "at least one row"),
    ("t,pwm_left\n0,1600\n", "has pwm_left but no pwm_right column"),
    ("t,rudder_deg\n0,5\n", "has rudder_deg but no prop_rps column"),
    ("t,lat\n0,5\n", "missing columns: need pwm_left,pwm_right"),
])
def test_inputs_csv_refuses_what_it_would_apply_silently(tmp_path, text, message):
    with pytest.raises(TwinError, match=message):
        read_inputs_csv(_inputs(tmp_path, text))


def test_inputs_csv_with_byte_order_mark(tmp_path):
    """Spreadsheets save UTF-8 CSV with a BOM in front of the first header; a first row before t = 0 is fine."""
    inputs = tmp_path / "in.csv"
    inputs.write_bytes("t,thrust_left,thrust_right\n-1,10,12\n3,0,0\n".encode("utf-8-sig"))
    series = read_inputs_csv(inputs)
    assert series.kind == "thrust"
    np.testing.assert_allclose(series.at(np.array([0.0, 2.9, 3.0])), [[10, 12], [10, 12], [0, 0]])


def test_a_run_from_inputs_can_start_under_way(tmp_path):
    inputs = _inputs(tmp_path, "t,prop_rps,rudder_deg\n0,10,0\n")
    for start, out in ((None, tmp_path / "rest.csv"), ("0.37", tmp_path / "way.csv")):
        done = twin("simulate", "--vessel", "esso_osaka", "--inputs", inputs, "--duration", "20", "--out", out,
                    *(["--start-speed", start] if start else []))
        assert done.returncode == 0, done.stderr
    # at 10 rps the ship's steady speed is about 0.37 m/s: started there it stays, from rest it is far below
    assert read_csv(tmp_path / "way.csv").nu[-1, 0] == pytest.approx(0.37, abs=0.01)
    assert read_csv(tmp_path / "rest.csv").nu[-1, 0] < 0.2


def test_inputs_csv_holds_an_input_over_empty_cells_as_a_recording_leaves_them(tmp_path):
    """The generic log layout: rows of other streams leave the PWM cells empty; the last PWM holds."""
    series = read_inputs_csv(_inputs(tmp_path, "t,lat,pwm_left,pwm_right\n0,37.4,1629,1506\n0.02,,,\n"
                                                "0.1,,1700,\n0.2,,1550,1450\n"))
    np.testing.assert_allclose(series.at(np.array([0.05, 0.15, 0.25])), [[1629, 1506], [1700, 1506], [1550, 1450]])
    with pytest.raises(TwinError, match="line 2: the first inputs row has an empty pwm_left or pwm_right"):
        read_inputs_csv(_inputs(tmp_path, "t,pwm_left,pwm_right\n0,1600,\n"))


def test_crosscheck_over_tolerance_exits_1(monkeypatch, capsys):
    """main() must pass on a command's exit code: without standalone mode Click returns it instead of exiting."""
    import importlib

    import twin.cli as cli

    crosscheck_module = importlib.import_module("twin.verify.crosscheck")
    monkeypatch.setattr(sys, "argv", ["twin", "crosscheck", "--vessel", "cybership1", "--duration", "1"])
    cli.main()  # within tolerance: returns, exit status 0
    captured = capsys.readouterr()
    assert "FAIL" not in captured.out
    # CyberShip I has no wind load: its wind case moves nothing, and is not called a pass
    # (nor does a 0.35-s input delay within a 1-s run)
    assert "no effect" in captured.out and "wind, input_delay: the term moves this vessel less than" in captured.out
    monkeypatch.setattr(crosscheck_module, "POSITION_TOL_M", 0.0)
    with pytest.raises(SystemExit) as exc:
        cli.main()
    assert exc.value.code == 1
    assert "FAIL" in capsys.readouterr().out


def test_a_ramped_vessel_failing_its_crosscheck_is_told_what_the_ramp_leaves(tmp_path, monkeypatch, capsys):
    """A thrust ramp is held at its mean over each engine step, which alone can take the thrust-alone
    case, and through an advance loss without a lag any case, over the tolerance: the command says so
    for those cases only (failures forced here by a tolerance of 1e-9 m)."""
    import importlib

    import twin.cli as cli

    data = json.loads((MODEL / "yellowfish.json").read_text())
    data["mjcf"] = str(MODEL / "yellowfish.xml")
    data["thrusters"].update({"ramp_s": 2.0, "advance_loss": 1.5, "lag_s": 0.0})
    (tmp_path / "ramped.json").write_text(json.dumps(data))
    data["thrusters"]["lag_s"] = 0.1
    (tmp_path / "lagged.json").write_text(json.dumps(data))
    argv = ["twin", "crosscheck", "--duration", "2", "--model"]
    monkeypatch.setattr(sys, "argv", argv + [str(tmp_path / "ramped.json")])
    cli.main()
    assert "thrust ramp" not in capsys.readouterr().out  # within tolerance: nothing to explain
    monkeypatch.setattr(importlib.import_module("twin.verify.crosscheck"), "POSITION_TOL_M", 1e-9)
    notes = {}
    for name in ("ramped.json", "lagged.json"):
        monkeypatch.setattr(sys, "argv", argv + [str(tmp_path / name)])
        with pytest.raises(SystemExit) as exc:
            cli.main()
        out = capsys.readouterr().out
        assert exc.value.code == 1 and "FAIL" in out
        notes[name] = [line for line in out.splitlines() if "holds a thrust ramp at its mean" in line]
    assert len(notes["ramped.json"]) == 1 and "damping, " in notes["ramped.json"][0]
    assert len(notes["lagged.json"]) == 1 and notes["lagged.json"][0].startswith("note: thrust: the engine holds")


@pytest.mark.parametrize("argv,message", [(["nosuch"], "No such command 'nosuch'"),
                                          (["params", "--bogus"], "No such option: --bogus")])
def test_usage_error_is_bad_input(monkeypatch, capsys, argv, message):
    """Typer raises its own copy of click's usage errors: still one line and exit 2, not an internal error."""
    import twin.cli as cli

    monkeypatch.setattr(sys, "argv", ["twin", *argv])
    with pytest.raises(SystemExit) as exc:
        cli.main()
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err.startswith(f"error: {message}") and len(err.strip().splitlines()) == 1


def _bad_mjcf(tmp, xml="<mujoco><worldbody><body></mujoco>"):
    (tmp / "bad.xml").write_text(xml)
    data = json.loads((MODEL / "yellowfish.json").read_text())
    data["mjcf"] = "bad.xml"
    (tmp / "bad.json").write_text(json.dumps(data))
    return tmp / "bad.json"


def _inputs(tmp, text):
    (tmp / "in.csv").write_text(text)
    return tmp / "in.csv"


def test_a_diverging_twin_is_one_line_exit_2_and_no_litter(tmp_path):
    """Quadratic damping this stiff passes every check (it is dissipative) but explodes under the
    explicit 2 ms step once the boat moves: MuJoCo resets the state and logs to MUJOCO_LOG.TXT;
    the twin must say when it diverged instead, and write nothing."""
    stiff = _vessel_file(tmp_path, damping={"Xu": -2.0, "Xuu": -1e5, "Yv": -45.0, "Nr": -40.0, "Nrr": -1e5})
    out = tmp_path / "run.csv"
    p = twin("simulate", "--model", stiff, "--scenario", "zigzag", "--duration", "20", "--out", out, cwd=tmp_path)
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1, p.stderr
    assert p.stderr.startswith("error: the twin diverged at t = 5.04 s")
    assert not out.exists() and not (tmp_path / "MUJOCO_LOG.TXT").exists()
    p = twin("crosscheck", "--model", stiff, "--duration", "20", cwd=tmp_path)
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1, p.stderr
    assert "crosscheck case 'full': the twin diverged at t = 5.04 s" in p.stderr
    log = tmp_path / "z.tlog"
    assert twin("simulate", "--vessel", "yellowfish", "--duration", "20", "--out", log).returncode == 0
    p = twin("view", log, "--sim", "--model", stiff, "--out", tmp_path / "v.rrd", cwd=tmp_path)
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1, p.stderr
    assert p.stderr.startswith("error: z.tlog: replay: the twin diverged at t = ")
    assert not (tmp_path / "v.rrd").exists() and not (tmp_path / "MUJOCO_LOG.TXT").exists()


def test_simulate_says_a_twins_sensor_errors_are_not_in_its_run(tmp_path):
    """A twin identified with sensor errors (a heading bias, a late PWM log) simulates the hull as it
    moved; the run says it does not carry them, naming them, and a perfect twin's says nothing."""
    data = json.loads((MODEL / "yellowfish.json").read_text())
    sensors = {**data.get("sensors", {}), "heading_bias_deg": 3.0, "pwm_clock_offset_s": 0.2}
    biased = _vessel_file(tmp_path, sensors=sensors)
    p = twin("simulate", "--model", biased, "--scenario", "turn", "--duration", "5", "--out", tmp_path / "b.csv")
    assert p.returncode == 0, p.stderr
    assert "without this twin's sensor errors (heading_bias_deg, pwm_clock_offset_s)" in p.stdout + p.stderr
    p = twin("simulate", "--vessel", "yellowfish", "--scenario", "turn", "--duration", "5", "--out", tmp_path / "y.csv")
    assert p.returncode == 0 and "sensor errors" not in p.stdout + p.stderr


def test_simulate_says_inputs_that_end_before_the_run_are_held(tmp_path):
    inputs = tmp_path / "in.csv"
    inputs.write_text("t,pwm_left,pwm_right\n0,1600,1600\n4,1700,1500\n")
    p = twin("simulate", "--vessel", "yellowfish", "--inputs", inputs, "--duration", "10", "--out", tmp_path / "r.csv")
    assert p.returncode == 0, p.stderr
    assert "the inputs end at 4 s: their last row is held to the end of the run (10 s)" in p.stdout + p.stderr
    read = read_csv(tmp_path / "r.csv")
    assert read.t[-1] == pytest.approx(10.0)


def test_simulate_runs_to_the_inputs_last_row_unless_told_and_says_a_shorter_duration(tmp_path):
    inputs = tmp_path / "in.csv"
    inputs.write_text("t,pwm_left,pwm_right\n0,1600,1600\n4,1700,1500\n7,1500,1500\n")
    p = twin("simulate", "--vessel", "yellowfish", "--inputs", inputs, "--out", tmp_path / "all.csv")
    assert p.returncode == 0 and "inputs" not in p.stderr, p.stderr
    assert read_csv(tmp_path / "all.csv").t[-1] == pytest.approx(7.0)
    p = twin("simulate", "--vessel", "yellowfish", "--inputs", inputs, "--duration", "5", "--out", tmp_path / "cut.csv")
    assert p.returncode == 0 and "the inputs run to 7 s: the run stops at --duration 5 s" in p.stdout + p.stderr
    assert read_csv(tmp_path / "cut.csv").t[-1] == pytest.approx(5.0)
    single = tmp_path / "one.csv"
    single.write_text("t,pwm_left,pwm_right\n0,1600,1600\n")
    p = twin("simulate", "--vessel", "yellowfish", "--inputs", single, "--out", tmp_path / "one_run.csv")
    assert p.returncode == 2 and p.stderr.strip() == "error: one.csv: give --duration (the inputs end at t = 0 s)"


def test_validate_names_the_figure_a_markdown_report_writes_beside_it(tmp_path):
    p = twin("validate", "--vessel", "blueboat", "--report", tmp_path / "v.md")
    assert p.returncode == 0, p.stderr
    assert f"wrote {tmp_path / 'v.md'}\nwrote {tmp_path / 'v_topview.png'}" in p.stdout
    assert (tmp_path / "v_topview.png").read_bytes()[:4] == b"\x89PNG"
    assert "v_topview.png" in (tmp_path / "v.md").read_text()
