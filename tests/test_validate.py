"""`twin validate`: the technical report's hand formulas pinned to its inputs, the engine to the MJCF, bad input."""
import json

import numpy as np
import pytest
import trimesh

import twin.vessel as vessel_mod
from twin.engine.mjcf import compile_vessel
from twin.errors import TwinError
from twin.physics import added_mass as am
from twin.physics.hydrostatics import submerged_volume, waterline_for_mass
from twin.verify.validate import validate
import twin_command

MODEL = vessel_mod.MODEL_DIR


@pytest.fixture(scope="module")
def nominal():
    return {q.name: q for q in validate(vessel_mod.load("yellowfish")).quantities}


def test_yellowfish_report_formulas_reproduce_its_tables(nominal):
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


def test_a_hull_in_the_surface_carries_half_its_double_bodys_added_mass():
    """A hemisphere floating in the surface moves as half a sphere does in open water (the surface a
    rigid wall): its added mass is half the hemisphere's own displaced mass, in surge and sway alike,
    where the whole ellipsoid of [Yellowfish-TR eq. 21] gives twice that."""
    r, rho = 0.1, 1000.0
    half = am.half_body_added_mass(r, r, r, rho)
    hemisphere_kg = rho * 2 / 3 * np.pi * r**3
    assert -half["Xudot"] == pytest.approx(0.5 * hemisphere_kg) == pytest.approx(-half["Yvdot"])
    slender = am.half_body_added_mass(0.48, 0.11, 0.066, rho)
    whole = am.ellipsoid_added_mass(0.48, 0.11, 0.066, rho)
    assert all(slender[k] == pytest.approx(0.5 * whole[k]) for k in ("Xudot", "Yvdot", "Nrdot"))
    assert slender["Yvdot"] < slender["Xudot"] < 0  # a slender hull: far more added mass across than along


def test_engine_values_follow_the_mjcf(nominal):
    assert nominal["m"].engine == pytest.approx(24.39)
    assert nominal["xg (eq. 17)"].engine == pytest.approx(-19.63, abs=0.01)
    assert nominal["x_hull"].engine == pytest.approx(-22.0, abs=0.01)
    assert nominal["Iz (eq. 18)"].engine == pytest.approx(nominal["Iz (eq. 18)"].mesh, rel=1e-6)
    for side, y_mm in (("port", -337.5), ("starboard", 337.5)):
        hull = f"hull_{side}"
        assert nominal[f"{hull} centroid x"].engine == pytest.approx(-22.0, abs=0.01)  # Table IV's x_hull
        assert nominal[f"{hull} centroid y"].mesh == pytest.approx(y_mm, abs=0.01)
        for row in ("volume", "centroid z", "Ixx (centroid)", "Iyy (centroid)", "Izz (centroid)"):
            q = nominal[f"{hull} {row}"]
            assert q.engine == pytest.approx(q.mesh, rel=1e-6), row
    # a slender hull: yaw and pitch inertia about ten times the roll inertia
    assert nominal["hull_port Izz (centroid)"].mesh > 8 * nominal["hull_port Ixx (centroid)"].mesh
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


def test_cybership_against_cybership_bertoni():
    q = {x.name: x for x in validate(vessel_mod.load("cybership1")).quantities}
    for name in ("M11", "M22", "M23", "M33", "D11", "D22", "D33"):
        assert q[name].rel_diff < 1e-9


def _vessel_with_mjcf(tmp_path, body_xml, asset_xml=""):
    (tmp_path / "v.xml").write_text(f"""<mujoco><asset>{asset_xml}</asset><worldbody><body name="vessel">
      <joint name="north" type="slide" axis="1 0 0"/><joint name="east" type="slide" axis="0 1 0"/>
      <joint name="yaw" type="hinge" axis="0 0 1"/>{body_xml}
      <site name="imu"/><site name="gnss"/><site name="thruster_left" pos="0 -0.2 0.18"/>
      <site name="thruster_right" pos="0 0.2 0.18"/></body></worldbody><actuator>
      <general name="thruster_left" site="thruster_left" gear="1 0 0 0 0 0"/>
      <general name="thruster_right" site="thruster_right" gear="1 0 0 0 0 0"/></actuator></mujoco>""")
    data = json.loads((MODEL / "cybership1.json").read_text())
    data["mjcf"] = "v.xml"
    data["name"] = "testboat"
    (tmp_path / "v.json").write_text(json.dumps(data))
    return tmp_path / "v.json"


def _run_validate(path, tmp_path):
    report = tmp_path / "r.html"
    p = twin_command.twin("validate", "--model", str(path), "--report", str(report),
                          "--json", str(tmp_path / "r.json"))
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
    p = twin_command.twin("validate", "--vessel", "yellowfish", "--json",
                          str(tmp_path / "v.json"), "--report", str(tmp_path / "v.md"))
    assert p.returncode == 0, p.stderr
    rows = json.loads((tmp_path / "v.json").read_text())["quantities"]
    assert set(rows[0]) >= {"name", "unit", "analytic", "table", "engine", "mesh", "independent", "rel_diff", "flag",
                            "explanation"}
    assert (tmp_path / "v_topview.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert max(len(line) for line in p.stdout.splitlines()) <= 100


def test_cli_checks_the_reports_figure_before_the_validation(tmp_path):
    """The page's companion PNG (d_topview.png beside d.md) a folder: refused before the table is printed,
    not after the whole validation; the page itself is not written."""
    (tmp_path / "d_topview.png").mkdir()
    p = twin_command.twin("validate", "--vessel", "yellowfish", "--report", str(tmp_path / "d.md"))
    assert p.returncode == 2 and p.stdout == "", p.stdout
    assert p.stderr == f"error: --report's figure '{tmp_path / 'd_topview.png'}' is a folder: give a file name\n"
    assert not (tmp_path / "d.md").exists() and not any((tmp_path / "d_topview.png").iterdir())


@pytest.fixture(scope="module")
def minimum():
    return {q.name: q for q in validate(vessel_mod.load("yellowfish", "min")).quantities}


def test_min_case_iz_follows_the_seed_chain_and_names_its_d_g(minimum):
    """eq. 19 with this case's m_box feeds eq. 18; Table V's single printed I_box stays in the table column."""
    i_box, iz = minimum["I_box (eq. 19)"], minimum["Iz (eq. 18)"]
    assert i_box.analytic == pytest.approx(7.61 * (0.50**2 + 0.52**2) / 12, rel=1e-9)
    assert i_box.table == pytest.approx(0.3586) and iz.table == pytest.approx(1.07)
    assert iz.analytic == pytest.approx(i_box.analytic + 2 * 8.06 * 0.21**2, rel=1e-9)
    assert iz.analytic == pytest.approx(1.041, abs=0.001)
    assert "d_g = 0.21 m" in iz.explanation and "0.30 m" not in iz.explanation
    assert "one I_box" in i_box.explanation and "0.330" in i_box.explanation


def test_table_vi_min_max_columns_reported_swapped(minimum, nominal):
    for name in ("Xu_dot (2 hulls)", "Yv_dot (2 hulls)", "Nr_dot (2 hulls, eq. 25)"):
        assert "appear swapped" in minimum[name].explanation, name
        assert "appear swapped" not in nominal[name].explanation, name
    assert "-2.15 kg, is near eq. 21 with the max case's semi-axes (-2.01 kg)" in minimum["Xu_dot (2 hulls)"].explanation


def test_vessel_without_seed_table_has_no_seed_sentence():
    q = {x.name: x for x in validate(vessel_mod.load("blueboat")).quantities}
    volume = q["displaced volume"]
    assert volume.table is None and volume.mesh == pytest.approx(16.11, abs=0.05)  # below z = 0
    for x in q.values():
        assert "Table VI" not in x.explanation and "nan" not in x.explanation, x.name


def test_mesh_rows_against_a_placed_and_turned_box(tmp_path):
    """A 1.0 x 0.2 x 0.3 m box whose file origin is 0.2 m off its centre, turned 90° about z and moved:
    volume, centroid and inertia in the vessel frame follow in closed form, from MuJoCo and from trimesh."""
    box = trimesh.creation.box(extents=(1.0, 0.2, 0.3))
    box.apply_translation((0.2, 0.0, 0.0))
    box.export(tmp_path / "box.stl")
    path = _vessel_with_mjcf(tmp_path, '<geom name="hull" type="mesh" mesh="box" mass="10" pos="0 0.3 0.05" '
                                       'quat="0.70710678 0 0 0.70710678"/>',
                             '<mesh name="box" file="box.stl" inertia="exact"/>')
    q = {x.name: x for x in validate(vessel_mod.load(path)).quantities}
    expected = {"hull volume": 60.0, "hull centroid x": 0.0, "hull centroid y": 500.0, "hull centroid z": 50.0,
                "hull Ixx (centroid)": 10 * (1.0**2 + 0.3**2) / 12, "hull Iyy (centroid)": 10 * (0.2**2 + 0.3**2) / 12,
                "hull Izz (centroid)": 10 * (1.0**2 + 0.2**2) / 12}
    for name, value in expected.items():
        close = pytest.approx(value, rel=1e-6, abs=1e-3 if "centroid" in name else 0.0)  # STL stores float32
        assert q[name].engine == close and q[name].mesh == close, name


def test_api_exports_validate():
    import twin

    result = twin.validate("yellowfish", case="max")
    assert isinstance(result, twin.Validation) and result.case == "max"
    assert {q.name for q in result.flagged()} >= {"Iz (eq. 18)", "Xu_dot (2 hulls)"}


@pytest.mark.parametrize("body_xml,part", [
    ('<geom type="box" size="0.1 0.1 0.1" mass="5"/><body name="hull_port"><geom name="hull_port" type="box" '
     'size="0.5 0.2 0.1" mass="0"/></body>', "zero mass in body hull_port: geom 'hull_port' has mass 0"),
    ('<geom type="box" size="0.1 0.1 0.1" mass="5"/><body name="box"><inertial pos="0 0 0" mass="0" '
     'diaginertia="1 1 1"/></body>', "zero mass in body box: its <inertial> has mass 0"),
    ('<inertial pos="0 0 0" mass="0" diaginertia="1 1 1"/>', "zero mass in body vessel: its <inertial> has mass 0"),
    ('<geom type="box" size="0.1 0.1 0.1" mass="5"/><geom name="float" type="box" size="0.1 0.1 0.1" density="0"/>',
     "zero mass in body vessel: geom 'float' has density 0"),
])
def test_massless_part_is_named(tmp_path, body_xml, part):
    """MuJoCo accepts a massless part welded to a heavier body; the twin must not (validate and simulate
    both start from compile_vessel)."""
    with pytest.raises(TwinError) as exc:
        compile_vessel(vessel_mod.load(_vessel_with_mjcf(tmp_path, body_xml)))
    assert part in str(exc.value)


def test_simulate_refuses_a_massless_hull(tmp_path):
    path = _vessel_with_mjcf(tmp_path, '<geom type="box" size="0.1 0.1 0.1" mass="5"/><body name="hull_port">'
                                       '<geom name="hull_port" type="box" size="0.5 0.2 0.1" mass="0"/></body>')
    out = tmp_path / "run.csv"
    p = twin_command.twin("simulate", "--model", str(path), "--duration", "1",
                          "--out", str(out))
    assert p.returncode == 2 and "geom 'hull_port' has mass 0" in p.stderr and not out.exists(), p.stderr
    assert len(p.stderr.strip().splitlines()) == 1


def test_a_thruster_above_the_waterline_but_below_the_hulls_top_is_refused_by_validate(tmp_path):
    """The BlueBoat floats its 15 kg with its waterline 3 mm below the MJCF's z = 0: a thruster at
    z = −0.05 m lies within the hulls' height (the engine accepts it) but in the air, which validate says."""
    mjcf = (vessel_mod.MODEL_DIR / "blueboat.xml").read_text().replace(
        'meshdir="../assets"', f'meshdir="{vessel_mod.MODEL_DIR.parent / "assets"}"').replace(
        'pos="-0.52 -0.285 0.10"', 'pos="-0.52 -0.285 -0.05"')
    (tmp_path / "boat.xml").write_text(mjcf)
    data = json.loads((vessel_mod.MODEL_DIR / "blueboat.json").read_text()) | {"mjcf": "boat.xml"}
    (tmp_path / "boat.json").write_text(json.dumps(data))
    boat = vessel_mod.load(str(tmp_path / "boat.json"))
    compile_vessel(boat)
    with pytest.raises(TwinError, match=r"site 'thruster_left' at z = -0.05 m lies 53 mm above the waterline"):
        validate(boat)
