"""Identification of a propeller-and-rudder ship: its MMG fit groups and beliefs,
simfit on (n, δ) inputs, the measured wind as a known input, and `twin identify --wind-measured`."""
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import twin.vessel as vessel_mod
from twin.errors import TwinError
from twin.api import simulate_run
from twin.drive import InputSeries
from twin.effects.coefficients import FIT_GROUPS, MMG_FIT_GROUPS, belief, coefficients, fit_groups
from twin.fit import simfit
from twin.fit.objective import Objective
from twin.fit.windows import make_windows
from twin.ident.identify import below_friction_line, prepared
from twin.recording import Recording, clean_stream
import twin_command

ESSO = Path(__file__).resolve().parents[2] / "shared" / "data" / "esso"
PWM_ONLY = {"thrust_gain", "reverse_scale", "asymmetry", "lag_s", "delay_s", "deadzone_fwd", "Xu", "Xuu", "Yvv",
            "Nrr", "Yuv", "Nur"}


@pytest.fixture(scope="module")
def esso():
    return vessel_mod.load("esso_osaka")


def test_mmg_groups_are_the_ships_own_each_name_once_with_a_belief(esso):
    assert fit_groups(esso) is MMG_FIT_GROUPS and fit_groups(vessel_mod.load("yellowfish")) is FIT_GROUPS
    names = [n for group in MMG_FIT_GROUPS.values() for n in group]
    assert len(names) == len(set(names)) and not PWM_ONLY & set(names)
    table = coefficients(esso)
    for n in names:
        q, b = table[n], belief(n, esso)
        assert q.lo <= q.get(esso) <= q.hi, n
        # a naval architect's width: linear derivatives within 25-50 %, nothing pinned a priori, nothing unbounded
        assert (0.2 <= b.sigma <= 0.7) if b.log else (0.05 <= b.sigma <= 0.5), (n, b)
    assert belief("mmg_Yv", esso).sigma == 0.25 and belief("mmg_Nr", esso).sigma == 0.3
    assert not any(n.startswith("mmg_") for n in coefficients(vessel_mod.load("yellowfish")))


def test_an_mmg_quantity_writes_its_own_coefficient_only(esso):
    q = coefficients(esso)["mmg_Nr"]
    other = q.put(esso, -0.07)
    assert other.mmg.hull.Nr == -0.07 and esso.mmg.hull.Nr == -0.049
    assert other.mmg.hull.Yv == esso.mmg.hull.Yv and other.mmg.rudder == esso.mmg.rudder
    eps = coefficients(esso)["mmg_epsilon"].put(esso, 1.3)
    assert eps.mmg.rudder.epsilon == 1.3 and eps.mmg.hull == esso.mmg.hull


def test_the_sway_added_mass_a_fit_moves_leaves_the_surge_force_of_a_turn_alone(esso):
    """MMG eq. 4/7: m_y and X'_vr multiply the same v·r in surge, so fitting m_y moves X'_vr back
    (coefficients.mmg_sway_added_mass): the sway row's inertia changes, a turn's speed loss does not."""
    from twin.effects.coefficients import added_mass
    from twin.engine.mjcf import compile_vessel
    from twin.physics.hydrodynamics import relative_acceleration

    def accel(v):  # 0.6 m/s ahead, drifting and turning, 10 rps, 20° of rudder
        return relative_acceleration(compile_vessel(v).hydro(), 0.0, np.array([0.6, -0.05, 0.04]), np.zeros(3),
                                     controls=(10.0, np.radians(20.0)))

    heavier = esso.added_mass.Yvdot * 3.0
    tied, untied = coefficients(esso)["Yvdot"].put(esso, heavier), added_mass("Yvdot").put(esso, heavier)
    assert tied.added_mass.Yvdot == untied.added_mass.Yvdot == heavier
    nd = 0.5 * esso.mmg.rho_kg_m3 * esso.mmg.lpp_m ** 2 * esso.mmg.draft_m
    assert tied.mmg.hull.Xvr == pytest.approx(esso.mmg.hull.Xvr + 2.0 * esso.added_mass.Yvdot / nd)
    a0, a_tied, a_untied = accel(esso), accel(tied), accel(untied)
    assert a_tied[0] == pytest.approx(a0[0], rel=1e-9, abs=1e-12)
    assert abs(a_untied[0] - a0[0]) > 0.1 * abs(a0[0])  # the coupling the tie removes is not small
    assert abs(a_tied[1] - a0[1]) > 0.05 * abs(a0[1])  # the sway row feels the heavier added mass
    # the library's added-mass effect (twin dataset's truths, the diagnosis's candidate) ties it the same way
    from twin.effects import apply_effects
    truth = apply_effects(esso, ["added_mass=Yvdot:3"])
    assert truth.added_mass.Yvdot == pytest.approx(heavier) and truth.mmg.hull.Xvr == pytest.approx(tied.mmg.hull.Xvr)
    assert accel(truth)[0] == pytest.approx(a0[0], rel=1e-9, abs=1e-12)
    with pytest.raises(TwinError, match="mmg_Xvr"):  # fitted together, the second would undo the tie
        simfit.check_names(esso, ("Yvdot", "mmg_Xvr"), "mass")
    boat = vessel_mod.load("yellowfish")  # no X'_vr on a PWM boat: its Yvdot writes itself only
    moved = coefficients(boat)["Yvdot"].put(boat, 2.0 * boat.added_mass.Yvdot)
    assert moved.damping == boat.damping and moved.added_mass.Nrdot == boat.added_mass.Nrdot


def synthetic_turns(truth, duration_s: float = 60.0) -> Recording:
    """A recording of `truth` driven by open-loop (n, δ): rudder ±25° every 15 s, 10 then 7 rps."""
    ts = np.arange(0.0, duration_s, 0.1)
    n = np.where(ts < duration_s / 2, 10.0, 7.0)
    delta = np.radians(np.where((ts // 15) % 2 == 0, 25.0, -25.0))
    run = simulate_run(truth, inputs=InputSeries(ts, np.column_stack([n, delta]), "propeller_rudder"),
                       duration_s=duration_s - 0.1).run
    rec = Recording(source="synthetic_turns.csv", kind="csv")
    rec.gnss = clean_stream("gnss", run.t, {"north_m": run.eta[:, 0], "east_m": run.eta[:, 1]}, rec.dropped)
    rec.meta["positions"] = "body origin"
    rec.heading = clean_stream("heading", run.t, {"psi_rad": run.eta[:, 2]}, rec.dropped)
    rec.imu = clean_stream("imu", run.t, {"yaw_rate_rads": run.nu[:, 2]}, rec.dropped)
    rec.prop_rudder = clean_stream("prop_rudder", ts, {"n_rps": n, "delta_rad": delta}, rec.dropped)
    return rec


def test_simfit_recovers_the_yaw_damping_of_a_propeller_rudder_ship(esso):
    q = coefficients(esso)["mmg_Nr"]
    truth = q.put(esso, -0.049 * 1.4)  # 40 % more yaw damping than the prior
    preps = prepared([synthetic_turns(truth)], esso)
    assert preps[0].input_kind == "propeller_rudder"
    fit = simfit.fit(esso, preps, ("mmg_Nr",), window_s=10.0, stride_s=10.0, max_evaluations=8)
    assert fit.estimates[0].value == pytest.approx(-0.049 * 1.4, rel=0.03)
    assert fit.cost_after < 0.05 * fit.cost_before


def test_a_direct_thruster_vessel_cannot_be_fitted():
    cyber = vessel_mod.load("cybership1")
    with pytest.raises(Exception, match="cannot drive it"):
        simfit.check_kind(cyber)


def esso_csv_without_wind(path: Path) -> Path:
    t = np.arange(0.0, 60.0, 0.1)
    rows = ["t [s],x_position_mid [m],y_position_mid [m],psi_hat [rad],r_angvelo [rad/s],n_prop [rps],"
            "delta_rudder [rad]"]
    rows += [f"{x:.1f},{0.5 * x:.3f},0.0,0.0,0.0,10,0.0" for x in t]
    path.write_text("\n".join(rows) + "\n")
    return path


def test_identify_wind_measured_without_a_wind_stream_is_a_one_line_error(tmp_path):
    csv = esso_csv_without_wind(tmp_path / "no_wind.csv")
    done = twin_command.twin("identify", str(csv), "--vessel", "esso_osaka",
                             "--out", str(tmp_path / "out.json"), "--wind-measured")
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and "no measured wind" in done.stderr
    assert not (tmp_path / "out.json").exists()


@pytest.mark.skipif(not ESSO.is_dir(), reason="no ../shared/data/esso")
def test_the_measured_wind_enters_the_fit_objective(esso):
    from twin.formats import read_recording

    rec = read_recording(ESSO / "turn_14-Oct-2020_14_29_49.csv")
    preps = prepared([rec], esso)
    windows = make_windows(preps, 30.0, 30.0, min_length_s=30.0)[:6]
    q = coefficients(esso)["mmg_Nr"]
    calm = Objective(esso, [q], preps, windows)
    gusty = Objective(esso, [q], preps, windows, wind="measured")
    x = calm.x_prior
    cost_calm, cost_gusty = (float(np.sum(o.residuals(x) ** 2)) for o in (calm, gusty))
    # the measured wind explains part of this test's sway: the cost falls by more than a tenth
    assert cost_gusty < 0.9 * cost_calm


@pytest.mark.skipif(not ESSO.is_dir(), reason="no ../shared/data/esso")
def test_twin_identify_on_the_ship_with_its_measured_wind(tmp_path):
    out = tmp_path / "esso.json"
    done = twin_command.twin("identify", str(ESSO / "turn_14-Oct-2020_14_29_49.csv"),
                             "--vessel", "esso_osaka", "--out", str(out), "--params", "mmg_Nr,mmg_epsilon",
                             "--beliefs", "0.1", "--max-evaluations", "3", "--window", "30", "--wind-measured",
                             "--greybox", "--json", str(tmp_path / "report.json"))
    assert done.returncode == 0, done.stderr
    assert "grey-box models PWM thrusters: skipped" in done.stderr + done.stdout
    identified = vessel_mod.load(str(out))
    assert identified.thrusters.kind == "propeller_rudder"
    # a yaw damping a naval architect would still sign: within a factor of 2 of KVLCC2's −0.049
    assert -0.1 < identified.mmg.hull.Nr < -0.025
    import json

    report = json.loads((tmp_path / "report.json").read_text())
    assert report["fit"]["wind"] == "measured" and report["expected_on_a_new_run"]["pooled"]["u"]["r2"] > 0.5
    # the twin says how it was fitted, and evaluate reminds a user who scores it otherwise
    assert report["wind"] == "measured" and "on a new run expect (with its measured wind)" in done.stdout
    assert identified.uncertainty["fitted_on"]["wind"] == "measured"
    assert "measured wind a known input" in identified.sources["identification"]
    calm = twin_command.twin("evaluate", str(ESSO / "turn_14-Oct-2020_14_29_49.csv"), "--model", str(out))
    assert calm.returncode == 0, calm.stderr
    assert "identified with the measured wind" in calm.stderr + calm.stdout
    assert "with the measured wind" not in calm.stdout
    # the replay and the diagnosis remind the user too; a log of another kind of vessel gets the error alone
    seen = twin_command.twin("view", str(ESSO / "turn_14-Oct-2020_14_29_49.csv"), "--model", str(out), "--sim",
                             "--out", str(tmp_path / "v.rrd"))
    assert seen.returncode == 0 and "identified with the measured wind" in seen.stderr, seen.stderr
    boat = next((ESSO.parent / "blueboat").glob("*.csv"), None)
    if boat is not None:
        wrong = twin_command.twin("evaluate", str(boat), "--model", str(out))
        assert wrong.returncode == 2 and "identified with the measured wind" not in wrong.stderr
        assert "is driven by propeller speed and rudder angle" in wrong.stderr


def test_evaluate_splits_a_slow_ships_free_runs_by_manoeuvre_at_its_own_window(esso):
    """A slow ship's misfit by manoeuvre is read on free runs as long as its fit's (30 s), a small boat's on
    10 s; a twin written by identify carries the horizon its envelope counted."""
    from types import SimpleNamespace

    from twin.ident.identify import manoeuvre_horizon_s

    assert manoeuvre_horizon_s(esso) == 30.0 and manoeuvre_horizon_s(vessel_mod.load("blueboat")) == 10.0
    assert manoeuvre_horizon_s(esso, SimpleNamespace(horizon_s=20.0)) == 20.0


def test_an_identified_resistance_below_its_friction_line_is_told_with_the_factor_it_is_carried_at(esso):
    """identify's notes say when an MMG hull's R'_0 fell below its friction line (physics/mmg.py): a user
    running faster reads that the line carries it in proportion, at the factor given."""
    shipped = esso
    assert below_friction_line(shipped) is None  # the prior sits on its line
    low = replace(shipped, mmg=replace(shipped.mmg, hull=replace(shipped.mmg.hull, R0=0.01)))
    told = below_friction_line(low)
    assert told is not None and "R'_0 0.01 lies below its friction line at 0.35 m/s (0.0218)" in told
    factor = float(told.split("(factor ")[1].split(",")[0])
    assert factor == pytest.approx(0.01 / 0.0218 * shipped.mmg.friction_factor, rel=0.01)
    assert below_friction_line(replace(low, mmg=replace(low.mmg, friction_factor=0.0))) is None
    assert below_friction_line(vessel_mod.load("blueboat")) is None
