"""The `twin` command end to end, including bad input."""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from twin.run import read_csv

MODEL = Path(__file__).resolve().parent.parent / "model"


def twin(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "twin.cli", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, timeout=600)


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


def test_params_json():
    p = twin("params", "--vessel", "yellowfish", "--json")
    assert p.returncode == 0, p.stderr
    data = json.loads(p.stdout)
    M = np.array(data["M"])
    np.testing.assert_allclose(M, M.T, atol=1e-9)
    assert np.all(np.linalg.eigvalsh(M) > 0)
    np.testing.assert_allclose(np.array(data["M_RB"]) + np.array(data["M_A"]), M)
    # seed 004 eq. 7's names, plus the speed-proportional sway and yaw terms (physics/damping.py)
    assert set(data["damping"]) == {"Xu", "Xuu", "Yv", "Yvv", "Yrv", "Yr", "Yvr", "Yrr", "Nv", "Nvv", "Nrv", "Nr",
                                    "Nvr", "Nrr", "Yuv", "Nur"}
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
     "positive-definite"),
    (lambda tmp: ["--vessel", "yellowfish", "--inputs", _inputs(tmp, "t,pwm_left\n0,1500\n")], "missing columns"),
    (lambda tmp: ["--vessel", "yellowfish", "--inputs", _inputs(tmp, "t,pwm_left,pwm_right\n0,1500,1500\n"
                                                              "2,1600,1600\n1,1500,1500\n")], "backwards"),
    (lambda tmp: ["--vessel", "yellowfish", "--current", "fast"], "SPEED,DIR_DEG"),
])
def test_bad_input_one_line_exit_2_no_output(tmp_path, make_args, message):
    out = tmp_path / "out.csv"
    p = twin("simulate", *make_args(tmp_path), "--duration", "5", "--out", out)
    assert p.returncode == 2
    assert message in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1, p.stderr
    assert "Traceback" not in p.stderr
    assert not out.exists()


def _bad_mjcf(tmp):
    (tmp / "bad.xml").write_text("<mujoco><worldbody><body></mujoco>")
    data = json.loads((MODEL / "yellowfish.json").read_text())
    data["mjcf"] = "bad.xml"
    (tmp / "bad.json").write_text(json.dumps(data))
    return tmp / "bad.json"


def _inputs(tmp, text):
    (tmp / "in.csv").write_text(text)
    return tmp / "in.csv"
