"""The standard manoeuvres (turning circle, zig-zag, crash stop) read from the twin's runs: their
geometry against the track itself, their symmetry, and how they move with the boat and the command."""
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

import twin
import twin.vessel as vessel_mod
from twin.engine.mjcf import compile_vessel
from twin.errors import TwinError
from twin.ident.identify import calibrate, prepared, read
from twin.verify.manoeuvres import APPROACH_S, _after_execute, _run, manoeuvre_bands, manoeuvres, recorded_turns


@pytest.fixture(scope="module")
def blueboat():
    return manoeuvres(vessel_mod.load("blueboat"))


def test_a_symmetric_boat_turns_the_same_circle_to_either_side(blueboat):
    starboard, port = blueboat.turns
    assert starboard.side == 1 and port.side == -1
    assert starboard.advance_m == pytest.approx(port.advance_m, rel=1e-6)
    assert starboard.transfer_m == pytest.approx(-port.transfer_m, rel=1e-6) and starboard.transfer_m > 0
    assert starboard.steady_rate_deg_s == pytest.approx(-port.steady_rate_deg_s, rel=1e-6)
    assert starboard.steady_rate_deg_s > 0
    assert blueboat.approach_speed_m_s == pytest.approx(blueboat.straight.speed_m_s, rel=0.01)
    assert blueboat.straight.stable


def test_the_steady_diameter_is_the_circle_the_track_draws():
    """2U/|r| of the steady turn against a circle fitted to the track after 360° (least squares)."""
    compiled = compile_vessel(vessel_mod.load("yellowfish"))
    m = manoeuvres(compiled.vessel)
    u0 = m.approach_speed_m_s
    run = _run(compiled, lambda t, eta, nu: (0.5, 1.0 if t >= 0 else 0.0), 60.0, u0)
    _, x, y, heading = _after_execute(run)
    steady = heading >= np.radians(360.0)
    A = np.column_stack([2 * x[steady], 2 * y[steady], np.ones(steady.sum())])
    cx, cy, c = np.linalg.lstsq(A, x[steady] ** 2 + y[steady] ** 2, rcond=None)[0]
    diameter = 2 * np.sqrt(c + cx ** 2 + cy ** 2)
    assert m.turns[0].steady_diameter_m == pytest.approx(diameter, rel=0.01)
    # the tactical diameter is where the heading has turned 180°: at least the steady circle's, the boat
    # running wider while it slows into the turn
    assert m.turns[0].tactical_diameter_m >= 0.99 * diameter
    assert 0 < m.turns[0].steady_speed_m_s < u0


def test_a_harder_zig_zag_overshoots_more_and_a_heavier_boat_stops_later():
    soft = manoeuvres(vessel_mod.load("blueboat"), zigzag_yaw=0.2)
    hard = manoeuvres(vessel_mod.load("blueboat"), zigzag_yaw=0.6)
    assert 0 < soft.zigzag.first_overshoot_deg < hard.zigzag.first_overshoot_deg
    assert hard.zigzag.time_to_first_switch_s < soft.zigzag.time_to_first_switch_s
    light = manoeuvres(vessel_mod.load("yellowfish", case="min")).crash_stop
    heavy = manoeuvres(vessel_mod.load("yellowfish", case="max")).crash_stop
    assert 0 < light.head_reach_m < heavy.head_reach_m and light.time_s < heavy.time_s
    assert abs(heavy.lateral_m) < 1e-6 and heavy.track_reach_m == pytest.approx(heavy.head_reach_m, rel=1e-6)


def test_a_ship_turns_within_its_length_scale_and_stops_on_its_propeller():
    """The Esso Osaka twin at full propeller speed: the turning circle and crash stop of its MMG forces,
    in lengths Lpp (a tanker turns in a few lengths and runs several before it stops)."""
    m = twin.manoeuvres("esso_osaka", surge=1.0, turn_yaw=35.0 / 40.0)
    L = m.length_m
    assert L == pytest.approx(3.0)
    starboard = m.turns[0]
    assert 2.0 < starboard.advance_m / L < 4.5 and 2.0 < starboard.tactical_diameter_m / L < 5.0
    assert starboard.steady_diameter_m < starboard.tactical_diameter_m
    assert starboard.steady_speed_m_s < 0.5 * m.approach_speed_m_s  # a full ship loses half its speed in a turn
    assert m.zigzag.yaw == pytest.approx(0.25) and 0 < m.zigzag.first_overshoot_deg < m.zigzag.second_overshoot_deg
    assert 2.0 < m.crash_stop.head_reach_m / L < 6.0


@pytest.mark.parametrize("kwargs, says", [
    ({"surge": 0.0}, r"approach \(surge\) command lies in \(0, 1\]"),
    ({"surge": None}, r"approach \(surge\) command lies in \(0, 1\] of full, got None"),
    ({"surge": "0.5"}, r"got '0.5'"),
    ({"surge": True}, r"got True"),
    ({"turn_yaw": 1.5}, "turning yaw command"),
    ({"zigzag_switch_deg": 95.0}, "switch angle lies between 0 and 90"),
])
def test_a_command_outside_its_range_is_refused(kwargs, says):
    with pytest.raises(TwinError, match=says):
        manoeuvres(vessel_mod.load("blueboat"), **kwargs)


def test_a_lagged_thrust_has_settled_by_the_execute():
    """The approach starts at the straight run's speed with the thrust lag's state at zero: after
    APPROACH_S a 1-s lag has settled, and the execute finds the straight run's speed again."""
    boat = vessel_mod.load("yellowfish")
    lagged = replace(boat, thrusters=replace(boat.thrusters, lag_s=1.0))
    m = manoeuvres(lagged)
    assert APPROACH_S >= 5.0
    assert m.approach_speed_m_s == pytest.approx(m.straight.speed_m_s, rel=0.01)


def test_a_twin_drawn_over_its_yaw_damping_spreads_its_steady_turn_and_nothing_without_it():
    """A BlueBoat whose Nr is uncertain (log-normal, σ 20 %): the steady turn rate's 90 % band brackets
    the nominal twin's and widens with σ; the crash stop, which no yaw term moves, keeps one value."""
    boat = vessel_mod.load("blueboat")
    nominal = manoeuvres(boat).turns[0].steady_rate_deg_s
    widths = []
    for sigma in (0.1, 0.2):
        uncertain = replace(boat, uncertainty={"coordinates": [{"name": "Nr", "log": True, "sign": -1.0}],
                                               "mean": [float(np.log(-boat.damping.Nr))],
                                               "covariance": [[sigma ** 2]]})
        drawn = manoeuvre_bands(uncertain, 12, seed=1)
        band = {b.name: b for b in drawn.bands}
        rate = band["turn_starboard.steady_rate_deg_s"]
        assert drawn.redrawn == 0 and drawn.diverged == 0 and rate.reached == 1.0 and rate.low < nominal < rate.high
        stop = band["crash_stop.head_reach_m"]
        assert stop.high - stop.low < 1e-9
        widths.append(rate.high - rate.low)
    assert widths[1] > 1.5 * widths[0]


@pytest.fixture(scope="module")
def held_turn_log(tmp_path_factory):
    """A BlueBoat run: 10 s straight at 1700 µs, then 1900 | 1500 µs held for 50 s (more than a full
    turn), then straight again."""
    series = twin.InputSeries(np.array([0.0, 10.0, 60.0]), np.array([[1700.0, 1700.0], [1900.0, 1500.0],
                                                                     [1700.0, 1700.0]]), "pwm")
    path = tmp_path_factory.mktemp("turns") / "turn.csv"
    twin.simulate_run("blueboat", inputs=series, duration_s=70.0).write(path)
    return path


def test_a_recorded_turn_is_found_its_own_twin_predicts_it_and_a_weaker_one_turns_slower(held_turn_log):
    recs = read([held_turn_log])
    boat = calibrate(recs, vessel_mod.load("blueboat"))[0]
    (turn,) = recorded_turns(boat, prepared(recs, boat))
    assert turn.inputs == ("pwm", (1900.0, 1500.0))
    assert turn.start_s == pytest.approx(10.0, abs=0.15) and turn.held_s == pytest.approx(50.0, abs=0.3)
    m, p = turn.measured, turn.predicted
    assert m.side == 1 and m.tactical_diameter_m > 0 and m.steady_rate_deg_s > 0
    for key in ("advance_m", "transfer_m", "tactical_diameter_m", "steady_diameter_m", "steady_rate_deg_s"):
        assert getattr(p, key) == pytest.approx(getattr(m, key), rel=0.03), key
    weak = replace(boat, thrusters=replace(boat.thrusters, gain_left=0.8 * boat.thrusters.gain_left))
    (slow,) = recorded_turns(weak, prepared(recs, weak))
    # less thrust on the outer side: a slower turn, at a lower speed (the diameter, their ratio, stays near)
    assert slow.predicted.steady_rate_deg_s < 0.95 * m.steady_rate_deg_s
    assert slow.predicted.steady_speed_m_s < 0.95 * m.steady_speed_m_s


def test_evaluate_turns_prints_the_recorded_turn_beside_the_twins(held_turn_log):
    p = subprocess.run([sys.executable, "-m", "twin", "evaluate", "--vessel", "blueboat", str(held_turn_log),
                        "--turns"], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    assert "turns held in the recordings, recorded | predicted" in p.stdout
    assert "turn.csv at 10.0 s for 49.9 s (PWM left 1900, right 1500 µs as the twin reads them" in p.stdout
