"""The MJCF models and the MuJoCo callbacks."""
import copy
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh

import twin.vessel as vessel_mod
from twin import analytic
from twin import drive as scenarios
from twin.engine import callbacks
from twin.engine.mjcf import CompiledVessel, compile_vessel
from twin.engine.sim import initial_state, simulate
from twin.physics.hydrodynamics import Terms, acceleration, kinetic_energy
from twin.physics.thrusters import allocation_matrix

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.parametrize("case,mass,xg_mm", [("min", 23.73, -18.7), ("nominal", 24.39, -19.6), ("max", 25.73, -20.5)])
def test_yellowfish_mass_and_cg_match_yellowfish_report_tables_iii_iv(case, mass, xg_mm):
    g = compile_vessel(vessel_mod.load("yellowfish", case)).geometry
    assert g.rigid.mass_kg == pytest.approx(mass, abs=0.005)
    assert g.rigid.xg_m * 1e3 == pytest.approx(xg_mm, abs=0.15)
    assert abs(g.rigid.yg_m) < 1e-9


def test_yellowfish_sites(yellowfish):
    g = yellowfish.geometry
    assert g.thruster_pos_m[1, 1] - g.thruster_pos_m[0, 1] == pytest.approx(0.68)
    np.testing.assert_allclose(g.imu_pos_m, 0.0)
    # [Yellowfish-TR eq. 29]: OP = (0.275, -0.2625) m from the antenna O to CO
    np.testing.assert_allclose(-g.gnss_pos_m[:2], [0.275, -0.2625])


def test_hull_meshes_are_watertight_and_reproducible():
    import importlib.util

    spec = importlib.util.spec_from_file_location("mk", ROOT / "scripts" / "make_hull_meshes.py")
    mk = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mk)
    fresh = trimesh.exchange.stl.export_stl(mk.hull_mesh())
    for side in ("port", "starboard"):
        path = vessel_mod.MODEL_DIR.parent / "assets" / f"yellowfish_hull_{side}.stl"
        assert path.read_bytes() == fresh
        mesh = trimesh.load(path)
        assert mesh.is_watertight
        # 0.298 m deep, not 0.30: the bow's rise and the aft rocker meet amidships, no station has the full depth
        np.testing.assert_allclose(mesh.extents, [1.28, 0.255, 0.298], atol=1e-3)


def test_cybership_total_inertia_is_cybership_bertoni(cybership):
    np.testing.assert_allclose(cybership.hydro().M, [[26.4272, 0, 0], [0, 51.3671, -0.7372], [0, -0.7372, 1.2645]],
                               atol=1e-9)


@pytest.mark.parametrize("name", ["yellowfish", "cybership1"])
def test_engine_acceleration_equals_equation_of_motion_instantly(name):
    """Added mass is applied exactly: no lag, even where M_A22 > m (CyberShip I)."""
    cv = compile_vessel(vessel_mod.load(name))
    m, d = cv.model, mujoco.MjData(cv.model)
    rng = np.random.default_rng(7)
    hydro = cv.hydro()
    B = allocation_matrix(cv.geometry.thruster_y_m)
    with callbacks.installed(m, hydro):
        for _ in range(5):
            eta0, nu0 = rng.normal(size=3), rng.normal(scale=0.5, size=3)
            initial_state(m, d, eta0, nu0)
            d.ctrl[:2] = rng.uniform(-1, 1, size=2)
            mujoco.mj_forward(m, d)
            psi = eta0[2]
            c, s = np.cos(psi), np.sin(psi)
            # body acceleration from the world-frame qacc: ν̇ = Rᵀ q̈ − S(r)… for planar motion
            qa, qv = d.qacc, d.qvel
            u_dot = c * qa[0] + s * qa[1] + qv[2] * (-s * qv[0] + c * qv[1])
            v_dot = -s * qa[0] + c * qa[1] - qv[2] * (c * qv[0] + s * qv[1])
            expected = acceleration(hydro, psi, nu0, B @ d.ctrl[:2])
            np.testing.assert_allclose([u_dot, v_dot, qa[2]], expected, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("name", ["cybership1", "yellowfish", "blueboat"])
def test_engine_conserves_kinetic_energy_without_damping_and_inputs(name):
    """C(ν) is skew-symmetric, so with damping, thrust and environment removed ½νᵀMν stays put:
    CyberShip I (M23 from [Bertoni-2024], sway added mass above the rigid mass), the Yellowfish
    (M23 = m·xg, CG 19.6 mm aft of CO) and the BlueBoat (CG at CO)."""
    cv = compile_vessel(vessel_mod.load(name))
    terms = Terms().only("added_mass", "added_mass_coriolis")
    run = simulate(cv, scenarios.get("step"), 30.0, nu0=(1.0, 0.3, 0.5), terms=terms)
    M = cv.hydro(terms).M
    e = np.array([kinetic_energy(M, nu) for nu in run.nu])
    assert np.max(np.abs(e / e[0] - 1.0)) < 1e-6
    assert np.ptp(run.nu[:, 0]) > 0.05  # the velocities do exchange energy: the test is not trivially still


def test_damping_only_loses_energy_monotonically(yellowfish):
    terms = Terms().only("added_mass", "added_mass_coriolis", "damping")
    run = simulate(yellowfish, scenarios.get("step"), 10.0, nu0=(1.0, 0.3, 0.5), terms=terms)
    e = np.array([kinetic_energy(yellowfish.hydro(terms).M, nu) for nu in run.nu])
    assert np.all(np.diff(e) < 0)


def test_thrust_lag_is_integrated_by_the_engine():
    from dataclasses import replace

    v = vessel_mod.load("yellowfish")
    lagged = replace(v, thrusters=replace(v.thrusters, lag_s=0.5))
    cv = compile_vessel(lagged)
    run = simulate(cv, scenarios.step(surge=0.6, at_s=0.0), 3.0, sample_dt_s=0.1)
    target = lagged.thrusters.thrust_from_pwm(1500 + 400 * 0.6)
    # first-order response: 1 − e^{−t/τ}
    i = int(round(0.5 / 0.1))
    assert run.thrust_n[i, 0] == pytest.approx(target * (1 - np.exp(-1.0)), rel=1e-3)
    ana = analytic.simulate(cv.hydro(), lagged.thrusters, cv.geometry.thruster_y_m, run.meta["inputs"], run.t)
    assert np.max(np.abs(run.eta[:, 0] - ana.eta[:, 0])) < 1e-6


def test_asymmetric_gain_turns_the_vessel():
    from dataclasses import replace

    v = vessel_mod.load("yellowfish")
    weak_right = replace(v, thrusters=replace(v.thrusters, gain_right=0.8))
    run = simulate(compile_vessel(weak_right), scenarios.step(surge=0.6, at_s=0.0), 10.0)
    assert run.eta[-1, 2] > np.deg2rad(5)  # left pushes harder: turns to starboard
    np.testing.assert_allclose(run.thrust_n[-1, 1] / run.thrust_n[-1, 0], 0.8)


def _anti_damped(yellowfish) -> CompiledVessel:
    """Positive (anti-)damping: energy is pumped in and the twin blows up within a second."""
    from dataclasses import replace

    from twin.physics.damping import Damping

    return CompiledVessel(replace(yellowfish.vessel, damping=Damping(Xu=200.0, Yv=200.0, Nr=200.0)),
                          yellowfish.model, yellowfish.geometry)


@pytest.mark.parametrize("backend", ["native", "python"])
def test_a_diverging_twin_raises_naming_the_time(yellowfish, backend, tmp_path, monkeypatch, capfd):
    """MuJoCo resets a diverged state and carries on; the twin must notice, say when, and leave
    neither MUJOCO_LOG.TXT in the working directory nor MuJoCo's own warning on the console."""
    from twin.errors import TwinError
    from twin.drive import InputSeries

    monkeypatch.chdir(tmp_path)
    series = InputSeries(np.array([0.0]), np.array([[1700.0, 1600.0]]), "pwm")
    with pytest.raises(TwinError) as exc:
        simulate(_anti_damped(yellowfish), series, 30.0, start_s=100.0, backend=backend)
    # the first step whose acceleration the twin's guard refuses (it comes before MuJoCo's own
    # bad-position reset for this hull's inertia), on the recording clock
    assert "diverged at t = 100.28 s" in str(exc.value) and "acceleration" in str(exc.value)
    assert "\n" not in str(exc.value)
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
    assert "WARNING" not in capfd.readouterr().err
    assert mujoco.MjLogConfig.get().logto_file  # MuJoCo's log is only silenced while the twin steps
    run = simulate(yellowfish, series, 2.0, backend=backend)
    assert np.all(np.isfinite(run.nu)) and run.nu[-1, 0] > 0.3


@pytest.mark.parametrize("name", ["yellowfish", "blueboat", "cybership1", "esso_osaka"])
def test_contact_and_constraint_stages_are_off_and_safe_to_be(name):
    """The MJCFs switch off contact and constraint (a fifth of every step): safe only while no geom
    can collide and no joint is limited, and the motion is the same as with them on."""
    cv = compile_vessel(vessel_mod.load(name))
    m = cv.model
    off = mujoco.mjtDisableBit
    assert m.opt.disableflags & off.mjDSBL_CONTACT and m.opt.disableflags & off.mjDSBL_CONSTRAINT
    assert not np.any(m.geom_contype | m.geom_conaffinity)
    assert not np.any(m.jnt_limited) and not np.any(m.dof_frictionloss) and m.neq == 0
    on = copy.copy(m)
    on.opt.disableflags = 0
    states = []
    for model in (m, on):
        d = mujoco.MjData(model)
        d.qvel[:] = (1.0, 0.3, 0.4)
        for _ in range(200):
            mujoco.mj_step(model, d)
        states.append(np.concatenate([d.qpos, d.qvel]))
    np.testing.assert_allclose(states[0], states[1], rtol=0, atol=1e-12)


def test_a_run_records_the_pwm_its_escs_take_not_a_pulse_beyond_their_range():
    """An inputs series asking 5000 µs is held at the ESC's 1900 µs, as the engine applies it; the run
    recorded 5000, which no autopilot log holds."""
    from twin.drive import InputSeries
    from twin.simulation import simulate

    run = simulate("blueboat", InputSeries(np.array([0.0]), np.array([[5000.0, -3000.0]]), "pwm"), duration_s=1.0)
    assert np.all(run.pwm_us[:, 0] == 1900.0) and np.all(run.pwm_us[:, 1] == 1100.0)
