"""The Esso Osaka ship in the engine: native against Python callback, the crosscheck against the analytic
model for every MMG term, the time-varying wind (engine, analytic model, window predictions), the inputs'
plumbing and bounds, and [Relay-ISO] (rudder relay, I-PD heading control) on this ship."""
import math
from dataclasses import replace

import mujoco
import numpy as np
import pytest

import twin.vessel as vessel_mod
from twin import analytic
from twin.drive import InputSeries, WindSeries, read_inputs_csv
from twin.engine import batch, callbacks, native
from twin.engine.limits import beyond_bounds
from twin.engine.mjcf import CompiledVessel, compile_vessel
from twin.engine.sim import simulate
from twin.errors import TwinError
from twin.physics.hydrodynamics import Terms
from twin.prepare import prepare, wind_series
from twin.recording import Recording, Stream
from twin.verify.crosscheck import crosscheck, gusty_wind, ship_cases

SHIP_CASES = {c.name: c for c in ship_cases()}


@pytest.fixture(scope="module")
def esso():
    return compile_vessel(vessel_mod.load("esso_osaka"))


def _turn(t_rudder_s: float = 20.0, rudder_deg: float = 25.0, n: float = 10.0) -> InputSeries:
    return InputSeries(np.array([0.0, t_rudder_s]), np.array([[n, 0.0], [n, math.radians(rudder_deg)]]),
                       "propeller_rudder")


@pytest.mark.parametrize("case", list(SHIP_CASES))
@pytest.mark.parametrize("wind_inputs", [False, True])
def test_native_passive_force_equals_python(esso, case, wind_inputs):
    c = SHIP_CASES[case]
    cv = compile_vessel(replace(esso.vessel, environment=c.environment), wind_inputs=wind_inputs)
    model, hydro = native.with_native_params(cv, c.terms), cv.hydro(c.terms)
    data, ref = mujoco.MjData(model), mujoco.MjData(cv.model)
    rng = np.random.default_rng(2024)
    for _ in range(25):
        q, w = rng.uniform(-5, 5, 3), rng.uniform(-0.6, 0.6, 3) * (1, 1, 0.3)
        ctrl = np.r_[rng.uniform(-12, 12), rng.uniform(-0.8, 0.8), rng.uniform(-3, 3, model.nu - 2)]
        for d in (data, ref):
            d.qpos[:], d.qvel[:], d.ctrl[:] = q, w, ctrl
        with native.installed_native():
            mujoco.mj_forward(model, data)
        with callbacks.installed(cv.model, hydro):
            mujoco.mj_forward(cv.model, ref)
        np.testing.assert_allclose(data.qfrc_passive, ref.qfrc_passive, rtol=1e-9, atol=1e-9)


def test_offsets_of_the_controls_the_callback_reads(esso):
    import ctypes

    model = native.with_native_params(esso, wind_inputs=True)
    data, off = mujoco.MjData(model), native.offsets()
    assert ctypes.c_int64.from_address(model._address + off["m.nu"]).value == model.nu == 4
    assert ctypes.c_int64.from_address(data._address + off["d.ctrl"]).value == data.ctrl.ctypes.data


def test_the_twin_thruster_layout_keeps_its_meaning(yellowfish):
    p = native.pack_params(yellowfish.hydro(), yellowfish.model)
    L = native.LAYOUT
    assert list(p[L["flags"]]) == [1.0, 0.0, -1.0, 0.0] and not p[L["mmg"]].any()


def test_crosscheck_passes_for_every_term_and_each_term_matters():
    results = crosscheck(vessel_mod.load("esso_osaka"))
    assert [r.case for r in results] == list(SHIP_CASES)
    for r in results:
        assert r.passed, r.to_dict()
        if r.case == "input_delay":  # a 0.35-s delay barely moves a slow ship: far more than the two differ
            assert r.effect_m > max(1e4 * r.position_err_m, 0.01), r.to_dict()
        else:
            assert r.effect_m is None or r.effect_m > 100 * 0.01, r.to_dict()


def test_rigid_body_alone_conserves_the_kinetic_energy(esso):
    run = simulate(esso, _turn(), 60.0, nu0=(0.3, 0.05, 0.04), terms=Terms().only())
    M = esso.hydro(Terms().only()).M
    energy = np.einsum("ij,jk,ik->i", run.nu, M, run.nu) / 2
    assert np.ptp(energy) < 1e-8 * energy[0]


def test_a_steady_turn_has_the_sign_of_the_rudder_and_the_tests_magnitude(esso):
    """10 rps, +35°: the Esso tests turn at +1.9..2.6 °/s and drift outward (research note §1.2, §4.1)."""
    run = simulate(esso, _turn(10.0, 35.0), 300.0, nu0=(0.3, 0.0, 0.0))
    r_deg = math.degrees(np.mean(run.nu[-500:, 2]))
    assert 1.9 < r_deg < 3.0 and np.mean(run.nu[-500:, 1]) < 0 and 0.08 < np.mean(run.nu[-500:, 0]) < 0.2
    mirror = simulate(esso, _turn(10.0, -35.0), 300.0, nu0=(0.3, 0.0, 0.0))
    # not quite mirrored: γ_R and the wake's C_2 differ by the side of the drift (MMG standard, KVLCC2)
    assert math.degrees(np.mean(mirror.nu[-500:, 2])) == pytest.approx(-r_deg, rel=0.1)
    assert np.all(np.isfinite(run.thrust_n)) and run.thrust_n[-1, 0] > 0 and run.thrust_n[-1, 1] > 0  # T, F_N


def test_time_varying_wind_engine_equals_analytic_model(esso):
    wind = gusty_wind(200.0, seed=11)
    inputs = _turn()
    eng = simulate(esso, inputs, 150.0, nu0=(0.25, 0.0, 0.0), wind=wind)
    py = simulate(esso, inputs, 150.0, nu0=(0.25, 0.0, 0.0), wind=wind, backend="python")
    ana = analytic.simulate(esso.hydro(), esso.vessel.thrusters, esso.geometry.thruster_y_m, eng.meta["inputs"],
                            eng.t, nu0=np.array([0.25, 0.0, 0.0]), wind=wind)
    np.testing.assert_allclose(eng.eta, py.eta, atol=1e-9)
    assert np.max(np.hypot(*(eng.eta[:, :2] - ana.eta[:, :2]).T)) < 1e-4
    calm = simulate(esso, inputs, 150.0, nu0=(0.25, 0.0, 0.0))
    assert np.max(np.hypot(*(eng.eta[:, :2] - calm.eta[:, :2]).T)) > 1.0  # the wind matters


def test_a_constant_wind_series_is_the_environments_wind(esso):
    windy = CompiledVessel(replace(esso.vessel, environment=replace(esso.vessel.environment, wind_speed_m_s=1.8,
                                                                    wind_dir_deg=135.0)), esso.model, esso.geometry)
    a = simulate(windy, _turn(), 80.0, nu0=(0.25, 0.0, 0.0))
    b = simulate(esso, _turn(), 80.0, nu0=(0.25, 0.0, 0.0), wind=WindSeries.from_speed_direction([0.0], [1.8], [135.0]))
    np.testing.assert_allclose(a.eta, b.eta, atol=1e-9)


def test_batch_rollout_takes_the_wind_as_two_more_controls(esso):
    model = native.with_native_params(esso, wind_inputs=True)
    h, nstep = model.opt.timestep, 2000
    wind = gusty_wind(nstep * h + 1, seed=5)
    controls = np.zeros((1, nstep, 4))
    controls[0, :, :2] = _turn(5.0).commanded_thrust(esso.vessel.thrusters, np.arange(nstep) * h)
    controls[0, :, 2:] = wind.at(np.arange(nstep) * h)
    states, diverged = batch.rollout(model, [batch.initial_state(model, nu0=(0.25, 0, 0))], controls, nthread=1)
    run = simulate(esso, _turn(5.0), nstep * h, nu0=(0.25, 0.0, 0.0), wind=wind, sample_dt_s=h)
    assert not diverged
    np.testing.assert_allclose(states[0, :, 1:4], run.eta[1:], atol=1e-9)
    with pytest.raises(TwinError, match="4 controls"):
        batch.rollout(native.with_native_params(esso), [batch.initial_state(model)], controls)


def _synthetic_recording(esso, wind: WindSeries, duration_s: float = 120.0):
    """A twin run logged as the Esso tests log (10 Hz positions at midship, heading, yaw rate, inputs, true wind)."""
    inputs = InputSeries(np.array([0.0, 15.0, 60.0]), np.array([[10.0, 0.0], [10.0, 0.45], [8.0, -0.3]]),
                         "propeller_rudder")
    run = simulate(esso, inputs, duration_s, nu0=(0.3, 0.0, 0.0), wind=wind)
    air = wind.at(run.t)
    rec = Recording(source="synthetic_esso.csv", kind="csv")
    rec.gnss = Stream(run.t, {"north_m": run.eta[:, 0], "east_m": run.eta[:, 1]})
    rec.heading = Stream(run.t, {"psi_rad": np.angle(np.exp(1j * run.eta[:, 2]))})
    rec.prop_rudder = Stream(run.t, {"n_rps": inputs.at(run.t)[:, 0], "delta_rad": inputs.at(run.t)[:, 1]})
    rec.wind = Stream(run.t, {"speed_m_s": np.hypot(air[:, 0], air[:, 1]),
                              "from_deg": np.degrees(np.arctan2(-air[:, 1], -air[:, 0])) % 360})
    rec.meta["positions"] = "body origin"
    return rec, run


def test_predict_with_the_measured_wind_runs_the_recordings_wind(esso):
    """A window of fit.windows.predict with wind="measured" is sim.simulate from the window's measured start with
    its inputs and the recording's wind series; without it the wind is the vessel's (none)."""
    from twin.fit.windows import Window, predict

    rec, _ = _synthetic_recording(esso, gusty_wind(200.0, seed=8))
    prep = prepare(rec, smoother="none")
    assert prep.input_kind == "propeller_rudder" and prep.wind_ned.shape == (len(prep.t), 2)
    w = Window(0, 300, 300)
    measured, calm = (predict(esso.vessel, [prep], [w], wind=k)[0] for k in ("measured", None))
    sl = slice(w.start, w.start + w.n + 1)
    t0 = prep.t[w.start]
    inputs = InputSeries(prep.t[sl] - t0, prep.pwm[sl], "propeller_rudder")
    start = dict(eta0=(prep.north[w.start], prep.east[w.start], prep.psi[w.start]),
                 nu0=(prep.u[w.start], prep.v[w.start], prep.r[w.start]))
    ref = simulate(esso, inputs, w.n * 0.1, wind=wind_series(prep, sl), **start)
    np.testing.assert_allclose(measured.eta[0, 1:], ref.eta[1:], atol=1e-9)
    np.testing.assert_allclose(calm.eta[0, 1:], simulate(esso, inputs, w.n * 0.1, **start).eta[1:], atol=1e-9)
    assert np.max(np.abs(measured.eta[0, -1, :2] - calm.eta[0, -1, :2])) > 0.1


def test_a_recording_of_the_other_kind_cannot_drive_the_vessel(esso, yellowfish):
    from twin.fit.windows import Window, predict

    rec, _ = _synthetic_recording(esso, gusty_wind(200.0, seed=8), 30.0)
    prep = prepare(rec, smoother="none")
    with pytest.raises(TwinError, match="driven by PWM"):
        predict(yellowfish.vessel, [prep], [Window(0, 0, 50)])
    no_wind = replace(prep, wind_ned=None)
    with pytest.raises(TwinError, match="no measured wind"):
        predict(esso.vessel, [no_wind], [Window(0, 0, 50)], wind="measured")
    with pytest.raises(TwinError, match="driven by propeller speed and rudder angle, not PWM"):
        simulate(esso, InputSeries(np.zeros(1), np.full((1, 2), 1500.0), "pwm"), 1.0)


def test_inputs_csv_and_bounds_of_a_propeller_and_rudder(esso, tmp_path):
    path = tmp_path / "in.csv"
    path.write_text("t,prop_rps,rudder_deg\n0,10,0\n5,12,-45\n")
    series = read_inputs_csv(path)
    assert series.kind == "propeller_rudder" and series.values[1, 1] == pytest.approx(math.radians(-45))
    limits = {(lim.thruster, lim.quantity): lim for lim in beyond_bounds(esso.vessel, series, 10.0)}
    assert limits[("propeller", "speed")].bound == 10.0 and limits[("rudder", "angle")].bound == pytest.approx(-40.0)
    assert "rudder angle requested below" in limits[("rudder", "angle")].text()
    path.write_text("t,prop_rps,rudder_deg,pwm_left,pwm_right\n0,10,0,1500,1500\n")
    with pytest.raises(TwinError, match="not more than one"):
        read_inputs_csv(path)


def test_iso_with_the_rudder_relay_and_the_ipd_heading_step(esso):
    from twin.ident.relay import ipd, iso

    sweep = iso.ship_sweep(esso, [15.0, 30.0], [10.0], duration_s=300.0)
    alpha, beta = iso.linear_model(sweep, 10.0)
    assert sweep.spreads()["alpha"].cv_percent < 10 and 1.0 < alpha / sweep.twin.alpha < 1.4  # sway-coupled yaw
    assert 0.5 < beta / sweep.twin.drag_lin < 1.0
    assert all(r.rudder_deg in (15.0, 30.0) and r.oscillation.periods >= 3 for r in sweep.rows)
    for dof in ("surge", "sway"):
        with pytest.raises(TwinError, match="propeller-and-rudder ship"):
            iso.check_dof("esso_osaka", dof, "propeller_rudder")
    yaw = ipd.DofModel(alpha, beta, ipd.binomial(ipd.SHIP_HEADING_OMEGA_RAD_S))
    loop = ipd.ship_heading_step(esso, yaw, 45.0).loops[0]
    assert 0.95 < loop.iae_ratio < 1.05 and loop.saturated_percent == 0
    assert abs(loop.reference - loop.response[-1]) < math.radians(0.5)
    alloc = ipd.RudderAllocation.at(esso, iso.straight_speed(esso, 10.0), 10.0)
    assert alloc.rudder(alloc.moment(0.3)) == pytest.approx(0.3) and alloc.rudder(1e3) == pytest.approx(alloc.max_rad)


def test_a_simulated_run_written_as_csv_is_replayed_by_its_own_twin(tmp_path):
    from twin import api
    from twin.formats import read_recording
    from twin.simulation import simulate_run

    sim = simulate_run("esso_osaka", scenario="turn", duration_s=60.0)
    path = tmp_path / "run.csv"
    sim.write(path)
    rec = read_recording(path)
    # the turn scenario: 0.6 of rps_max ahead, then 0.3 of rudder_max_deg to starboard from 10 s
    pr = rec.prop_rudder
    assert np.allclose(pr["n_rps"], 6.0)
    assert np.allclose(np.degrees(pr["delta_rad"][pr.t >= 10.05]), 12.0)
    assert np.allclose(pr["delta_rad"][pr.t < 9.95], 0.0)
    metrics = api.evaluate("esso_osaka", [path]).metrics
    for horizon in ("free_run_10s", "free_run_30s"):
        for dof in ("u", "v", "r"):
            assert metrics[horizon][dof]["r2"] > 0.999, (horizon, dof, metrics[horizon][dof])


def test_a_spin_refuses_a_propeller_and_rudder_ship():
    from twin.scale.montecarlo import scenario_mission
    from twin.simulation import simulate_run

    with pytest.raises(TwinError, match=r"esso_osaka.*propeller_rudder.*step, turn, zigzag, random"):
        simulate_run("esso_osaka", scenario="spin", duration_s=5.0)
    with pytest.raises(TwinError, match=r"scenario 'spin'.*esso_osaka"):  # `twin montecarlo --scenario spin`
        scenario_mission(vessel_mod.load("esso_osaka"), "spin", 5.0)
    assert simulate_run("cybership1", scenario="spin", duration_s=5.0).run.nu[-1, 2] != 0.0


@pytest.mark.parametrize("columns,given", [("pwm_left,pwm_right", "pwm_left,pwm_right"),
                                           ("thrust_left,thrust_right", "thrust_left,thrust_right")])
def test_a_ship_given_thruster_inputs_is_told_the_columns_it_takes(tmp_path, columns, given):
    from twin.errors import TwinError
    from twin.simulation import simulate_run

    path = tmp_path / "in.csv"
    path.write_text(f"t,{columns}\n0,1600,1600\n5,1600,1600\n")
    with pytest.raises(TwinError, match=rf"vessel 'esso_osaka' is driven by prop_rps,rudder_deg .*, not {given}$"):
        simulate_run("esso_osaka", inputs=path, duration_s=5.0)


def test_simulate_refuses_to_write_a_ships_run_where_its_inputs_would_be_lost(tmp_path):
    import twin_command

    done = twin_command.twin("simulate", "--vessel", "esso_osaka", "--scenario", "turn", "--duration", "5",
                             "--out", tmp_path / "a.csv", "--out", tmp_path / "a.tlog")
    assert done.returncode == 2 and "a.tlog: a propeller-and-rudder ship's run keeps its propeller speed" in done.stderr
    assert not (tmp_path / "a.csv").exists()


def test_a_faster_test_than_the_vessel_files_bound_is_replayed_as_logged(esso, tmp_path):
    """The shipped Esso's rps_max (10) is the shared tests' fastest; a run of the same twin at 17 rps,
    written as a log, is replayed by evaluate at its logged speed: the twin predicts its own run
    exactly, where clipped to the bound its 30-s free runs' R² u would be 0.04."""
    import twin

    fast = replace(esso.vessel, thrusters=replace(esso.vessel.thrusters, rps_max=20.0))
    t = np.arange(0.0, 120.0, 0.1)
    rudder = np.where((t > 40) & (t < 80), np.radians(35.0) * np.sign(np.sin(2 * np.pi * t / 20) + 1e-9), 0.0)
    inputs = InputSeries(t, np.column_stack([np.minimum(17.0 * t / 5.0, 17.0), rudder]), "propeller_rudder")
    twin.simulate_run(fast, inputs=inputs, duration_s=120.0).write(tmp_path / "fast.csv")
    scored = twin.evaluate(esso.vessel, [tmp_path / "fast.csv"])
    assert min(scored.score(dof, "free_run_30s", calibrated=False).r2 for dof in "uvr") > 0.99
    assert esso.vessel.as_logged().thrusters.rps_max is None and esso.vessel.thrusters.rps_max == 10.0
    from twin.ident.identify import beyond_command_bounds, read

    notes = beyond_command_bounds(read([tmp_path / "fast.csv"]), esso.vessel)
    assert len(notes) == 1 and "propeller speed reaches 17 rps" in notes[0] and "replayed as logged" in notes[0]


def test_a_ships_scenario_starts_from_its_steady_approach(esso):
    """A propeller-and-rudder ship's scenario begins at the steady straight speed of its first propeller
    speed [IMO-MSC137]: the zig-zag (0.3 of 10 rps) at 0.097 m/s, where from rest it would take two
    minutes to reach half of it; a small boat's scenario starts at rest."""
    from twin.analytic import straight_speed
    from twin.simulation import simulate_run

    run = simulate_run("esso_osaka", scenario="zigzag", duration_s=30.0).run
    assert run.nu[0, 0] == pytest.approx(straight_speed(esso, 3.0)) and run.nu[0, 0] == pytest.approx(0.097, abs=0.002)
    assert run.meta["approach_speed_m_s"] == run.nu[0, 0] and abs(run.nu[:50, 0] - run.nu[0, 0]).max() < 0.005
    assert np.all(simulate_run("blueboat", scenario="zigzag", duration_s=1.0).run.nu[0] == 0.0)
