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
from twin.engine.sim_reference import simulate_reference
from twin.drive import InputSeries, StepPieces, ZigZag
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
                                    {"advance_loss": 1.0, "lag_s": 0.4, "delay_s": 0.2}, {"ramp_s": 3.0},
                                    {"ramp_s": 2.0, "lag_s": 0.3, "delay_s": 0.2, "decay_per_min": 0.2},
                                    {"full_share": 0.7}, {"pwm_span_right": 1.4},
                                    {"pwm_span_left": 0.8, "start_fwd": 0.15, "start_rev": -0.15}])
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


def test_an_input_changing_within_a_step_acts_for_its_share_of_it():
    """A thrust series stamped off the 0.02-s grid, 0.005 s late: step 1 (0.02-0.04 s) holds 1 N until
    the stamp 0.021 + 0.005, then 3 N until 0.031 + 0.005, then 5 N: share 0.3, the rest 3 N for
    0.5 of the step and 5 N for 0.2, mean 0.3·1 + 0.5·3 + 0.2·5 = 2.8 N. A step without a change keeps
    its one command."""
    base = vessel_mod.load("cybership1").thrusters
    thrusters = replace(base, delay_s=0.005)
    series = InputSeries(np.array([0.0, 0.021, 0.031]), np.array([[1.0, -1.0], [3.0, -3.0], [5.0, -5.0]]), "thrust")
    pieces = StepPieces.of(series, thrusters, 3, 0.02)
    assert pieces.split.tolist() == [1]
    np.testing.assert_allclose(pieces.share, [1.0, 0.3, 1.0])
    np.testing.assert_allclose(pieces.rest[1], [(0.5 * 3 + 0.2 * 5) / 0.7, -(0.5 * 3 + 0.2 * 5) / 0.7])
    np.testing.assert_allclose(pieces.mean(), [[1.0, -1.0], [2.8, -2.8], [5.0, -5.0]])
    np.testing.assert_allclose(series.thrust_on_steps(thrusters, 3, 0.02), pieces.mean())


@pytest.mark.parametrize("delay_s", [0.35, 0.013])
def test_engine_matches_analytic_with_a_delay_between_steps(delay_s):
    """A delay that is not a whole number of 0.02-s steps, through the advance loss's curvature: the
    engine takes the step in two parts (held at the step's start, a change acted up to a step late)."""
    base = vessel_mod.load("blueboat")
    v = replace(base, thrusters=replace(base.thrusters, delay_s=delay_s))
    eng, ana = _both(v, start_s=30.0)
    pos, head = _compare(eng, ana)
    assert pos < 1e-4 and head < 1e-3


@pytest.mark.parametrize("delay_s", [0.35, 0.013])
def test_closed_loop_matches_analytic_with_a_delay_between_steps(delay_s):
    """A controller's output reaching the thrusters between two steps: the step it lands in is taken
    in two parts (at the nearest step, 1.6 cm and 0.33° off over the 120-s zig-zag at 0.35 s). The
    run's inputs replay it: the neutral first, as nothing acted until the first command came through
    the delay (without it the analytic model pushed from t = 0: 0.43 m off)."""
    base = vessel_mod.load("blueboat")
    v = replace(base, thrusters=replace(base.thrusters, delay_s=delay_s))
    cv = compile_vessel(v)
    eng = simulate(cv, ZigZag(), 120.0)
    inputs = eng.meta["inputs"]
    assert inputs.t[0] == -delay_s and inputs.values[0].tolist() == [v.thrusters.neutral_us] * 2
    ana = analytic.simulate(cv.hydro(), v.thrusters, cv.geometry.thruster_y_m, inputs, eng.t, nu0=np.zeros(3))
    pos, head = _compare(eng, ana)
    assert pos < 1e-4 and head < 1e-3


def test_a_sample_at_a_split_step_shows_the_thrust_acting_at_its_instant():
    """CyberShip I (0.01-s step) with a 0.013-s delay: the change stamped 1.0 s acts from 1.013 s,
    so the samples at 1.00 and 1.01 s still show the thrust before it (they showed the step's mean)."""
    base = vessel_mod.load("cybership1")
    v = replace(base, thrusters=replace(base.thrusters, delay_s=0.013))
    series = InputSeries(np.array([0.0, 1.0]), np.array([[0.5, 0.5], [2.0, -1.0]]), "thrust")
    run = simulate(compile_vessel(v), series, 2.0, sample_dt_s=0.01)
    at = {round(t, 2): tuple(x) for t, x in zip(run.t, run.thrust_n)}
    assert at[1.0] == at[1.01] == pytest.approx((0.5, 0.5)) and at[1.02] == pytest.approx((2.0, -1.0))


def test_a_wind_series_changing_between_the_inputs_changes_runs_open_loop():
    """A wind series whose changes fall on steps where the inputs do not change (the loop returns at
    both): it raised a bare KeyError."""
    from twin.drive import WindSeries

    cv = compile_vessel(vessel_mod.load("yellowfish"))
    series = InputSeries(np.array([0.0, 5.0]), np.array([[1700.0, 1700.0], [1600.0, 1800.0]]), "pwm")
    wind = WindSeries.from_speed_direction([0.0, 0.74], [3.0, 6.0], [90.0, 180.0])
    eng = simulate(cv, series, 10.0, wind=wind)
    ana = analytic.simulate(cv.hydro(), cv.vessel.thrusters, cv.geometry.thruster_y_m, series, eng.t,
                            nu0=np.zeros(3), wind=wind)
    assert _compare(eng, ana)[0] < 1e-4


def test_a_ramp_heads_for_the_input_where_it_changes_within_a_step():
    """With a slew limit and a delay off the step grid (0.013 s), each step's command is the mean of
    the continuous ramp, which heads for the input held over each part of the step: the same as the
    ramp on a grid a thousand times finer, to 1e-9 N. Guards against a ramp that follows the input at
    each step's start (a change a step late: 0.1 N off here), one fed the step's mean (an input reversing
    within a step turns it a whole step's slew the wrong way) and one heading for the mean of several
    inputs within a step (up to a step's slew off)."""
    base = vessel_mod.load("yellowfish")
    th = replace(base.thrusters, ramp_s=2.0, delay_s=0.013)
    # a reversal within a step; two changes within one step (2.500 and 2.503 s, acting at 2.513 and
    # 2.516); a stamp repeating the input held (3.0 s)
    series = InputSeries(np.array([0.0, 2.0, 2.5, 2.503, 3.0]),
                         np.array([[1800.0, 1800.0], [1200.0, 1600.0], [1750.0, 1450.0], [1300.0, 1900.0],
                                   [1300.0, 1900.0]]), "pwm")
    fine = 1000
    held = series.commanded_thrust(th, np.arange(200 * fine) * (0.02 / fine))
    continuous = th.slewed(held, 0.02 / fine)[0].reshape(200, fine, 2).mean(axis=1)
    steps = series.thrust_on_steps(th, 200, 0.02)
    np.testing.assert_allclose(steps, continuous, rtol=0, atol=1e-9)
    at_start = th.slewed(series.commanded_thrust(th, np.arange(200) * 0.02), 0.02)[0]
    assert np.max(np.abs(steps - at_start)) > 0.05  # what holding the step's start gave


def test_a_ramped_vessel_with_a_delay_off_the_step_grid_meets_the_analytic_model():
    """Yellowfish, ramp 2 s, delay 0.35 s (17.5 steps), over the zig-zag: the engine, its readable
    reference loop and the analytic model agree, open and closed loop (guards against a ramp that
    follows the input at each step's start: 0.014 m / 0.18° off)."""
    base = vessel_mod.load("yellowfish")
    v = replace(base, thrusters=replace(base.thrusters, ramp_s=2.0, delay_s=0.35))
    cv = compile_vessel(v)
    closed = simulate(cv, ZigZag(), 40.0)
    series = closed.meta["inputs"]
    opened = simulate(cv, series, 40.0)
    ana = analytic.simulate(cv.hydro(), v.thrusters, cv.geometry.thruster_y_m, series, closed.t, nu0=np.zeros(3))
    for run in (closed, opened):
        pos, head = _compare(run, ana)
        assert pos < 1e-3 and head < 2e-3, (pos, head)
    for drive, run in ((ZigZag(), closed), (series, opened)):
        ref = simulate_reference(cv, drive, 40.0)
        np.testing.assert_allclose(ref.eta, run.eta, rtol=0, atol=1e-9)
        np.testing.assert_allclose(ref.thrust_n, run.thrust_n, rtol=0, atol=1e-9)


def test_a_ramped_closed_loop_run_is_replayed_by_its_inputs():
    """The inputs repeat the held command at every tick; a repeated stamp changes nothing, so a replay
    splits no step the run did not (guards against splitting where a mean of equal commands rounds:
    the split steps' ramp parts take the replay 0.057 m and 1.7 N off the run, BlueBoat, ramp 0.3 s,
    delay 0.41 s)."""
    base = vessel_mod.load("blueboat")
    v = replace(base, thrusters=replace(base.thrusters, ramp_s=0.3, delay_s=0.41))
    cv = compile_vessel(v)
    run = simulate(cv, ZigZag(surge=0.6, yaw=0.9, switch_deg=8.0, at_s=2.0), 30.0)
    replay = simulate(cv, run.meta["inputs"], 30.0)
    assert np.max(np.abs(replay.eta - run.eta)) < 1e-6
    assert np.max(np.abs(replay.thrust_n - run.thrust_n)) < 1e-4


def test_a_closed_loop_command_arriving_after_the_run_is_not_shown_at_its_end():
    base = vessel_mod.load("yellowfish")
    v = replace(base, thrusters=replace(base.thrusters, delay_s=0.35))
    run = simulate(compile_vessel(v), ZigZag(), 10.0)
    ticks = run.meta["inputs"]
    # the last sample shows the command of the tick delay_s before it, not the one at the end
    expected = replace(v.thrusters, delay_s=0.0).command("pwm", ticks.at(np.array([10.0 - 0.35])), np.array([10.0]))
    np.testing.assert_allclose(run.thrust_n[-1], expected[0] * np.array(v.thrusters.gains()), rtol=1e-12)


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
    bias = Sensors(heading_bias_deg=-7.6)  # a bias alone is taken out in one step, to the last bit
    np.testing.assert_array_equal(true_heading(bias, measured_heading(bias, psi)),
                                  psi + np.radians(-7.6) - np.radians(-7.6))


def test_vessel_file_round_trip_keeps_the_new_fields(tmp_path):
    base = vessel_mod.load("yellowfish")
    v = replace(base, sensors=Sensors(heading_bias_deg=1.5, antenna_offset_m=(0.1, 0.0)), cg_offset_m=(0.01, 0.0),
                thrusters=replace(base.thrusters, delay_s=0.2, decay_per_min=0.05, advance_loss=1.2,
                                            start_fwd=0.15, start_rev=-0.16))
    path = vessel_mod.save(v, tmp_path / "amended.json")
    back = vessel_mod.load(str(path))
    assert back.sensors == v.sensors and back.cg_offset_m == v.cg_offset_m and back.thrusters == v.thrusters
    assert "start_fwd" not in vessel_mod.save(base, tmp_path / "plain.json").read_text()  # old files unchanged
    assert "ramp_s" not in vessel_mod.save(base, tmp_path / "plain.json").read_text()
    ramped = replace(base, thrusters=replace(base.thrusters, ramp_s=1.7))
    assert vessel_mod.load(str(vessel_mod.save(ramped, tmp_path / "ramped.json"))).thrusters.ramp_s == 1.7


# ---------------------------------------------------------------- motor start/stop hysteresis

HYST = {"start_fwd": 0.16, "start_rev": -0.17}  # 64 µs and 68 µs from neutral, dead zone 31 / 37 µs


def test_motor_states_vectorised_and_stepwise_agree():
    from twin.physics.thrusters import motor_state_step, motor_states
    rng = np.random.default_rng(3)
    for _ in range(50):
        x = np.cumsum(rng.normal(0.0, 0.05, 400)) * rng.uniform(0.2, 1.0)
        x[rng.random(400) < 0.05] = np.nan
        state, steps = 0, []
        for xi in x:
            state = motor_state_step(state, xi, 0.16, 0.0775, -0.17, -0.0925)
            steps.append(state)
        np.testing.assert_array_equal(motor_states(x, 0.16, 0.0775, -0.17, -0.0925), steps)


def test_a_stopped_motor_starts_beyond_its_start_edge_and_stops_inside_the_dead_zone():
    t = replace(vessel_mod.load("yellowfish").thrusters, **HYST)
    pwm = np.array([1500, 1550, 1570, 1550, 1540, 1525, 1550, 1440, 1420, 1450, 1470, 1440], float)
    driven = t.as_driven(np.column_stack([pwm, np.full_like(pwm, 1500.0)]))[:, 0]
    # 1550 from stopped: nothing; 1570 starts it; 1550, 1540 keep it; 1525 (inside 1531) stops it;
    # 1550 again: stopped; 1440 not past 1432: stopped; 1420 starts astern; 1450 keeps; 1470 stops
    np.testing.assert_array_equal(driven, [1500, 1500, 1570, 1550, 1540, 1500, 1500, 1500, 1420, 1450, 1500, 1500])
    state, stepped = (0, 0), []
    for p in pwm:
        state, pair = t.driven_step(state, (p, 1500.0))
        stepped.append(pair[0])
    np.testing.assert_array_equal(stepped, driven)
    plain = vessel_mod.load("yellowfish").thrusters
    assert not plain.hysteretic and np.array_equal(plain.as_driven(pwm[:, None]), pwm[:, None])
    inside = replace(plain, start_fwd=0.05, start_rev=-0.05)  # edges inside the dead zone: no hysteresis
    assert not inside.hysteretic and inside.start_edges == (plain.deadzone_fwd, plain.deadzone_rev)


NEAR_NEUTRAL = InputSeries(np.arange(0.0, 24.0, 2.0), np.array(
    [[1550, 1545], [1575, 1500], [1545, 1545], [1540, 1430], [1520, 1415], [1550, 1445],
     [1565, 1470], [1545, 1440], [1600, 1550], [1535, 1535], [1500, 1420], [1548, 1455]], float), "pwm")


def test_hysteresis_engine_matches_analytic_and_changes_the_run():
    base = vessel_mod.load("yellowfish")
    v = replace(base, thrusters=replace(base.thrusters, **HYST))
    cv = compile_vessel(v)
    eng = simulate(cv, NEAR_NEUTRAL, 24.0)
    ana = analytic.simulate(cv.hydro(), v.thrusters, cv.geometry.thruster_y_m, NEAR_NEUTRAL, eng.t,
                            nu0=np.zeros(3))
    pos, head = _compare(eng, ana)
    assert pos < 0.01 and head < 0.1
    plain = simulate(compile_vessel(base), NEAR_NEUTRAL, 24.0)
    assert _compare(eng, plain)[0] > 0.5
    # the run logs the PWM as commanded, not as the motors answered it
    np.testing.assert_array_equal(eng.pwm_us[0], [1550, 1545])


def test_hysteresis_closed_loop_is_its_own_pwm_replayed():
    base = vessel_mod.load("yellowfish")
    v = replace(base, thrusters=replace(base.thrusters, **HYST))
    cv = compile_vessel(v)
    levels = [(0.1, 0.0), (0.25, 0.05), (0.12, -0.02), (0.0, 0.0), (-0.15, 0.03), (0.1, 0.08)]

    def controller(t, eta, nu):
        return levels[min(int(t // 3.0), len(levels) - 1)]
    closed = simulate(cv, controller, 18.0, sample_dt_s=0.1)
    replayed = simulate(cv, closed.meta["inputs"], 18.0, sample_dt_s=0.1)
    np.testing.assert_allclose(closed.eta, replayed.eta, atol=1e-9)
    assert np.abs(closed.nu[:, 0]).max() > 0.1


# ---------------------------------------------------------------- thrust ramp (slew limit)

def test_a_ramp_heads_for_the_command_at_its_rate_and_its_step_means_keep_the_impulse():
    t = replace(vessel_mod.load("yellowfish").thrusters, ramp_s=2.0)
    rate = t.slew_n_per_s
    assert rate == pytest.approx(t.bounds()[1] / 2.0)
    # a step from 0 to 20 N (held 0 first) on steps of 0.05 s and of 0.01 s
    for dt in (0.05, 0.01):
        n = int(round(4.0 / dt))
        cmd = np.zeros((n, 2))
        cmd[int(round(1.0 / dt)):] = [20.0, -15.0]
        means, end = t.slewed(cmd, dt)
        times = np.arange(n) * dt
        ramp = np.column_stack([np.clip((times - 1.0) * rate, 0.0, 20.0), -np.clip((times - 1.0) * rate, 0.0, 15.0)])
        after = np.clip((times + dt - 1.0) * rate, 0.0, None)  # the ramp at each step's end
        np.testing.assert_allclose(end, [20.0, -15.0])
        # each step's mean is the continuous ramp's mean over it: the impulse is the ramp's to rounding
        np.testing.assert_allclose(means.sum(axis=0) * dt, [20.0 * (3.0 - 20.0 / rate / 2),
                                                            -15.0 * (3.0 - 15.0 / rate / 2)], rtol=1e-9)
        assert np.all(np.abs(means - ramp) <= rate * dt / 2 + 1e-9)
        assert np.all(means[:, 0] <= np.minimum(after, 20.0) + 1e-9)
    plain = vessel_mod.load("yellowfish").thrusters
    cmd = np.array([[0.0, 0.0], [25.0, -10.0], [40.0, -40.0]])
    np.testing.assert_array_equal(plain.slewed(cmd, 0.05)[0], np.clip(cmd, *plain.bounds()))


def test_a_ramp_needs_a_thrust_to_ramp_across():
    from twin.errors import TwinError
    cyber = vessel_mod.load("cybership1")
    unbounded = replace(cyber, thrusters=replace(cyber.thrusters, thrust_min_n=None, thrust_max_n=None,
                                                 command_scale_n=None, ramp_s=1.0))
    with pytest.raises(TwinError, match="ramp"):
        vessel_mod.check(unbounded)
    base = vessel_mod.load("yellowfish")
    with pytest.raises(TwinError, match="ramp_s"):
        vessel_mod.check(replace(base, thrusters=replace(base.thrusters, ramp_s=-1.0)))


def test_a_ramped_closed_loop_is_its_own_pwm_replayed_and_slower_to_answer():
    base = vessel_mod.load("yellowfish")
    v = replace(base, thrusters=replace(base.thrusters, ramp_s=2.5))
    cv = compile_vessel(v)
    levels = [(0.0, 0.0), (0.8, 0.0), (0.8, 0.4), (-0.5, 0.0), (0.3, -0.3)]

    def controller(t, eta, nu):
        return levels[min(int(t // 4.0), len(levels) - 1)]
    closed = simulate(cv, controller, 20.0, sample_dt_s=0.1)
    replayed = simulate(cv, closed.meta["inputs"], 20.0, sample_dt_s=0.1)
    np.testing.assert_allclose(closed.eta, replayed.eta, atol=1e-9)
    plain = simulate(compile_vessel(base), controller, 20.0, sample_dt_s=0.1)
    # 0.8 of full ahead from rest at t = 4 s: the plain thrusters give it at once, the ramp after 1.6 s
    k = np.searchsorted(closed.t, 5.0)
    assert plain.thrust_n[k, 0] == pytest.approx(plain.thrust_n[k + 15, 0])
    assert closed.thrust_n[k, 0] < 0.7 * plain.thrust_n[k, 0]
    np.testing.assert_allclose(closed.thrust_n[np.searchsorted(closed.t, 7.0), 0], plain.thrust_n[k, 0], rtol=1e-6)


# ---------------------------------------------------------------- thrust following the supply voltage

SUPPLY = {"supply_exponent": 2.0, "supply_ref_v": 16.0}
VOLTS = np.array([16.0, 15.1, 14.4, 15.6])  # held with PWM's four inputs: a pack sagging under load


def test_the_supply_factor_is_the_voltage_ratio_to_the_power_k():
    t = replace(vessel_mod.load("yellowfish").thrusters, **SUPPLY)
    pwm = np.array([[1800.0, 1300.0], [1700.0, 1650.0]])
    raw = t.command("pwm", pwm, np.zeros(2))
    np.testing.assert_allclose(t.command("pwm", pwm, np.zeros(2), np.array([12.0, 16.0])),
                               raw * np.array([[0.5625], [1.0]]), rtol=1e-12)
    # no voltage, a sample before the first reading, or a map that does not follow it: the map as it is
    np.testing.assert_array_equal(t.command("pwm", pwm, np.zeros(2), None), raw)
    np.testing.assert_array_equal(t.command("pwm", pwm, np.zeros(2), np.array([np.nan, 16.0])), raw)
    plain = replace(t, supply_exponent=0.0)
    np.testing.assert_array_equal(plain.command("pwm", pwm, np.zeros(2), np.array([12.0, 12.0])), raw)


def test_engine_matches_analytic_with_a_logged_supply_voltage():
    base = vessel_mod.load("yellowfish")
    v = replace(base, thrusters=replace(base.thrusters, **SUPPLY, lag_s=0.3, delay_s=0.2))
    series = replace(PWM, supply_v=VOLTS)
    cv = compile_vessel(v)
    eng = simulate(cv, series, 20.0, start_s=30.0, nu0=(0.5, 0.0, 0.0))
    ana = analytic.simulate(cv.hydro(), v.thrusters, cv.geometry.thruster_y_m, series, eng.t - 30.0,
                            nu0=np.array([0.5, 0.0, 0.0]), start_s=30.0)
    pos, head = _compare(eng, ana)
    assert pos < 0.01 and head < 0.1
    unlogged = simulate(cv, PWM, 20.0, start_s=30.0, nu0=(0.5, 0.0, 0.0))  # no voltage: the map at V_ref
    assert _compare(eng, unlogged)[0] > 0.3


def test_the_thrust_follows_the_voltage_held_with_the_inputs():
    base = vessel_mod.load("yellowfish")
    v = replace(base, thrusters=replace(base.thrusters, **SUPPLY))
    run = simulate(compile_vessel(v), replace(PWM, supply_v=VOLTS), 18.0, sample_dt_s=0.1)
    ref = simulate(compile_vessel(base), PWM, 18.0, sample_dt_s=0.1)
    volt = VOLTS[np.searchsorted(PWM.t, run.t + 1e-9, side="right") - 1]
    np.testing.assert_allclose(run.thrust_n, ((volt / 16.0) ** 2)[:, None] * ref.thrust_n, rtol=1e-9)


def test_a_closed_loop_on_a_sagging_pack_is_its_own_inputs_replayed():
    from twin.drive import SupplySeries

    base = vessel_mod.load("yellowfish")
    cv = compile_vessel(replace(base, thrusters=replace(base.thrusters, **SUPPLY)))
    supply = SupplySeries(np.array([0.0, 6.0, 12.0]), np.array([16.0, 14.8, 15.5]))  # changes at ticks

    def controller(t, eta, nu):
        return (0.6, 0.2 if t < 9.0 else -0.1)
    closed = simulate(cv, controller, 18.0, sample_dt_s=0.1, supply=supply)
    replayed = simulate(cv, closed.meta["inputs"], 18.0, sample_dt_s=0.1)
    np.testing.assert_allclose(closed.eta, replayed.eta, atol=1e-9)
    full = simulate(cv, controller, 18.0, sample_dt_s=0.1)  # the same pack at V_ref all along
    assert full.nu[:, 0].mean() - closed.nu[:, 0].mean() > 0.03  # the sagging pack is slower


def test_a_vessel_file_keeps_its_supply_and_refuses_an_exponent_without_a_reference(tmp_path):
    from twin.errors import TwinError

    base = vessel_mod.load("yellowfish")
    v = replace(base, thrusters=replace(base.thrusters, **SUPPLY))
    assert vessel_mod.load(str(vessel_mod.save(v, tmp_path / "v.json"))).thrusters == v.thrusters
    assert "supply" not in vessel_mod.save(base, tmp_path / "plain.json").read_text()  # old files unchanged
    with pytest.raises(TwinError, match="supply_ref_v"):
        vessel_mod.check(replace(base, thrusters=replace(base.thrusters, supply_exponent=1.5)))
    with pytest.raises(TwinError, match="supply_exponent"):
        vessel_mod.check(replace(base, thrusters=replace(base.thrusters, supply_exponent=-1.0, supply_ref_v=16.0)))


# ---------------------------------------------------------------- a forward curve that saturates

def test_a_saturating_forward_curve_gives_its_share_at_full_pwm_and_keeps_the_low_end():
    t = vessel_mod.load("yellowfish").thrusters
    top = replace(t, full_share=0.7)
    pwm = np.arange(1100.0, 1900.5, 1.0)
    raw, bent = t.thrust_from_pwm(pwm), top.thrust_from_pwm(pwm)
    assert bent[-1] == pytest.approx(0.7 * t.full_forward_n, rel=1e-12) and top.bounds()[1] == pytest.approx(bent[-1])
    near = (pwm > 1500) & (raw > 0) & (raw < 0.1 * t.full_forward_n)
    np.testing.assert_allclose(bent[near], raw[near], rtol=0.01)  # the low end is the map's
    assert np.all(np.diff(bent[pwm >= 1540]) > 0)  # still rising with the PWM
    np.testing.assert_array_equal(bent[raw <= 0], raw[raw <= 0])  # astern and the dead zone untouched
    steeper = replace(t, full_share=1.2).thrust_from_pwm(pwm)
    assert steeper[-1] == pytest.approx(1.2 * t.full_forward_n) and np.all(np.diff(steeper[pwm >= 1540]) > 0)


def test_full_thrust_composes_and_a_vessel_file_keeps_it(tmp_path):
    from twin.effects.library import full_thrust
    from twin.errors import TwinError

    base = vessel_mod.load("yellowfish")
    v = full_thrust(full_thrust(base, 0.8), 0.9)
    assert v.thrusters.full_share == pytest.approx(0.72)
    assert vessel_mod.load(str(vessel_mod.save(v, tmp_path / "v.json"))).thrusters == v.thrusters
    assert "full_share" not in vessel_mod.save(base, tmp_path / "plain.json").read_text()  # old files unchanged
    with pytest.raises(TwinError, match="full_share"):
        vessel_mod.check(replace(base, thrusters=replace(base.thrusters, full_share=0.0)))
    with pytest.raises(TwinError, match="falls with the PWM"):
        vessel_mod.check(replace(base, thrusters=replace(base.thrusters, forward=(-20.0, 14.97, -0.62))))


def test_compass_error_that_follows_the_throttle_and_its_inverse():
    """δψ = τ·(B_m sin ψ + C_m cos ψ) beside the fixed deviation; τ the mean |pwm − neutral| over its side's
    range, ahead or astern alike (a battery's current flows one way either way)."""
    from twin.physics.sensors import motor_throttle

    tau = motor_throttle([[1500, 1500], [1900, 1100], [1700, 1500], [1300, 1600]], (1500, 1500), 1100.0, 1900.0)
    np.testing.assert_allclose(tau, [0.0, 1.0, 0.25, 0.375])
    s = Sensors(heading_bias_deg=1.0, compass_deviation_deg=(2.0, 0.0, 0.0, 0.0), compass_motor_deg=(8.0, -5.0))
    psi = np.linspace(-np.pi, np.pi, 37)
    throttle = np.linspace(0.0, 1.0, 37)
    m = measured_heading(s, psi, throttle)
    expected = psi + np.radians(1 + 2 * np.sin(psi) + throttle * (8 * np.sin(psi) - 5 * np.cos(psi)))
    np.testing.assert_allclose(m, expected)
    np.testing.assert_allclose(true_heading(s, m, throttle, iterations=12), psi, atol=1e-9)
    idle = measured_heading(s, psi, 0.0)  # at idle only the fixed errors are left
    np.testing.assert_allclose(idle, psi + np.radians(1 + 2 * np.sin(psi)))


def test_a_log_is_corrected_with_the_throttle_at_each_heading_sample(tmp_path):
    """calibrated() reads the PWM in force when each heading sample was taken, on the PWM log's own clock,
    and a vessel that logs no PWM cannot carry the effect."""
    from twin.errors import TwinError
    from twin.fit.calibrate import calibrated
    from twin.recording import Recording, Stream

    base = vessel_mod.load("yellowfish")
    v = replace(base, sensors=Sensors(compass_motor_deg=(0.0, 10.0), pwm_clock_offset_s=0.5))
    t = np.arange(0.0, 10.0, 0.1)
    rec = Recording(kind="csv", source="x.csv", heading=Stream(t, {"psi_rad": np.zeros_like(t)}),
                    pwm=Stream(np.array([0.0, 5.5]), {"left_us": np.array([1500.0, 1900.0]),
                                                      "right_us": np.array([1500.0, 1900.0])}))
    psi = calibrated(rec, v).heading["psi_rad"]
    # stamped 0.5 s late: full throttle from heading time 5.0 s, where the true heading ψ ≈ −9.85° reads 0
    np.testing.assert_allclose(psi[t < 4.95], 0.0, atol=1e-12)
    after = psi[t > 5.05]
    assert after == pytest.approx(np.full(len(after), -0.17196), abs=1e-4)
    np.testing.assert_allclose(measured_heading(v.sensors, after, 1.0), 0.0, atol=1e-6)
    # an ESC answering half the logged PWM's range draws half the current: the left one here, so the
    # mean throttle is 0.75 and the motors' deviation three quarters of it
    part = calibrated(rec, replace(v, thrusters=replace(v.thrusters, pwm_span_left=0.5)))
    np.testing.assert_allclose(measured_heading(v.sensors, part.heading["psi_rad"][t > 5.05], 0.75), 0.0, atol=1e-6)
    assert abs(part.heading["psi_rad"][-1]) == pytest.approx(0.75 * abs(after[-1]), rel=0.02)
    # a span past 1 drives no motor beyond full: the ESC clips its pulse
    wide = calibrated(rec, replace(v, thrusters=replace(v.thrusters, pwm_span_left=1.5, pwm_span_right=1.5)))
    np.testing.assert_allclose(wide.heading["psi_rad"], psi, atol=1e-12)
    with pytest.raises(TwinError, match="needs the thrusters' PWM"):
        calibrated(replace(rec, pwm=Stream.empty("left_us", "right_us")), v)
    esso = vessel_mod.load("esso_osaka")
    with pytest.raises(TwinError, match="compass_motor_deg follows the PWM throttle"):
        vessel_mod.check(replace(esso, sensors=Sensors(compass_motor_deg=(3.0, 0.0))))
    back = vessel_mod.load(str(vessel_mod.save(v, tmp_path / "motor.json")))
    assert back.sensors.compass_motor_deg == (0.0, 10.0)
    assert "compass_motor_deg" not in vessel_mod.save(base, tmp_path / "plain.json").read_text()


@pytest.mark.parametrize("name, value", [("thrust_gain", 0.85), ("thruster_asymmetry", 0.9)])
def test_a_gain_effect_is_read_as_a_multiple_of_the_twins_own(name, value):
    """On a twin whose gains are not 1 (the BlueBoat's 1.605 for its 14.8-V pack, made unequal here)
    the diagnosis reads thrust_gain and thruster_asymmetry as the effect applies them, a multiple of
    the twin's own: the value it names can be given back (--effect, --given)."""
    from twin.effects import apply_effects, candidates

    boat = vessel_mod.load("blueboat")
    prior = replace(boat, thrusters=replace(boat.thrusters, gain_left=1.5, gain_right=1.7))
    cand = candidates(prior, [])[name]
    q = cand.params[0]
    assert q.get(prior) == pytest.approx(1.0) and cand.starts[0][0] == 1.0
    truth = apply_effects(prior, [(name, {q.name: value})])
    assert q.get(truth) == pytest.approx(value)
    put = q.put(prior, value)
    assert (put.thrusters.gain_left, put.thrusters.gain_right) == pytest.approx(
        (truth.thrusters.gain_left, truth.thrusters.gain_right))


def test_one_escs_pwm_span_is_a_pulse_scale_not_a_thrust_scale(tmp_path):
    """An ESC that answers 4/3 of the logged pulse's deviation from neutral: its thrust is the map's
    at that pulse (clipped to the PWM range), the other thruster's untouched; through the map's curve
    that is a thrust ratio of 1.5-1.8 at part throttle ahead and 1 at full. A log that reports 0.75 of
    the pulse is its truth back at span 1/0.75; a motor's start edge is read on the received pulse; the
    step-by-step path (closed loops) gives the same thrust as the array path (SITL: tests/test_sitl.py);
    a vessel file keeps the span, old files stay as they were, and a span of 0 is refused."""
    from twin.effects import apply_effects
    from twin.engine.tick import TickMap
    from twin.errors import TwinError

    base = vessel_mod.load("blueboat")
    spanned = apply_effects(base, ["pwm_span_right=1.3333"]).thrusters
    t, n = base.thrusters, base.thrusters.neutral_us
    pwm = np.column_stack([np.linspace(1100, 1900, 81), np.linspace(1100, 1900, 81)])
    got = spanned.thrust_from_pwm(pwm)
    np.testing.assert_array_equal(got[:, 0], t.thrust_from_pwm(pwm)[:, 0])
    want = t.thrust_from_pwm(np.column_stack([pwm[:, 0], n + 1.3333 * (pwm[:, 1] - n)]))[:, 1]
    np.testing.assert_allclose(got[:, 1], want, rtol=1e-12)
    ahead = (pwm[:, 0] > n + 60) & (pwm[:, 0] < n + 280)
    ratio = got[ahead, 1] / got[ahead, 0]
    assert ratio.min() > 1.2 and ratio.max() < 2.0 and got[-1, 1] == got[-1, 0]  # full is full
    assert spanned.bounds() == t.bounds()  # the ESC's range is the map's
    # a log whose right PWM reports 0.75 of the deviation the ESC received: span 1/0.75 gives the thrust back
    true = np.column_stack([np.full(9, 1600.0), np.linspace(1150, 1850, 9)])
    logged = np.column_stack([true[:, 0], n + 0.75 * (true[:, 1] - n)])
    back = apply_effects(base, [f"pwm_span_right={1 / 0.75}"]).thrusters
    np.testing.assert_allclose(back.thrust_from_pwm(logged), t.thrust_from_pwm(true), rtol=1e-9, atol=1e-9)
    # a motor that starts late reads its start edge on the pulse its ESC receives: 1580 µs starts it as
    # logged (δ̃ 0.17 ≥ 0.15), not at a span of 0.8 (1566 µs received, δ̃ 0.14)
    late = replace(t, start_fwd=0.15, start_rev=-0.15)
    assert late.as_driven(np.array([[1580.0, 1580.0]])).tolist() == [[1580.0, 1580.0]]
    assert replace(late, pwm_span_left=0.8).as_driven(np.array([[1580.0, 1580.0]])).tolist() == [[n, 1580.0]]
    tick = TickMap.of(spanned)
    for left, right in ((1700.0, 1650.0), (1300.0, 1420.0), (1900.0, 1880.0)):
        pair = tick.raw_thrust("pwm", (left, right))
        np.testing.assert_allclose(pair, spanned.thrust_from_pwm(np.array([left, right])), rtol=1e-12)
    v = replace(base, thrusters=spanned)
    assert vessel_mod.load(str(vessel_mod.save(v, tmp_path / "v.json"))).thrusters == spanned
    assert "pwm_span" not in vessel_mod.save(base, tmp_path / "plain.json").read_text()
    import json

    d = json.loads(vessel_mod.save(base, tmp_path / "zero.json").read_text())
    d["thrusters"]["pwm_span_left"] = 0.0
    (tmp_path / "zero.json").write_text(json.dumps(d))
    with pytest.raises(TwinError, match="pwm_span_left"):
        vessel_mod.load(str(tmp_path / "zero.json"))
