"""The native (numba cfunc) passive callback against the Python reference."""
import ctypes
import os
import threading
from dataclasses import replace

import mujoco
import numpy as np
import pytest

import twin.vessel as vessel_mod
from twin.verify.crosscheck import TERM_ENV, cases
from twin.engine import callbacks, native, sixdof
from twin.engine.mjcf import CompiledVessel, compile_vessel
from twin.errors import TwinError
from twin.physics.environment import Environment
from twin.physics import drop_stale_jit_caches
from twin.physics.hydrodynamics import Terms

VESSELS = ("yellowfish", "cybership1", "blueboat")
CASES = {c.name: c for c in cases()}


@pytest.fixture(scope="module")
def compiled():
    return {name: compile_vessel(vessel_mod.load(name)) for name in VESSELS}


def _with_env(cv: CompiledVessel, env: Environment) -> CompiledVessel:
    return CompiledVessel(replace(cv.vessel, environment=env), cv.model, cv.geometry)


def _random_state(rng, data):
    data.qpos[:] = rng.uniform(-5.0, 5.0, 3)
    data.qvel[:] = rng.uniform(-2.0, 2.0, 3)
    data.ctrl[:] = rng.uniform(-30.0, 60.0, 2)


def _passive(model, data, install) -> np.ndarray:
    with install():
        mujoco.mj_forward(model, data)
    return data.qfrc_passive.copy()


def test_offsets_point_at_the_fields_of_a_vessel_model(compiled):
    model = native.with_native_params(compiled["yellowfish"])
    data = mujoco.MjData(model)
    off = native.offsets()

    def word(obj, key):
        return ctypes.c_int64.from_address(obj._address + off[key]).value

    assert word(model, "m.nq") == model.nq and word(model, "m.nv") == model.nv
    assert word(model, "m.nnumeric") == model.nnumeric == 1
    for name in ("numeric_adr", "numeric_size", "numeric_data"):
        assert word(model, f"m.{name}") == getattr(model, name).ctypes.data
    for name in ("qpos", "qvel", "qfrc_passive", "qfrc_actuator"):
        assert word(data, f"d.{name}") == getattr(data, name).ctypes.data


def test_pack_params_layout(compiled):
    cv = _with_env(compiled["cybership1"], TERM_ENV)
    hydro = cv.hydro(Terms(wind=False))
    p = native.pack_params(hydro, cv.model)
    L = native.LAYOUT
    assert p.shape == (native.NPARAM,) and tuple(p[L["magic"]]) == native.MAGIC and p[2] == native.NPARAM
    assert list(p[L["switches"]]) == [1, 1, 1, 1, 1, 0]
    np.testing.assert_array_equal(p[L["M_inv"]].reshape(3, 3), hydro.M_inv)
    np.testing.assert_array_equal(p[L["current_ned"]], TERM_ENV.current_ned)
    no_current = native.pack_params(compiled["cybership1"].hydro(), cv.model)  # speed 0: switch off
    assert no_current[L["switches"]][4] == 0


@pytest.mark.parametrize("case", list(CASES))
@pytest.mark.parametrize("name", VESSELS)
def test_native_passive_force_equals_python(compiled, name, case):
    c = CASES[case]
    cv = _with_env(compiled[name], c.environment)
    model, hydro = native.with_native_params(cv, c.terms), cv.hydro(c.terms)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(1234)
    for _ in range(25):
        _random_state(rng, data)
        reference = _passive(model, data, lambda: callbacks.installed(model, hydro))
        fast = _passive(model, data, native.installed_native)
        np.testing.assert_allclose(fast, reference, rtol=0, atol=1e-9)
    if case in ("full", "damping", "full_environment"):
        assert np.abs(reference).max() > 1.0  # the comparison is not between zeros


@pytest.mark.parametrize("case", ["full", "added_mass", "current", "wind", "full_environment"])
@pytest.mark.parametrize("name", VESSELS)
def test_native_trajectory_equals_python(compiled, name, case):
    c = CASES[case]
    cv = _with_env(compiled[name], c.environment)
    model, hydro = native.with_native_params(cv, c.terms), cv.hydro(c.terms)
    rng = np.random.default_rng(7)
    controls = np.repeat(rng.uniform(-30.0, 60.0, (10, 2)), 50, axis=0)  # 500 steps, held 50 each
    runs = []
    for install in (lambda: callbacks.installed(model, hydro), native.installed_native):
        data = mujoco.MjData(model)
        data.qvel[:] = c.nu0
        out = []
        with install():
            for u in controls:
                data.ctrl[:] = u
                mujoco.mj_step(model, data)
                out.append(np.concatenate([data.qpos, data.qvel]))
        runs.append(np.array(out))
    np.testing.assert_allclose(runs[1], runs[0], rtol=0, atol=1e-9)
    assert np.ptp(runs[0][:, 0]) > 0.1  # the vessel did move


def test_the_3dof_callback_moves_a_twin_as_the_full_one_and_gives_a_6dof_hull_nothing(compiled):
    # compiled without the 6-DOF hull's terms (a quarter of the time), it steps a 3-DOF twin bit for bit
    # as the full callback does; a 6-DOF hull under it gets no force at all, which no run could take
    # for physics, and is told apart by is_six_dof (batch.rollout picks the full callback for one)
    c = CASES["full_environment"]
    model = native.with_native_params(_with_env(compiled["blueboat"], c.environment), c.terms)
    controls = np.repeat(np.random.default_rng(3).uniform(-30.0, 60.0, (10, 2)), 50, axis=0)
    runs = []
    for six_dof in (True, False):
        data = mujoco.MjData(model)
        data.qvel[:] = c.nu0
        with native.installed_native(six_dof=six_dof):
            for u in controls:
                data.ctrl[:] = u
                mujoco.mj_step(model, data)
        runs.append(np.concatenate([data.qpos, data.qvel]))
    np.testing.assert_array_equal(runs[1], runs[0])
    assert np.ptp(runs[0][:2]) != 0.0 and not native.is_six_dof(model)
    hull = sixdof.compile_six(compiled["yellowfish"]).model
    assert native.is_six_dof(hull)
    data = mujoco.MjData(hull)
    data.qvel[:3] = [1.0, 0.2, 0.3]
    forces = {six_dof: _passive(hull, data, lambda: native.installed_native(six_dof=six_dof)) for six_dof in (True, False)}
    assert np.abs(forces[True]).max() > 1.0 and not forces[False].any()


def test_set_params_changes_the_physics_without_recompiling(compiled):
    cv = _with_env(compiled["yellowfish"], TERM_ENV)
    model = native.with_native_params(cv, Terms().only("thrust"))
    terms = Terms()
    native.set_params(model, cv.hydro(terms))
    data = mujoco.MjData(model)
    _random_state(np.random.default_rng(3), data)
    reference = _passive(model, data, lambda: callbacks.installed(model, cv.hydro(terms)))
    np.testing.assert_allclose(_passive(model, data, native.installed_native), reference, atol=1e-9)
    assert np.abs(reference).max() > 1.0


def test_models_without_params_are_left_alone(compiled):
    model = compiled["yellowfish"].model  # no custom numeric at all
    data = mujoco.MjData(model)
    _random_state(np.random.default_rng(5), data)
    assert not native.has_params(model)
    np.testing.assert_array_equal(_passive(model, data, native.installed_native), np.zeros(3))
    with pytest.raises(TwinError):
        native.set_params(model, compiled["yellowfish"].hydro())


def test_foreign_first_numeric_is_ignored():
    xml = """<mujoco><custom><numeric name="other" data="1 2 3"/></custom><worldbody><body>
    <joint name="north" type="slide" axis="1 0 0"/><joint name="east" type="slide" axis="0 1 0"/>
    <joint name="yaw" type="hinge" axis="0 0 1"/><geom size=".1" mass="1"/></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.qvel[:] = 1.0
    assert not native.has_params(model)
    np.testing.assert_array_equal(_passive(model, data, native.installed_native), np.zeros(3))


def test_installed_native_restores_the_previous_callback(compiled):
    assert mujoco.get_mjcb_passive() is None
    with native.installed_native():
        assert mujoco.get_mjcb_passive() is not None
    assert mujoco.get_mjcb_passive() is None
    cv = compiled["cybership1"]
    with callbacks.installed(cv.model, cv.hydro()):
        python_cb = mujoco.get_mjcb_passive()
        with native.installed_native():
            pass
        assert mujoco.get_mjcb_passive() is python_cb
    assert mujoco.get_mjcb_passive() is None


def test_a_second_thread_cannot_take_the_callback_from_a_block_still_stepping(compiled):
    """MuJoCo's passive callback is one per process: a thread leaving its block while another's is
    still inside would restore its own previous callback (none) under the other's steps."""
    entered, done, seen = threading.Event(), threading.Event(), []

    def other():
        entered.wait(5)
        with native.installed_native():
            pass
        done.set()

    thread = threading.Thread(target=other)
    thread.start()
    with native.installed_native():
        entered.set()
        done.wait(0.3)  # the other thread's block waits for this one to end
        seen.append(mujoco.get_mjcb_passive())
    thread.join(5)
    assert seen[0] is not None and done.is_set()
    assert mujoco.get_mjcb_passive() is None


def test_every_damping_coefficient_reaches_the_native_callback(compiled):
    from twin.physics.damping import Damping

    coefficients = {n: -(1.0 + i) for i, n in enumerate(Damping.names())}  # all on, none equal
    cv = compiled["yellowfish"]
    vessel = replace(cv.vessel, damping=Damping(**coefficients))
    cv = CompiledVessel(vessel, cv.model, cv.geometry)
    model, hydro = native.with_native_params(cv), cv.hydro()
    data = mujoco.MjData(model)
    rng = np.random.default_rng(99)
    for _ in range(10):
        _random_state(rng, data)
        reference = _passive(model, data, lambda: callbacks.installed(model, hydro))
        np.testing.assert_allclose(_passive(model, data, native.installed_native), reference, rtol=0, atol=1e-9)
    # the speed terms act: yaw damping with |u| differs from without
    nu = np.array([1.5, 0.2, 0.3])
    assert abs(Damping(Nur=-4.0).matrix(nu)[2, 2] - 6.0) < 1e-12 and abs(Damping(Yuv=-2.0).matrix(nu)[1, 1] - 3.0) < 1e-12
    # the signed coupling changes sign with the direction of travel (physics.damping)
    assert Damping(Yur=2.0).matrix(nu)[1, 2] == pytest.approx(-3.0)
    assert Damping(Yur=2.0).matrix(-nu)[1, 2] == pytest.approx(3.0)
    # the astern excess acts going astern only, on the whole surge curve
    hull = Damping(Xu=-2.0, Xuu=-8.0, astern_excess=0.5)
    assert hull.matrix(nu)[0, 0] == pytest.approx(14.0) and hull.matrix(-nu)[0, 0] == pytest.approx(21.0)


def test_advance_loss_reaches_the_native_callback(compiled):
    """The propellers' advance loss reads each thruster's actuator force in the callback: the
    native one must agree with the Python reference, and the loss must act."""
    cv = compiled["yellowfish"]
    vessel = replace(cv.vessel, thrusters=replace(cv.vessel.thrusters, advance_loss=1.7))
    cv = CompiledVessel(vessel, cv.model, cv.geometry)
    model, hydro = native.with_native_params(cv), cv.hydro()
    plain = native.with_native_params(compiled["yellowfish"])
    data = mujoco.MjData(model)
    rng = np.random.default_rng(5)
    moved = []
    for _ in range(10):
        _random_state(rng, data)
        data.ctrl[:2] = rng.uniform(-20.0, 30.0, 2)
        reference = _passive(model, data, lambda: callbacks.installed(model, hydro))
        np.testing.assert_allclose(_passive(model, data, native.installed_native), reference, rtol=0, atol=1e-9)
        d2 = mujoco.MjData(plain)
        d2.qpos[:], d2.qvel[:], d2.ctrl[:] = data.qpos, data.qvel, data.ctrl
        moved.append(np.abs(reference - _passive(plain, d2, native.installed_native)).max())
    assert max(moved) > 0.5


@pytest.mark.parametrize("name", VESSELS + ("esso_osaka",))
def test_the_lean_model_moves_as_the_full_one(name):
    """The fit's model without meshes, geoms and welded bodies (mjcf.make_lean): the same planar
    M_RB, sites and actuators, and the same trajectory to round-off under thrust and the callback."""
    cv = compile_vessel(vessel_mod.load(name))
    full = native.with_native_params(cv)
    lean = native.with_native_params(cv, lean=True)
    assert lean.ngeom == 0 and lean.nbody == 2 and lean.nu == full.nu and lean.nsite == full.nsite
    M = []
    for m in (full, lean):
        d = mujoco.MjData(m)
        mujoco.mj_forward(m, d)
        M.append(np.zeros((3, 3)))
        mujoco.mj_fullM(m, d, M[-1])
    np.testing.assert_allclose(M[1], M[0], rtol=1e-12, atol=1e-12)
    ends = []
    for m in (full, lean):
        d = mujoco.MjData(m)
        d.qvel[:] = [1.0, 0.2, 0.3]
        d.ctrl[:2] = [8.0, 0.2] if name == "esso_osaka" else [30.0, 10.0]  # rps and rudder, or N
        with native.installed_native():
            mujoco.mj_step(m, d, nstep=500)
        ends.append(np.concatenate([d.qpos, d.qvel]))
    assert np.abs(ends[0][:3]).max() > 1.0  # it went somewhere
    np.testing.assert_allclose(ends[1], ends[0], rtol=1e-9, atol=1e-9)


def test_a_vessel_with_a_site_on_a_welded_part_is_left_whole():
    """make_lean moves no site: one that sits on a welded body keeps the model as it is."""
    from twin.engine.mjcf import make_lean
    from twin.physics.added_mass import RigidBody

    spec = mujoco.MjSpec.from_string("""<mujoco><worldbody><body name="vessel">
      <joint name="north" type="slide" axis="1 0 0"/><joint name="east" type="slide" axis="0 1 0"/>
      <joint name="yaw" type="hinge" axis="0 0 1"/><geom type="box" size=".5 .2 .1" mass="10"/>
      <body name="mast" pos="0.1 0 -0.5"><geom type="box" size=".05 .05 .3" mass="1"/><site name="gnss"/></body>
      </body></worldbody></mujoco>""")
    make_lean(spec, RigidBody(11.0, 0.01, 0.0, 0.5))
    model = spec.compile()
    assert model.nbody == 3 and model.ngeom == 2
    spec = mujoco.MjSpec.from_string("""<mujoco><worldbody><body name="vessel">
      <joint name="north" type="slide" axis="1 0 0"/><joint name="east" type="slide" axis="0 1 0"/>
      <joint name="yaw" type="hinge" axis="0 0 1"/><geom type="box" size=".5 .2 .1" mass="10"/>
      <body name="mast" pos="0.1 0 -0.5"><geom type="box" size=".05 .05 .3" mass="1"/></body><site name="gnss"/>
      </body></worldbody></mujoco>""")
    make_lean(spec, RigidBody(11.0, 0.01, 0.0, 0.5))
    model = spec.compile()
    assert model.nbody == 2 and model.ngeom == 0 and model.body_mass[1] == pytest.approx(11.0)


def test_a_later_process_loads_the_compiled_callback_from_the_disk_cache_and_steps_alike():
    """Compiling the callback takes seconds, every `twin` command needs it: the second process
    finds the first one's code (numba's cache) and steps the twin to the same state."""
    import subprocess
    import sys

    code = ("import mujoco, numpy as np, twin.vessel as v; from twin.engine import native; "
            "from twin.engine.mjcf import compile_vessel; f = native.passive_cfunc(); "
            "m = native.with_native_params(compile_vessel(v.load('yellowfish'))); d = mujoco.MjData(m); "
            "d.qvel[:] = [1.0, 0.2, 0.3]; d.ctrl[:2] = [30.0, 10.0]; native.install(); "
            "mujoco.mj_step(m, d, nstep=500); print(f.cache_hits, repr(float(np.sum(d.qpos))))")
    first, second = (subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
                     for _ in range(2))
    assert first.returncode == 0 and second.returncode == 0, first.stderr + second.stderr
    hits, state = second.stdout.split()
    assert hits == "1" and state == first.stdout.split()[1] and float(state) != 0.0


def test_a_compiled_cache_older_than_a_jitted_source_is_dropped_and_a_newer_one_kept(tmp_path):
    # numba would reuse a caller's cache after a callee in another file changed (twin.physics)
    source, cache = tmp_path / "hydrostatics.py", tmp_path / "__pycache__"
    cache.mkdir()
    source.write_text("x = 1\n")
    stale, fresh, other = cache / "seakeeping.sea_load-1.py311.nbi", cache / "waves.grid-2.py311.1.nbc", cache / "a.pyc"
    for f in (stale, fresh, other):
        f.write_bytes(b"0")
    t = source.stat().st_mtime
    os.utime(stale, (t - 10, t - 10))
    os.utime(fresh, (t + 10, t + 10))
    os.utime(other, (t - 10, t - 10))
    assert drop_stale_jit_caches([source], [cache]) == [stale]
    assert not stale.exists() and fresh.exists() and other.exists()
    assert drop_stale_jit_caches([], [cache]) == []
