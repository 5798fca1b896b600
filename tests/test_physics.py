"""The force modules against the published equations and basic mechanics."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from twin.physics.added_mass import AddedMass, RigidBody, total_mass_matrix
from twin.physics.coriolis import coriolis_force, coriolis_matrix, printed_coriolis_bertoni
from twin.physics.damping import Damping, damping_force, dissipated_power, is_dissipative
from twin.physics.environment import Environment, WindLoad, current_body, wind_force
from twin.physics.hydrodynamics import HydroModel, Terms, acceleration, kinetic_energy
from twin.physics.thrusters import (ThrusterModel, allocation_matrix, force_torque_bounds, lag_alpha,
                                    lag_time_constant_s)

CYBERSHIP_M = np.array([[26.4272, 0, 0], [0, 51.3671, -0.7372], [0, -0.7372, 1.2645]])
RNG = np.random.default_rng(1234)


def test_coriolis_is_skew_and_matches_morel_eq6():
    m, xg, Xud, Yvd, Yrd, Nrd, Iz = 24.39, -0.0196, -1.0, -10.92, 0.3, -3.95, 1.81
    M = total_mass_matrix(RigidBody(m, xg, 0.0, Iz), AddedMass(Xud, Yvd, Yrd, Yrd, Nrd))
    for nu in RNG.normal(size=(20, 3)):
        C = coriolis_matrix(M, nu)
        np.testing.assert_allclose(C, -C.T, atol=1e-12)
        u, v, r = nu
        seed = np.array([[0, 0, -(m - Yvd) * v - (m * xg - Yrd) * r],
                         [0, 0, (m - Xud) * u],
                         [(m - Yvd) * v + (m * xg - Yrd) * r, -(m - Xud) * u, 0]])
        np.testing.assert_allclose(C, seed, atol=1e-12)
        np.testing.assert_allclose(coriolis_force(M, nu), C @ nu, atol=1e-12)


def test_bertoni_printed_coriolis_is_not_skew_and_does_not_conserve_energy():
    nu0 = np.array([0.5, 0.2, 0.3])
    C = printed_coriolis_bertoni(CYBERSHIP_M, nu0)
    assert not np.allclose(C, -C.T)
    assert abs(nu0 @ C @ nu0) > 0.1  # it does work on the vessel

    def energy_after(cfun):
        sol = solve_ivp(lambda t, nu: -np.linalg.solve(CYBERSHIP_M, cfun(CYBERSHIP_M, nu) @ nu),
                        (0, 20), nu0, rtol=1e-10, atol=1e-12)
        return kinetic_energy(CYBERSHIP_M, sol.y[:, -1]) / kinetic_energy(CYBERSHIP_M, nu0)

    assert energy_after(coriolis_matrix) == pytest.approx(1.0, abs=1e-7)
    assert abs(energy_after(printed_coriolis_bertoni) - 1.0) > 0.05


def test_rigid_coriolis_equals_fossen_3dof_with_yg():
    m, xg, yg = 10.0, 0.1, -0.05
    M = RigidBody(m, xg, yg, 2.0).matrix()
    u, v, r = 0.7, -0.3, 0.4
    fossen = np.array([[0, 0, -m * (xg * r + v)], [0, 0, -m * (yg * r - u)],
                       [m * (xg * r + v), m * (yg * r - u), 0]])
    np.testing.assert_allclose(coriolis_matrix(M, np.array([u, v, r])) @ [u, v, r], fossen @ [u, v, r])


def test_damping_eq7_signs_and_dissipation():
    d = Damping(Xu=-2, Xuu=-8, Yv=-20, Yvv=-60, Nr=-4, Nrr=-6, Yr=-1, Nv=-1)
    nu = np.array([1.0, 0.5, -0.2])
    f = damping_force(d, nu)
    assert f[0] == pytest.approx(2 * 1 + 8 * 1 * 1)
    assert f[1] == pytest.approx(20 * 0.5 + 60 * 0.25 + 1 * -0.2)
    assert f[2] == pytest.approx(1 * 0.5 + 4 * -0.2 + 6 * 0.2 * -0.2)
    assert is_dissipative(d)
    assert not is_dissipative(Damping(Xu=2.0))
    assert not is_dissipative(Damping(Yv=-1, Nr=-1, Yr=-5, Nv=5 - 20))


def test_dissipated_power_is_nu_dot_damping_force_for_every_coefficient():
    """The vectorised νᵀD(ν)ν that is_dissipative checks equals ν·D(ν)ν of eq. 7, term by term."""
    rng = np.random.default_rng(7)
    for name in Damping.names():
        d = Damping(**{name: float(rng.normal(0.0, 10.0))})
        nu = rng.normal(0.0, 1.5, (6, 3))
        expected = np.array([x @ damping_force(d, x) for x in nu])
        np.testing.assert_allclose(dissipated_power(d, nu), expected, rtol=1e-12, atol=1e-12)


def test_t200_map_reproduces_table_viii_and_dead_zone():
    t = ThrusterModel()
    assert t.normalised(1500) == pytest.approx(0.0)
    assert t.normalised([1100, 1900]) == pytest.approx([-1.0, 1.0])
    # inside the experimental dead zone (Table VII) no thrust
    assert t.thrust_from_pwm(1500 + 400 * 0.077) == 0.0
    assert t.thrust_from_pwm(1500 + 400 * -0.092) == 0.0
    assert t.thrust_from_pwm(1500 + 400 * 0.078) > 0.0
    assert t.thrust_from_pwm(1500 + 400 * -0.093) < 0.0
    b = force_torque_bounds(t, (-0.34, 0.34))
    assert b["Fu_max_n"] == pytest.approx(57.40, abs=0.01)
    assert b["Fu_min_n"] == pytest.approx(-45.32, abs=0.01)
    assert b["tau_r_max_nm"] == pytest.approx(17.46, abs=0.01)
    assert b["tau_r_min_nm"] == pytest.approx(-17.46, abs=0.01)


def test_allocation_eq26_left_thruster_turns_to_starboard():
    B = allocation_matrix((-0.34, 0.34))
    tau = B @ [10.0, 0.0]
    assert tau[0] == 10.0 and tau[1] == 0.0
    assert tau[2] == pytest.approx(0.68 / 2 * 10.0)


def test_lag_discrete_continuous_round_trip():
    assert lag_time_constant_s(lag_alpha(0.35, 0.2), 0.2) == pytest.approx(0.35)
    with pytest.raises(ValueError):
        lag_time_constant_s(1.2, 0.2)


def test_current_and_wind_directions():
    env = Environment(current_speed_m_s=0.5, current_dir_deg=90.0)  # flowing east
    nu_c = current_body(0.0, env.current_ned)
    np.testing.assert_allclose(nu_c, [0.0, 0.5, 0.0], atol=1e-12)
    load = WindLoad(0.3, 0.45, 1.28, 0.6, 0.8, 0.1)
    head = wind_force(load, 0.0, np.zeros(3), Environment(wind_speed_m_s=10, wind_dir_deg=0).wind_ned)
    assert head[0] < 0 and abs(head[1]) < 1e-9
    beam = wind_force(load, 0.0, np.zeros(3), Environment(wind_speed_m_s=10, wind_dir_deg=90).wind_ned)
    assert beam[1] < 0  # wind from the east pushes the vessel west (to port when heading north)


def test_current_drift_reaches_water_velocity():
    hydro = HydroModel(RigidBody(20, 0, 0, 2).matrix(), AddedMass(-2, -10, 0, 0, -1).matrix(),
                       Damping(Xu=-5, Yv=-10, Nr=-2), environment=Environment(0.4, 30.0))
    sol = solve_ivp(lambda t, nu: acceleration(hydro, 0.0, nu, np.zeros(3)), (0, 60), np.zeros(3), rtol=1e-9)
    np.testing.assert_allclose(sol.y[:2, -1], 0.4 * np.array([np.cos(np.pi / 6), np.sin(np.pi / 6)]), atol=1e-4)


def test_energy_conserved_by_analytic_model_without_damping():
    hydro = HydroModel(RigidBody(23.8, 0, 0, 0.805).matrix(), CYBERSHIP_M - RigidBody(23.8, 0, 0, 0.805).matrix(),
                       Damping(), terms=Terms().only("added_mass", "added_mass_coriolis"))
    nu0 = np.array([1.0, 0.3, 0.5])
    sol = solve_ivp(lambda t, nu: acceleration(hydro, 0.0, nu, np.zeros(3)), (0, 60), nu0, rtol=1e-11, atol=1e-12)
    e = [kinetic_energy(hydro.M, nu) for nu in sol.y.T]
    assert max(abs(np.array(e) / e[0] - 1)) < 1e-7
