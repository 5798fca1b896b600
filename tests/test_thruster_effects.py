"""Delay, decay and advance-speed loss of the thrusters, the CG offset and the sensor
model: engine against the analytic model, and each against its own definition."""
from dataclasses import replace

import numpy as np
import pytest

import twin.vessel as vessel_mod
from twin import analytic
from twin.verify.crosscheck import _compare
from twin.engine.mjcf import compile_vessel
from twin.engine.sim import simulate
from twin.drive import InputSeries
from twin.physics.sensors import Sensors, measured_heading, true_heading

PWM = InputSeries(np.array([0.0, 4.0, 9.0, 14.0]), np.array([[1750, 1750], [1800, 1600], [1500, 1700],
                                                             [1850, 1850]], float), "pwm")


def _both(vessel, duration=20.0, start_s=0.0):
    cv = compile_vessel(vessel)
    eng = simulate(cv, PWM, duration, start_s=start_s, nu0=(0.5, 0.0, 0.0))
    ana = analytic.simulate(cv.hydro(), vessel.thrusters, cv.geometry.thruster_y_m, PWM, eng.t - start_s,
                            nu0=np.array([0.5, 0.0, 0.0]), start_s=start_s)
    return eng, ana


@pytest.mark.parametrize("change", [{"delay_s": 0.3}, {"decay_per_min": 0.2}, {"advance_loss": 1.5},
                                    {"advance_loss": 1.0, "lag_s": 0.4, "delay_s": 0.2}])
def test_engine_matches_analytic_with_thruster_effects(change):
    base = vessel_mod.load("yellowfish")
    v = replace(base, thrusters=replace(base.thrusters, **change))
    eng, ana = _both(v, start_s=30.0)
    pos, head = _compare(eng, ana)
    assert pos < 0.01 and head < 0.1
    plain, _ = _both(base, start_s=30.0)
    assert _compare(eng, plain)[0] > 0.3  # and the effect is really applied


def test_delay_shifts_the_response_by_the_delay():
    base = vessel_mod.load("yellowfish")
    cv = compile_vessel(base)
    step = InputSeries(np.array([0.0, 2.0]), np.array([[1500, 1500], [1800, 1800]], float), "pwm")
    plain = simulate(cv, step, 10.0, sample_dt_s=0.02)
    late = simulate(compile_vessel(replace(base, thrusters=replace(base.thrusters, delay_s=0.5))), step, 10.0,
                    sample_dt_s=0.02)
    np.testing.assert_allclose(late.nu[25:, 0], plain.nu[:-25, 0], atol=1e-9)


def test_decay_scales_thrust_with_recording_time():
    base = vessel_mod.load("yellowfish")
    v = replace(base, thrusters=replace(base.thrusters, decay_per_min=0.1))
    run = simulate(compile_vessel(v), PWM, 5.0, start_s=120.0)
    ref = simulate(compile_vessel(base), PWM, 5.0, start_s=120.0)
    assert run.t[0] == 120.0
    np.testing.assert_allclose(run.thrust_n, (1 - 0.1 * run.t / 60)[:, None] * ref.thrust_n, rtol=1e-9)


def test_advance_loss_is_each_propellers_own_advance():
    base = vessel_mod.load("yellowfish")
    c = 1.5
    v = replace(base, thrusters=replace(base.thrusters, advance_loss=c))
    cv = compile_vessel(v)
    run = simulate(cv, PWM, 8.0, nu0=(1.0, 0.0, 0.3))
    y = np.array(cv.geometry.thruster_y_m)
    cmd = np.clip(PWM.commanded_thrust(v.thrusters, run.t), *v.thrusters.bounds())
    expected = cmd - c * np.sqrt(np.abs(cmd)) * (run.nu[:, [0]] - run.nu[:, [2]] * y)
    np.testing.assert_allclose(run.thrust_n, expected, rtol=1e-12)


def test_advance_loss_damps_the_advance_whichever_way_the_propeller_turns():
    """K_T linear in J: a reversed propeller on a boat going ahead pushes harder (crash stop), one
    backing into its own jet pushes less; the T0·(1 − k·u_a) form has both the wrong way round."""
    from twin.physics.thrusters import delivered

    y = (-0.3, 0.3)
    ahead, astern = np.array([1.0, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0])
    forward, reverse = np.array([20.0, 20.0]), np.array([-20.0, -20.0])
    assert np.all(delivered(1.0, forward, ahead, y) < 20.0)  # advancing: less thrust
    assert np.all(delivered(1.0, reverse, ahead, y) < -20.0)  # crash stop: more reverse thrust
    assert np.all(delivered(1.0, reverse, astern, y) > -20.0)  # backing into its jet: less
    spin = delivered(1.0, np.array([20.0, -20.0]), np.array([0.0, 0.0, 1.0]), y)
    # r > 0 moves the port (y < 0) thruster ahead and the starboard one astern: both push less
    np.testing.assert_allclose(spin, [20.0 - np.sqrt(20) * 0.3, -20.0 + np.sqrt(20) * 0.3])
    assert delivered(0.0, forward, ahead, y) == pytest.approx(forward)


def test_cg_offset_moves_the_centre_of_gravity_only():
    base = vessel_mod.load("yellowfish")
    g0 = compile_vessel(base).geometry
    g1 = compile_vessel(replace(base, cg_offset_m=(0.05, -0.02))).geometry
    assert g1.rigid.mass_kg == pytest.approx(g0.rigid.mass_kg)
    assert g1.rigid.xg_m - g0.rigid.xg_m == pytest.approx(0.05, abs=1e-9)
    assert g1.rigid.yg_m - g0.rigid.yg_m == pytest.approx(-0.02, abs=1e-9)
    # parallel axis: Iz grows by m(2 x_g dx + dx²) + m(2 y_g dy + dy²)
    m = g0.rigid.mass_kg
    dI = m * (2 * g0.rigid.xg_m * 0.05 + 0.05**2 + 2 * g0.rigid.yg_m * -0.02 + 0.02**2)
    assert g1.rigid.Iz_kgm2 - g0.rigid.Iz_kgm2 == pytest.approx(dI, rel=1e-6)
    np.testing.assert_allclose(g1.gnss_pos_m, g0.gnss_pos_m)
    np.testing.assert_allclose(g1.thruster_pos_m, g0.thruster_pos_m)


def test_heading_error_and_its_inverse():
    s = Sensors(heading_bias_deg=2.0, compass_deviation_deg=(3.0, -1.5, 1.0, 0.5))
    psi = np.linspace(-np.pi, np.pi, 37)
    m = measured_heading(s, psi)
    expected = psi + np.radians(2 + 3 * np.sin(psi) - 1.5 * np.cos(psi) + np.sin(2 * psi) + 0.5 * np.cos(2 * psi))
    np.testing.assert_allclose(m, expected)
    np.testing.assert_allclose(true_heading(s, m, iterations=12), psi, atol=1e-9)


def test_vessel_file_round_trip_keeps_the_new_fields(tmp_path):
    base = vessel_mod.load("yellowfish")
    v = replace(base, sensors=Sensors(heading_bias_deg=1.5, antenna_offset_m=(0.1, 0.0)), cg_offset_m=(0.01, 0.0),
                thrusters=replace(base.thrusters, delay_s=0.2, decay_per_min=0.05, advance_loss=1.2))
    path = vessel_mod.save(v, tmp_path / "amended.json")
    back = vessel_mod.load(str(path))
    assert back.sensors == v.sensors and back.cg_offset_m == v.cg_offset_m and back.thrusters == v.thrusters
