"""Vessel files a user writes and moves: identified and amended vessels keep working wherever they go."""
import json
from pathlib import Path

import mujoco
import numpy as np
import pytest

import twin.vessel as vessel_mod
from twin.engine.mjcf import compile_vessel
from twin.errors import TwinError


def test_a_written_vessel_names_a_shipped_mjcf_by_package_so_it_can_move(tmp_path):
    v = vessel_mod.load("blueboat")
    (tmp_path / "a").mkdir()
    path = vessel_mod.save(v, tmp_path / "a" / "identified.json")
    assert json.loads(path.read_text())["mjcf"] == "package:blueboat.xml"
    moved = tmp_path / "elsewhere" / "deeper" / "identified.json"
    moved.parent.mkdir(parents=True)
    path.replace(moved)
    again = vessel_mod.load(str(moved))
    assert again.mjcf.resolve() == v.mjcf.resolve() and again.damping == v.damping
    data = json.loads(moved.read_text())
    data["mjcf"] = "package:nonesuch.xml"
    moved.write_text(json.dumps(data))
    with pytest.raises(TwinError, match="nonesuch.xml' not found"):
        vessel_mod.load(str(moved))


def test_a_vessel_with_its_own_mjcf_keeps_the_path_relative_to_its_file(tmp_path):
    xml = (vessel_mod.MODEL_DIR / "yellowfish.xml").read_text()
    (tmp_path / "boat.xml").write_text(xml)
    data = json.loads((vessel_mod.MODEL_DIR / "yellowfish.json").read_text())
    data["mjcf"] = "boat.xml"
    (tmp_path / "boat.json").write_text(json.dumps(data))
    v = vessel_mod.load(str(tmp_path / "boat.json"))
    out = vessel_mod.save(v, tmp_path / "copy.json")
    assert json.loads(out.read_text())["mjcf"] == "boat.xml"


def test_a_heading_sensors_yaw_rate_window_is_written_only_where_set(tmp_path):
    """`sensors.heading_rate_window_s`: a vessel file without it is written exactly as before (dataset
    fingerprints), one with it keeps it, identify and diagnose prepare with it, and it must be positive."""
    from dataclasses import replace

    from twin.errors import TwinError
    from twin.fit.calibrate import HEADING_WINDOW_S, rate_windows

    boat = vessel_mod.load("yellowfish")
    assert "heading_rate_window_s" not in boat.to_dict()["sensors"]
    assert rate_windows(boat)["heading_window_s"] == HEADING_WINDOW_S
    slow = replace(boat, sensors=replace(boat.sensors, heading_rate_window_s=1.5))
    path = vessel_mod.save(slow, tmp_path / "slow.json")
    again = vessel_mod.load(str(path))
    assert again.sensors.heading_rate_window_s == 1.5 and rate_windows(again)["heading_window_s"] == 1.5
    with pytest.raises(TwinError, match="heading_rate_window_s must be positive"):
        vessel_mod.check(replace(boat, sensors=replace(boat.sensors, heading_rate_window_s=0.0)))
    # where the yaw rate is read likewise: absent means the heading's slope, the Esso's file says gyro
    assert "yaw_rate_source" not in boat.to_dict()["sensors"] and rate_windows(boat)["yaw_rate_source"] == "heading"
    ship = vessel_mod.load("esso_osaka")
    assert rate_windows(ship)["yaw_rate_source"] == "gyro" and not ship.sensors.errors()
    path = vessel_mod.save(ship, tmp_path / "ship.json")
    assert vessel_mod.load(str(path)).sensors.yaw_rate_source == "gyro"
    with pytest.raises(TwinError, match="yaw_rate_source must be heading or gyro"):
        vessel_mod.check(replace(boat, sensors=replace(boat.sensors, yaw_rate_source="compass")))


@pytest.mark.parametrize("edit, message", [
    (lambda d: d.__setitem__("dampng", d.pop("damping")), "unknown vessel file field.s. dampng"),
    (lambda d: d.pop("damping"), "needs its damping section"),
    (lambda d: d.pop("thrusters"), "needs its thrusters section"),
    (lambda d: d.__setitem__("thrusters", None), "needs its thrusters section"),  # null loaded as defaults
    (lambda d: d.__setitem__("added_mass", None), "needs its added_mass section"),
    (lambda d: d.__setitem__("added_mass", {}), "needs its added_mass section"),  # empty: all zeros
    (lambda d: d.__setitem__("thrusters", {}), "needs its thrusters section"),  # empty: a generic thruster
])
def test_a_vessel_file_missing_or_misspelling_a_physics_section_is_refused(tmp_path, edit, message):
    """A misspelt or missing section would load as zeros or defaults (a twin with no damping, whose
    free runs score R² r −573): refused in one line instead."""
    v = vessel_mod.load("blueboat")
    path = vessel_mod.save(v, tmp_path / "boat.json")
    data = json.loads(path.read_text())
    edit(data)
    path.write_text(json.dumps(data))
    with pytest.raises(TwinError, match=message):
        vessel_mod.load(str(path))


@pytest.mark.parametrize("edit, message", [
    (lambda d: d.__setitem__("damping", {}), "damping has no coefficient"),
    (lambda d: d["added_mass"].__setitem__("Xudot", 5.0), r"added_mass.Xudot is 5: .* ≤ 0"),
    (lambda d: d["thrusters"].__setitem__("gain_left", 1605.0), r"thrusters.gain_left is 1605"),
    (lambda d: d["thrusters"].__setitem__("gain_right", -1.0), r"thrusters.gain_right must be > 0, got -1"),
    (lambda d: d["thrusters"].__setitem__("lag_s", 200.0), r"thrusters.lag_s is 200 s"),
    (lambda d: d["thrusters"].__setitem__("reversed_channels", ["left"]),
     r"thrusters.reversed_channels \['left'\]: a channel wired in reverse is mirrored where the log is read"),
    (lambda d: d.__setitem__("cg_offset_m", [100.0, 0.0]), r"cg_offset_m \[100.0, 0.0\]"),
    (lambda d: d["wind_load"].__setitem__("frontal_area_m2", -0.3), r"wind_load.frontal_area_m2 must be ≥ 0"),
    (lambda d: d.pop("name"), r"a vessel file needs 'name'$"),
    (lambda d: d["thrusters"].update(deadzone_fwd=-0.09, deadzone_rev=0.08),
     r"deadzone_fwd, deadzone_rev \(-0.09, 0.08\) must be a forward edge ≥ 0 and an astern edge ≤ 0"),
    (lambda d: d["thrusters"].__setitem__("deadzone_left", [0.05, 0.02]), r"thrusters.deadzone_left \(0.05, 0.02\)"),
    (lambda d: d["thrusters"].__setitem__("reverse", [12.8, -9.5, 0.3595]),
     r"the reverse thrust map \[12.8, -9.5, 0.3595\] gives \+1.35 N at its dead-zone edge"),
    (lambda d: d["thrusters"].__setitem__("reverse", [30.0, 9.5, -0.3]), r"does not push harder astern"),
    (lambda d: d["thrusters"].update(pwm_min_us=1000.0, pwm_max_us=2000.0),
     r"thrusters.pwm_min_us 1000 µs reads the thrust map at δ̃ -1.28, past its full-thrust end ±1"),
])
def test_a_vessel_file_value_only_a_slipped_unit_gives_is_refused_naming_its_field(tmp_path, edit, message):
    """Each of these would run without a word as another boat (a gain in per mille reaches 35 m/s, a
    headwind on a negative area pushes the boat ahead): refused, naming the field."""
    path = vessel_mod.save(vessel_mod.load("blueboat"), tmp_path / "boat.json")
    data = json.loads(path.read_text())
    edit(data)
    path.write_text(json.dumps(data))
    with pytest.raises(TwinError, match=message):
        vessel_mod.load(str(path))


def test_masses_in_grams_are_refused_where_the_hull_meshes_say_what_floats(tmp_path):
    import shutil

    from twin.engine.mjcf import compile_vessel

    mjcf = (vessel_mod.MODEL_DIR / "blueboat.xml").read_text()
    (tmp_path / "boat.xml").write_text(mjcf.replace('mass="4.5"', 'mass="4500"').replace(
        'meshdir="../assets"', f'meshdir="{vessel_mod.MODEL_DIR.parent / "assets"}"'))
    shutil.copy(vessel_mod.MODEL_DIR / "blueboat.json", tmp_path / "boat.json")
    data = json.loads((tmp_path / "boat.json").read_text())
    data["mjcf"] = "boat.xml"
    (tmp_path / "boat.json").write_text(json.dumps(data))
    with pytest.raises(TwinError, match=r"9006 kg cannot float: its hull meshes displace 98.2. kg"):
        compile_vessel(vessel_mod.load(str(tmp_path / "boat.json")))
    assert compile_vessel(vessel_mod.load("blueboat")).geometry.rigid.mass_kg == pytest.approx(15.0)


def _own_copy(tmp_path, name: str, mjcf_edit=lambda x: x, file_edit=lambda d: None) -> Path:
    """A shipped vessel copied beside its own MJCF, each edited."""
    mjcf = mjcf_edit((vessel_mod.MODEL_DIR / f"{name}.xml").read_text()).replace(
        'meshdir="../assets"', f'meshdir="{vessel_mod.MODEL_DIR.parent / "assets"}"')
    (tmp_path / "boat.xml").write_text(mjcf)
    data = json.loads((vessel_mod.MODEL_DIR / f"{name}.json").read_text()) | {"mjcf": "boat.xml"}
    file_edit(data)
    (tmp_path / "boat.json").write_text(json.dumps(data))
    return tmp_path / "boat.json"


def test_unit_slips_and_mirrored_thrusters_are_refused_where_no_mesh_or_range_catches_them(tmp_path):
    """A hull of boxes with its masses in grams (no mesh to say what floats), thrusters placed in a
    forward-left-up frame (every differential thrust would turn the twin the other way) and an added
    mass in grams: each would run as another boat, and each is refused naming what to fix; the shipped
    vessels pass."""
    grams = _own_copy(tmp_path, "cybership1", lambda x: x.replace('mass="23.8"', 'mass="23800"'))
    with pytest.raises(TwinError, match=r"23800 kg cannot float: the box around its geoms \(1.19 x 0.3 x 0.16 m\)"):
        compile_vessel(vessel_mod.load(str(grams)))
    mirrored = _own_copy(tmp_path, "blueboat", lambda x: x.replace('pos="-0.52 -0.285 0.10"', 'pos="LEFT"').replace(
        'pos="-0.52 0.285 0.10"', 'pos="-0.52 -0.285 0.10"').replace('pos="LEFT"', 'pos="-0.52 0.285 0.10"'))
    with pytest.raises(TwinError, match=r"site 'thruster_left' at y = \+0.285 m lies to starboard of 'thruster_right'"):
        compile_vessel(vessel_mod.load(str(mirrored)))
    one_side = _own_copy(tmp_path, "blueboat", lambda x: x.replace('pos="-0.52 -0.285 0.10"', 'pos="-0.52 0.285 0.10"'))
    with pytest.raises(TwinError, match=r"sites 'thruster_left' and 'thruster_right' both at y = \+0.285 m"):
        compile_vessel(vessel_mod.load(str(one_side)))
    heavy = _own_copy(tmp_path, "blueboat", file_edit=lambda d: d["added_mass"].__setitem__("Xudot", -1486.0))
    with pytest.raises(TwinError, match=r"boat.json: added_mass.Xudot -1486 kg is 99 times the rigid body's 15 kg"):
        compile_vessel(vessel_mod.load(str(heavy)))
    for name in ("blueboat", "yellowfish", "cybership1", "esso_osaka"):
        compile_vessel(vessel_mod.load(name))


@pytest.mark.parametrize("mjcf_edit, file_edit, message", [
    (lambda x: x.replace('axis="0 0 1"', 'axis="0 0 -1"'), None, r"joint 'yaw' must be a hinge with axis=\"0 0 1\""),
    (lambda x: x.replace('name="north" type="slide" axis="1 0 0"', 'name="north" type="slide" axis="0 1 0"'), None,
     r"joint 'north' must be a slide with axis=\"1 0 0\", got a slide with axis=\"0 1 0\""),
    (lambda x: x.replace('<joint name="north" type="slide" axis="1 0 0"/>', 'NORTH').replace(
        '<joint name="east" type="slide" axis="0 1 0"/>', '<joint name="north" type="slide" axis="1 0 0"/>').replace(
        'NORTH', '<joint name="east" type="slide" axis="0 1 0"/>'), None, r"joint 'north' is degree of freedom 2"),
    (lambda x: x.replace('gear="1 0 0 0 0 0"', 'gear="0 1 0 0 0 0"', 1), None,
     r"actuator 'thruster_left' has gear=\"0 1 0 0 0 0\""),
    (lambda x: x.replace('pos="-0.52 -0.285 0.10"/>', 'pos="-0.52 -0.285 0.10" euler="0 0 0.35"/>'), None,
     r"site 'thruster_left' of actuator 'thruster_left' pushes 20.1° off body x"),
    (lambda x: x.replace('pos="-0.52 0.285 0.10"/>', 'pos="-0.52 0.285 0.10" euler="0 0.5 0"/>'), None,
     r"site 'thruster_right' of actuator 'thruster_right' pushes 28.6° off body x"),
    (lambda x: x.replace('pos="-0.52 -0.285 0.10"', 'pos="-0.52 -0.285 -0.30"'), None,
     r"site 'thruster_left' at z = -0.3 m lies above the hulls' top \(z = -0.18 m; body z points down\)"),
    (lambda x: x.replace('<general name="thruster_right" site="thruster_right" gear="1 0 0 0 0 0"/>', ''), None,
     r"no actuator 'thruster_right' \(a t200 vessel has two thrusters.*a one-propeller ship is a propeller_rudder"),
    (lambda x: x.replace('<site name="imu" pos="0 0 0"', '<site name="imu" pos="10 0 0"'), None,
     r"site 'imu' at \(10, 0, 0\) m lies far beyond the hull"),
    (lambda x: x, lambda d: d.__setitem__("sensors", {"antenna_offset_m": [275.0, -262.5]}),
     r"boat.json: sensors.antenna_offset_m \[275.0, -262.5\] puts the GNSS antenna at"),
    (lambda x: x, lambda d: d.__setitem__("cases", {"max": {"geom_mass_kg": {"batery": 9.0}}}),
     r"boat.json: cases.max.geom_mass_kg names geom 'batery', which boat.xml does not have"),
    (lambda x: x.replace('mass="4.5"', 'mass="150"', 1), None,
     r"boat.json: the vessel's 160.5 kg cannot float: its hull meshes displace 98.2. kg fully submerged \(every mesh"),
])
@pytest.mark.filterwarnings("ignore:Inertia matrix is too close to singular")  # MuJoCo's, of a swapped slide
def test_an_mjcf_that_would_mirror_steer_or_sink_the_boat_is_refused(tmp_path, mjcf_edit, file_edit, message):
    """A reversed or swapped planar joint mirrors the twin, a thruster's gear or site turned off body x
    steers it with its forward thrust (the allocation and the analytic model push along x), a thruster
    above the hulls pushes from the air, a one-thruster boat is pointed to the propeller-and-rudder kind, a sensor or antenna in mm, a mass case naming no geom (found only the day it is used)
    and a vessel its hulls cannot float: each refused, at whichever case the file is loaded in."""
    path = _own_copy(tmp_path, "blueboat", mjcf_edit, file_edit or (lambda d: None))
    with pytest.raises(TwinError, match=message):
        compile_vessel(vessel_mod.load(str(path)))


def test_a_thruster_site_rolled_about_its_own_thrust_axis_is_accepted_and_pushes_ahead(tmp_path):
    """Only the site's x axis carries thrust: a site rolled about it (a thruster mounted at an angle about
    its shaft) pushes as the shipped one does."""
    path = _own_copy(tmp_path, "blueboat", lambda x: x.replace('pos="-0.52 -0.285 0.10"/>',
                                                               'pos="-0.52 -0.285 0.10" euler="0.4 0 0"/>'))
    forces = []
    for vessel in (vessel_mod.load(str(path)), vessel_mod.load("blueboat")):
        model = compile_vessel(vessel).model
        data = mujoco.MjData(model)
        data.ctrl[:] = 10.0
        mujoco.mj_forward(model, data)
        forces.append(data.qfrc_actuator.copy())
    assert forces[1][0] > 15.0 and abs(forces[1][2]) < 1e-9
    np.testing.assert_allclose(forces[0], forces[1], atol=1e-9)


def test_a_thruster_site_in_millimetres_is_refused_before_the_twin_diverges(tmp_path):
    from twin.engine.mjcf import compile_vessel

    mjcf = (vessel_mod.MODEL_DIR / "blueboat.xml").read_text().replace(
        'pos="-0.52 -0.285 0.10"', 'pos="-520 -285 100"').replace(
        'meshdir="../assets"', f'meshdir="{vessel_mod.MODEL_DIR.parent / "assets"}"')
    (tmp_path / "boat.xml").write_text(mjcf)
    data = json.loads((vessel_mod.MODEL_DIR / "blueboat.json").read_text()) | {"mjcf": "boat.xml"}
    data["thrusters"]["pwm_min_us"] = 1100.0
    (tmp_path / "boat.json").write_text(json.dumps(data))
    with pytest.raises(TwinError, match=r"site 'thruster_left' at \(-520, -285, 100\) m lies far beyond the hull"):
        compile_vessel(vessel_mod.load(str(tmp_path / "boat.json")))
    data["thrusters"]["pwm_min_us"], data["thrusters"]["pwm_max_us"] = 1.1, 1.9
    (tmp_path / "boat.json").write_text(json.dumps(data))
    with pytest.raises(TwinError, match=r"pwm_min_us 1.1 and pwm_max_us 1.9 must be pulse widths in µs"):
        vessel_mod.load(str(tmp_path / "boat.json"))


def test_a_meshdir_of_ones_own_that_names_no_folder_is_said_not_replaced_by_the_packages(tmp_path):
    """A shipped MJCF copied elsewhere finds the package's meshes; a user's own meshdir does not:
    with a typo it loaded the package's hulls of the same names without a word."""
    from twin.engine.mjcf import compile_vessel

    import shutil

    shutil.copy(vessel_mod.MODEL_DIR / "blueboat.xml", tmp_path / "blueboat.xml")
    shutil.copy(vessel_mod.MODEL_DIR / "blueboat.json", tmp_path / "blueboat.json")
    assert compile_vessel(vessel_mod.load(str(tmp_path / "blueboat.json"))).geometry.rigid.mass_kg == pytest.approx(15)
    (tmp_path / "blueboat.xml").write_text((tmp_path / "blueboat.xml").read_text().replace(
        'meshdir="../assets"', 'meshdir="mesh"'))
    with pytest.raises(TwinError, match="Error opening file 'mesh/blueboat_hull_port.stl'"):
        compile_vessel(vessel_mod.load(str(tmp_path / "blueboat.json")))


def test_a_datasets_truth_file_loads_as_its_truth_vessel(tmp_path):
    """`--model my_log.truth.json` is the twin that generated the log, not an error."""
    from dataclasses import replace

    from twin.synth.dataset import generate

    boat = vessel_mod.load("blueboat")
    ds = generate(boat, effects=["thrust_gain=0.9"], n_segments=1, seed=2, segment_s=(10, 11))
    (tmp_path / "sub").mkdir()
    path = tmp_path / "sub" / "d.truth.json"
    path.write_text(json.dumps(ds.truth(path)))
    got = vessel_mod.load(path)
    assert got.thrusters.gain_left == pytest.approx(0.9 * boat.thrusters.gain_left)
    assert got.mjcf == boat.mjcf and replace(got, path=None).name == ds.truth_vessel.name


@pytest.mark.parametrize("edit, message", [
    (lambda m: m.__setitem__("hull", None), r"mmg needs its hull object"),
    (lambda m: m["hull"].__setitem__("R0", -1.0), r"mmg.hull.R0 .* must be positive, got -1.0"),
    (lambda m: m.__setitem__("friction_factor", -1.0), r"mmg.friction_factor .* got -1.0"),
])
def test_a_ship_file_whose_hull_cannot_resist_is_refused(tmp_path, edit, message):
    """A hull with no resistance (R'_0 ≤ 0, or its hull object null) runs away under any thrust and has
    no approach speed: refused in one line when the file is read."""
    path = vessel_mod.save(vessel_mod.load("esso_osaka"), tmp_path / "ship.json")
    data = json.loads(path.read_text())
    edit(data["mmg"])
    path.write_text(json.dumps(data))
    with pytest.raises(TwinError, match=message):
        vessel_mod.load(str(path))


def test_a_ship_whose_thrust_outruns_its_resistance_has_no_approach_speed():
    from dataclasses import replace

    from twin.analytic import straight_speed
    from twin.engine.mjcf import compile_vessel

    ship = vessel_mod.load("esso_osaka")
    assert 0.3 < straight_speed(compile_vessel(ship), 10.0) < 0.45  # the shipped twin at the tests' 10 rps
    mmg = ship.mmg
    wild = replace(ship, mmg=replace(mmg, propeller=replace(mmg.propeller, k0=1e30)))
    with pytest.raises(TwinError, match="no straight-running speed under .* m/s at 10 rps"):
        straight_speed(compile_vessel(wild), 10.0)


def test_an_uncertainty_block_naming_no_coefficient_is_refused_before_a_draw():
    from dataclasses import replace

    from twin.fit.uncertainty import check_drawable, draw

    boat = vessel_mod.load("blueboat")
    with pytest.raises(TwinError, match="carries no identification uncertainty"):
        check_drawable(boat)
    block = {"coordinates": [{"name": "nope", "log": False}], "mean": [0.0], "covariance": [[1.0]]}
    with pytest.raises(TwinError, match="uncertainty.coordinates name 'nope', which is no coefficient of this vessel"):
        draw(replace(boat, uncertainty=block), 2, np.random.default_rng(0))
    short = {"coordinates": [{"name": "Xu", "log": False}], "mean": [0.0, 1.0], "covariance": [[1.0]]}
    with pytest.raises(TwinError, match="mean and covariance must match its 1 coordinates"):
        check_drawable(replace(boat, uncertainty=short))
    fine = {"coordinates": [{"name": "Xu", "log": False}], "mean": [-0.4], "covariance": [[0.01]]}
    assert len(draw(replace(boat, uncertainty=fine), 3, np.random.default_rng(0))[0]) == 3


def test_an_mjcf_that_is_no_xml_file_is_refused_in_one_line(tmp_path):
    """MuJoCo picks its reader by the extension and, without one it knows, prints a warning of its own:
    the file is refused in one line before MuJoCo reads it."""
    (tmp_path / "hull.txt").write_text("hello")
    data = json.loads(vessel_mod.save(vessel_mod.load("blueboat"), tmp_path / "boat.json").read_text())
    data["mjcf"] = "hull.txt"
    (tmp_path / "boat.json").write_text(json.dumps(data))
    with pytest.raises(TwinError, match=r"boat.json: MJCF file 'hull.txt' must be an .xml file"):
        vessel_mod.load(str(tmp_path / "boat.json"))


def test_a_vessel_written_in_another_mass_case_loads_in_it(tmp_path):
    """A dataset simulated in case max, or a twin fitted in it, describes that boat: its file says the case,
    and loading it gives that case unless another is asked for."""
    heavy = vessel_mod.load("yellowfish", "max")
    path = tmp_path / "heavy.json"
    vessel_mod.save(heavy, path)
    back = vessel_mod.load(str(path))
    mass = lambda v: float(compile_vessel(v).model.body_subtreemass[1])  # noqa: E731
    assert back.case == "max" and mass(back) == pytest.approx(mass(heavy)) and mass(heavy) > mass(vessel_mod.load("yellowfish"))
    assert vessel_mod.load(str(path), "nominal").case == "nominal"
    assert "case" not in vessel_mod.load("yellowfish").to_dict()  # a nominal vessel's file stays as it was
