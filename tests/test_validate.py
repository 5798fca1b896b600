"""`twin validate`: the seed's hand formulas pinned to its inputs, the engine to the MJCF, bad input."""
import json
import subprocess
import sys

import numpy as np
import pytest
import trimesh

import twin.vessel as vessel_mod
from twin.errors import TwinError
from twin.physics import added_mass as am
from twin.physics.hydrostatics import submerged_volume, waterline_for_mass
from twin.validate import validate

MODEL = vessel_mod.MODEL_DIR


@pytest.fixture(scope="module")
def nominal():
    return {q.name: q for q in validate(vessel_mod.load("yellowfish")).quantities}


def test_seed000_formulas_reproduce_its_tables(nominal):
    assert nominal["xg (eq. 17)"].analytic == pytest.approx(-19.6, abs=0.05)
    assert nominal["I_box (eq. 19)"].analytic == pytest.approx(0.3586, abs=1e-4)
    assert nominal["Iz (eq. 18)"].analytic == pytest.approx(1.81, abs=0.005)
    assert nominal["Xu_dot (2 hulls)"].analytic == pytest.approx(-1.00, abs=0.02)
    assert nominal["Yv_dot (2 hulls)"].analytic == pytest.approx(-10.92, abs=0.02)
    assert nominal["Nr_dot (2 hulls, eq. 25)"].analytic == pytest.approx(-3.95, abs=0.01)
    assert nominal["Fu max (Table VIII)"].analytic == pytest.approx(57.40, abs=0.01)
    assert nominal["tau_r max (Table VIII)"].analytic == pytest.approx(17.46, abs=0.01)


def test_lamb_integrals_three_ways():
    a, b, c = 0.56, 0.1275, 0.05
    quad = am.ellipsoid_lamb_coefficients(a, b, c)
    closed = am.ellipsoid_lamb_coefficients_closed_form(a, b, c)
    np.testing.assert_allclose(quad, closed, rtol=1e-9)
    assert sum(quad) == pytest.approx(2.0, abs=1e-9)
    # a sphere: α0 = β0 = γ0 = 2/3 and the added mass is half the displaced mass
    sphere = am.ellipsoid_added_mass(0.1, 0.1, 0.1, 1000.0)
    assert sphere["alpha0"] == pytest.approx(2 / 3)
    assert -sphere["Xudot"] == pytest.approx(0.5 * 1000 * 4 / 3 * np.pi * 0.001)


def test_engine_values_follow_the_mjcf(nominal):
    assert nominal["m"].engine == pytest.approx(24.39)
    assert nominal["xg (eq. 17)"].engine == pytest.approx(-19.63, abs=0.01)
    assert nominal["x_hull"].engine == pytest.approx(-22.0, abs=0.01)
    assert nominal["Iz (eq. 18)"].engine == pytest.approx(nominal["Iz (eq. 18)"].mesh, rel=1e-6)
    assert nominal["hull Izz about centroid"].engine == pytest.approx(nominal["hull Izz about centroid"].mesh, rel=1e-6)
    # MuJoCo's ellipsoid fluid model agrees with eq. 21-22 (independent column)
    assert nominal["Xu_dot (2 hulls)"].independent == pytest.approx(nominal["Xu_dot (2 hulls)"].analytic, rel=1e-3)
    assert nominal["alpha0 (eq. 22)"].independent == pytest.approx(nominal["alpha0 (eq. 22)"].analytic, rel=1e-3)


def test_flags_carry_explanations(nominal):
    flagged = {n for n, q in nominal.items() if q.flag}
    assert {"Iz (eq. 18)", "alpha0 (eq. 22)", "Nr_dot (2 hulls, eq. 25)", "draft at flotation"} <= flagged
    assert not nominal["m"].flag and not nominal["Fu max (Table VIII)"].flag
    for name in flagged:
        assert len(nominal[name].to_dict()["explanation"]) > 40


def test_hydrostatics_box_floats_at_archimedes_draft():
    box = trimesh.creation.box(extents=(1.0, 0.2, 0.3))  # centred: z from -0.15 to 0.15
    assert submerged_volume(box.vertices, box.faces, 0.0)[0] == pytest.approx(0.03)
    fl = waterline_for_mass([(box.vertices, box.faces)], 20.0)
    assert fl["draft_m"] == pytest.approx(0.1, abs=1e-6)  # 20 kg / (1000 kg/m³ · 0.2 m²)
    assert fl["waterline_length_m"] == pytest.approx(1.0)


def test_cybership_against_seed002():
    q = {x.name: x for x in validate(vessel_mod.load("cybership1")).quantities}
    for name in ("M11", "M22", "M23", "M33", "D11", "D22", "D33"):
        assert q[name].rel_diff < 1e-9


def _vessel_with_mjcf(tmp_path, body_xml, asset_xml=""):
    (tmp_path / "v.xml").write_text(f"""<mujoco><asset>{asset_xml}</asset><worldbody><body name="vessel">
      <joint name="north" type="slide" axis="1 0 0"/><joint name="east" type="slide" axis="0 1 0"/>
      <joint name="yaw" type="hinge" axis="0 0 1"/>{body_xml}
      <site name="imu"/><site name="gnss"/><site name="thruster_left" pos="0 -0.2 0"/>
      <site name="thruster_right" pos="0 0.2 0"/></body></worldbody><actuator>
      <general name="thruster_left" site="thruster_left" gear="1 0 0 0 0 0"/>
      <general name="thruster_right" site="thruster_right" gear="1 0 0 0 0 0"/></actuator></mujoco>""")
    data = json.loads((MODEL / "cybership1.json").read_text())
    data["mjcf"] = "v.xml"
    data["name"] = "testboat"
    (tmp_path / "v.json").write_text(json.dumps(data))
    return tmp_path / "v.json"


def _run_validate(path, tmp_path):
    report = tmp_path / "r.html"
    p = subprocess.run([sys.executable, "-m", "twin.cli", "validate", "--model", str(path), "--report", str(report),
                        "--json", str(tmp_path / "r.json")], capture_output=True, text=True)
    return p, report


def test_no_geometry_is_a_clear_error(tmp_path):
    path = _vessel_with_mjcf(tmp_path, '<inertial pos="0 0 0" mass="20" diaginertia="1 1 1"/>')
    p, report = _run_validate(path, tmp_path)
    assert p.returncode == 2 and "no geometry" in p.stderr and not report.exists()


def test_zero_mass_is_a_clear_error(tmp_path):
    path = _vessel_with_mjcf(tmp_path, '<geom type="box" size="0.5 0.2 0.1" mass="0"/>')
    p, report = _run_validate(path, tmp_path)
    assert p.returncode == 2 and "zero mass in body vessel" in p.stderr and len(p.stderr.strip().splitlines()) == 1
    assert not report.exists() and not (tmp_path / "r.json").exists()


def test_open_mesh_is_named(tmp_path):
    box = trimesh.creation.box(extents=(1.0, 0.2, 0.2))
    open_mesh = trimesh.Trimesh(box.vertices, box.faces[:-2])
    open_mesh.export(tmp_path / "leaky.stl")
    path = _vessel_with_mjcf(tmp_path, '<geom type="mesh" mesh="leaky" mass="10"/>',
                             '<mesh name="leaky" file="leaky.stl"/>')
    p, report = _run_validate(path, tmp_path)
    assert p.returncode == 2 and "leaky.stl" in p.stderr and "watertight" in p.stderr
    assert not report.exists()


def test_cli_writes_json_and_report(tmp_path):
    p = subprocess.run([sys.executable, "-m", "twin.cli", "validate", "--vessel", "yellowfish", "--json",
                        str(tmp_path / "v.json"), "--report", str(tmp_path / "v.md")], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    rows = json.loads((tmp_path / "v.json").read_text())["quantities"]
    assert set(rows[0]) >= {"name", "unit", "analytic", "table", "engine", "mesh", "independent", "rel_diff", "flag",
                            "explanation"}
    assert (tmp_path / "v_topview.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert max(len(line) for line in p.stdout.splitlines()) <= 100
