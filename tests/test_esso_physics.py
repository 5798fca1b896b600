"""The MMG standard method and Fujiwara's wind loads (physics/mmg.py, physics/fujiwara.py) against the
equations written out by hand here, in the paper's own form, on the Esso Osaka vessel's numbers."""
import json
import math
from dataclasses import replace

import numpy as np
import pytest

import twin.vessel as vessel_mod
from twin.engine.mjcf import compile_vessel
from twin.errors import TwinError
from twin.physics import fujiwara, mmg
from twin.physics.environment import WindLoad, wind_force
from twin.physics.hydrodynamics import Terms, mmg_forces


@pytest.fixture(scope="module")
def esso():
    return compile_vessel(vessel_mod.load("esso_osaka"))


def _p(esso) -> dict:
    """The packed parameters by name."""
    return dict(zip(mmg.FIELDS, esso.hydro().mmg))


def _by_hand(p: dict, u, v, r, n, delta):
    """[MMG-2015] as printed (valid for u > 0, n > 0, U above the floor), R'_0 on the friction line."""
    L, d, rho = p["L"], p["d"], p["rho"]
    U = math.hypot(u, v)
    vp, rp = v / U, r * L / U
    q = 0.5 * rho * L * d * U**2
    # R'_0 carried along the ITTC-1957 friction line from its reference speed (the twin's extension, module
    # docstring of physics/mmg.py; F = 0 is the standard's constant R'_0)
    r0 = p["R0"] + p["F_fric"] * (0.075 / (math.log10(U * p["L_nu"]) - 2.0) ** 2 - p["cf_ref"])
    X_H = q * (-r0 + p["Xvv"] * vp**2 + p["Xvr"] * vp * rp + p["Xrr"] * rp**2 + p["Xvvvv"] * vp**4)
    Y_H = q * (p["Yv"] * vp + p["Yr"] * rp + p["Yvvv"] * vp**3 + p["Yvvr"] * vp**2 * rp + p["Yvrr"] * vp * rp**2
               + p["Yrrr"] * rp**3)
    N_H = q * L * (p["Nv"] * vp + p["Nr"] * rp + p["Nvvv"] * vp**3 + p["Nvvr"] * vp**2 * rp + p["Nvrr"] * vp * rp**2
                   + p["Nrrr"] * rp**3)
    beta = math.atan(-v / u)
    beta_p = beta - p["xP_nd"] * rp
    c2 = p["C2_plus"] if beta_p > 0 else p["C2_minus"]
    one_minus_w = (1 - p["wP0"]) * (1 + (1 - math.exp(-p["C1"] * abs(beta_p))) * (c2 - 1))
    D = p["D_P"]
    J = u * one_minus_w / (n * D)
    K_T = p["k0"] + p["k1"] * J + p["k2"] * J**2
    T = rho * n**2 * D**4 * K_T
    X_P = (1 - p["tP"]) * T
    eta, eps, kappa = p["eta"], p["epsilon"], p["kappa"]
    u_R = eps * u * one_minus_w * math.sqrt(eta * (1 + kappa * (math.sqrt(1 + 8 * K_T / (math.pi * J**2)) - 1))**2
                                            + (1 - eta))
    beta_R = beta - p["lR_nd"] * rp
    gamma = p["gamma_minus"] if beta_R < 0 else p["gamma_plus"]
    v_R = U * gamma * beta_R
    alpha_R = delta - math.atan(v_R / u_R)
    F_N = 0.5 * rho * p["A_R"] * (u_R**2 + v_R**2) * p["f_alpha"] * math.sin(alpha_R)
    X_R = -(1 - p["tR"]) * F_N * math.sin(delta)
    Y_R = -(1 + p["aH"]) * F_N * math.cos(delta)
    N_R = -(p["xR_m"] + p["aH"] * p["xH_m"]) * F_N * math.cos(delta)
    return {"hull": (X_H, Y_H, N_H), "propeller": (X_P, 0.0, 0.0), "rudder": (X_R, Y_R, N_R), "T": T, "F_N": F_N}


STATES = [(0.35, -0.04, 0.03, 10.0, math.radians(20)), (0.2, 0.05, -0.04, 8.0, math.radians(-35)),
          (0.3, 0.0, 0.0, 10.0, 0.0), (0.12, -0.045, 0.044, 10.0, math.radians(35))]


@pytest.mark.parametrize("state", STATES)
def test_mmg_hull_propeller_rudder_equal_the_equations(esso, state):
    u, v, r, n, delta = state
    p, hydro = _p(esso), esso.hydro()
    ref = _by_hand(p, u, v, r, n, delta)
    nu = np.array([u, v, r])
    for term, name in (("mmg_hull", "hull"), ("propeller", "propeller"), ("rudder", "rudder")):
        got = mmg_forces(hydro.with_terms(Terms().only(term)), nu, (n, delta))
        np.testing.assert_allclose(got[:3], ref[name], rtol=1e-12, atol=1e-12, err_msg=name)
    got = mmg_forces(hydro, nu, (n, delta))
    np.testing.assert_allclose(got[3:], (ref["T"], ref["F_N"]), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(got[:3], np.sum([ref[k] for k in ("hull", "propeller", "rudder")], axis=0), rtol=1e-12)


def test_the_vessel_numbers_are_the_ones_the_sources_name(esso):
    p = _p(esso)
    assert p["f_alpha"] == pytest.approx(6.13 * 1.539 / (1.539 + 2.25))  # Fujii, [MMG-2015 eq. 20]
    assert p["eta"] == pytest.approx(0.084 / math.sqrt(0.01063 * 1.539))  # D_P / H_R = 0.657
    assert p["xP_nd"] == pytest.approx(-0.48) and p["xR_m"] == pytest.approx(-1.5)  # the MJCF's sites
    assert p["xH_m"] == pytest.approx(-0.464 * 3.0)
    M = esso.hydro().M
    q2, q4 = 0.5 * 998 * 3.0**2 * 0.201, 0.5 * 998 * 3.0**4 * 0.201
    m, xg, izg = 244.6, 0.094, 244.6 * 0.75**2
    np.testing.assert_allclose(np.diag(M), [m + 0.022 * q2, m + 0.223 * q2, izg + m * xg**2 + 0.011 * q4], rtol=1e-4)
    assert M[1, 2] == pytest.approx(m * xg)  # MMG eq. 4: x_G m in Y and N


def test_rudder_to_starboard_turns_to_starboard_and_the_propeller_pushes_ahead(esso):
    hydro = esso.hydro()
    for delta in (0.1, 0.35, 0.6):
        X, Y, N, T, F_N = mmg_forces(hydro.with_terms(Terms().only("rudder")), np.array([0.3, 0.0, 0.0]), (10, delta))
        assert N > 0 and Y < 0 and F_N > 0 and X < 0
    assert mmg_forces(hydro.with_terms(Terms().only("propeller")), np.zeros(3), (10.0, 0.0))[0] > 0
    assert mmg_forces(hydro.with_terms(Terms().only("propeller")), np.array([0.3, 0, 0]), (-10.0, 0.0))[0] < 0


def test_outside_the_standard_the_forces_stay_finite_continuous_and_resist(esso):
    hydro, p = esso.hydro(), _p(esso)
    for nu in ([0.0, 0.0, 0.05], [0.0, 0.0, 0.0], [-0.2, 0.1, -0.02], [0.0, 0.3, 0.0], [1e-9, 0.0, 0.3]):
        assert np.all(np.isfinite(mmg_forces(hydro, np.array(nu), (10.0, 0.3))))
    hull = hydro.with_terms(Terms().only("mmg_hull"))
    for u in (0.3, -0.3):  # the resistance opposes the motion ahead and astern
        assert mmg_forces(hull, np.array([u, 0.0, 0.0]))[0] * u < 0
    # broadside a fore-aft symmetric hull is pushed straight back: no surge force, no yaw
    broadside = mmg_forces(hull, np.array([0.0, 0.2, 0.0]))
    assert broadside[0] == 0.0 and broadside[2] == 0.0 and broadside[1] < 0
    # astern the hull is the forward one mirrored fore and aft: at (−u, v, −r) X and N reverse, Y stays
    # (a backing hull with a drift yaws as the mirror image of one going ahead, Munk moment and all)
    for u, v, r in ((0.3, 0.05, 0.02), (0.2, -0.08, -0.03), (0.05, 0.1, 0.01), (0.15, 0.02, -0.06)):
        ahead, astern = mmg_forces(hull, np.array([u, v, r])), mmg_forces(hull, np.array([-u, v, -r]))
        np.testing.assert_allclose(astern[:3], [-ahead[0], ahead[1], -ahead[2]], rtol=1e-12, atol=1e-12)
    assert abs(mmg_forces(hull, np.array([-0.2, 0.05, 0.0]))[2]) > 0.1  # the mirror is not zero
    rudder = hydro.with_terms(Terms().only("rudder"))
    below, above = (mmg_forces(rudder, np.array([u, 0.0, 0.0]), (10.0, 0.3))[4] for u in (-1e-9, 1e-9))
    assert below == pytest.approx(above, rel=1e-6)  # u_R continuous at u = 0 (the race alone)
    u, r, un = 0.01, 0.05, p["U_min"]  # below the floor U_nd = low_speed_m_s stands in for U in v', r', U²
    rp = r * 3.0 / un
    assert mmg_forces(hull, np.array([u, 0.0, r]))[1] == pytest.approx(
        0.5 * 998 * 3.0 * 0.201 * un**2 * (p["Yr"] * rp + p["Yrrr"] * rp**3), rel=1e-12)
    clipped = mmg_forces(hydro, np.array([0.3, 0.0, 0.0]), (25.0, 1.2))  # the vessel's bounds: 10 rps, 40°
    np.testing.assert_allclose(clipped, mmg_forces(hydro, np.array([0.3, 0.0, 0.0]), (10.0, math.radians(40))))


def test_fujiwara_regression_gives_the_published_simulator_coefficients(esso):
    # [NAOE-MMG-SIM]'s XX0..NN3 for the Esso 3 m model (research note §2.2)
    published = (-0.010466, -0.821992, 0.060274, 0.044558, 1.058172, 0.002321, -0.015293, -0.030728, 0.104116,
                 -0.000880)
    w = esso.vessel.wind_regression
    np.testing.assert_allclose(fujiwara.regression(w), published, atol=1e-6)
    np.testing.assert_allclose(w.coefficients, fujiwara.regression(w), atol=1e-9)  # the vessel file stores them


def test_fujiwara_signs_and_its_first_harmonics_are_the_simple_wind_load(esso):
    p = fujiwara.pack(esso.vessel.wind_regression)
    q = 0.5 * 1.166 * 2.0**2
    X, Y, N = fujiwara.wind_force(p, 1.0, 0.0, 0.0, 0.0, -2.0, 0.0)  # ship heading north, wind from north: head
    assert X == pytest.approx(q * 0.13544 * sum(p[4:8])) and X < 0 and Y == pytest.approx(0.0, abs=1e-12)
    X, Y, N = fujiwara.wind_force(p, 1.0, 0.0, 0.0, 0.0, 0.0, 2.0)  # wind from the west: from port
    assert Y > 0 and Y == pytest.approx(q * 0.52038 * (p[8] - p[9] + p[10]))
    s = math.sqrt(0.5)
    assert fujiwara.wind_force(p, 1.0, 0.0, 0.0, 0.0, -2 * s, 2 * s)[2] > 0  # from the port bow: bow turns away
    # only X1, Y1, N2 (and the twin's air density): environment.WindLoad with c_x = −X1, c_y = Y1, c_n = N2
    only = np.zeros_like(p)
    only[:4] = (0.3, 0.5, 1.3, 1.225)
    only[5], only[8], only[12] = -0.7, 0.9, 0.12
    load = WindLoad(0.3, 0.5, 1.3, 0.7, 0.9, 0.12)
    rng = np.random.default_rng(7)
    for _ in range(20):
        psi, u, v, wn, we = rng.uniform(-3, 3, 5)
        np.testing.assert_allclose(fujiwara.wind_force(only, math.cos(psi), math.sin(psi), u, v, wn, we),
                                   wind_force(load, psi, np.array([u, v, 0.0]), np.array([wn, we])), atol=1e-12)


def test_munk_moment_is_left_to_the_hull_and_the_energy_balance_says_so(esso):
    """C_A without its yaw row (MMG eq. 4): with added mass and its Coriolis terms alone the kinetic energy
    changes at (m_y − m_x)·u·v·r, the Munk moment's power; the Fossen C_A (a twin-thruster vessel) conserves it."""
    from twin.physics.hydrodynamics import acceleration

    hydro = esso.hydro(Terms().only("added_mass", "added_mass_coriolis"))
    fossen = replace(hydro, munk_moment=True)
    mx, my = hydro.M_A[0, 0], hydro.M_A[1, 1]
    rng = np.random.default_rng(3)
    for _ in range(10):
        nu = rng.uniform(-0.4, 0.4, 3)
        power = nu @ hydro.M @ acceleration(hydro, 0.3, nu, np.zeros(3))
        assert power == pytest.approx((my - mx) * nu[0] * nu[1] * nu[2], rel=1e-9, abs=1e-12)
        assert nu @ fossen.M @ acceleration(fossen, 0.3, nu, np.zeros(3)) == pytest.approx(0.0, abs=1e-12)


def test_hull_resistance_and_rudder_drag_dissipate_in_straight_motion(esso):
    hydro = esso.hydro(Terms().only("mmg_hull", "rudder"))
    for u in (0.05, 0.2, 0.4, -0.1, -0.3):
        nu = np.array([u, 0.0, 0.0])
        assert nu @ mmg_forces(hydro, nu, (0.0, 0.4))[:3] < 0


def test_vessel_file_checks_the_ship_description(tmp_path):
    import json

    data = json.loads(vessel_mod.load("esso_osaka").path.read_text())
    data["mjcf"] = str(vessel_mod.MODEL_DIR / "esso_osaka.xml")

    def load(change):
        d = json.loads(json.dumps(data))
        change(d)
        path = tmp_path / "v.json"
        path.write_text(json.dumps(d))
        return vessel_mod.load(path)

    assert load(lambda d: None).mmg.hull.Nr == -0.049
    with pytest.raises(TwinError, match="go together"):
        load(lambda d: d.pop("mmg"))
    with pytest.raises(TwinError, match="go together"):
        load(lambda d: d["thrusters"].update(kind="direct"))
    with pytest.raises(TwinError, match="mmg.propeller.diameter_m must be positive"):
        load(lambda d: d["mmg"]["propeller"].update(diameter_m=0.0))
    with pytest.raises(TwinError, match="must be a number"):
        load(lambda d: d["mmg"]["hull"].update(Yv="big"))
    with pytest.raises(TwinError, match="unknown mmg.rudder field"):
        load(lambda d: d["mmg"]["rudder"].update(chord=0.1))
    with pytest.raises(TwinError, match="10 numbers"):
        load(lambda d: d["wind_regression"].update(coefficients=[1.0, 2.0]))
    computed = load(lambda d: d["wind_regression"].update(coefficients=None)).wind_regression.coefficients
    np.testing.assert_allclose(computed, data["wind_regression"]["coefficients"], atol=1e-9)
    saved = vessel_mod.save(vessel_mod.load("esso_osaka"), tmp_path / "copy.json")
    again = vessel_mod.load(saved)
    assert again.mmg == vessel_mod.load("esso_osaka").mmg and again.thrusters.rudder_max_deg == 40.0
    assert "rps_max" not in json.loads(vessel_mod.save(vessel_mod.load("yellowfish"),
                                                       tmp_path / "y.json").read_text())["thrusters"]


def test_a_backing_propeller_swings_the_bow_to_starboard_and_only_when_backing(esso):
    """The astern side force (physics/mmg.py; Hachii's form, the NAOE Esso 3 m coefficients): written out
    by hand at J_s = u/(nD_P) in each of its three pieces, continuous at both knots, N > 0 (the bow to
    starboard, as a right-handed single screw backing) down to where the published lowest piece turns
    over, finite for any n, and nothing for n ≥ 0."""
    hydro, p = esso.hydro(), _p(esso)
    prop = hydro.with_terms(Terms().only("propeller"))
    a = [p[f"ay{i}"] for i in range(5)]
    b = [p[f"bn{i}"] for i in range(5)]
    assert (a[4], b[4]) == (-5.58e-4, 2.25e-4)  # NAOE's set for this model: stern to port, bow to starboard
    n, D, L, d = -7.0, p["D_P"], p["L"], p["d"]
    q = 0.5 * 998 * L * d * (n * D) ** 2
    pieces = {0.0: (a[4], b[4]), 0.02: (a[4], b[4]),  # J_s above −0.06, between the knots, below −0.35
              0.15: (a[0] + a[1] * 0.15 / (n * D), b[0] + b[1] * 0.15 / (n * D)),
              0.4: (a[2] + a[3] * 0.4 / (n * D), b[2] + b[3] * 0.4 / (n * D))}
    for u, (ka, kb) in pieces.items():
        X, Y, N, _, _ = mmg_forces(prop, np.array([u, 0.0, 0.0]), (n, 0.0))
        assert Y == pytest.approx(q * ka, rel=1e-9) and N == pytest.approx(q * L * kb, rel=1e-9), u
        assert N > 0
    for js in (mmg.JS_SYN, mmg.JS_SYN0):  # continuous where the pieces meet (to the published 3 digits)
        u = js * n * D
        lo, hi = (mmg_forces(prop, np.array([u * f, 0.0, 0.0]), (n, 0.0))[1:3] for f in (1 - 1e-7, 1 + 1e-7))
        np.testing.assert_allclose(lo, hi, rtol=2e-3)
    js = -1.0  # past where the published lowest piece changes sign: the bow to port (module docstring)
    N = mmg_forces(prop, np.array([js * n * D, 0.0, 0.0]), (n, 0.0))[2]
    assert N == pytest.approx(q * L * (b[2] + b[3] * js), rel=1e-9) and N < 0
    assert np.all(np.isfinite(mmg_forces(prop, np.array([0.2, 0.0, 0.0]), (-1e-320, 0.0))))  # no tiny n divides
    for n_ahead in (0.0, 5.0):
        assert mmg_forces(prop, np.array([0.1, 0.0, 0.0]), (n_ahead, 0.0))[1:3] == pytest.approx((0.0, 0.0), abs=1e-12)


def test_an_mmg_file_without_a_side_force_is_written_as_before(tmp_path):
    """The astern side force's coefficients are written only where set (dataset fingerprints of other
    MMG vessels stay what they were) and read back."""
    ship = vessel_mod.load("esso_osaka")
    assert ship.to_dict()["mmg"]["propeller"]["astern_side_n"][4] == 2.25e-4
    bare = replace(ship, mmg=replace(ship.mmg, propeller=replace(ship.mmg.propeller, astern_side_y=(0.0,) * 5,
                                                                  astern_side_n=(0.0,) * 5)))
    assert not {"astern_side_y", "astern_side_n"} & set(bare.to_dict()["mmg"]["propeller"])
    again = vessel_mod.load(str(vessel_mod.save(ship, tmp_path / "esso.json")))
    assert again.mmg.propeller.astern_side_y == ship.mmg.propeller.astern_side_y


def _hull_forces(vessel, u, v, r, domain_deg=None):
    ship = vessel if domain_deg is None else replace(vessel, mmg=replace(vessel.mmg, drift_domain_deg=domain_deg))
    return mmg_forces(compile_vessel(ship).hydro().with_terms(Terms().only("mmg_hull")), np.array([u, v, r]))[:3]


def test_beyond_its_drift_domain_the_hull_polynomial_continues_along_its_tangent(esso, tmp_path):
    """Within 30° of drift the standard's polynomial as it is; beyond, each power of v' along its
    tangent at the edge (value and slope kept), so the broadside sway force is Y'_v + Y'_vvv·s²(3 − 2s),
    s = sin 30°, not Y'_v + Y'_vvv."""
    ship, p = esso.vessel, _p(esso)
    assert ship.mmg.drift_domain_deg == 30.0 and p["v_domain"] == pytest.approx(0.5)
    inside = (0.3, -0.3 * math.tan(math.radians(25)), 0.02)  # 25° of drift
    np.testing.assert_allclose(_hull_forces(ship, *inside), _hull_forces(ship, *inside, domain_deg=90.0), rtol=1e-12)
    U, q = 0.2, 0.5 * p["rho"] * p["L"] * p["d"]
    broadside = _hull_forces(ship, 0.0, U, 0.0)
    assert broadside[1] == pytest.approx(q * U**2 * (p["Yv"] + p["Yvvv"] * 0.25 * 2.0), rel=1e-12)
    assert _hull_forces(ship, 0.0, U, 0.0, domain_deg=90.0)[1] == pytest.approx(q * U**2 * (p["Yv"] + p["Yvvv"]))
    # at 60° with a yaw rate: v'², v'³ of the yaw moment replaced by their tangents (f = 1 up to 60°)
    u, v, r = U * math.cos(math.radians(59)), -U * math.sin(math.radians(59)), 0.01
    vp, rp = v / U, r * p["L"] / U
    v2, v3, _ = mmg.drift_powers(vp, 0.5)
    assert (v2, v3) == pytest.approx((0.5 * (2 * abs(vp) - 0.5), -0.25 * (3 * abs(vp) - 1.0)))
    f = min(2 * u / U, 1.0)
    N_H = q * p["L"] * U**2 * (f * p["Nv"] * vp + p["Nr"] * rp + f * p["Nvvv"] * v3 + p["Nvvr"] * v2 * rp
                               + f * p["Nvrr"] * vp * rp**2 + p["Nrrr"] * rp**3)
    assert _hull_forces(ship, u, v, r)[2] == pytest.approx(N_H, rel=1e-12)
    # less yaw damping there than the polynomial as it is gives (N'_vvr < 0 grows as v'² beyond the tests)
    assert abs(_hull_forces(ship, u, v, r)[2]) < abs(_hull_forces(ship, u, v, r, domain_deg=90.0)[2])
    # continuous with its slope across the edge, in every force
    edge = math.radians(30)
    at = [np.array(_hull_forces(ship, U * math.cos(b), -U * math.sin(b), 0.02)) for b in
          (edge - 2e-6, edge - 1e-6, edge + 1e-6, edge + 2e-6)]
    # across the edge (2e-6 rad) each force moves as twice a step beside it: no jump
    np.testing.assert_allclose(at[2] - at[1], 2 * (at[1] - at[0]), rtol=1e-3, atol=1e-12)
    np.testing.assert_allclose((at[1] - at[0]) / 1e-6, (at[3] - at[2]) / 1e-6, rtol=1e-3, atol=1e-6)
    # the vessel file keeps its domain, refuses one outside (0, 90], and a file written without one
    # (its hull identified with the polynomial as it is) keeps the polynomial as it is
    wide = replace(ship, mmg=replace(ship.mmg, drift_domain_deg=90.0))
    assert ship.to_dict()["mmg"]["drift_domain_deg"] == 30.0
    assert vessel_mod.load(str(vessel_mod.save(wide, tmp_path / "wide.json"))).mmg.drift_domain_deg == 90.0
    old = ship.to_dict()
    del old["mmg"]["drift_domain_deg"]
    (tmp_path / "old.json").write_text(json.dumps(old))
    assert vessel_mod.load(str(tmp_path / "old.json")).mmg.drift_domain_deg == 90.0
    data = wide.to_dict()
    data["mmg"]["drift_domain_deg"] = 120.0
    (tmp_path / "bad.json").write_text(json.dumps(data))
    with pytest.raises(TwinError, match="drift_domain_deg must lie in"):
        vessel_mod.load(str(tmp_path / "bad.json"))
